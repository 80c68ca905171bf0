"""`sfap check`: coverage, overlap, B/H, GSD and blur of images or a plan, judged in the field."""

from __future__ import annotations

import dataclasses
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

import click

from planner.area import build_area, load_polygons
from planner.outputs import check_output_dir
from planner.plan_folder import is_plan_folder
from processing.check import MAX_CELL_M, MIN_CELL_M, run_check
from processing.check_inputs import gather_inputs
from processing.check_pixels import PixelOnlyCheck
from processing.check_result import CheckResult
from processing.errors import NoPositionsError, ProcessingError
from processing.image_tags import CameraConfidence, camera_option
from processing.pixel_match import DEFAULT_MATCH_SIZE_PX, PixelOptions
from processing.verdict import Thresholds

from ..common import (
    FINITE_FLOAT,
    FiniteFloatRange,
    dumps_json,
    echo_table,
    json_option,
    overwrite_option,
    progress,
)

_THRESHOLD_KEYS = tuple(f.name for f in dataclasses.fields(Thresholds))


def _thresholds(values: tuple[str, ...]) -> Thresholds:
    changes: dict[str, float] = {}
    for item in values:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or key not in _THRESHOLD_KEYS:
            raise click.BadParameter(
                f"{item!r}: give KEY=VALUE with KEY one of {', '.join(_THRESHOLD_KEYS)}",
                param_hint="--threshold",
            )
        try:
            changes[key] = float(text)
        except ValueError:
            raise click.BadParameter(
                f"{item!r}: {text!r} is not a number", param_hint="--threshold"
            ) from None
    try:
        return Thresholds(**changes)
    except ProcessingError as error:
        raise click.BadParameter(str(error), param_hint="--threshold") from None


