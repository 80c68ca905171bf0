"""Readers of flight logs into the normalized tables of :mod:`acquisition.telemetry.model`.

:func:`read_log` recognises a file by its content, not its name, and calls the reader:

============  ==========================================================  =====================
format        recognised by                                               reader
============  ==========================================================  =====================
``ulog``      header ``ULog\\x01\\x12\\x35``                                  :mod:`.ulog`
``dataflash`` DataFlash message header 0xA3 0x95 and the FMT type 0x80    :mod:`.dataflash`
``tlog``      8-byte big-endian receive time (microseconds, 2001-2100)     :mod:`.tlog`
              followed by a MAVLink 1 (0xFE) or 2 (0xFD) frame
``gpx``       a ``<gpx`` element                                          :mod:`.gpx`
``csv``       a header row of a GPS track layout (exiftool's: GPSLatitude  :mod:`.tracks`
              and GPSDateTime; an autopilot's GPS export: CSV_LAYOUTS)
``mrk``       a DJI ``photo tow [week] n,N`` line                         :mod:`.mrk`
============  ==========================================================  =====================
"""

from __future__ import annotations

import csv
import os
import struct

from ..errors import TelemetryError
from .model import FlightLog, ReadProgress

__all__ = ["FORMATS", "FlightLog", "ReadProgress", "TelemetryError", "detect_format", "read_log"]

#: The formats :func:`read_log` knows, with what each is.
FORMATS: dict[str, str] = {
    "tlog": "MAVLink telemetry log (.tlog)",
    "dataflash": "ArduPilot DataFlash log (.bin)",
    "ulog": "PX4 ULog (.ulg)",
    "csv": "CSV track (.csv): exiftool's layout, or an ArduPilot/PX4 GPS export",
    "gpx": "GPX track (.gpx)",
    "mrk": "DJI RTK photo events (.MRK)",
}

_ULOG_MAGIC = b"ULog\x01\x12\x35"
_DATAFLASH_HEAD = b"\xa3\x95\x80"
# Receive times a tlog may carry: 2001-09-09 to 2100-01-01, microseconds since 1970.
_TLOG_MIN_US = 1_000_000_000_000_000
_TLOG_MAX_US = 4_102_444_800_000_000
_SNIFF_BYTES = 65_536


def _mavlink_frame_len(data: bytes, at: int) -> int | None:
    """Length of the MAVLink frame starting at ``at`` (None if there is none)."""
    if at + 2 > len(data):
        return None
    magic, payload = data[at], data[at + 1]
    if magic == 0xFE:
        return 6 + payload + 2
    if magic == 0xFD:
        if at + 3 > len(data):
            return None
        signed = data[at + 2] & 0x01
        return 10 + payload + 2 + (13 if signed else 0)
    return None


def _looks_like_tlog(data: bytes) -> bool:
    """A receive time and a MAVLink frame, twice in a row, within the first few KB."""
    # A receive time in range is below 2**56: its first (big-endian) byte is zero. Text has no
    # zero byte, so a CSV or GPX track is told apart without the walk below.
    if data.find(b"\x00", 0, max(0, min(len(data) - 9, 4096))) < 0:
        return False
    for start in range(min(len(data) - 9, 4096)):
        (t_us,) = struct.unpack_from(">Q", data, start)
        if not _TLOG_MIN_US <= t_us <= _TLOG_MAX_US:
            continue
        n = _mavlink_frame_len(data, start + 8)
        if n is None:
            continue
        nxt = start + 8 + n
        if nxt + 9 > len(data):
            return start == 0  # a one-message file
        (t2,) = struct.unpack_from(">Q", data, nxt)
        if _TLOG_MIN_US <= t2 <= _TLOG_MAX_US and data[nxt + 8] in (0xFE, 0xFD):
            return True
    return False


def detect_format(path: str | os.PathLike[str]) -> str:
    """The format of the log at ``path``, one of :data:`FORMATS`, recognised by its content.

    Raises :class:`TelemetryError` naming the file and the formats known when it is none.
    """
    from .tracks import csv_layout_message, is_csv_track

    p = os.fspath(path)
    try:
        with open(p, "rb") as f:
            head = f.read(_SNIFF_BYTES)
    except OSError as exc:
        raise TelemetryError(f"cannot read flight log {p}: {exc.strerror or exc}") from exc
    if not head:
        raise TelemetryError(f"{p} is empty; expected a flight log")
    if head.startswith(_ULOG_MAGIC):
        return "ulog"
    if head.startswith(_DATAFLASH_HEAD):
        return "dataflash"
    if _looks_like_tlog(head):
        return "tlog"
    text = head.decode("utf-8", errors="replace").lstrip("\ufeff")
    if "<gpx" in text[:4096]:
        return "gpx"
    lines = [line for line in text.splitlines() if line.strip()]
    if lines:
        first = lines[0]
        header = next(csv.reader([first.replace(";", ",")]), [])
        if is_csv_track(header):
            return "csv"
        from .mrk import MRK_SIGNATURE  # here: a CSV track does not pay for the MRK reader's import

        if MRK_SIGNATURE.match(first):
            return "mrk"
        printable = all(c.isprintable() or c in "\t\r\n" for c in text[:4096])
        if printable and len([h for h in header if h.strip()]) >= 2:
            raise TelemetryError(csv_layout_message(p, header))
    known = "; ".join(f"{k}: {v}" for k, v in FORMATS.items())
    raise TelemetryError(f"{p}: not a flight log format sfap reads (known: {known})")


def read_log(path: str | os.PathLike[str], progress: ReadProgress | None = None) -> FlightLog:
    """Read any flight log sfap knows (see :data:`FORMATS`) into a :class:`FlightLog`: camera
    events and poses in UTC, with warnings for anything odd (a truncated file and where
    reading stopped, a missing time reference...). Raises :class:`TelemetryError`.

    ``progress(done, total)`` is called as the file is read (bytes; the DataFlash reader
    counts its two passes, so its total is twice the size; small formats report at the end)."""
    fmt = detect_format(path)
    if fmt == "tlog":
        from .tlog import read_tlog

        return read_tlog(path, progress)
    if fmt == "dataflash":
        from .dataflash import read_dataflash

        return read_dataflash(path, progress)
    if fmt == "ulog":
        from .ulog import read_ulog

        log = read_ulog(path)
    elif fmt == "gpx":
        from .gpx import read_gpx

        log = read_gpx(path)
    elif fmt == "csv":
        from .tracks import read_csv_track

        log = read_csv_track(path)
    else:
        from .mrk import read_mrk

        log = read_mrk(path)
    if progress is not None:
        size = os.path.getsize(path)
        progress(size, size)
    return log
