"""`sfap gcp-plan`: where to lay ground control and check points over a planned survey."""

from __future__ import annotations

from pathlib import Path

import click

from planner.gcp_layout import GcpOptions
from planner.gcp_outputs import plan_gcp_folder
from planner.limits import MAX_PHOTOS

from ..common import FINITE_FLOAT, dumps_json, echo_table, json_option, overwrite_option


@click.command("gcp-plan")
@click.argument("spec_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    "out_dir",
    type=click.Path(file_okay=False, path_type=Path),
    required=True,
    help="Folder for the files (created; must be empty unless --overwrite).",
)
@click.option("--gcp", "gcp_count", type=int, default=8, show_default=True, help="Ground control points.")
@click.option("--check", "check_count", type=int, default=4, show_default=True, help="Check points.")
@click.option(
    "--min-frames", type=int, default=5, show_default=True, help="Planned frames that must see each point."
)
@click.option(
    "--clearance-m",
    type=FINITE_FLOAT,
    default=5.0,
    show_default=True,
    help="Distance kept from exclusions, m.",
)
@click.option(
    "--edge-margin-m",
    type=FINITE_FLOAT,
    default=5.0,
    show_default=True,
    help="Distance inside the area's edge, m.",
)
@click.option(
    "--min-separation-m",
    type=FINITE_FLOAT,
    default=30.0,
    show_default=True,
    help="Least distance between points, m.",
)
@click.option(
    "--max-photos",
    "max_photos",
    type=click.IntRange(min=1),
    default=MAX_PHOTOS,
    show_default=True,
    help="Refuse at once a survey estimated at more photos than this (as sfap plan does).",
)
@overwrite_option
@json_option
def command(
    spec_file: Path,
    out_dir: Path,
    gcp_count: int,
    check_count: int,
    min_frames: int,
    clearance_m: float,
    edge_margin_m: float,
    min_separation_m: float,
    max_photos: int,
    overwrite: bool,
    as_json: bool,
) -> None:
    """Plan the survey of SPEC_FILE and lay out where to put ground control points (GCPs) and
    independent check points: the corners and edges of the area plus a stratified interior
    (Martinez-Carricondo et al. 2018; James et al. 2017), never inside exclusions, each seen by
    at least --min-frames planned frames. Writes gcp.geojson, gcp.kml, gcp.csv (name, lat_deg,
    lon_deg, easting_m, northing_m, role, crs: for a GNSS rover), gcp.json (with the expected
    accuracy) and gcp_map.png into OUTPUT.

    Example: sfap gcp-plan missions/field-concave.toml -o out/field-gcp --gcp 6 --check 3
    """
    options = GcpOptions(
        gcp_count=gcp_count,
        check_count=check_count,
        min_frames=min_frames,
        clearance_m=clearance_m,
        edge_margin_m=edge_margin_m,
        min_separation_m=min_separation_m,
    )
    plan, layout = plan_gcp_folder(spec_file, options, out_dir, overwrite=overwrite, max_photos=max_photos)
    if as_json:
        click.echo(dumps_json({**layout.as_dict(), "output_dir": str(out_dir)}))
        return
    rows = [
        (
            p.name,
            f"{p.role:5} {p.placement:8} lat {p.lat_deg:.7f} lon {p.lon_deg:.7f}, {p.frame_count} frames",
        )
        for p in layout.points
    ]
    acc = layout.expected_accuracy()
    h, v = acc["horizontal_rmse_m"], acc["vertical_rmse_m"]
    assert isinstance(h, list) and isinstance(v, list)
    rows.append(("expected RMSE", f"{h[0]:.3f}-{h[1]:.3f} m horizontal, {v[0]:.3f}-{v[1]:.3f} m vertical"))
    echo_table(rows, title=f"{plan.name}: ground control into {out_dir}")
    click.echo(f"accuracy basis: {acc['basis']}", err=True)
