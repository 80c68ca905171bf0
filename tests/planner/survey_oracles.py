"""Shared helpers for the planner tests: specs from dicts, and an independent replay of the
trigger items that says where an autopilot fires the camera."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import shapely
from pyproj import Geod
from shapely.geometry import LineString

from planner.mission import Autopilot, MavCmd, Mission
from planner.plan import SurveyPlan
from planner.spec import MissionSpec, parse_spec

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"


def make_spec(overrides: dict[str, Any] | None = None, camera: dict[str, Any] | None = None) -> MissionSpec:
    """A valid spec (area path unused: tests call plan_polygons) with survey overrides."""
    survey: dict[str, Any] = {
        "gsd_cm": 2.0,
        "front_overlap_pct": 80,
        "side_overlap_pct": 70,
        "speed_m_s": 5.0,
        "turnaround_m": 10.0,
    }
    survey.update(overrides or {})
    survey = {key: value for key, value in survey.items() if value is not None}  # None: drop the key
    data = {
        "name": "test",
        "area": "area.geojson",
        "camera": camera or {"model": "dji-phantom-4-pro"},
        "survey": survey,
        "vehicle": {"type": "multirotor", "max_alt_agl_m": 400},
    }
    return parse_spec(data, REPO / "tests" / "spec.toml")


def replay_triggers(mission: Mission, to_xy: Any) -> np.ndarray:
    """Where an autopilot fires the camera, replaying the mission items the way ArduPilot's
    AP_Camera does: DO_SET_CAM_TRIGG_DIST(d, _, 1) fires once at the current position, then
    whenever the straight distance from the last photo reaches d along the flown legs; d = 0
    stops; IMAGE_START_CAPTURE fires once at the current position.

    This is written from the MAVLink command definitions, independently of the planner's
    station computation, so it can be the oracle for "the photo count the vehicle will take".
    ``to_xy(lon, lat) -> (x, y)`` projects waypoints into metres.
    """
    photos: list[tuple[float, float]] = []
    position: tuple[float, float] | None = None
    last_photo: tuple[float, float] | None = None
    distance = 0.0
    for item in mission.items:
        command = int(item.command)
        if command in (MavCmd.NAV_WAYPOINT, MavCmd.NAV_TAKEOFF):
            x, y = to_xy(item.lon_deg, item.lat_deg)
            target = (float(x), float(y))
            if position is not None and distance > 0 and last_photo is not None:
                photos_on_leg = _fire_along_leg(position, target, last_photo, distance)
                photos.extend(photos_on_leg)
                if photos_on_leg:
                    last_photo = photos_on_leg[-1]
            position = target
        elif command == MavCmd.DO_SET_CAM_TRIGG_DIST:
            assert item.param1 is not None
            distance = float(item.param1)
            if item.param3 == 1.0 and position is not None:
                photos.append(position)
                last_photo = position
        elif command == MavCmd.IMAGE_START_CAPTURE:
            assert position is not None
            photos.append(position)
            last_photo = position
    return np.asarray(photos, float).reshape(-1, 2)


def _fire_along_leg(
    a: tuple[float, float], b: tuple[float, float], last: tuple[float, float], d: float
) -> list[tuple[float, float]]:
    """Points on the leg a->b where the straight distance from the last photo first reaches d
    (solved exactly: the leg meets the circle of radius d around the last photo)."""
    out: list[tuple[float, float]] = []
    wx, wy = b[0] - a[0], b[1] - a[1]
    ww = wx * wx + wy * wy
    if ww == 0.0:
        return out
    t0 = 0.0
    while True:
        # |a + t w - last|^2 = d^2, smallest root t >= t0
        ox, oy = a[0] - last[0], a[1] - last[1]
        bq = 2.0 * (ox * wx + oy * wy)
        cq = ox * ox + oy * oy - d * d
        disc = bq * bq - 4.0 * ww * cq
        if disc < 0:
            return out
        roots = sorted(((-bq - math.sqrt(disc)) / (2 * ww), (-bq + math.sqrt(disc)) / (2 * ww)))
        t = next((r for r in roots if r >= t0 - 1e-12 and r > 1e-12), None)
        if t is None or t > 1.0 + 1e-12:
            return out
        last = (a[0] + t * wx, a[1] + t * wy)
        out.append(last)
        t0 = t


# --- ArduPilot's trigger, replayed at its loop rate --------------------------------------------
#: AP_Camera_Backend::update runs at 50 Hz (its own comment: "should be called at 50hz").
ARDUPILOT_LOOP_HZ = 50.0
_WGS84 = Geod(ellps="WGS84")


def ardupilot_distance_m(lat0: np.ndarray, lon0: np.ndarray, lat1: float, lon1: float) -> np.ndarray:
    """Location::get_distance of ArduPilot (libraries/AP_Common/Location.cpp), rewritten from its
    source: positions as int32 of 1e-7 degree, the longitude difference times the cosine of the
    mean latitude, times LOCATION_SCALING_FACTOR = 6378100 m x pi/180 x 1e-7."""
    a_lat, a_lon = np.round(np.asarray(lat0) * 1e7), np.round(np.asarray(lon0) * 1e7)
    b_lat, b_lon = round(lat1 * 1e7), round(lon1 * 1e7)
    dlat = b_lat - a_lat
    dlng = (b_lon - a_lon) * np.cos(np.radians((a_lat + b_lat) / 2 * 1e-7))
    return np.sqrt(dlat**2 + dlng**2) * (6378100.0 * math.pi / 180.0 * 1e-7)


def px4_distance_m(lat0: np.ndarray, lon0: np.ndarray, lat1: float, lon1: float) -> np.ndarray:
    """Great-circle distance on PX4's sphere (CONSTANTS_RADIUS_OF_EARTH = 6371000 m)."""
    p0, p1 = np.radians(lat0), math.radians(lat1)
    h = np.sin((p1 - p0) / 2) ** 2 + np.cos(p0) * math.cos(p1) * np.sin(np.radians(lon1 - lon0) / 2) ** 2
    return 2 * 6371000.0 * np.arcsin(np.sqrt(h))


