"""Planning a block survey (polygons): from a mission spec to a :class:`~planner.plan.SurveyPlan`.

Where a change belongs (DESIGN.md, "The planner's flow"): a block's layout here; a corridor's in
planner.corridor; what both share in planner.survey_steps; the flight path and its items in
planner.mission_builder, planner.flight_path, planner.mission_items; what ``sfap plan`` does
around a plan (resume, sorties, files) in planner.plan_run.

The steps, each in its own module:
1. area: load the polygons, remove holes and exclusions (planner.area), project into the
   area's UTM zone (planner.geo);
2. exposure: height from the GSD (Eq. 3-4), the frame's ground rectangle per pass, air base and
   line spacing (Eq. 3-5), speed checks (Eq. 3-6, blur) (planner.exposure, planner.footprint);
3. lines: camera-on segments per pass with guaranteed edge coverage (planner.lines);
4. route: boustrophedon order from the corner nearest the vehicle, transits around no-fly
   zones (planner.route);
5. flight path: the lines in order, routed, turned and entered as the vehicle flies them
   (planner.mission_builder -> planner.flight_path), reshaped over a DEM
   (planner.terrain_follow), then read: every station exactly where the trigger plan fires
   it, the flight time, and the items an autopilot flies (planner.mission_items).

The steps a corridor shares (area, height, home, speed, terrain, the plan from the built
mission) are planner.survey_steps.
"""

from __future__ import annotations

import functools
import itertools
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

from . import exposure as ex
from . import survey_steps as steps
from . import trigger as trig
from .area import load_polygons
from .coverage import ViewShares, view_shares
from .errors import SpecError
from .estimate import PassGeometry, PlanEstimate, estimate, too_large
from .footprint import near_far_gsd_cm, tilted_gsd_cm
from .kinds import PassKind
from .limits import MAX_PHOTOS
from .lines import layout_pass
from .mission import VehicleType
from .mission_builder import BuiltMission, PassPlan
from .plan import FlightPass, PlanLayout, SurveyPlan
from .spec import MissionSpec, TriggerMode

if TYPE_CHECKING:  # the map's view is made only for a caller who asks (on_built)
    from .mapview import MapPlan

log = logging.getLogger(__name__)


def plan_survey(
    spec: MissionSpec,
    *,
    max_photos: int | None = MAX_PHOTOS,
    stage: Callable[[str], None] | None = None,
    on_built: Callable[[MapPlan], None] | None = None,
    announce: Callable[[PlanEstimate], None] | None = None,
) -> SurveyPlan:
    """Plan the survey a spec describes. Raises SfapError subclasses with the fix; a block
    estimated at more than ``max_photos`` photos is refused at once (planner.estimate; None: no
    limit). ``stage(what)`` is told each step of a block's planning as it starts (progress).
    ``on_built(view)`` and ``announce(estimate)``: see :func:`plan_polygons` (a corridor calls
    neither)."""
    survey = spec.survey
    vehicle = spec.vehicle
    if vehicle.type is VehicleType.FIXED_WING and survey.trigger is TriggerMode.HOVER:
        raise SpecError(
            f'{spec.source}: trigger = "hover" needs a vehicle that can hover; use '
            f'trigger = "distance" for a fixed-wing'
        )

    if spec.corridor_width_m is not None:
        from .corridor import plan_corridor

        return plan_corridor(spec)
    polygons = load_polygons(spec.area_path)
    exclusions = [p for path in spec.exclude_paths for p in load_polygons(path)]
    return plan_polygons(
        spec, polygons, exclusions, max_photos=max_photos, stage=stage, on_built=on_built, announce=announce
    )


def estimate_survey(spec: MissionSpec) -> PlanEstimate | None:
    """The plan's estimate from its geometry alone (planner.estimate); None for a corridor."""
    if spec.corridor_width_m is not None:
        return None
    polygons = load_polygons(spec.area_path)
    exclusions = [p for path in spec.exclude_paths for p in load_polygons(path)]
    site = steps.project_area(spec, polygons, exclusions, what="area")
    alt_agl_m, _ = steps.flying_height(spec)
    return estimate(spec, site.area_xy, _pass_geometry(spec, _all_pass_defs(spec, site), alt_agl_m))


