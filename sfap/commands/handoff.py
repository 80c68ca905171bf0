"""`sfap handoff`: write the reconstruction project (COLMAP, OpenDroneMap, Metashape, Pix4D),
optionally run COLMAP's quick-look, and measure accuracy at check points."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import click

from processing.handoff.pipeline import Engine, HandoffOptions, HandoffResult, handoff
from processing.handoff.prepare import GroundOptions
from processing.handoff.quicklook import (
    DEFAULT_MAPPER,
    DEFAULT_MAX_FEATURES,
    DEFAULT_MAX_IMAGE_SIZE_PX,
    DEFAULT_SIFT_FIRST_OCTAVE,
    MAPPERS,
    SIFT_FIRST_OCTAVES,
)
from processing.image_tags import camera_option

from ..common import FINITE_FLOAT, FiniteFloatRange, dumps_json, echo_table, json_option, overwrite_option

_ENGINES = [e.value for e in Engine]


@click.command("handoff")
@click.argument("images", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option(
    "--to",
    "engine",
    required=True,
    metavar="ENGINE",
    help="The engine: colmap (database + pairs, pycolmap), odm (project folder), metashape or pix4d "
    "(reference CSVs), or a NodeODM node: nodeodm://HOST:PORT, https://HOST (with --token).",
)
@click.option(
    "--token",
    default="",
    envvar="SFAP_NODEODM_TOKEN",
    help="The NodeODM node's token (or SFAP_NODEODM_TOKEN).",
)
@click.option(
    "-o",
    "--output",
    "work",
    required=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Project folder.",
)
@click.option(
    "--run", is_flag=True, help="colmap: extract, match the footprint pairs, map, georegister, report."
)
@click.option(
    "--gcp",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Ground control: OpenDroneMap gcp_list.txt (first line the CRS) or a .csv with columns name, "
    "lon_deg, lat_deg (or easting_m, northing_m with --gcp-crs), alt_m, image, x_px, y_px (one row per "
    "observation; pixels from the top-left corner of the full-size image).",
)
@click.option("--gcp-crs", default=None, help="CRS of a CSV's easting/northing columns, e.g. EPSG:32611.")
@click.option(
    "--check-points",
    default=None,
    help="Check points kept out of the fit: names separated by commas, or a count (spread over the block).",
)
@click.option(
    "--camera",
    "camera_id",
    default=None,
    help="The camera, when its EXIF does not say (as for `sfap check`): an id from `sfap cameras`, or a "
    "TOML file with the keys of a mission spec's [camera] table. Frames of a smaller size are taken "
    "as scaled copies (the same field of view).",
)
@click.option(
    "--dem", type=click.Path(exists=True, dir_okay=False, path_type=Path), help="Ground DEM, GeoTIFF, m AMSL."
)
@click.option(
    "--ground-elevation-m", type=FINITE_FLOAT, default=None, help="Flat ground at this elevation, m AMSL."
)
@click.option("--takeoff-elevation-m", type=FINITE_FLOAT, default=None, help="Take-off elevation, m AMSL.")
@click.option(
    "--min-overlap-pct",
    type=FiniteFloatRange(0.1, 100.0),
    default=5.0,
    show_default=True,
    help="Smallest footprint overlap of a matched pair, percent of the smaller footprint.",
)
@click.option(
    "--max-image-size-px",
    type=int,
    default=DEFAULT_MAX_IMAGE_SIZE_PX,
    show_default=True,
    help="--run: longer side of the downscaled frames features are extracted on, pixels.",
)
@click.option(
    "--max-features",
    type=int,
    default=DEFAULT_MAX_FEATURES,
    show_default=True,
    help="--run: SIFT features per frame.",
)
@click.option(
    "--mapper",
    type=click.Choice(MAPPERS),
    default=DEFAULT_MAPPER,
    show_default=True,
    help="--run: COLMAP's incremental mapper (with the pose priors) or its global mapper (GLOMAP).",
)
@click.option(
    "--sift-first-octave",
    type=click.Choice([str(v) for v in SIFT_FIRST_OCTAVES]),
    default=str(DEFAULT_SIFT_FIRST_OCTAVE),
    show_default=True,
    help="--run: -1 doubles the downscaled frames before SIFT (finer features, about three times the "
    "time), 0 takes features from their own pixels.",
)
@overwrite_option
@json_option
def command(
    images: Path,
    engine: str,
    token: str,
    work: Path,
    run: bool,
    gcp: Path | None,
    gcp_crs: str | None,
    check_points: str | None,
    camera_id: str | None,
    dem: Path | None,
    ground_elevation_m: float | None,
    takeoff_elevation_m: float | None,
    min_overlap_pct: float,
    max_image_size_px: int,
    max_features: int,
    mapper: str,
    sift_first_octave: str,
    overwrite: bool,
    as_json: bool,
) -> HandoffResult:
    """Hand the frames in IMAGES to a reconstruction engine: a project it opens or runs with no
    hand editing. Image pairs come from the frames' ground footprints (EXIF altitudes are AMSL:
    give --ground-elevation-m or --dem, as for `sfap check`); pose priors are in a local metric
    frame named in WORK/project.json.

    Exit code 0 done, 1 the block did not reconstruct (--run) or an engine failed, 2 bad input.

    Example: sfap handoff photos/ --to colmap --run -o work/
    """
    start = time.perf_counter()

    def say(text: str) -> None:
        if not as_json:
            click.echo(f"[{time.perf_counter() - start:6.1f} s] {text}", err=True)

    node_url: str | None = None
    if "://" in engine:
        node_url, engine = engine, Engine.NODEODM.value
    elif engine not in _ENGINES or engine == Engine.NODEODM.value:
        raise click.BadParameter(
            f"{engine!r}: choose colmap, odm, metashape, pix4d or a node URL nodeodm://HOST:PORT",
            param_hint="--to",
        )
    options = HandoffOptions(
        engine=Engine(engine),
        node_url=node_url,
        token=token,
        run=run,
        gcp=gcp,
        gcp_crs=gcp_crs,
        check_points=check_points,
        ground=GroundOptions(
            dem=dem, ground_elevation_m=ground_elevation_m, takeoff_elevation_m=takeoff_elevation_m
        ),
        min_overlap_pct=min_overlap_pct,
        max_image_size_px=max_image_size_px,
        max_features=max_features,
        mapper=mapper,
        sift_first_octave=int(sift_first_octave),
        overwrite=overwrite,
        camera=camera_option(camera_id) if camera_id else None,
    )
    result = handoff(images, work, options, progress=say)
    _present(result, as_json)
    return result  # sfap/cli.py: exit 1 when the block did not reconstruct


def _present(result: HandoffResult, as_json: bool) -> None:
    report = result.report
    if as_json:
        click.echo(dumps_json(report | {"work": str(result.work)}))
        return
    project = report["project"]
    rows = [
        ("frames", f"{project['images']} ({project['positioned']} with a position)"),
        ("pairs", f"{project['pairs']['count']} of {project['pairs']['possible']} possible"),
        ("prior accuracy", project["prior_sigma_source"]),
    ]
    for cam in project["cameras"]:
        rows.append(("camera", f"{cam['camera']}: f = {cam['focal_px']:.1f} px ({cam['source']})"))
    ql = report.get("quicklook")
    if ql:
        rows += [
            (
                "registered",
                f"{ql['frames_registered']} of {ql['frames_total']} frames; models {ql['models']}",
            ),
            ("3D points", str(ql["points3d"])),
            (
                "time",
                ", ".join(f"{k.removesuffix('_s')} {v:.0f} s" for k, v in ql["timings_s"].items()),
            ),
            ("mean track length", f"{ql['mean_track_length']:.2f}" if ql["mean_track_length"] else "-"),
            (
                "reprojection error",
                f"{ql['mean_reprojection_error_px']:.2f} px" if ql["mean_reprojection_error_px"] else "-",
            ),
        ]
        geo = ql.get("georegistration")
        if geo:
            rows.append(
                (
                    "cameras vs GPS",
                    f"RMSE {geo['camera_rmse_horizontal_m']:.2f} m horizontal, "
                    f"{geo['camera_rmse_vertical_m']:.2f} m vertical",
                )
            )
    echo_table(rows, title=f"{report['engine']} project: {result.work}")
    engine_notes = [n for key in ("odm", "metashape", "pix4d") for n in report.get(key, {}).get("notes", [])]
    for note in [*project["notes"], *engine_notes]:
        click.echo(f"note: {note}", err=True)
    for key in ("metashape", "pix4d"):
        if key in report and not report[key]["complete"]:
            click.echo(
                f"FAIL: no image has a position, so the {key} project has no camera positions; "
                f"written: {', '.join(report[key]['files'])}"
            )
    if ql:
        for message in ql["messages"]:
            click.echo(f"warning: {message}", err=True)
        cmp_ = ql.get("check_vs_reconstruction")
        if cmp_:
            click.echo(
                f"check vs reconstruction: {cmp_['covered_but_empty_cells']} of "
                f"{cmp_['covered_cells']} cells of "
                f"{cmp_['cell_m']:g} m that the check sees in two frames or more hold no sparse point "
                f"({cmp_['covered_but_empty_area_m2']:.0f} m2); the check's gaps: "
                f"{cmp_['check_gap_area_m2']:.0f} m2"
            )
        click.echo(("" if ql["reconstructs"] else "FAIL: ") + ql["verdict"])
    acc = report.get("accuracy")
    if acc:
        click.echo(acc["table_3_2"])
        for note in acc.get("notes", []):
            click.echo(f"note: {note}", err=True)
    sys.stdout.flush()
