"""The flight path: what the vehicle will fly, as typed points, before any mission item exists.

Planning a survey goes in two phases, as QGroundControl's TransectStyleComplexItem does: the
path is built first (planner.mission_builder: line order, routing around no-fly zones, a
plane's turns, take-off and landing), then reshaped over the terrain (planner.terrain_follow:
altitudes, added points); the stations, the flight time and the mission items are all read from
it at the end (planner.mission_items emits the items in one pass).

Each :class:`PathPoint` holds its position in the local frame (metres), its :class:`Role`, the
pass and line it belongs to, its altitude with the altitude's reference, and what happens there
(the trigger spacing where the camera starts, a hold, a speed, the camera's pose for the line
that starts there). A point at the same place as the one before it (a run that continues the
previous run of its line) is kept for what happens there, but is no waypoint and no leg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray

from .plan import FlightLine


class Role(StrEnum):
    """What a point of the path is for."""

    #: Home, where the flight starts (the take-off climbs above it).
    TAKE_OFF = "take-off"
    #: A waypoint of a transit (around a no-fly zone, to a line, home).
    TRANSIT = "transit"
    #: A corner of a plane's turn between two lines.
    LOOP_TURN = "loop turn"
    #: The start of a line's lead-in: the end of the turnaround before it.
    ENTRY = "entry"
    #: The camera starts taking photos every ``trigger_spacing_m`` here.
    TRIGGER_START = "trigger start"
    #: The camera stops here (half a spacing past the last station).
    TRIGGER_STOP = "trigger stop"
    #: A hover station: the vehicle stops, holds and takes one photo.
    STATION = "station"
    #: The end of a line's lead-out: where the turnaround after it starts.
    EXIT = "exit"
    #: Added by terrain following, on a straight leg, to keep the height above the ground.
    TERRAIN = "terrain"
    #: A plane's landing approach: the loiter down to the approach altitude.
    APPROACH = "approach"
    #: Home at the end: the landing (or the return to launch).
    LANDING = "landing"


class AltitudeRef(StrEnum):
    """What a point's altitude is measured from."""

    #: Above home (the vehicle's barometric altitude), as every mission item sfap writes.
    HOME = "home"


#: The roles that are waypoints of the mission (the others are flown by the autopilot's own
#: take-off, loiter-down and landing).
WAYPOINT_ROLES = frozenset(
    {
        Role.TRANSIT,
        Role.LOOP_TURN,
        Role.ENTRY,
        Role.TRIGGER_START,
        Role.TRIGGER_STOP,
        Role.STATION,
        Role.EXIT,
        Role.TERRAIN,
    }
)


@dataclass(frozen=True, kw_only=True)
class CameraPose:
    """The camera's pose for a line: pitch (-90 down), yaw relative to the vehicle's heading,
    and for an oblique the true bearing it looks toward (None: nadir)."""

    pitch_deg: float
    yaw_deg: float
    look_true_deg: float | None = None


@dataclass(frozen=True, kw_only=True)
class PathPoint:
    """One point of the flight path (module docstring)."""

    xy: tuple[float, float]
    role: Role
    pass_index: int | None = None
    line_index: int | None = None
    #: Altitude, metres, from ``alt_ref``; None where the autopilot sets it (take-off, landing).
    alt_m: float | None = None
    alt_ref: AltitudeRef = AltitudeRef.HOME
    #: Seconds held at the point (hover stations).
    hold_s: float = 0.0
    #: TRIGGER_START: the ground spacing of the photos, and the distance commanded to the
    #: autopilot for it (its own measure, less half a loop step: planner.trigger).
    trigger_spacing_m: float | None = None
    trigger_command_m: float | None = None
    #: The speed flown from here on, when it changes here (m/s).
    speed_m_s: float | None = None
    #: The camera's pose from here on, set before the leg to this point (ENTRY, TAKE_OFF).
    camera: CameraPose | None = None
    #: At the same place as the point before: no waypoint and no leg of its own.
    on_previous: bool = False

    @property
    def is_waypoint(self) -> bool:
        return self.role in WAYPOINT_ROLES and not self.on_previous

    @property
    def takes_photos_on_leg(self) -> bool:
        """The leg that ends here is flown at the survey speed taking photos (camera on)."""
        return self.role in (Role.TRIGGER_STOP, Role.STATION)


