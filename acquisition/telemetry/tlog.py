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

import logging
import math
import os
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..attitude import euler_deg_from_quat
from ..errors import TelemetryError
from .gpstime import BootClock, fit_boot_clock, gps_usec_to_utc_s, time_order
from .model import PROGRESS_STEP_BYTES, AttitudeTrack, CameraEvents, FlightLog, PositionTrack, ReadProgress

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]

# Below this many microseconds (about 3.2 years) a time_usec is time since boot.
BOOT_US_LIMIT = 100_000_000_000_000
# A reboot: time_boot_ms falls back by more than this.
_REBOOT_BACKSTEP_MS = 5_000
_MAV_AUTOPILOT_INVALID = 8
# Messages other components of the vehicle send (a MAVLink camera, a gimbal device); the
# others are taken only from the autopilot.
_FROM_PAYLOADS = {"CAMERA_IMAGE_CAPTURED", "GIMBAL_DEVICE_ATTITUDE_STATUS"}
_GIMBAL_YAW_LOCK = 16
_GIMBAL_YAW_IN_VEHICLE_FRAME = 32
_GIMBAL_YAW_IN_EARTH_FRAME = 64

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


def euler_deg_from_quaternion(w: ArrayLike, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> tuple[F64, F64, F64]:
    """(roll, pitch, yaw) in degrees, Tait-Bryan z-y'-x'' (yaw, then pitch, then roll), of the
    rotation from body (FRD) to local NED given as a quaternion (w, x, y, z), the convention of
    MAVLink and PX4. Yaw is 0-360 clockwise from north; the quaternion need not be unit (a zero
    quaternion reads as no rotation). At pitch +-90 (a gimbal looking straight down) the roll is
    0 and the yaw carries the whole turn (:func:`acquisition.attitude.euler_deg_from_quat`)."""
    q = np.stack([np.asarray(a, dtype=np.float64) for a in np.broadcast_arrays(w, x, y, z)], axis=-1)
    flat = np.atleast_2d(q.reshape(-1, 4)).copy()
    zero = np.linalg.norm(flat, axis=1) == 0
    flat[zero] = (1.0, 0.0, 0.0, 0.0)
    yaw, pitch, roll = euler_deg_from_quat(flat)
    shape = q.shape[:-1]
    return roll.reshape(shape)[()], pitch.reshape(shape)[()], yaw.reshape(shape)[()]


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


@dataclass
class _Reading:
    """What one pass over the file collected (lists of tuples, one per message)."""

    rows: dict[str, list[tuple[float, ...]]] = field(default_factory=dict)
    boot_segment: int = 0
    last_boot_ms: float | None = None
    n_messages: int = 0
    n_bad: int = 0
    first_bad_at: int | None = None
    last_good_end: int = 0
    cam_idx: Counter[int] = field(default_factory=Counter)
    failed_captures: int = 0
    vehicle: tuple[int, int] | None = None
    ignored: Counter[tuple[int, int]] = field(default_factory=Counter)


def _receive_boot_ms(r: _Reading) -> float:
    """The vehicle's boot time when the current message arrived (the last one seen), NaN
    before any message carried one."""
    return math.nan if r.last_boot_ms is None else r.last_boot_ms


def _note_boot(r: _Reading, boot_ms: float) -> None:
    if r.last_boot_ms is not None and boot_ms < r.last_boot_ms - _REBOOT_BACKSTEP_MS:
        r.boot_segment += 1
    r.last_boot_ms = boot_ms


def _collect(path: str, progress: ReadProgress | None = None) -> _Reading:
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
            r.n_messages += 1
            r.last_good_end = conn.f.tell()
            src = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
            if mtype == "HEARTBEAT" and r.vehicle is None and msg.autopilot != _MAV_AUTOPILOT_INVALID:
                r.vehicle = src  # the first autopilot heard; GCS, gimbals, cameras send INVALID
            if mtype not in _WANTED:
                continue
            # Until the autopilot's first HEARTBEAT every source is taken as the vehicle.
            from_vehicle = r.vehicle is None or src == r.vehicle
            same_system = r.vehicle is None or src[0] == r.vehicle[0]
            if not (same_system if mtype in _FROM_PAYLOADS else from_vehicle):
                r.ignored[src] += 1
                continue
            rx_s = float(msg._timestamp)
            seg = float(r.boot_segment)
            if mtype == "SYSTEM_TIME":
                _note_boot(r, float(msg.time_boot_ms))
                seg = float(r.boot_segment)
                r.rows[mtype].append((rx_s, seg, float(msg.time_boot_ms), float(msg.time_unix_usec)))
            elif mtype == "CAMERA_FEEDBACK":
                r.cam_idx[int(msg.cam_idx)] += 1
                r.rows[mtype].append(
                    (
                        rx_s,
                        seg,
                        _receive_boot_ms(r),
                        float(msg.time_usec),
                        float(msg.img_idx),
                        msg.lat * 1e-7,
                        msg.lng * 1e-7,
                        float(msg.alt_msl),
                        float(msg.alt_rel),
                        float(msg.roll),
                        float(msg.pitch),
                        float(msg.yaw),
                    )
                )
            elif mtype == "CAMERA_TRIGGER":
                r.rows[mtype].append((rx_s, seg, _receive_boot_ms(r), float(msg.time_usec), float(msg.seq)))
            elif mtype == "CAMERA_IMAGE_CAPTURED":
                if int(msg.capture_result) != 1:
                    r.failed_captures += 1
                    continue
                q = list(msg.q)
                # A camera component's time_boot_ms counts from its own boot: only the
                # autopilot's is on the clock SYSTEM_TIME maps; otherwise the arrival time.
                boot_ms = float(msg.time_boot_ms) if from_vehicle else _receive_boot_ms(r)
                r.rows[mtype].append(
                    (
                        rx_s,
                        seg,
                        boot_ms,
                        float(msg.time_utc),
                        float(msg.image_index),
                        msg.lat * 1e-7,
                        msg.lon * 1e-7,
                        msg.alt * 1e-3,
                        msg.relative_alt * 1e-3,
                        *(float(v) for v in q),
                    )
                )
            elif mtype == "GLOBAL_POSITION_INT":
                _note_boot(r, float(msg.time_boot_ms))
                if msg.lat == 0 and msg.lon == 0:
                    continue  # no position yet
                r.rows[mtype].append(
                    (
                        rx_s,
                        float(r.boot_segment),
                        float(msg.time_boot_ms),
                        msg.lat * 1e-7,
                        msg.lon * 1e-7,
                        msg.alt * 1e-3,
                        msg.relative_alt * 1e-3,
                    )
                )
            elif mtype == "GPS_RAW_INT":
                if msg.fix_type < 2 or (msg.lat == 0 and msg.lon == 0):
                    continue
                r.rows[mtype].append(
                    (
                        rx_s,
                        seg,
                        _receive_boot_ms(r),
                        float(msg.time_usec),
                        msg.lat * 1e-7,
                        msg.lon * 1e-7,
                        msg.alt * 1e-3,
                    )
                )
            elif mtype == "ATTITUDE":
                _note_boot(r, float(msg.time_boot_ms))
                r.rows[mtype].append(
                    (
                        rx_s,
                        float(r.boot_segment),
                        float(msg.time_boot_ms),
                        math.degrees(msg.roll),
                        math.degrees(msg.pitch),
                        math.degrees(msg.yaw),
                    )
                )
            elif mtype == "MOUNT_STATUS":
                # ArduPilot: pointing_a pitch, pointing_b roll, pointing_c yaw relative to the
                # vehicle, centidegrees. No time field: the arrival time stands in.
                r.rows[mtype].append(
                    (
                        rx_s,
                        seg,
                        _receive_boot_ms(r),
                        msg.pointing_b * 1e-2,
                        msg.pointing_a * 1e-2,
                        msg.pointing_c * 1e-2,
                    )
                )
            elif mtype == "GIMBAL_DEVICE_ATTITUDE_STATUS":
                # Sent by the autopilot for its own mount drivers, or by a MAVLink gimbal
                # device whose time_boot_ms is its own clock (then the arrival time is used).
                if from_vehicle:
                    _note_boot(r, float(msg.time_boot_ms))
                boot_ms = float(msg.time_boot_ms) if from_vehicle else _receive_boot_ms(r)
                q = list(msg.q)
                r.rows[mtype].append(
                    (
                        rx_s,
                        float(r.boot_segment),
                        boot_ms,
                        float(msg.flags),
                        *(float(v) for v in q),
                    )
                )
    finally:
        conn.close()
    return r


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
            fit = fit_boot_clock(st[sel, 2] / 1e3, st[sel, 3] / 1e6)
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
            pairs.setdefault(int(row[1]), []).append((row[2] / 1e3, row[0]))
    for seg in sorted(segs_needed - set(fits)):
        p = np.array(pairs[seg])
        fallback[seg] = fit_boot_clock(p[:, 0], p[:, 1])
        warnings.append(
            f"{path}: boot {seg} has no SYSTEM_TIME with UTC (no GPS time); its times come "
            f"from the ground station's receive clock, which can be off by seconds"
        )
    return _Clock(fits=fits, fallback=fallback, warnings=warnings)


def _time_usec_to_utc(time_usec: F64, seg: F64, rx_boot_ms: F64, clock: _Clock) -> tuple[F64, list[str]]:
    """UTC of time_usec values that are Unix-epoch, GPS-epoch or boot microseconds; 0 -> the
    arrival time (boot clock of the last message before it)."""
    notes: list[str] = []
    out = np.full(time_usec.shape, np.nan)
    rx_utc = clock.utc_s(seg, rx_boot_ms / 1e3)
    zero = time_usec <= 0
    boot = ~zero & (time_usec < BOOT_US_LIMIT)
    epoch = ~zero & ~boot
    out[boot] = clock.utc_s(seg[boot], time_usec[boot] / 1e6)
    if epoch.any():
        us = time_usec[epoch].astype(np.int64)
        as_unix = (us // 1_000_000).astype(np.float64) + (us % 1_000_000) / 1e6
        as_gps = gps_usec_to_utc_s(us)
        ref = rx_utc[epoch]
        use_gps = np.isfinite(ref) & (np.abs(as_gps - ref) < np.abs(as_unix - ref))
        out[epoch] = np.where(use_gps, as_gps, as_unix)
        if use_gps.any():
            notes.append(f"{int(use_gps.sum())} time_usec values read as GPS-epoch microseconds")
    if zero.any():
        out[zero] = rx_utc[zero]
        notes.append(
            f"{int(zero.sum())} events have no time of their own (time_usec 0, no GPS time); "
            f"their arrival time is used"
        )
    return out, notes


def _arr(rows: list[tuple[float, ...]], width: int) -> F64:
    return np.array(rows, dtype=np.float64).reshape(-1, width)


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
    if chosen == "CAMERA_FEEDBACK":
        if len(r.cam_idx) > 1:
            warnings.append(
                f"{path}: CAMERA_FEEDBACK from several cameras (cam_idx {sorted(r.cam_idx)}); "
                f"their image indices are mixed in one table"
            )
        a = _arr(r.rows[chosen], 12)
        t, notes = _time_usec_to_utc(a[:, 3], a[:, 1], a[:, 2], clock)
        order = time_order(t, a[:, 4])
        cols = {
            "lat_deg": a[:, 5],
            "lon_deg": a[:, 6],
            "alt_amsl_m": a[:, 7],
            "alt_rel_home_m": a[:, 8],
            "roll_deg": a[:, 9],
            "pitch_deg": a[:, 10],
            "yaw_deg": np.mod(a[:, 11], 360.0),
        }
        seq = a[:, 4]
    elif chosen == "CAMERA_IMAGE_CAPTURED":
        a = _arr(r.rows[chosen], 13)
        t = np.where(a[:, 3] > 0, a[:, 3] / 1e6, clock.utc_s(a[:, 1], a[:, 2] / 1e3))
        notes = []
        roll, pitch, yaw = euler_deg_from_quaternion(a[:, 9], a[:, 10], a[:, 11], a[:, 12])
        order = time_order(t, a[:, 4])
        cols = {
            "lat_deg": a[:, 5],
            "lon_deg": a[:, 6],
            "alt_amsl_m": a[:, 7],
            "alt_rel_home_m": a[:, 8],
            "roll_deg": roll,
            "pitch_deg": pitch,
            "yaw_deg": yaw,
        }
        seq = a[:, 4]
    else:
        a = _arr(r.rows[chosen], 5)
        t, notes = _time_usec_to_utc(a[:, 3], a[:, 1], a[:, 2], clock)
        order = time_order(t, a[:, 4])
        cols = {}
        seq = a[:, 4]
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
        t = clock.utc_s(a[:, 1], a[:, 2] / 1e3)
        o = time_order(t)
        return PositionTrack(
            time_utc_s=t[o],
            lat_deg=a[o, 3],
            lon_deg=a[o, 4],
            alt_amsl_m=a[o, 5],
            alt_rel_home_m=a[o, 6],
            source="tlog:GLOBAL_POSITION_INT",
        )
    if r.rows["GPS_RAW_INT"]:
        a = _arr(r.rows["GPS_RAW_INT"], 7)
        t, _ = _time_usec_to_utc(a[:, 3], a[:, 1], a[:, 2], clock)
        o = time_order(t)
        return PositionTrack(
            time_utc_s=t[o],
            lat_deg=a[o, 4],
            lon_deg=a[o, 5],
            alt_amsl_m=a[o, 6],
            source="tlog:GPS_RAW_INT",
        )
    return None


def _attitudes(r: _Reading, clock: _Clock) -> AttitudeTrack | None:
    if not r.rows["ATTITUDE"]:
        return None
    a = _arr(r.rows["ATTITUDE"], 6)
    t = clock.utc_s(a[:, 1], a[:, 2] / 1e3)
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
        t = clock.utc_s(a[:, 1], a[:, 2] / 1e3)
        roll, pitch, yaw = euler_deg_from_quaternion(a[:, 4], a[:, 5], a[:, 6], a[:, 7])
        flags = a[:, 3].astype(np.int64)
        earth = ((flags & _GIMBAL_YAW_IN_EARTH_FRAME) != 0) | (
            ((flags & _GIMBAL_YAW_LOCK) != 0) & ((flags & _GIMBAL_YAW_IN_VEHICLE_FRAME) == 0)
        )
        source = "tlog:GIMBAL_DEVICE_ATTITUDE_STATUS"
    elif r.rows["MOUNT_STATUS"]:
        a = _arr(r.rows["MOUNT_STATUS"], 6)
        t = clock.utc_s(a[:, 1], a[:, 2] / 1e3)
        roll, pitch, yaw = a[:, 3], a[:, 4], a[:, 5]
        earth = np.zeros(len(a), dtype=bool)
        source = "tlog:MOUNT_STATUS"
    else:
        return None, []
    warnings: list[str] = []
    if not earth.all():
        yaw_e = yaw_to_earth_deg(yaw, t, vehicle)
        if yaw_e is None:
            return None, [
                f"{path}: gimbal yaw is relative to the vehicle and there is no "
                f"vehicle attitude to add; gimbal left out"
            ]
        yaw = np.where(earth, yaw, yaw_e)
    o = time_order(t)
    return (
        AttitudeTrack(
            time_utc_s=t[o],
            roll_deg=roll[o],
            pitch_deg=pitch[o],
            yaw_deg=np.mod(yaw[o], 360.0),
            source=source,
        ),
        warnings,
    )


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
    for w_ in warnings:
        log.warning("%s", w_)
    return FlightLog(
        path=p,
        format="tlog",
        events=events,
        positions=positions,
        attitudes=attitudes,
        gimbal=gimbal,
        warnings=tuple(warnings),
    )
