"""MAVLink telemetry logs (.tlog) -> :class:`~acquisition.telemetry.model.FlightLog`.

A .tlog is what a ground station received: each MAVLink packet preceded by the ground
station's own receive time (8 bytes, big-endian microseconds since the Unix epoch). That
clock is the ground station's, and runs at wall-clock speed even when a simulator runs faster
than real time, so it is used only as a last resort. UTC comes from the vehicle:

- SYSTEM_TIME pairs the vehicle's UTC (``time_unix_usec``, 0 until the GPS sets it) with its
  boot clock (``time_boot_ms``); :func:`~acquisition.telemetry.gpstime.fit_boot_clock` maps
  boot time onto UTC, one fit per boot (a reboot restarts ``time_boot_ms``).
- CAMERA_FEEDBACK (ArduPilot, id 180): ``time_usec`` is the event time. Without a feedback
  pin ArduPilot sends ``AP::gps().time_epoch_usec()``, Unix-epoch UTC microseconds computed
  from the GPS week and time of week with its own 18 s leap-second constant; with a feedback
  pin it sends the pin's microseconds since boot. The magnitude tells which (below about 3
  years of microseconds it is boot time); an epoch value is taken as Unix UTC, the MAVLink
  definition, unless reading it as GPS-epoch microseconds lands closer to the time the
  message arrived (some firmwares have sent that). ``img_idx`` is the sequence number:
  ``completed_captures`` stays 0 without a feedback pin (REFERENCES.md section 3).
- CAMERA_TRIGGER (112): ``time_usec`` (Unix epoch or boot, by magnitude) and ``seq``.
- CAMERA_IMAGE_CAPTURED (263): ``time_utc`` (Unix microseconds, 0 = unknown, then
  ``time_boot_ms``), ``image_index``, position and attitude quaternion; failed captures
  (``capture_result`` 0) are left out, with a warning.
- GLOBAL_POSITION_INT (positions; GPS_RAW_INT when it is missing), ATTITUDE (attitudes),
  GIMBAL_DEVICE_ATTITUDE_STATUS or MOUNT_STATUS (gimbal, yaw turned into earth frame).

Messages received twice (same time and index, e.g. through two links) are kept once.
A truncated or corrupt file yields what could be read and a warning that says where.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import math
import mmap
import os
import sys
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, BinaryIO

import numpy as np
from numpy.typing import NDArray

from .. import mavlink_messages as mm
from ..attitude import roll_pitch_yaw_deg_from_quaternion
from ..errors import TelemetryError
from . import model
from .gpstime import BootClock, fit_boot_clock, time_order
from .model import PROGRESS_STEP_BYTES, AttitudeTrack, CameraEvents, FlightLog, PositionTrack, ReadProgress
from .tlog_records import IrregularLogError, records

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]

# A reboot: time_boot_ms falls back by more than this (s).
_REBOOT_BACKSTEP_S = 5.0
# Messages other components of the vehicle send (a MAVLink camera, a gimbal device); the
# others are taken only from the autopilot.
_FROM_PAYLOADS = {"CAMERA_IMAGE_CAPTURED", "GIMBAL_DEVICE_ATTITUDE_STATUS"}

_WANTED = (
    "SYSTEM_TIME",
    "CAMERA_FEEDBACK",
    "CAMERA_TRIGGER",
    "CAMERA_IMAGE_CAPTURED",
    "GLOBAL_POSITION_INT",
    "GPS_RAW_INT",
    "ATTITUDE",
    "MOUNT_STATUS",
    "GIMBAL_DEVICE_ATTITUDE_STATUS",
)


@dataclass
class _Reading:
    """What one pass over the file collected (lists of tuples, one per message)."""

    rows: dict[str, list[tuple[float, ...]]] = field(default_factory=dict)
    boot_segment: int = 0
    last_boot_s: float | None = None
    n_messages: int = 0
    n_bad: int = 0
    first_bad_at: int | None = None
    last_good_end: int = 0
    cam_idx: Counter[int] = field(default_factory=Counter)
    failed_captures: int = 0
    vehicle: tuple[int, int] | None = None
    mav_type: int | None = None  # the vehicle's HEARTBEAT type
    ignored: Counter[tuple[int, int]] = field(default_factory=Counter)


def _receive_boot_s(r: _Reading) -> float:
    """The vehicle's boot time (s) when the current message arrived (the last one seen), NaN
    before any message carried one."""
    return math.nan if r.last_boot_s is None else r.last_boot_s


def _note_boot(r: _Reading, boot_s: float) -> None:
    if r.last_boot_s is not None and boot_s < r.last_boot_s - _REBOOT_BACKSTEP_S:
        r.boot_segment += 1
    r.last_boot_s = boot_s


def _collect(path: str, progress: ReadProgress | None = None) -> _Reading:
    """Every message of the file, through :func:`_collect_records` when the file is regular,
    else through pymavlink's stream parser (:func:`_collect_stream`), the reference."""
    try:
        return _collect_records(path, progress)
    except IrregularLogError as why:
        log.debug("%s: read by pymavlink's parser (%s)", path, why)
    return _collect_stream(path, progress)


