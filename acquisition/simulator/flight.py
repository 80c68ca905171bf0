"""Kinematic flight of a stored mission, stepping simulated time; no sockets.

:class:`FlightSimulator` holds the vehicle's state (armed, mode, position, mission progress,
camera) and ``step(dt_s)`` advances simulated time by ``dt_s`` seconds and returns the MAVLink
messages (pymavlink message objects, not yet packed) the vehicle emits during that time:
HEARTBEAT 1 Hz, SYSTEM_TIME 1 Hz, GLOBAL_POSITION_INT 10 Hz, ATTITUDE 10 Hz, GPS_RAW_INT 5 Hz,
MISSION_CURRENT 1 Hz and on change, MISSION_ITEM_REACHED, MOUNT_STATUS (ArduPilot) or
GIMBAL_DEVICE_ATTITUDE_STATUS (PX4) 1 Hz once a gimbal was commanded, and at every photo
CAMERA_FEEDBACK (ArduPilot) or CAMERA_TRIGGER + CAMERA_IMAGE_CAPTURED (PX4).

Telemetry rates (``streams_on_request``): a real ArduPilot sends nothing but HEARTBEAT (and
the messages it sends on events: STATUSTEXT, MISSION_CURRENT on change, MISSION_ITEM_REACHED,
CAMERA_FEEDBACK) until a ground station asks, because its SRx_ stream rates default to 0 on
its serial ports. With ``streams_on_request`` the periodic streams start at 0 and follow
MAV_CMD_SET_MESSAGE_INTERVAL (:meth:`FlightSimulator.set_message_interval`) and the legacy
REQUEST_DATA_STREAM (:meth:`FlightSimulator.request_data_stream`, grouped as ArduCopter's
GCS_Mavlink.cpp groups them: :data:`DATA_STREAM_GROUPS`); without it they run at the rates
above from boot (as PX4 does). EXTENDED_SYS_STATE (landed state) is sent only when asked.
The rates are the vehicle's, not one per ground station (ArduPilot keeps them per port).

The motion is exact and piecewise linear: every leg is a straight line flown at the commanded
horizontal speed, its vertical part limited by the climb or descent rate; arrivals, holds and
photos happen at their exact times whatever the step size, so a flight is a function of the
commands' times only. Positions live in an azimuthal equidistant frame centred on home
(pyproj, WGS84), in which distances from home are exact and local distances are correct to
about 1e-6 within a few kilometres.

Mission semantics follow ArduPilot's AP_Mission (PX4 does the same for these commands): the
DO commands that follow a NAV command run when that NAV command completes (those before the
first NAV command run at the start); DO_SET_CAM_TRIGG_DIST sets the distance and, with
param3 = 1, takes one photo at once; distance triggering takes a photo whenever the horizontal
straight-line distance from the last photo's position reaches the distance (AP_Camera), with
the crossing solved exactly (ArduPilot checks at 50 Hz, which adds up to speed / 50 m);
distance 0 stops it. IMAGE_START_CAPTURE takes ``total`` photos every ``interval`` seconds
(1 and 0: one photo now). RTL climbs to ``rtl_alt_m`` if lower, flies home, descends and
disarms, as ArduCopter does. A fixed-wing vehicle is flown with the same kinematics (it climbs
vertically at take-off and "lands" vertically at home: a simplification).

The reported positions carry GPS noise: a smooth, seeded function of time (a sum of
sinusoids with periods 8-90 s, RMS ``horizontal_noise_m`` per axis and ``vertical_noise_m``),
so it is deterministic and independent of the step size. Photo decisions use the true
position (as the truth of a test), the messages report the noisy one (as a real autopilot
would). :attr:`FlightSimulator.shots` keeps both for tests.

CAMERA_FEEDBACK.time_usec is the photo's UTC time in microseconds since the Unix epoch, as
ArduPilot derives it from GPS time (AP_GPS::time_epoch_usec) when no feedback pin is set.
"""

from __future__ import annotations

import math
import random
import zlib
from dataclasses import dataclass, field
from enum import Enum

from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from pyproj import CRS, Transformer

from planner.errors import InputError
from planner.geo import WGS84, LocalFrame
from planner.mission import (
    Autopilot,
    HomePosition,
    MavCmd,
    MavFrame,
    MissionItem,
    VehicleType,
)

M = mavlink2

#: ArduCopter / ArduPlane custom mode numbers (ArduPilot's mode tables).
COPTER_MODES = {"STABILIZE": 0, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9}
PLANE_MODES = {"MANUAL": 0, "AUTO": 10, "RTL": 11, "LOITER": 12, "GUIDED": 15}
#: PX4 main modes and AUTO sub-modes (px4_custom_mode.h).
PX4_MAIN_MANUAL, PX4_MAIN_POSCTL, PX4_MAIN_AUTO = 1, 3, 4
PX4_SUB_AUTO = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5, "LAND": 6}

_MAV_MODE_FLAG_CUSTOM_MODE_ENABLED = 1
_MAV_MODE_FLAG_AUTO_ENABLED = 4
_MAV_MODE_FLAG_GUIDED_ENABLED = 8
_MAV_MODE_FLAG_STABILIZE_ENABLED = 16
_MAV_MODE_FLAG_SAFETY_ARMED = 128

