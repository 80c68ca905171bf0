"""`sfap plan`: a mission spec in, every mission file and the numbers that justify it out."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import click

from planner.aside import Helper
from planner.limits import ANNOUNCE_PHOTOS, MAX_PHOTOS

from ..common import dumps_json, echo_table, json_option, overwrite_option, progress, warnings_once

#: What map.png's helper runs while the plan is being made (planner.aside.Helper's warm-up, by
#: name): the drawing imported (never the planner), Pillow's formats and the map's fonts loaded.
MAP_WARM_UP = "planner.maprender:prepare"
#: Memory map.png's helper faults in while it waits for the plan (planner.aside.Helper): its
#: canvases, about 26 MB for the gully's map and 36 MB for a square kilometre's, with room to spare.
MAP_ROOM_BYTES = 48 << 20

if TYPE_CHECKING:  # the planner is imported once map.png's helper is started (command)
    from planner.estimate import PlanEstimate
    from planner.plan_run import PlanRun

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
@click.option(
    "--resume-from",
    "resume_from",
    type=int,
    default=None,
    help="Plan only what is left from this station on (0-based, the station property of stations.geojson).",
)
@click.option(
    "--max-photos",
    "max_photos",
    type=click.IntRange(min=1),
    default=MAX_PHOTOS,
    show_default=True,
    help="Refuse at once a plan estimated at more photos than this (the estimate and the fix are printed).",
)
@click.option(
    "--resume-record",
    "resume_record",
    type=click.Path(exists=True, path_type=Path),
    default=None,
    help="Resume after the last station recorded by sfap monitor (its folder, or its triggers.csv).",
)
def command(
    spec_file: Path,
    out_dir: Path,
    overwrite: bool,
    as_json: bool,
    no_progress: bool,
    resume_from: int | None = None,
    resume_record: Path | None = None,
    max_photos: int = MAX_PHOTOS,
) -> None:
    """Plan a survey from SPEC_FILE (a mission spec in TOML) and write, into OUTPUT:
    mission.plan (QGroundControl), mission.waypoints (QGC WPL 110), flight_lines.geojson,
    stations.geojson, footprints.geojson, area.geojson, mission.kml, map.png and summary.json;
    a terrain plan also carries its DEM, clipped to the area and home with a margin, so the
    folder is self-contained (the check, the monitor and the re-fly read it there).

    Distances in metres, GSD in cm, altitudes above ground (AGL) or home. The files are
    written all at once: on any error nothing is left behind.

    With endurance_s (or battery_capacity_mah and consumption_ma) in [vehicle], the mission is
    also split into sorties that each fit one battery less its reserve, each in OUTPUT/sortie-NN/
    with its own files. --resume-from N (or --resume-record MONITOR_DIR) plans only what is left
    of the mission from station N on (after the last station the monitor recorded).

    A plan's size is estimated first from its geometry alone (photos, lines, items, hours,
    flights, memory); a large one is announced, and one beyond --max-photos refused at once.

    Example: sfap plan missions/bardenas-gully.toml -o out/gully
    """
    with warnings_once("planner") as handled:  # each warning printed once
        started = time.monotonic()
        loud = False  # a plan above ANNOUNCE_PHOTOS takes more than a few seconds: say each step

        def announce(guess: PlanEstimate) -> None:
            nonlocal loud
            loud = guess.photos > ANNOUNCE_PHOTOS and not as_json and not no_progress
            if loud:
                click.echo(f"planning {guess.text()}", err=True)

        def stage(what: str) -> None:
            if loud:
                click.echo(f"  {time.monotonic() - started:6.1f} s  {what}", err=True)

        # map.png's helper, a second interpreter started first thing (planner.aside: spawned,
        # asking glibc to keep its memory), imports the drawing and gets Pillow and the fonts
        # ready on the other core while this one imports the planner and plans (the helper never
        # imports the planner: planner.maprender.prepare), and faults in the memory the map will
        # use; then it draws the map (sent as its view of the plan, planner.mapview, as soon as
        # the mission is built) while this one makes the summary and writes the other files.
        with Helper(warm=MAP_WARM_UP, room_bytes=MAP_ROOM_BYTES) as helper:
            from planner.plan_run import plan_spec

            run = plan_spec(
                spec_file, resume_from=resume_from, resume_record=resume_record, max_photos=max_photos,
                announce=announce, stage=stage, helper=helper,
            )  # fmt: skip
            with progress("writing", run.file_count, enabled=not no_progress and not as_json) as advance:
                run.write(out_dir, overwrite=overwrite, progress=advance, helper=helper)
        _present(run, out_dir, as_json)
        handled.update(run.plan.warnings)  # printed by _present, in the JSON, or left out on purpose


def _present(run: PlanRun, out_dir: Path, as_json: bool) -> None:
    plan, sorties, spec = run.plan, run.sorties, run.spec
    summary = run.summary()
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
    for param in plan.summary.vehicle_parameters:  # planner.vehicle_params: the vehicle must have them
        rows.append((f"vehicle parameter {param['name']}", f"{param['needed']} (sfap upload checks it)"))
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
    if spec.survey.scales:
        from planner.multiscale import pass_summaries

        for p in pass_summaries(plan):
            rows.append(
                (
                    f"pass {p['pass']} ({p['name']})",
                    f"{p['alt_agl_m']:.0f} m, GSD {p['gsd_cm']:.2f} cm, spacing {p['line_spacing_m']:.1f} m, "
                    f"trigger {p['trigger_distance_m']:.1f} m, {p['photo_count']:,} photos",
                )
            )
    if sorties:
        from planner.sorties import sortie_folder  # only a vehicle with an endurance has sorties
    for sortie in sorties:
        s = sortie.plan.summary
        seconds = round(s.flight_time_s)
        rows.append(
            (
                f"sortie {sortie.number} ({sortie_folder(sortie.number)})",
                f"{seconds // 60} min {seconds % 60:02d} s, {s.flight_distance_m:,.0f} m, "
                f"{s.photo_count:,} photos, {sortie.line_count} lines",
            )
        )
    echo_table(rows, title=f"{plan.name}: planned into {out_dir}")
    for warning in plan.warnings:  # with sorties, of the plan as flown: each sortie fits one battery
        click.echo(f"warning: {warning}", err=True)
    if sorties:
        usable = spec.vehicle.usable_flight_s or 0.0
        click.echo(
            f"{len(sorties)} sorties of at most {usable / 60.0:.1f} min each (endurance less reserve) "
            f"in {out_dir}/sortie-NN/",
            err=True,
        )