def _collect_stream(path: str, progress: ReadProgress | None = None) -> _Reading:
    """Every message of the file decoded by pymavlink's log reader (robust parsing: corrupt
    bytes are skipped and counted)."""
    from pymavlink import mavutil

    r = _Reading(rows={name: [] for name in _WANTED})
    try:
        conn = mavutil.mavlogfile(path, robust_parsing=True)
    except OSError as exc:
        raise TelemetryError(f"cannot open {path}: {exc}") from exc
    total = os.path.getsize(path)
    next_report = 0
    try:
        while True:
            if progress is not None and r.last_good_end >= next_report:
                progress(r.last_good_end, total)
                next_report = r.last_good_end + PROGRESS_STEP_BYTES
            try:
                msg = conn.recv_msg()
            except Exception as exc:  # pymavlink raises plain Exceptions on broken frames
                log.debug("%s: stopped at byte %d: %s", path, conn.f.tell(), exc)
                break
            if msg is None:
                break
            mtype = msg.get_type()
            if mtype == "BAD_DATA":
                r.n_bad += 1
                if r.first_bad_at is None:
                    r.first_bad_at = r.last_good_end
                continue
            src = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
            _take(r, mtype, src, float(msg._timestamp), conn.f.tell(), functools.partial(_itself, msg))
    finally:
        conn.close()
    return r


def _collect_records(path: str, progress: ReadProgress | None = None) -> _Reading:
    """Every message of a regular file (:mod:`.tlog_records`); only the wanted ones, and the
    HEARTBEATs until the vehicle is known, are decoded, by pymavlink. Raises
    :class:`IrregularLogError` when the file is not regular."""
    from pymavlink import mavutil
    from pymavlink.generator.mavcrc import mcrf4xx

    if mcrf4xx is None:  # fastcrc missing: no faster than pymavlink's own reader
        raise IrregularLogError("no fastcrc")
    try:
        # The dialect pymavlink's reader would decode with: it picks it by the file's first
        # frame (a MAVLink 2 frame switches it to the v2.0 module, for this process).
        first = mavutil.mavlogfile(path, robust_parsing=True)
        try:
            first.recv_msg()
            dialect = sys.modules[type(first.mav).__module__]
        finally:
            first.close()
        with open(path, "rb") as f, _mapped(f) as data:
            return _walk(data, dialect, mcrf4xx, progress)
    except OSError as exc:
        raise TelemetryError(f"cannot open {path}: {exc}") from exc


@contextlib.contextmanager
def _mapped(f: BinaryIO) -> Iterator[bytes | mmap.mmap]:
    """The file's bytes, mapped (a long flight's log is not read into memory); b"" when empty."""
    if os.fstat(f.fileno()).st_size == 0:
        yield b""
        return
    with mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as data:
        yield data


def _walk(data: bytes | mmap.mmap, dialect: Any, mcrf4xx: Any, progress: ReadProgress | None) -> _Reading:
    types = dialect.mavlink_map
    crc_extra = {msg_id: t.crc_extra for msg_id, t in types.items()}
    names = {msg_id: t.msgname for msg_id, t in types.items()}
    decoder = dialect.MAVLink(None)
    r = _Reading(rows={name: [] for name in _WANTED})
    next_report = 0
    for rx_s, start, end, msg_id, system, component in records(data, crc_extra, mcrf4xx):
        if progress is not None and r.last_good_end >= next_report:
            progress(r.last_good_end, len(data))
            next_report = r.last_good_end + PROGRESS_STEP_BYTES
        name = names.get(msg_id, "UNKNOWN")

        def decoded(start: int = start, end: int = end) -> Any:
            return decoder.decode(bytearray(data[start:end]))

        _take(r, name, (system, component), rx_s, end, decoded)
    return r


