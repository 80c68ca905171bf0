"""The numbers that justify a plan (summary.json and the table `sfap plan` prints)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from . import exposure as ex
from .camera import Orientation
from .geo import LocalFrame
from .mission import Autopilot
from .plan import Summary
from .spec import MissionSpec, VehicleSpec
from .vehicle_params import required_parameters

if TYPE_CHECKING:
    from .coverage import ViewShares
    from .mission_builder import BuiltMission, PassPlan

#: Mission capacity assumed, items including home. ArduPilot stores 15 bytes per item in the
#: board's mission storage, so the figure depends on the board; 650 is what ArduPilot 4.5.4 SITL
#: accepts ("Only 650 items are supported"; sfap's simulator holds 724), typical of 16 KB storage
#: boards; boards that keep missions on the SD card (BRD_SD_MISSION) hold thousands. PX4 keeps
#: up to 2,000 items in its dataman (NUM_MISSIONS_SUPPORTED).
MAX_MISSION_ITEMS = {Autopilot.ARDUPILOT: 650, Autopilot.PX4: 2000}
#: How each autopilot is named to the user.
AUTOPILOT_NAMES = {Autopilot.ARDUPILOT: "ArduPilot", Autopilot.PX4: "PX4"}
#: The share of the area seen by three or more nadir frames a plan promises when its forward
#: overlap gives three views along a line (>= 2/3); the edges get them from the extra end
#: stations (planner.lines.END_STATIONS), so only the sampling and exclusions take from it.
STEREO_3_TARGET_PCT = 99.0


def summarize(
    *,
    spec: MissionSpec,
    frame: LocalFrame,
    area_m2: float,
    alt_agl_m: float,
    speed_m_s: float,
    nadir: PassPlan,
    passes: list[PassPlan],
    built: BuiltMission,
    warnings: tuple[str, ...],
    true_north_grid_deg: float,
    views: ViewShares,
    terrain: dict[str, object] | None = None,
) -> Summary:
    camera = spec.camera
    footprint = camera.footprint(alt_agl_m, spec.orientation)
    landscape = spec.orientation is Orientation.LANDSCAPE
    gsd_along = camera.gsd_y_cm(alt_agl_m) if landscape else camera.gsd_x_cm(alt_agl_m)
    gsd_across = camera.gsd_x_cm(alt_agl_m) if landscape else camera.gsd_y_cm(alt_agl_m)
    air_base = nadir.trigger_distance_m
    max_trigger = min(
        ex.max_speed_for_trigger_m_s(p.trigger_distance_m, camera.min_trigger_interval_s) for p in passes
    )
    blur_limits = [  # the limit the planner enforces, per pass
        ex.blur_speed_limit_m_s(
            camera, spec.orientation, spec.survey.max_blur_px,
            p.alt_agl_m if p.alt_agl_m is not None else alt_agl_m,
            p.tilt_deg, p.direction_deg, p.look_heading_deg,
        )
        for p in passes
    ]  # fmt: skip
    max_blur = min((b for b in blur_limits if b is not None), default=None)
    max_speed = min(max_trigger, max_blur) if max_blur is not None else max_trigger
    interval = ex.exposure_interval_s(air_base, speed_m_s)
    return Summary(
        name=spec.name,
        area_m2=area_m2,
        camera_id=camera.id,
        orientation=spec.orientation.value,
        gsd_cm=camera.gsd_cm(alt_agl_m),
        gsd_along_cm=gsd_along,
        gsd_across_cm=gsd_across,
        altitude_agl_m=alt_agl_m,
        scale_number=camera.scale_number(alt_agl_m),
        footprint_along_m=footprint.along_m,
        footprint_across_m=footprint.across_m,
        front_overlap_pct=spec.survey.front_overlap_pct,
        side_overlap_pct=spec.survey.side_overlap_pct,
        air_base_m=air_base,
        line_spacing_m=nadir.line_spacing_m,
        trigger_distance_m=air_base,
        exposure_interval_s=interval,
        speed_m_s=speed_m_s,
        max_speed_m_s=max_speed,
        max_speed_trigger_m_s=max_trigger,
        max_speed_blur_m_s=max_blur,
        base_height_ratio=ex.base_height_ratio(air_base, alt_agl_m),
        intersection_angle_deg=ex.intersection_angle_deg(air_base, alt_agl_m),
        depth_precision_m=ex.depth_precision_m(camera, air_base, alt_agl_m, spec.orientation),
        direction_deg=(nadir.direction_deg - true_north_grid_deg) % 180.0,
        pass_count=len(passes),
        line_count=sum(len({s.row for s in p.segments}) for p in passes),
        photo_count=len(built.stations),
        flight_distance_m=built.flight_distance_m,
        flight_time_s=built.flight_time_s,
        item_count=len(built.mission.items),
        max_item_count=MAX_MISSION_ITEMS[spec.vehicle.autopilot],
        stereo_seen_2_pct=views.seen_2_pct,
        stereo_seen_3_pct=views.seen_3_pct,
        stereo_seen_3_target_pct=stereo_3_target_pct(nadir.trigger_distance_m, nadir.rect.along_m),
        crs=f"EPSG:{frame.epsg}" if frame.epsg else frame.crs.to_string(),
        warnings=warnings,
        terrain=terrain,
        vehicle_parameters=tuple(
            r.to_dict()
            for r in required_parameters(built.mission.items, spec.vehicle.autopilot, spec.vehicle.type)
        ),
    )


def stereo_3_target_pct(air_base_m: float, frame_along_m: float) -> float:
    """The promised share seen by >= 3 frames: STEREO_3_TARGET_PCT when three frames of a line
    overlap (air base at most a third of the frame), else none."""
    return STEREO_3_TARGET_PCT if 3.0 * air_base_m <= frame_along_m + 1e-9 else 0.0


def one_battery_s(vehicle: VehicleSpec) -> tuple[float, str]:
    """The one battery model: the longest flight one battery allows (seconds) and what it comes
    from. ``endurance_s`` (or capacity over current) less the reserve when given, which is also
    what sorties are cut by (planner.sorties); else ``max_flight_time_min``."""
    usable = vehicle.usable_flight_s
    if usable is not None:
        assert vehicle.endurance_s is not None
        return usable, f"endurance_s = {vehicle.endurance_s:g} s less its reserve"
    return vehicle.max_flight_time_min * 60.0, f"max_flight_time_min = {vehicle.max_flight_time_min:g}"


def limit_warnings(
    *, vehicle: VehicleSpec, item_count: int, flight_time_s: float, sortie: bool = False
) -> list[str]:
    """What the vehicle cannot fly as the plan will be flown: too many items, too long a flight
    for one battery. A vehicle with an endurance flies a whole plan as sorties, each cut to fit
    both its battery and the autopilot's memory (planner.sorties), so only a sortie is judged
    (``sortie``); without one, the mission as planned."""
    if vehicle.endurance_s is not None and not sortie:
        return []
    out = []
    autopilot = vehicle.autopilot
    capacity = MAX_MISSION_ITEMS[autopilot]
    what = "this sortie" if sortie else "the mission"
    if item_count + 1 > capacity:  # + 1: home is item 0 on ArduPilot and counted by PX4 tools
        out.append(
            f"{what} has {item_count + 1} items with home, more than {AUTOPILOT_NAMES[autopilot]} holds "
            f"({capacity} on a board without mission storage on its SD card); give [vehicle] endurance_s "
            f"to fly it as sorties that each fit, split the area into smaller blocks, or fly it from a "
            f"vehicle that stores missions on its SD card"
        )
    battery_s, battery = one_battery_s(vehicle)
    minutes = flight_time_s / 60.0
    if flight_time_s > battery_s + 1e-6:
        flights = math.ceil(flight_time_s / battery_s)
        out.append(
            f"{what} takes {minutes:.0f} min ({minutes / 60.0:.1f} h), more than one battery "
            f"({battery_s / 60.0:.0f} min: {battery}); it needs at least {flights} flights: give [vehicle] "
            f"endurance_s to fly it as sorties, split the area, or raise max_flight_time_min if the "
            f"vehicle can"
            if not sortie
            else f"{what} takes {minutes:.0f} min, more than one battery ({battery_s / 60.0:.0f} min: "
            f"{battery})"
        )
    return out