def replay_at_loop_rate(
    mission: Mission, loop_hz: float = ARDUPILOT_LOOP_HZ, autopilot: Autopilot | None = None
) -> np.ndarray:
    """Where the camera fires when the vehicle flies the mission at its commanded speeds and the
    autopilot checks the trigger distance once per loop, measured its own way.

    The vehicle flies straight legs between the NAV items at the speed of the last
    DO_CHANGE_SPEED (true ground metres, WGS84 geodesic), and passes through each waypoint; the DO
    items that follow a waypoint run at the first loop at or after reaching it, after that loop's
    camera check (AP_Camera: fire when get_distance(last photo) >= trigger distance; distance 0
    forgets the last photo; DO_SET_CAM_TRIGG_DIST(d, _, 1) fires at once). Returns (N, 2)
    lon/lat of the photos, in order.
    """
    autopilot = autopilot or mission.autopilot
    distance = ardupilot_distance_m if autopilot is Autopilot.ARDUPILOT else px4_distance_m
    nav: list[tuple[float, float]] = []  # lon, lat of each NAV point
    leg_speed: list[float] = []  # speed of the leg ending at each NAV point
    events: list[list[tuple[str, float, float]]] = []  # DO items after each NAV point
    speed = mission.hover_speed_m_s
    for item in mission.items:
        command = int(item.command)
        if command in (MavCmd.NAV_WAYPOINT, MavCmd.NAV_TAKEOFF):
            nav.append((item.lon_deg, item.lat_deg))
            leg_speed.append(speed)
            events.append([])
        elif command == MavCmd.DO_CHANGE_SPEED:
            assert item.param2 is not None
            speed = float(item.param2)
        elif command == MavCmd.DO_SET_CAM_TRIGG_DIST and nav:
            assert item.param1 is not None
            events[-1].append(("dist", float(item.param1), float(item.param3 or 0.0)))
        elif command == MavCmd.IMAGE_START_CAPTURE and nav:
            events[-1].append(("shot", 0.0, 1.0))
    lon = np.array([p[0] for p in nav])
    lat = np.array([p[1] for p in nav])
    _, _, legs = _WGS84.inv(lon[:-1], lat[:-1], lon[1:], lat[1:])
    t_nav = np.concatenate([[0.0], np.cumsum(np.asarray(legs) / np.asarray(leg_speed[1:]))])
    dt = 1.0 / loop_hz
    n_ticks = math.ceil(t_nav[-1] / dt) + 1
    t = np.arange(n_ticks) * dt
    # Straight legs: interpolate in lon/lat within each leg (legs are a few km at most).
    tick_lon = np.interp(t, t_nav, lon)
    tick_lat = np.interp(t, t_nav, lat)
    reach_tick = np.minimum(np.ceil(t_nav / dt - 1e-9).astype(int), n_ticks - 1)

    photos: list[int] = []
    trig = 0.0
    last: int | None = None  # tick of the last photo (None: forgotten)
    tick = 0
    for i in range(len(nav)):
        k_event = int(reach_tick[i])
        # camera checks on the ticks up to and including the one that reaches this waypoint
        while trig > 0 and tick <= k_event:
            if last is None:
                last = tick
                tick += 1
                continue
            window = np.arange(tick, min(k_event, tick + 1024) + 1)
            d = distance(tick_lat[window], tick_lon[window], float(tick_lat[last]), float(tick_lon[last]))
            moved = (tick_lat[window] != tick_lat[last]) | (tick_lon[window] != tick_lon[last])
            hit = np.nonzero((d >= trig) & moved)[0]
            if hit.size == 0:
                tick = int(window[-1]) + 1
                continue
            last = int(window[hit[0]])
            photos.append(last)
            tick = last + 1
        tick = k_event + 1
        for kind, value, now in events[i]:
            if kind == "dist":
                trig = value
                if trig <= 0:
                    last = None
                if now == 1.0:
                    photos.append(k_event)
                    last = k_event
            else:
                photos.append(k_event)
                last = k_event
    return np.column_stack([tick_lon[photos], tick_lat[photos]]) if photos else np.zeros((0, 2))