def _itself(message: Any) -> Any:
    return message


def _take(
    r: _Reading, mtype: str, src: tuple[int, int], rx_s: float, end: int, message: Callable[[], Any]
) -> None:
    """One message of the file (not corrupt), ending at byte ``end``: counted, and kept when
    it is wanted; ``message()`` gives it decoded by pymavlink, called only then."""
    r.n_messages += 1
    r.last_good_end = end
    if mtype == "HEARTBEAT" and r.vehicle is None:
        heartbeat = mm.decode(message())
        if isinstance(heartbeat, mm.Heartbeat) and heartbeat.is_autopilot:
            r.vehicle = src  # the first autopilot heard; GCS, gimbals, cameras send INVALID
            r.mav_type = heartbeat.mav_type
    if mtype not in _WANTED:
        return
    # Until the autopilot's first HEARTBEAT every source is taken as the vehicle.
    from_vehicle = r.vehicle is None or src == r.vehicle
    same_system = r.vehicle is None or src[0] == r.vehicle[0]
    if not (same_system if mtype in _FROM_PAYLOADS else from_vehicle):
        r.ignored[src] += 1
        return
    _add_row(r, mm.decode(message()), rx_s, from_vehicle)


def _add_row(r: _Reading, m: mm.Record | None, rx_s: float, from_vehicle: bool) -> None:
    """One decoded message as a row of its table: (receive time, boot segment, boot time s, ...)."""
    if isinstance(m, mm.SystemTime | mm.GlobalPosition | mm.Attitude) or (
        isinstance(m, mm.GimbalAttitude) and from_vehicle
    ):
        _note_boot(r, m.time_boot_s)
    seg = float(r.boot_segment)
    rx_boot_s = _receive_boot_s(r)
    if isinstance(m, mm.SystemTime):
        r.rows["SYSTEM_TIME"].append((rx_s, seg, m.time_boot_s, m.time_utc_s or 0.0))
    elif isinstance(m, mm.CameraFeedback):
        r.cam_idx[m.camera_index] += 1
        r.rows["CAMERA_FEEDBACK"].append(
            (
                rx_s,
                seg,
                rx_boot_s,
                float(m.time_usec),
                float(m.image_index),
                m.lat_deg,
                m.lon_deg,
                m.alt_amsl_m,
                m.alt_rel_home_m,
                m.roll_deg,
                m.pitch_deg,
                m.yaw_deg,
            )
        )
    elif isinstance(m, mm.CameraTrigger):
        r.rows["CAMERA_TRIGGER"].append((rx_s, seg, rx_boot_s, float(m.time_usec), float(m.seq)))
    elif isinstance(m, mm.CameraImageCaptured):
        if not m.captured:
            r.failed_captures += 1
            return
        # A camera component's time_boot_ms counts from its own boot: only the autopilot's is
        # on the clock SYSTEM_TIME maps; otherwise the arrival time.
        boot_s = m.time_boot_s if from_vehicle else rx_boot_s
        r.rows["CAMERA_IMAGE_CAPTURED"].append(
            (
                rx_s,
                seg,
                boot_s,
                m.time_utc_s or 0.0,
                float(m.image_index),
                m.lat_deg,
                m.lon_deg,
                m.alt_amsl_m,
                m.alt_rel_home_m,
                *m.q,
            )
        )
    elif isinstance(m, mm.GlobalPosition):
        if m.has_position:  # else no position yet
            r.rows["GLOBAL_POSITION_INT"].append(
                (rx_s, seg, m.time_boot_s, m.lat_deg, m.lon_deg, m.alt_amsl_m, m.alt_rel_home_m)
            )
    elif isinstance(m, mm.GpsRaw):
        if m.has_fix:
            r.rows["GPS_RAW_INT"].append(
                (rx_s, seg, rx_boot_s, float(m.time_usec), m.lat_deg, m.lon_deg, m.alt_amsl_m)
            )
    elif isinstance(m, mm.Attitude):
        r.rows["ATTITUDE"].append((rx_s, seg, m.time_boot_s, m.roll_deg, m.pitch_deg, m.yaw_deg))
    elif isinstance(m, mm.MountStatus):
        # no time field: the arrival time stands in
        r.rows["MOUNT_STATUS"].append((rx_s, seg, rx_boot_s, m.roll_deg, m.pitch_deg, m.yaw_rel_deg))
    elif isinstance(m, mm.GimbalAttitude):
        # Sent by the autopilot for its own mount drivers, or by a MAVLink gimbal device whose
        # time_boot_ms is its own clock (then the arrival time is used).
        boot_s = m.time_boot_s if from_vehicle else rx_boot_s
        r.rows["GIMBAL_DEVICE_ATTITUDE_STATUS"].append((rx_s, seg, boot_s, float(m.flags), *m.q))


