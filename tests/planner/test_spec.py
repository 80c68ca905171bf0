"""Mission specs (planner.spec): a good spec loads; bad input gets one clear message that names
the value and the fix."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from planner.errors import CameraError, SpecError
from planner.spec import load_spec

GOOD = """
name = "t"
area = "area.geojson"
[camera]
model = "dji-phantom-4-pro"
[survey]
gsd_cm = 2.0
front_overlap_pct = 80
side_overlap_pct = 70
speed_m_s = 5
[vehicle]
type = "multirotor"
"""

SQUARE = [[-1.60, 42.50], [-1.597, 42.50], [-1.597, 42.502], [-1.60, 42.502], [-1.60, 42.50]]


def write(tmp_path: Path, toml: str, ring: list[list[float]] | None = None) -> Path:
    (tmp_path / "area.geojson").write_text(json.dumps({"type": "Polygon", "coordinates": [ring or SQUARE]}))
    spec = tmp_path / "m.toml"
    spec.write_text(toml)
    return spec


def test_good_spec_loads(tmp_path: Path) -> None:
    spec = load_spec(write(tmp_path, GOOD))
    assert spec.survey.gsd_cm == 2.0 and spec.survey.direction_deg is None
    assert spec.area_path == (tmp_path / "area.geojson").resolve()


@pytest.mark.parametrize(
    ("change", "pattern"),
    [
        (
            ("front_overlap_pct = 80", "front_overlap_pct = 97"),
            r"front_overlap_pct = 97 is outside 0 to 95",
        ),
        (("side_overlap_pct = 70", "side_overlap_pct = -5"), r"side_overlap_pct = -5 is outside"),
        (
            ("gsd_cm = 2.0", "gsd_cm = 2.0\naltitude_agl_m = 50"),
            "exactly one of gsd_cm and altitude_agl_m",
        ),
        (("gsd_cm = 2.0", ""), "exactly one of gsd_cm and altitude_agl_m"),
        (
            ("speed_m_s = 5", "speed_m_s = 5\nsped = 3"),
            r"unknown key sped in \[survey\]; valid keys: .*speed_m_s",
        ),
        (
            ('name = "t"', 'name = "t"\ncolour = 1'),
            r"unknown key colour in the top level; valid keys",
        ),
        (('type = "multirotor"', 'type = "blimp"'), "use one of multirotor, fixed_wing, vtol"),
        (("speed_m_s = 5", 'speed_m_s = "fast"'), "speed_m_s = 'fast' must be a number"),
        (
            ("speed_m_s = 5", 'trigger = "sometimes"'),
            "trigger = 'sometimes'; use one of distance, hover",
        ),
        (("[vehicle]", "[vehicle]\nhome = [42.5]"), r"home must be \[lat, lon\]"),
        (("gsd_cm = 2.0", 'gsd_cm = 2.0\ndirection_deg = "north"'), 'use "auto" or a bearing'),
        (
            ("speed_m_s = 5", "speed_m_s = 5\n[[survey.oblique]]\ntilt_deg = 85"),
            r"tilt_deg = 85 is outside 5 to 60",
        ),
    ],
)
def test_bad_values_name_the_key_and_the_fix(tmp_path: Path, change: tuple[str, str], pattern: str) -> None:
    with pytest.raises(SpecError, match=pattern):
        load_spec(write(tmp_path, GOOD.replace(*change)))


def test_bad_toml_and_missing_file(tmp_path: Path) -> None:
    with pytest.raises(SpecError, match="not valid TOML"):
        load_spec(write(tmp_path, GOOD + "\n[[[ nope"))
    with pytest.raises(SpecError, match="does not exist"):
        load_spec(tmp_path / "missing.toml")


def test_camera_errors(tmp_path: Path) -> None:
    with pytest.raises(CameraError, match="sfap cameras"):
        load_spec(write(tmp_path, GOOD.replace("dji-phantom-4-pro", "dji-phantom-5")))
    custom = GOOD.replace('model = "dji-phantom-4-pro"', (
        "sensor_width_mm = 13.2\nsensor_height_mm = 8.8\nimage_width_px = 5472\n"
        "image_height_px = 3648\nfocal_length_mm = -8.8"
    ))  # fmt: skip
    with pytest.raises(CameraError, match="focal_length_mm"):
        load_spec(write(tmp_path, custom))
