"""Writing a geotag run's outputs: the tagged frames (a few at a time, see
:func:`acquisition.exif.write_geotags`), the sidecars and ``geotag_report.json``, staged and moved
into place whole; with ``in_place`` every original is backed up before the first is touched."""

from __future__ import annotations

import shutil
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from planner.errors import OutputExistsError
from planner.outputs import StagedOutputDir, atomic_write_text, staged

from . import exif, sidecars
from .card_ahead import CardAhead
from .geotag_results import REPORT_NAME, FrameResult, FrameStatus, GeotagResult, report_json


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


def write_outputs(
    frames: list[FrameResult],
    *,
    out_dir: Path,
    in_place: bool,
    backup_dir: Path | None,
    overwrite: bool,
    report: Callable[[int], None],
    warn: Callable[[Iterable[str]], None],
    summary: Callable[[list[FrameResult], list[str]], GeotagResult],
    seen: Mapping[str, exif.HeaderSnapshot] | None = None,
    staging: StagedOutputDir | None = None,
    ahead: CardAhead | None = None,
) -> tuple[list[FrameResult], list[str]]:
    """Write tagged frames, sidecars and the report; returns the frames with their output paths.
    ``seen``: each source path's header as read (:class:`acquisition.exif.HeaderSnapshot`).
    ``staging``: the output's staging folder, when begun by the caller, and ``ahead`` the worker
    copying the frames into it (:mod:`acquisition.card_ahead`): each written frame takes its
    copy, the others' are removed before the folder is moved into place."""
    seen = seen or {}
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
    with staged(staging or StagedOutputDir(out_dir, overwrite=overwrite)) as stage:
        folder = stage.path
        by_path: dict[str, FrameResult] = {}
        # In place: each original is replaced atomically (synced). Copies go plainly into the
        # staging folder, which is moved into place whole at the end. Frames are written a few at
        # a time (the image data is copied by the kernel, see exif.write_geotags).
        jobs = [
            exif.GeotagJob(
                src=frame.source_path,
                dst=frame.source_path if in_place else str(folder / frame.name),
                tag=_geotag_of(frame),
                seen=seen.get(frame.source_path),
            )
            for frame in to_write
        ]
        try:
            outcomes = exif.write_geotags(
                jobs, overwrite=in_place, atomic=in_place, progress=report, ahead=ahead
            )
        finally:
            if ahead is not None:  # the worker stopped before the folder is moved or removed
                ahead.finish()
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
        sidecar_paths = sidecars.write_all(folder, rows)
        outputs = [str(out_dir / p.name) for p in sidecar_paths] + [str(out_dir / REPORT_NAME)]
        result = summary(written, outputs)
        atomic_write_text(folder / REPORT_NAME, report_json(result))
    return written, outputs
