"""`sfap check` through the real click group: exit codes, output, report and re-fly files."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from shapely.geometry import box
from shared_data import SHARED_DATA

from acquisition.exif import GeoTag, strip_gps, write_geotag
from acquisition.simulator.flight import FlightSimulator
from planner.export import write_outputs
from planner.formats.qgc_plan import read_plan
from planner.mission import Autopilot, VehicleType
from planner.spec import load_spec, parse_spec
from planner.survey import plan_polygons, plan_survey
from processing.inputs import track_heading_deg
from sfap.cli import cli

GARFIELD = SHARED_DATA / "garfield_rgb"
MISSIONS = Path(__file__).resolve().parents[2] / "missions"


@pytest.fixture(scope="module")
def plans(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The gully plan folder, and a copy without the first line flown."""
    root = tmp_path_factory.mktemp("plans")
    write_outputs(plan_survey(load_spec(MISSIONS / "bardenas-gully.toml")), root / "gully")
    shutil.copytree(root / "gully", root / "minus")
    stations = root / "minus" / "stations.geojson"
    data = json.loads(stations.read_text())
    first = data["features"][0]["properties"]["line"]
    data["features"] = [f for f in data["features"] if f["properties"]["line"] != first]
    stations.write_text(json.dumps(data))
    return root / "gully", root / "minus"


def test_a_plan_passes(plans: tuple[Path, Path], tmp_path: Path) -> None:
    result = CliRunner().invoke(cli, ["check", str(plans[0]), "--cell-m", "4", "-o", str(tmp_path / "r")])
    assert result.exit_code == 0, result.output
    assert result.output.startswith("PASS")
    assert "forward overlap" in result.output and "planned 80 %" in result.output
    assert (tmp_path / "r" / "report.html").is_file()
    assert json.loads((tmp_path / "r" / "report.json").read_text())["verdict"] == "pass"


def test_a_missing_line_fails_and_refly_writes_a_mission(plans: tuple[Path, Path], tmp_path: Path) -> None:
    out = tmp_path / "report"
    args = ["check", str(plans[1]), "--cell-m", "4", "-o", str(out), "--refly", "--json"]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 1, result.output
    data = json.loads(result.stdout)  # --json: the figures on stdout, nothing else
    assert data["verdict"] == "fail" and data["coverage"]["gap_count"] >= 1
    assert any("seen by any frame" in reason for reason in data["reasons"])
    assert data["report_dir"] == str(out) and data["refly_dir"] == str(out / "refly")
    assert "per_frame" not in data
    gaps = json.loads((out / "gaps.geojson").read_text())["features"]
    assert len(gaps) == data["coverage"]["gap_count"]
    mission = read_plan(out / "refly" / "mission.plan")  # QGroundControl's format, read back
    assert len(mission.items) > 3
    summary = json.loads((out / "refly" / "summary.json").read_text())
    assert summary["camera_id"] == "canon-eos-350d-20mm" and summary["front_overlap_pct"] == 80
    assert "Re-fly mission" in (out / "report.html").read_text()


def test_images_need_a_ground_elevation() -> None:
    result = CliRunner().invoke(cli, ["check", str(GARFIELD)])
    assert result.exit_code == 2
    assert "--ground-elevation-m" in result.output


def test_real_images_with_a_ground_elevation(tmp_path: Path) -> None:
    out = tmp_path / "garfield"
    result = CliRunner().invoke(
        cli, ["check", str(GARFIELD), "--ground-elevation-m", "258", "-o", str(out), "--refly"]
    )
    # The frames cover their block, but 11 of 28 are blurred beyond half a pixel: exit 1.
    assert result.exit_code == 1, result.output
    assert "motion blur" in result.output and "parrot-sequoia-rgb" in result.output
    assert "re-fly mission: none needed (no gap)" in result.output
    assert not (out / "refly").exists()
    # Relaxing the blur threshold turns the verdict.
    relaxed = CliRunner().invoke(
        cli, ["check", str(GARFIELD), "--ground-elevation-m", "258", "--threshold", "max_blur_px=2"]
    )
    assert relaxed.exit_code == 0, relaxed.output


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--refly"], "-o REPORT"),
        (["--threshold", "nope=1"], "KEY=VALUE"),
        (["--threshold", "max_blur_px=x"], "not a number"),
        (["--plan", "."], "drop --plan"),
        (["--camera", "no-such-camera"], "not in the built-in database"),
    ],
)
def test_usage_errors(plans: tuple[Path, Path], args: list[str], message: str) -> None:
    result = CliRunner().invoke(cli, ["check", str(plans[0]), *args])
    assert result.exit_code == 2
    assert message in result.output


def test_existing_report_needs_overwrite(plans: tuple[Path, Path], tmp_path: Path) -> None:
    out = tmp_path / "r"
    out.mkdir()
    (out / "keep.txt").write_text("x")
    # Refused before the check runs (test_report_folder covers writing over it).
    result = CliRunner().invoke(cli, ["check", str(plans[0]), "-o", str(out)])
    assert result.exit_code == 2 and "--overwrite" in result.output
    assert (out / "keep.txt").is_file() and len(list(out.iterdir())) == 1


