"""The MAVLink adapter for telemetry: positions, camera events and attitudes as typed records.

The only module (with :mod:`acquisition.mavlink_items` for mission items, whose degE7
conversion it shares) that knows MAVLink's wire units and constants. The live monitor
(:mod:`acquisition.flight_recorder`), the .tlog reader (:mod:`acquisition.telemetry.tlog`)
and the simulated vehicle (:mod:`acquisition.simulator`) speak the records below: WGS84
degrees, metres with their reference in the name (``alt_amsl_m``, ``alt_rel_home_m``), m/s,
degrees, and times that say their clock (``time_boot_s`` the vehicle's seconds since boot,
``time_utc_s`` POSIX seconds UTC). :func:`decode` turns a received pymavlink message into its
record; each record's ``to_message()`` is the encoder the simulator emits it with.

Wire units (MAVLink common.xml): latitude/longitude degE7 (int32), altitudes mm (int32) in
GLOBAL_POSITION_INT, GPS_RAW_INT, CAMERA_IMAGE_CAPTURED and HOME_POSITION but metres (float)
in CAMERA_FEEDBACK, velocities cm/s, ATTITUDE radians (yaw -pi..pi), MOUNT_STATUS centidegrees,
CAMERA_FEEDBACK degrees, quaternions (w, x, y, z) body FRD to NED.

Event times: CAMERA_FEEDBACK and CAMERA_TRIGGER carry one ``time_usec`` whose clock depends on
the firmware (:func:`event_time_utc_s`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from planner.mission import HomePosition

from .mavlink_items import deg_to_e7
from .mavlink_units import DEG_PER_E7
from .telemetry.gpstime import gps_usec_to_utc_s

F64 = NDArray[np.float64]

#: Below this many microseconds (about 3.2 years) a ``time_usec`` is time since boot.
BOOT_US_LIMIT = 100_000_000_000_000

# MAVLink enums used by the monitor, the readers and the simulator (common.xml).
MAV_TYPE_FIXED_WING = mavlink2.MAV_TYPE_FIXED_WING
MAV_TYPE_QUADROTOR = mavlink2.MAV_TYPE_QUADROTOR
MAV_TYPE_GCS = mavlink2.MAV_TYPE_GCS
MAV_AUTOPILOT_ARDUPILOTMEGA = mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA
MAV_AUTOPILOT_PX4 = mavlink2.MAV_AUTOPILOT_PX4
MAV_AUTOPILOT_INVALID = mavlink2.MAV_AUTOPILOT_INVALID
MODE_FLAG_CUSTOM_MODE_ENABLED = mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
MODE_FLAG_AUTO_ENABLED = mavlink2.MAV_MODE_FLAG_AUTO_ENABLED
MODE_FLAG_GUIDED_ENABLED = mavlink2.MAV_MODE_FLAG_GUIDED_ENABLED
MODE_FLAG_STABILIZE_ENABLED = mavlink2.MAV_MODE_FLAG_STABILIZE_ENABLED
MODE_FLAG_SAFETY_ARMED = mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
MAV_STATE_STANDBY = mavlink2.MAV_STATE_STANDBY
MAV_STATE_ACTIVE = mavlink2.MAV_STATE_ACTIVE
#: MAV_LANDED_STATE: the vehicle is in the air, taking off or landing.
LANDED_STATES_AIRBORNE = frozenset(
    {mavlink2.MAV_LANDED_STATE_IN_AIR, mavlink2.MAV_LANDED_STATE_TAKEOFF, mavlink2.MAV_LANDED_STATE_LANDING}
)
#: MAV_LANDED_STATE: in the air or landing (not yet on the ground).
LANDED_STATES_NOT_DOWN = frozenset({mavlink2.MAV_LANDED_STATE_IN_AIR, mavlink2.MAV_LANDED_STATE_LANDING})
MAV_CMD_SET_MESSAGE_INTERVAL = mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL
MAV_RESULT_ACCEPTED = mavlink2.MAV_RESULT_ACCEPTED
_GIMBAL_YAW_LOCK = mavlink2.GIMBAL_DEVICE_FLAGS_YAW_LOCK
_GIMBAL_YAW_IN_VEHICLE_FRAME = mavlink2.GIMBAL_DEVICE_FLAGS_YAW_IN_VEHICLE_FRAME
_GIMBAL_YAW_IN_EARTH_FRAME = mavlink2.GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME

#: Message name -> MAVLink message id, for the telemetry streams a ground station asks for.
MESSAGE_ID: dict[str, int] = {
    name: getattr(mavlink2, f"MAVLINK_MSG_ID_{name}")
    for name in (
        "HEARTBEAT",
        "SYSTEM_TIME",
        "GPS_RAW_INT",
        "ATTITUDE",
        "GLOBAL_POSITION_INT",
        "MISSION_CURRENT",
        "MOUNT_STATUS",
        "EXTENDED_SYS_STATE",
        "GIMBAL_DEVICE_ATTITUDE_STATUS",
    )
}
#: REQUEST_DATA_STREAM's MAV_DATA_STREAM group of each message, as ArduCopter's
#: GCS_Mavlink.cpp files them: EXTENDED_STATUS (2), POSITION (6), EXTRA1 (10), EXTRA3 (12).
#: MAV_DATA_STREAM_ALL (0) is every group.
ARDUPILOT_STREAM_GROUP: dict[str, int] = {
    "GPS_RAW_INT": mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS,
    "MISSION_CURRENT": mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS,
    "GLOBAL_POSITION_INT": mavlink2.MAV_DATA_STREAM_POSITION,
    "ATTITUDE": mavlink2.MAV_DATA_STREAM_EXTRA1,
    "SYSTEM_TIME": mavlink2.MAV_DATA_STREAM_EXTRA3,
    "MOUNT_STATUS": mavlink2.MAV_DATA_STREAM_EXTRA3,
    "GIMBAL_DEVICE_ATTITUDE_STATUS": mavlink2.MAV_DATA_STREAM_EXTRA3,
}
MAV_DATA_STREAM_ALL = mavlink2.MAV_DATA_STREAM_ALL


def deg_from_e7(value_e7: ArrayLike) -> F64:
    """degE7 integers (an array) -> degrees (also for uORB topics, which use the same unit)."""
    return np.asarray(value_e7, dtype=np.float64) * DEG_PER_E7


def _q(values: Any) -> tuple[float, float, float, float]:
    w, x, y, z = (float(v) for v in values)
    return w, x, y, z


# --- records ------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True, slots=True)
class Heartbeat:
    """HEARTBEAT: who the sender is and whether it is armed."""

    mav_type: int
    autopilot: int
    base_mode: int
    custom_mode: int
    system_status: int

    @property
    def is_autopilot(self) -> bool:
        """Sent by a flight controller (ground stations, gimbals and cameras send INVALID)."""
        return self.autopilot != MAV_AUTOPILOT_INVALID

    @property
    def is_ground_station(self) -> bool:
        return self.mav_type == MAV_TYPE_GCS

    @property
    def armed(self) -> bool:
        return bool(self.base_mode & MODE_FLAG_SAFETY_ARMED)

    def to_message(self) -> Any:
        return mavlink2.MAVLink_heartbeat_message(
            self.mav_type, self.autopilot, self.base_mode, self.custom_mode, self.system_status, 3
        )


@dataclass(frozen=True, kw_only=True, slots=True)
class SystemTime:
    """SYSTEM_TIME: the vehicle's UTC (None until its GPS sets it) at boot time ``time_boot_s``."""

    time_boot_s: float
    time_utc_s: float | None

    def to_message(self) -> Any:
        unix_us = 0 if self.time_utc_s is None else round(self.time_utc_s * 1e6)
        return mavlink2.MAVLink_system_time_message(unix_us, round(self.time_boot_s * 1000))


