"""Planning a survey: from a mission spec to a :class:`~planner.plan.SurveyPlan`.

The steps, each in its own module:
1. area: load the polygons, remove holes and exclusions (planner.area), project into the
   area's UTM zone (planner.geo);
2. exposure: height from the GSD (Eq. 3-4), the frame's ground rectangle per pass, air base and
   line spacing (Eq. 3-5), speed checks (Eq. 3-6, blur) (planner.exposure, planner.footprint);
3. lines: camera-on segments per pass with guaranteed edge coverage (planner.lines);
4. route: boustrophedon order from the corner nearest the vehicle, transits around no-fly
   zones (planner.route);
5. mission: the items an autopilot flies, and every station exactly where the trigger plan
   fires it (planner.mission_builder).
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

from . import exposure as ex
from . import trigger as trig
from .area import build_area, check_area_size, load_polygons
from .camera import Orientation
from .coverage import ViewShares, view_shares
from .errors import AreaError, PlanningError, SpecError
from .fixed_wing import fixed_wing_for
from .footprint import near_far_gsd_cm, tilted_gsd_cm
from .geo import LocalFrame, geodesic_area_m2
from .lines import layout_pass, split_run
from .mission import HomePosition, VehicleType
from .mission_builder import PassPlan, build_mission
from .plan import FlightPass, PassKind, PlanLayout, SurveyPlan
from .spec import MissionSpec, TriggerMode
from .terrain import Dem
from .terrain_follow import TerrainSummary, apply_terrain

log = logging.getLogger(__name__)


@dataclass(frozen=True, kw_only=True)
class _PassDef:
    kind: PassKind
    name: str
    direction_deg: float
    tilt_deg: float
    look_heading_deg: float | None
    front_overlap_pct: float
    side_overlap_pct: float
    alt_agl_m: float | None = None  # a multi-scale pass at its own height ([[survey.scale]])


def plan_survey(spec: MissionSpec) -> SurveyPlan:
    """Plan the survey a spec describes. Raises SfapError subclasses with the fix."""
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
    return plan_polygons(spec, polygons, exclusions)


def plan_polygons(spec: MissionSpec, polygons: list[Polygon], exclusions: list[Polygon]) -> SurveyPlan:
    """Plan over polygons already loaded (lon/lat degrees); :func:`plan_survey` reads them from
    the spec's files."""
    survey = spec.survey
    vehicle = spec.vehicle
    camera = spec.camera
    warnings: list[str] = []

    # 1. area --------------------------------------------------------------------------------------
    area_lonlat, zones_lonlat = build_area(polygons, exclusions)
    if area_lonlat.is_empty:
        raise SpecError(f"{spec.area_path}: nothing is left of the area once the exclusions are removed")
    west, _, east, _ = area_lonlat.bounds
    if east - west > 180.0:
        raise AreaError(
            f"{spec.area_path}: the area spans longitudes {west:.4f} to {east:.4f}: it crosses the "
            f"antimeridian (180 degrees), which sfap does not plan across; split it at 180 degrees "
            f"and plan each side as its own mission"
        )
    centroid = area_lonlat.centroid
    frame = LocalFrame.utm_for(centroid.x, centroid.y)
    area_m2 = geodesic_area_m2(area_lonlat)
    check_area_size(area_m2, str(spec.area_path))
    area_xy = frame.geometry_to_xy(area_lonlat)
    zones_xy = tuple(frame.geometry_to_xy(z) for z in zones_lonlat)
    assert isinstance(area_xy, Polygon | MultiPolygon)

    # 2. height and GSD ----------------------------------------------------------------------------
    if survey.altitude_agl_m is not None:
        alt_agl_m = survey.altitude_agl_m
    else:
        assert survey.gsd_cm is not None
        alt_agl_m = camera.height_for_gsd_m(survey.gsd_cm)
    if alt_agl_m > vehicle.max_alt_agl_m + 1e-9:
        needed = f"{alt_agl_m:.1f} m above ground"
        raise SpecError(
            f"{spec.source}: that GSD needs a flying height of {needed}, above the vehicle limit "
            f"max_alt_agl_m = {vehicle.max_alt_agl_m:g} m; ask for a finer gsd_cm (at most "
            f"{camera.gsd_cm(vehicle.max_alt_agl_m):.2f} cm at the limit) or raise the limit"
        )
    gsd_cm = camera.gsd_cm(alt_agl_m)

    # home
    if vehicle.home_lat_deg is not None and vehicle.home_lon_deg is not None:
        home = HomePosition(
            lat_deg=vehicle.home_lat_deg,
            lon_deg=vehicle.home_lon_deg,
            alt_amsl_m=vehicle.home_alt_amsl_m,
        )
        hx, hy = frame.to_xy(home.lon_deg, home.lat_deg)
        home_xy = (float(hx), float(hy))
        if math.dist(home_xy, (area_xy.centroid.x, area_xy.centroid.y)) > 50_000:
            raise SpecError(
                f"{spec.source}: home {vehicle.home_lat_deg}, {vehicle.home_lon_deg} is more than "
                f"50 km from the area; home is [lat, lon]: check the order"
            )
    else:
        home_xy = _default_home(area_xy)
        lon, lat = frame.to_lonlat(*home_xy)
        home = HomePosition(lat_deg=float(lat), lon_deg=float(lon), alt_amsl_m=vehicle.home_alt_amsl_m)
    for zone in zones_xy:
        if zone.contains(shapely.Point(home_xy)):
            raise SpecError(f"{spec.source}: home lies inside an exclusion zone; move it out")

    # 3. passes --------------------------------------------------------------------------------
    # Bearings in the spec and in every output are true bearings; geometry uses grid bearings.
    true_north_grid = frame.true_north_grid_bearing_deg(centroid.x, centroid.y)
    if survey.direction_deg is not None:
        direction = (survey.direction_deg + true_north_grid) % 180.0
    else:
        direction = auto_direction_deg(area_xy)
    pass_defs = _pass_definitions(spec, direction, true_north_grid)
    if survey.scales:
        from .multiscale import scale_pass_defs

        if spec.terrain is not None:
            raise SpecError(
                f"{spec.source}: [[survey.scale]] passes are not planned over a [terrain] DEM yet; "
                f"plan each height as its own mission, or remove [terrain]"
            )
        pass_defs += [_PassDef(**fields) for fields in scale_pass_defs(spec, direction)]

    blocked_xy = (
        shapely.union_all([z.buffer(survey.exclusion_clearance_m) for z in zones_xy]) if zones_xy else None
    )
    warnings_before_passes = len(warnings)
    dem = _read_dem(spec, area_lonlat, home) if spec.terrain is not None else None
    scale = 1.0  # footprint scale at the highest ground under the frames (terrain following)
    for _attempt in range(_TERRAIN_ATTEMPTS):
        del warnings[warnings_before_passes:]
        used_scale = scale  # the footprint scale of the passes built in this attempt
        pass_plans, views, speed_m_s = _lay_out_passes(
            spec, pass_defs, area_xy, blocked_xy, alt_agl_m, gsd_cm, scale, warnings
        )
        # 4-5. route, mission and stations --------------------------------------------------------
        built = build_mission(
            spec=spec,
            frame=frame,
            home=home,
            home_xy=home_xy,
            alt_agl_m=alt_agl_m,
            speed_m_s=speed_m_s,
            passes=pass_plans,
            zones_xy=zones_xy,
            true_north_grid_deg=true_north_grid,
            fixed_wing=fixed_wing_for(spec, speed_m_s, true_north_grid),
        )
        terrain_summary = None
        if spec.terrain is None or dem is None:
            break
        built_t, home_t, terrain_summary = apply_terrain(
            built,
            dem=dem,
            terrain=spec.terrain,
            frame=frame,
            home=home,
            home_xy=home_xy,
            alt_agl_m=alt_agl_m,
            speed_m_s=speed_m_s,
            max_alt_agl_m=spec.vehicle.max_alt_agl_m,
            passes=pass_plans,
            camera=camera,
            footprint_scale=scale,
        )
        scale_needed = terrain_summary.footprint_scale_min
        if not spec.terrain.follow or scale_needed >= scale - 1e-3:
            break
        # Lines and triggers spaced for the highest ground in each footprint: plan again with
        # the frame shrunk to its size there (a little below, for the path's own changes).
        scale = max(0.05, scale_needed - 0.005)
    if terrain_summary is not None:
        built, home = built_t, home_t
        _judge_terrain_overlaps(spec, terrain_summary, warnings)

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
            lines=built.lines[p.index],
            near_gsd_cm=p.near_gsd_cm,
            far_gsd_cm=p.far_gsd_cm,
        )
        for p in pass_plans
    )

    from .summary import limit_warnings, stereo_3_target_pct, summarize  # reads the whole plan

    nadir_pass = pass_plans[0]
    if views.seen_2_pct < 100.0 - 1e-9:
        fix = "; raise front_overlap_pct to at least 50" if survey.front_overlap_pct < 50 else ""
        warnings.append(
            f"{100.0 - views.seen_2_pct:.2f} % of the area is seen by fewer than two nadir frames "
            f"(no stereo there){fix}"
        )
    elif views.edge_weak_points:
        warnings.append(
            f"{views.edge_weak_points} points along the area's edge (beside exclusions) are seen by "
            f"fewer than two nadir frames (no stereo there)"
        )
    target3 = stereo_3_target_pct(nadir_pass.trigger_distance_m, nadir_pass.rect.along_m)
    if views.seen_3_pct < target3:
        warnings.append(
            f"only {views.seen_3_pct:.1f} % of the area is seen by three or more nadir frames "
            f"(target {target3:g} %)"
        )
    warnings.extend(
        limit_warnings(
            autopilot=vehicle.autopilot,
            item_count=len(built.mission.items),
            flight_time_s=built.flight_time_s,
            max_flight_time_min=vehicle.max_flight_time_min,
        )
    )

    nadir = pass_plans[0]
    summary = summarize(
        spec=spec,
        frame=frame,
        area_m2=area_m2,
        alt_agl_m=alt_agl_m,
        speed_m_s=speed_m_s,
        nadir=nadir,
        passes=pass_plans,
        built=built,
        warnings=tuple(warnings),
        true_north_grid_deg=true_north_grid,
        views=views,
        terrain=terrain_summary.as_dict() if terrain_summary is not None else None,
    )
    for w in warnings:
        log.warning(w)
    return SurveyPlan(
        name=spec.name,
        camera=camera,
        orientation=spec.orientation,
        frame=frame,
        area_xy=area_xy,
        area_lonlat=area_lonlat,
        exclusions_xy=zones_xy,
        exclusions_lonlat=zones_lonlat,
        home=home,
        home_xy_m=home_xy,
        passes=passes,
        stations=built.stations,
        path_xy_m=built.path_xy_m,
        path_lonlat_deg=built.path_lonlat_deg,
        mission=built.mission,
        summary=summary,
        warnings=tuple(warnings),
        layout=PlanLayout(
            spec=spec,
            alt_agl_m=alt_agl_m,
            speed_m_s=speed_m_s,
            pass_plans=tuple(pass_plans),
            true_north_grid_deg=true_north_grid,
            dem=dem,
            footprint_scale=used_scale,
        ),
    )