@dataclass
class _Clock:
    """Boot time -> UTC for each boot segment of the log, with the fallback used."""

    fits: dict[int, BootClock]
    fallback: dict[int, BootClock]
    warnings: list[str]

    def utc_s(self, seg: F64, boot_s: F64) -> F64:
        out = np.full(boot_s.shape, np.nan)
        for s in np.unique(seg[np.isfinite(seg)]):
            fit = self.fits.get(int(s)) or self.fallback.get(int(s))
            if fit is None:
                continue
            sel = seg == s
            out[sel] = fit.utc_s(boot_s[sel])
        return out


def _boot_clock(path: str, r: _Reading) -> _Clock:
    warnings: list[str] = []
    fits: dict[int, BootClock] = {}
    fallback: dict[int, BootClock] = {}
    st = np.array(r.rows["SYSTEM_TIME"], dtype=np.float64).reshape(-1, 4)
    valid = st[:, 3] > 0
    for seg in np.unique(st[:, 1]):
        sel = valid & (st[:, 1] == seg)
        if sel.any():
            fit = fit_boot_clock(st[sel, 2], st[sel, 3])
            fits[int(seg)] = fit
            log.debug("%s boot %d: %s", path, int(seg), fit)
            if fit.residual_rms_s > 0.05:
                warnings.append(
                    f"{path}: SYSTEM_TIME of boot {int(seg)} scatters by "
                    f"{fit.residual_rms_s * 1e3:.0f} ms RMS around its fit; event times are "
                    f"no better than that"
                )
    # Fallback for boots without a UTC reference: the ground station's receive clock against
    # the boot time of the messages that carry one.
    segs_needed: set[int] = set()
    pairs: dict[int, list[tuple[float, float]]] = {}
    for name in ("ATTITUDE", "GLOBAL_POSITION_INT", "SYSTEM_TIME"):
        for row in r.rows[name]:
            segs_needed.add(int(row[1]))
            pairs.setdefault(int(row[1]), []).append((row[2], row[0]))
    for seg in sorted(segs_needed - set(fits)):
        p = np.array(pairs[seg])
        fallback[seg] = fit_boot_clock(p[:, 0], p[:, 1])
        warnings.append(
            f"{path}: boot {seg} has no SYSTEM_TIME with UTC (no GPS time); its times come "
            f"from the ground station's receive clock, which can be off by seconds"
        )
    return _Clock(fits=fits, fallback=fallback, warnings=warnings)


def _time_usec_to_utc(time_usec: F64, seg: F64, rx_boot_s: F64, clock: _Clock) -> tuple[F64, list[str]]:
    """UTC of time_usec values that are Unix-epoch, GPS-epoch or boot microseconds
    (:func:`acquisition.mavlink_messages.event_time_utc_s`); 0 -> the arrival time (boot clock
    of the last message before it)."""
    times = mm.event_time_utc_s(time_usec, clock.utc_s(seg, time_usec / 1e6), clock.utc_s(seg, rx_boot_s))
    notes: list[str] = []
    if times.gps_epoch.any():
        notes.append(f"{int(times.gps_epoch.sum())} time_usec values read as GPS-epoch microseconds")
    if times.no_time.any():
        notes.append(
            f"{int(times.no_time.sum())} events have no time of their own (time_usec 0, no GPS time); "
            f"their arrival time is used"
        )
    return times.utc_s, notes


