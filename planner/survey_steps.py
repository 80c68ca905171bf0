"""The steps every survey plan takes, whatever the shape of its area: a block of polygons
(:mod:`planner.survey`) or a corridor along a centre line (:mod:`planner.corridor`).

1. :func:`project_area`: the area less its exclusions, projected into a local frame, its true
   area checked;
2. :func:`flying_height`: the height above ground from the GSD (or as given) against the
   vehicle's limit; :func:`home_position`: home as given (or a default), away from exclusions;
3. :func:`check_speed`: the speed a pass's trigger distance and the shutter allow;
4. :func:`build`: the mission and its stations from laid-out passes, and
   :func:`fit_to_terrain`: planned again over a DEM until the footprints keep the overlaps;
5. :func:`finish_plan`: the warnings a plan always checks (views, autopilot limits), the
   summary and the :class:`~planner.plan.SurveyPlan` from the built mission.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol, TypeVar

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

from . import exposure as ex
from .area import build_area, check_area_size
from .coverage import ViewShares
from .errors import AreaError, PlanningError, SpecError
from .fixed_wing import fixed_wing_for
from .geo import LocalFrame, geodesic_area_m2, geodesic_distance_m
from .kinds import PassKind
from .mission import HomePosition
from .mission_builder import BuiltMission, PassPlan, build_mission
from .plan import FlightPass, PlanLayout, SurveyPlan
from .spec import MissionSpec, TriggerMode
from .terrain import Dem
from .terrain_follow import CastOverlap, TerrainSummary, apply_terrain

log = logging.getLogger(__name__)

#: Plans over a DEM with following: the first at the flat-ground spacing, then re-spaced for
#: the highest ground under the frames until the footprints cast on the DEM keep the overlaps.
TERRAIN_ATTEMPTS = 6
#: Home farther than this from the area is taken for a mistake (lat and lon swapped), metres.
MAX_HOME_DISTANCE_M = 50_000.0


@dataclass(frozen=True, kw_only=True)
class PassDef:
    """One pass to lay out: its line bearing (grid, degrees), camera tilt and look heading
    (grid, degrees; None: along the lines' up direction), overlaps (percent)."""

    kind: PassKind
    name: str
    direction_deg: float
    tilt_deg: float
    look_heading_deg: float | None
    front_overlap_pct: float
    side_overlap_pct: float
    alt_agl_m: float | None = None  # a multi-scale pass at its own height ([[survey.scale]])


@dataclass(frozen=True, kw_only=True)
class ProjectedArea:
    """The area to survey and its exclusions, in lon/lat degrees and in ``frame`` (metres)."""

    frame: LocalFrame
    area_lonlat: Polygon | MultiPolygon
    area_xy: Polygon | MultiPolygon
    zones_lonlat: tuple[Polygon, ...]
    zones_xy: tuple[Polygon, ...]
    area_m2: float  # geodesic
    true_north_grid_deg: float  # grid bearing of true north at the area's centroid


def project_area(
    spec: MissionSpec,
    polygons_lonlat: Sequence[Polygon | MultiPolygon],
    exclusions_lonlat: Sequence[Polygon],
    *,
    what: str,
    frame: LocalFrame | None = None,
) -> ProjectedArea:
    """The polygons' union less holes and exclusions, in ``frame`` (default: the UTM zone of the
    area's centroid). ``what`` names the area in messages ("area", "corridor")."""
    area_lonlat, zones_lonlat = build_area(polygons_lonlat, exclusions_lonlat)
    if area_lonlat.is_empty:
        raise SpecError(f"{spec.area_path}: nothing is left of the {what} once the exclusions are removed")
    west, _, east, _ = area_lonlat.bounds
    if east - west > 180.0:
        raise AreaError(
            f"{spec.area_path}: the {what} spans longitudes {west:.4f} to {east:.4f}: it crosses the "
            f"antimeridian (180 degrees), which sfap does not plan across; split it at 180 degrees "
            f"and plan each side as its own mission"
        )
    centroid = area_lonlat.centroid
    if frame is None:
        frame = LocalFrame.utm_for(centroid.x, centroid.y)
    area_m2 = geodesic_area_m2(area_lonlat)
    check_area_size(area_m2, str(spec.area_path))
    area_xy = frame.geometry_to_xy(area_lonlat)
    assert isinstance(area_xy, Polygon | MultiPolygon)
    return ProjectedArea(
        frame=frame,
        area_lonlat=area_lonlat,
        area_xy=area_xy,
        zones_lonlat=zones_lonlat,
        zones_xy=tuple(frame.geometry_to_xy(z) for z in zones_lonlat),
        area_m2=area_m2,
        true_north_grid_deg=frame.true_north_grid_bearing_deg(centroid.x, centroid.y),
    )


def flying_height(spec: MissionSpec) -> tuple[float, float]:
    """``(alt_agl_m, gsd_cm)``: the height above ground the spec asks for (from its GSD, Eq. 3-4,
    or as given) and the GSD there; refused above the vehicle's max_alt_agl_m."""
    survey, vehicle, camera = spec.survey, spec.vehicle, spec.camera
    if survey.altitude_agl_m is not None:
        alt_agl_m = survey.altitude_agl_m
    else:
        assert survey.gsd_cm is not None
        alt_agl_m = camera.height_for_gsd_m(survey.gsd_cm)
    if alt_agl_m > vehicle.max_alt_agl_m + 1e-9:
        limit = f"the vehicle limit max_alt_agl_m = {vehicle.max_alt_agl_m:g} m"
        if survey.altitude_agl_m is not None:
            raise SpecError(
                f"{spec.source}: altitude_agl_m = {survey.altitude_agl_m:g} is above {limit}; ask for "
                f"altitude_agl_m = {vehicle.max_alt_agl_m:g} or lower (a GSD of "
                f"{camera.gsd_cm(vehicle.max_alt_agl_m):.2f} cm there) or raise the limit"
            )
        raise SpecError(
            f"{spec.source}: gsd_cm = {survey.gsd_cm:g} needs a flying height of {alt_agl_m:.1f} m above "
            f"ground, above {limit}; ask for a finer gsd_cm (at most "
            f"{camera.gsd_cm(vehicle.max_alt_agl_m):.2f} cm at the limit) or raise the limit"
        )
    return alt_agl_m, camera.gsd_cm(alt_agl_m)


def home_position(
    spec: MissionSpec,
    site: ProjectedArea,
    *,
    near: shapely.Geometry,
    default_xy: Callable[[], tuple[float, float]],
    what: str,
) -> tuple[HomePosition, tuple[float, float]]:
    """Home (lon/lat and in the site's frame): the vehicle's, refused farther than
    MAX_HOME_DISTANCE_M from ``near``, else ``default_xy()``; never inside an exclusion zone."""
    vehicle = spec.vehicle
    frame = site.frame
    if vehicle.home_lat_deg is not None and vehicle.home_lon_deg is not None:
        home = HomePosition(
            lat_deg=vehicle.home_lat_deg, lon_deg=vehicle.home_lon_deg, alt_amsl_m=vehicle.home_alt_amsl_m
        )
        hx, hy = frame.to_xy(home.lon_deg, home.lat_deg)
        home_xy = (float(hx), float(hy))
        if near.distance(shapely.Point(home_xy)) > MAX_HOME_DISTANCE_M:
            raise SpecError(_far_home_message(spec, frame, near, what))
    else:
        home_xy = default_xy()
        lon, lat = frame.to_lonlat(*home_xy)
        home = HomePosition(lat_deg=float(lat), lon_deg=float(lon), alt_amsl_m=vehicle.home_alt_amsl_m)
    for zone in site.zones_xy:
        if zone.contains(shapely.Point(home_xy)):
            raise SpecError(f"{spec.source}: home lies inside an exclusion zone; move it out")
    return home, home_xy


def _far_home_message(spec: MissionSpec, frame: LocalFrame, near: shapely.Geometry, what: str) -> str:
    """Home too far from the area. When the two meet with latitude and longitude swapped in one
    of them (an area file written [lat, lon], or home written [lon, lat]: the geometry cannot
    tell which), say so and show how each was read, so the one written the other way is found."""
    vehicle = spec.vehicle
    assert vehicle.home_lat_deg is not None and vehicle.home_lon_deg is not None
    lat, lon = vehicle.home_lat_deg, vehicle.home_lon_deg
    centre = near.centroid
    c_lon, c_lat = (float(v) for v in frame.to_lonlat(centre.x, centre.y))
    lead = (
        f"{spec.source}: home {lat:g}, {lon:g} is more than {MAX_HOME_DISTANCE_M / 1000:g} km from the {what}"
    )
    read = (
        f"the {what} file's positions must be [lon, lat] (its centre was read as lon {c_lon:.5f}, lat "
        f"{c_lat:.5f}) and home = [lat, lon] in the spec"
    )
    if abs(c_lon) <= 90.0 and geodesic_distance_m(lat, lon, c_lon, c_lat) < MAX_HOME_DISTANCE_M:
        return (
            f"{lead}; they meet with latitude and longitude swapped in one of them: {read}; swap the "
            f"one written the other way"
        )
    return f"{lead}: {read}; check both"


def default_home_xy(area_xy: Polygon | MultiPolygon) -> tuple[float, float]:
    """No home given: the area's vertex nearest the south-west corner of its bounding box."""
    min_x, min_y, _, _ = area_xy.bounds
    polys = getattr(area_xy, "geoms", [area_xy])
    vertices = np.vstack([np.asarray(p.exterior.coords) for p in polys])
    k = int(np.argmin(np.hypot(vertices[:, 0] - min_x, vertices[:, 1] - min_y)))
    return float(vertices[k, 0]), float(vertices[k, 1])


def blocked_xy(spec: MissionSpec, zones_xy: Sequence[Polygon]) -> shapely.Geometry | None:
    """Where no line may fly: the exclusion zones grown by the spec's clearance (None: none)."""
    if not zones_xy:
        return None
    return shapely.union_all([z.buffer(spec.survey.exclusion_clearance_m) for z in zones_xy])


def check_speed(
    spec: MissionSpec,
    pdef: PassDef,
    trigger_m: float,
    alt_agl_m: float,
    speed_m_s: float,
    warnings: list[str],
) -> float:
    """Refuse (or, with adjust_speed, lower) a speed the camera cannot keep up with: the
    trigger distance over the camera's shortest interval (Eq. 3-6) and, with a shutter time,
    the blur limit."""
    camera = spec.camera
    if spec.survey.trigger is TriggerMode.HOVER:
        return speed_m_s
    limits = {"trigger": ex.max_speed_for_trigger_m_s(trigger_m, camera.min_trigger_interval_s)}
    blur = ex.blur_speed_limit_m_s(
        camera, spec.orientation, spec.survey.max_blur_px, alt_agl_m, pdef.tilt_deg, pdef.direction_deg,
        pdef.look_heading_deg,
    )  # fmt: skip
    if blur is not None:
        limits["blur"] = blur
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


def build(
    spec: MissionSpec,
    site: ProjectedArea,
    home: HomePosition,
    home_xy: tuple[float, float],
    *,
    alt_agl_m: float,
    speed_m_s: float,
    passes: list[PassPlan],
) -> BuiltMission:
    """The mission and its stations for passes laid out in the site's frame (route, no-fly
    transits and a fixed-wing's turns: planner.mission_builder)."""
    tng = site.true_north_grid_deg
    return build_mission(
        spec=spec, frame=site.frame, home=home, home_xy=home_xy, alt_agl_m=alt_agl_m, speed_m_s=speed_m_s,
        passes=passes, zones_xy=site.zones_xy, true_north_grid_deg=tng,
        fixed_wing=fixed_wing_for(spec, speed_m_s, tng),
    )  # fmt: skip


def read_dem(spec: MissionSpec, area_lonlat: Polygon | MultiPolygon, home: HomePosition) -> Dem:
    """Only the DEM around the area and home (with a margin for the turnarounds and footprints)."""
    assert spec.terrain is not None
    west, south, east, north = area_lonlat.bounds
    west, east = min(west, home.lon_deg), max(east, home.lon_deg)
    south, north = min(south, home.lat_deg), max(north, home.lat_deg)
    margin = 0.01
    return Dem.from_geotiff(
        spec.terrain.dem_path, bounds_lonlat=(west - margin, south - margin, east + margin, north + margin)
    )


class Attempt(Protocol):
    """One layout of a plan at a footprint scale, built into a mission."""

    @property
    def built(self) -> BuiltMission: ...  # stations numbered by the passes below

    @property
    def terrain_passes(self) -> list[PassPlan]: ...  # the passes terrain overlaps are judged by

    @property
    def speed_m_s(self) -> float: ...

    @property
    def views(self) -> ViewShares: ...  # of the first pass (a corridor: of all its pieces)


A = TypeVar("A", bound=Attempt)


@dataclass(frozen=True, kw_only=True)
class TerrainFit:
    """What :func:`fit_to_terrain` settled on: the built mission (over the DEM when there is
    one), home (its ground elevation from the DEM), the terrain figures and the footprint scale
    the passes were laid out with (1 over flat ground)."""

    built: BuiltMission
    home: HomePosition
    terrain: TerrainSummary | None
    footprint_scale: float


def fit_to_terrain(
    spec: MissionSpec,
    site: ProjectedArea,
    home: HomePosition,
    home_xy: tuple[float, float],
    *,
    alt_agl_m: float,
    dem: Dem | None,
    attempt: Callable[[float], A],
    warnings: list[str],
) -> tuple[A, TerrainFit]:
    """Lay out and build with ``attempt(footprint_scale)``; over a DEM with following, again
    with the frame shrunk to its size on the highest ground under the frames (a little below,
    for the path's own changes) until the footprints cast on the DEM keep the overlaps (at most
    TERRAIN_ATTEMPTS times). The overlaps over the DEM are then judged
    (:func:`judge_terrain_overlaps`). ``attempt`` resets the warnings it adds."""
    scale = 1.0
    terrain_summary = None
    for _ in range(TERRAIN_ATTEMPTS):
        used_scale = scale
        laid = attempt(scale)
        built = laid.built
        terrain_summary = None
        if spec.terrain is None or dem is None:
            break
        built_t, home_t, terrain_summary = apply_terrain(
            built, dem=dem, terrain=spec.terrain, frame=site.frame, home=home, home_xy=home_xy,
            alt_agl_m=alt_agl_m, speed_m_s=laid.speed_m_s, max_alt_agl_m=spec.vehicle.max_alt_agl_m,
            passes=laid.terrain_passes, camera=spec.camera, footprint_scale=scale,
        )  # fmt: skip
        if not spec.terrain.follow:
            break  # constant altitude: the overlaps are judged as they come
        smaller = []
        needed = terrain_summary.footprint_scale_min
        if needed < scale - 1e-3:
            smaller.append(needed - 0.005)
        for got, want in _overlap_shortfalls(laid.terrain_passes, built_t.cast_overlaps):
            # the bases scale with the frame: 1 - B s' / D = want where 1 - B s / D = got
            smaller.append(scale * (1.0 - (want + OVERLAP_AIM_PCT) / 100.0) / (1.0 - got / 100.0))
        if not smaller:
            break
        scale = max(0.05, min(smaller))
    if terrain_summary is not None:
        built, home = built_t, home_t
        judge_terrain_overlaps(
            spec, laid.terrain_passes, built.cast_overlaps, terrain_summary, site.frame, warnings
        )
    return laid, TerrainFit(built=built, home=home, terrain=terrain_summary, footprint_scale=used_scale)


#: Over a DEM, lines and triggers are spaced for this much more overlap than the spec asks
#: (percentage points), so that the overlaps the footprints cast on the DEM keep hold.
OVERLAP_AIM_PCT = 0.5


def _overlap_shortfalls(
    passes: Sequence[PassPlan], overlaps: Sequence[CastOverlap]
) -> list[tuple[float, float]]:
    """(achieved, asked) for every overlap of a nadir pass cast on the DEM that falls short."""
    wanted = {p.index: (p.front_overlap_pct, p.side_overlap_pct) for p in passes}
    out: list[tuple[float, float]] = []
    for o in overlaps:
        front, side = wanted.get(o.pass_index, (None, None))
        if front is not None and o.front_pct < front:
            out.append((o.front_pct, front))
        if side is not None and o.side_pct < side:
            out.append((o.side_pct, side))
    return out


def judge_terrain_overlaps(
    spec: MissionSpec,
    passes: Sequence[PassPlan],
    overlaps: Sequence[CastOverlap],
    terrain: TerrainSummary,
    frame: LocalFrame,
    warnings: list[str],
) -> None:
    """The overlaps of the footprints cast on the DEM against the spec, pass by pass: where one
    falls short of what the spec asks, planning fails with where and by how much, unless the
    spec accepts it (``accept_overlap_loss``), then it is a warning."""
    assert spec.terrain is not None
    names = {p.index: p.name for p in passes}
    wanted = {p.index: (p.front_overlap_pct, p.side_overlap_pct) for p in passes}
    short: list[str] = []
    for o in overlaps:
        front, side = wanted.get(o.pass_index, (None, None))
        for what, got, want, xy in (
            ("forward", o.front_pct, front, o.front_xy),
            ("side", o.side_pct, side, o.side_xy),
        ):
            if want is None or got >= want - OVERLAP_TOLERANCE_PCT or xy is None:
                continue
            lon, lat = frame.to_lonlat(xy[0], xy[1])
            gap = " (a gap between the frames)" if got < 0.0 else ""
            short.append(
                f"the {names.get(o.pass_index, 'nadir')} pass overlaps by {got:.1f} % {what}{gap}, "
                f"{want - got:.1f} points below the {want:g} % asked, between the frames around lon "
                f"{float(lon):.6f}, lat {float(lat):.6f}"
            )
    judged = {o.pass_index for o in overlaps}
    unjudged = [p.name for p in passes if p.tilt_deg != 0.0 and p.index not in judged]
    if unjudged:
        # Said, never silent: the cast judges the nadir frames only (a tilted frame's footprint
        # over relief is not a trapezoid whose facing edges the cut compares).
        warnings.append(
            f"over the DEM the overlaps of the oblique pass(es) {', '.join(unjudged)} are not judged: "
            "their lines and triggers are spaced for the planned height over flat ground; check them "
            "with `sfap check` of the plan folder, which casts every frame on the plan's DEM"
        )
    if not short:
        return
    fix = (
        "set follow = true in [terrain] or fly higher"
        if not spec.terrain.follow
        else "lower tolerance_m in [terrain], or fly higher"
    )
    where = "; ".join(short)
    ground = (
        f"the stations are {terrain.station_alt_agl_min_m:.1f} to {terrain.station_alt_agl_max_m:.1f} m "
        f"above the ground"
    )
    if not spec.terrain.accept_overlap_loss:
        raise PlanningError(
            f"{spec.source}: over the DEM {where} ({ground}); {fix}, or set accept_overlap_loss = true "
            f"in [terrain] to fly it anyway"
        )
    warnings.append(f"over the DEM {where} ({ground}); {fix}")


#: An overlap this far (percentage points) below the spec's is still taken as held: the cast
#: footprints are measured at a finite number of rays and cuts.
OVERLAP_TOLERANCE_PCT = 0.5


def finish_plan(
    spec: MissionSpec,
    site: ProjectedArea,
    laid: Attempt,
    fit: TerrainFit,
    home_xy: tuple[float, float],
    *,
    alt_agl_m: float,
    flight_passes: tuple[FlightPass, ...],
    warnings: list[str],
    what: str,
    frames: str,
    few_views_note: str = "",
    stations_replaced: dict[str, object] | None = None,
    summary_replaced: dict[str, object] | None = None,
    layout: PlanLayout | None = None,
    logger: logging.Logger = log,
) -> SurveyPlan:
    """The plan from its built mission (``laid``: its passes, speed and views; ``fit``: the
    mission as built over the terrain): the warnings every plan checks (the share of the
    ``what`` seen by fewer than two of its first pass's ``frames``, by three against the forward
    overlap's target, the autopilot's item and flight-time limits), logged, the summary and the
    :class:`SurveyPlan`. ``stations_replaced``/``summary_replaced``: fields set on the built
    stations and on the summary (a corridor numbers its runs as lines of one pass); ``logger``:
    the warnings are logged under the planning module's name."""
    from .summary import limit_warnings, stereo_3_target_pct, summarize  # reads the whole plan

    built, views, pass_plans = fit.built, laid.views, laid.terrain_passes
    first = pass_plans[0]
    if views.seen_2_pct < 100.0 - 1e-9:
        warnings.append(
            f"{100.0 - views.seen_2_pct:.2f} % of the {what} is seen by fewer than two {frames}"
            f"{few_views_note}"
        )
    elif views.edge_weak_points:
        warnings.append(
            f"{views.edge_weak_points} points along the {what}'s edge (beside exclusions) are seen by "
            f"fewer than two {frames} (no stereo there)"
        )
    target3 = stereo_3_target_pct(first.trigger_distance_m, first.rect.along_m)
    if views.seen_3_pct < target3:
        warnings.append(
            f"only {views.seen_3_pct:.1f} % of the {what} is seen by three or more {frames} "
            f"(target {target3:g} %)"
        )
    vehicle = spec.vehicle
    warnings.extend(
        limit_warnings(
            vehicle=vehicle, item_count=len(built.mission.items), flight_time_s=built.flight_time_s
        )
    )
    summary = summarize(
        spec=spec, frame=site.frame, area_m2=site.area_m2, alt_agl_m=alt_agl_m, speed_m_s=laid.speed_m_s,
        nadir=first, passes=pass_plans, built=built, warnings=tuple(warnings),
        true_north_grid_deg=site.true_north_grid_deg, views=views,
        terrain=fit.terrain.as_dict() if fit.terrain is not None else None,
    )  # fmt: skip
    if summary_replaced:
        summary = dataclasses.replace(summary, **summary_replaced)  # type: ignore[arg-type]
    stations = built.stations
    if stations_replaced:
        stations = dataclasses.replace(stations, **stations_replaced)  # type: ignore[arg-type]
    for w in warnings:
        logger.warning(w)  # under the planning module's name
    return SurveyPlan(
        name=spec.name, camera=spec.camera, orientation=spec.orientation, frame=site.frame,
        area_xy=site.area_xy, area_lonlat=site.area_lonlat,
        exclusions_xy=site.zones_xy, exclusions_lonlat=site.zones_lonlat,
        home=fit.home, home_xy_m=home_xy, passes=flight_passes, stations=stations,
        path_xy_m=built.path_xy_m, path_lonlat_deg=built.path_lonlat_deg, mission=built.mission,
        summary=summary, warnings=tuple(warnings), layout=layout,
    )  # fmt: skip