#: Plans over a DEM with following: the first at the flat-ground spacing, then re-spaced for
#: the highest ground under the frames until the footprints cast on the DEM keep the overlaps.
_TERRAIN_ATTEMPTS = 4


def _lay_out_passes(
    spec: MissionSpec,
    pass_defs: list[_PassDef],
    area_xy: Polygon | MultiPolygon,
    blocked_xy: shapely.Geometry | None,
    alt_agl_m: float,
    gsd_cm: float,
    scale: float,
    warnings: list[str],
) -> tuple[list[PassPlan], ViewShares, float]:
    """Lines and stations of every pass; ``scale`` (<= 1) shrinks the frame rectangle to its
    size on the highest ground under the frames (1 over flat ground)."""
    survey = spec.survey
    camera = spec.camera
    speed_m_s = survey.speed_m_s
    pass_plans: list[PassPlan] = []
    views: ViewShares | None = None
    for index, pdef in enumerate(pass_defs):
        up = (
            pdef.look_heading_deg
            if pdef.look_heading_deg is not None
            else ex.up_bearing_deg(pdef.direction_deg, spec.orientation)
        )
        pass_alt_m = pdef.alt_agl_m if pdef.alt_agl_m is not None else alt_agl_m
        flat = ex.frame_rectangle(camera, pass_alt_m, pdef.direction_deg, up, pdef.tilt_deg)
        rect = ex.FrameRectangle(
            u_min_m=flat.u_min_m * scale, u_max_m=flat.u_max_m * scale,
            v_min_m=flat.v_min_m * scale, v_max_m=flat.v_max_m * scale,
        )  # fmt: skip
        trigger_m = ex.air_base_m(rect.along_m, pdef.front_overlap_pct)
        spacing_m = ex.air_base_m(rect.across_m, pdef.side_overlap_pct)
        speed_m_s = _check_speed(spec, pdef, trigger_m, pass_alt_m, speed_m_s, warnings)
        area_uv = _rotate(area_xy, pdef.direction_deg)
        blocked_uv = _rotate(blocked_xy, pdef.direction_deg) if blocked_xy is not None else None
        hover = survey.trigger is TriggerMode.HOVER
        step_m = trigger_m if hover else trig.station_step_m(trigger_m, speed_m_s)
        layout = layout_pass(area_uv, blocked_uv, rect, step_m, spacing_m)
        segments = layout.segments
        if not hover:
            segments = tuple(
                part
                for seg in segments
                for part in split_run(seg, trig.max_run_stations(seg.spacing_m, speed_m_s))
            )
        if layout.uncovered_m2 > 0:
            warnings.append(
                f"{pdef.name}: {layout.uncovered_m2:.0f} m2 beside exclusion zones cannot be seen "
                f"without flying over them"
            )
        if index == 0:
            views = view_shares(area_uv, segments, rect, trigger_m, spacing_m)
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
            )
        )
    assert views is not None
    return pass_plans, views, speed_m_s


