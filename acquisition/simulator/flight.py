"""Kinematic flight of a stored mission, stepping simulated time; no sockets.

:class:`FlightSimulator` holds the vehicle's state (armed, mode, position, mission progress,
camera) and ``step(dt_s)`` advances simulated time by ``dt_s`` seconds and returns the MAVLink
messages (pymavlink message objects, not yet packed) the vehicle emits during that time: the
periodic telemetry (:mod:`.telemetry_streams`), MISSION_CURRENT on change, MISSION_ITEM_REACHED,
and the camera events at every photo (:mod:`.triggering`). Arrivals, holds and photos happen at
their exact times whatever the step size, so a flight is a function of the commands' times only
(the motion: :mod:`.kinematics`; the modes: :mod:`.modes`).

This module holds the state and the commands (arm, modes, mission start, RTL) and steps time;
the mission runs as ArduPilot's AP_Mission runs it (:mod:`.mission_execution`). A fixed-wing
vehicle flies its waypoints as ArduPlane does (:mod:`.plane`: L1 guidance, bank-limited turns,
so it settles onto a line over a distance) and climbs out along its heading at the take-off
pitch; it still "lands" vertically at the end of its approach (a simplification).

Photo decisions use the true position (as the truth of a test), the messages report the noisy
one (as a real autopilot would). :attr:`FlightSimulator.shots` keeps both for tests.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field

from planner.errors import InputError
from planner.geo import LocalFrame
from planner.mission import (
    Autopilot,
    HomePosition,
    MissionItem,
    VehicleType,
)

from .. import mavlink_messages as mm
from . import kinematics, mission_execution, modes, plane
from .kinematics import AIRBORNE_ABOVE_M, GpsNoise, HomeFrame, Leg
from .modes import Mode
from .telemetry_streams import TelemetryStreams, periodic_record
from .triggering import Camera, Gimbal, Shot, photo_records


@dataclass(frozen=True, kw_only=True)
class FlightConfig:
    """Flight model settings. Speeds m/s, rates m/s, altitudes m above home, noise m (RMS)."""

    climb_rate_m_s: float = 2.5
    descent_rate_m_s: float = 1.5
    default_speed_m_s: float | None = None  # None: 5 m/s multirotor, 15 m/s fixed wing
    rtl_alt_m: float = 15.0
    horizontal_noise_m: float = 0.3
    vertical_noise_m: float = 0.5
    attitude_noise_deg: float = 0.5
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("climb_rate_m_s", "descent_rate_m_s"):
            if not getattr(self, name) > 0:
                raise InputError(f"FlightConfig.{name} must be > 0, got {getattr(self, name)}")
        if self.default_speed_m_s is not None and not self.default_speed_m_s > 0:
            raise InputError(f"default_speed_m_s must be > 0, got {self.default_speed_m_s}")
        for name in ("horizontal_noise_m", "vertical_noise_m", "attitude_noise_deg"):
            if getattr(self, name) < 0:
                raise InputError(f"FlightConfig.{name} must be >= 0, got {getattr(self, name)}")


@dataclass
class _MissionState:
    items: list[MissionItem] = field(default_factory=list)
    current: int = 0
    started: bool = False
    complete: bool = False
    jumps_left: dict[int, int] = field(default_factory=dict)


class FlightSimulator:
    """The vehicle's flight, camera and telemetry, stepped in simulated time (module docstring).

    ``boot_utc_s`` is the UTC time (POSIX s) of simulated time 0; ``gps_fix_s`` when the GPS
    gets its fix (home is set then, arming allowed). Not thread-safe: the server locks.
    """

    def __init__(
        self,
        *,
        autopilot: Autopilot,
        vehicle_type: VehicleType,
        home: HomePosition,
        config: FlightConfig | None = None,
        gps_fix_s: float = 1.0,
        boot_utc_s: float = 1.7e9,
        streams_on_request: bool = False,
    ) -> None:
        self.autopilot = Autopilot(autopilot)
        self.vehicle_type = VehicleType(vehicle_type)
        self.home = home
        self.config = config or FlightConfig()
        self.gps_fix_s = gps_fix_s
        self.boot_utc_s = boot_utc_s
        self._home_frame = HomeFrame(home)
        self.time_s = 0.0
        self.pos = [0.0, 0.0, 0.0]  # east, north, up above home (m)
        self.vel = (0.0, 0.0, 0.0)
        self.heading_deg = 0.0
        self.armed = False
        self.mode = Mode.MANUAL
        self.speed_m_s = self.config.default_speed_m_s or (
            15.0 if self.vehicle_type is VehicleType.FIXED_WING else 5.0
        )
        self.has_flown = False
        self.has_landed_after_flight = False
        self.mission = _MissionState()
        self.mission_id = 0
        self.camera = Camera()
        self.gimbal = Gimbal()
        self.gimbal_commanded = False
        self.shots: list[Shot] = []
        self.reached: list[tuple[float, int]] = []
        self.legs: list[Leg] = []
        self.after_legs: str | None = None  # "nav_done", "landed"
        # a plane's guidance (plane): its tuning, the last update's tick and turn rate, the
        # waypoint it last reached (the start of its next track; None: from where it is)
        self.plane_tuning = plane.PlaneTuning()
        self.plane_tick = -1
        self.plane_rate_rad_s = 0.0
        self.plane_bank_rad = 0.0
        self.plane_last_wp: tuple[float, float] | None = None
        self._out: list[tuple[float, object]] = []  # event messages with their times
        self._out_timed: list[tuple[float, object]] | None = None
        c = self.config
        self._noise = GpsNoise(c.seed, c.horizontal_noise_m, c.vertical_noise_m, c.attitude_noise_deg)
        self._streams = TelemetryStreams(streams_on_request)

    # --- telemetry rates (telemetry_streams) -------------------------------------------------

    @property
    def telemetry_requested(self) -> bool:
        """True once a ground station asked for a telemetry stream."""
        return self._streams.requested

    def set_message_interval(self, message_id: int, interval_us: float) -> bool:
        """MAV_CMD_SET_MESSAGE_INTERVAL (:meth:`.TelemetryStreams.set_message_interval`)."""
        return self._streams.set_message_interval(message_id, interval_us, self.time_s)

    def request_data_stream(self, stream_id: int, rate_hz: float, start: bool) -> None:
        """REQUEST_DATA_STREAM (:meth:`.TelemetryStreams.request_data_stream`)."""
        self._streams.request_data_stream(stream_id, rate_hz, start, self.time_s)

    def stream_rates_hz(self) -> dict[str, float]:
        """Every stream's rate now (Hz of simulated time; 0 = not sent)."""
        return self._streams.rates_hz()

    # --- clocks and identity ------------------------------------------------------------------

    @property
    def frame(self) -> LocalFrame:
        """The local frame centred on home (x east, y north, metres)."""
        return self._home_frame.frame

    @property
    def utc_s(self) -> float:
        return self.boot_utc_s + self.time_s

    @property
    def gps_has_fix(self) -> bool:
        return self.time_s >= self.gps_fix_s

    @property
    def airborne(self) -> bool:
        return self.pos[2] > AIRBORNE_ABOVE_M

    @property
    def landed_state(self) -> int:
        """MAV_LANDED_STATE: 1 on the ground, 2 in the air, 3 taking off, 4 landing."""
        if not self.airborne:
            return 1
        vz = self.vel[2]
        if vz > 0.1 and self.pos[2] < 5.0:
            return 3
        if vz < -0.1 and self.after_legs == "landed":
            return 4
        return 2

    def move_home(self, home: HomePosition) -> None:
        """Put the vehicle (on the ground, never flown) at ``home``: the frame is rebuilt there."""
        if self.has_flown or self.armed:
            raise InputError("the vehicle has flown or is armed; its home cannot move now")
        self.home = home
        self._home_frame = HomeFrame(home)
        self.pos = [0.0, 0.0, 0.0]
        self.camera.last_xy = None

    @property
    def first_index(self) -> int:
        return 1 if self.autopilot is Autopilot.ARDUPILOT else 0

    # --- mission and commands -----------------------------------------------------------------

    def set_mission(self, items: list[MissionItem]) -> None:
        """The stored mission as read back (ArduPilot: home at 0)."""
        if list(items) != self.mission.items:
            # MISSION_CURRENT.mission_id: an id that changes with the mission (PX4 sends a
            # CRC32 of the items; 0 is "no mission")
            body = items[self.first_index :]
            self.mission_id = zlib.crc32(repr(body).encode()) or 1 if body else 0
        self.mission.items = list(items)
        if self.mission.current >= len(items):
            self.mission.current = max(0, len(items) - 1)

    def set_current(self, seq: int) -> None:
        if 0 <= seq < len(self.mission.items):
            self.mission.current = seq
            if self.mode is Mode.AUTO and self.armed:
                mission_execution.start_nav(self, seq)

    @property
    def has_mission(self) -> bool:
        """True when a mission with at least one item is loaded."""
        return self._has_mission()

    def _has_mission(self) -> bool:
        return len(self.mission.items) > self.first_index

    def arm(self) -> tuple[bool, str]:
        if self.armed:
            return True, ""
        if not self.gps_has_fix:
            return False, "PreArm: Need 3D Fix"
        self.armed = True
        self.has_landed_after_flight = False
        if self.mode is Mode.AUTO:
            mission_execution.begin_mission(self, restart=not self.mission.started or self.mission.complete)
        return True, ""

    def disarm(self, force: bool = False) -> tuple[bool, str]:
        if self.airborne and not force:
            return False, "Disarm: vehicle is flying"
        self.armed = False
        self.legs = []
        self.vel = (0.0, 0.0, 0.0)
        return True, ""

    def split_custom_mode(self, custom_mode: int) -> tuple[int, int]:
        """SET_MODE's custom_mode as DO_SET_MODE's (param2, param3)."""
        return modes.split_custom_mode(self.autopilot, custom_mode)

    def set_mode(self, base_mode: int, p2: int, p3: int = 0) -> bool:
        """DO_SET_MODE (param1 base mode, param2 custom/main mode, param3 PX4 sub mode)."""
        if not modes.is_custom_mode(base_mode):
            return False
        mode = modes.mode_from_numbers(self.autopilot, self.vehicle_type, p2, p3)
        if mode is None:
            return False
        if mode is Mode.AUTO:
            if not self._has_mission():
                return False
            previous = self.mode
            self.mode = Mode.AUTO
            if self.armed and previous is not Mode.AUTO:
                mission_execution.begin_mission(
                    self, restart=not self.mission.started or self.mission.complete
                )
            return True
        self.mode = mode
        if mode is Mode.RTL:
            mission_execution.plan_rtl(self)
        elif mode is Mode.LAND:
            mission_execution.plan_land_here(self)
        else:
            self.legs = [Leg(None, forever=True)] if self.airborne else []
            self.after_legs = None
        return True

    def start_mission(self) -> tuple[bool, str]:
        """MAV_CMD_MISSION_START: AUTO from the first item."""
        if not self._has_mission():
            return False, "Mission start: no mission"
        if not self.armed:
            return False, "Mission start: arm first"
        self.mode = Mode.AUTO
        mission_execution.begin_mission(self, restart=True)
        return True, ""

    def return_to_launch(self) -> bool:
        if not self.armed:
            return False
        self.mode = Mode.RTL
        mission_execution.plan_rtl(self)
        return True

    # --- camera (triggering) ------------------------------------------------------------------

    def take_photo(self) -> None:
        """A photo now at the current position (AP_Camera::take_picture)."""
        if not self.gps_has_fix:
            return
        cam = self.camera
        cam.count += 1
        cam.last_xy = (self.pos[0], self.pos[1])
        index = cam.count if self.autopilot is Autopilot.ARDUPILOT else cam.count - 1
        lat, lon = self._home_frame.latlon(self.pos[0], self.pos[1])
        rlat, rlon, ralt = self.reported_position()
        shot = Shot(
            time_s=self.time_s,
            utc_s=self.utc_s,
            index=index,
            x_m=self.pos[0],
            y_m=self.pos[1],
            lat_deg=lat,
            lon_deg=lon,
            alt_rel_home_m=self.pos[2],
            reported_lat_deg=rlat,
            reported_lon_deg=rlon,
            reported_alt_rel_home_m=ralt,
            gimbal_pitch_deg=self.gimbal.pitch_deg,
            mission_seq=self.mission.current,
        )
        self.shots.append(shot)
        for record in photo_records(self.autopilot, shot, self.attitude_deg(), self.home.alt_amsl_m):
            self.queue_message(record.to_message())

    def timed_capture(self) -> None:
        self.take_photo()
        self.camera.timed_photo_taken(self.time_s)

    def distance_trigger(self, start: tuple[float, float], end: tuple[float, float]) -> list[float]:
        """Fractions of the piece start->end at which distance triggering fires (exact)."""
        if not self.gps_has_fix:
            return []
        return self.camera.distance_crossings(start, end)

    # --- motion (kinematics) ------------------------------------------------------------------

    def flying_allowed(self) -> bool:
        return self.armed and self.mode in modes.FLYING_MODES

    def finish_legs(self) -> None:
        """The legs are flown (:func:`.mission_execution.finish_legs`)."""
        mission_execution.finish_legs(self)

    # --- telemetry (telemetry_streams) --------------------------------------------------------

    def reported_position(self) -> tuple[float, float, float]:
        """(lat_deg, lon_deg, alt_rel_home_m) the GPS reports now (true position + noise)."""
        x, y, z = self._noise.position(self.pos, self.time_s, self.airborne)
        lat, lon = self._home_frame.latlon(x, y)
        return lat, lon, z

    def attitude_deg(self) -> tuple[float, float, float]:
        """(roll, pitch, yaw) degrees the vehicle reports now."""
        return self._noise.attitude_deg(
            self.vel, self.heading_deg, self.vehicle_type, self.time_s, self.airborne
        )

    def heartbeat(self) -> mm.Heartbeat:
        return modes.heartbeat(self.autopilot, self.vehicle_type, self.mode, self.armed)

    def heartbeat_message(self) -> object:
        return self.heartbeat().to_message()

    def home_position_message(self) -> object | None:
        if not self.gps_has_fix:
            return None
        return mm.home_position_message(self.home, self.utc_s)

    def queue_message(self, msg: object) -> None:
        self._out.append((self.time_s, msg))

    def queue_mission_current(self) -> None:
        self.queue_message(self.mission_current().to_message())

    def drain_events(self) -> list[tuple[float, object]]:
        """Event messages queued outside :meth:`step` (by a command), with their times."""
        out, self._out = self._out, []
        return out

    def mission_current(self) -> mm.MissionCurrent:
        m = self.mission
        total = len(m.items)
        if total <= self.first_index:
            state = 1  # NO_MISSION
        elif m.complete:
            state = 5
        elif m.started and self.mode is Mode.AUTO:
            state = 3
        elif m.started:
            state = 4
        else:
            state = 2
        return mm.MissionCurrent(seq=m.current, total=total, mission_state=state)

    def step(self, dt_s: float) -> list[object]:
        """Advance simulated time by ``dt_s`` s; the messages emitted meanwhile, in time order."""
        return [msg for _, msg in self.step_timed(dt_s)]

    def step_timed(self, dt_s: float) -> list[tuple[float, object]]:
        """As :meth:`step`, each message with its emission time (simulated s since boot)."""
        if dt_s < 0 or not math.isfinite(dt_s):
            raise InputError(f"dt_s is {dt_s}; give a finite time step >= 0")
        out: list[tuple[float, object]] = []
        end = self.time_s + dt_s
        self._out_timed = out
        try:
            while True:
                nxt = self._streams.next_due_s()
                target = min(end, nxt)
                if target > self.time_s:
                    kinematics.advance(self, target - self.time_s)
                else:
                    self._settle()
                self._collect()
                if nxt > end + 1e-12:
                    break
                for name in self._streams.take_due(self.time_s):
                    record = periodic_record(self, name)
                    if record is not None:
                        out.append((self.time_s, record.to_message()))
                if target >= end:
                    break
        finally:
            self._out_timed = None
        self.time_s = max(self.time_s, end)
        return out

    def _collect(self) -> None:
        """Move event messages (stamped when queued) to the step's output."""
        if self._out_timed is not None:
            self._out_timed.extend(self._out)
        self._out = []

    def _settle(self) -> None:
        """Run zero-time events (a finished leg) so that commands take effect at once."""
        guard = 0
        while self.flying_allowed() and not self.legs and self.after_legs is not None:
            guard += 1
            if guard > 10_000:
                break
            mission_execution.finish_legs(self)