# --- the planner's promises, measured on a plan -------------------------------------------------


def sample_points(area: shapely.Geometry, cell_m: float) -> np.ndarray:
    """Points of a regular grid inside the area plus points every metre along its boundary."""
    u0, v0, u1, v1 = area.bounds
    gx, gy = np.meshgrid(np.arange(u0 + cell_m / 2, u1, cell_m), np.arange(v0 + cell_m / 2, v1, cell_m))
    gx, gy = gx.ravel(), gy.ravel()
    inside = shapely.contains_xy(area, gx, gy)
    grid = np.column_stack([gx[inside], gy[inside]])
    rings = [g.exterior for g in getattr(area, "geoms", [area])]
    rings += [r for g in getattr(area, "geoms", [area]) for r in g.interiors]
    edge = [shapely.get_coordinates(ring.interpolate(np.arange(0.0, ring.length, 1.0))) for ring in rings]
    return np.vstack([grid, *edge])


def views(footprints_xy: np.ndarray, points: np.ndarray, tolerance_m: float = 1e-6) -> np.ndarray:
    """How many footprints (N, 4, 2) hold each point, edges (to ``tolerance_m``) included
    (shapely, no planner code)."""
    polygons = shapely.polygons(footprints_xy)
    tree = shapely.STRtree(polygons)
    hits = tree.query(shapely.points(points), predicate="dwithin", distance=tolerance_m)
    return np.bincount(hits[0], minlength=len(points))


