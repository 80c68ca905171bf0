"""`sfap plan` with sorties, scales and resume, and `sfap gcp-plan`: the files a crew takes to
the field, opened with the tools of the field, and the refusals (one message, no files)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from click.testing import CliRunner
from pymavlink import mavwp

from sfap.cli import cli

REPO = Path(__file__).resolve().parents[2]
MULTISCALE = REPO / "missions" / "field-multiscale.toml"
QUARRY_SORTIES = REPO / "missions" / "quarry-block-sorties.toml"


def _areas_absolute(text: str) -> str:
    """The multiscale spec's text for a copy elsewhere: its area files named by absolute path."""
    text = text.replace(
        'area = "field-concave.geojson"', f'area = "{REPO / "missions" / "field-concave.geojson"}"'
    )
    return text.replace(
        'exclude = ["field-pylon.geojson"]', f'exclude = ["{REPO / "missions" / "field-pylon.geojson"}"]'
    )


def test_multiscale_example_flies_as_sorties_of_one_height_each(tmp_path: Path) -> None:
    out = tmp_path / "ms"
    result = CliRunner().invoke(cli, ["plan", str(MULTISCALE), "-o", str(out), "--json"])
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    sorties = summary["sorties"]
    assert sorties["usable_flight_s"] == pytest.approx(1500 * 0.75)
    assert sorties["count"] == len(sorties["list"]) >= 2
    assert sum(s["photo_count"] for s in sorties["list"]) == summary["photo_count"]
    heights = {p["index"]: p["alt_agl_m"] for p in summary["passes"]}
    assert sorted(heights.values())[-1] == pytest.approx(110.0)
    for s in sorties["list"]:
        folder = out / s["folder"]
        assert s["flight_time_s"] <= 1125.0
        assert len(s["passes"]) == 1  # one height per sortie (scale_flight = "sorties")
        loader = mavwp.MAVWPLoader()
        loader.load(str(folder / "mission.waypoints"))
        assert loader.count() == s["item_count"] + 1
        stations = json.loads((folder / "stations.geojson").read_text())["features"]
        assert len(stations) == s["photo_count"]
        assert {f["properties"]["pass"] for f in stations} == set(s["passes"])
        assert json.loads((folder / "summary.json").read_text())["flight_time_s"] == s["flight_time_s"]
    # the whole plan's stations and footprints carry their pass
    whole = json.loads((out / "footprints.geojson").read_text())["features"]
    assert {f["properties"]["pass"] for f in whole} == set(heights)


@pytest.mark.slow
def test_quarry_flies_as_sorties_of_one_battery(quarry_sorties_cli: tuple[Path, int, str, str]) -> None:
    _, exit_code, stdout, output = quarry_sorties_cli  # `sfap plan` of QUARRY_SORTIES, --json
    assert exit_code == 0, output
    sorties = json.loads(stdout)["sorties"]
    assert sorties["usable_flight_s"] == pytest.approx(1800.0)
    assert all(s["flight_time_s"] <= 1800.0 for s in sorties["list"])
    assert all(s["item_count"] + 1 <= 650 for s in sorties["list"])


def test_endurance_shorter_than_a_line_is_refused_without_files(tmp_path: Path) -> None:
    spec = tmp_path / "short.toml"
    spec.write_text(_areas_absolute(MULTISCALE.read_text().replace("endurance_s = 1500", "endurance_s = 60")))
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(out)])
    assert result.exit_code == 1
    assert "as a sortie of its own" in result.stderr and "raise endurance_s" in result.stderr
    assert "Traceback" not in result.output
    assert not out.exists()


def test_resume_from_a_station(tmp_path: Path) -> None:
    whole, part = tmp_path / "whole", tmp_path / "part"
    spec = REPO / "missions" / "field-concave.toml"
    assert CliRunner().invoke(cli, ["plan", str(spec), "-o", str(whole), "--json"]).exit_code == 0
    total = len(json.loads((whole / "stations.geojson").read_text())["features"])
    result = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(part), "--json", "--resume-from", "100"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["resumed_from_station"] == 100
    assert len(json.loads((part / "stations.geojson").read_text())["features"]) == total - 100
    bad = CliRunner().invoke(cli, ["plan", str(spec), "-o", str(tmp_path / "x"), "--resume-from", "99999"])
    assert bad.exit_code == 2 and "has stations 0 to" in bad.stderr
    assert not (tmp_path / "x").exists()


def test_gcp_plan_writes_what_a_rover_loads(tmp_path: Path) -> None:
    out = tmp_path / "gcp"
    args = ["gcp-plan", str(MULTISCALE), "-o", str(out), "--gcp", "6", "--check", "3", "--json"]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    with (out / "gcp.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [r["role"] for r in rows].count("gcp") == 6 and [r["role"] for r in rows].count("check") == 3
    assert set(rows[0]) >= {"name", "lat_deg", "lon_deg", "easting_m", "northing_m", "role"}
    features = json.loads((out / "gcp.geojson").read_text())["features"]
    assert [f["properties"]["name"] for f in features] == [r["name"] for r in rows]
    assert (out / "gcp.kml").read_text().count("<Placemark>") == 9
    assert (out / "gcp_map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads(result.stdout)["expected_accuracy"]["horizontal_rmse_m"][0] > 0


def test_gcp_plan_more_points_than_the_area_holds(tmp_path: Path) -> None:
    out = tmp_path / "gcp"
    args = ["gcp-plan", str(MULTISCALE), "-o", str(out), "--gcp", "400", "--min-separation-m", "40"]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 2  # an impossible request is bad input (issue 24)
    assert "points or fewer" in result.stderr and "Traceback" not in result.output
    assert not out.exists()


def test_warnings_are_printed_once_and_the_battery_one_not_with_sorties(tmp_path: Path) -> None:
    """The real command (its own process and logging set-up). With sorties, the warning that the
    flight needs more than one battery is left out on purpose (each sortie fits one); without
    them it is printed, once, and it is in the JSON."""
    import subprocess
    import sys

    def plan(spec: Path, *extra: str) -> subprocess.CompletedProcess[str]:
        command = [sys.executable, "-m", "sfap", "plan", str(spec), "-o", str(tmp_path / spec.stem)]
        return subprocess.run(
            [*command, "--no-progress", *extra], capture_output=True, text=True, timeout=120
        )

    done = plan(MULTISCALE)
    assert done.returncode == 0, done.stderr
    assert "more than one battery" not in done.stderr and "3 sorties" in done.stderr
    one = tmp_path / "one-battery.toml"
    one.write_text(_areas_absolute(MULTISCALE.read_text().replace("endurance_s = 1500\n", "")))
    done = plan(one)
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("more than one battery") == 1, done.stderr
    assert [line for line in done.stderr.splitlines() if line] == [
        line for line in done.stderr.splitlines() if line.startswith("warning: ")
    ]
    done = plan(one, "--json", "--overwrite")
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert sum("more than one battery" in w for w in json.loads(done.stdout)["warnings"]) == 1
