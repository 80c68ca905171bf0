"""The survey's flight path (planner.flight_path), from the passes' camera-on segments: line
order, routing around no-fly zones, a plane's turns, take-off and landing; then the stations and
the flight time read from it, and its mission items (planner.mission_items).

Each line is flown [transit around no-fly zones] -> entry (the lead-in's start) -> camera on ->
camera off (half a spacing past the last station, so the photo count is exactly the station
count) -> exit (the lead-out's end); the trigger distance is the run's spacing in the
autopilot's own measure, less half a loop step (planner.trigger). Runs of one line that follow
each other (a long line cut by planner.trigger's run limit) have no lead-in or lead-out between
them. Hover triggering: a held station at every photo.

Altitudes are relative to home; over flat ground at the home's elevation they equal the height
above ground (planner.terrain_follow reshapes them over a DEM).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from shapely.geometry import Polygon

from . import trigger as trig
from .errors import PlanningError
from .exposure import FrameRectangle, from_pass_frame, up_bearing_deg
from .fixed_wing import FixedWing, loop_turn
from .flight_path import CameraPose, FlightPath, PathPoint, PathRun, Role
from .footprint import footprint_corners
from .geo import LocalFrame
from .kinds import PassKind
from .lines import Segment
from .mission import HomePosition, Mission, VehicleType
from .mission_items import MissionEmitter, wrap180
from .plan import FlightLine, Stations
from .route import Router, boustrophedon, nearest_start, polyline_length_m
from .spec import MissionSpec, TriggerMode

if TYPE_CHECKING:
    from .terrain_follow import CastOverlap

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
    #: The overlaps the spec asks of this pass (percent): over a DEM they must hold everywhere.
    front_overlap_pct: float | None = None
    side_overlap_pct: float | None = None


@dataclass(frozen=True, kw_only=True)
class BuiltMission:
    """A flight path with what is read from it: the mission items, the stations, the track and
    the flight's length and time."""

    path: FlightPath
    emitter: MissionEmitter
    mission: Mission
    stations: Stations
    path_xy_m: NDArray[np.float64]
    path_lonlat_deg: NDArray[np.float64]
    flight_distance_m: float
    flight_time_s: float
    #: Over a DEM: each nadir pass's smallest overlaps, from the footprints cast on it.
    cast_overlaps: tuple[CastOverlap, ...] = ()

    @property
    def lines(self) -> dict[int, tuple[FlightLine, ...]]:
        return self.path.lines


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
    """The flight path of the passes in order, and what is read from it. Geometry is in grid
    bearings; headings in the stations and lines are reported as true bearings. With
    ``fixed_wing`` the lines are ordered, turned, entered and left as the plane can fly them, and
    the mission takes off and lands as a plane does (planner.fixed_wing)."""
    path = build_path(
        spec=spec, frame=frame, home_xy=home_xy, alt_agl_m=alt_agl_m, speed_m_s=speed_m_s,
        passes=passes, zones_xy=zones_xy, true_north_grid_deg=true_north_grid_deg, fixed_wing=fixed_wing,
    )  # fmt: skip
    stations = path_stations(spec, frame, alt_agl_m, path)
    return read_path(path, stations, spec=spec, frame=frame, home=home, alt_agl_m=alt_agl_m,
                     speed_m_s=speed_m_s, fixed_wing=fixed_wing)  # fmt: skip


def read_path(
    path: FlightPath,
    stations: Stations,
    *,
    spec: MissionSpec,
    frame: LocalFrame,
    home: HomePosition,
    alt_agl_m: float,
    speed_m_s: float,
    fixed_wing: FixedWing | None,
) -> BuiltMission:
    """The mission items, track, length and flight time of ``path`` (its ``stations`` given)."""
    vehicle = spec.vehicle
    path_xy = path.track_xy_m()
    lon, lat = frame.to_lonlat(path_xy[:, 0], path_xy[:, 1])
    flight_time = _flight_time_s(
        path_xy, path.transit_legs(), speed_m_s, spec.survey.transit_speed_m_s, alt_agl_m,
        vehicle.takeoff_alt_m, vehicle.climb_rate_m_s, path.holds_s(), vehicle.type,
        path.stops(), alt_sequence_m=list(path.pass_alts_m),
    )  # fmt: skip
    emitter = MissionEmitter(spec=spec, frame=frame, speed_m_s=speed_m_s, fixed_wing=fixed_wing)
    return BuiltMission(
        path=path,
        emitter=emitter,
        mission=emitter(path, home),
        stations=stations,
        path_xy_m=path_xy,
        path_lonlat_deg=np.column_stack([lon, lat]),
        flight_distance_m=polyline_length_m(path_xy),
        flight_time_s=flight_time,
    )


