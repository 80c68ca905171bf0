"""PX4 ULog files (.ulg) -> :class:`~acquisition.telemetry.model.FlightLog`, read with pyulog.

Topics used (each optional):

- ``camera_capture`` {timestamp, timestamp_utc, seq, lat, lon, alt (AMSL), q, result}: the
  events when present (captures with ``result`` 0 are left out, with a warning), else
  ``camera_trigger`` {timestamp, timestamp_utc, seq, feedback}. PX4 copies its latest
  position into camera_capture rather than interpolating (REFERENCES.md section 3).
- ``vehicle_global_position`` {lat, lon, alt (AMSL)}: positions (the GPS topic when absent).
- ``vehicle_attitude`` {q}: attitudes; the quaternion (w, x, y, z, body FRD to NED) becomes
  roll, pitch, yaw in degrees.
- ``gimbal_device_attitude_status`` {q, device_flags}: the gimbal, yaw turned to earth frame.

Times: every ``timestamp`` is microseconds since boot. The boot clock is mapped onto UTC by
fitting the GPS topic's ``time_utc_usec`` against its ``timestamp``
(``vehicle_gps_position``, or ``sensor_gps`` in newer PX4), the same mapping for every topic.
With no GPS time, the events' own ``timestamp_utc`` is used (PX4 fills it from the same
source), and the poses cannot be put on UTC.

A truncated or corrupt file yields what pyulog could read and a warning saying where the
message framing stopped.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import struct
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..attitude import roll_pitch_yaw_deg_from_quaternion
from ..errors import TelemetryError
from ..mavlink_messages import deg_from_e7, gimbal_yaw_in_earth_frame
from .gpstime import BootClock, fit_boot_clock, time_order
from .model import (
    AttitudeTrack,
    CameraEvents,
    FlightLog,
    PositionTrack,
    VehicleType,
    assemble_log,
    gimbal_track,
    position_track,
    vehicle_type_of_mav_type,
)

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]

ULOG_MAGIC = b"ULog\x01\x12\x35"
_HEADER_LEN = 16
_GPS_TOPICS = ("vehicle_gps_position", "sensor_gps")
_TOPICS = [
    "camera_capture",
    "camera_trigger",
    "vehicle_global_position",
    "vehicle_attitude",
    "gimbal_device_attitude_status",
    "vehicle_status",
    *_GPS_TOPICS,
]


def ulog_framing_end(path: str) -> tuple[int, int, int]:
    """(byte offset just past the last complete ULog message, file size, messages counted).

    Walks the message headers (uint16 size, uint8 type) from the end of the 16-byte file
    header; a size that runs past the end of the file, or a zero size or type, ends it.
    """
    with open(path, "rb") as f:
        data = f.read()
    size = len(data)
    if size < _HEADER_LEN or not data.startswith(ULOG_MAGIC):
        return 0, size, 0
    ofs, count = _HEADER_LEN, 0
    unpack = struct.Struct("<HB").unpack_from
    while ofs + 3 <= size:
        msg_size, msg_type = unpack(data, ofs)
        if msg_size == 0 or msg_type == 0 or ofs + 3 + msg_size > size:
            break
        ofs += 3 + msg_size
        count += 1
    return ofs, size, count


def _topic(ulog: Any, name: str) -> dict[str, NDArray[Any]] | None:
    """The data of a topic's first instance (multi_id 0 when present)."""
    items = [d for d in ulog.data_list if d.name == name]
    if not items:
        return None
    items.sort(key=lambda d: d.multi_id)
    data: dict[str, NDArray[Any]] = items[0].data
    return data


def _q(d: dict[str, NDArray[Any]]) -> tuple[F64, F64, F64]:
    return roll_pitch_yaw_deg_from_quaternion(d["q[0]"], d["q[1]"], d["q[2]"], d["q[3]"])


def _clock(path: str, ulog: Any) -> tuple[BootClock | None, list[str]]:
    for name in _GPS_TOPICS:
        d = _topic(ulog, name)
        if d is None or "time_utc_usec" not in d:
            continue
        utc_us = d["time_utc_usec"].astype(np.float64)
        ok = utc_us > 0
        if "fix_type" in d:
            ok &= d["fix_type"] >= 3
        if ok.any():
            fit = fit_boot_clock(d["timestamp"][ok] / 1e6, utc_us[ok] / 1e6)
            log.debug("%s: boot clock from %s: %s", path, name, fit)
            notes = []
            if fit.residual_rms_s > 0.05:
                notes.append(
                    f"{path}: {name}.time_utc_usec scatters by {fit.residual_rms_s * 1e3:.0f} ms "
                    f"RMS around the boot clock fit"
                )
            return fit, notes
    return None, [f"{path}: no GPS topic with UTC time: boot times cannot be put on UTC"]