@dataclass(frozen=True, kw_only=True)
class PathRun:
    """The stations of one run of a line (camera on), in flight order: where they are and how
    the camera sees from them. ``start_point``: the TRIGGER_START point they are measured from
    (``offsets_m`` along the path from it); hover runs: ``station_points``, one per station."""

    pass_index: int
    line_index: int
    x_m: NDArray[np.float64]
    y_m: NDArray[np.float64]
    heading_true_deg: float
    look_true_deg: float
    up_deg: float
    tilt_deg: float
    gsd_cm: float
    alt_m: float
    start_point: int | None = None
    offsets_m: NDArray[np.float64] | None = None
    station_points: tuple[int, ...] = ()


@dataclass(frozen=True, kw_only=True)
class FlightPath:
    """The whole flight, home to home (module docstring)."""

    points: tuple[PathPoint, ...]
    runs: tuple[PathRun, ...]
    #: The lines flown, per pass, in flight order (a pass with no lines: empty).
    lines: dict[int, tuple[FlightLine, ...]]
    #: The height of each pass flown, in order (the climbs between them take time).
    pass_alts_m: tuple[float, ...]
    home_xy: tuple[float, float]
    #: A plane's take-off: the point it climbs toward (None: straight up over home).
    takeoff_target_xy: tuple[float, float] | None = None
    #: A plane's climb-out pitch (None: a vertical take-off).
    takeoff_pitch_deg: float | None = None

    def horizontal(self) -> list[int]:
        """Indices of the points that start or end a leg (not ``on_previous``, not TERRAIN: the
        added points lie on the legs, so the horizontal track is the same without them)."""
        return [k for k, p in enumerate(self.points) if not p.on_previous and p.role is not Role.TERRAIN]

    def track_xy_m(self) -> NDArray[np.float64]:
        """The horizontal track, (M, 2): home, every leg's end, home."""
        return np.asarray([self.points[k].xy for k in self.horizontal()], float)

    def distance_along_m(self) -> list[float]:
        """The distance flown to each point of the path, metres, summed leg by leg along the
        horizontal track (a point on the previous one gets its distance; a TERRAIN point, its
        place along its leg)."""
        out: list[float] = []
        last: tuple[float, float] | None = None
        s = 0.0
        for p in self.points:
            if p.role is Role.TERRAIN and last is not None:
                out.append(s + math.dist(last, p.xy))
                continue
            if last is not None and not p.on_previous:
                s = s + math.dist(last, p.xy)
            if not p.on_previous:
                last = p.xy
            out.append(s)
        return out

    def station_distance_m(self, along: list[float] | None = None) -> NDArray[np.float64]:
        """The distance flown to each station, in flight order."""
        s = self.distance_along_m() if along is None else along
        parts: list[NDArray[np.float64]] = []
        for run in self.runs:
            if run.start_point is not None and run.offsets_m is not None:
                parts.append(s[run.start_point] + run.offsets_m)
            else:
                parts.append(np.asarray([s[k] for k in run.station_points], float))
        return np.concatenate(parts) if parts else np.zeros(0)

    def transit_legs(self) -> list[bool]:
        """Per leg of the horizontal track: True when flown camera-off (at the transit speed)."""
        idx = self.horizontal()
        return [not self.points[k].takes_photos_on_leg for k in idx[1:]]

    def holds_s(self) -> float:
        total = 0.0
        for p in self.points:
            if p.hold_s:
                total += p.hold_s
        return total

    def stops(self) -> int:
        """Hover stations (each a stop and go)."""
        return sum(1 for p in self.points if p.role is Role.STATION)