def random_points(area: shapely.Geometry, n: int, seed: int = 1) -> np.ndarray:
    """``n`` points drawn uniformly in the area (rejection sampling in its bounds)."""
    rng = np.random.default_rng(seed)
    u0, v0, u1, v1 = area.bounds
    out = np.zeros((0, 2))
    while len(out) < n:
        p = rng.uniform((u0, v0), (u1, v1), (4 * n, 2))
        out = np.vstack([out, p[shapely.contains_xy(area, p[:, 0], p[:, 1])]])
    return out[:n]


def check_plan(plan: SurveyPlan, front_pct: float, side_pct: float, clearance_m: float) -> None:
    stations = plan.stations
    assert len(stations) > 0
    camera = plan.camera
    alt = float(stations.alt_agl_m[0])
    fp = camera.footprint(alt, plan.orientation)
    air_base = fp.along_m * (1 - front_pct / 100)
    spacing = fp.across_m * (1 - side_pct / 100)
    nadir = stations.pass_index == 0
    summary = plan.summary

    # 1. stereo: every point of the area (exclusions removed) is seen by two nadir frames, and the
    #    share seen by three is what summary.json says (and meets its target)
    cell = min(air_base, spacing) / 4.0
    points = sample_points(plan.area_xy, cell)
    n_grid = int(np.count_nonzero(shapely.contains_xy(plan.area_xy, points[:, 0], points[:, 1])))
    counts = views(stations.footprint_xy_m[nadir], points)
    weak = int(np.count_nonzero(counts < 2))
    reported = [w for w in plan.warnings if "fewer than two" in w or "cannot be seen" in w]
    share2 = 100.0 * np.count_nonzero(counts[:n_grid] >= 2) / max(1, n_grid)
    if reported:  # only beside an exclusion, and then said with its share
        assert plan.exclusions_xy
        assert abs(share2 - summary.stereo_seen_2_pct) < 1.0
    else:
        assert weak == 0, f"{weak} of {len(points)} sample points seen by fewer than two nadir frames"
        assert summary.stereo_seen_2_pct == pytest.approx(100.0)
    uniform = random_points(plan.area_xy, 20_000)
    share3 = 100.0 * np.count_nonzero(views(stations.footprint_xy_m[nadir], uniform) >= 3) / len(uniform)
    assert abs(share3 - summary.stereo_seen_3_pct) < 2.0
    if 3 * air_base <= fp.along_m:
        assert summary.stereo_seen_3_target_pct > 0
        assert summary.stereo_seen_3_pct >= summary.stereo_seen_3_target_pct or any(
            "three or more" in w for w in plan.warnings
        )

    # 2. the lines, measured: main lines one spacing apart (no more than the sidelap allows),
    #    the fewest that span the area, the block centred (equal margins at both edges)
    for p in plan.passes:
        if p.tilt_deg != 0.0:
            continue
        line = max(p.lines, key=lambda ln: math.dist(ln.start_xy_m, ln.end_xy_m))
        bearing = math.atan2(line.end_xy_m[0] - line.start_xy_m[0], line.end_xy_m[1] - line.start_xy_m[1])
        x0, y0 = line.start_xy_m
        mask = stations.pass_index == p.index
        across = (stations.x_m[mask] - x0) * math.cos(bearing) - (stations.y_m[mask] - y0) * math.sin(bearing)
        area_v = shapely.get_coordinates(plan.area_xy)
        area_across = (area_v[:, 0] - x0) * math.cos(bearing) - (area_v[:, 1] - y0) * math.sin(bearing)
        rows = np.unique(np.round(across, 4))
        assert p.line_spacing_m == pytest.approx(spacing, rel=1e-9)
        width = fp.across_m
        span = float(area_across.max() - area_across.min())
        n_main = max(1, math.ceil((span - width) / spacing - 1e-9) + 1)
        # The main lines, from the area alone: the fewest n rows one spacing apart whose frames
        # span it, centred (equal margins at both edges). The plan's rows must lie on that lattice;
        # fill rows may lie between. A line whose frames add nothing is dropped (thin shapes
        # across the lines): a frame spans 1 / (1 - sidelap) spacings, so the rows kept are at
        # least the share (1 - sidelap) of the lattice that single coverage needs. A block that is
        # not centred puts no row on the lattice at all.
        first = (area_across.min() + area_across.max() - (n_main - 1) * spacing) / 2.0
        lattice = first + np.arange(n_main) * spacing
        on = np.array([np.min(np.abs(rows - v)) < 1e-3 for v in lattice])
        assert on.sum() >= max(1, math.ceil(n_main * (1.0 - side_pct / 100.0) - 1e-9)), (
            f"{on.sum()} of {n_main} rows where a centred block of lines {spacing:.2f} m apart puts them"
        )
        assert area_across.min() - (first - width / 2) >= -1e-6  # the outer frames reach the edges

    # 3. along each camera-on run the stations are at most an air base apart
    for p in plan.passes:
        mask = np.flatnonzero(stations.pass_index == p.index)
        pass_points = shapely.points(np.column_stack([stations.x_m[mask], stations.y_m[mask]]))
        base = p.trigger_distance_m
        for line_obj in p.lines:
            run = LineString([line_obj.start_xy_m, line_obj.end_xy_m])
            on = shapely.distance(run, pass_points) < 1e-3
            assert on.any(), "a camera-on run with no station"
            along = np.sort(shapely.line_locate_point(run, pass_points[on]))
            assert np.all(np.diff(along) <= base + 1e-6)
            assert run.length > 0, "a zero-length camera-on line"

    # 4. photos see the area; camera-on segments stay near it and out of exclusions
    zones = shapely.union_all(plan.exclusions_xy) if plan.exclusions_xy else None
    # every photo sees some of the area
    assert np.all(shapely.intersects(shapely.polygons(stations.footprint_xy_m), plan.area_xy.buffer(1e-6)))
    for p in plan.passes:
        # the camera is on no farther from the area than a frame reaches, plus the half spacing
        # between the last station and the camera-off point
        mask = stations.pass_index == p.index
        cam = np.stack([stations.x_m[mask], stations.y_m[mask]], axis=-1)[:, None, :]
        reach = float(np.max(np.hypot(*(stations.footprint_xy_m[mask] - cam).transpose(2, 0, 1))))
        buffer = plan.area_xy.buffer(reach + 0.5 * p.trigger_distance_m + 1e-6)
        for line_obj in p.lines:
            seg = LineString([line_obj.start_xy_m, line_obj.end_xy_m])
            assert buffer.contains(seg), "camera on outside the area's buffer"
            if zones is not None:
                assert seg.distance(zones) >= clearance_m - 1e-6, "camera on inside an exclusion"
    if zones is not None:
        pts = shapely.points(stations.x_m, stations.y_m)
        assert not np.any(shapely.intersects(zones, pts)), "a station inside an exclusion"

    # 5. ArduPilot's trigger replayed at its loop rate, distances on its sphere: every station
    #    fires once, near where it is planned, and the frames it takes still see every point twice
    fired_ll = replay_at_loop_rate(plan.mission)
    assert len(fired_ll) == len(stations), (
        f"autopilot fires {len(fired_ll)} photos, plan says {len(stations)}"
    )
    fx, fy = plan.frame.to_xy(fired_ll[:, 0], fired_ll[:, 1])
    offset = np.hypot(fx - stations.x_m, fy - stations.y_m)
    assert np.max(offset) < 0.5 * air_base
    moved = stations.footprint_xy_m + np.stack([fx - stations.x_m, fy - stations.y_m], axis=-1)[:, None, :]
    fired_counts = views(moved[nadir], points, tolerance_m=0.05)  # positions to 1e-7 degree
    assert np.count_nonzero(fired_counts < 2) <= (weak if reported else 0), (
        "the photos fired leave stereo gaps"
    )
