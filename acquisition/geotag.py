"""Geotagging frames from the flight's own telemetry: the whole job, its options, results and report.

:func:`geotag_images` reads the frames' capture times, matches them to the log's camera events
(:mod:`acquisition.matching`), places them on the track (:mod:`acquisition.interpolation`, with
the camera attitude from :mod:`acquisition.attitude`), writes the tags and the sidecars, and
reports every frame (:class:`GeotagResult`, :class:`FrameResult`, :class:`FrameStatus`;
:func:`report_json` is ``geotag_report.json``). :class:`GeotagOptions` tunes it.

Placing frames
--------------
A matched frame is placed at its *event* time (the autopilot's clock, not the camera's): the
position track is interpolated there in a local metric frame (UTM of the flight,
:class:`planner.geo.LocalFrame`), attitude by spherical linear interpolation of quaternions; the
camera attitude combines vehicle and gimbal when the log has gimbal attitude. Without camera
events every frame is placed at its capture time corrected by the offset (given, from the
crew's sync points, or from the frames' own EXIF GPS time, else zero, said loudly with what a
wrong offset costs in metres). A frame without an event is placed at its corrected capture
time when the track covers it, and listed. Frames that cannot be placed (no capture time,
unreadable, outside the log, a gap in the track longer than ``max_gap_s``) are listed with the
reason, never guessed, and nothing is written for them.

Never from an offset the data do not pin down: when another camera clock offset aligns the
frames with the events nearly as well (a subset of a card, regular lines; see
:mod:`acquisition.matching`), :func:`geotag_images` raises :class:`GeotagError` naming the
competing offsets, unless ``offset_s`` or a sync point (:class:`SyncPoint`: a frame's known
UTC time, or its known position) settles it.

Cards: the image folder is read recursively (a DCIM folder with 100CANON, 101CANON...); names
that repeat across folders are kept apart by :func:`output_names` (``100CANON_IMG_0001.JPG``).

Camera attitude is written as Pix4D ``Camera:Yaw/Pitch/Roll`` in the convention of
:mod:`acquisition.attitude` (a camera fixed to the airframe looking down carries the vehicle's
yaw, pitch and roll; a level, nadir camera has pitch 0, roll 0).
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import shutil
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from planner.errors import InputError, OutputExistsError
from planner.geo import LocalFrame
from planner.outputs import atomic_write_text, check_output_dir, staged_output_dir

from . import exif, sidecars
from .attitude import GimbalMode, camera_attitude_deg
from .errors import GeotagError
from .interpolation import InterpolatedPose, PoseInterpolation, interpolate_poses, iso_utc
from .matching import Matching, match_frames_to_events
from .telemetry.model import CameraEvents, FlightLog, PositionTrack

logger = logging.getLogger(__name__)

F64 = NDArray[np.float64]

JPEG_SUFFIXES = (".jpg", ".jpeg")
REPORT_NAME = "geotag_report.json"

#: progress(done, total): called as frames are read and written.
ProgressCallback = Callable[[int, int], None]


class FrameStatus(StrEnum):
    """What happened to one frame. The first three are placed; the others are not."""

    MATCHED = "matched"  # paired with a camera event, placed at the event time
    BY_TIME = "by_time"  # the log has no camera events: placed at the corrected capture time
    EXTRA_BY_TIME = "extra_by_time"  # no event for this frame; placed at its corrected capture time
    EXTRA = "extra"  # no event for this frame, and the track does not cover its time
    NO_POSITION = "no_position"  # the time is outside the log or in a gap of the track
    NO_CAPTURE_TIME = "no_capture_time"
    UNREADABLE = "unreadable"
    DUPLICATE_NAME = "duplicate_name"
    WRITE_FAILED = "write_failed"

    @property
    def placed(self) -> bool:
        return self in (FrameStatus.MATCHED, FrameStatus.BY_TIME, FrameStatus.EXTRA_BY_TIME)


class PositionSource(StrEnum):
    """Where a matched frame's position comes from: ``auto`` = the event's own position for
    RTK event files (MRK), the interpolated track otherwise (the event's position when the
    track does not cover the event)."""

    AUTO = "auto"
    TRACK = "track"
    EVENT = "event"


class OffsetSource(StrEnum):
    GIVEN = "given"  # --offset-s, used as is (time only) or as the alignment to refine
    MATCHED = "matched"  # from the alignment with camera events
    EXIF_GPS = "exif_gps"  # frames' own GPS time stamps versus capture time
    SYNC = "sync"  # from the crew's sync points (a frame's known time or position)
    ASSUMED_ZERO = "assumed_zero"


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
            and not (-90.0 <= self.lat_deg <= 90.0 and -180.0 <= self.lon_deg <= 180.0)
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


@dataclass(frozen=True, kw_only=True)
class GeotagOptions:
    """Tuning of :func:`geotag_images`.

    - ``tolerance_s``: largest frame/event residual (None: 35 % of the event interval).
    - ``max_gap_s``: longest track interval to interpolate over.
    - ``xy_accuracy_m``, ``z_accuracy_m``: one-sigma accuracy of the log's positions (uncorrected
      GNSS by default); frames placed by time add speed x timing scatter.
    - ``place_extra_by_time``: place frames that have no event at their corrected capture time.
    - ``gimbal_mode``: see :class:`GimbalMode`.
    """

    tolerance_s: float | None = None
    max_gap_s: float = 5.0
    xy_accuracy_m: float = 2.0
    z_accuracy_m: float = 3.0
    place_extra_by_time: bool = True
    position_source: PositionSource = PositionSource.AUTO
    gimbal_mode: GimbalMode = GimbalMode.EARTH

    def __post_init__(self) -> None:
        if self.tolerance_s is not None and not (0.0 < self.tolerance_s <= 60.0):
            raise InputError(f"tolerance {self.tolerance_s} s is outside 0-60 s")
        if not (0.0 < self.max_gap_s <= 3600.0):
            raise InputError(f"max gap {self.max_gap_s} s is outside 0-3600 s")
        if self.xy_accuracy_m < 0 or self.z_accuracy_m < 0:
            raise InputError("position accuracies must be >= 0 m")


@dataclass(frozen=True, kw_only=True)
class FrameResult:
    """One frame's outcome. Position and attitude are None when the frame was not placed.

    ``capture_time_s``: the camera's time stamp (camera clock); ``time_utc_s``: the UTC time the
    frame was placed at (its event's time, or the corrected capture time); ``time_residual_s``:
    capture time minus the time predicted from the matched event (matched frames only).
    """

    name: str
    source_path: str
    status: FrameStatus
    message: str | None = None
    capture_time_s: float | None = None
    time_utc_s: float | None = None
    event_index: int | None = None
    event_seq: int | None = None
    time_residual_s: float | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_amsl_m: float | None = None
    alt_rel_home_m: float | None = None
    yaw_deg: float | None = None
    pitch_deg: float | None = None
    roll_deg: float | None = None
    xy_accuracy_m: float | None = None
    z_accuracy_m: float | None = None
    interpolation_gap_s: float | None = None
    position_source: str | None = None
    output_path: str | None = None

    @property
    def placed(self) -> bool:
        return self.status.placed

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "source_path": self.source_path,
            "status": str(self.status),
            "message": self.message,
            "capture_time": None if self.capture_time_s is None else iso_utc(self.capture_time_s),
            "capture_time_s": self.capture_time_s,
            "time_utc": None if self.time_utc_s is None else iso_utc(self.time_utc_s),
            "time_utc_s": self.time_utc_s,
            "event_index": self.event_index,
            "event_seq": self.event_seq,
            "time_residual_s": self.time_residual_s,
            "lat_deg": self.lat_deg,
            "lon_deg": self.lon_deg,
            "alt_amsl_m": self.alt_amsl_m,
            "alt_rel_home_m": self.alt_rel_home_m,
            "yaw_deg": self.yaw_deg,
            "pitch_deg": self.pitch_deg,
            "roll_deg": self.roll_deg,
            "xy_accuracy_m": self.xy_accuracy_m,
            "z_accuracy_m": self.z_accuracy_m,
            "interpolation_gap_s": self.interpolation_gap_s,
            "position_source": self.position_source,
            "output_path": self.output_path,
        }


@dataclass(frozen=True, kw_only=True)
class GeotagResult:
    """Everything :func:`geotag_images` did: per frame, and the summary.

    ``unmatched_events``: (index, seq) of camera events no frame was found for (dropped frames).
    ``untagged``: frames nothing was written for, with the reason. ``offset_s``: camera clock
    minus UTC; ``drift_ppm``: its rate of change.
    """

    frames: tuple[FrameResult, ...]
    n_events: int
    unmatched_events: tuple[tuple[int, int], ...]
    offset_s: float
    offset_source: OffsetSource
    drift_ppm: float
    residual_mad_s: float | None
    tolerance_s: float | None
    dry_run: bool
    out_dir: str
    outputs: tuple[str, ...] = ()
    warnings: tuple[str, ...] = field(default=())

    @property
    def extra_frames(self) -> tuple[str, ...]:
        """Frames without a camera event (whether or not they could be placed by time)."""
        return tuple(
            f.name for f in self.frames if f.status in (FrameStatus.EXTRA, FrameStatus.EXTRA_BY_TIME)
        )

    @property
    def untagged(self) -> tuple[FrameResult, ...]:
        return tuple(f for f in self.frames if not f.placed or f.status is FrameStatus.WRITE_FAILED)

    @property
    def tagged(self) -> tuple[FrameResult, ...]:
        return tuple(f for f in self.frames if f.placed)

    def to_dict(self) -> dict[str, Any]:
        return {
            "summary": {
                "frames": len(self.frames),
                "tagged": len(self.tagged),
                "untagged": [
                    {"name": f.name, "status": str(f.status), "message": f.message} for f in self.untagged
                ],
                "camera_events": self.n_events,
                "matched": sum(1 for f in self.frames if f.status is FrameStatus.MATCHED),
                "extra_frames": list(self.extra_frames),
                "unmatched_events": [{"index": i, "seq": s} for i, s in self.unmatched_events],
                "offset_s": self.offset_s,
                "offset_source": str(self.offset_source),
                "drift_ppm": self.drift_ppm,
                "residual_mad_s": self.residual_mad_s,
                "tolerance_s": self.tolerance_s,
                "dry_run": self.dry_run,
                "out_dir": self.out_dir,
                "outputs": list(self.outputs),
                "warnings": list(self.warnings),
            },
            "frames": [f.to_dict() for f in self.frames],
        }


def list_images(image_dir: str | os.PathLike[str]) -> list[Path]:
    """JPEG files under ``image_dir`` (recursively: a card's DCIM folder holds 100CANON,
    101CANON...), by path."""
    root = Path(image_dir)
    if not root.is_dir():
        raise InputError(f"{root} is not a folder of images; give the folder that holds the JPEGs")
    return sorted(
        p
        for p in root.rglob("*")
        if p.is_file() and p.suffix.lower() in JPEG_SUFFIXES and not p.name.startswith(".")
    )


def output_names(image_dir: str | os.PathLike[str], paths: Sequence[Path]) -> dict[Path, str]:
    """The name each frame gets in the outputs (tagged copies, geo.txt, the CSV, the report).

    Its own file name while names are unique; when names repeat across folders (cameras
    restart at IMG_0001 in each DCIM subfolder), every frame in a subfolder is prefixed with
    its folder path relative to ``image_dir``: ``100CANON/IMG_0001.JPG`` becomes
    ``100CANON_IMG_0001.JPG``, so that the copies sit side by side in one flat folder, as
    reconstruction tools want them, and nothing is overwritten."""
    root = Path(image_dir)
    names = {p: p.name for p in paths}
    if len({n.lower() for n in names.values()}) == len(names):
        return names
    out: dict[Path, str] = {}
    for p in paths:
        try:
            folders = p.relative_to(root).parts[:-1]
        except ValueError:
            folders = p.parent.parts[-1:]
        prefix = "_".join(re.sub(r"[\s,]+", "-", part) for part in folders)
        out[p] = f"{prefix}_{p.name}" if prefix else p.name
    return out


def _resolve_sync_frame(frame: str, root: Path, paths: Sequence[Path], names: dict[Path, str]) -> Path:
    wanted = frame.replace("\\", "/").strip("/").lower()
    by_output = [p for p in paths if names[p].lower() == wanted]
    by_relative = [p for p in paths if p.relative_to(root).as_posix().lower() == wanted]
    by_name = [p for p in paths if p.name.lower() == wanted]
    for found in (by_relative, by_output, by_name):
        if len(found) == 1:
            return found[0]
    if len(by_name) > 1:
        options = ", ".join(p.relative_to(root).as_posix() for p in by_name[:4])
        raise InputError(f"sync frame {frame} names several images ({options}); give its folder too")
    raise InputError(f"sync frame {frame} is not an image under {root}")


def prepare_images(
    image_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    dry_run: bool = False,
    in_place: bool = False,
    backup_dir: str | os.PathLike[str] | None = None,
    overwrite: bool = False,
    sync: Sequence[SyncPoint] = (),
) -> list[Path]:
    """Check the images and the options before anything slow (reading a large log): the
    folder holds JPEGs, the output can be written, the sync frames exist. Returns the images."""
    paths = list_images(image_dir)
    if not paths:
        raise InputError(f"no JPEG images (.jpg, .jpeg) under {image_dir}: give the card's DCIM folder")
    if in_place and backup_dir is None:
        raise InputError("--in-place needs --backup-dir: the originals are copied there first")
    if not dry_run:
        check_output_dir(out_dir, overwrite=overwrite)
        if not in_place and Path(out_dir).resolve() == Path(image_dir).resolve():
            raise InputError("the output folder is the image folder; choose another -o or use --in-place")
    names = output_names(image_dir, paths)
    for point in sync:
        _resolve_sync_frame(point.frame, Path(image_dir), paths, names)
    return paths


@dataclass
class _Frame:
    path: Path
    tags: exif.ImageTags | None = None
    error: str | None = None


def _offset_from_exif_gps(frames: Sequence[_Frame]) -> float | None:
    """Camera clock minus UTC from frames that carry their own GPS time stamp (median)."""
    diffs = [
        fr.tags.capture_time_s - fr.tags.gps_time_utc_s
        for fr in frames
        if fr.tags is not None and fr.tags.capture_time_s is not None and fr.tags.gps_time_utc_s is not None
    ]
    return float(np.median(diffs)) if diffs else None


def _accuracy(options: GeotagOptions, speed_m_s: float, timing_s: float) -> tuple[float, float]:
    xy = math.hypot(options.xy_accuracy_m, speed_m_s * timing_s)
    return xy, options.z_accuracy_m


def _event_pose(events: CameraEvents, j: int) -> InterpolatedPose | None:
    if events.lat_deg is None or events.lon_deg is None:
        return None

    def col(c: F64 | None) -> float | None:
        return None if c is None else float(c[j])

    yaw, pitch, roll = col(events.yaw_deg), col(events.pitch_deg), col(events.roll_deg)
    if yaw is not None and pitch is not None and roll is not None:
        cy, cp, cr = camera_attitude_deg(([yaw], [pitch], [roll]))
        yaw, pitch, roll = float(cy[0]), float(cp[0]), float(cr[0])
    else:
        yaw = pitch = roll = None
    return InterpolatedPose(
        time_utc_s=float(events.time_utc_s[j]),
        lat_deg=float(events.lat_deg[j]),
        lon_deg=float(events.lon_deg[j]),
        alt_amsl_m=col(events.alt_amsl_m),
        alt_rel_home_m=col(events.alt_rel_home_m),
        yaw_deg=yaw,
        pitch_deg=pitch,
        roll_deg=roll,
        position_gap_s=0.0,
        attitude_gap_s=None if yaw is None else 0.0,
        speed_m_s=0.0,
    )


@dataclass(frozen=True)
class _Pass:
    time_utc_s: float
    distance_m: float
    speed_m_s: float


def _passes(times_s: F64, lat_deg: F64, lon_deg: F64, point: SyncPoint) -> list[_Pass]:
    """Where a track (or a sequence of event positions) comes closest to a sync position: one
    entry per pass (local minimum of the distance), nearest first."""
    assert point.lat_deg is not None and point.lon_deg is not None
    order = np.argsort(times_s, kind="stable")
    t, lat, lon = times_s[order], lat_deg[order], lon_deg[order]
    frame = LocalFrame.utm_for(point.lon_deg, point.lat_deg)
    x, y = frame.to_xy(lon, lat)
    px, py = frame.to_xy(point.lon_deg, point.lat_deg)
    if t.size == 1:
        return [_Pass(float(t[0]), float(np.hypot(x[0] - px, y[0] - py)), 0.0)]
    dx, dy, dt = np.diff(x), np.diff(y), np.diff(t)
    length2 = dx * dx + dy * dy
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.clip(np.where(length2 > 0, ((px - x[:-1]) * dx + (py - y[:-1]) * dy) / length2, 0.0), 0.0, 1.0)
        speed = np.where(dt > 0, np.sqrt(length2) / dt, 0.0)
    d = np.hypot(x[:-1] + u * dx - px, y[:-1] + u * dy - py)
    tc = t[:-1] + u * dt
    minima = [
        k
        for k in range(d.size)
        if (k == 0 or d[k] <= d[k - 1]) and (k == d.size - 1 or d[k] < d[k + 1]) and np.isfinite(d[k])
    ]
    passes: list[_Pass] = []
    for k in sorted(minima, key=lambda k: float(d[k])):
        if all(abs(float(tc[k]) - p.time_utc_s) > 5.0 for p in passes):  # one pass, several minima
            passes.append(_Pass(float(tc[k]), float(d[k]), float(speed[k])))
    return passes


def _near_passes(passes: list[_Pass], point: SyncPoint) -> list[_Pass]:
    """The passes a sync position may belong to: within SYNC_POSITION_RADIUS_M of the nearest."""
    if not passes or passes[0].distance_m > SYNC_POSITION_MAX_M:
        nearest = f"{passes[0].distance_m:.0f} m" if passes else "nowhere"
        raise InputError(
            f"sync position {point.lat_deg}, {point.lon_deg} of {point.frame} is not on the flight "
            f"(the nearest pass is {nearest} away, more than {SYNC_POSITION_MAX_M:g} m): check the "
            f"position and the frame"
        )
    return [p for p in passes if p.distance_m <= passes[0].distance_m + SYNC_POSITION_RADIUS_M]


def _track_speeds_m_s(positions: PositionTrack) -> list[float]:
    """Ground speed between consecutive samples of a track, m/s."""
    order = np.argsort(positions.time_utc_s, kind="stable")
    t, lat, lon = positions.time_utc_s[order], positions.lat_deg[order], positions.lon_deg[order]
    frame = LocalFrame.utm_for(float(np.median(lon)), float(np.median(lat)))
    x, y = frame.to_xy(lon, lat)
    dt = np.diff(t)
    ok = (dt > 0) & np.isfinite(np.diff(x)) & np.isfinite(np.diff(y))
    return (np.hypot(np.diff(x), np.diff(y))[ok] / dt[ok]).tolist()


def _offset_cost_warning(offset: float, source: OffsetSource, speeds_m_s: Sequence[float]) -> str | None:
    """What a wrong camera clock offset costs when frames are placed by time: metres per second
    of error at the flight's ground speed."""
    moving = [s for s in speeds_m_s if s > 0.5]
    if not moving:
        return None
    speed = float(np.median(moving))
    how = {
        OffsetSource.GIVEN: "given (--offset-s)",
        OffsetSource.EXIF_GPS: "from the frames' own GPS time stamps",
        OffsetSource.SYNC: "from the sync points",
        OffsetSource.ASSUMED_ZERO: "ASSUMED to be 0 s (no camera events, no --offset-s, no sync point)",
    }.get(source, str(source))
    return (
        f"frames are placed by their capture time: the camera clock offset {offset:+.3f} s is "
        f"{how}; every second it is wrong moves each frame about {speed:.1f} m along the track "
        f"(median ground speed {speed:.1f} m/s), and a wrong time zone by hours puts them "
        f"outside the log. Give a sync point (--sync FRAME=TIME or --sync-position "
        f"FRAME=LAT,LON) to check it"
    )


def _sync_windows_with_events(
    sync_capture: Sequence[tuple[SyncPoint, float]], events: CameraEvents, log: FlightLog
) -> list[list[tuple[float, float]]]:
    """Per sync point, the camera clock offsets it allows, as (centre, half width) windows: a
    known time allows offsets within SYNC_TIME_ACCURACY_S of capture minus that time; a known
    position allows the offsets that put the frame on one of the events taken there."""
    windows: list[list[tuple[float, float]]] = []
    steps = np.diff(np.sort(events.time_utc_s))
    half_step = 0.5 * float(np.median(steps)) if steps.size else 1.0
    for point, capture_s in sync_capture:
        if point.time_utc_s is not None:
            windows.append([(capture_s - point.time_utc_s, SYNC_TIME_ACCURACY_S)])
            continue
        if events.lat_deg is not None and events.lon_deg is not None:
            lat, lon = events.lat_deg, events.lon_deg
        elif log.positions is not None and len(log.positions) > 0:
            lat, lon = _track_at(log, events.time_utc_s)
        else:
            raise InputError(f"sync position for {point.frame}: the log has no positions to compare it with")
        near = _near_passes(_event_points(events.time_utc_s, lat, lon, point), point)
        windows.append([(capture_s - p.time_utc_s, half_step) for p in near])
    return windows


def _event_points(times_s: F64, lat_deg: F64, lon_deg: F64, point: SyncPoint) -> list[_Pass]:
    """Each event as a 'pass' at its own distance from the point, nearest first."""
    assert point.lat_deg is not None and point.lon_deg is not None
    frame = LocalFrame.utm_for(point.lon_deg, point.lat_deg)
    x, y = frame.to_xy(lon_deg, lat_deg)
    px, py = frame.to_xy(point.lon_deg, point.lat_deg)
    d = np.hypot(x - px, y - py)
    return [_Pass(float(times_s[k]), float(d[k]), 0.0) for k in np.argsort(d) if np.isfinite(d[k])]


def _track_at(log: FlightLog, times_s: F64) -> tuple[F64, F64]:
    assert log.positions is not None
    interpolation = interpolate_poses(times_s, positions=log.positions, max_gap_s=1e9)
    lat = np.array([np.nan if p is None else p.lat_deg for p in interpolation.poses])
    lon = np.array([np.nan if p is None else p.lon_deg for p in interpolation.poses])
    return lat, lon


def _sync_offset_by_track(sync_capture: Sequence[tuple[SyncPoint, float]], log: FlightLog) -> float | None:
    """The camera clock offset from sync points alone (no camera events): the median of the
    offsets they give, after checking that they agree within their accuracies. A sync position
    gives the time the track passes it; a track that passes it more than once is ambiguous."""
    if not sync_capture:
        return None
    estimates: list[tuple[float, float, str]] = []  # (offset, accuracy s, what)
    for point, capture_s in sync_capture:
        if point.time_utc_s is not None:
            estimates.append((capture_s - point.time_utc_s, SYNC_TIME_ACCURACY_S, f"{point.frame} time"))
            continue
        if log.positions is None or len(log.positions) < 2:
            raise InputError(f"sync position for {point.frame}: the log has no track to compare it with")
        near = _near_passes(
            _passes(log.positions.time_utc_s, log.positions.lat_deg, log.positions.lon_deg, point), point
        )
        if len(near) > 1:
            listed = ", ".join(f"{iso_utc(p.time_utc_s)} ({p.distance_m:.0f} m)" for p in near[:5])
            raise GeotagError(
                f"nothing written: the flight passes the sync position of {point.frame} "
                f"{len(near)} times ({listed}); the position does not say which pass took the "
                f"frame: give a sync time (--sync) or a position on a single pass"
            )
        speed = max(near[0].speed_m_s, 1.0)
        accuracy = (near[0].distance_m + SYNC_POSITION_RADIUS_M) / speed
        estimates.append((capture_s - near[0].time_utc_s, accuracy, f"{point.frame} position"))
    for a in estimates:
        for b in estimates:
            if abs(a[0] - b[0]) > a[1] + b[1]:
                raise InputError(
                    f"the sync points disagree: {a[2]} gives a camera clock offset of {a[0]:+.1f} s, "
                    f"{b[2]} {b[0]:+.1f} s; check them"
                )
    return float(np.median([e[0] for e in estimates]))


def geotag_images(
    image_dir: str | os.PathLike[str],
    log: FlightLog,
    out_dir: str | os.PathLike[str],
    *,
    offset_s: float | None = None,
    sync: Sequence[SyncPoint] = (),
    dry_run: bool = False,
    in_place: bool = False,
    backup_dir: str | os.PathLike[str] | None = None,
    overwrite: bool = False,
    progress: ProgressCallback | None = None,
    options: GeotagOptions | None = None,
) -> GeotagResult:
    """Geotag every JPEG under ``image_dir`` (recursively) from ``log``; results in ``out_dir``.

    ``out_dir`` receives the tagged copies (unless ``in_place``), the sidecars (``geo.txt``,
    ``pix4d_geolocation.csv``, ``cameras.geojson``) and ``geotag_report.json``; it is built in a
    staging folder and moved into place whole. Names that repeat across folders are kept apart
    (:func:`output_names`). ``offset_s``: camera clock minus UTC, seconds, if known. ``sync``:
    frames whose time or position the crew knows, to find or check the offset. ``in_place``
    rewrites the originals, after copying each to ``backup_dir`` (required). ``dry_run`` writes
    nothing. Frames that cannot be placed are reported, never written.

    Raises :class:`GeotagError` when the frames and events cannot be reconciled, or when their
    alignment is ambiguous (another camera clock offset fits nearly as well) and neither
    ``offset_s`` nor a sync point settles it: no position is written from an offset the data
    do not pin down.
    """
    options = options or GeotagOptions()
    report = progress or (lambda done, total: None)
    root = Path(image_dir)
    paths = prepare_images(
        image_dir,
        out_dir,
        dry_run=dry_run,
        in_place=in_place,
        backup_dir=backup_dir,
        overwrite=overwrite,
        sync=sync,
    )
    names = output_names(image_dir, paths)
    total = 2 * len(paths)

    frames: list[_Frame] = []
    for done, path in enumerate(paths, start=1):
        try:
            frames.append(_Frame(path, tags=exif.read_tags(path)))
        except (GeotagError, OSError) as error:
            frames.append(_Frame(path, error=str(error)))
        report(done, total)

    name_count: dict[str, int] = {}
    for fr in frames:
        name_count[names[fr.path].lower()] = name_count.get(names[fr.path].lower(), 0) + 1
    timed = [fr for fr in frames if fr.tags is not None and fr.tags.capture_time_s is not None]
    timed.sort(key=lambda fr: (fr.tags.capture_time_s if fr.tags else 0.0, str(fr.path)))
    times = np.array([fr.tags.capture_time_s for fr in timed if fr.tags is not None], dtype=float)

    # The sync frames' capture times (camera clock).
    by_path = {fr.path: fr for fr in frames}
    sync_capture: list[tuple[SyncPoint, float]] = []
    for point in sync:
        sync_frame = by_path[_resolve_sync_frame(point.frame, root, paths, names)]
        if sync_frame.tags is None or sync_frame.tags.capture_time_s is None:
            raise InputError(
                f"sync frame {point.frame} has no capture time (DateTimeOriginal): choose another"
            )
        sync_capture.append((point, float(sync_frame.tags.capture_time_s)))

    warnings: list[str] = list(log.warnings)
    events = log.events if log.events is not None and len(log.events) > 0 else None
    matching: Matching | None = None
    results: dict[Path, FrameResult] = {}
    unmatched_events: tuple[tuple[int, int], ...] = ()
    residual_mad: float | None = None
    tolerance: float | None = None
    drift_ppm = 0.0

    def model_to_utc(t: F64) -> F64:
        if matching is not None:
            return matching.frame_time_to_utc(t)
        return np.asarray(t - offset, float)

    # A camera that writes no sub-seconds truncates its times to the second: take the middle.
    whole_seconds = bool(times.size > 1 and np.all(np.abs(times - np.round(times)) < 1e-6))
    if whole_seconds:
        times = times + 0.5
        sync_capture = [(point, t + 0.5) for point, t in sync_capture]
        warnings.append(
            "the capture times have whole seconds only (no SubSecTimeOriginal): matched with a "
            "wider tolerance; frames placed by time can be off by up to half a second of flight"
        )
    if events is not None and times.size:
        windows = None if offset_s is not None else _sync_windows_with_events(sync_capture, events, log)
        matching = match_frames_to_events(
            times,
            events.time_utc_s,
            offset_s=offset_s,
            tolerance_s=options.tolerance_s,
            resolution_s=1.0 if whole_seconds else 0.0,
            offset_windows_s=windows or (),
        )
        if matching.ambiguous and offset_s is None:
            raise GeotagError(
                f"nothing written: {matching.warnings[0]}"
                if matching.warnings
                else "nothing written: the alignment of frames and camera events is ambiguous"
            )
        offset = matching.offset_s
        if offset_s is not None:
            offset_source = OffsetSource.GIVEN
        elif sync_capture:
            offset_source = OffsetSource.SYNC
        else:
            offset_source = OffsetSource.MATCHED
        drift_ppm = matching.drift_ppm
        residual_mad = matching.residual_mad_s
        tolerance = matching.tolerance_s
        warnings.extend(matching.warnings)
        unmatched_events = tuple((int(j), int(events.seq[j])) for j in matching.unmatched_events)
    else:
        if events is None and log.events is not None:
            warnings.append("the log has no camera events: frames are placed by capture time")
        from_sync = None if offset_s is not None else _sync_offset_by_track(sync_capture, log)
        if offset_s is not None:
            offset, offset_source = float(offset_s), OffsetSource.GIVEN
        elif from_sync is not None:
            offset, offset_source = from_sync, OffsetSource.SYNC
        else:
            from_gps = _offset_from_exif_gps(timed)
            if from_gps is not None:
                offset, offset_source = from_gps, OffsetSource.EXIF_GPS
            else:
                offset, offset_source = 0.0, OffsetSource.ASSUMED_ZERO
                if timed and not all(fr.tags is not None and fr.tags.capture_time_zone_known for fr in timed):
                    warnings.append(
                        "no camera events and no --offset-s: the camera clock is assumed to be "
                        "UTC; a wrong clock or time zone places every frame wrongly"
                    )

    # What time and which event each timed frame is placed at.
    event_of = matching.event_of_frame() if matching is not None else {}
    residual_of = (
        {int(fi): float(r) for (fi, _), r in zip(matching.pairs, matching.residuals_s, strict=True)}
        if matching is not None
        else {}
    )
    utc_of_frame = model_to_utc(times) if times.size else np.zeros(0)
    place_times: list[float] = []
    for k in range(len(timed)):
        if k in event_of and events is not None:
            place_times.append(float(events.time_utc_s[event_of[k]]))
        else:
            place_times.append(float(utc_of_frame[k]))

    interpolation: PoseInterpolation | None = None
    if log.positions is not None and len(log.positions) > 0 and place_times:
        interpolation = interpolate_poses(
            place_times,
            positions=log.positions,
            attitudes=log.attitudes,
            gimbal=log.gimbal,
            gimbal_mode=options.gimbal_mode,
            max_gap_s=options.max_gap_s,
        )
    prefer_event = options.position_source is PositionSource.EVENT or (
        options.position_source is PositionSource.AUTO and log.format == "mrk"
    )
    timing_scatter = residual_mad if residual_mad is not None else 0.0

    if events is None and log.positions is not None and len(log.positions) > 1:
        speeds = [] if interpolation is None else [p.speed_m_s for p in interpolation.poses if p is not None]
        if not speeds:  # no frame inside the log: the flight's own ground speed
            speeds = _track_speeds_m_s(log.positions)
        cost = _offset_cost_warning(offset, offset_source, speeds)
        if cost is not None:
            warnings.append(cost)

    for k, fr in enumerate(timed):
        assert fr.tags is not None and fr.tags.capture_time_s is not None
        base: dict[str, Any] = {
            "name": names[fr.path],
            "source_path": str(fr.path),
            "capture_time_s": fr.tags.capture_time_s,
            "time_utc_s": place_times[k],
        }
        pose: InterpolatedPose | None = None
        reason: str | None = None
        source = "track"
        j = event_of.get(k)
        if j is not None and events is not None:
            status = FrameStatus.MATCHED
            base["event_index"] = j
            base["event_seq"] = int(events.seq[j])
            base["time_residual_s"] = residual_of.get(k)
            if options.position_source is not PositionSource.TRACK:
                event_pose = _event_pose(events, j)
            else:
                event_pose = None
            if prefer_event and event_pose is not None:
                pose, source = event_pose, "event"
            elif interpolation is not None and interpolation.poses[k] is not None:
                pose = interpolation.poses[k]
            elif event_pose is not None:
                pose, source = event_pose, "event"
            else:
                reason = interpolation.reasons[k] if interpolation is not None else "the log has no positions"
            if pose is None:
                status = FrameStatus.NO_POSITION
        else:
            extra = events is not None
            status = FrameStatus.EXTRA_BY_TIME if extra else FrameStatus.BY_TIME
            if extra and not options.place_extra_by_time:
                pose, reason = None, "no camera event matches this frame"
            elif interpolation is not None:
                pose, reason = interpolation.poses[k], interpolation.reasons[k]
            else:
                reason = "the log has no positions to place a frame by time"
            if pose is None:
                status = FrameStatus.EXTRA if extra else FrameStatus.NO_POSITION
                if extra:
                    reason = f"no camera event matches this frame; {reason}" if reason else "no camera event"
        if pose is not None:
            timing = 0.0 if status is FrameStatus.MATCHED else timing_scatter
            xy_acc, z_acc = _accuracy(options, pose.speed_m_s, timing)
            if status is FrameStatus.EXTRA_BY_TIME:
                reason = (
                    "no camera event matches this frame: placed at its capture time corrected by the offset"
                )
            results[fr.path] = FrameResult(
                **base,
                status=status,
                message=reason,
                lat_deg=pose.lat_deg,
                lon_deg=pose.lon_deg,
                alt_amsl_m=pose.alt_amsl_m,
                alt_rel_home_m=pose.alt_rel_home_m,
                yaw_deg=pose.yaw_deg,
                pitch_deg=pose.pitch_deg,
                roll_deg=pose.roll_deg,
                xy_accuracy_m=xy_acc,
                z_accuracy_m=z_acc,
                interpolation_gap_s=pose.position_gap_s,
                position_source=source,
            )
        else:
            results[fr.path] = FrameResult(**base, status=status, message=reason)

    for fr in frames:
        if fr.tags is None:
            results[fr.path] = FrameResult(
                name=names[fr.path],
                source_path=str(fr.path),
                status=FrameStatus.UNREADABLE,
                message=fr.error,
            )
        elif fr.tags.capture_time_s is None:
            results[fr.path] = FrameResult(
                name=names[fr.path],
                source_path=str(fr.path),
                status=FrameStatus.NO_CAPTURE_TIME,
                message="no capture time (DateTimeOriginal) in the file: it cannot be matched or placed",
            )
        elif name_count[names[fr.path].lower()] > 1:
            old = results[fr.path]
            results[fr.path] = FrameResult(
                **{
                    **old.__dict__,
                    "status": FrameStatus.DUPLICATE_NAME,
                    "message": f"another image also comes out as {names[fr.path]} (names must be "
                    f"unique in the outputs); rename one of them",
                    "lat_deg": None,
                    "lon_deg": None,
                    "alt_amsl_m": None,
                    "alt_rel_home_m": None,
                    "yaw_deg": None,
                    "pitch_deg": None,
                    "roll_deg": None,
                }
            )
    timed_paths = {fr.path for fr in timed}
    ordered = [results[fr.path] for fr in timed] + [
        results[fr.path] for fr in frames if fr.path not in timed_paths
    ]

    if interpolation is not None and timed and not any(r.placed for r in ordered):
        outside = [r for r in interpolation.reasons if r is not None and " the log (" in r]
        if len(outside) == len(timed):
            warnings.append(
                "no frame falls inside the log: it is from another flight or day, or the camera "
                "clock is off; pass --offset-s (camera clock minus UTC, seconds)"
            )
    for message in warnings:
        logger.warning("%s", message)

    def result(frames_now: Sequence[FrameResult], outs: Sequence[str]) -> GeotagResult:
        return GeotagResult(
            frames=tuple(frames_now),
            n_events=0 if events is None else len(events),
            unmatched_events=unmatched_events,
            offset_s=offset,
            offset_source=offset_source,
            drift_ppm=drift_ppm,
            residual_mad_s=residual_mad,
            tolerance_s=tolerance,
            dry_run=dry_run,
            out_dir=str(out_dir),
            outputs=tuple(outs),
            warnings=tuple(warnings),
        )

    final: list[FrameResult] = ordered
    outputs: list[str] = []
    if not dry_run:
        final, outputs = _write_outputs(
            ordered,
            out_dir=Path(out_dir),
            in_place=in_place,
            backup_dir=None if backup_dir is None else Path(backup_dir),
            overwrite=overwrite,
            report=lambda n: report(len(paths) + n, total),
            warn=warnings.extend,
            summary=result,
        )
    report(total, total)
    return result(final, outputs)


def _json_clean(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_clean(v) for v in value]
    return value


def report_json(result: GeotagResult) -> str:
    """The result as JSON text (what ``geotag_report.json`` holds and ``--json`` prints): the
    summary indented, then one line per frame (json's fast encoder; 1000 frames stay quick)."""
    doc = _json_clean(result.to_dict())
    summary = json.dumps(doc["summary"], indent=2, allow_nan=False).replace("\n", "\n  ")
    frames = ",\n    ".join(json.dumps(f, allow_nan=False) for f in doc["frames"])
    return f'{{\n  "summary": {summary},\n  "frames": [\n    {frames}\n  ]\n}}\n'


def _geotag_of(frame: FrameResult) -> exif.GeoTag:
    assert frame.lat_deg is not None and frame.lon_deg is not None
    return exif.GeoTag(
        lat_deg=frame.lat_deg,
        lon_deg=frame.lon_deg,
        alt_amsl_m=frame.alt_amsl_m,
        time_utc_s=frame.time_utc_s,
        yaw_deg=frame.yaw_deg,
        pitch_deg=frame.pitch_deg,
        roll_deg=frame.roll_deg,
        xy_accuracy_m=frame.xy_accuracy_m,
        z_accuracy_m=frame.z_accuracy_m,
        alt_rel_home_m=frame.alt_rel_home_m,
    )


def _with(frame: FrameResult, **changes: Any) -> FrameResult:
    return FrameResult(**{**frame.__dict__, **changes})


def _write_outputs(
    frames: list[FrameResult],
    *,
    out_dir: Path,
    in_place: bool,
    backup_dir: Path | None,
    overwrite: bool,
    report: Callable[[int], None],
    warn: Callable[[Iterable[str]], None],
    summary: Callable[[list[FrameResult], list[str]], GeotagResult],
) -> tuple[list[FrameResult], list[str]]:
    """Write tagged frames, sidecars and the report; returns the frames with their output paths."""
    to_write = [f for f in frames if f.placed]
    written: list[FrameResult] = []
    if in_place:
        assert backup_dir is not None
        backup_dir.mkdir(parents=True, exist_ok=True)
        for frame in to_write:  # every backup before the first original is touched
            target = backup_dir / frame.name
            if target.exists() and not overwrite:
                raise OutputExistsError(
                    f"backup {target} exists; pass --overwrite or choose another --backup-dir"
                )
            shutil.copy2(frame.source_path, target)
    with staged_output_dir(out_dir, overwrite=overwrite) as staging:
        by_path: dict[str, FrameResult] = {}
        # In place: each original is replaced atomically (synced). Copies go plainly into the
        # staging folder, which is moved into place whole at the end. Frames are written a few at
        # a time (the image data is copied by the kernel, see exif.write_geotags).
        jobs = [
            exif.GeotagJob(
                src=frame.source_path,
                dst=frame.source_path if in_place else str(staging / frame.name),
                tag=_geotag_of(frame),
            )
            for frame in to_write
        ]
        outcomes = exif.write_geotags(jobs, overwrite=in_place, atomic=in_place, progress=report)
        for frame, outcome in zip(to_write, outcomes, strict=True):
            final_path = Path(frame.source_path) if in_place else out_dir / frame.name
            if outcome.written:
                by_path[frame.source_path] = _with(frame, output_path=str(final_path))
                warn(outcome.warnings)
            else:
                by_path[frame.source_path] = _with(
                    frame, status=FrameStatus.WRITE_FAILED, message=f"tags not written: {outcome.error}"
                )
        written = [by_path.get(f.source_path, f) for f in frames]
        placed = [f for f in written if f.placed]
        rows = [
            sidecars.CameraPosition(
                name=f.name,
                lat_deg=f.lat_deg,
                lon_deg=f.lon_deg,
                alt_amsl_m=f.alt_amsl_m,
                yaw_deg=f.yaw_deg,
                pitch_deg=f.pitch_deg,
                roll_deg=f.roll_deg,
                xy_accuracy_m=f.xy_accuracy_m,
                z_accuracy_m=f.z_accuracy_m,
                time_utc_s=f.time_utc_s,
                status=str(f.status),
            )
            for f in placed
            if f.lat_deg is not None and f.lon_deg is not None
        ]
        sidecar_paths = sidecars.write_all(staging, rows)
        outputs = [str(out_dir / p.name) for p in sidecar_paths] + [str(out_dir / REPORT_NAME)]
        result = summary(written, outputs)
        atomic_write_text(staging / REPORT_NAME, report_json(result))
    return written, outputs