def _all_pass_defs(spec: MissionSpec, site: steps.ProjectedArea) -> list[steps.PassDef]:
    """Every pass of the block: nadir, crosshatch, obliques, then the [[survey.scale]] passes."""
    survey = spec.survey
    true_north_grid = site.true_north_grid_deg
    if survey.direction_deg is not None:
        direction = (survey.direction_deg + true_north_grid) % 180.0
    else:
        direction = auto_direction_deg(site.area_xy)
    pass_defs = _pass_definitions(spec, direction, true_north_grid)
    if survey.scales:
        from .multiscale import scale_pass_defs

        if spec.terrain is not None:
            raise SpecError(
                f"{spec.source}: [[survey.scale]] passes are not planned over a [terrain] DEM yet; "
                f"plan each height as its own mission, or remove [terrain]"
            )
        alt_agl_m, _ = steps.flying_height(spec)
        pass_defs += [steps.PassDef(**fields) for fields in scale_pass_defs(spec, direction, alt_agl_m)]
    return pass_defs


def _pass_geometry(spec: MissionSpec, pass_defs: list[steps.PassDef], alt_agl_m: float) -> list[PassGeometry]:
    out = []
    for pdef in pass_defs:
        up = (
            pdef.look_heading_deg
            if pdef.look_heading_deg is not None
            else ex.up_bearing_deg(pdef.direction_deg, spec.orientation)
        )
        pass_alt_m = pdef.alt_agl_m if pdef.alt_agl_m is not None else alt_agl_m
        rect = ex.frame_rectangle(spec.camera, pass_alt_m, pdef.direction_deg, up, pdef.tilt_deg)
        out.append(
            PassGeometry(
                direction_deg=pdef.direction_deg, rect=rect, front_overlap_pct=pdef.front_overlap_pct,
                side_overlap_pct=pdef.side_overlap_pct,
            )
        )  # fmt: skip
    return out


def plan_polygons(
    spec: MissionSpec,
    polygons: list[Polygon],
    exclusions: list[Polygon],
    *,
    max_photos: int | None = MAX_PHOTOS,
    stage: Callable[[str], None] | None = None,
    on_built: Callable[[MapPlan], None] | None = None,
    announce: Callable[[PlanEstimate], None] | None = None,
) -> SurveyPlan:
    """Plan over polygons already loaded (lon/lat degrees); :func:`plan_survey` reads them from
    the spec's files. ``announce(estimate)`` is given the block's estimate (planner.estimate,
    the same as :func:`estimate_survey`'s) before its lines are laid out, and before a block
    beyond ``max_photos`` is refused. ``on_built(view)`` is given the map's view of the plan
    (:func:`planner.mapview.map_geometry`: its header and caption still empty) as soon as the
    mission is built, before the coverage figures and the summary are made: `sfap plan` starts
    drawing map.png with it."""
    survey = spec.survey
    warnings: list[str] = []

    # 1. area and 2. height, GSD and home -----------------------------------------------------------
    site = steps.project_area(spec, polygons, exclusions, what="area")
    area_xy = site.area_xy
    alt_agl_m, gsd_cm = steps.flying_height(spec)
    home, home_xy = steps.home_position(
        spec, site, near=area_xy.centroid, default_xy=lambda: steps.default_home_xy(area_xy), what="area"
    )

    # 3. passes ---------------------------------------------------------------------------------
    # Bearings in the spec and in every output are true bearings; geometry uses grid bearings.
    true_north_grid = site.true_north_grid_deg
    pass_defs = _all_pass_defs(spec, site)
    guess = estimate(spec, area_xy, _pass_geometry(spec, pass_defs, alt_agl_m))
    log.info("estimate: %s", guess.text())
    if announce is not None:
        announce(guess)
    refusal = too_large(spec, guess, max_photos) if max_photos is not None else None
    if refusal is not None:
        raise SpecError(refusal)

    blocked_xy = steps.blocked_xy(spec, site.zones_xy)
    dem = steps.read_dem(spec, site.area_lonlat, home) if spec.terrain is not None else None

    def step(what: str) -> None:
        if stage is not None:
            stage(what)

    def attempt(scale: float) -> _Attempt:
        del warnings[:]
        step(f"laying out the lines of {len(pass_defs)} pass{'es' if len(pass_defs) != 1 else ''}")
        pass_plans, count_views, speed_m_s = _lay_out_passes(
            spec, pass_defs, area_xy, blocked_xy, alt_agl_m, gsd_cm, scale, warnings
        )
        # 4-5. route, mission and stations --------------------------------------------------------
        step("building the flight path, its stations and items")
        built = steps.build(
            spec, site, home, home_xy, alt_agl_m=alt_agl_m, speed_m_s=speed_m_s, passes=pass_plans
        )
        return _Attempt(built=built, terrain_passes=pass_plans, count_views=count_views, speed_m_s=speed_m_s)

    laid, fit = steps.fit_to_terrain(
        spec, site, home, home_xy, alt_agl_m=alt_agl_m, dem=dem, attempt=attempt, warnings=warnings
    )
    step("the summary")
    pass_plans = laid.terrain_passes
    passes = tuple(
        FlightPass(
            index=p.index,
            kind=p.kind,
            name=p.name,
            direction_deg=(p.direction_deg - true_north_grid) % 180.0,
            tilt_deg=p.tilt_deg,
            look_heading_deg=(
                None if p.look_heading_deg is None else (p.look_heading_deg - true_north_grid) % 360.0
            ),
            alt_agl_m=p.alt_agl_m if p.alt_agl_m is not None else alt_agl_m,
            line_spacing_m=p.line_spacing_m,
            trigger_distance_m=p.trigger_distance_m,
            lines=fit.built.lines[p.index],
            near_gsd_cm=p.near_gsd_cm,
            far_gsd_cm=p.far_gsd_cm,
        )
        for p in pass_plans
    )
    if on_built is not None:
        from .mapview import map_geometry

        on_built(
            map_geometry(
                name=spec.name,
                home_xy_m=home_xy,
                area_xy=site.area_xy,
                exclusions_xy=site.zones_xy,
                passes=passes,
                stations=fit.built.stations,
                path_xy_m=fit.built.path_xy_m,
            )
        )
    fix = "; raise front_overlap_pct to at least 50" if survey.front_overlap_pct < 50 else ""
    return steps.finish_plan(
        spec,
        site,
        laid,
        fit,
        home_xy,
        alt_agl_m=alt_agl_m,
        flight_passes=passes,
        warnings=warnings,
        what="area",
        frames="nadir frames",
        few_views_note=f" (no stereo there){fix}",
        logger=log,
        layout=PlanLayout(
            spec=spec,
            alt_agl_m=alt_agl_m,
            speed_m_s=laid.speed_m_s,
            pass_plans=tuple(pass_plans),
            true_north_grid_deg=true_north_grid,
            dem=dem,
            footprint_scale=fit.footprint_scale,
        ),
    )


