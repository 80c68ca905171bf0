"""`sfap cameras` through the real click group: list, show, --json, unknown id, --help."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from planner.camera_db import get_camera, load_cameras
from sfap.cli import cli


def _run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_list_shows_every_camera_with_its_numbers() -> None:
    code, out, _ = _run("cameras")
    assert code == 0
    lines = out.splitlines()
    assert lines[0].split()[:2] == ["id", "name"]
    assert "pitch um" in lines[0]
    cameras = load_cameras()
    assert len(lines) == 1 + len(cameras)
    by_id = {line.split()[0]: line for line in lines[1:]}
    assert set(by_id) == set(cameras)
    textbook = by_id["canon-eos-350d-20mm"]
    assert "22.2 x 14.8" in textbook and "3456 x 2304" in textbook and "6.42" in textbook


def test_list_as_json() -> None:
    code, out, _ = _run("cameras", "--json")
    assert code == 0
    rows = json.loads(out)
    assert [row["id"] for row in rows] == list(load_cameras())
    p1 = next(row for row in rows if row["id"] == "dji-zenmuse-p1-35mm")
    assert p1["image_width_px"] == 8192
    assert p1["focal_length_mm"] == 35.0
    assert p1["pixel_pitch_um"] == pytest.approx(4.4, rel=0.01)


def test_show_one_camera_with_derived_figures() -> None:
    code, out, _ = _run("cameras", "canon-eos-350d-20mm")
    assert code == 0
    assert out.splitlines()[0] == "canon-eos-350d-20mm"
    assert "6.424 / 6.424 um" in out  # pitch per axis
    assert "3.212 / 3.212 cm" in out  # GSD at 100 m: 6.424 um x 100 m / 20 mm
    assert "111.0 x 74.0 m" in out  # footprint at 100 m
    assert "height for 2 cm GSD" in out and "62.3 m AGL" in out
    assert "Aber" in out  # the source


def test_show_as_json_matches_the_camera_model() -> None:
    code, out, _ = _run("cameras", "dji-mavic-3-enterprise", "--json")
    assert code == 0
    data = json.loads(out)
    camera = get_camera("dji-mavic-3-enterprise")
    assert data["id"] == camera.id
    assert data["at_height"]["alt_agl_m"] == 100.0
    assert data["at_height"]["gsd_cm"] == pytest.approx(camera.gsd_cm(100.0))
    assert data["at_height"]["gsd_x_cm"] < data["at_height"]["gsd_y_cm"]  # 4/3: 3.277 < 3.286 um
    heights = {entry["gsd_cm"]: entry["alt_agl_m"] for entry in data["height_for_gsd"]}
    assert set(heights) == {1.0, 2.0, 3.0}
    for gsd_cm, alt_agl_m in heights.items():
        assert camera.gsd_cm(alt_agl_m) == pytest.approx(gsd_cm)
    assert data["fov_x_deg"] > data["fov_y_deg"] > 0
    assert data["exif_model"] == "M3E"


def test_unknown_id_is_a_usage_error_listing_close_ids() -> None:
    code, out, err = _run("cameras", "dji-mavic-3-enterprize")
    assert code == 2
    assert out == ""
    assert "dji-mavic-3-enterprise" in err
    assert "sfap cameras" in err


def test_help_shows_an_example_and_units() -> None:
    code, out, _ = _run("cameras", "--help")
    assert code == 0
    assert "Example: sfap cameras" in out
    assert "--json" in out
    assert "mm" in out and "AGL" in out