def build_path(
    *,
    spec: MissionSpec,
    frame: LocalFrame,
    home_xy: tuple[float, float],
    alt_agl_m: float,
    speed_m_s: float,
    passes: list[PassPlan],
    zones_xy: tuple[Polygon, ...],
    true_north_grid_deg: float = 0.0,
    fixed_wing: FixedWing | None = None,
) -> FlightPath:
    """The flight path (planner.flight_path) of the passes in order (build_mission)."""
    survey = spec.survey
    vehicle = spec.vehicle
    clearance = survey.exclusion_clearance_m
    router = Router([z.buffer(clearance) for z in zones_xy], margin_m=max(1.0, 0.25 * clearance))
    hover = survey.trigger is TriggerMode.HOVER
    alt = alt_agl_m

    def to_lonlat(p: tuple[float, float]) -> tuple[float, float]:
        lon, lat = frame.to_lonlat(p[0], p[1])
        return float(lat), float(lon)

    turnaround_m = survey.turnaround_m
    lead_out_m: float | None = None  # None: the turnaround; a plane's lead-out is shorter than its run-in
    takeoff_target: tuple[float, float] | None = None
    takeoff_pitch: float | None = None
    if fixed_wing is not None:
        lead_out_m = max(turnaround_m, fixed_wing.lead_out_m)
        turnaround_m = max(turnaround_m, fixed_wing.lead_in_m)
        first_entry = passes[0].segments[0] if passes and passes[0].segments else None
        aim = home_xy
        if first_entry is not None:
            fx, fy = from_pass_frame(
                np.array([first_entry.u_first_m]), np.array([first_entry.v_m]), passes[0].direction_deg
            )
            aim = (float(fx[0]), float(fy[0]))
        takeoff_target = fixed_wing.takeoff_point(home_xy, aim)
        takeoff_pitch = fixed_wing.takeoff_pitch_deg
    elif vehicle.type is VehicleType.FIXED_WING:
        takeoff_pitch = 15.0
    nadir = CameraPose(pitch_deg=-90.0, yaw_deg=0.0)
    # nothing else points the camera down (QGC issue 8694)
    points: list[PathPoint] = [PathPoint(xy=home_xy, role=Role.TAKE_OFF, speed_m_s=speed_m_s, camera=nadir)]
    position = home_xy
    last_heading: float | None = None  # grid bearing of the last line flown (fixed-wing turns)
    runs: list[PathRun] = []
    lines: dict[int, tuple[FlightLine, ...]] = {}
    alt_sequence: list[float] = []  # the height of each pass flown, for the climbs in the time

    def add(p: tuple[float, float], role: Role, **kw: object) -> int:
        """Append a point (one on the previous point, not held, adds no leg); its index."""
        nonlocal position
        hold = float(kw.get("hold_s", 0.0))  # type: ignore[arg-type]
        on_previous = math.dist(position, p) < 1e-3 and hold == 0.0
        points.append(PathPoint(xy=p, role=role, alt_m=alt, on_previous=on_previous, **kw))  # type: ignore[arg-type]
        if not on_previous:
            position = p
        return len(points) - 1

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
                geo = _segment_points(s, direction, pp, turnaround_m, router, lead_out_m)
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
            pts = _segment_points(seg, direction, pp, turnaround_m, router, lead_out_m)
            heading = (pp.direction_deg + (0.0 if direction > 0 else 180.0)) % 360.0
            if fixed_wing is not None and len(points) == 1:  # the first line: after the climb-out
                first_lead = fixed_wing.first_lead_in_m(home_xy, pts["start"], heading)
                if first_lead > turnaround_m:
                    pts = _segment_points(seg, direction, pp, first_lead, router, lead_out_m)
            where = {"pass_index": pp.index, "line_index": seg.row}
            if fixed_wing is not None and last_heading is not None:
                turn = wrap180(heading - last_heading)
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
                        add(p, Role.LOOP_TURN, **where)
            last_heading = heading
            # transit to the entry, around no-fly zones
            for p in router.path(position, pts["entry"])[1:-1]:
                add(p, Role.TRANSIT, **where)
            if pp.look_heading_deg is not None:
                pose = CameraPose(
                    pitch_deg=-(90.0 - pp.tilt_deg),
                    yaw_deg=wrap180(pp.look_heading_deg - heading),
                    look_true_deg=(pp.look_heading_deg - true_north_grid_deg) % 360.0,
                )
            else:
                pose = nadir
            transit_speed = survey.transit_speed_m_s
            back_to_survey_speed = speed_m_s if transit_speed is not None else None
            add(pts["entry"], Role.ENTRY, camera=pose, speed_m_s=back_to_survey_speed, **where)
            u_stations = seg.station_u()
            v_stations = np.full_like(u_stations, seg.v_m)
            sx, sy = from_pass_frame(u_stations, v_stations, pp.direction_deg)
            run_at: dict[str, object]
            if hover:
                held = tuple(
                    add((float(x), float(y)), Role.STATION, hold_s=survey.hover_hold_s, **where)
                    for x, y in zip(sx, sy, strict=True)
                )
                run_at = {"station_points": held}
            else:
                (lat0, lon0), (lat1, lon1) = to_lonlat(pts["start"]), to_lonlat(pts["stop"])
                ratio = trig.distance_ratio(
                    (lat0, lat1), (lon0, lon1), math.dist(pts["start"], pts["stop"]), vehicle.autopilot
                )
                commanded = trig.commanded_distance_m(seg.spacing_m, ratio, speed_m_s)
                start = add(
                    pts["start"], Role.TRIGGER_START, trigger_spacing_m=seg.spacing_m,
                    trigger_command_m=commanded, **where,
                )  # fmt: skip
                run_at = {"start_point": start, "offsets_m": np.abs(u_stations - u_stations[0])}
                add(pts["stop"], Role.TRIGGER_STOP, **where)
            add(pts["exit"], Role.EXIT, speed_m_s=transit_speed, **where)
            true_heading = (heading - true_north_grid_deg) % 360.0
            pass_lines.append(
                FlightLine(
                    pass_index=pp.index,
                    line_index=seg.row,
                    start_xy_m=pts["start"],
                    end_xy_m=pts["stop"],
                    entry_xy_m=pts["entry"],
                    exit_xy_m=pts["exit"],
                    heading_deg=true_heading,
                )
            )
            if pp.look_heading_deg is not None:
                look, up = (pp.look_heading_deg - true_north_grid_deg) % 360.0, pp.look_heading_deg
            else:
                look, up = true_heading, up_bearing_deg(heading, spec.orientation)
            runs.append(
                PathRun(
                    pass_index=pp.index, line_index=seg.row, x_m=sx, y_m=sy, heading_true_deg=true_heading,
                    look_true_deg=look, up_deg=up, tilt_deg=pp.tilt_deg, gsd_cm=pp.centre_gsd_cm, alt_m=alt,
                    **run_at,  # type: ignore[arg-type]
                )
            )  # fmt: skip
        lines[pp.index] = tuple(pass_lines)

    if fixed_wing is not None:
        # to the approach point, around no-fly zones, then the landing sequence (planner.fixed_wing)
        approach = fixed_wing.approach_point(home_xy, position)
        for p in router.path(position, approach)[1:-1]:
            add(p, Role.TRANSIT)
        # the approach keeps its altitude (the glide slope's top)
        points.append(PathPoint(xy=approach, role=Role.APPROACH))
    else:
        # home, around no-fly zones, then RTL
        for p in router.path(position, home_xy)[1:-1]:
            add(p, Role.TRANSIT)
    points.append(PathPoint(xy=home_xy, role=Role.LANDING))
    return FlightPath(
        points=tuple(points),
        runs=tuple(runs),
        lines=lines,
        pass_alts_m=tuple(alt_sequence),
        home_xy=home_xy,
        takeoff_target_xy=takeoff_target,
        takeoff_pitch_deg=takeoff_pitch,
    )


