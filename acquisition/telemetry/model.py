"""The normalized tables every telemetry reader produces (.tlog, DataFlash .bin, .ulg, CSV, GPX, MRK).

All times are UTC, POSIX seconds (float64). Columns are numpy arrays of equal length, in
time order. A column the source does not carry is ``None`` (never NaN-filled or -9999).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .gpstime import time_order

log = logging.getLogger(__name__)

S = TypeVar("S")  # what a reader parsed (tables, a ULog)
C = TypeVar("C")  # its clock: boot time -> UTC

F64 = NDArray[np.float64]

#: progress(bytes_read, total_bytes): called by the readers as a log is read.
ReadProgress = Callable[[int, int], None]

#: How often, in bytes, the readers report progress.
PROGRESS_STEP_BYTES = 1 << 20


@dataclass(frozen=True, kw_only=True)
class CameraEvents:
    """One row per camera event (trigger or capture) the autopilot recorded.

    - ``time_utc_s``: when the photo was taken (the event's own time stamp, not the last GPS fix).
    - ``seq``: the autopilot's image index / sequence number (int64).
    - ``lat_deg``, ``lon_deg``, ``alt_amsl_m``, ``alt_rel_home_m``: position the autopilot logged.
    - ``roll_deg``, ``pitch_deg``, ``yaw_deg``: vehicle attitude the autopilot logged (yaw 0-360
      clockwise from north).
    - ``source``: where the rows come from, e.g. ``"tlog:CAMERA_FEEDBACK"``.
    """

    time_utc_s: F64
    seq: NDArray[np.int64]
    lat_deg: F64 | None = None
    lon_deg: F64 | None = None
    alt_amsl_m: F64 | None = None
    alt_rel_home_m: F64 | None = None
    roll_deg: F64 | None = None
    pitch_deg: F64 | None = None
    yaw_deg: F64 | None = None
    source: str = ""

    def __len__(self) -> int:
        return int(self.time_utc_s.shape[0])


@dataclass(frozen=True, kw_only=True)
class PositionTrack:
    """Vehicle positions over time (GLOBAL_POSITION_INT, POS, GPS, a CSV/GPX track...)."""

    time_utc_s: F64
    lat_deg: F64
    lon_deg: F64
    alt_amsl_m: F64 | None = None
    alt_rel_home_m: F64 | None = None
    source: str = ""

    def __len__(self) -> int:
        return int(self.time_utc_s.shape[0])


@dataclass(frozen=True, kw_only=True)
class AttitudeTrack:
    """Vehicle (or gimbal) attitude over time, degrees; yaw clockwise from north, 0-360."""

    time_utc_s: F64
    roll_deg: F64
    pitch_deg: F64
    yaw_deg: F64
    source: str = ""

    def __len__(self) -> int:
        return int(self.time_utc_s.shape[0])


class VehicleType(StrEnum):
    """What the log says the vehicle is (a .tlog's HEARTBEAT type, a DataFlash log's firmware
    name, a .ulg's vehicle_status system_type); it decides a camera's mount when the user does
    not (see :class:`acquisition.attitude.CameraMount`)."""

    FIXED_WING = "fixed wing"
    VTOL = "VTOL"  # a fixed wing with lift rotors, flying its survey lines as a fixed wing
    MULTIROTOR = "multirotor"
    HELICOPTER = "helicopter"
    OTHER = "vehicle of another kind"


#: MAVLink's MAV_TYPE values (common.xml) of the kinds above; any other is OTHER.
_MAV_TYPES = {
    VehicleType.FIXED_WING: {1},  # FIXED_WING
    # VTOL_TAILSITTER_DUOROTOR, _QUADROTOR, VTOL_TILTROTOR, VTOL_FIXEDROTOR, VTOL_TAILSITTER,
    # VTOL_TILTWING, VTOL_RESERVED5 (older names: VTOL_DUOROTOR ... VTOL_RESERVED2-5), VTOL_GYRODYNE
    VehicleType.VTOL: {19, 20, 21, 22, 23, 24, 25, 47},
    # QUADROTOR, COAXIAL, HEXAROTOR, OCTOROTOR, TRICOPTER, DODECAROTOR, DECAROTOR,
    # GENERIC_MULTIROTOR
    VehicleType.MULTIROTOR: {2, 3, 13, 14, 15, 29, 35, 43},
    VehicleType.HELICOPTER: {4},
}


def vehicle_type_of_mav_type(mav_type: int) -> VehicleType:
    """The :class:`VehicleType` of a MAVLink MAV_TYPE value."""
    return next((kind for kind, values in _MAV_TYPES.items() if mav_type in values), VehicleType.OTHER)


@dataclass(frozen=True, kw_only=True)
class FlightLog:
    """What one log file yields. Absent parts are None; ``warnings`` says what was odd
    (a truncated file and where reading stopped, a missing time reference...)."""

    path: str
    format: str  # "tlog", "dataflash", "ulog", "csv", "gpx", "mrk"
    events: CameraEvents | None = None
    positions: PositionTrack | None = None
    attitudes: AttitudeTrack | None = None
    gimbal: AttitudeTrack | None = None
    warnings: tuple[str, ...] = field(default=())
    vehicle_type: VehicleType | None = None  # None: the log does not say


# --- what every reader does with them -----------------------------------------------------------


def yaw_to_earth_deg(
    rel_yaw_deg: ArrayLike, time_utc_s: ArrayLike, vehicle: AttitudeTrack | None
) -> F64 | None:
    """Earth-frame yaw (0-360 clockwise from north) of a yaw measured relative to the vehicle
    heading, using the vehicle's yaw interpolated (along the shorter arc) at the same times.
    None when there is no vehicle attitude to add."""
    if vehicle is None or len(vehicle) == 0:
        return None
    unwrapped = np.degrees(np.unwrap(np.radians(vehicle.yaw_deg)))
    veh = np.interp(np.asarray(time_utc_s, dtype=np.float64), vehicle.time_utc_s, unwrapped)
    return np.mod(np.asarray(rel_yaw_deg, dtype=np.float64) + veh, 360.0)


def position_track(
    time_utc_s: F64,
    lat_lon_deg: tuple[ArrayLike, ArrayLike],
    alt_amsl_m: ArrayLike | None,
    alt_rel_home_m: ArrayLike | None,
    source: str,
    keep: ArrayLike | None = None,
) -> PositionTrack:
    """A :class:`PositionTrack` of the rows in time order, those with ``keep`` False (no fix,
    another receiver) or no finite time left out; columns as float64, None where not logged."""
    o = time_order(time_utc_s if keep is None else np.where(keep, time_utc_s, np.nan))

    def column(values: ArrayLike | None) -> F64 | None:
        return None if values is None else np.asarray(values, dtype=np.float64)[o]

    lat, lon = (np.asarray(v, dtype=np.float64)[o] for v in lat_lon_deg)
    rest = {"alt_amsl_m": column(alt_amsl_m), "alt_rel_home_m": column(alt_rel_home_m)}
    return PositionTrack(time_utc_s=time_utc_s[o], lat_deg=lat, lon_deg=lon, source=source, **rest)


def gimbal_track(
    time_utc_s: F64,
    rpy_deg: tuple[F64, F64, F64],
    yaw_in_earth_frame: NDArray[np.bool_],
    vehicle: AttitudeTrack | None,
    source: str,
) -> AttitudeTrack | None:
    """A gimbal's :class:`AttitudeTrack` (``rpy_deg``: roll, pitch, yaw) in time order with an
    earth-frame yaw: where ``yaw_in_earth_frame`` is False the yaw is relative to the vehicle's
    nose and the vehicle's yaw is added (:func:`yaw_to_earth_deg`). None when such a yaw has no
    vehicle attitude to add (the reader says so in its warnings). Rows with a NaN time are left
    out."""
    roll_deg, pitch_deg, yaw_deg = rpy_deg
    yaw = yaw_deg
    if not np.all(yaw_in_earth_frame):
        yaw_e = yaw_to_earth_deg(yaw_deg, time_utc_s, vehicle)
        if yaw_e is None:
            return None
        yaw = np.where(yaw_in_earth_frame, yaw_deg, yaw_e)
    o = time_order(time_utc_s)
    return AttitudeTrack(
        time_utc_s=time_utc_s[o],
        roll_deg=roll_deg[o],
        pitch_deg=pitch_deg[o],
        yaw_deg=np.mod(yaw[o], 360.0),
        source=source,
    )


def flight_log(
    path: str,
    fmt: str,
    warnings: list[str],
    *,
    events: CameraEvents | None = None,
    positions: PositionTrack | None = None,
    attitudes: AttitudeTrack | None = None,
    gimbal: AttitudeTrack | None = None,
    vehicle_type: VehicleType | None = None,
) -> FlightLog:
    """The :class:`FlightLog` a reader returns, its warnings logged once here."""
    for warning in warnings:
        log.warning("%s", warning)
    tracks = FlightLog(path=path, format=fmt, positions=positions, attitudes=attitudes, gimbal=gimbal)
    return replace(tracks, events=events, warnings=tuple(warnings), vehicle_type=vehicle_type)


def assemble_log(
    path: str,
    fmt: str,
    warnings: list[str],
    source: S,
    clock: Callable[[str, S], tuple[C, list[str]]],
    events: Callable[[str, S, C], tuple[CameraEvents | None, list[str]]],
    attitudes: Callable[[S, C], AttitudeTrack | None],
    gimbal: Callable[[str, S, C, AttitudeTrack | None], tuple[AttitudeTrack | None, list[str]]],
    positions: Callable[[S, C], PositionTrack | None],
    vehicle_type: VehicleType | None = None,
) -> FlightLog:
    """The steps of a reader whose log carries a boot clock, in order: the clock onto UTC, the
    camera events, the vehicle's attitudes, the gimbal (its yaw made earth-frame with those
    attitudes) and the positions; each step's warnings are added to ``warnings``."""
    utc, notes = clock(path, source)
    warnings += notes
    camera, notes = events(path, source, utc)
    warnings += notes
    vehicle = attitudes(source, utc)
    mount, notes = gimbal(path, source, utc, vehicle)
    warnings += notes
    track = positions(source, utc)
    return flight_log(
        path,
        fmt,
        warnings,
        events=camera,
        positions=track,
        attitudes=vehicle,
        gimbal=mount,
        vehicle_type=vehicle_type,
    )