@dataclass(frozen=True, kw_only=True, slots=True)
class GlobalPosition:
    """GLOBAL_POSITION_INT: the autopilot's fused position and velocity (NED, m/s).

    ``has_position`` is False while the autopilot sends 0, 0 (no position yet)."""

    time_boot_s: float
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    alt_rel_home_m: float
    north_m_s: float
    east_m_s: float
    down_m_s: float
    heading_deg: float | None
    has_position: bool = True

    def to_message(self) -> Any:
        return mavlink2.MAVLink_global_position_int_message(
            round(self.time_boot_s * 1000),
            deg_to_e7(self.lat_deg),
            deg_to_e7(self.lon_deg),
            round(self.alt_amsl_m * 1000),
            round(self.alt_rel_home_m * 1000),
            round(self.north_m_s * 100),
            round(self.east_m_s * 100),
            round(self.down_m_s * 100),
            65535 if self.heading_deg is None else round(self.heading_deg * 100) % 36000,
        )


@dataclass(frozen=True, kw_only=True, slots=True)
class GpsRaw:
    """GPS_RAW_INT: the receiver's own fix. ``time_usec`` is UTC or boot microseconds
    (by magnitude, :func:`event_time_utc_s`); ``has_fix``: a 2D fix or better away from 0, 0."""

    time_usec: int
    fix_type: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    eph: int = 65535
    epv: int = 65535
    ground_speed_m_s: float = 0.0
    course_deg: float | None = None
    satellites: int = 255

    @property
    def has_fix(self) -> bool:
        return self.fix_type >= 2 and not (self.lat_deg == 0.0 and self.lon_deg == 0.0)

    def to_message(self) -> Any:
        return mavlink2.MAVLink_gps_raw_int_message(
            self.time_usec,
            self.fix_type,
            deg_to_e7(self.lat_deg),
            deg_to_e7(self.lon_deg),
            round(self.alt_amsl_m * 1000),
            self.eph,
            self.epv,
            round(self.ground_speed_m_s * 100),
            65535 if self.course_deg is None else round(self.course_deg * 100) % 36000,
            self.satellites,
        )


