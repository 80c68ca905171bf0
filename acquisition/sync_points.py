"""The crew's sync points (``--sync FRAME=TIME``, ``--sync-position FRAME=LAT,LON``): frames whose
UTC time or position is known independently of the camera clock, and how they are read from the
command line. What they settle is in :mod:`acquisition.geotag_offset`.

Standard library only, so that the geotag command can check its options before numpy is loaded
(see :mod:`acquisition.card_ahead`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime

from planner.errors import InputError

#: How well a crew knows a sync frame's time (read off a GPS clock, a phone), seconds.
SYNC_TIME_ACCURACY_S = 1.0
#: How far, beyond the nearest, a pass of the track or an event may be from a sync position and
#: still be where the frame was taken (a point picked on a map under a nadir frame), metres.
SYNC_POSITION_RADIUS_M = 15.0
#: A sync position farther than this from every pass of the flight is not on it, metres.
SYNC_POSITION_MAX_M = 100.0


@dataclass(frozen=True, kw_only=True)
class SyncPoint:
    """A frame the crew can place independently: its known UTC time (``time_utc_s``), or the
    known position it was taken from (``lat_deg``, ``lon_deg``). ``frame`` is the file name,
    or its path relative to the image folder when names repeat across folders."""

    frame: str
    time_utc_s: float | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None

    def __post_init__(self) -> None:
        if (self.time_utc_s is None) == (self.lat_deg is None or self.lon_deg is None):
            raise InputError(f"sync point for {self.frame}: give a time or a position (one of them)")
        if (
            self.lat_deg is not None
            and self.lon_deg is not None
            and not (-90.0 < self.lat_deg < 90.0 and -180.0 <= self.lon_deg <= 180.0)
        ):
            raise InputError(
                f"sync position {self.lat_deg}, {self.lon_deg} for {self.frame} is not a latitude, "
                f"longitude in degrees (WGS84)"
            )


def parse_sync_time(text: str) -> SyncPoint:
    """``FRAME=TIME`` (``--sync``): TIME in ISO 8601 UTC (``2026-11-22T10:32:05.4Z``; a time
    without a zone is read as UTC) or POSIX seconds."""
    frame, sep, value = text.rpartition("=")
    if not sep or not frame.strip() or not value.strip():
        raise InputError(
            f"sync point {text!r}: expected FRAME=TIME, e.g. IMG_0001.JPG=2026-11-22T10:32:05.4Z"
        )
    value = value.strip()
    try:
        time_utc_s = float(value)
    except ValueError:
        try:
            stamp = datetime.fromisoformat(value.replace("Z", "+00:00").replace("z", "+00:00"))
        except ValueError:
            raise InputError(
                f"sync time {value!r} for {frame}: not an ISO 8601 time (2026-11-22T10:32:05.4Z) "
                f"or POSIX seconds"
            ) from None
        if stamp.tzinfo is None:
            stamp = stamp.replace(tzinfo=UTC)
        time_utc_s = stamp.timestamp()
    if not math.isfinite(time_utc_s):
        raise InputError(f"sync time {value!r} for {frame} is not a finite number")
    return SyncPoint(frame=frame.strip(), time_utc_s=time_utc_s)


def parse_sync_position(text: str) -> SyncPoint:
    """``FRAME=LAT,LON`` (``--sync-position``): the position the frame was taken from, WGS84
    degrees."""
    frame, sep, value = text.rpartition("=")
    parts = value.split(",")
    if not sep or not frame.strip() or len(parts) != 2:
        raise InputError(
            f"sync position {text!r}: expected FRAME=LAT,LON, e.g. IMG_0001.JPG=42.0012,-93.0004"
        )
    try:
        lat, lon = (float(p) for p in parts)
    except ValueError:
        raise InputError(f"sync position {value!r} for {frame}: LAT,LON must be numbers (degrees)") from None
    if not (math.isfinite(lat) and math.isfinite(lon)):
        raise InputError(f"sync position {value!r} for {frame}: not finite")
    return SyncPoint(frame=frame.strip(), lat_deg=lat, lon_deg=lon)