def _segment_points(
    seg: Segment,
    direction: int,
    pp: PassPlan,
    turnaround_m: float,
    router: Router,
    lead_out_m: float | None = None,
) -> dict[str, tuple[float, float]]:
    """Lead-in (``turnaround_m``), camera-on, camera-off and lead-out (``lead_out_m``, None:
    ``turnaround_m``) points of a segment flown in ``direction``."""
    flown = dataclasses.replace(seg, direction=direction)
    start_u, stop_u = flown.camera_on_u()
    out_m = turnaround_m if lead_out_m is None else lead_out_m
    # A run that continues another of the same line has no lead-in (lead-out) on that side.
    lead_in = 0.0 if (seg.join_lo if direction > 0 else seg.join_hi) else turnaround_m
    lead_out = 0.0 if (seg.join_hi if direction > 0 else seg.join_lo) else out_m

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


def path_stations(spec: MissionSpec, frame: LocalFrame, alt_agl_m: float, path: FlightPath) -> Stations:
    """The stations of the path's runs, in flight order, over flat ground."""

    def col(get: object, dtype: type) -> NDArray:
        parts = [np.full(len(r.x_m), get(r)) for r in path.runs]  # type: ignore[operator]
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype)

    runs = path.runs
    x = np.concatenate([r.x_m for r in runs]).astype(float) if runs else np.zeros(0)
    y = np.concatenate([r.y_m for r in runs]).astype(float) if runs else np.zeros(0)
    up, tilt = col(lambda r: r.up_deg, float), col(lambda r: r.tilt_deg, float)
    n = x.shape[0]
    alt = col(lambda r: r.alt_m, float) if runs else np.full(n, alt_agl_m)
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
        pass_index=col(lambda r: r.pass_index, np.int32),
        line_index=col(lambda r: r.line_index, np.int32),
        x_m=x,
        y_m=y,
        lon_deg=np.asarray(lon, float),
        lat_deg=np.asarray(lat, float),
        alt_rel_home_m=alt.copy(),
        alt_agl_m=alt,
        heading_deg=col(lambda r: r.heading_true_deg, float),
        look_heading_deg=col(lambda r: r.look_true_deg, float),
        tilt_deg=tilt,
        gsd_cm=col(lambda r: r.gsd_cm, float),
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