@dataclass(frozen=True, kw_only=True, slots=True)
class Attitude:
    """ATTITUDE: the vehicle's roll, pitch, yaw in degrees (yaw as sent, -180..180)."""

    time_boot_s: float
    roll_deg: float
    pitch_deg: float
    yaw_deg: float

    def to_message(self) -> Any:
        yaw = self.yaw_deg % 360.0
        yaw_rad = math.radians(yaw if yaw <= 180 else yaw - 360)
        return mavlink2.MAVLink_attitude_message(
            round(self.time_boot_s * 1000),
            math.radians(self.roll_deg),
            math.radians(self.pitch_deg),
            yaw_rad,
            0.0,
            0.0,
            0.0,
        )


@dataclass(frozen=True, kw_only=True, slots=True)
class CameraFeedback:
    """CAMERA_FEEDBACK (ArduPilot): one photo with the position and attitude logged for it.

    ``time_usec`` as sent (Unix, GPS or boot microseconds: :func:`event_time_utc_s`);
    ``image_index`` is ``img_idx``, the sequence number (``completed_captures`` stays 0
    without a feedback pin); ``yaw_deg`` 0-360."""

    time_usec: int
    camera_index: int
    image_index: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    alt_rel_home_m: float
    roll_deg: float
    pitch_deg: float
    yaw_deg: float

    def to_message(self) -> Any:
        return mavlink2.MAVLink_camera_feedback_message(
            self.time_usec,
            0,
            self.camera_index,
            self.image_index,
            deg_to_e7(self.lat_deg),
            deg_to_e7(self.lon_deg),
            self.alt_amsl_m,
            self.alt_rel_home_m,
            self.roll_deg,
            self.pitch_deg,
            self.yaw_deg % 360.0,
            0.0,
            0,
            0,
        )


@dataclass(frozen=True, kw_only=True, slots=True)
class CameraTrigger:
    """CAMERA_TRIGGER: a time (:func:`event_time_utc_s`) and a sequence number, no position."""

    time_usec: int
    seq: int

    def to_message(self) -> Any:
        return mavlink2.MAVLink_camera_trigger_message(self.time_usec, self.seq)


@dataclass(frozen=True, kw_only=True, slots=True)
class CameraImageCaptured:
    """CAMERA_IMAGE_CAPTURED (PX4, MAVLink cameras): ``time_utc_s`` None when the camera sent
    0 (then ``time_boot_s``, on the sending component's own boot clock); ``captured`` False
    for a failed capture; ``q`` (w, x, y, z) the camera's attitude, body FRD to NED."""

    time_boot_s: float
    time_utc_s: float | None
    image_index: int
    captured: bool
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    alt_rel_home_m: float
    q: tuple[float, float, float, float]

    def to_message(self) -> Any:
        return mavlink2.MAVLink_camera_image_captured_message(
            int(self.time_boot_s * 1000),
            0 if self.time_utc_s is None else round(self.time_utc_s * 1e6),
            0,
            deg_to_e7(self.lat_deg),
            deg_to_e7(self.lon_deg),
            round(self.alt_amsl_m * 1000),
            round(self.alt_rel_home_m * 1000),
            list(self.q),
            self.image_index,
            1 if self.captured else 0,
            b"",
        )


