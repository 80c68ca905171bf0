"""The normalized tables every telemetry reader produces (.tlog, DataFlash .bin, .ulg, CSV, GPX, MRK).

All times are UTC, POSIX seconds (float64). Columns are numpy arrays of equal length, in
time order. A column the source does not carry is ``None`` (never NaN-filled or -9999).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

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