def _arr(rows: list[tuple[float, ...]], width: int) -> F64:
    return np.array(rows, dtype=np.float64).reshape(-1, width)


_EVENT_COLUMNS = ("lat_deg", "lon_deg", "alt_amsl_m", "alt_rel_home_m", "roll_deg", "pitch_deg", "yaw_deg")


def _events(path: str, r: _Reading, clock: _Clock) -> tuple[CameraEvents | None, list[str]]:
    warnings: list[str] = []
    present = {
        name: len(r.rows[name])
        for name in ("CAMERA_FEEDBACK", "CAMERA_IMAGE_CAPTURED", "CAMERA_TRIGGER")
        if r.rows[name]
    }
    if r.failed_captures:
        warnings.append(
            f"{path}: {r.failed_captures} CAMERA_IMAGE_CAPTURED report a failed capture "
            f"(capture_result 0) and are left out"
        )
    if not present:
        return None, warnings
    chosen = next(iter(present))
    others = [f"{n} ({c})" for n, c in present.items() if n != chosen]
    if others:
        warnings.append(
            f"{path}: camera events taken from {chosen} ({present[chosen]}); also present and "
            f"not used: {', '.join(others)}"
        )
    if chosen == "CAMERA_FEEDBACK" and len(r.cam_idx) > 1:
        warnings.append(
            f"{path}: CAMERA_FEEDBACK from several cameras (cam_idx {sorted(r.cam_idx)}); "
            f"their image indices are mixed in one table"
        )
    # rows: receive time, boot segment, boot time, time, index, then for a positional event
    # lat, lon, alt AMSL, alt above home and the attitude (Euler angles or a quaternion)
    if chosen == "CAMERA_IMAGE_CAPTURED":
        a = _arr(r.rows[chosen], 13)
        t = np.where(a[:, 3] > 0, a[:, 3], clock.utc_s(a[:, 1], a[:, 2]))
        notes: list[str] = []
        angles: tuple[F64, ...] = roll_pitch_yaw_deg_from_quaternion(a[:, 9], a[:, 10], a[:, 11], a[:, 12])
    else:
        a = _arr(r.rows[chosen], 12 if chosen == "CAMERA_FEEDBACK" else 5)
        t, notes = _time_usec_to_utc(a[:, 3], a[:, 1], a[:, 2], clock)
        angles = (a[:, 9], a[:, 10], a[:, 11]) if chosen == "CAMERA_FEEDBACK" else ()
    seq = a[:, 4]
    order = time_order(t, seq)
    values = (a[:, 5], a[:, 6], a[:, 7], a[:, 8], *angles) if angles else ()
    cols = dict(zip(_EVENT_COLUMNS, values, strict=False))
    warnings += [f"{path}: {chosen}: {n}" for n in notes]
    untimed = int(np.count_nonzero(~np.isfinite(t)))
    if untimed:
        warnings.append(f"{path}: {untimed} {chosen} have no time that can be put on UTC and are left out")
    dropped = len(a) - len(order)
    if dropped:
        log.info("%s: %d duplicated or untimed %s dropped", path, dropped, chosen)
    ev = CameraEvents(
        time_utc_s=t[order],
        seq=seq[order].astype(np.int64),
        source=f"tlog:{chosen}",
        **{k: v[order] for k, v in cols.items()},
    )
    return ev, warnings


def _positions(path: str, r: _Reading, clock: _Clock) -> PositionTrack | None:
    if r.rows["GLOBAL_POSITION_INT"]:
        a = _arr(r.rows["GLOBAL_POSITION_INT"], 7)
        if r.rows["GPS_RAW_INT"]:
            # Before the first GPS fix the estimator's position is relative to a null origin
            # (ArduPilot reports points near 0, 0): keep only positions from the first fix on.
            first_fix_rx_s = min(row[0] for row in r.rows["GPS_RAW_INT"])
            a = a[a[:, 0] >= first_fix_rx_s]
            if len(a) == 0:
                return None
        t = clock.utc_s(a[:, 1], a[:, 2])
        return model.position_track(t, (a[:, 3], a[:, 4]), a[:, 5], a[:, 6], "tlog:GLOBAL_POSITION_INT")
    if r.rows["GPS_RAW_INT"]:
        a = _arr(r.rows["GPS_RAW_INT"], 7)
        t, _ = _time_usec_to_utc(a[:, 3], a[:, 1], a[:, 2], clock)
        return model.position_track(t, (a[:, 4], a[:, 5]), a[:, 6], None, "tlog:GPS_RAW_INT")
    return None


