"""Survey areas and corridor centre lines (planner.area): GeoJSON and KML read, bad polygons,
other CRSs and formats refused with the fix."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from planner.area import build_area, load_centreline, load_polygons
from planner.errors import AreaError

SQUARE = [[-1.60, 42.50], [-1.597, 42.50], [-1.597, 42.502], [-1.60, 42.502], [-1.60, 42.50]]


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


def test_a_centre_line_from_geojson_or_kml(tmp_path: Path) -> None:
    line = [[-1.60, 42.50], [-1.59, 42.505], [-1.59, 42.505], [-1.58, 42.50]]  # a repeated point
    path = tmp_path / "c.geojson"
    path.write_text(json.dumps({"type": "Feature", "geometry": {"type": "LineString", "coordinates": line}}))
    expected = [(-1.60, 42.50), (-1.59, 42.505), (-1.58, 42.50)]
    assert load_centreline(path) == expected
    kml = tmp_path / "c.kml"
    kml.write_text(
        '<kml xmlns="http://www.opengis.net/kml/2.2"><Placemark><LineString><coordinates>'
        + " ".join(f"{x},{y},0" for x, y in line)
        + "</coordinates></LineString></Placemark></kml>"
    )
    assert load_centreline(kml) == expected
    two = tmp_path / "two.geojson"
    two.write_text(json.dumps({"type": "MultiLineString", "coordinates": [line, line]}))
    with pytest.raises(AreaError, match="holds 2 LineStrings; a corridor's area file holds exactly one"):
        load_centreline(two)
    crs = tmp_path / "crs.geojson"
    crs.write_text(json.dumps({
        "type": "LineString", "coordinates": line,
        "crs": {"type": "name", "properties": {"name": "EPSG:25830"}},
    }))  # fmt: skip
    with pytest.raises(AreaError, match="re-export the centre line in EPSG:4326"):
        load_centreline(crs)