def _read_dem(spec: MissionSpec, area_lonlat: Polygon | MultiPolygon, home: HomePosition) -> Dem:
    """Only the DEM around the area and home (with a margin for the turnarounds and footprints)."""
    assert spec.terrain is not None
    west, south, east, north = area_lonlat.bounds
    west, east = min(west, home.lon_deg), max(east, home.lon_deg)
    south, north = min(south, home.lat_deg), max(north, home.lat_deg)
    margin = 0.01
    return Dem.from_geotiff(
        spec.terrain.dem_path, bounds_lonlat=(west - margin, south - margin, east + margin, north + margin)
    )


def _judge_terrain_overlaps(spec: MissionSpec, terrain: TerrainSummary, warnings: list[str]) -> None:
    """The overlaps of the footprints cast on the DEM against the spec: gaps at constant altitude
    fail unless accepted; a shortfall is a warning."""
    assert spec.terrain is not None
    survey = spec.survey
    front, side = terrain.front_overlap_min_pct, terrain.side_overlap_min_pct
    figures = (
        f"over the DEM the frames overlap by as little as {front:.0f} % forward and {side:.0f} % side "
        f"(planned {survey.front_overlap_pct:g} % and {survey.side_overlap_pct:g} %; the stations are "
        f"{terrain.station_alt_agl_min_m:.1f} to {terrain.station_alt_agl_max_m:.1f} m above the ground)"
    )
    gaps = side < 0.0 or front < 0.0
    if not spec.terrain.follow and gaps and not spec.terrain.accept_overlap_loss:
        raise PlanningError(
            f"{spec.source}: {figures}: gaps open between the frames where the ground is high; set "
            f"follow = true in [terrain] (or fly higher), or set accept_overlap_loss = true in "
            f"[terrain] to fly it anyway"
        )
    if front < survey.front_overlap_pct - 1.0 or side < survey.side_overlap_pct - 1.0:
        fix = (
            "set follow = true in [terrain]" if not spec.terrain.follow else "lower tolerance_m in [terrain]"
        )
        warnings.append(f"{figures}{' (gaps between frames)' if gaps else ''}; {fix}")


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