@click.command("check")
@click.argument(
    "source",
    metavar="IMAGES_OR_PLAN",
    type=click.Path(exists=True, file_okay=False, path_type=Path),
)
@click.option(
    "--plan",
    "plan_dir",
    type=click.Path(exists=True, file_okay=False, path_type=Path),
    help="Plan folder (written by `sfap plan`) the images were flown from: its area is judged and "
    "its overlaps are the reference.",
)
@click.option(
    "--area",
    "area_file",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Area to judge (GeoJSON or KML polygon, WGS84). Default: the plan's area, else the block "
    "the frames' centres span (convex hull).",
)
@click.option(
    "--dem",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Ground elevations, GeoTIFF in any CRS, metres above mean sea level (with a plan folder no "
    "--takeoff-elevation-m is needed).",
)
@click.option(
    "--ground-elevation-m",
    type=FINITE_FLOAT,
    default=None,
    help="Flat ground at this elevation, metres above mean sea level.",
)
@click.option(
    "--takeoff-elevation-m",
    type=FINITE_FLOAT,
    default=None,
    help="Elevation of the take-off point, metres AMSL (for altitudes relative to home "
    "with --dem or --ground-elevation-m; a plan folder records its own).",
)
@click.option(
    "--camera",
    "camera_id",
    default=None,
    metavar="ID|FILE.toml",
    help="The camera: an id from `sfap cameras`, or a TOML file with the keys of a mission spec's "
    "[camera] table (sensor_width_mm, sensor_height_mm, image_width_px, image_height_px, "
    "focal_length_mm, or model = ID with overrides). Default: from the images' EXIF (the database, "
    "else EXIF focal length with focal plane resolution, else the 35 mm equivalent focal length).",
)
@click.option(
    "--cell-m",
    type=FiniteFloatRange(min=MIN_CELL_M, max=MAX_CELL_M),
    default=None,
    help=f"Raster cell size, metres, {MIN_CELL_M:g}-{MAX_CELL_M:g} (default: 1/50 of a frame's short side, "
    "rounded).",
)
@click.option(
    "--threshold",
    "threshold_items",
    multiple=True,
    metavar="KEY=VALUE",
    help="Change a pass threshold, e.g. --threshold min_seen_3_pct=80 (repeatable; keys: "
    + ", ".join(_THRESHOLD_KEYS)
    + ").",
)
@click.option(
    "--pixels/--no-pixels",
    default=True,
    help="Match neighbouring frames in the images (SIFT and COLMAP's matcher on downscaled frames, about "
    "a second per frame on two cores) and judge the block on what they show: the share of neighbours "
    "that match, the parts they form, the measured overlap and image scale (default: on for images; "
    "COLMAP's log goes to colmap-match.log in the report folder).",
)
@click.option(
    "--match-size-px",
    type=click.IntRange(min=64, max=8192),
    default=DEFAULT_MATCH_SIZE_PX,
    show_default=True,
    help="Longer side of the frames as matched, pixels (larger: slower, more features).",
)
@click.option("--refly", is_flag=True, help="Also write a mission covering the gaps into REPORT/refly/.")
@click.option(
    "-o",
    "--output",
    "out_dir",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Report folder: report.html, report.json, coverage.tif, gaps.geojson, "
    "footprints.geojson and the maps (created; must be empty unless --overwrite).",
)
@overwrite_option
@json_option
@click.option("--no-progress", is_flag=True, help="No progress bar.")
def command(
    source: Path,
    plan_dir: Path | None,
    area_file: Path | None,
    dem: Path | None,
    ground_elevation_m: float | None,
    takeoff_elevation_m: float | None,
    camera_id: str | None,
    cell_m: float | None,
    threshold_items: tuple[str, ...],
    pixels: bool,
    match_size_px: int,
    refly: bool,
    out_dir: Path | None,
    overwrite: bool,
    as_json: bool,
    no_progress: bool,
) -> CheckResult | PixelOnlyCheck:
    """Check the frames in IMAGES_OR_PLAN (a folder of geotagged images, or a plan folder
    written by `sfap plan` to check the plan itself) before leaving the field: views per
    ground cell, gaps, forward and side overlap, base-height ratios, GSD, motion blur.

    Images' EXIF altitudes are above mean sea level: give --ground-elevation-m or --dem (the
    check never guesses the height above ground); DJI's relative altitudes are above take-off.
    Frames without a real position, of another camera or image size, or not taken on the survey
    (on the ground, climbing, in transit) are left out and listed. When no image has a position
    (a kite, a camera without GPS), the images are judged on their pixels alone: whether they
    match and a quick reconstruction holds them (with -o, report.json only; --no-pixels refuses).
    A plan is judged on its own ground: a terrain plan on its DEM (found in the plan folder, or
    --dem) and take-off elevation, a flat plan on flat ground at home, or on --dem from the DEM's elevation at
    home; images flown from a terrain plan (--plan) use its DEM when no ground is given.

    Exit code 0 when every threshold is met, 1 when the check fails (the reasons are
    printed), 2 for bad options or inputs.

    Example: sfap check photos/ --plan out/gully --ground-elevation-m 412 -o report/ --refly
    """
    if refly and out_dir is None:
        raise click.UsageError("--refly writes the mission into the report folder: give -o REPORT/")
    thresholds = _thresholds(threshold_items)
    if out_dir is not None:
        check_output_dir(out_dir, overwrite=overwrite)  # refuse before minutes of work
    camera = camera_option(camera_id) if camera_id else None
    show_progress = not no_progress and not as_json
    if plan_dir is not None and is_plan_folder(source):
        raise click.UsageError(f"{source} is a plan folder already; drop --plan")
    try:
        with progress(
            "reading images", 0 if is_plan_folder(source) else 100, enabled=show_progress
        ) as advance:
            inputs = gather_inputs(
                source,
                plan_dir=plan_dir,
                camera=camera,
                dem=dem,
                ground_elevation_m=ground_elevation_m,
                takeoff_elevation_m=takeoff_elevation_m,
                progress=_in_percent(advance),
            )
    except NoPositionsError as error:
        if not pixels or plan_dir is not None or area_file is not None or refly:
            raise
        # No position to put the frames on the ground (a kite, a camera without GPS): the pixels
        # alone say whether they will reconstruct.
        return _pixels_only(
            source, error.names, thresholds, match_size_px, out_dir, overwrite, as_json, show_progress
        )
    area = None
    if area_file is not None:
        area, _ = build_area(load_polygons(area_file), [])
    pixel_options = None
    match_log: Path | None = None
    if pixels and inputs.image_dir is not None:
        with tempfile.NamedTemporaryFile(prefix="sfap-colmap-match-", suffix=".log", delete=False) as handle:
            match_log = Path(handle.name)
        pixel_options = PixelOptions(
            image_dir=inputs.image_dir, max_image_size_px=match_size_px, log_path=match_log
        )
        if show_progress:
            click.echo(
                "matching neighbouring frames in the pixels (about a second per frame; --no-pixels to "
                "skip); "
                f"COLMAP's log: {match_log}",
                err=True,
            )
    with progress("counting views", 100, enabled=show_progress) as advance:
        result = run_check(
            inputs.frames,
            ground=inputs.ground,
            area=area,
            plan=inputs.plan,
            cell_m=cell_m,
            thresholds=thresholds,
            progress=_in_percent(advance),
            ground_description=inputs.ground_description,
            notes=inputs.notes,
            unpositioned=inputs.unpositioned,
            left_out=inputs.left_out,
            warnings=inputs.warnings,
            camera_source=inputs.camera_source,
            pixels=pixel_options,
            camera_rough=inputs.camera_confidence == CameraConfidence.EQUIVALENT_35MM.value,
            detrended=inputs.detrended,
        )
    refly_plan = None
    if refly and result.gaps:
        from processing.refly import refly_mission, refly_parameters

        refly_plan = refly_mission([g.polygon_lonlat for g in result.gaps], refly_parameters(result))
    if out_dir is not None:
        from processing.report import write_report

        write_report(result, out_dir, overwrite=overwrite, refly=refly_plan)
        if match_log is not None:
            shutil.move(match_log, out_dir / "colmap-match.log")
            match_log = out_dir / "colmap-match.log"
    _present(result, out_dir, refly, refly_plan is not None, as_json)
    if match_log is not None and not as_json:
        click.echo(f"COLMAP's log of the matching: {match_log}", err=True)
    return result  # sfap.cli exits 1 when it did not pass


def _pixels_only(
    source: Path,
    names: tuple[str, ...],
    thresholds: Thresholds,
    match_size_px: int,
    out_dir: Path | None,
    overwrite: bool,
    as_json: bool,
    show_progress: bool,
) -> PixelOnlyCheck:
    """Images without positions judged on their pixels alone (processing.check_pixels)."""
    import json

    from planner.outputs import atomic_write_text, json_safe, staged_output_dir
    from processing.check_pixels import check_pixels_only

    with tempfile.NamedTemporaryFile(prefix="sfap-colmap-match-", suffix=".log", delete=False) as handle:
        match_log = Path(handle.name)
    if show_progress:
        click.echo(
            f"no positions in the {len(names)} images: judging them on their pixels alone (every pair "
            f"matched; COLMAP's log: {match_log}); --no-pixels to refuse instead",
            err=True,
        )
    options = PixelOptions(image_dir=source, max_image_size_px=match_size_px, log_path=match_log)
    result = check_pixels_only(source, names, options, thresholds)
    data = result.as_dict()
    if out_dir is not None:
        with staged_output_dir(out_dir, overwrite=overwrite) as staging:
            atomic_write_text(staging / "report.json", json.dumps(json_safe(data), indent=2) + "\n")
            shutil.move(match_log, staging / "colmap-match.log")
        match_log = out_dir / "colmap-match.log"
    if as_json:
        data["report_dir"] = str(out_dir) if out_dir is not None else None
        click.echo(dumps_json(data))
        return result
    click.echo(
        f"{'PASS' if result.passed else 'FAIL'}: {len(result.names)} frames checked on their pixels alone"
    )
    for reason in result.reasons:
        click.echo(f"  - {reason}")
    echo_table(result.key_figures())
    for warning in result.warnings:
        click.echo(f"warning: {warning}", err=True)
    if out_dir is not None:
        click.echo(f"report: {out_dir / 'report.json'}")
    click.echo(f"COLMAP's log of the matching: {match_log}", err=True)
    return result


def _in_percent(advance: Callable[[int], None]) -> Callable[[int, int], None]:
    """A library's ``progress(done, total)`` as steps of a bar of 100."""
    shown = [0]

    def on_progress(done: int, total: int) -> None:
        step = int(100 * done / max(total, 1)) - shown[0]
        if step > 0:
            shown[0] += step
            advance(step)

    return on_progress


def _present(
    result: CheckResult, out_dir: Path | None, refly: bool, wrote_refly: bool, as_json: bool
) -> None:
    if as_json:
        data = result.as_dict()
        data.pop("per_frame", None)
        data["report_dir"] = str(out_dir) if out_dir is not None else None
        data["refly_dir"] = str(out_dir / "refly") if wrote_refly and out_dir is not None else None
        click.echo(dumps_json(data))
        return
    verdict = "PASS" if result.passed else "FAIL"
    click.echo(f"{verdict}: {len(result.frames)} frames checked")
    for reason in result.reasons:
        click.echo(f"  - {reason}")
    echo_table(result.key_figures())
    for warning in result.warnings:
        click.echo(f"warning: {warning}", err=True)
    if out_dir is not None:
        click.echo(f"report: {out_dir / 'report.html'}")
    if refly:
        if wrote_refly and out_dir is not None:
            click.echo(f"re-fly mission: {out_dir / 'refly' / 'mission.plan'}")
        elif result.passed:
            click.echo("re-fly mission: none needed (no gap)")
        else:
            click.echo(
                "re-fly mission: none written: there is no gap to fill, the block fails for the reasons "
                "above; fly it again as they say"
            )
