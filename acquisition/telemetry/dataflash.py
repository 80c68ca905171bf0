"""ArduPilot DataFlash logs (.bin) -> :class:`~acquisition.telemetry.model.FlightLog`.

Read with pymavlink's DFReader (its type filter skips the messages we do not need, through
the index it builds when it opens the file). Every field is looked up by name in the log's
own FMT messages, because the layouts changed over the years:

- CAM / TRIG, current (ArduPilot PR 30375, 2025): ``QBHIHLLeeefff``
  ``TimeUS,I,Img,GPSTime,GPSWeek,Lat,Lng,Alt,RelAlt,GPSAlt,R,P,Y``, float degrees.
- 4.x before it (the flight in ../shared/data, 4.5.6): ``QBHIHLLeeeccC``, the same names with
  centi-degree integers (``c``/``C``, which DFReader scales to degrees).
- 3.x: ``QIHLLeeeccC`` ``TimeUS,GPSTime,GPSWeek,Lat,Lng,Alt,RelAlt,GPSAlt,Roll,Pitch,Yaw``
  (no image number: events are numbered 1, 2, ... in log order), and older ones with
  ``TimeMS`` or no boot time at all.

Timing: CAM is logged when the camera is triggered (or, with a feedback pin, when the hot
shoe fires; TRIG then marks the trigger command). Its ``GPSTime``/``GPSWeek`` are those of
the last GPS fix, up to a GPS period before the event, so the event time is ``TimeUS``
(boot clock) mapped onto UTC through the GPS messages: each fix gives GPS week + time of
week (``GWk``, ``GMS``) against the boot time at which the autopilot received it (GPA
``SMS``, ms; the GPS message's own ``TimeUS`` when there is no GPA, which is logged some
milliseconds later), and :func:`~acquisition.telemetry.gpstime.fit_boot_clock` fits the
line. This is the same mapping ArduPilot uses for the time it sends in CAMERA_FEEDBACK.

Poses: POS (EKF position, AMSL and above home; GPS when there is no POS), ATT (attitude),
MNT (gimbal; earth-frame yaw ``YawE`` when logged, else the body-frame yaw plus the
vehicle's).
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import re
import struct
import sys
import tempfile
from collections.abc import Iterator
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import TelemetryError
from .gpstime import BootClock, fit_boot_clock, gps_week_ms_to_utc_s, time_order
from .model import (
    PROGRESS_STEP_BYTES,
    AttitudeTrack,
    CameraEvents,
    FlightLog,
    PositionTrack,
    ReadProgress,
    VehicleType,
    assemble_log,
    gimbal_track,
    position_track,
)

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]

_TYPES = ["CAM", "TRIG", "GPS", "GPA", "POS", "ATT", "MNT"]
# MSG: the firmware names itself ("ArduPlane V4.5.6 (7ce11b41)") in the first messages; a
# QuadPlane is an ArduPlane too (a fixed wing with lift rotors).
_FIRMWARE = re.compile(r"^\s*Ardu(Plane|Copter)\b")
# Integer format characters that DFReader does not scale; an attitude stored in one of them
# is in centi-degrees (the int16 roll/pitch/uint16 yaw of the old log structures).
_RAW_INT_FORMATS = set("bBhHiI")
_GPS_3D_FIX = 3


def _field(names: list[str], *candidates: str) -> str | None:
    for c in candidates:
        if c in names:
            return c
    return None


class _Columns:
    """The rows of one message type, column by column, looked up by name."""

    def __init__(self, fmt: Any) -> None:
        self.names: list[str] = list(fmt.columns)
        self.formats: str = str(fmt.format)
        self.rows: list[list[Any]] = []

    def add(self, msg: Any) -> None:
        self.rows.append([getattr(msg, n) for n in self.names])

    def has(self, name: str | None) -> bool:
        return name is not None and name in self.names

    def col(self, name: str) -> F64:
        i = self.names.index(name)
        return np.array([row[i] for row in self.rows], dtype=np.float64)

    def angle_deg(self, name: str) -> F64:
        """An attitude column in degrees, whichever unit the layout stored it in."""
        v = self.col(name)
        if self.formats[self.names.index(name)] in _RAW_INT_FORMATS:
            v = v / 100.0
        return v

    def __len__(self) -> int:
        return len(self.rows)


def _boot_s(cols: _Columns) -> F64 | None:
    if cols.has("TimeUS"):
        return cols.col("TimeUS") / 1e6
    if cols.has("TimeMS") and not cols.has("Week"):
        return cols.col("TimeMS") / 1e3
    return None


@contextlib.contextmanager
def _captured_output() -> Iterator[io.StringIO]:
    """Capture what is printed while inside, from Python and from C extensions alike.

    DFReader prints its complaints about corrupt data, and its C indexer writes them to the
    process's file descriptor 2 directly; both are kept for the warnings instead of
    flooding the user's terminal.
    """
    text = io.StringIO()
    sys.stdout.flush()
    sys.stderr.flush()
    with tempfile.TemporaryFile() as sink:
        saved = [os.dup(1), os.dup(2)]
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            with contextlib.redirect_stdout(text), contextlib.redirect_stderr(text):
                yield text
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            sink.seek(0)
            text.write(sink.read().decode("utf-8", errors="replace"))


def _read(path: str, progress: ReadProgress | None = None) -> tuple[dict[str, _Columns], list[str], int, int]:
    """Columns per wanted type, DFReader's complaints, end of the last message, file size."""
    from pymavlink import DFReader

    tables: dict[str, _Columns] = {}
    with _captured_output() as captured:
        try:
            # Two passes: DFReader indexes the file (reported in percent), then the messages
            # wanted are read; progress counts both, as twice the file's size.
            size_bytes = os.path.getsize(path)

            def indexed(percent: int) -> None:
                if progress is not None:
                    progress(size_bytes * int(percent) // 100, 2 * size_bytes)

            reader = DFReader.DFReader_binary(path, zero_time_base=True, progress_callback=indexed)
        except (OSError, ValueError, KeyError, IndexError, struct.error) as exc:
            raise TelemetryError(f"{path}: not a readable DataFlash log: {exc}") from exc
        try:
            wanted = [t for t in [*_TYPES, "MSG"] if t in reader.name_to_id]
            total = int(reader.data_len)
            next_report = 0
            while wanted:
                if progress is not None and reader.offset >= next_report:
                    progress(total + int(reader.offset), 2 * total)
                    next_report = int(reader.offset) + PROGRESS_STEP_BYTES
                msg = reader.recv_match(type=wanted)
                if msg is None:
                    break
                name = msg.get_type()
                if name not in tables:
                    tables[name] = _Columns(msg.fmt)
                tables[name].add(msg)
            end = _end_of_last_message(reader)
            size = int(reader.data_len)
        finally:
            reader.filehandle.close()
    complaints = [line for line in captured.getvalue().splitlines() if line.strip()]
    return tables, complaints, end, size


def _end_of_last_message(reader: Any) -> int:
    """Byte offset just past the last complete message DFReader's index found."""
    end = 0
    offsets = reader.offsets
    for mtype in range(len(offsets)):
        if not offsets[mtype] or mtype not in reader.formats:
            continue
        last = int(offsets[mtype][-1])
        length = int(reader.formats[mtype].len)
        if last + length <= reader.data_len:
            end = max(end, last + length)
        elif len(offsets[mtype]) > 1:
            end = max(end, int(offsets[mtype][-2]) + length)
    return end


def _clock(path: str, t: dict[str, _Columns]) -> tuple[BootClock | None, list[str]]:
    gps = t.get("GPS")
    if gps is None or len(gps) == 0:
        return None, [f"{path}: no GPS messages: times cannot be put on UTC"]
    week_f = _field(gps.names, "GWk", "Week")
    tow_f = _field(gps.names, "GMS", "GPSTimeMS")
    boot: F64 | None
    if tow_f is None and week_f == "Week" and gps.has("TimeMS") and gps.has("T"):
        tow_f, boot = "TimeMS", gps.col("T") / 1e3  # ArduPilot 3.2-era layout
    else:
        boot = _boot_s(gps)
    if week_f is None or tow_f is None or boot is None:
        return None, [f"{path}: GPS messages lack week/time-of-week/boot time ({gps.names})"]
    week, tow = gps.col(week_f), gps.col(tow_f)
    ok = week > 0
    if gps.has("Status"):
        ok &= gps.col("Status") >= _GPS_3D_FIX
    if gps.has("I"):
        ok &= gps.col("I") == 0
    notes: list[str] = []
    gpa = t.get("GPA")
    if gpa is not None and gpa.has("SMS") and gpa.has("TimeUS") and gps.has("TimeUS"):
        # GPA is written right after GPS with the same TimeUS; its SMS is the boot time at
        # which the fix was received, the instant ArduPilot itself pins the GPS time to.
        inst = gpa.col("I") if gpa.has("I") else np.zeros(len(gpa))
        g_us = gpa.col("TimeUS")[inst == 0]
        sms = gpa.col("SMS")[inst == 0] / 1e3
        gus = gps.col("TimeUS")
        pos = np.searchsorted(g_us, gus)
        pos = np.clip(pos, 0, max(len(g_us) - 1, 0))
        matched = len(g_us) > 0
        if matched:
            hit = g_us[pos] == gus
            boot = np.where(hit, sms[pos], boot)
            if not hit[ok].all():
                notes.append(f"{path}: {int((~hit[ok]).sum())} GPS fixes without GPA SMS")
    if not ok.any():
        return None, [f"{path}: no GPS message with a 3D fix: times cannot be put on UTC"]
    fit = fit_boot_clock(boot[ok], gps_week_ms_to_utc_s(week[ok], tow[ok]))
    log.debug("%s: boot clock %s", path, fit)
    if fit.residual_rms_s > 0.05:
        notes.append(
            f"{path}: GPS time scatters by {fit.residual_rms_s * 1e3:.0f} ms RMS around the "
            f"boot clock fit; event times are no better than that"
        )
    return fit, notes


def _events(
    path: str, t: dict[str, _Columns], clock: BootClock | None
) -> tuple[CameraEvents | None, list[str]]:
    warnings: list[str] = []
    name = "CAM" if t.get("CAM") else "TRIG" if t.get("TRIG") else None
    if name is None:
        return None, warnings
    if name == "CAM" and t.get("TRIG"):
        warnings.append(
            f"{path}: CAM ({len(t['CAM'])}, at the camera's feedback) used for the events; "
            f"TRIG ({len(t['TRIG'])}, at the trigger command) not used"
        )
    c = t[name]
    n = len(c)
    if c.has("I"):
        inst = c.col("I")
        if len(np.unique(inst)) > 1:
            warnings.append(
                f"{path}: {name} from several cameras (instances "
                f"{sorted({int(i) for i in inst})}); their image numbers are mixed in one table"
            )
    seq_f = _field(c.names, "Img", "Seq", "ImgNum")
    seq = c.col(seq_f) if seq_f else np.arange(1, n + 1, dtype=np.float64)
    boot = _boot_s(c)
    if boot is not None and clock is not None:
        time_utc = clock.utc_s(boot)
    elif c.has("GPSWeek") and c.has("GPSTime"):
        time_utc = gps_week_ms_to_utc_s(c.col("GPSWeek"), c.col("GPSTime"))
        warnings.append(
            f"{path}: {name} times are those of the last GPS fix (GPSTime), up to a GPS period "
            f"before each event: no boot time or no GPS clock mapping"
        )
    else:
        return None, [*warnings, f"{path}: {name} has no usable time; events left out"]
    cols: dict[str, F64] = {}
    for key, cands in (
        ("lat_deg", ("Lat",)),
        ("lon_deg", ("Lng", "Lon")),
        ("alt_amsl_m", ("Alt",)),
        ("alt_rel_home_m", ("RelAlt",)),
    ):
        f = _field(c.names, *cands)
        if f is not None:
            cols[key] = c.col(f)
    for key, cands in (
        ("roll_deg", ("R", "Roll")),
        ("pitch_deg", ("P", "Pitch")),
        ("yaw_deg", ("Y", "Yaw")),
    ):
        f = _field(c.names, *cands)
        if f is not None:
            cols[key] = c.angle_deg(f)
    if "yaw_deg" in cols:
        cols["yaw_deg"] = np.mod(cols["yaw_deg"], 360.0)
    if "alt_amsl_m" in cols and not c.has("RelAlt") and not c.has("GPSAlt"):
        # The oldest layouts logged current_loc.alt, relative or absolute depending on the
        # mission frame: not a reliable AMSL altitude.
        del cols["alt_amsl_m"]
    order = time_order(time_utc, seq)
    return (
        CameraEvents(
            time_utc_s=time_utc[order],
            seq=seq[order].astype(np.int64),
            source=f"dataflash:{name}",
            **{k: v[order] for k, v in cols.items()},
        ),
        warnings,
    )


def _positions(t: dict[str, _Columns], clock: BootClock | None) -> PositionTrack | None:
    if clock is None:
        return None
    pos = t.get("POS")
    if pos is not None and len(pos) and (boot := _boot_s(pos)) is not None:
        time_utc = clock.utc_s(boot)
        lat, lon = pos.col("Lat"), pos.col(_field(pos.names, "Lng", "Lon") or "Lng")
        keep = ~((lat == 0) & (lon == 0))
        rel_f = _field(pos.names, "RelHomeAlt", "RelAlt")
        rel = pos.col(rel_f) if rel_f else None
        return position_track(time_utc, (lat, lon), pos.col("Alt"), rel, "dataflash:POS", keep=keep)
    gps = t.get("GPS")
    if gps is not None and len(gps) and (boot := _boot_s(gps)) is not None:
        time_utc = clock.utc_s(boot)
        ok = gps.col("Status") >= _GPS_3D_FIX if gps.has("Status") else np.ones(len(gps), bool)
        if gps.has("I"):
            ok &= gps.col("I") == 0
        lat_lon = (gps.col("Lat"), gps.col(_field(gps.names, "Lng", "Lon") or "Lng"))
        return position_track(time_utc, lat_lon, gps.col("Alt"), None, "dataflash:GPS", keep=ok)
    return None


def _attitudes(t: dict[str, _Columns], clock: BootClock | None) -> AttitudeTrack | None:
    att = t.get("ATT")
    if clock is None or att is None or not len(att) or (boot := _boot_s(att)) is None:
        return None
    time_utc = clock.utc_s(boot)
    o = time_order(time_utc)
    return AttitudeTrack(
        time_utc_s=time_utc[o],
        roll_deg=att.angle_deg("Roll")[o],
        pitch_deg=att.angle_deg("Pitch")[o],
        yaw_deg=np.mod(att.angle_deg("Yaw")[o], 360.0),
        source="dataflash:ATT",
    )


def _gimbal(
    path: str, t: dict[str, _Columns], clock: BootClock | None, vehicle: AttitudeTrack | None
) -> tuple[AttitudeTrack | None, list[str]]:
    mnt = t.get("MNT")
    if clock is None or mnt is None or not len(mnt) or (boot := _boot_s(mnt)) is None:
        return None, []
    time_utc = clock.utc_s(boot)
    if mnt.has("I") and len(np.unique(mnt.col("I"))) > 1:
        keep = mnt.col("I") == 0
        time_utc = np.where(keep, time_utc, np.nan)
    roll_f = _field(mnt.names, "Roll", "R")
    pitch_f = _field(mnt.names, "Pitch", "P")
    if roll_f is None or pitch_f is None:
        return None, [f"{path}: MNT without Roll/Pitch ({mnt.names}); gimbal left out"]
    yaw_f = _field(mnt.names, "YawE", "YawB", "Yaw")
    if yaw_f is None:
        return None, [f"{path}: MNT without a yaw ({mnt.names}); gimbal left out"]
    # YawE is earth-frame; YawB (and the old Yaw) are relative to the vehicle's nose.
    rpy = (mnt.angle_deg(roll_f), mnt.angle_deg(pitch_f), mnt.angle_deg(yaw_f))
    earth = np.full(len(time_utc), yaw_f == "YawE")
    track = gimbal_track(time_utc, rpy, earth, vehicle, "dataflash:MNT")
    if track is None:
        return None, [f"{path}: MNT yaw is body-frame and there is no ATT; gimbal left out"]
    return track, []


_SKIPPED = re.compile(r"Skipped (\d+) bad bytes in log at offset (\d+)")
# The Python indexer writes "bad header 0x00 0x00 at N", the C one "bad header 0x0000 at N".
_BAD_HEADER = re.compile(r"bad header 0x[0-9a-fA-F]+(?: 0x[0-9a-fA-F]+)? at (\d+)")


def read_dataflash(path: str | os.PathLike[str], progress: ReadProgress | None = None) -> FlightLog:
    """Read an ArduPilot DataFlash .bin log into the normalized tables (UTC times; see the
    module docstring). Raises :class:`TelemetryError` when the file is not one."""
    p = os.fspath(path)
    tables, complaints, end, size = _read(p, progress)
    vehicle_type = _vehicle_type(tables.pop("MSG", None))
    if progress is not None:
        progress(2 * size, 2 * size)
    warnings: list[str] = []
    if end < size:
        n = sum(len(c) for c in tables.values())
        warnings.append(
            f"{p}: reading stopped at byte {end} of {size} (truncated or corrupt tail; "
            f"{n} messages of the types used were read)"
        )
    bad = [int(m.group(1)) for line in complaints if (m := _BAD_HEADER.search(line))]
    bad += [
        int(m.group(2)) + k
        for line in complaints
        if (m := _SKIPPED.search(line))
        for k in range(int(m.group(1)))
    ]
    if bad:
        warnings.append(f"{p}: {len(set(bad))} bytes of corrupt data skipped, the first at byte {min(bad)}")
    for line in complaints:
        log.debug("DFReader: %s", line)
    if not tables:
        if size and end == 0:
            raise TelemetryError(f"{p}: no DataFlash message could be read ({size} bytes)")
        warnings.append(f"{p}: none of {', '.join(_TYPES)} in the log")
    return assemble_log(
        p, "dataflash", warnings, tables, _clock, _events, _attitudes, _gimbal, _positions, vehicle_type
    )


def _vehicle_type(msg: _Columns | None) -> VehicleType | None:
    """What the firmware's own MSG says the vehicle is (ArduPlane, ArduCopter); None when no
    MSG names either."""
    if msg is None or not msg.has("Message"):
        return None
    i = msg.names.index("Message")
    for row in msg.rows:
        if m := _FIRMWARE.match(str(row[i])):
            return VehicleType.FIXED_WING if m.group(1) == "Plane" else VehicleType.MULTIROTOR
    return None
