"""The ground control files (planner.gcp_outputs) read back by independent readers: the csv
module, json, ElementTree for the KML, pyproj for the projected coordinates; written all or
nothing."""

from __future__ import annotations

import csv
import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from pyproj import Transformer
from survey_oracles import make_spec
from test_survey import to_lonlat_polygon

from planner.errors import InputError
from planner.gcp_layout import GcpLayout, GcpOptions, plan_gcps
from planner.gcp_outputs import GCP_FILES, write_gcp_outputs
from planner.plan import SurveyPlan
from planner.survey import plan_polygons

KML = "{http://www.opengis.net/kml/2.2}"


@pytest.fixture(scope="module")
def planned() -> tuple[SurveyPlan, GcpLayout]:
    square = [(0.0, 0.0), (600.0, 0.0), (600.0, 450.0), (0.0, 450.0)]
    plan = plan_polygons(make_spec({"gsd_cm": 2.5}), [to_lonlat_polygon(square)], [])
    return plan, plan_gcps(plan, GcpOptions(gcp_count=6, check_count=3))


def test_every_file_holds_every_point_where_the_layout_put_it(
    planned: tuple[SurveyPlan, GcpLayout], tmp_path: Path
) -> None:
    plan, layout = planned
    written = write_gcp_outputs(plan, layout, str(tmp_path / "gcp"))
    assert sorted(p.name for p in written) == sorted(GCP_FILES)
    assert all(p.is_file() and p.stat().st_size > 0 for p in written)
    points = {p.name: p for p in layout.points}
    assert len(points) == 9

    with (tmp_path / "gcp" / "gcp.csv").open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    # Oracle for the projected columns: pyproj from WGS84 to the CRS the file names.
    to_crs = Transformer.from_crs("EPSG:4326", rows[0]["crs"], always_xy=True)
    assert {r["name"] for r in rows} == set(points)
    for r in rows:
        e, n = to_crs.transform(float(r["lon_deg"]), float(r["lat_deg"]))
        assert (float(r["easting_m"]), float(r["northing_m"])) == (
            pytest.approx(e, abs=0.01),
            pytest.approx(n, abs=0.01),
        )
        assert r["role"] == points[r["name"]].role

    features = json.loads((tmp_path / "gcp" / "gcp.geojson").read_text())["features"]
    for f in features:
        p = points[f["id"]]
        lon, lat = f["geometry"]["coordinates"]
        assert (lon, lat) == (pytest.approx(p.lon_deg, abs=1e-9), pytest.approx(p.lat_deg, abs=1e-9))
        assert f["properties"]["frame_count"] == p.frame_count

    root = ET.parse(tmp_path / "gcp" / "gcp.kml").getroot()
    marks = root.iter(f"{KML}Placemark")
    seen = {}
    for mark in marks:
        lon_text, lat_text, _ = mark.findtext(f"{KML}Point/{KML}coordinates").split(",")  # type: ignore[union-attr]
        seen[mark.findtext(f"{KML}name")] = (float(lon_text), float(lat_text))
    assert seen == {
        n: (pytest.approx(p.lon_deg, abs=1e-9), pytest.approx(p.lat_deg, abs=1e-9)) for n, p in points.items()
    }

    data = json.loads((tmp_path / "gcp" / "gcp.json").read_text())
    assert data == json.loads(json.dumps(layout.as_dict()))


def test_a_folder_in_use_is_left_as_it_was(planned: tuple[SurveyPlan, GcpLayout], tmp_path: Path) -> None:
    plan, layout = planned
    out = tmp_path / "gcp"
    out.mkdir()
    (out / "notes.txt").write_text("field notes")
    with pytest.raises(InputError, match="--overwrite"):
        write_gcp_outputs(plan, layout, str(out))
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