def _default_home(area_xy: Polygon | MultiPolygon) -> tuple[float, float]:
    """No home given: the area's vertex nearest the south-west corner of its bounding box."""
    min_x, min_y, _, _ = area_xy.bounds
    polys = getattr(area_xy, "geoms", [area_xy])
    vertices = np.vstack([np.asarray(p.exterior.coords) for p in polys])
    k = int(np.argmin(np.hypot(vertices[:, 0] - min_x, vertices[:, 1] - min_y)))
    return float(vertices[k, 0]), float(vertices[k, 1])


def _pass_definitions(spec: MissionSpec, direction: float, true_north_grid: float) -> list[_PassDef]:
    """The passes to fly; ``direction`` is the nadir lines' grid bearing, look headings are
    turned from true to grid bearings with ``true_north_grid``."""
    s = spec.survey
    defs = [
        _PassDef(
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
            _PassDef(
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
                _PassDef(
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


def _check_speed(
    spec: MissionSpec,
    pdef: _PassDef,
    trigger_m: float,
    alt_agl_m: float,
    speed_m_s: float,
    warnings: list[str],
) -> float:
    """Refuse (or, with adjust_speed, lower) a speed the camera cannot keep up with."""
    camera = spec.camera
    if spec.survey.trigger is TriggerMode.HOVER:
        return speed_m_s
    limits = {"trigger": ex.max_speed_for_trigger_m_s(trigger_m, camera.min_trigger_interval_s)}
    if camera.shutter_s is not None:
        along_gsd = (
            min(near_far_gsd_cm(camera, alt_agl_m, pdef.tilt_deg))
            if pdef.tilt_deg
            else (
                camera.gsd_y_cm(alt_agl_m)
                if spec.orientation is Orientation.LANDSCAPE
                else camera.gsd_x_cm(alt_agl_m)
            )
        )
        limits["blur"] = ex.max_speed_for_blur_m_s(along_gsd, camera.shutter_s, spec.survey.max_blur_px)
    reason, limit = min(limits.items(), key=lambda kv: kv[1])
    if speed_m_s <= limit + 1e-9:
        return speed_m_s
    why = (
        f"the camera needs {camera.min_trigger_interval_s:g} s between photos and the {pdef.name} pass "
        f"triggers every {trigger_m:.1f} m"
        if reason == "trigger"
        else f"a {camera.shutter_s:g} s exposure blurs more than {spec.survey.max_blur_px:g} px above it"
    )
    safe = math.floor(limit * 10.0) / 10.0
    if spec.survey.adjust_speed:
        warnings.append(f"speed lowered from {speed_m_s:g} to {safe:g} m/s: {why}")
        return safe
    raise SpecError(
        f"{spec.source}: speed_m_s = {speed_m_s:g} is too fast: {why}, so at most {safe:g} m/s; "
        f"lower speed_m_s, lower the overlaps, or set adjust_speed = true"
    )


def _rotate(geom: shapely.Geometry, direction_deg: float) -> shapely.Geometry:
    def fn(coords: np.ndarray) -> np.ndarray:
        u, v = ex.to_pass_frame(coords[:, 0], coords[:, 1], direction_deg)
        return np.column_stack([u, v])

    return shapely.transform(geom, fn)