@dataclass(frozen=True, kw_only=True)
class _Attempt:
    """The passes of a block laid out at one footprint scale and built (planner.survey_steps)."""

    built: BuiltMission
    terrain_passes: list[PassPlan]
    count_views: Callable[[], ViewShares]  # the first pass's (planner.coverage.view_shares)
    speed_m_s: float

    @functools.cached_property
    def views(self) -> ViewShares:
        """The first pass's coverage figures, counted when first asked for: after the mission
        is built (the map is started first), and only for the attempt kept."""
        return self.count_views()


def _lay_out_passes(
    spec: MissionSpec,
    pass_defs: list[steps.PassDef],
    area_xy: Polygon | MultiPolygon,
    blocked_xy: shapely.Geometry | None,
    alt_agl_m: float,
    gsd_cm: float,
    scale: float,
    warnings: list[str],
) -> tuple[list[PassPlan], Callable[[], ViewShares], float]:
    """Lines and stations of every pass, and what the first pass's coverage figures are counted
    from; ``scale`` (<= 1) shrinks the frame rectangle to its size on the highest ground under
    the frames (1 over flat ground)."""
    survey = spec.survey
    camera = spec.camera
    speed_m_s = survey.speed_m_s
    pass_plans: list[PassPlan] = []
    views: Callable[[], ViewShares] | None = None
    for index, pdef in enumerate(pass_defs):
        up = (
            pdef.look_heading_deg
            if pdef.look_heading_deg is not None
            else ex.up_bearing_deg(pdef.direction_deg, spec.orientation)
        )
        pass_alt_m = pdef.alt_agl_m if pdef.alt_agl_m is not None else alt_agl_m
        rect = ex.frame_rectangle(camera, pass_alt_m, pdef.direction_deg, up, pdef.tilt_deg).scaled(scale)
        trigger_m = ex.air_base_m(rect.along_m, pdef.front_overlap_pct)
        spacing_m = ex.air_base_m(rect.across_m, pdef.side_overlap_pct)
        speed_m_s = steps.check_speed(spec, pdef, trigger_m, pass_alt_m, speed_m_s, warnings)
        area_uv = ex.geometry_to_pass_frame(area_xy, pdef.direction_deg)
        blocked_uv = (
            ex.geometry_to_pass_frame(blocked_xy, pdef.direction_deg) if blocked_xy is not None else None
        )
        hover = survey.trigger is TriggerMode.HOVER
        step_m = trigger_m if hover else trig.station_step_m(trigger_m, speed_m_s)
        layout = layout_pass(area_uv, blocked_uv, rect, step_m, spacing_m)
        segments = layout.segments if hover else trig.split_for_trigger(layout.segments, speed_m_s)
        if layout.uncovered_m2 > 0:
            warnings.append(
                f"{pdef.name}: {layout.uncovered_m2:.0f} m2 beside exclusion zones cannot be seen "
                f"without flying over them"
            )
        if index == 0:
            views = functools.partial(view_shares, area_uv, segments, rect, trigger_m, spacing_m)
        near_gsd, far_gsd = near_far_gsd_cm(camera, pass_alt_m, pdef.tilt_deg)
        pass_plans.append(
            PassPlan(
                index=index,
                kind=pdef.kind,
                name=pdef.name,
                direction_deg=pdef.direction_deg,
                tilt_deg=pdef.tilt_deg,
                look_heading_deg=pdef.look_heading_deg,
                rect=rect,
                trigger_distance_m=trigger_m,
                line_spacing_m=spacing_m,
                segments=segments,
                near_gsd_cm=near_gsd,
                far_gsd_cm=far_gsd,
                centre_gsd_cm=(
                    gsd_cm if pdef.tilt_deg == 0 else max(tilted_gsd_cm(camera, alt_agl_m, pdef.tilt_deg))
                )
                if pdef.alt_agl_m is None
                else camera.gsd_cm(pdef.alt_agl_m),
                alt_agl_m=pdef.alt_agl_m,
                front_overlap_pct=pdef.front_overlap_pct,
                side_overlap_pct=pdef.side_overlap_pct,
            )
        )
    assert views is not None
    return pass_plans, views, speed_m_s