@pytest.mark.slow  # plans a re-fly of a 16 ha ring: about 8 s
def test_images_over_a_larger_area_find_gaps_and_refly_them(tmp_path: Path) -> None:
    """The Garfield block judged over a box 150 m larger on each side: the ring around the
    frames is a gap, and the re-fly flies the Sequoia at the frames' median height over it."""
    west, south, east, north = -81.6085, 41.4270, -81.6030, 41.4320  # the frames span about
    # -81.6064..-81.6053 / 41.4286..41.4302
    area = tmp_path / "area.geojson"
    ring = [[west, south], [east, south], [east, north], [west, north], [west, south]]
    area.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    out = tmp_path / "r"
    args = ["check", str(GARFIELD), "--ground-elevation-m", "258", "--area", str(area), "-o", str(out)]
    result = CliRunner().invoke(cli, [*args, "--refly", "--cell-m", "4", "--json"])
    assert result.exit_code == 1, result.output
    data = json.loads(result.stdout)
    assert data["area"]["source"] == "the area given"
    assert data["coverage"]["gap_count"] >= 1
    assert data["coverage"]["seen_by_at_least_pct"]["1"] < 50.0
    summary = json.loads((out / "refly" / "summary.json").read_text())
    assert summary["camera_id"] == "parrot-sequoia-rgb"
    assert summary["altitude_agl_m"] == pytest.approx(data["height_agl_m"]["median"], abs=0.1)


def test_the_flown_images_check_agrees_with_the_plan_check(tmp_path: Path) -> None:
    """Plan a small Sequoia survey (three lines), fly it with the simulated vehicle, write each photo as a
    copy of a real Sequoia JPEG geotagged with the reported position (AMSL: home at 300 m)
    and the track heading, then `sfap check photos/ --plan PLAN --ground-elevation-m 300`:
    the same verdict and figures as `sfap check PLAN`."""
    spec = parse_spec(
        {
            "name": "square",
            "area": "square.geojson",
            "camera": {"model": "parrot-sequoia-rgb"},
            "survey": {"altitude_agl_m": 50.0, "front_overlap_pct": 80, "side_overlap_pct": 70,
                       "speed_m_s": 2.0},
            "vehicle": {"home": [42.0, -1.5], "home_alt_amsl_m": 300.0},
        },
        tmp_path / "square.toml",
    )  # fmt: skip
    plan = plan_polygons(spec, [box(-1.4995, 42.0003, -1.4983, 42.0012)], [])
    write_outputs(plan, tmp_path / "plan")
    sim = FlightSimulator(autopilot=Autopilot.ARDUPILOT, vehicle_type=VehicleType.MULTIROTOR, home=plan.home)
    sim.set_mission(list(plan.mission.items))
    sim.step(2.0)
    assert sim.arm() == (True, "") and sim.set_mode(1, 3)
    while not sim.has_landed_after_flight and sim.time_s < 3000:
        sim.step(2.0)
    shots = sim.shots
    assert len(shots) == len(plan.stations)
    photos = tmp_path / "photos"
    photos.mkdir()
    base = tmp_path / "base.jpg"
    strip_gps(sorted(GARFIELD.glob("*.JPG"))[0], base, attitude=True)
    heading = track_heading_deg(
        np.array([s.reported_lon_deg for s in shots]), np.array([s.reported_lat_deg for s in shots])
    )
    for k, s in enumerate(shots):
        tag = GeoTag(
            lat_deg=s.reported_lat_deg,
            lon_deg=s.reported_lon_deg,
            alt_amsl_m=300.0 + s.reported_alt_rel_home_m,
            time_utc_s=s.utc_s,
            yaw_deg=float(heading[k]),
            pitch_deg=0.0,
            roll_deg=0.0,
        )
        write_geotag(base, photos / f"IMG_{k:04d}.JPG", tag)
    planned = CliRunner().invoke(cli, ["check", str(tmp_path / "plan"), "--cell-m", "1", "--json"])
    flown = CliRunner().invoke(
        cli,
        ["check", str(photos), "--plan", str(tmp_path / "plan"), "--ground-elevation-m", "300",
         "--cell-m", "1", "--json"],
    )  # fmt: skip
    # The planner puts two extra stations beyond each line end, so even this small block (3
    # lines) is seen by 3 frames or more: both checks pass it, with the same exit code.
    assert planned.exit_code == flown.exit_code == 0, (planned.output, flown.output)
    p, f = json.loads(planned.stdout), json.loads(flown.stdout)
    assert p["reasons"] == f["reasons"] == []
    assert f["frames"]["camera_id"] == "parrot-sequoia-rgb" and f["frames"]["attitude_source"] == "xmp"
    assert f["area"]["area_m2"] == pytest.approx(p["area"]["area_m2"], rel=1e-3)
    for views in ("1", "2", "3", "5"):
        seen_p = p["coverage"]["seen_by_at_least_pct"][views]
        seen_f = f["coverage"]["seen_by_at_least_pct"][views]
        assert seen_f == pytest.approx(seen_p, abs=1.5)
    for key in ("forward_pct", "side_pct"):
        assert f["overlap"][key]["median"] == pytest.approx(p["overlap"][key]["median"], abs=2.0)
    assert f["height_agl_m"]["median"] == pytest.approx(50.0, abs=0.5)