@dataclass(frozen=True, kw_only=True, slots=True)
class MountStatus:
    """MOUNT_STATUS (ArduPilot): the gimbal's angles, degrees; yaw relative to the vehicle's
    nose. No time field: the arrival time stands in."""

    roll_deg: float
    pitch_deg: float
    yaw_rel_deg: float

    def to_message(self) -> Any:
        return mavlink2.MAVLink_mount_status_message(
            0,
            0,
            round(self.pitch_deg * 100),
            round(self.roll_deg * 100),
            round(self.yaw_rel_deg * 100),
            mavlink2.MAV_MOUNT_MODE_MAVLINK_TARGETING,
        )


@dataclass(frozen=True, kw_only=True, slots=True)
class GimbalAttitude:
    """GIMBAL_DEVICE_ATTITUDE_STATUS: the gimbal's attitude quaternion (w, x, y, z) and its
    flags (:func:`gimbal_yaw_in_earth_frame`); ``time_boot_s`` on the sender's boot clock."""

    time_boot_s: float
    flags: int
    q: tuple[float, float, float, float]

    def to_message(self) -> Any:
        return mavlink2.MAVLink_gimbal_device_attitude_status_message(
            0, 0, round(self.time_boot_s * 1000), self.flags, list(self.q), 0.0, 0.0, 0.0, 0
        )


@dataclass(frozen=True, kw_only=True, slots=True)
class MissionCurrent:
    """MISSION_CURRENT: the item being flown; ``total``, ``mission_state`` (MISSION_STATE) and
    ``mission_id`` (an opaque id of the mission held) as sent, None when the message has no such
    field (older MAVLink). ``total`` 0 or 65535 and ``mission_state`` 0 mean not known."""

    seq: int
    total: int | None
    mission_state: int | None
    mission_id: int | None = None

    @property
    def items_total(self) -> int | None:
        """The number of items, None when not known."""
        return self.total if self.total not in (None, 0, 65535) else None

    def to_message(self) -> Any:
        # mission_id is not in the pymavlink this project pins: it cannot be sent
        return mavlink2.MAVLink_mission_current_message(self.seq, self.total or 0, self.mission_state or 0, 0)


@dataclass(frozen=True, kw_only=True, slots=True)
class ExtendedSysState:
    """EXTENDED_SYS_STATE: MAV_LANDED_STATE (1 on the ground, 2 in the air, 3 taking off,
    4 landing; None: undefined)."""

    landed_state: int | None

    def to_message(self) -> Any:
        return mavlink2.MAVLink_extended_sys_state_message(0, self.landed_state or 0)


Record = (
    Heartbeat
    | SystemTime
    | GlobalPosition
    | GpsRaw
    | Attitude
    | CameraFeedback
    | CameraTrigger
    | CameraImageCaptured
    | MountStatus
    | GimbalAttitude
    | MissionCurrent
    | ExtendedSysState
)


# --- decoding -----------------------------------------------------------------------------------


def _heartbeat(m: Any) -> Heartbeat:
    return Heartbeat(
        mav_type=int(m.type),
        autopilot=int(m.autopilot),
        base_mode=int(m.base_mode),
        custom_mode=int(m.custom_mode),
        system_status=int(m.system_status),
    )


def _system_time(m: Any) -> SystemTime:
    unix_us = int(m.time_unix_usec)
    return SystemTime(time_boot_s=m.time_boot_ms / 1e3, time_utc_s=unix_us / 1e6 if unix_us > 0 else None)


def _global_position(m: Any) -> GlobalPosition:
    return GlobalPosition(
        time_boot_s=m.time_boot_ms / 1e3,
        lat_deg=m.lat * DEG_PER_E7,
        lon_deg=m.lon * DEG_PER_E7,
        alt_amsl_m=m.alt * 1e-3,
        alt_rel_home_m=m.relative_alt * 1e-3,
        north_m_s=m.vx / 100.0,
        east_m_s=m.vy / 100.0,
        down_m_s=m.vz / 100.0,
        heading_deg=None if m.hdg == 65535 else m.hdg / 100.0,
        has_position=m.lat != 0 or m.lon != 0,
    )


def _gps_raw(m: Any) -> GpsRaw:
    return GpsRaw(
        time_usec=int(m.time_usec),
        fix_type=int(m.fix_type),
        lat_deg=m.lat * DEG_PER_E7,
        lon_deg=m.lon * DEG_PER_E7,
        alt_amsl_m=m.alt * 1e-3,
        eph=int(m.eph),
        epv=int(m.epv),
        ground_speed_m_s=m.vel / 100.0,
        course_deg=None if m.cog == 65535 else m.cog / 100.0,
        satellites=int(m.satellites_visible),
    )


