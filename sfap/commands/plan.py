"""`sfap plan`: a mission spec in, every mission file and the numbers that justify it out."""

from __future__ import annotations

from pathlib import Path

import click

from planner.export import OUTPUT_FILES, write_outputs
from planner.spec import load_spec
from planner.survey import plan_survey

from ..common import dumps_json, echo_table, json_option, overwrite_option, progress

_ROWS = (
    ("area", "area_m2", "{:,.0f} m2"),
    ("camera", "camera_id", "{}"),
    ("GSD", "gsd_cm", "{:.2f} cm"),
    ("altitude above ground", "altitude_agl_m", "{:.1f} m"),
    ("scale", "scale_number", "1:{:,.0f}"),
    ("footprint along x across", None, None),
    ("air base (trigger distance)", "air_base_m", "{:.2f} m"),
    ("line spacing", "line_spacing_m", "{:.2f} m"),
    ("speed", "speed_m_s", "{:.1f} m/s"),
    ("exposure interval", "exposure_interval_s", "{:.2f} s"),
    ("max speed", "max_speed_m_s", "{:.1f} m/s"),
    ("base-height ratio", "base_height_ratio", "{:.3f}"),
    ("intersection angle", "intersection_angle_deg", "{:.1f} deg"),
    ("expected depth precision", "depth_precision_m", "{:.3f} m"),
    ("line direction", "direction_deg", "{:.1f} deg"),
    ("passes", "pass_count", "{}"),
    ("lines", "line_count", "{}"),
    ("photos", "photo_count", "{:,}"),
    ("area seen by 2+ nadir frames", "stereo_seen_2_pct", "{:.1f} %"),
    ("area seen by 3+ nadir frames", "stereo_seen_3_pct", "{:.1f} %"),
    ("flight distance", "flight_distance_m", "{:,.0f} m"),
    ("flight time", "flight_time_s", None),
    ("mission items", "item_count", "{}"),
    ("mission items the autopilot holds", "max_item_count", "{}"),
)


@click.command("plan")
@click.argument("spec_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    "out_dir",
    type=click.Path(file_okay=False, path_type=Path),
    required=True,
    help="Folder for the mission files (created; must be empty unless --overwrite).",
)
@overwrite_option
@json_option
@click.option("--no-progress", is_flag=True, help="No progress bar.")
def command(spec_file: Path, out_dir: Path, overwrite: bool, as_json: bool, no_progress: bool) -> None:
    """Plan a survey from SPEC_FILE (a mission spec in TOML) and write, into OUTPUT:
    mission.plan (QGroundControl), mission.waypoints (QGC WPL 110), flight_lines.geojson,
    stations.geojson, footprints.geojson, area.geojson, mission.kml, map.png and summary.json.

    Distances in metres, GSD in cm, altitudes above ground (AGL) or home. The files are
    written all at once: on any error nothing is left behind.

    Example: sfap plan missions/bardenas-gully.toml -o out/gully
    """
    spec = load_spec(spec_file)
    plan = plan_survey(spec)
    with progress("writing", len(OUTPUT_FILES), enabled=not no_progress and not as_json) as advance:
        write_outputs(plan, out_dir, overwrite=overwrite, progress=advance)
    summary = plan.summary.as_dict()
    if as_json:
        click.echo(dumps_json({**summary, "output_dir": str(out_dir)}))
        return
    rows = []
    for label, key, fmt in _ROWS:
        if key is None and label.startswith("footprint"):
            value = f"{summary['footprint_along_m']:.1f} x {summary['footprint_across_m']:.1f} m"
        elif key == "flight_time_s":
            seconds = round(float(summary[key]))  # type: ignore[arg-type]
            value = f"{seconds // 60} min {seconds % 60:02d} s"
        else:
            assert key is not None and fmt is not None
            value = fmt.format(summary[key])
        rows.append((label, value))
    terrain = plan.summary.terrain
    if terrain is not None:
        mode = "follows the ground" if terrain["follow"] else "constant above home"
        agl = f"{terrain['station_alt_agl_min_m']:.1f}-{terrain['station_alt_agl_max_m']:.1f} m"
        gsd = f"{terrain['gsd_min_cm']:.2f}-{terrain['gsd_max_cm']:.2f} cm"
        lows = (
            f"{terrain['front_overlap_min_pct']:.0f} % forward, {terrain['side_overlap_min_pct']:.0f} % side"
        )
        rows += [
            ("terrain", f"{terrain['dem']}, altitude {mode}"),
            ("height above ground", agl),
            ("GSD over the terrain", gsd),
            ("lowest overlaps", lows),
            ("waypoints added for terrain", f"{terrain['waypoints_added']}"),
        ]
    echo_table(rows, title=f"{plan.name}: planned into {out_dir}")
    for warning in plan.warnings:
        click.echo(f"warning: {warning}", err=True)
