"""The files of a recording folder, written so that a crash or a power cut loses (almost) nothing.

* ``flight.tlog``: every message, as MAVProxy and QGroundControl write a telemetry log: an
  8-byte big-endian receive time (microseconds since the Unix epoch, UTC, the ground
  station's clock) then the packet's raw bytes (``msg.get_msgbuf()``, signature included).
  The file is flushed after every message, so a crash of this process loses nothing that
  was received; it is also fsync'ed after every camera event and at least once every
  :data:`FSYNC_INTERVAL_S`, so a power cut loses at most the last second.
* ``triggers.csv``: one row per camera event (header :data:`CSV_COLUMNS`, units in the
  names), appended and flushed and fsync'ed row by row, never rewritten.
* ``monitor.json``: the final state, written atomically when the recording closes.
"""

from __future__ import annotations

import csv
import io
import math
import os
import struct
from collections.abc import Sequence
from pathlib import Path
from typing import IO, Any

from planner.errors import OutputExistsError

from .clock import WALL_CLOCK, Clock
from .monitor_state import CameraEvent

TLOG_NAME = "flight.tlog"
CSV_NAME = "triggers.csv"
SUMMARY_NAME = "monitor.json"
#: The trigger CSV's header, in order.
CSV_COLUMNS = (
    "time_utc_s",
    "seq",
    "lat_deg",
    "lon_deg",
    "alt_amsl_m",
    "alt_rel_home_m",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "source",
)
#: fsync the tlog at least this often (wall seconds).
FSYNC_INTERVAL_S = 1.0


def recording_paths(out_dir: str | os.PathLike[str]) -> tuple[Path, Path, Path]:
    """(tlog, trigger CSV, summary JSON) paths of a recording folder."""
    folder = Path(out_dir)
    return folder / TLOG_NAME, folder / CSV_NAME, folder / SUMMARY_NAME


def check_recording_target(out_dir: str | os.PathLike[str], *, overwrite: bool) -> Path:
    """Refuse (:class:`OutputExistsError`) when ``out_dir`` already holds a recording and
    ``overwrite`` is False; a file in place of the folder is always refused."""
    folder = Path(out_dir)
    if folder.exists() and not folder.is_dir():
        raise OutputExistsError(f"{folder} exists and is not a folder; choose another -o folder")
    existing = [p for p in recording_paths(folder) if p.exists()]
    if existing and not overwrite:
        raise OutputExistsError(
            f"{folder} already holds a recording ({', '.join(p.name for p in existing)}); "
            f"pass --overwrite to replace it or choose another -o folder"
        )
    return folder


def _fmt(value: float | None, decimals: int) -> str:
    if value is None or not math.isfinite(value):
        return ""
    return f"{value:.{decimals}f}"


class RecordingFiles:
    """The open tlog and trigger CSV of a recording folder (created; checked with
    :func:`check_recording_target`); a stale ``monitor.json`` is removed."""

    def __init__(
        self, out_dir: str | os.PathLike[str], *, overwrite: bool, clock: Clock = WALL_CLOCK
    ) -> None:
        self.clock = clock
        folder = check_recording_target(out_dir, overwrite=overwrite)
        folder.mkdir(parents=True, exist_ok=True)
        self.folder = folder
        self.tlog_path, self.csv_path, self.summary_path = recording_paths(folder)
        if self.summary_path.exists():
            self.summary_path.unlink()
        self._tlog: IO[bytes] | None = open(self.tlog_path, "wb")  # noqa: SIM115 - close()
        self._csv: IO[str] | None = open(self.csv_path, "w", encoding="utf-8", newline="")  # noqa: SIM115
        self._write_csv_row(CSV_COLUMNS)
        self._last_fsync_s = self.clock.monotonic()

    def write_message(self, msg: Any, rx_time_utc_s: float) -> None:
        """One tlog record: the receive time, then the packet."""
        assert self._tlog is not None
        data = msg.get_msgbuf()
        stamp = struct.pack(">Q", max(round(rx_time_utc_s * 1e6), 0))
        self._tlog.write(stamp + bytes(data))  # one write: a record is whole or absent
        self._tlog.flush()
        now = self.clock.monotonic()
        if now - self._last_fsync_s >= FSYNC_INTERVAL_S:
            os.fsync(self._tlog.fileno())
            self._last_fsync_s = now

    def write_event(self, event: CameraEvent) -> None:
        """One trigger CSV row, and the tlog made durable: an event is what the crew cannot
        get back."""
        self._write_csv_row(
            (
                _fmt(event.time_utc_s, 6),
                str(event.seq),
                _fmt(event.lat_deg, 7),
                _fmt(event.lon_deg, 7),
                _fmt(event.alt_amsl_m, 3),
                _fmt(event.alt_rel_home_m, 3),
                _fmt(event.roll_deg, 3),
                _fmt(event.pitch_deg, 3),
                _fmt(event.yaw_deg, 3),
                event.source,
            )
        )
        self.sync_tlog()

    def sync_tlog(self) -> None:
        """Flush and fsync the tlog now (an event, a drop)."""
        if self._tlog is not None:
            self._tlog.flush()
            os.fsync(self._tlog.fileno())
            self._last_fsync_s = self.clock.monotonic()

    def _write_csv_row(self, row: Sequence[str]) -> None:
        assert self._csv is not None
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n").writerow(row)
        self._csv.write(buffer.getvalue())  # one write per row: a row is whole or absent
        self._csv.flush()
        os.fsync(self._csv.fileno())

    def close(self) -> None:
        """Close both files, fsync'ed."""
        for handle in (self._tlog, self._csv):
            if handle is not None:
                handle.flush()
                os.fsync(handle.fileno())
                handle.close()
        self._tlog = self._csv = None
