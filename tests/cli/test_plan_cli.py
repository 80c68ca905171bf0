"""`sfap plan` on every bundled example, and its refusals. Every example in missions/ is
planned here, and its files are opened with the tools of the field (pymavlink's mavwp for the
.waypoints, JSON + QGC's required keys for the .plan, shapely for GeoJSON, ElementTree for KML)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from click.testing import CliRunner
from pymavlink import mavwp
from shapely.geometry import shape

from sfap.cli import COMMANDS, cli

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((REPO / "missions").glob("*.toml"))


def test_there_are_three_or_more_examples() -> None:
    assert len(EXAMPLES) >= 3


@pytest.mark.parametrize("spec", EXAMPLES, ids=lambda p: p.stem)
def test_every_example_plans_and_its_files_open(
    spec: Path, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    if spec.stem == "quarry-block-sorties":  # the same command, run once for the tests that read it
        out, exit_code, stdout, output = request.getfixturevalue("quarry_sorties_cli")
    else:
        out = tmp_path / spec.stem
        result = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(out), "--json"])
        exit_code, stdout, output = result.exit_code, result.stdout, result.output
    assert exit_code == 0, output
    summary = json.loads(stdout)
    for key in (
        "area_m2", "gsd_cm", "altitude_agl_m", "footprint_along_m", "footprint_across_m",
        "air_base_m", "line_spacing_m", "exposure_interval_s", "max_speed_m_s",
        "base_height_ratio", "line_count", "photo_count", "flight_distance_m",
        "flight_time_s", "item_count",
    ):  # fmt: skip
        assert isinstance(summary[key], int | float) and summary[key] > 0, key
    assert summary["speed_m_s"] <= summary["max_speed_m_s"]

    loader = mavwp.MAVWPLoader()
    loader.load(str(out / "mission.waypoints"))
    assert loader.count() == summary["item_count"] + 1  # home in row 0

    plan = json.loads((out / "mission.plan").read_text())
    assert plan["fileType"] == "Plan"
    assert len(plan["mission"]["items"]) == summary["item_count"]

    stations = json.loads((out / "stations.geojson").read_text())
    assert len(stations["features"]) == summary["photo_count"]
    footprints = json.loads((out / "footprints.geojson").read_text())
    assert all(shape(f["geometry"]).is_valid for f in footprints["features"][:500])
    lines = json.loads((out / "flight_lines.geojson").read_text())
    assert lines["features"]
    # no output holds a zero-length line (a one-photo run still has its camera-off point)
    for feature in lines["features"]:
        geometry = shape(feature["geometry"])
        parts = getattr(geometry, "geoms", [geometry])
        assert all(len(set(part.coords)) >= 2 for part in parts), feature["properties"]

    root = ET.parse(out / "mission.kml").getroot()
    assert root.tag == "{http://www.opengis.net/kml/2.2}kml"
    assert (out / "map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads((out / "summary.json").read_text())["photo_count"] == summary["photo_count"]


def test_table_output_and_overwrite(tmp_path: Path) -> None:
    spec = REPO / "missions" / "bardenas-gully.toml"
    out = tmp_path / "gully"
    first = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(out)])
    assert first.exit_code == 0, first.output
    assert "GSD" in first.output and "photos" in first.output
    before = (out / "summary.json").read_bytes()
    again = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(out)])
    assert again.exit_code == 2
    assert "--overwrite" in again.output
    assert (out / "summary.json").read_bytes() == before  # untouched
    forced = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(out), "--overwrite"])
    assert forced.exit_code == 0


@pytest.mark.parametrize(
    ("edit", "code", "message"),
    [
        # values no vehicle can fly as asked: bad input, exit 2 (README: impossible spec value)
        (("gsd_cm = 2.4", "gsd_cm = 9.0"), 2, "max_alt_agl_m"),
        (("speed_m_s = 5", "speed_m_s = 30"), 2, "too fast"),
        (
            (
                'trigger = "distance"',
                'trigger = "distance"\n[[survey.oblique]]\ntilt_deg = 75\nheadings_deg = [0]',
            ),
            2,
            "tilt_deg = 75 is outside",
        ),
        (("front_overlap_pct = 80", "front_overlap_pct = 99"), 2, "front_overlap_pct = 99"),
        (("turnaround_m = 10", "turnaround_m = 10\nwind = 3"), 2, "unknown key wind"),
    ],
)
def test_bad_input_gives_one_message_and_no_files(
    tmp_path: Path, edit: tuple[str, str], code: int, message: str
) -> None:
    source = (REPO / "missions" / "bardenas-gully.toml").read_text()
    assert edit[0] in source
    spec = tmp_path / "bad.toml"
    spec.write_text(source.replace(*edit))
    (tmp_path / "bardenas-gully.geojson").write_bytes(
        (REPO / "missions" / "bardenas-gully.geojson").read_bytes()
    )
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(out)])
    assert result.exit_code == code, result.output
    assert message in result.output
    assert "Traceback" not in result.output
    assert not out.exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no staging left


def test_missing_spec_is_a_usage_error(tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["plan", str(tmp_path / "nope.toml"), "-o", str(tmp_path / "o")])
    assert result.exit_code == 2
    assert "does not exist" in result.output


def test_every_registered_command_loads_and_has_help() -> None:
    runner = CliRunner()
    for name in COMMANDS:
        result = runner.invoke(cli, [name, "--help"])
        assert result.exit_code == 0, f"{name}: {result.output}"
        assert "Example" in result.output or "example" in result.output, name


def test_version() -> None:
    result = CliRunner().invoke(cli, ["--version"])
    assert result.exit_code == 0 and "sfap" in result.output


def test_an_area_across_the_antimeridian_is_refused(tmp_path: Path) -> None:
    ring = [[179.999, -16.5], [-179.998, -16.5], [-179.998, -16.502], [179.999, -16.502], [179.999, -16.5]]
    (tmp_path / "fiji.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    source = (REPO / "missions" / "bardenas-gully.toml").read_text()
    source = source.replace('area = "bardenas-gully.geojson"', 'area = "fiji.geojson"')
    source = "\n".join(line for line in source.splitlines() if not line.startswith("home"))
    spec = tmp_path / "fiji.toml"
    spec.write_text(source)
    result = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2, result.output
    assert "antimeridian" in result.output and "split it at 180" in result.output
    assert not (tmp_path / "out").exists()


def test_constant_altitude_over_relief_that_opens_gaps_fails(tmp_path: Path) -> None:
    source = (
        (REPO / "missions" / "bardenas-gully-terrain.toml")
        .read_text()
        .replace("follow = true", "follow = false")
    )
    spec = tmp_path / "constant.toml"
    spec.write_text(source.replace('"bardenas-gully', f'"{REPO}/missions/bardenas-gully'))
    result = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(tmp_path / "out")])
    assert result.exit_code == 1, result.output
    assert "% side" in result.output and "follow = true" in result.output
    assert "accept_overlap_loss = true" in result.output
    assert not (tmp_path / "out").exists()


def test_a_plan_no_vehicle_can_fly_says_so_on_the_terminal(tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["plan", str(REPO / "missions" / "quarry-block.toml"), "-o",
                                      str(tmp_path / "q"), "--no-progress"])  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "warning: the mission has" in result.stderr and "650" in result.stderr
    assert "more than one battery" in result.stderr
    summary = json.loads((tmp_path / "q" / "summary.json").read_text())
    assert any("battery" in w for w in summary["warnings"])


_THREADS_AFTER_NUMPY = """
import os, sys
from sfap.cli import cli
cli.get_command(None, sys.argv[1])
import gc
import numpy
print(os.environ.get("OPENBLAS_NUM_THREADS"), len(os.listdir("/proc/self/task")), gc.get_freeze_count(),
      gc.isenabled())
"""


@pytest.mark.parametrize(
    ("command", "user_value", "expected"),
    [
        ("plan", None, "1"),
        ("gcp-plan", None, "1"),
        ("geotag", None, "1"),
        ("plan", "2", "2"),
        ("check", None, None),
    ],
)
def test_small_commands_load_openblas_with_one_thread(
    command: str, user_value: str | None, expected: str | None
) -> None:
    """plan loads numpy's OpenBLAS with one thread (the process has no other thread once numpy
    is imported, counted by Linux in /proc/self/task); a value the user set is kept, and the
    commands with large arrays keep OpenBLAS's default."""
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    if user_value is not None:
        env["OPENBLAS_NUM_THREADS"] = user_value
    out = subprocess.run(
        [sys.executable, "-c", _THREADS_AFTER_NUMPY, command],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    assert out[0] == str(expected)
    if expected == "1":
        assert out[1] == "1"
    # The imports' objects are frozen out of the garbage collector's full collections, and the
    # collector, off while the command's modules were imported, runs again.
    assert int(out[2]) > 10_000
    assert out[3] == "True"
