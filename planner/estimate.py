"""What a plan will hold, estimated from the geometry alone before any line is laid out: photos,
lines, mission items, flights, hours and the planner's memory. It takes the area's width across
each pass and its size, the frame's ground rectangle and the overlaps (Eq. 3-5): no line, station
or footprint is made, so it takes well under a second for any area.

A plan whose estimate exceeds :data:`planner.limits.MAX_PHOTOS` is refused at once with the
estimate and the fix (split the area, a coarser GSD, or a higher limit: ``sfap plan
--max-photos``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import shapely

from . import exposure as ex
from . import trigger as trig
from .fixed_wing import fixed_wing_for
from .lines import END_STATIONS
from .spec import MissionSpec, TriggerMode

#: Peak memory of `sfap plan` per photo and whatever the size, bytes, from whole processes
#: (25 km2: 23,856 photos, 136 MB; 100 km2: 95,625 photos, 200 MB; 1,000 km2: 956,390 photos,
#: 1,311 MB with its footprints.gpkg; BENCHMARKS.md): the largest case's slope, an upper bound.
BYTES_PER_PHOTO = 1_250
BASE_BYTES = 115_000_000
#: Mission items per armed run of a line: camera on + trigger, camera off + trigger (and per line
#: its entry and exit).
ITEMS_PER_RUN = 4


@dataclass(frozen=True, kw_only=True)
class PlanEstimate:
    area_km2: float
    passes: int
    lines: int
    photos: int
    items: int
    flight_hours: float
    flights: int
    memory_mb: float

    def text(self) -> str:
        passes = f"{self.passes} pass{'es' if self.passes != 1 else ''}"
        flights = f"{self.flights:,} flight{'s' if self.flights != 1 else ''}"
        return (
            f"about {self.photos:,} photos on {self.lines:,} lines ({passes}, {self.area_km2:,.2f} km2), "
            f"{self.items:,} mission items, {self.flight_hours:,.1f} h of flight ({flights}), "
            f"about {self.memory_mb:,.0f} MB of memory to plan"
        )


@dataclass(frozen=True, kw_only=True)
class PassGeometry:
    """One pass as the estimate sees it: its line bearing (grid), the frame's rectangle on the
    ground and the overlaps asked."""

    direction_deg: float
    rect: ex.FrameRectangle
    front_overlap_pct: float
    side_overlap_pct: float


def estimate(spec: MissionSpec, area_xy: shapely.Geometry, passes: Sequence[PassGeometry]) -> PlanEstimate:
    """The estimate for ``passes`` over ``area_xy`` (metres, the plan's local frame)."""
    survey = spec.survey
    area_m2 = float(area_xy.area)
    lines = photos = runs = 0
    length_m = 0.0
    # The straight flown before and after each line: the turnaround, or a plane's run-in (one L1
    # period of flight) and lead-out, and its turn at least a U-turn's half circle.
    ends_m, turn_m = 2.0 * survey.turnaround_m, 0.0
    plane = fixed_wing_for(spec, survey.speed_m_s, 0.0)
    if plane is not None:
        ends_m = max(ends_m, plane.lead_in_m + plane.lead_out_m)
        turn_m = math.pi * plane.radius_m
    for p in passes:
        base = ex.air_base_m(p.rect.along_m, p.front_overlap_pct)
        spacing = ex.air_base_m(p.rect.across_m, p.side_overlap_pct)
        rotated = ex.geometry_to_pass_frame(area_xy, p.direction_deg)
        _, v0, _, v1 = rotated.bounds
        n = max(1, math.ceil(max(v1 - v0 - p.rect.across_m, 0.0) / spacing - 1e-9) + 1)
        on_m = area_m2 / spacing  # the camera-on length: the area over the band each line answers for
        lines += n
        pass_photos = math.ceil(on_m / base) + n * (1 + 2 * END_STATIONS)
        photos += pass_photos
        # long lines are cut into runs that each re-arm the trigger (planner.trigger)
        runs += max(n, math.ceil(pass_photos / trig.max_run_stations(base, survey.speed_m_s)))
        length_m += on_m + n * (ends_m + max(spacing, turn_m))
    speed = survey.speed_m_s
    hover = survey.trigger is TriggerMode.HOVER
    seconds = length_m / speed + (photos * (survey.hover_hold_s + speed) if hover else 0.0)
    usable = spec.vehicle.usable_flight_s or spec.vehicle.max_flight_time_min * 60.0
    per_line = 2 + (2 if survey.transit_speed_m_s is not None else 0)  # entry, exit, speed changes
    per_run = 0 if hover else ITEMS_PER_RUN
    items = lines * per_line + runs * per_run + (2 * photos if hover else 0) + 3 + len(passes)
    return PlanEstimate(
        area_km2=area_m2 / 1e6,
        passes=len(passes),
        lines=lines,
        photos=photos,
        items=items,
        flight_hours=seconds / 3600.0,
        flights=max(1, math.ceil(seconds / usable)),
        memory_mb=(BASE_BYTES + BYTES_PER_PHOTO * photos) / 1e6,
    )


def too_large(spec: MissionSpec, est: PlanEstimate, max_photos: int) -> str | None:
    """The refusal of a plan estimated beyond ``max_photos``, with the estimate and the fix; None
    when it is within."""
    if est.photos <= max_photos:
        return None
    blocks = math.ceil(est.photos / max_photos)
    gsd = spec.survey.gsd_cm
    coarser = (
        f"a coarser gsd_cm (about {gsd * math.sqrt(est.photos / max_photos):.2g} cm for "
        f"{max_photos:,} photos)"
        if gsd is not None
        else "a higher altitude_agl_m"
    )
    return (
        f"{spec.source}: this plan would hold {est.text()}, more than the {max_photos:,} photos planned "
        f"without asking; split the area into at least {blocks} blocks, ask for {coarser}, or raise the "
        f"limit (--max-photos {est.photos + 1})"
    )
