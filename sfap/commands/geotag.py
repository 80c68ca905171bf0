"""`sfap geotag`: geotag frames from the flight's own telemetry log (acquisition.geotag)."""

from __future__ import annotations

from pathlib import Path

import click

from acquisition.geotag import (
    FrameStatus,
    GeotagOptions,
    GeotagResult,
    geotag_images,
    list_images,
    report_json,
)
from acquisition.telemetry import read_log

from ..common import echo_table, json_option, overwrite_option, progress


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
    "--out",
    "out_dir",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Output folder: tagged copies, geo.txt, pix4d_geolocation.csv, cameras.geojson and "
    "geotag_report.json (with --in-place: everything but the images).",
)
@click.option(
    "--offset-s",
    type=float,
    default=None,
    help="Camera clock minus UTC, seconds (time zone included). Default: found by matching "
    "frames to camera events, or from the frames' own GPS time, else 0.",
)
@click.option(
    "--tolerance-s",
    type=float,
    default=None,
    help="Largest capture-time residual of a frame/event pair, seconds. Default: 35 percent of the "
    "event interval, then 8 x the residual scatter.",
)
@click.option(
    "--max-gap-s",
    type=float,
    default=5.0,
    show_default=True,
    help="Longest interval of the log's position track to interpolate over, seconds.",
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
@click.pass_context
def command(
    ctx: click.Context,
    images: Path,
    log_path: Path,
    out_dir: Path,
    offset_s: float | None,
    tolerance_s: float | None,
    max_gap_s: float,
    dry_run: bool,
    in_place: bool,
    backup_dir: Path | None,
    overwrite: bool,
    as_json: bool,
    no_progress: bool,
) -> None:
    """Geotag the JPEG frames under IMAGES from the flight's own log, losslessly.

    Frames are matched to the log's camera events by aligning their time sequences (dropped
    and extra frames are found and named), placed at the event time by interpolating the
    position track (WGS84, altitude AMSL) and attitude, and written as EXIF GPS and Pix4D XMP
    tags to copies in OUT; pixel data stay byte-identical; originals are never modified
    without --in-place. Exit code 1 when any frame is left untagged (they are listed).

    Example: sfap geotag card/DCIM --log flight.tlog -o tagged/
    """
    if in_place and backup_dir is None:
        raise click.UsageError("--in-place needs --backup-dir (the originals are copied there first)")
    if backup_dir is not None and not in_place:
        raise click.UsageError("--backup-dir only applies with --in-place")

    flight_log = read_log(log_path)
    options = GeotagOptions(tolerance_s=tolerance_s, max_gap_s=max_gap_s)
    total = 2 * len(list_images(images))
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
            dry_run=dry_run,
            in_place=in_place,
            backup_dir=backup_dir,
            overwrite=overwrite,
            progress=report,
            options=options,
        )

    if as_json:
        click.echo(report_json(result), nl=False)
    else:
        _present(result)
    if result.untagged:
        ctx.exit(1)


def _present(result: GeotagResult) -> None:
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
            f"{result.offset_s:+.3f} s ({result.offset_source}), drift {result.drift_ppm:.1f} ppm",
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