def auto_direction_deg(area_xy: Polygon | MultiPolygon) -> float:
    """Bearing of the lines that minimizes their number: parallel to the edge of the convex hull
    across which the area is narrowest (rotating calipers); ties go to the longest edge."""
    hull = area_xy.convex_hull
    coords = np.asarray(hull.exterior.coords)
    best: tuple[float, float, float] = (math.inf, 0.0, 0.0)  # (width, -edge length, bearing)
    for (x0, y0), (x1, y1) in itertools.pairwise(coords):
        length = math.hypot(x1 - x0, y1 - y0)
        if length < 1e-6:
            continue
        bearing = math.degrees(math.atan2(x1 - x0, y1 - y0)) % 180.0
        _, v = ex.to_pass_frame(coords[:, 0], coords[:, 1], bearing)
        width = float(v.max() - v.min())
        key = (round(width, 3), -length, bearing)
        if key < best:
            best = key
    return best[2]


def _pass_definitions(spec: MissionSpec, direction: float, true_north_grid: float) -> list[steps.PassDef]:
    """The passes to fly; ``direction`` is the nadir lines' grid bearing, look headings are
    turned from true to grid bearings with ``true_north_grid``."""
    s = spec.survey
    defs = [
        steps.PassDef(
            kind=PassKind.NADIR,
            name="nadir",
            direction_deg=direction % 180.0,
            tilt_deg=0.0,
            look_heading_deg=None,
            front_overlap_pct=s.front_overlap_pct,
            side_overlap_pct=s.side_overlap_pct,
        )
    ]
    if s.crosshatch:
        defs.append(
            steps.PassDef(
                kind=PassKind.CROSSHATCH,
                name="crosshatch",
                direction_deg=(direction + 90.0) % 180.0,
                tilt_deg=0.0,
                look_heading_deg=None,
                front_overlap_pct=s.front_overlap_pct,
                side_overlap_pct=s.side_overlap_pct,
            )
        )
    for oblique in s.oblique:
        for true_heading in oblique.headings_deg:
            heading = (true_heading + true_north_grid) % 360.0
            # Lines parallel or perpendicular to the look direction (the frame's trapezoid is then
            # symmetric about the line axis), whichever is closer to the nadir direction.
            options = [heading % 180.0, (heading + 90.0) % 180.0]
            line_dir = min(
                options,
                key=lambda d: min(abs(d - direction % 180.0), 180 - abs(d - direction % 180.0)),
            )
            defs.append(
                steps.PassDef(
                    kind=PassKind.OBLIQUE,
                    name=f"oblique {oblique.tilt_deg:g} deg looking {true_heading:g} deg",
                    direction_deg=line_dir,
                    tilt_deg=oblique.tilt_deg,
                    look_heading_deg=heading,
                    front_overlap_pct=(
                        s.oblique_front_overlap_pct
                        if s.oblique_front_overlap_pct is not None
                        else s.front_overlap_pct
                    ),
                    side_overlap_pct=(
                        s.oblique_side_overlap_pct
                        if s.oblique_side_overlap_pct is not None
                        else s.side_overlap_pct
                    ),
                )
            )
    return defs
