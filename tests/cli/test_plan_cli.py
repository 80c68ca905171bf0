"""`sfap plan` on every bundled example, and its refusals. Every example in missions/ is
planned here, and its files are opened with the tools of the field (pymavlink's mavwp for the
.waypoints, JSON + QGC's required keys for the .plan, shapely for GeoJSON, ElementTree for KML)."""

from __future__ import annotations

import json
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
def test_every_example_plans_and_its_files_open(spec: Path, tmp_path: Path) -> None:
    out = tmp_path / spec.stem
    result = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(out), "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
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
        (("gsd_cm = 2.4", "gsd_cm = 9.0"), 1, "max_alt_agl_m"),
        (("speed_m_s = 5", "speed_m_s = 30"), 1, "too fast"),
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
