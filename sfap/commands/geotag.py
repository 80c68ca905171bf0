"""`sfap geotag`: geotag frames from the flight's own telemetry log (acquisition.geotag)."""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import click

from acquisition.card import output_names, prepare_images

# Only what checking the options needs, and the card's worker: the rest (numpy, the log
# readers, the matcher) is loaded in `command` once the worker is reading the card.
from acquisition.card_ahead import CardAhead
from acquisition.sync_points import SyncPoint, parse_sync_position, parse_sync_time
from planner.errors import InputError
from planner.outputs import StagedOutputDir

from ..common import FINITE_FLOAT, echo_table, json_option, overwrite_option, progress, warnings_once

if TYPE_CHECKING:
    from acquisition.geotag_results import GeotagResult
    from acquisition.offset_from_images import ReconstructionOptions


#: The largest camera clock offset taken: about 50 years (a clock never set reads 2000-01-01).
MAX_OFFSET_S = 50 * 365.25 * 86400.0


def _finite(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
    if value is not None and not math.isfinite(value):
        raise click.BadParameter(f"{value} is not a finite number of seconds")
    if value is not None and abs(value) > MAX_OFFSET_S:
        raise click.BadParameter(
            f"{value:g} s is more than 50 years; give the camera clock minus UTC in seconds "
            f"(e.g. 3600 for a camera an hour ahead)"
        )
    return value


def _seconds_within(most_s: float) -> Callable[[click.Context, click.Parameter, float | None], float | None]:
    """A callback refusing a time that is not above 0 s and at most ``most_s`` (0 < t <= most)."""

    def callback(ctx: click.Context, param: click.Parameter, value: float | None) -> float | None:
        if value is not None and not (math.isfinite(value) and 0.0 < value <= most_s):
            raise click.BadParameter(
                f"{value:g} s: give a time above 0 s and at most {most_s:g} s (0 < s <= {most_s:g})"
            )
        return value

    return callback


def _sync_points(parse: Callable[[str], SyncPoint]) -> Callable[..., tuple[SyncPoint, ...]]:
    def callback(
        ctx: click.Context, param: click.Parameter, values: tuple[str, ...]
    ) -> tuple[SyncPoint, ...]:
        try:
            return tuple(parse(v) for v in values)
        except InputError as error:
            raise click.BadParameter(str(error)) from None

    return callback


@contextmanager
def _log_progress(enabled: bool) -> Iterator[Callable[[int, int], None] | None]:
    """A percentage bar on stderr while the log is read (the readers report bytes)."""
    if not enabled or not sys.stderr.isatty():
        yield None
        return
    with click.progressbar(length=100, label="reading log", file=sys.stderr) as bar:
        shown = [0]

        def report(done: int, total: int) -> None:
            percent = min(100, done * 100 // total) if total > 0 else 100
            if percent > shown[0]:
                bar.update(percent - shown[0])
                shown[0] = percent

        yield report


@contextmanager
def _card_ahead(
    enabled: bool, images: Path, paths: Sequence[Path], out_dir: Path, overwrite: bool
) -> Iterator[tuple[StagedOutputDir | None, CardAhead | None]]:
    """The output's staging folder, and a worker process reading the frames and copying them into
    it while this process loads its libraries and reads the log (:mod:`acquisition.card_ahead`);
    the worker stopped and the folder removed unless the run moved it into place."""
    if not enabled:
        yield None, None
        return
    staging = StagedOutputDir(out_dir, overwrite=overwrite)
    try:
        names = output_names(images, paths)
        ahead = CardAhead.start(staging.path, [(p, names[p]) for p in paths])
        try:
            yield staging, ahead
        finally:
            ahead.finish()
    finally:
        staging.discard()


@click.command("geotag")
@click.argument("images", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option(
    "--log",
    "log_path",
    required=True,
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Flight log: MAVLink .tlog, DataFlash .bin, PX4 .ulg, exiftool CSV track, GPX or MRK.",
)
@click.option(
    "-o",
    "--output",
    "out_dir",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Output folder: tagged copies, geo.txt, pix4d_geolocation.csv, cameras.geojson and "
    "geotag_report.json (with --in-place: everything but the images).",
)
@click.option(
    "--offset-s",
    type=FINITE_FLOAT,
    default=None,
    callback=_finite,
    help="Camera clock minus UTC, seconds (time zone included). Default: found by matching "
    "frames to camera events (refused when that is ambiguous), or from sync points or the "
    "frames' own GPS time, else assumed 0 (and said loudly).",
)
@click.option(
    "--sync",
    "sync_times",
    multiple=True,
    metavar="FRAME=TIME",
    callback=_sync_points(parse_sync_time),
    help="A frame and the UTC time it was taken (ISO 8601, e.g. "
    "IMG_0001.JPG=2026-11-22T10:32:05.4Z, known to about 1 s: a photo of a GPS clock), to find "
    "or check the camera clock offset. FRAME is the file name, or its path under IMAGES when "
    "names repeat (101CANON/IMG_0001.JPG). Repeatable.",
)
@click.option(
    "--sync-position",
    "sync_positions",
    multiple=True,
    metavar="FRAME=LAT,LON",
    callback=_sync_points(parse_sync_position),
    help="A frame and the position it was taken from (WGS84 degrees, e.g. "
    "IMG_0001.JPG=42.00123,-93.00045: the point under a nadir frame's centre), to find or check "
    "the offset; refused when the flight passes there more than once. Repeatable.",
)
@click.option(
    "--offset-from-images",
    is_flag=True,
    help="Without camera events in the log: estimate the camera clock offset from the frames' own "
    "motion against the track (a quick reconstruction of the frames with pycolmap, minutes for "
    "hundreds of frames), with its uncertainty, or say that the frames do not pin it down (straight "
    "lines flown one way do not; lines in opposite directions and turns do).",
)
@click.option(
    "--tolerance-s",
    type=float,
    default=None,
    callback=_seconds_within(60.0),
    help="Largest capture-time residual of a frame/event pair, seconds. Default: 35 percent of the "
    "event interval, then 10 x the residual scatter.",
)
@click.option(
    "--max-gap-s",
    type=float,
    default=5.0,
    callback=_seconds_within(3600.0),
    show_default=True,
    help="Longest interval of the log's position track to interpolate over, seconds.",
)
@click.option(
    "--camera-mount",
    type=click.Choice(["auto", "gimbal", "fixed"]),
    default="auto",
    show_default=True,
    help="How the camera is carried, for a log without gimbal angles: gimbal = stabilised, "
    "looking straight down (as sfap's plans point it), heading the vehicle's; fixed = fixed to the "
    "airframe, taking the vehicle's pitch and roll; auto = as the log says the vehicle is (fixed "
    "for a fixed wing or a VTOL, gimbal for a multirotor, or for a track that does not say).",
)
@click.option("--dry-run", is_flag=True, help="Match and report; write nothing.")
@click.option(
    "--in-place",
    is_flag=True,
    help="Rewrite the original images (each copied to --backup-dir first).",
)
@click.option(
    "--backup-dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Where --in-place copies the originals before touching them (required with it).",
)
@overwrite_option
@json_option
@click.option("--no-progress", is_flag=True, help="No progress bar on stderr.")
def command(
    images: Path,
    log_path: Path,
    out_dir: Path,
    offset_s: float | None,
    sync_times: tuple[SyncPoint, ...],
    sync_positions: tuple[SyncPoint, ...],
    offset_from_images: bool,
    tolerance_s: float | None,
    max_gap_s: float,
    camera_mount: str,
    dry_run: bool,
    in_place: bool,
    backup_dir: Path | None,
    overwrite: bool,
    as_json: bool,
    no_progress: bool,
) -> GeotagResult:
    """Geotag the JPEG frames under IMAGES from the flight's own log, losslessly.

    Frames are matched to the log's camera events by aligning their time sequences (dropped
    and extra frames are found and named), placed at the event time by interpolating the
    position track (WGS84, altitude AMSL) and attitude, and written as EXIF GPS and Pix4D XMP
    tags to copies in OUT; pixel data stay byte-identical; originals are never modified
    without --in-place. Give the card's DCIM folder: its subfolders are read together, and
    names that repeat across them (100CANON/IMG_0001.JPG, 101CANON/IMG_0001.JPG) are kept
    apart as 100CANON_IMG_0001.JPG, 101CANON_IMG_0001.JPG in the outputs.

    When the frames' rhythm fits several camera clock offsets nearly equally well (a subset
    of a card, regular lines), nothing is written and the competing offsets are listed:
    confirm one with --offset-s, or give a sync point. Without camera events in the log,
    frames are placed by capture time and the cost of a wrong offset (ground speed times
    the error) is stated; --offset-from-images estimates the offset from the frames' own
    motion against the track, with its uncertainty, or says why the frames cannot.

    Exit codes: 0 every frame tagged; 1 frames left untagged (listed), or the operation
    failed (an ambiguous alignment, frames that cannot be reconciled with the log); 2 bad
    usage or input.

    Example: sfap geotag card/DCIM --log flight.tlog -o tagged/
    """
    if in_place and backup_dir is None:
        raise click.UsageError("--in-place needs --backup-dir (the originals are copied there first)")
    if backup_dir is not None and not in_place:
        raise click.UsageError("--backup-dir only applies with --in-place")
    sync = sync_times + sync_positions
    if sync and offset_s is not None:
        raise click.UsageError("give either --offset-s or sync points (--sync, --sync-position), not both")
    if offset_from_images and offset_s is not None:
        raise click.UsageError(
            "give either --offset-s (the offset known) or --offset-from-images (estimate it), not both"
        )
    if offset_from_images:
        import importlib.util

        if importlib.util.find_spec("pycolmap") is None:
            raise click.UsageError(
                "--offset-from-images needs pycolmap: install it (pip install 'sfap[colmap]') or give "
                "--offset-s / --sync instead"
            )

    with warnings_once("acquisition") as handled:  # each warning printed once
        # Everything that can be checked without the log, before reading it (a log can take a while).
        paths = prepare_images(
            images,
            out_dir,
            dry_run=dry_run,
            in_place=in_place,
            backup_dir=backup_dir,
            overwrite=overwrite,
            sync=sync,
        )
        with _card_ahead(not dry_run and not in_place, images, paths, out_dir, overwrite) as (staging, ahead):
            from acquisition.attitude import CameraMount
            from acquisition.geotag import geotag_images
            from acquisition.geotag_results import GeotagOptions
            from acquisition.telemetry import read_log

            options = GeotagOptions(
                tolerance_s=tolerance_s, max_gap_s=max_gap_s, camera_mount=CameraMount(camera_mount)
            )
            with _log_progress(not no_progress and not as_json) as log_report:
                flight_log = read_log(log_path, log_report)
            total = 2 * len(paths)
            with progress("geotagging", total, enabled=not no_progress and not as_json) as advance:
                seen = [0]

                def report(done: int, _total: int) -> None:
                    advance(done - seen[0])
                    seen[0] = done

                result = geotag_images(
                    images,
                    flight_log,
                    out_dir,
                    offset_s=offset_s,
                    sync=sync,
                    dry_run=dry_run,
                    in_place=in_place,
                    backup_dir=backup_dir,
                    overwrite=overwrite,
                    progress=report,
                    options=options,
                    staging=staging,
                    ahead=ahead,
                    images=paths,
                    offset_from_images=_reconstruction_options() if offset_from_images else None,
                )

        if as_json:
            from acquisition.geotag_results import report_json

            click.echo(report_json(result), nl=False)
        else:
            _present(result)
        handled.update(result.warnings)  # in the JSON, or printed by _present
    return result  # sfap/cli.py: exit 1 when frames were left untagged


def _reconstruction_options() -> ReconstructionOptions:
    from acquisition.offset_from_images import ReconstructionOptions

    return ReconstructionOptions()


def _present(result: GeotagResult) -> None:
    from acquisition.geotag_results import FrameStatus

    matched = sum(1 for f in result.frames if f.status is FrameStatus.MATCHED)
    rows = [
        ("frames", str(len(result.frames))),
        ("camera events", str(result.n_events)),
        ("matched", str(matched)),
        (
            "tagged",
            f"{len(result.tagged)}" + (" (dry run: nothing written)" if result.dry_run else ""),
        ),
        (
            "camera clock offset",
            f"{result.offset_s:+.3f} s"
            + (f" +/- {result.offset_sigma_s:.3f} s" if result.offset_sigma_s is not None else "")
            + f" ({result.offset_source}), drift {result.drift_ppm:.1f} ppm",
        ),
    ]
    if result.residual_mad_s is not None:
        rows.append(
            (
                "residual scatter",
                f"{result.residual_mad_s:.3f} s (tolerance {result.tolerance_s:.3f} s)",
            )
        )
    if result.unmatched_events:
        seqs = ", ".join(str(seq) for _, seq in result.unmatched_events)
        rows.append(("dropped frames", f"{len(result.unmatched_events)} events without a frame: seq {seqs}"))
    if result.extra_frames:
        rows.append(
            (
                "extra frames",
                f"{len(result.extra_frames)} without an event: {', '.join(result.extra_frames)}",
            )
        )
    if not result.dry_run:
        rows.append(("output", result.out_dir))
    echo_table(rows, title="geotag")
    for warning in result.warnings:
        click.echo(f"warning: {warning}", err=True)
    if result.untagged:
        click.echo(f"untagged frames ({len(result.untagged)}), nothing written for them:")
        for frame in result.untagged:
            click.echo(f"  {frame.source_path}  [{frame.status}]  {frame.message or ''}")
