"""Bad input gets one clear message that names the value and the fix."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.area import build_area, load_polygons
from planner.errors import AreaError, CameraError, SpecError
from planner.geo import LocalFrame
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


@pytest.mark.parametrize(
    ("ring", "pattern"),
    [
        ([[0, 0], [1, 1], [1, 0], [0, 1], [0, 0]], "invalid .*Self-intersection"),
        ([[-1.6, 42.5], [-1.59, 42.5], [-1.59, 42.51]], "at least 4"),
        ([[-1.6, 42.5], [-1.59, 42.5], [-1.59, 42.51], [-1.6, 42.51]], "not closed"),
        (
            [[615000, 4706000], [615100, 4706000], [615100, 4706100], [615000, 4706000]],
            "looks projected",
        ),
        ([[-1.6, 42.5], [-1.59, 42.5], [-1.58, 42.5], [-1.6, 42.5]], "empty"),
    ],
)
def test_bad_polygons(tmp_path: Path, ring: list[list[float]], pattern: str) -> None:
    path = tmp_path / "a.geojson"
    path.write_text(json.dumps({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [ring]}}))
    with pytest.raises(AreaError, match=pattern):
        load_polygons(path)


def test_other_crs_and_formats(tmp_path: Path) -> None:
    path = tmp_path / "a.geojson"
    path.write_text(json.dumps({
        "type": "FeatureCollection",
        "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::25830"}},
        "features": [{"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [SQUARE]}}],
    }))  # fmt: skip
    with pytest.raises(AreaError, match="EPSG:4326"):
        load_polygons(path)
    shp = tmp_path / "a.shp"
    shp.write_bytes(b"x")
    with pytest.raises(AreaError, match=r"GeoJSON .* or KML"):
        load_polygons(shp)
    broken = tmp_path / "b.geojson"
    broken.write_text("{ nope")
    with pytest.raises(AreaError, match="not valid GeoJSON"):
        load_polygons(broken)


def test_kml_with_hole(tmp_path: Path) -> None:
    kml = tmp_path / "a.kml"
    outer = " ".join(f"{x},{y},0" for x, y in SQUARE)
    hole = [[-1.599, 42.5005], [-1.598, 42.5005], [-1.598, 42.5010], [-1.599, 42.5005]]
    inner = " ".join(f"{x},{y}" for x, y in hole)
    kml.write_text(
        '<kml xmlns="http://www.opengis.net/kml/2.2"><Document><Placemark><Polygon>'
        f"<outerBoundaryIs><LinearRing><coordinates>{outer}</coordinates></LinearRing></outerBoundaryIs>"
        f"<innerBoundaryIs><LinearRing><coordinates>{inner}</coordinates></LinearRing></innerBoundaryIs>"
        "</Polygon></Placemark></Document></kml>"
    )
    polygons = load_polygons(kml)
    assert len(polygons) == 1 and len(polygons[0].interiors) == 1
    area, zones = build_area(polygons, [])
    assert len(zones) == 1
    assert area.area == pytest.approx(polygons[0].area)


# --- the UTM zone of an area ------------------------------------------------------------------


@settings(max_examples=200, deadline=None, derandomize=True)
@given(
    lon=st.floats(-179.9, 179.9).filter(lambda x: abs((x + 180.0) / 6.0 - round((x + 180.0) / 6.0)) > 1e-4),
    lat=st.floats(-79.9, 83.9).filter(lambda y: abs(y) > 1e-6),
)
def test_utm_zone_is_the_one_proj_database_names(lon: float, lat: float) -> None:
    """LocalFrame.utm_for computes the zone; PROJ's database (query_utm_crs_info, the CRSs' areas
    of use) is the independent oracle, away from zone borders where both zones are right."""
    from pyproj.aoi import AreaOfInterest
    from pyproj.database import query_utm_crs_info

    infos = query_utm_crs_info(datum_name="WGS 84", area_of_interest=AreaOfInterest(lon, lat, lon, lat))
    codes = {int(i.code) for i in infos if i.code.startswith(("326", "327"))}
    assert LocalFrame.utm_for(lon, lat).epsg in codes


@pytest.mark.parametrize(("lon", "lat"), [(0.0, 84.5), (10.0, -80.5), (181.0, 10.0)])
def test_no_utm_zone_beyond_its_limits(lon: float, lat: float) -> None:
    with pytest.raises(AreaError, match="no UTM zone covers"):
        LocalFrame.utm_for(lon, lat)
