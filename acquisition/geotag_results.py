"""What geotagging did, frame by frame, and how it is tuned: statuses, options, results, the report.

:class:`FrameResult` is one frame's outcome (:class:`FrameStatus`), :class:`GeotagResult` the whole
run's; :func:`report_json` is ``geotag_report.json``. :class:`GeotagOptions` tunes
:func:`acquisition.geotag.geotag_images`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from planner.errors import InputError
from planner.outputs import json_safe

from .attitude import CameraMount, GimbalMode
from .interpolation import iso_utc

REPORT_NAME = "geotag_report.json"


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
    IMAGES = "images"  # from the frames' own motion against the track (acquisition.offset_from_images)


@dataclass(frozen=True, kw_only=True)
class GeotagOptions:
    """Tuning of :func:`geotag_images`.

    - ``tolerance_s``: largest frame/event residual (None: 35 % of the event interval).
    - ``max_gap_s``: longest track interval to interpolate over.
    - ``xy_accuracy_m``, ``z_accuracy_m``: one-sigma accuracy of the log's positions (uncorrected
      GNSS by default); frames placed by time add speed x timing scatter.
    - ``place_extra_by_time``: place frames that have no event at their corrected capture time.
    - ``gimbal_mode``: see :class:`GimbalMode`.
    - ``camera_mount``: see :class:`CameraMount` (what the camera's attitude is when the log has
      no gimbal angles).
    """

    tolerance_s: float | None = None
    max_gap_s: float = 5.0
    xy_accuracy_m: float = 2.0
    z_accuracy_m: float = 3.0
    place_extra_by_time: bool = True
    position_source: PositionSource = PositionSource.AUTO
    gimbal_mode: GimbalMode = GimbalMode.EARTH
    camera_mount: CameraMount = CameraMount.AUTO

    def __post_init__(self) -> None:
        if self.tolerance_s is not None and not (0.0 < self.tolerance_s <= 60.0):
            raise InputError(
                f"tolerance {self.tolerance_s:g} s: give a time above 0 s and at most 60 s (0 < s <= 60)"
            )
        if not (0.0 < self.max_gap_s <= 3600.0):
            raise InputError(
                f"max gap {self.max_gap_s:g} s: give a time above 0 s and at most 3600 s (0 < s <= 3600)"
            )
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
    minus UTC; ``drift_ppm``: its rate of change. ``offset_sigma_s``: the offset's one-sigma
    uncertainty when it was estimated with one (from the images); ``offset_from_images``: what the
    images said (:meth:`acquisition.offset_from_images.OffsetEstimate.as_dict`), when asked.
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
    offset_sigma_s: float | None = None
    offset_from_images: dict[str, Any] | None = None

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
    def passed(self) -> bool:
        """Every frame tagged (else `sfap geotag` exits 1, having listed the others)."""
        return not self.untagged

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
                "offset_sigma_s": self.offset_sigma_s,
                "offset_from_images": self.offset_from_images,
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


def report_json(result: GeotagResult) -> str:
    """The result as JSON text (what ``geotag_report.json`` holds and ``--json`` prints): the
    summary indented, then one line per frame (json's fast encoder; 1000 frames stay quick)."""
    doc = json_safe(result.to_dict())
    summary = json.dumps(doc["summary"], indent=2, allow_nan=False).replace("\n", "\n  ")
    frames = ",\n    ".join(json.dumps(f, allow_nan=False) for f in doc["frames"])
    return f'{{\n  "summary": {summary},\n  "frames": [\n    {frames}\n  ]\n}}\n'
