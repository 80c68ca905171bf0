"""Geotagging frames from the flight's own telemetry: the whole job, its options, results and report.

:func:`geotag_images` reads the frames' capture times, matches them to the log's camera events
(:mod:`acquisition.matching`), places them on the track (:mod:`acquisition.interpolation`, with
the camera attitude from :mod:`acquisition.attitude`), writes the tags and the sidecars, and
reports every frame (:mod:`acquisition.geotag_results`). It is a pipeline of named steps over
the library, each a function: the card's frames (:mod:`acquisition.card`) and their tags
(:mod:`acquisition.geotag_frames`), the camera clock (:func:`_set_clock`: matched to events, or
from sync points and the frames' GPS time, :mod:`acquisition.geotag_offset`), the frames placed
and those that cannot be (:mod:`acquisition.geotag_placement`), and the outputs
(:mod:`acquisition.geotag_outputs`).

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
competing offsets, unless ``offset_s`` or a sync point
(:class:`~acquisition.geotag_offset.SyncPoint`: a frame's known UTC time, or its known position)
settles it.

Cards: the image folder is read recursively (a DCIM folder with 100CANON, 101CANON...); names
that repeat across folders are kept apart (:func:`acquisition.card.output_names`,
``100CANON_IMG_0001.JPG``).

Camera attitude is written as Pix4D ``Camera:Yaw/Pitch/Roll`` in the convention of
:mod:`acquisition.attitude` (a camera fixed to the airframe looking down carries the vehicle's
yaw, pitch and roll; a level, nadir camera has pitch 0, roll 0).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from planner.outputs import StagedOutputDir

from .card import output_names, prepare_images
from .card_ahead import CardAhead
from .errors import GeotagError
from .geotag_frames import (
    Frame,
    read_frames,
    sync_capture_times,
    timed_frames,
)
from .geotag_offset import (
    offset_from_exif_gps,
    sync_offset_by_track,
    sync_windows_with_events,
)
from .geotag_outputs import write_outputs
from .geotag_placement import Clock, not_placed, place_frames
from .geotag_results import (
    FrameResult,
    GeotagOptions,
    GeotagResult,
    OffsetSource,
)
from .matching import match_frames_to_events
from .sync_points import SyncPoint
from .telemetry.model import CameraEvents, FlightLog

if TYPE_CHECKING:
    from .offset_from_images import ReconstructionOptions

logger = logging.getLogger(__name__)

F64 = NDArray[np.float64]

#: progress(done, total): called as frames are read and written.
ProgressCallback = Callable[[int, int], None]


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
    staging: StagedOutputDir | None = None,
    ahead: CardAhead | None = None,
    images: Sequence[Path] | None = None,
    offset_from_images: ReconstructionOptions | None = None,
) -> GeotagResult:
    """Geotag every JPEG under ``image_dir`` (recursively) from ``log``; results in ``out_dir``.

    ``out_dir`` receives the tagged copies (unless ``in_place``), the sidecars (``geo.txt``,
    ``pix4d_geolocation.csv``, ``cameras.geojson``) and ``geotag_report.json``; it is built in a
    staging folder and moved into place whole. Names that repeat across folders are kept apart
    (:func:`~acquisition.card.output_names`). ``offset_s``: camera clock minus UTC,
    seconds, if known. ``sync``: frames whose time or position the crew knows, to find or check
    the offset. ``in_place`` rewrites the originals, after copying each to ``backup_dir``
    (required). ``dry_run`` writes nothing. Frames that cannot be placed are reported, never
    written. ``staging``: the output's staging folder when the caller began it, and ``ahead`` the
    worker copying the frames into it (:mod:`acquisition.card_ahead`); the caller stops the
    worker and removes the folder if this raises. ``images``: the frames, when the caller has
    listed them and checked the options (:func:`acquisition.card.prepare_images`).
    ``offset_from_images``: without camera events and ``offset_s``, estimate the camera clock
    offset from the frames' own motion against the track (:mod:`acquisition.offset_from_images`;
    needs pycolmap, and minutes).

    Raises :class:`GeotagError` when the frames and events cannot be reconciled, or when their
    alignment is ambiguous (another camera clock offset fits nearly as well) and neither
    ``offset_s`` nor a sync point settles it: no position is written from an offset the data
    do not pin down.
    """
    options = options or GeotagOptions()
    report = progress or (lambda done, total: None)
    if images is None:
        images = prepare_images(
            image_dir,
            out_dir,
            dry_run=dry_run,
            in_place=in_place,
            backup_dir=backup_dir,
            overwrite=overwrite,
            sync=sync,
        )
    paths = list(images)
    names = output_names(image_dir, paths)
    total = 2 * len(paths)
    frames = read_frames(paths, lambda done: report(done, total))
    timed = timed_frames(frames)
    sync_capture = sync_capture_times(sync, frames, Path(image_dir), names)
    warnings: list[str] = list(log.warnings)
    events = log.events if log.events is not None and len(log.events) > 0 else None

    times = np.array([fr.tags.capture_time_s for fr in timed if fr.tags is not None], dtype=float)
    whole_seconds = _whole_seconds(times)
    if whole_seconds:  # truncated to the second: take the middle
        times = times + 0.5
        sync_capture = [(point, t + 0.5) for point, t in sync_capture]
        warnings.append(
            "the capture times have whole seconds only (no SubSecTimeOriginal): matched with a "
            "wider tolerance; frames placed by time can be off by up to half a second of flight"
        )
    images_asked = offset_from_images is not None and events is None and offset_s is None
    clock = _set_clock(
        times,
        timed,
        sync_capture,
        events,
        log,
        offset_s,
        options.tolerance_s,
        whole_seconds,
        warnings,
        images_asked=images_asked,
    )
    estimate = None
    if offset_from_images is not None and not images_asked:
        why = (
            "the log has camera events: the offset comes from matching them"
            if events is not None
            else "the offset was given"
        )
        warnings.append(f"--offset-from-images not used: {why}")
    if images_asked and offset_from_images is not None:
        from .offset_from_images import clock_from_images

        clock, estimate = clock_from_images(
            clock, Path(image_dir), timed, times, log, offset_from_images, warnings
        )
    placed, interpolation = place_frames(timed, times, names, clock, events, log, options, warnings)
    ordered = not_placed(frames, timed, names, placed)
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
            unmatched_events=clock.unmatched_events,
            offset_s=clock.offset_s,
            offset_source=clock.source,
            drift_ppm=clock.drift_ppm,
            residual_mad_s=clock.residual_mad_s,
            tolerance_s=clock.tolerance_s,
            dry_run=dry_run,
            out_dir=str(out_dir),
            outputs=tuple(outs),
            warnings=tuple(warnings),
            offset_sigma_s=estimate.sigma_s if estimate is not None and estimate.claimed else None,
            offset_from_images=None if estimate is None else estimate.as_dict(),
        )

    final: list[FrameResult] = ordered
    outputs: list[str] = []
    if not dry_run:
        final, outputs = write_outputs(
            ordered,
            out_dir=Path(out_dir),
            in_place=in_place,
            backup_dir=None if backup_dir is None else Path(backup_dir),
            overwrite=overwrite,
            report=lambda n: report(len(paths) + n, total),
            warn=warnings.extend,
            summary=result,
            seen={str(fr.path): fr.seen for fr in frames if fr.seen is not None},
            staging=staging,
            ahead=ahead,
        )
    report(total, total)
    return result(final, outputs)


def _whole_seconds(times: F64) -> bool:
    """True when a camera writes no sub-seconds (its times are truncated to the second)."""
    return bool(times.size > 1 and np.all(np.abs(times - np.round(times)) < 1e-6))


def _set_clock(
    times: F64,
    timed: Sequence[Frame],
    sync_capture: list[tuple[SyncPoint, float]],
    events: CameraEvents | None,
    log: FlightLog,
    offset_s: float | None,
    tolerance_s: float | None,
    whole_seconds: bool,
    warnings: list[str],
    *,
    images_asked: bool = False,
) -> Clock:
    """Match the frames to the camera events, or (without events) take the offset as given, from
    the sync points, from the frames' own GPS time, or assume 0 and say so."""
    if events is not None and times.size:
        windows = None if offset_s is not None else sync_windows_with_events(sync_capture, events, log)
        matching = match_frames_to_events(
            times,
            events.time_utc_s,
            offset_s=offset_s,
            tolerance_s=tolerance_s,
            resolution_s=1.0 if whole_seconds else 0.0,
            offset_windows_s=windows or (),
        )
        if matching.ambiguous and offset_s is None:
            raise GeotagError(
                f"nothing written: {matching.warnings[0]}"
                if matching.warnings
                else "nothing written: the alignment of frames and camera events is ambiguous"
            )
        if offset_s is not None:
            source = OffsetSource.GIVEN
        elif sync_capture:
            source = OffsetSource.SYNC
        else:
            source = OffsetSource.MATCHED
        warnings.extend(matching.warnings)
        return Clock(
            offset_s=matching.offset_s,
            source=source,
            matching=matching,
            drift_ppm=matching.drift_ppm,
            residual_mad_s=matching.residual_mad_s,
            tolerance_s=matching.tolerance_s,
            unmatched_events=tuple((int(j), int(events.seq[j])) for j in matching.unmatched_events),
        )
    if events is None and log.events is not None:
        warnings.append("the log has no camera events: frames are placed by capture time")
    from_sync = None if offset_s is not None else sync_offset_by_track(sync_capture, log)
    if offset_s is not None:
        return Clock(offset_s=float(offset_s), source=OffsetSource.GIVEN)
    if from_sync is not None:
        return Clock(offset_s=from_sync, source=OffsetSource.SYNC)
    from_gps = offset_from_exif_gps([fr.tags for fr in timed if fr.tags is not None])
    if from_gps is not None:
        return Clock(offset_s=from_gps, source=OffsetSource.EXIF_GPS)
    if (
        timed
        and not images_asked  # the images' estimate says what it found instead
        and not all(fr.tags is not None and fr.tags.capture_time_zone_known for fr in timed)
    ):
        warnings.append(
            "no camera events and no --offset-s: the camera clock is assumed to be "
            "UTC; a wrong clock or time zone places every frame wrongly"
        )
    return Clock(offset_s=0.0, source=OffsetSource.ASSUMED_ZERO)