GPS_EPOCH_UNIX_S = 315964800.0  # 1980-01-06 00:00:00 UTC


class Mode(Enum):
    """What the vehicle is doing, whatever its autopilot calls it."""

    MANUAL = "manual"  # STABILIZE / MANUAL / POSCTL: holds still in this simulator
    AUTO = "auto"
    GUIDED = "guided"
    LOITER = "loiter"
    RTL = "rtl"
    LAND = "land"


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


@dataclass(frozen=True, kw_only=True)
class Shot:
    """One photo: truth and what the vehicle reported.

    ``time_s`` simulated seconds since boot; ``utc_s`` POSIX seconds; ``index`` the image
    index reported (ArduPilot img_idx from 1, PX4 image_index from 0); ``x_m``/``y_m`` east and
    north of home (true); ``lat_deg``/``lon_deg``/``alt_rel_home_m`` true position;
    ``reported_*`` the noisy position in the message; ``gimbal_pitch_deg`` the gimbal pitch
    commanded then (None: no gimbal command yet); ``mission_seq`` the current mission item.
    """

    time_s: float
    utc_s: float
    index: int
    x_m: float
    y_m: float
    lat_deg: float
    lon_deg: float
    alt_rel_home_m: float
    reported_lat_deg: float
    reported_lon_deg: float
    reported_alt_rel_home_m: float
    gimbal_pitch_deg: float | None
    mission_seq: int


@dataclass
class _Leg:
    """A straight move to ``target`` (x, y, z m, z above home), or a wait (target None)."""

    target: tuple[float, float, float] | None
    wait_s: float = 0.0
    forever: bool = False


class _SmoothNoise:
    """A smooth seeded random function of time: a sum of sinusoids, RMS ``sigma``."""

    def __init__(self, rng: random.Random, sigma: float, n: int = 4) -> None:
        self.terms = [
            (rng.uniform(8.0, 90.0), rng.uniform(0.0, 2 * math.pi), rng.uniform(0.5, 1.0)) for _ in range(n)
        ]
        power = sum(a * a / 2 for _, _, a in self.terms)
        self.scale = sigma / math.sqrt(power) if power > 0 else 0.0

    def __call__(self, t_s: float) -> float:
        return self.scale * sum(a * math.sin(2 * math.pi * t_s / p + ph) for p, ph, a in self.terms)


@dataclass
class _Stream:
    """One periodic message. ``period_s`` 0: not sent (ArduPilot's rate 0)."""

    name: str
    default_period_s: float
    period_s: float = 0.0
    next_s: float = 0.0


#: MAVLink message id -> the stream that sends it (what SET_MESSAGE_INTERVAL can change).
STREAM_OF_MESSAGE_ID = {
    0: "HEARTBEAT",
    2: "SYSTEM_TIME",
    33: "GLOBAL_POSITION_INT",
    30: "ATTITUDE",
    24: "GPS_RAW_INT",
    42: "MISSION_CURRENT",
    245: "EXTENDED_SYS_STATE",
    158: "GIMBAL",  # MOUNT_STATUS (ArduPilot)
    285: "GIMBAL",  # GIMBAL_DEVICE_ATTITUDE_STATUS (PX4)
}
#: REQUEST_DATA_STREAM's MAV_DATA_STREAM groups, as ArduCopter's GCS_Mavlink.cpp files the
#: messages this simulator sends: EXTENDED_STATUS (2) GPS_RAW_INT and MISSION_CURRENT;
#: POSITION (6) GLOBAL_POSITION_INT; EXTRA1 (10) ATTITUDE; EXTRA3 (12) SYSTEM_TIME and the
#: gimbal's attitude. MAV_DATA_STREAM_ALL (0) is every group.
DATA_STREAM_GROUPS: dict[int, tuple[str, ...]] = {
    2: ("GPS_RAW_INT", "MISSION_CURRENT"),
    6: ("GLOBAL_POSITION_INT",),
    10: ("ATTITUDE",),
    12: ("SYSTEM_TIME", "GIMBAL"),
}


@dataclass
class _Camera:
    trigger_distance_m: float = 0.0
    last_xy: tuple[float, float] | None = None
    interval_s: float = 0.0
    remaining: int = 0  # timed capture: photos left; -1 = until stopped
    next_capture_s: float = math.inf
    count: int = 0


