"""From ordered camera-on segments to mission items and the stations the vehicle will shoot.

Items per segment, distance triggering (as QGroundControl with "images in turnarounds" off,
REFERENCES.md section 2): [transit waypoints around no-fly zones], [gimbal command when the pose
changes], WP(lead-in), WP(camera on) + DO_SET_CAM_TRIGG_DIST(d, 0, 1), WP(camera off) +
DO_SET_CAM_TRIGG_DIST(0, 0, 0), WP(lead-out). The trigger fires once on reaching the camera-on
point (param 3 = 1), then every d metres; the camera-off point lies half a spacing past the last
station, so the photo count is exactly the station count. d is the run's spacing in the
autopilot's own measure, less half a loop step (planner.trigger). Runs of one line that follow
each other (a long line cut by planner.trigger's run limit) have no lead-in or lead-out between
them. Hover triggering: WP(station, hold) +
IMAGE_START_CAPTURE(0, 0, 1) at every station.

Altitudes are relative to home; over flat ground at the home's elevation they equal the height
above ground.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import Polygon

from . import trigger as trig
from .errors import PlanningError
from .exposure import FrameRectangle, from_pass_frame, up_bearing_deg
from .fixed_wing import FixedWing, loop_turn
from .footprint import footprint_corners
from .geo import LocalFrame
from .lines import Segment
from .mission import Autopilot, HomePosition, Mission, MissionItem, VehicleType
from .plan import FlightLine, PassKind, Stations
from .route import Router, boustrophedon, nearest_start, polyline_length_m
from .spec import MissionSpec, TriggerMode

#: Acceleration assumed for the time lost at each stop or sharp turn of a multirotor, m/s2.
_MULTIROTOR_ACCEL_M_S2 = 2.0
#: A change of direction sharper than this costs a stop-and-go in the time estimate.
_SHARP_TURN_DEG = 30.0


@dataclass(frozen=True, kw_only=True)
class PassPlan:
    """One pass as laid out, before routing."""

    index: int
    kind: PassKind
    name: str
    direction_deg: float
    tilt_deg: float
    look_heading_deg: float | None
    rect: FrameRectangle
    trigger_distance_m: float
    line_spacing_m: float
    segments: tuple[Segment, ...]
    near_gsd_cm: float
    far_gsd_cm: float
    centre_gsd_cm: float
    #: Height of this pass when it differs from the mission's (multi-scale blocks), metres.
    alt_agl_m: float | None = None


@dataclass(frozen=True, kw_only=True)
class BuiltMission:
    mission: Mission
    stations: Stations
    lines: dict[int, tuple[FlightLine, ...]]
    path_xy_m: NDArray[np.float64]
    path_lonlat_deg: NDArray[np.float64]
    flight_distance_m: float
    flight_time_s: float
    path_s_m: NDArray[np.float64]  # distance flown to each path point
    path_item_index: tuple[int | None, ...]  # the mission item of each path point (None: home)
    station_s_m: NDArray[np.float64]  # distance flown to each station


@dataclass
class _Columns:
    pass_index: list[NDArray[np.int32]] = field(default_factory=list)
    line_index: list[NDArray[np.int32]] = field(default_factory=list)
    x: list[NDArray[np.float64]] = field(default_factory=list)
    y: list[NDArray[np.float64]] = field(default_factory=list)
    heading: list[NDArray[np.float64]] = field(default_factory=list)
    look: list[NDArray[np.float64]] = field(default_factory=list)
    up: list[NDArray[np.float64]] = field(default_factory=list)
    tilt: list[NDArray[np.float64]] = field(default_factory=list)
    gsd: list[NDArray[np.float64]] = field(default_factory=list)
    alt: list[NDArray[np.float64]] = field(default_factory=list)


def build_mission(
    *,
    spec: MissionSpec,
    frame: LocalFrame,
    home: HomePosition,
    home_xy: tuple[float, float],
    alt_agl_m: float,
    speed_m_s: float,
    passes: list[PassPlan],
    zones_xy: tuple[Polygon, ...],
    true_north_grid_deg: float = 0.0,
    fixed_wing: FixedWing | None = None,
) -> BuiltMission:
    """Items, stations and path for the passes in order. Geometry is in grid bearings;
    headings in the stations and lines are reported as true bearings. With ``fixed_wing``
    the lines are ordered, turned, entered and left as the plane can fly them, and the
    mission takes off and lands as a plane does (planner.fixed_wing)."""
    survey = spec.survey
    vehicle = spec.vehicle
    clearance = survey.exclusion_clearance_m
    router = Router([z.buffer(clearance) for z in zones_xy], margin_m=max(1.0, 0.25 * clearance))
    hover = survey.trigger is TriggerMode.HOVER
    alt = alt_agl_m

    def to_lonlat(p: tuple[float, float]) -> tuple[float, float]:
        lon, lat = frame.to_lonlat(p[0], p[1])
        return float(lat), float(lon)

    items: list[MissionItem] = [MissionItem.takeoff(home.lat_deg, home.lon_deg, vehicle.takeoff_alt_m)]
    turnaround_m = survey.turnaround_m
    if fixed_wing is not None:
        turnaround_m = max(turnaround_m, fixed_wing.lead_in_m)
        first_entry = passes[0].segments[0] if passes and passes[0].segments else None
        aim = home_xy
        if first_entry is not None:
            fx, fy = from_pass_frame(
                np.array([first_entry.u_first_m]), np.array([first_entry.v_m]), passes[0].direction_deg
            )
            aim = (float(fx[0]), float(fy[0]))
        t_lat, t_lon = to_lonlat(fixed_wing.takeoff_point(home_xy, aim))
        items[0] = MissionItem(
            command=items[0].command, param1=fixed_wing.takeoff_pitch_deg, param5=t_lat, param6=t_lon,
            param7=vehicle.takeoff_alt_m,
        )  # fmt: skip
    elif vehicle.type is VehicleType.FIXED_WING:
        items[0] = MissionItem(
            command=items[0].command, param1=15.0, param5=home.lat_deg, param6=home.lon_deg,
            param7=vehicle.takeoff_alt_m,
        )  # fmt: skip
    items.append(MissionItem.change_speed(speed_m_s))
    gimbal_state: tuple[float, float] | None = None

    def gimbal(pitch_deg: float, yaw_deg: float, look_true_deg: float | None = None) -> None:
        """Pitch, yaw relative to the heading; PX4 obliques take ``look_true_deg`` (true bearing)
        as an earth-frame yaw instead."""
        nonlocal gimbal_state
        px4_yaw = None if look_true_deg is None else _wrap180(look_true_deg)
        state = (
            pitch_deg,
            px4_yaw if vehicle.autopilot is Autopilot.PX4 and px4_yaw is not None else yaw_deg,
        )
        if gimbal_state == state:
            return
        gimbal_state = state
        if vehicle.autopilot is Autopilot.PX4:
            if px4_yaw is not None:
                items.append(MissionItem.gimbal_manager_pitch_yaw(pitch_deg, px4_yaw, yaw_earth_frame=True))
            else:
                items.append(MissionItem.gimbal_manager_pitch_yaw(pitch_deg, yaw_deg))
        else:
            items.append(MissionItem.gimbal_pitch_yaw(pitch_deg, yaw_deg))

    gimbal(-90.0, 0.0)  # nothing else points the camera down (QGC issue 8694)

    path: list[tuple[float, float]] = [home_xy]
    path_s: list[float] = [0.0]  # distance flown along the path to each point, metres
    path_item: list[int | None] = [None]  # the mission item of each path point (None: home)
    station_s: list[NDArray[np.float64]] = []  # distance along the path of every station
    transit_flags: list[bool] = []  # per leg of `path`: True when camera-off transit
    holds_s = 0.0
    position = home_xy
    last_heading: float | None = None  # grid bearing of the last line flown (fixed-wing turns)
    columns = _Columns()
    lines: dict[int, tuple[FlightLine, ...]] = {}
    alt_sequence: list[float] = []  # the height of each pass flown, for the climbs in the time

    def waypoint(p: tuple[float, float], hold_s: float = 0.0, transit: bool = True) -> None:
        nonlocal position
        if path and math.dist(path[-1], p) < 1e-3 and hold_s == 0.0:
            return
        lat, lon = to_lonlat(p)
        items.append(MissionItem.waypoint(lat, lon, alt, hold_s=hold_s))
        path_s.append(path_s[-1] + math.dist(path[-1], p))
        path_item.append(len(items) - 1)
        path.append(p)
        transit_flags.append(transit)
        position = p

    for pp in passes:
        segs = pp.segments
        if not segs:
            lines[pp.index] = ()
            continue
        alt = pp.alt_agl_m if pp.alt_agl_m is not None else alt_agl_m
        alt_sequence.append(alt)
        rows: dict[int, list[int]] = {}
        for k, s in enumerate(segs):
            rows.setdefault(s.row, []).append(k)
        row_list = [sorted(rows[r], key=lambda k: segs[k].u_first_m) for r in sorted(rows)]
        entries = {}
        for k, s in enumerate(segs):
            for direction in (1, -1):
                geo = _segment_points(s, direction, pp, turnaround_m, router)
                entries[(k, direction)] = geo["entry"]
        reverse_rows, first_dir = nearest_start(row_list, entries, position)
        if fixed_wing is not None:
            row_v = [segs[r[0]].v_m for r in row_list]
            order = fixed_wing.line_order(row_list, row_v, (reverse_rows, first_dir))
        else:
            order = boustrophedon(row_list, reverse_rows, first_dir)
        pass_lines: list[FlightLine] = []
        for k, direction in order:
            seg = dataclasses.replace(segs[k], direction=direction)
            pts = _segment_points(seg, direction, pp, turnaround_m, router)
            heading = (pp.direction_deg + (0.0 if direction > 0 else 180.0)) % 360.0
            if fixed_wing is not None and last_heading is not None:
                turn = _wrap180(heading - last_heading)
                loop = loop_turn(position, last_heading, pts["entry"], fixed_wing.radius_m)
                if abs(abs(turn) - 180.0) < 1.0 and loop:
                    legs = [position, *loop]
                    clear = all(router.is_clear(a, b) for a, b in itertools.pairwise(legs))
                    if not clear and len(loop) > 2:
                        raise PlanningError(
                            f"a {fixed_wing.radius_m:.0f} m turn loop of the plane crosses an exclusion "
                            f"zone; give the zones more room, fly slower, or allow a steeper bank"
                        )
                    for p in loop if clear else []:  # square corners blocked: the transit goes around
                        waypoint(p)
            last_heading = heading
            # transit to the entry, around no-fly zones
            for p in router.path(position, pts["entry"])[1:-1]:
                waypoint(p)
            if pp.look_heading_deg is not None:
                gimbal(
                    -(90.0 - pp.tilt_deg),
                    _wrap180(pp.look_heading_deg - heading),
                    (pp.look_heading_deg - true_north_grid_deg) % 360.0,
                )
            else:
                gimbal(-90.0, 0.0)
            waypoint(pts["entry"])
            if survey.transit_speed_m_s is not None:
                items.append(MissionItem.change_speed(speed_m_s))
            u_stations = seg.station_u()
            v_stations = np.full_like(u_stations, seg.v_m)
            sx, sy = from_pass_frame(u_stations, v_stations, pp.direction_deg)
            if hover:
                hover_s = []
                for x, y in zip(sx, sy, strict=True):
                    waypoint((float(x), float(y)), hold_s=survey.hover_hold_s, transit=False)
                    hover_s.append(path_s[-1])
                    items.append(MissionItem.image_start_capture())
                    holds_s += survey.hover_hold_s
                station_s.append(np.asarray(hover_s, float))
            else:
                waypoint(pts["start"], transit=True)
                station_s.append(path_s[-1] + np.abs(u_stations - u_stations[0]))
                (lat0, lon0), (lat1, lon1) = to_lonlat(pts["start"]), to_lonlat(pts["stop"])
                ratio = trig.distance_ratio(
                    (lat0, lat1), (lon0, lon1), math.dist(pts["start"], pts["stop"]), vehicle.autopilot
                )
                commanded = trig.commanded_distance_m(seg.spacing_m, ratio, speed_m_s)
                items.append(MissionItem.cam_trigger_distance(commanded, trigger_now=True))
                waypoint(pts["stop"], transit=False)
                items.append(MissionItem.cam_trigger_distance(0.0, trigger_now=False))
            waypoint(pts["exit"])
            if survey.transit_speed_m_s is not None:
                items.append(MissionItem.change_speed(survey.transit_speed_m_s))
            pass_lines.append(
                FlightLine(
                    pass_index=pp.index,
                    line_index=seg.row,
                    start_xy_m=pts["start"],
                    end_xy_m=pts["stop"],
                    entry_xy_m=pts["entry"],
                    exit_xy_m=pts["exit"],
                    heading_deg=(heading - true_north_grid_deg) % 360.0,
                )
            )
            n = seg.count
            columns.pass_index.append(np.full(n, pp.index, np.int32))
            columns.line_index.append(np.full(n, seg.row, np.int32))
            columns.x.append(sx)
            columns.y.append(sy)
            true_heading = (heading - true_north_grid_deg) % 360.0
            columns.heading.append(np.full(n, true_heading))
            if pp.look_heading_deg is not None:
                columns.look.append(np.full(n, (pp.look_heading_deg - true_north_grid_deg) % 360.0))
                columns.up.append(np.full(n, pp.look_heading_deg))
            else:
                columns.look.append(np.full(n, true_heading))
                columns.up.append(np.full(n, up_bearing_deg(heading, spec.orientation)))
            columns.tilt.append(np.full(n, pp.tilt_deg))
            columns.gsd.append(np.full(n, pp.centre_gsd_cm))
            columns.alt.append(np.full(n, alt))
        lines[pp.index] = tuple(pass_lines)

    if fixed_wing is not None:
        # to the approach point, around no-fly zones, then the landing sequence (planner.fixed_wing)
        approach = fixed_wing.approach_point(home_xy, position)
        for p in router.path(position, approach)[1:-1]:
            waypoint(p)
        items.extend(fixed_wing.landing_items(to_lonlat(approach), (home.lat_deg, home.lon_deg)))
        path_s.append(path_s[-1] + math.dist(path[-1], approach))
        path_item.append(None)  # the approach keeps its altitude (the glide slope's top)
        path.append(approach)
        transit_flags.append(True)
    else:
        # home, around no-fly zones, then RTL
        for p in router.path(position, home_xy)[1:-1]:
            waypoint(p)
        items.append(MissionItem.return_to_launch())
    path_s.append(path_s[-1] + math.dist(path[-1], home_xy))
    path_item.append(None)
    path.append(home_xy)
    transit_flags.append(True)

    stations = _stations(spec, frame, alt_agl_m, columns)
    path_xy = np.asarray(path, float)
    lon, lat = frame.to_lonlat(path_xy[:, 0], path_xy[:, 1])
    path_lonlat = np.column_stack([lon, lat])
    distance = polyline_length_m(path_xy)
    flight_time = _flight_time_s(
        path_xy, transit_flags, speed_m_s, survey.transit_speed_m_s, alt_agl_m,
        vehicle.takeoff_alt_m, vehicle.climb_rate_m_s, holds_s, vehicle.type,
        len(stations) if hover else 0, alt_sequence_m=alt_sequence,
    )  # fmt: skip
    mission = Mission(
        items=tuple(items),
        home=home,
        autopilot=vehicle.autopilot,
        vehicle_type=vehicle.type,
        cruise_speed_m_s=survey.transit_speed_m_s or speed_m_s,
        hover_speed_m_s=speed_m_s,
        metadata={"name": spec.name, "generator": "sfap"},
    )
    return BuiltMission(
        mission=mission,
        stations=stations,
        lines=lines,
        path_xy_m=path_xy,
        path_lonlat_deg=path_lonlat,
        flight_distance_m=distance,
        flight_time_s=flight_time,
        path_s_m=np.asarray(path_s, float),
        path_item_index=tuple(path_item),
        station_s_m=np.concatenate(station_s) if station_s else np.zeros(0),
    )


def _segment_points(
    seg: Segment, direction: int, pp: PassPlan, turnaround_m: float, router: Router
) -> dict[str, tuple[float, float]]:
    """Lead-in, camera-on, camera-off and lead-out points of a segment flown in ``direction``."""
    flown = dataclasses.replace(seg, direction=direction)
    start_u, stop_u = flown.camera_on_u()
    # A run that continues another of the same line has no lead-in (lead-out) on that side.
    lead_in = 0.0 if (seg.join_lo if direction > 0 else seg.join_hi) else turnaround_m
    lead_out = 0.0 if (seg.join_hi if direction > 0 else seg.join_lo) else turnaround_m

    def xy(u: float) -> tuple[float, float]:
        x, y = from_pass_frame(np.array([u]), np.array([seg.v_m]), pp.direction_deg)
        return float(x[0]), float(y[0])

    start, stop = xy(start_u), xy(stop_u)
    entry, exit_ = xy(start_u - direction * lead_in), xy(stop_u + direction * lead_out)
    if not router.is_clear(entry, start):
        entry = start
    if not router.is_clear(stop, exit_):
        exit_ = stop
    return {"entry": entry, "start": start, "stop": stop, "exit": exit_}


def _stations(spec: MissionSpec, frame: LocalFrame, alt_agl_m: float, c: _Columns) -> Stations:
    def cat(parts: list[NDArray], dtype: type) -> NDArray:
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype)

    x, y = cat(c.x, float), cat(c.y, float)
    up, tilt = cat(c.up, float), cat(c.tilt, float)
    n = x.shape[0]
    alt = cat(c.alt, float) if c.alt else np.full(n, alt_agl_m)
    if n:
        corners = footprint_corners(spec.camera, x, y, alt, up, tilt)
        lon, lat = frame.to_lonlat(x, y)
        clon, clat = frame.to_lonlat(corners[..., 0].ravel(), corners[..., 1].ravel())
        corners_ll = np.stack([clon.reshape(n, 4), clat.reshape(n, 4)], axis=-1)
    else:
        corners = np.zeros((0, 4, 2))
        corners_ll = np.zeros((0, 4, 2))
        lon = lat = np.zeros(0)
    return Stations(
        pass_index=cat(c.pass_index, np.int32),
        line_index=cat(c.line_index, np.int32),
        x_m=x,
        y_m=y,
        lon_deg=np.asarray(lon, float),
        lat_deg=np.asarray(lat, float),
        alt_rel_home_m=alt.copy(),
        alt_agl_m=alt,
        heading_deg=cat(c.heading, float),
        look_heading_deg=cat(c.look, float),
        tilt_deg=tilt,
        gsd_cm=cat(c.gsd, float),
        footprint_xy_m=corners,
        footprint_lonlat_deg=corners_ll,
    )


def _flight_time_s(
    path_xy: NDArray[np.float64],
    transit_flags: list[bool],
    speed_m_s: float,
    transit_speed_m_s: float | None,
    alt_agl_m: float,
    takeoff_alt_m: float,
    climb_rate_m_s: float,
    holds_s: float,
    vehicle_type: VehicleType,
    stops: int,
    alt_sequence_m: list[float] | None = None,
) -> float:
    """Estimated flight time: legs at their speed, climbs and the final descent at the climb
    rate, holds, and for a multirotor a stop-and-go (v / a) at every sharp turn and stop."""
    legs = np.hypot(*np.diff(path_xy, axis=0).T) if len(path_xy) > 1 else np.zeros(0)
    fast = transit_speed_m_s or speed_m_s
    speeds = np.array([fast if t else speed_m_s for t in transit_flags[: len(legs)]])
    time = float(np.sum(legs / speeds)) if len(legs) else 0.0
    heights = alt_sequence_m or [alt_agl_m]  # passes at other heights: a climb or descent between
    vertical_m = takeoff_alt_m + abs(heights[0] - takeoff_alt_m) + heights[-1]
    vertical_m += float(np.sum(np.abs(np.diff(heights)))) if len(heights) > 1 else 0.0
    time += vertical_m / climb_rate_m_s
    time += holds_s
    if vehicle_type is not VehicleType.FIXED_WING and len(path_xy) > 2:
        d = np.diff(path_xy, axis=0)
        keep = np.hypot(d[:, 0], d[:, 1]) > 1e-6
        d = d[keep]
        if len(d) > 1:
            ang = np.degrees(np.arctan2(d[:, 0], d[:, 1]))
            turn = np.abs((np.diff(ang) + 180.0) % 360.0 - 180.0)
            sharp = int(np.count_nonzero(turn > _SHARP_TURN_DEG))
            time += (sharp + stops) * speed_m_s / _MULTIROTOR_ACCEL_M_S2
    return time


def _wrap180(angle_deg: float) -> float:
    a = (angle_deg + 180.0) % 360.0 - 180.0
    return 180.0 if a == -180.0 else a