def _events(path: str, ulog: Any, clock: BootClock | None) -> tuple[CameraEvents | None, list[str]]:
    warnings: list[str] = []
    cap = _topic(ulog, "camera_capture")
    trig = _topic(ulog, "camera_trigger")
    if cap is not None:
        d, name = cap, "camera_capture"
        if trig is not None:
            warnings.append(
                f"{path}: events from camera_capture ({len(cap['timestamp'])}); "
                f"camera_trigger ({len(trig['timestamp'])}) not used"
            )
    elif trig is not None:
        d, name = trig, "camera_trigger"
    else:
        return None, warnings
    keep = np.ones(len(d["timestamp"]), dtype=bool)
    if "result" in d:
        keep = d["result"] != 0
        if not keep.all():
            warnings.append(
                f"{path}: {int((~keep).sum())} camera_capture report a failed capture "
                f"(result 0) and are left out"
            )
    if clock is not None:
        t = clock.utc_s(d["timestamp"] / 1e6)
    elif "timestamp_utc" in d:
        t = np.where(d["timestamp_utc"] > 0, d["timestamp_utc"] / 1e6, np.nan)
        warnings.append(f"{path}: {name} times from its timestamp_utc (no GPS clock mapping)")
    else:
        return None, [*warnings, f"{path}: {name} cannot be put on UTC; events left out"]
    seq = d["seq"].astype(np.float64)
    cols: dict[str, F64] = {}
    if name == "camera_capture":
        cols = {
            "lat_deg": d["lat"].astype(np.float64),
            "lon_deg": d["lon"].astype(np.float64),
            "alt_amsl_m": d["alt"].astype(np.float64),
        }
        if "q[0]" in d:
            cols["roll_deg"], cols["pitch_deg"], cols["yaw_deg"] = _q(d)
    order = time_order(np.where(keep, t, np.nan), seq)
    return (
        CameraEvents(
            time_utc_s=t[order],
            seq=seq[order].astype(np.int64),
            source=f"ulog:{name}",
            **{k: v[order] for k, v in cols.items()},
        ),
        warnings,
    )


def _positions(ulog: Any, clock: BootClock | None) -> PositionTrack | None:
    if clock is None:
        return None
    d = _topic(ulog, "vehicle_global_position")
    if d is not None:
        t = clock.utc_s(d["timestamp"] / 1e6)
        return position_track(t, (d["lat"], d["lon"]), d["alt"], None, "ulog:vehicle_global_position")
    for name in _GPS_TOPICS:
        d = _topic(ulog, name)
        if d is None:
            continue
        if "latitude_deg" in d:  # PX4 1.14+
            lat, lon = d["latitude_deg"], d["longitude_deg"]
            alt = d["altitude_msl_m"]
        else:
            lat, lon, alt = deg_from_e7(d["lat"]), deg_from_e7(d["lon"]), d["alt"] * 1e-3
        ok = d["fix_type"] >= 3 if "fix_type" in d else np.ones(len(lat), dtype=bool)
        t = clock.utc_s(d["timestamp"] / 1e6)
        return position_track(t, (lat, lon), alt, None, f"ulog:{name}", keep=ok)
    return None


def _attitudes(ulog: Any, clock: BootClock | None) -> AttitudeTrack | None:
    d = _topic(ulog, "vehicle_attitude")
    if clock is None or d is None:
        return None
    t = clock.utc_s(d["timestamp"] / 1e6)
    roll, pitch, yaw = _q(d)
    o = time_order(t)
    return AttitudeTrack(
        time_utc_s=t[o],
        roll_deg=roll[o],
        pitch_deg=pitch[o],
        yaw_deg=yaw[o],
        source="ulog:vehicle_attitude",
    )


def _gimbal(
    path: str, ulog: Any, clock: BootClock | None, vehicle: AttitudeTrack | None
) -> tuple[AttitudeTrack | None, list[str]]:
    d = _topic(ulog, "gimbal_device_attitude_status")
    if clock is None or d is None:
        return None, []
    t = clock.utc_s(d["timestamp"] / 1e6)
    roll, pitch, yaw = _q(d)
    earth = gimbal_yaw_in_earth_frame(d.get("device_flags", np.zeros(len(t))))
    track = gimbal_track(t, (roll, pitch, yaw), earth, vehicle, "ulog:gimbal_device_attitude_status")
    if track is None:
        return None, [f"{path}: gimbal yaw relative to the vehicle and no vehicle attitude"]
    return track, []


def read_ulog(path: str | os.PathLike[str]) -> FlightLog:
    """Read a PX4 .ulg into the normalized tables (UTC times; see the module docstring).
    Raises :class:`TelemetryError` when pyulog cannot parse it."""
    from pyulog import ULog

    p = os.fspath(path)
    captured = io.StringIO()
    # pyulog prints its corruption notices; keep them for the log.
    with contextlib.redirect_stdout(captured):
        try:
            ulog = ULog(p, message_name_filter_list=_TOPICS, disable_str_exceptions=True)
        except Exception as exc:  # pyulog raises ULogException and struct/IO errors
            raise TelemetryError(f"{p}: not a readable ULog file: {exc}") from exc
    for line in captured.getvalue().splitlines():
        log.debug("pyulog: %s", line)
    warnings: list[str] = []
    end, size, count = ulog_framing_end(p)
    if end < size:
        warnings.append(
            f"{p}: reading stopped at byte {end} of {size} after {count} messages (truncated or corrupt tail)"
        )
    if ulog.file_corruption:
        warnings.append(f"{p}: pyulog found corrupt data and skipped it")
    return assemble_log(
        p, "ulog", warnings, ulog, _clock, _events, _attitudes, _gimbal, _positions, _vehicle_type(ulog)
    )


def _vehicle_type(ulog: Any) -> VehicleType | None:
    """What vehicle_status says the vehicle is: its ``system_type`` (the MAVLink MAV_TYPE of the
    airframe, a VTOL_* type for a VTOL). Not ``vehicle_type``: a VTOL's changes between rotary
    and fixed wing with each transition. None when the log has no vehicle_status."""
    status = _topic(ulog, "vehicle_status")
    if status is None or len(status.get("timestamp", ())) == 0:
        return None
    if "system_type" in status:
        return vehicle_type_of_mav_type(int(status["system_type"][0]))
    return None