def _attitudes(r: _Reading, clock: _Clock) -> AttitudeTrack | None:
    if not r.rows["ATTITUDE"]:
        return None
    a = _arr(r.rows["ATTITUDE"], 6)
    t = clock.utc_s(a[:, 1], a[:, 2])
    o = time_order(t)
    return AttitudeTrack(
        time_utc_s=t[o],
        roll_deg=a[o, 3],
        pitch_deg=a[o, 4],
        yaw_deg=np.mod(a[o, 5], 360.0),
        source="tlog:ATTITUDE",
    )


def _gimbal(
    path: str, r: _Reading, clock: _Clock, vehicle: AttitudeTrack | None
) -> tuple[AttitudeTrack | None, list[str]]:
    if r.rows["GIMBAL_DEVICE_ATTITUDE_STATUS"]:
        a = _arr(r.rows["GIMBAL_DEVICE_ATTITUDE_STATUS"], 8)
        roll, pitch, yaw = roll_pitch_yaw_deg_from_quaternion(a[:, 4], a[:, 5], a[:, 6], a[:, 7])
        earth = mm.gimbal_yaw_in_earth_frame(a[:, 3])
        source = "tlog:GIMBAL_DEVICE_ATTITUDE_STATUS"
    elif r.rows["MOUNT_STATUS"]:
        a = _arr(r.rows["MOUNT_STATUS"], 6)
        roll, pitch, yaw = a[:, 3], a[:, 4], a[:, 5]
        earth = np.zeros(len(a), dtype=bool)
        source = "tlog:MOUNT_STATUS"
    else:
        return None, []
    t = clock.utc_s(a[:, 1], a[:, 2])
    track = model.gimbal_track(t, (roll, pitch, yaw), earth, vehicle, source)
    if track is None:
        return None, [
            f"{path}: gimbal yaw is relative to the vehicle and there is no "
            f"vehicle attitude to add; gimbal left out"
        ]
    return track, []


def read_tlog(path: str | os.PathLike[str], progress: ReadProgress | None = None) -> FlightLog:
    """Read a MAVLink .tlog into the normalized tables (UTC times; see the module docstring).

    Raises :class:`TelemetryError` when the file holds no MAVLink message at all.
    """
    p = os.fspath(path)
    size = os.path.getsize(p)
    r = _collect(p, progress)
    if progress is not None:
        progress(size, size)
    if r.n_messages == 0:
        raise TelemetryError(
            f"{p}: no MAVLink message could be read ({size} bytes, {r.n_bad} corrupt packets); is it a .tlog?"
        )
    warnings: list[str] = []
    if r.last_good_end < size:
        warnings.append(
            f"{p}: reading stopped at byte {r.last_good_end} of {size} after {r.n_messages} "
            f"messages (truncated or corrupt tail)"
        )
    if r.ignored:
        srcs = ", ".join(f"{sys_}/{comp} ({n})" for (sys_, comp), n in sorted(r.ignored.items()))
        warnings.append(
            f"{p}: messages from other sources than the vehicle "
            f"{r.vehicle[0] if r.vehicle else '?'}/{r.vehicle[1] if r.vehicle else '?'} "
            f"ignored (system/component: {srcs})"
        )
    if r.n_bad:
        warnings.append(
            f"{p}: {r.n_bad} corrupt MAVLink packets skipped, the first after byte {r.first_bad_at}"
        )
    clock = _boot_clock(p, r)
    warnings += clock.warnings
    events, w = _events(p, r, clock)
    warnings += w
    attitudes = _attitudes(r, clock)
    gimbal, w = _gimbal(p, r, clock, attitudes)
    warnings += w
    positions = _positions(p, r, clock)
    return model.flight_log(
        p,
        "tlog",
        warnings,
        events=events,
        positions=positions,
        attitudes=attitudes,
        gimbal=gimbal,
        vehicle_type=None if r.mav_type is None else model.vehicle_type_of_mav_type(r.mav_type),
    )