def _attitude(m: Any) -> Attitude:
    return Attitude(
        time_boot_s=m.time_boot_ms / 1e3,
        roll_deg=math.degrees(m.roll),
        pitch_deg=math.degrees(m.pitch),
        yaw_deg=math.degrees(m.yaw),
    )


def _camera_feedback(m: Any) -> CameraFeedback:
    return CameraFeedback(
        time_usec=int(m.time_usec),
        camera_index=int(m.cam_idx),
        image_index=int(m.img_idx),
        lat_deg=m.lat * DEG_PER_E7,
        lon_deg=m.lng * DEG_PER_E7,
        alt_amsl_m=float(m.alt_msl),
        alt_rel_home_m=float(m.alt_rel),
        roll_deg=float(m.roll),
        pitch_deg=float(m.pitch),
        yaw_deg=float(m.yaw) % 360.0,
    )


def _camera_trigger(m: Any) -> CameraTrigger:
    return CameraTrigger(time_usec=int(m.time_usec), seq=int(m.seq))


def _image_captured(m: Any) -> CameraImageCaptured:
    utc_us = int(m.time_utc)
    return CameraImageCaptured(
        time_boot_s=m.time_boot_ms / 1e3,
        time_utc_s=utc_us / 1e6 if utc_us > 0 else None,
        image_index=int(m.image_index),
        captured=int(m.capture_result) == 1,
        lat_deg=m.lat * DEG_PER_E7,
        lon_deg=m.lon * DEG_PER_E7,
        alt_amsl_m=m.alt * 1e-3,
        alt_rel_home_m=m.relative_alt * 1e-3,
        q=_q(m.q),
    )


def _mount_status(m: Any) -> MountStatus:
    # ArduPilot: pointing_a pitch, pointing_b roll, pointing_c yaw (vehicle frame), centidegrees
    return MountStatus(
        roll_deg=m.pointing_b * 1e-2, pitch_deg=m.pointing_a * 1e-2, yaw_rel_deg=m.pointing_c * 1e-2
    )


def _gimbal_attitude(m: Any) -> GimbalAttitude:
    return GimbalAttitude(time_boot_s=m.time_boot_ms / 1e3, flags=int(m.flags), q=_q(m.q))


def _mission_current(m: Any) -> MissionCurrent:
    total = getattr(m, "total", None)
    state = getattr(m, "mission_state", None)
    mission_id = getattr(m, "mission_id", None)
    return MissionCurrent(
        seq=int(m.seq),
        total=None if total is None else int(total),
        mission_state=None if state is None else int(state),
        mission_id=None if mission_id is None else int(mission_id),
    )


def _extended_sys_state(m: Any) -> ExtendedSysState:
    return ExtendedSysState(landed_state=int(m.landed_state) or None)


_DECODERS: dict[str, Callable[[Any], Record]] = {
    "HEARTBEAT": _heartbeat,
    "SYSTEM_TIME": _system_time,
    "GLOBAL_POSITION_INT": _global_position,
    "GPS_RAW_INT": _gps_raw,
    "ATTITUDE": _attitude,
    "CAMERA_FEEDBACK": _camera_feedback,
    "CAMERA_TRIGGER": _camera_trigger,
    "CAMERA_IMAGE_CAPTURED": _image_captured,
    "MOUNT_STATUS": _mount_status,
    "GIMBAL_DEVICE_ATTITUDE_STATUS": _gimbal_attitude,
    "MISSION_CURRENT": _mission_current,
    "EXTENDED_SYS_STATE": _extended_sys_state,
}
#: The message types :func:`decode` knows.
DECODED_TYPES = frozenset(_DECODERS)


def decode(msg: Any) -> Record | None:
    """The record of a received pymavlink message; None for a type this adapter does not decode."""
    decoder = _DECODERS.get(msg.get_type())
    return None if decoder is None else decoder(msg)


# --- other messages the vehicle sends or the ground station asks with ----------------------------


def home_position_message(home: HomePosition, time_utc_s: float) -> Any:
    """HOME_POSITION of ``home`` (no approach vector, identity attitude)."""
    return mavlink2.MAVLink_home_position_message(
        deg_to_e7(home.lat_deg),
        deg_to_e7(home.lon_deg),
        round(home.alt_amsl_m * 1000),
        0.0,
        0.0,
        0.0,
        [1.0, 0.0, 0.0, 0.0],
        0.0,
        0.0,
        0.0,
        round(time_utc_s * 1e6),
    )