@dataclass
class _Gimbal:
    pitch_deg: float | None = None
    yaw_deg: float = 0.0
    roll_deg: float = 0.0


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
        crs = CRS.from_proj4(
            f"+proj=aeqd +lat_0={home.lat_deg!r} +lon_0={home.lon_deg!r} +datum=WGS84 +units=m +no_defs"
        )
        self.frame = LocalFrame.from_crs(crs)
        # scalar transforms, several times faster than the array API, for the telemetry
        self._lonlat_from_xy = Transformer.from_crs(crs, WGS84, always_xy=True)
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
        self.camera = _Camera()
        self.gimbal = _Gimbal()
        self.gimbal_commanded = False
        self.shots: list[Shot] = []
        self.reached: list[tuple[float, int]] = []
        self._legs: list[_Leg] = []
        self._after_legs: str | None = None  # "nav_done", "landed"
        self._out: list[tuple[float, object]] = []  # event messages with their times
        self._out_timed: list[tuple[float, object]] | None = None
        self._last_current_sent = -1
        rng = random.Random(self.config.seed)
        self._noise_e = _SmoothNoise(rng, self.config.horizontal_noise_m)
        self._noise_n = _SmoothNoise(rng, self.config.horizontal_noise_m)
        self._noise_u = _SmoothNoise(rng, self.config.vertical_noise_m)
        self._noise_att = [_SmoothNoise(rng, self.config.attitude_noise_deg) for _ in range(3)]
        self._streams = [
            _Stream("HEARTBEAT", 1.0),
            _Stream("SYSTEM_TIME", 1.0),
            _Stream("GLOBAL_POSITION_INT", 0.1),
            _Stream("ATTITUDE", 0.1),
            _Stream("GPS_RAW_INT", 0.2),
            _Stream("MISSION_CURRENT", 1.0),
            _Stream("GIMBAL", 1.0),
            _Stream("EXTENDED_SYS_STATE", 1.0),
        ]
        # ArduPilot sends only HEARTBEAT until a ground station asks (its SRx_ rates are 0);
        # EXTENDED_SYS_STATE is in none of its stream groups: only SET_MESSAGE_INTERVAL starts it.
        for stream in self._streams:
            asked_only = streams_on_request or stream.name == "EXTENDED_SYS_STATE"
            stream.period_s = 0.0 if asked_only and stream.name != "HEARTBEAT" else stream.default_period_s
        #: True once a ground station asked for a telemetry stream.
        self.telemetry_requested = False

    # --- telemetry rates ---------------------------------------------------------------------

    def _stream(self, name: str) -> _Stream:
        return next(s for s in self._streams if s.name == name)

    def _set_period(self, name: str, period_s: float) -> None:
        stream = self._stream(name)
        if period_s > 0 and stream.period_s <= 0:
            stream.next_s = self.time_s  # the first one at once
        elif period_s > 0:
            stream.next_s = min(stream.next_s, self.time_s + period_s)
        stream.period_s = max(period_s, 0.0)
        if period_s > 0 and name != "HEARTBEAT":
            self.telemetry_requested = True

    def set_message_interval(self, message_id: int, interval_us: float) -> bool:
        """MAV_CMD_SET_MESSAGE_INTERVAL: ``interval_us`` > 0 that period (simulated
        microseconds), 0 the default rate, -1 stop. False for a message this vehicle cannot send."""
        name = STREAM_OF_MESSAGE_ID.get(int(message_id))
        if name is None or not math.isfinite(interval_us) or interval_us < -1:
            return False
        if interval_us == 0:
            period = self._stream(name).default_period_s
        elif interval_us < 0:
            period = 0.0
        else:
            period = max(interval_us / 1e6, 0.001)
        self._set_period(name, period)
        return True

    def request_data_stream(self, stream_id: int, rate_hz: float, start: bool) -> None:
        """REQUEST_DATA_STREAM (the legacy way): every message of the group at ``rate_hz``
        (ArduPilot stores it as its SRx_ rate), or off when ``start`` is 0 or the rate 0."""
        groups = DATA_STREAM_GROUPS.values() if stream_id == 0 else [DATA_STREAM_GROUPS.get(stream_id, ())]
        period = 1.0 / rate_hz if start and rate_hz > 0 else 0.0
        for group in groups:
            for name in group:
                self._set_period(name, period)

    def stream_rates_hz(self) -> dict[str, float]:
        """Every stream's rate now (Hz of simulated time; 0 = not sent)."""
        return {s.name: (1.0 / s.period_s if s.period_s > 0 else 0.0) for s in self._streams}

    # --- clocks and identity ------------------------------------------------------------------

    @property
    def utc_s(self) -> float:
        return self.boot_utc_s + self.time_s

    @property
    def gps_has_fix(self) -> bool:
        return self.time_s >= self.gps_fix_s

    @property
    def airborne(self) -> bool:
        return self.pos[2] > 0.05

    @property
    def landed_state(self) -> int:
        """MAV_LANDED_STATE: 1 on the ground, 2 in the air, 3 taking off, 4 landing."""
        if not self.airborne:
            return 1
        vz = self.vel[2]
        if vz > 0.1 and self.pos[2] < 5.0:
            return 3
        if vz < -0.1 and self._after_legs == "landed":
            return 4
        return 2

    def move_home(self, home: HomePosition) -> None:
        """Put the vehicle (on the ground, never flown) at ``home``: the frame is rebuilt there."""
        if self.has_flown or self.armed:
            raise InputError("the vehicle has flown or is armed; its home cannot move now")
        self.home = home
        crs = CRS.from_proj4(
            f"+proj=aeqd +lat_0={home.lat_deg!r} +lon_0={home.lon_deg!r} +datum=WGS84 +units=m +no_defs"
        )
        self.frame = LocalFrame.from_crs(crs)
        self._lonlat_from_xy = Transformer.from_crs(crs, WGS84, always_xy=True)
        self.pos = [0.0, 0.0, 0.0]
        self.camera.last_xy = None

    @property
    def _first_index(self) -> int:
        return 1 if self.autopilot is Autopilot.ARDUPILOT else 0

    # --- mission and commands -----------------------------------------------------------------

    def set_mission(self, items: list[MissionItem]) -> None:
        """The stored mission as read back (ArduPilot: home at 0)."""
        if list(items) != self.mission.items:
            # MISSION_CURRENT.mission_id: an id that changes with the mission (PX4 sends a
            # CRC32 of the items; 0 is "no mission")
            body = items[self._first_index :]
            self.mission_id = zlib.crc32(repr(body).encode()) or 1 if body else 0
        self.mission.items = list(items)
        if self.mission.current >= len(items):
            self.mission.current = max(0, len(items) - 1)

    def set_current(self, seq: int) -> None:
        if 0 <= seq < len(self.mission.items):
            self.mission.current = seq
            if self.mode is Mode.AUTO and self.armed:
                self._start_nav(seq)

    @property
    def has_mission(self) -> bool:
        """True when a mission with at least one item is loaded."""
        return self._has_mission()

    def _has_mission(self) -> bool:
        return len(self.mission.items) > self._first_index

    def arm(self) -> tuple[bool, str]:
        if self.armed:
            return True, ""
        if not self.gps_has_fix:
            return False, "PreArm: Need 3D Fix"
        self.armed = True
        self.has_landed_after_flight = False
        if self.mode is Mode.AUTO:
            self._begin_mission(restart=not self.mission.started or self.mission.complete)
        return True, ""

    def disarm(self, force: bool = False) -> tuple[bool, str]:
        if self.airborne and not force:
            return False, "Disarm: vehicle is flying"
        self.armed = False
        self._legs = []
        self.vel = (0.0, 0.0, 0.0)
        return True, ""

    def split_custom_mode(self, custom_mode: int) -> tuple[int, int]:
        """SET_MODE's custom_mode as DO_SET_MODE's (param2, param3)."""
        if self.autopilot is Autopilot.PX4:
            return (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
        return int(custom_mode), 0

    def _mode_from_numbers(self, p2: int, p3: int) -> Mode | None:
        if self.autopilot is Autopilot.PX4:
            if p2 == PX4_MAIN_AUTO:
                for name, sub in PX4_SUB_AUTO.items():
                    if sub == p3:
                        return {
                            "MISSION": Mode.AUTO,
                            "RTL": Mode.RTL,
                            "LAND": Mode.LAND,
                            "LOITER": Mode.LOITER,
                        }.get(name, Mode.LOITER)
                return None
            if p2 in (PX4_MAIN_MANUAL, 2, PX4_MAIN_POSCTL):
                return Mode.MANUAL
            return None
        table = PLANE_MODES if self.vehicle_type is VehicleType.FIXED_WING else COPTER_MODES
        for name, number in table.items():
            if number == p2:
                return {
                    "AUTO": Mode.AUTO,
                    "GUIDED": Mode.GUIDED,
                    "LOITER": Mode.LOITER,
                    "RTL": Mode.RTL,
                    "LAND": Mode.LAND,
                }.get(name, Mode.MANUAL)
        return None

    def set_mode(self, base_mode: int, p2: int, p3: int = 0) -> bool:
        """DO_SET_MODE (param1 base mode, param2 custom/main mode, param3 PX4 sub mode)."""
        if not base_mode & _MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return False
        mode = self._mode_from_numbers(p2, p3)
        if mode is None:
            return False
        if mode is Mode.AUTO:
            if not self._has_mission():
                return False
            previous = self.mode
            self.mode = Mode.AUTO
            if self.armed and previous is not Mode.AUTO:
                self._begin_mission(restart=not self.mission.started or self.mission.complete)
            return True
        self.mode = mode
        if mode is Mode.RTL:
            self._plan_rtl()
        elif mode is Mode.LAND:
            self._plan_land_here()
        else:
            self._legs = [_Leg(None, forever=True)] if self.airborne else []
            self._after_legs = None
        return True

    def start_mission(self) -> tuple[bool, str]:
        """MAV_CMD_MISSION_START: AUTO from the first item."""
        if not self._has_mission():
            return False, "Mission start: no mission"
        if not self.armed:
            return False, "Mission start: arm first"
        self.mode = Mode.AUTO
        self._begin_mission(restart=True)
        return True, ""

    def return_to_launch(self) -> bool:
        if not self.armed:
            return False
        self.mode = Mode.RTL
        self._plan_rtl()
        return True

    def _begin_mission(self, restart: bool) -> None:
        m = self.mission
        if restart:
            m.current = self._first_index
            m.complete = False
            m.jumps_left = {}
        m.started = True
        self._run_do_commands_from(m.current)

    # --- mission execution --------------------------------------------------------------------

    def _item_xyz(self, item: MissionItem) -> tuple[float, float, float]:
        frame = MavFrame(int(item.frame))
        if frame in (MavFrame.GLOBAL, MavFrame.GLOBAL_INT):
            z = item.alt_m - self.home.alt_amsl_m
        else:  # relative to home; terrain frames are flat at home level in this simulator
            z = item.alt_m
        if item.lat_deg == 0.0 and item.lon_deg == 0.0:
            return self.pos[0], self.pos[1], z
        x, y = self.frame.to_xy(item.lon_deg, item.lat_deg)
        return float(x), float(y), z

    def _run_do_commands_from(self, index: int) -> None:
        """Run DO commands from ``index`` up to the next NAV command, then start that one."""
        items = self.mission.items
        i = index
        guard = 0
        while i < len(items):
            guard += 1
            if guard > 10_000:
                break
            item = items[i]
            if _is_nav(item.command):
                self._start_nav(i)
                return
            jump = self._do_command(i, item)
            i = jump if jump is not None else i + 1
        self.mission.current = max(len(items) - 1, 0)
        self._mission_complete()

    def _mission_complete(self) -> None:
        self.mission.complete = True
        self._legs = [_Leg(None, forever=True)] if self.airborne else []
        self._after_legs = None

    def _start_nav(self, index: int) -> None:
        m = self.mission
        m.current = index
        item = m.items[index]
        cmd = int(item.command)
        self._legs = []
        self._after_legs = "nav_done"
        copter = self.vehicle_type is not VehicleType.FIXED_WING
        if cmd == MavCmd.NAV_TAKEOFF:
            _, _, z = self._item_xyz(item)
            self._legs = [_Leg((self.pos[0], self.pos[1], max(z, self.pos[2])))]
            self.has_flown = True
        elif cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
            self._plan_rtl(from_mission=True)
        elif cmd in (MavCmd.NAV_LAND, MavCmd.NAV_VTOL_LAND):
            x, y, _ = self._item_xyz(item)
            self._legs = [_Leg((x, y, self.pos[2])), _Leg((x, y, 0.0))]
            self._after_legs = "landed"
        else:
            target = self._item_xyz(item)
            if not self.airborne and target[2] > 0:
                self.has_flown = True
            self._legs = [_Leg(target)]
            hold = 0.0
            waypoint = cmd in (MavCmd.NAV_WAYPOINT, MavCmd.NAV_SPLINE_WAYPOINT)
            if (waypoint and copter) or cmd == MavCmd.NAV_LOITER_TIME:
                hold = float(item.param1 or 0.0)  # Plane ignores a waypoint's hold time
            if cmd == MavCmd.NAV_LOITER_UNLIM:
                self._legs.append(_Leg(None, forever=True))
            elif hold > 0:
                self._legs.append(_Leg(None, wait_s=hold))
        self._queue_mission_current()

    def _nav_done(self) -> None:
        m = self.mission
        seq = m.current
        self.reached.append((self.time_s, seq))
        self._queue(M.MAVLink_mission_item_reached_message(seq))
        self._run_do_commands_from(seq + 1)

    def _do_command(self, index: int, item: MissionItem) -> int | None:
        """Run one DO command; returns the index to continue at for DO_JUMP."""
        cmd = int(item.command)
        p = [0.0 if v is None else float(v) for v in item.params]
        self.mission.current = index
        if cmd == MavCmd.DO_CHANGE_SPEED:
            if p[1] > 0:
                self.speed_m_s = p[1]
        elif cmd == MavCmd.DO_SET_CAM_TRIGG_DIST:
            self.camera.trigger_distance_m = max(p[0], 0.0)
            if p[2] == 1:
                self._take_photo()
        elif cmd == MavCmd.IMAGE_START_CAPTURE:
            interval, total = p[1], int(p[2])
            if interval <= 0 or total == 1:
                self._take_photo()
            else:
                self.camera.interval_s = interval
                self.camera.remaining = total if total > 0 else -1
                self._take_photo()
                if self.camera.remaining > 0:
                    self.camera.remaining -= 1
                self._schedule_capture()
        elif cmd == MavCmd.IMAGE_STOP_CAPTURE:
            self.camera.remaining = 0
            self.camera.next_capture_s = math.inf
        elif cmd == MavCmd.DO_SET_CAM_TRIGG_INTERVAL:
            if p[0] > 0:
                self.camera.interval_s = p[0] / 1000.0
                self.camera.remaining = -1
                self._schedule_capture()
            else:
                self.camera.remaining = 0
                self.camera.next_capture_s = math.inf
        elif cmd == MavCmd.DO_DIGICAM_CONTROL:
            if p[4] == 1:
                self._take_photo()
        elif cmd == MavCmd.DO_MOUNT_CONTROL:
            self.gimbal = _Gimbal(pitch_deg=p[0], roll_deg=p[1], yaw_deg=p[2])
            self.gimbal_commanded = True
        elif cmd == MavCmd.DO_GIMBAL_MANAGER_PITCHYAW:
            self.gimbal = _Gimbal(pitch_deg=p[0], yaw_deg=p[1])
            self.gimbal_commanded = True
        elif cmd == MavCmd.DO_JUMP:
            target, repeat = int(p[0]), int(p[1])
            left = self.mission.jumps_left.setdefault(index, repeat)
            if 0 <= target < len(self.mission.items) and (left > 0 or repeat < 0):
                if repeat >= 0:
                    self.mission.jumps_left[index] = left - 1
                return target
        return None

    def _plan_rtl(self, from_mission: bool = False) -> None:
        climb_to = max(self.pos[2], self.config.rtl_alt_m)
        self._legs = []
        if self.airborne or from_mission:
            self._legs.append(_Leg((self.pos[0], self.pos[1], climb_to)))
            self._legs.append(_Leg((0.0, 0.0, climb_to)))
            self._legs.append(_Leg((0.0, 0.0, 0.0)))
            self._after_legs = "landed"
            if from_mission:
                self._queue_mission_current()

    def _plan_land_here(self) -> None:
        self._legs = [_Leg((self.pos[0], self.pos[1], 0.0))] if self.airborne else []
        self._after_legs = "landed" if self._legs else None

    def _landed(self) -> None:
        self.pos[2] = 0.0
        self.vel = (0.0, 0.0, 0.0)
        self.armed = False
        self.has_landed_after_flight = True
        self.mission.complete = True
        self._legs = []
        self._after_legs = None

    # --- camera ------------------------------------------------------------------------------

    def _schedule_capture(self) -> None:
        if self.camera.remaining != 0 and self.camera.interval_s > 0:
            self.camera.next_capture_s = self.time_s + self.camera.interval_s
        else:
            self.camera.next_capture_s = math.inf

    def _take_photo(self) -> None:
        """A photo now at the current position (AP_Camera::take_picture)."""
        if not self.gps_has_fix:
            return
        cam = self.camera
        cam.count += 1
        cam.last_xy = (self.pos[0], self.pos[1])
        index = cam.count if self.autopilot is Autopilot.ARDUPILOT else cam.count - 1
        lat, lon = self._lonlat(self.pos[0], self.pos[1])
        rlat, rlon, ralt = self._reported_position()
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
        roll, pitch, yaw = self._attitude_deg()
        if self.autopilot is Autopilot.ARDUPILOT:
            self._queue(
                M.MAVLink_camera_feedback_message(
                    round(shot.utc_s * 1e6),
                    0,
                    0,
                    index,
                    _e7(rlat),
                    _e7(rlon),
                    ralt + self.home.alt_amsl_m,
                    ralt,
                    roll,
                    pitch,
                    yaw % 360.0,
                    0.0,
                    0,
                    0,
                )
            )
        else:
            self._queue(M.MAVLink_camera_trigger_message(round(shot.utc_s * 1e6), index))
            self._queue(
                M.MAVLink_camera_image_captured_message(
                    int(self.time_s * 1000),
                    round(shot.utc_s * 1e6),
                    0,
                    _e7(rlat),
                    _e7(rlon),
                    round((ralt + self.home.alt_amsl_m) * 1000),
                    round(ralt * 1000),
                    _quaternion(roll, pitch, yaw),
                    index,
                    1,
                    b"",
                )
            )

    def _distance_trigger(self, start: tuple[float, float], end: tuple[float, float]) -> list[float]:
        """Fractions of the piece start->end at which distance triggering fires (exact)."""
        d = self.camera.trigger_distance_m
        if d <= 0 or not self.gps_has_fix:
            return []
        fractions: list[float] = []
        last = self.camera.last_xy
        s0 = 0.0
        bx, by = end[0] - start[0], end[1] - start[1]
        if bx == 0.0 and by == 0.0:
            return []
        if last is None:
            # AP_Camera: the first update only remembers where the vehicle is.
            self.camera.last_xy = start
            last = start
        while True:
            ax = start[0] + s0 * bx - last[0]
            ay = start[1] + s0 * by - last[1]
            # smallest s >= s0 with |A + (s - s0) B| = d
            a = bx * bx + by * by
            b = 2 * (ax * bx + ay * by)
            c = ax * ax + ay * ay - d * d
            if c >= 0:
                u = 0.0
            else:
                disc = b * b - 4 * a * c
                u = (-b + math.sqrt(disc)) / (2 * a)
            s = s0 + u
            if s > 1.0 + 1e-12:
                return fractions
            fractions.append(min(s, 1.0))
            last = (start[0] + s * bx, start[1] + s * by)
            s0 = s

    # --- motion ------------------------------------------------------------------------------

    def _flying_allowed(self) -> bool:
        return self.armed and self.mode in (Mode.AUTO, Mode.RTL, Mode.LAND)

    def _advance(self, dt: float) -> None:
        """Move for ``dt`` simulated seconds (exact events inside)."""
        end_time = self.time_s + dt
        guard = 0
        while self.time_s < end_time - 1e-12:
            guard += 1
            if guard > 100_000:
                break
            remaining = end_time - self.time_s
            cap = self.camera.next_capture_s - self.time_s
            if not self._flying_allowed() or not self._legs:
                if self._flying_allowed() and self._after_legs is not None:
                    self._finish_legs()
                    continue
                step = min(remaining, cap) if cap > 0 else 0.0
                self.time_s += step
                self.vel = (0.0, 0.0, 0.0)
                if self.time_s >= self.camera.next_capture_s - 1e-12:
                    self._timed_capture()
                continue
            leg = self._legs[0]
            if leg.target is None:
                if leg.forever:
                    step = min(remaining, cap) if cap > 0 else 0.0
                else:
                    step = min(remaining, leg.wait_s, cap) if cap > 0 else 0.0
                    leg.wait_s -= step
                self.time_s += step
                self.vel = (0.0, 0.0, 0.0)
                if not leg.forever and leg.wait_s <= 1e-12:
                    self._legs.pop(0)
                if self.time_s >= self.camera.next_capture_s - 1e-12:
                    self._timed_capture()
                continue
            tx, ty, tz = leg.target
            dx, dy, dz = tx - self.pos[0], ty - self.pos[1], tz - self.pos[2]
            horizontal = math.hypot(dx, dy)
            vrate = self.config.climb_rate_m_s if dz > 0 else self.config.descent_rate_m_s
            need = max(horizontal / self.speed_m_s, abs(dz) / vrate)
            if need <= 1e-12:
                self.pos = [tx, ty, tz]
                self._legs.pop(0)
                continue
            step = min(remaining, need, cap) if cap > 0 else 0.0
            frac = step / need
            start = (self.pos[0], self.pos[1])
            new = [self.pos[0] + dx * frac, self.pos[1] + dy * frac, self.pos[2] + dz * frac]
            if frac >= 1.0 - 1e-12:
                new = [tx, ty, tz]
            if horizontal > 0:
                self.heading_deg = math.degrees(math.atan2(dx, dy)) % 360.0
            self.vel = (dx / need, dy / need, dz / need)
            t0, z0 = self.time_s, self.pos[2]
            for s in self._distance_trigger(start, (new[0], new[1])):
                self.time_s = t0 + s * step
                self.pos = [
                    start[0] + (new[0] - start[0]) * s,
                    start[1] + (new[1] - start[1]) * s,
                    z0 + (new[2] - z0) * s,
                ]
                self._take_photo()
            self.pos = new
            self.time_s = t0 + step
            if self.pos[2] > 0.05:
                self.has_flown = True
            if frac >= 1.0 - 1e-12:
                self._legs.pop(0)
            if self.time_s >= self.camera.next_capture_s - 1e-12:
                self._timed_capture()
        self.time_s = max(self.time_s, end_time)

    def _timed_capture(self) -> None:
        self._take_photo()
        if self.camera.remaining > 0:
            self.camera.remaining -= 1
        self._schedule_capture()

    def _finish_legs(self) -> None:
        after = self._after_legs
        self._after_legs = None
        if after == "landed":
            self._landed()
        elif after == "nav_done" and self.mode is Mode.AUTO:
            self._nav_done()

    # --- telemetry ---------------------------------------------------------------------------

    def _lonlat(self, x: float, y: float) -> tuple[float, float]:
        """(latitude, longitude) in degrees of a point east/north of home in metres."""
        lon, lat = self._lonlat_from_xy.transform(x, y)
        return float(lat), float(lon)

    def _reported_position(self) -> tuple[float, float, float]:
        t = self.time_s
        x = self.pos[0] + self._noise_e(t)
        y = self.pos[1] + self._noise_n(t)
        z = self.pos[2] + (self._noise_u(t) if self.airborne else 0.0)
        lat, lon = self._lonlat(x, y)
        return lat, lon, z

    def _attitude_deg(self) -> tuple[float, float, float]:
        t = self.time_s
        vx, vy, vz = self.vel
        speed = math.hypot(vx, vy)
        if self.vehicle_type is VehicleType.FIXED_WING:
            pitch = math.degrees(math.atan2(vz, speed)) if speed > 0 else 0.0
        else:
            pitch = -min(2.0 * speed, 25.0)  # nose down to fly forward
        noise = [n(t) if self.airborne else 0.0 for n in self._noise_att]
        return noise[0], pitch + noise[1], (self.heading_deg + noise[2]) % 360.0

    def _custom_mode(self) -> tuple[int, int]:
        """(base_mode, custom_mode) of the HEARTBEAT."""
        base = _MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | _MAV_MODE_FLAG_STABILIZE_ENABLED
        if self.armed:
            base |= _MAV_MODE_FLAG_SAFETY_ARMED
        if self.mode in (Mode.AUTO, Mode.RTL, Mode.LAND, Mode.LOITER, Mode.GUIDED):
            base |= _MAV_MODE_FLAG_GUIDED_ENABLED
        if self.mode in (Mode.AUTO, Mode.RTL, Mode.LAND):
            base |= _MAV_MODE_FLAG_AUTO_ENABLED
        if self.autopilot is Autopilot.PX4:
            main, sub = {
                Mode.MANUAL: (PX4_MAIN_POSCTL, 0),
                Mode.AUTO: (PX4_MAIN_AUTO, PX4_SUB_AUTO["MISSION"]),
                Mode.GUIDED: (PX4_MAIN_AUTO, PX4_SUB_AUTO["LOITER"]),
                Mode.LOITER: (PX4_MAIN_AUTO, PX4_SUB_AUTO["LOITER"]),
                Mode.RTL: (PX4_MAIN_AUTO, PX4_SUB_AUTO["RTL"]),
                Mode.LAND: (PX4_MAIN_AUTO, PX4_SUB_AUTO["LAND"]),
            }[self.mode]
            return base, (main << 16) | (sub << 24)
        plane = self.vehicle_type is VehicleType.FIXED_WING
        table = PLANE_MODES if plane else COPTER_MODES
        name = {
            Mode.MANUAL: "MANUAL" if plane else "STABILIZE",
            Mode.AUTO: "AUTO",
            Mode.GUIDED: "GUIDED",
            Mode.LOITER: "LOITER",
            Mode.RTL: "RTL",
            Mode.LAND: "RTL" if plane else "LAND",
        }[self.mode]
        return base, table[name]

    def heartbeat_message(self) -> object:
        base, custom = self._custom_mode()
        mav_type = 1 if self.vehicle_type is VehicleType.FIXED_WING else 2
        autopilot = 3 if self.autopilot is Autopilot.ARDUPILOT else 12
        status = 4 if self.armed else 3  # ACTIVE / STANDBY
        return M.MAVLink_heartbeat_message(mav_type, autopilot, base, custom, status, 3)

    def home_position_message(self) -> object | None:
        if not self.gps_has_fix:
            return None
        h = self.home
        return M.MAVLink_home_position_message(
            _e7(h.lat_deg),
            _e7(h.lon_deg),
            round(h.alt_amsl_m * 1000),
            0.0,
            0.0,
            0.0,
            [1.0, 0.0, 0.0, 0.0],
            0.0,
            0.0,
            0.0,
            round(self.utc_s * 1e6),
        )

    def _queue(self, msg: object) -> None:
        self._out.append((self.time_s, msg))

    def _queue_mission_current(self) -> None:
        self._queue(self._mission_current_message())

    def drain_events(self) -> list[tuple[float, object]]:
        """Event messages queued outside :meth:`step` (by a command), with their times."""
        out, self._out = self._out, []
        return out

    def _mission_current_message(self) -> object:
        m = self.mission
        total = len(m.items)
        if total <= self._first_index:
            state = 1  # NO_MISSION
        elif m.complete:
            state = 5
        elif m.started and self.mode is Mode.AUTO:
            state = 3
        elif m.started:
            state = 4
        else:
            state = 2
        return M.MAVLink_mission_current_message(m.current, total, state, 0)

    def _emit(self, name: str) -> object | None:
        t = self.time_s
        boot_ms = round(t * 1000)
        fix = self.gps_has_fix
        if name == "HEARTBEAT":
            return self.heartbeat_message()
        if name == "SYSTEM_TIME":
            unix_us = round(self.utc_s * 1e6) if fix else 0
            return M.MAVLink_system_time_message(unix_us, boot_ms)
        if name == "MISSION_CURRENT":
            return self._mission_current_message()
        if name == "EXTENDED_SYS_STATE":
            return M.MAVLink_extended_sys_state_message(0, self.landed_state)
        if name == "GIMBAL":
            if not self.gimbal_commanded:
                return None
            g = self.gimbal
            pitch = g.pitch_deg or 0.0
            if self.autopilot is Autopilot.ARDUPILOT:
                return M.MAVLink_mount_status_message(
                    0,
                    0,
                    round(pitch * 100),
                    round(g.roll_deg * 100),
                    round(g.yaw_deg * 100),
                    2,
                )
            return M.MAVLink_gimbal_device_attitude_status_message(
                0, 0, boot_ms, 0, _quaternion(g.roll_deg, pitch, g.yaw_deg), 0.0, 0.0, 0.0, 0
            )
        lat, lon, alt_rel = self._reported_position() if fix else (0.0, 0.0, 0.0)
        vx, vy, vz = self.vel
        if name == "GLOBAL_POSITION_INT":
            return M.MAVLink_global_position_int_message(
                boot_ms,
                _e7(lat),
                _e7(lon),
                round((alt_rel + self.home.alt_amsl_m) * 1000) if fix else 0,
                round(alt_rel * 1000),
                round(vy * 100),  # north
                round(vx * 100),  # east
                round(-vz * 100),  # down
                round(self.heading_deg * 100) % 36000,
            )
        if name == "ATTITUDE":
            roll, pitch, yaw = self._attitude_deg()
            yaw_rad = math.radians(yaw if yaw <= 180 else yaw - 360)
            return M.MAVLink_attitude_message(
                boot_ms, math.radians(roll), math.radians(pitch), yaw_rad, 0.0, 0.0, 0.0
            )
        if name == "GPS_RAW_INT":
            speed = math.hypot(vx, vy)
            return M.MAVLink_gps_raw_int_message(
                round(t * 1e6),
                3 if fix else 1,
                _e7(lat),
                _e7(lon),
                round((alt_rel + self.home.alt_amsl_m) * 1000) if fix else 0,
                70 if fix else 9999,
                120 if fix else 9999,
                round(speed * 100),
                round(self.heading_deg * 100) % 36000 if speed > 0 else 65535,
                14 if fix else 0,
            )
        return None

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
                nxt = min((s.next_s for s in self._streams if s.period_s > 0), default=math.inf)
                target = min(end, nxt)
                if target > self.time_s:
                    self._advance(target - self.time_s)
                else:
                    self._settle()
                self._collect()
                if nxt > end + 1e-12:
                    break
                for stream in self._streams:
                    if stream.period_s > 0 and stream.next_s <= self.time_s + 1e-9:
                        msg = self._emit(stream.name)
                        if msg is not None:
                            out.append((self.time_s, msg))
                        stream.next_s += stream.period_s
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
        while self._flying_allowed() and not self._legs and self._after_legs is not None:
            guard += 1
            if guard > 10_000:
                break
            self._finish_legs()


def _is_nav(command: int) -> bool:
    try:
        cmd = MavCmd(int(command))
    except ValueError:
        return False
    return cmd.is_nav or cmd is MavCmd.NAV_RETURN_TO_LAUNCH


def _e7(value_deg: float) -> int:
    return math.floor(value_deg * 1e7 + 0.5)


def _quaternion(roll_deg: float, pitch_deg: float, yaw_deg: float) -> list[float]:
    """Quaternion [w, x, y, z] of a ZYX Euler rotation (MAVLink's convention)."""
    r, p, y = (math.radians(v) / 2 for v in (roll_deg, pitch_deg, yaw_deg))
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return [
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    ]