def mission_item_reached_message(seq: int) -> Any:
    return mavlink2.MAVLink_mission_item_reached_message(seq)


def set_message_interval_message(
    target_system: int, target_component: int, message_id: int, rate_hz: float
) -> Any:
    """COMMAND_LONG MAV_CMD_SET_MESSAGE_INTERVAL: ``message_id`` at ``rate_hz`` (param2 the
    interval in microseconds)."""
    return mavlink2.MAVLink_command_long_message(
        target_system,
        target_component,
        MAV_CMD_SET_MESSAGE_INTERVAL,
        0,
        float(message_id),
        1e6 / rate_hz,
        0,
        0,
        0,
        0,
        0,
    )


def request_data_stream_message(target_system: int, target_component: int, group: int, rate_hz: int) -> Any:
    """REQUEST_DATA_STREAM (the legacy way): start ``group`` at ``rate_hz``."""
    return mavlink2.MAVLink_request_data_stream_message(target_system, target_component, group, rate_hz, 1)


# --- meanings that need more than one message ---------------------------------------------------


def gimbal_yaw_in_earth_frame(flags: ArrayLike) -> NDArray[np.bool_]:
    """GIMBAL_DEVICE_FLAGS (also uORB's gimbal_device_attitude_status.device_flags): True where
    the yaw is earth-frame (YAW_IN_EARTH_FRAME, or YAW_LOCK without YAW_IN_VEHICLE_FRAME)."""
    f = np.asarray(flags).astype(np.int64)
    return ((f & _GIMBAL_YAW_IN_EARTH_FRAME) != 0) | (
        ((f & _GIMBAL_YAW_LOCK) != 0) & ((f & _GIMBAL_YAW_IN_VEHICLE_FRAME) == 0)
    )


@dataclass(frozen=True)
class EventTimes:
    """UTC of ``time_usec`` values: ``utc_s`` (NaN: no time), where they were read as
    GPS-epoch microseconds, and where the value was 0 (the arrival time was used)."""

    utc_s: F64
    gps_epoch: NDArray[np.bool_]
    no_time: NDArray[np.bool_]


def event_time_utc_s(time_usec: ArrayLike, boot_utc_s: ArrayLike, arrival_utc_s: ArrayLike) -> EventTimes:
    """UTC (POSIX s) of CAMERA_FEEDBACK / CAMERA_TRIGGER / GPS_RAW_INT ``time_usec`` values.

    Without a feedback pin ArduPilot sends Unix-epoch UTC microseconds (computed from GPS
    time); with one, the pin's microseconds since boot; the magnitude tells which (below
    :data:`BOOT_US_LIMIT` it is boot time). An epoch value is Unix UTC, the MAVLink definition,
    unless reading it as GPS-epoch microseconds lands nearer ``arrival_utc_s`` (some firmwares
    have sent that). 0 means no time: the arrival time stands in.

    ``boot_utc_s``: UTC of each value read as microseconds since boot (the caller's boot
    clock; NaN: unknown); ``arrival_utc_s``: the vehicle's UTC when the message arrived (NaN:
    unknown). All three broadcast together.
    """
    us_f, boot_utc, arrival = np.broadcast_arrays(
        np.asarray(time_usec, dtype=np.float64),
        np.asarray(boot_utc_s, dtype=np.float64),
        np.asarray(arrival_utc_s, dtype=np.float64),
    )
    out = np.full(us_f.shape, np.nan)
    zero = us_f <= 0
    boot = ~zero & (us_f < BOOT_US_LIMIT)
    epoch = ~zero & ~boot
    out[boot] = boot_utc[boot]
    gps = np.zeros(us_f.shape, dtype=bool)
    if epoch.any():
        us = us_f[epoch].astype(np.int64)
        as_unix = (us // 1_000_000).astype(np.float64) + (us % 1_000_000) / 1e6
        as_gps = gps_usec_to_utc_s(us)
        ref = arrival[epoch]
        use_gps = np.isfinite(ref) & (np.abs(as_gps - ref) < np.abs(as_unix - ref))
        out[epoch] = np.where(use_gps, as_gps, as_unix)
        gps[epoch] = use_gps
    out[zero] = arrival[zero]
    return EventTimes(utc_s=out, gps_epoch=gps, no_time=zero)
