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


def test_the_gcp_map_has_legend_scale_bar_north_arrow_and_fits_the_area(tmp_path: Path) -> None:
    """Issue 24: gcp_map.png read as a surveyor would. The legend names the area, the exclusions
    and both kinds of point; the scale bar's drawn length is the ground distance its label says
    (measured geodesically between its ends, through pyproj: the grid's scale factor aside); a
    north arrow points up the grid; the view is the area with a small margin, not half blank."""
    import re

    from geographiclib.geodesic import Geodesic
    from matplotlib.patches import FancyArrow, Rectangle

    from planner.gcp_outputs import gcp_map_figure

    outer = [(0.0, 0.0), (900.0, 0.0), (900.0, 300.0), (0.0, 300.0)]  # wide: the half-blank case
    zone = [(100.0, 100.0), (160.0, 100.0), (160.0, 160.0), (100.0, 160.0)]
    plan = plan_polygons(make_spec({"gsd_cm": 2.5}), [to_lonlat_polygon(outer)], [to_lonlat_polygon(zone)])
    layout = plan_gcps(plan, GcpOptions(gcp_count=5, check_count=2))
    fig = gcp_map_figure(plan, layout)
    ax = fig.axes[0]
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels == ["area to cover", "exclusion zones (1)", "ground control points (5)", "check points (2)"]
    assert "EPSG:" in ax.get_xlabel() and "easting" in ax.get_xlabel() and "northing" in ax.get_ylabel()

    squares = [p for p in ax.patches if isinstance(p, Rectangle) and p.get_height() < p.get_width() * 2]
    quarters = sorted((p for p in squares if p.get_zorder() == 10), key=lambda p: p.get_x())
    assert len(quarters) == 4
    left, right = quarters[0].get_x(), quarters[-1].get_x() + quarters[-1].get_width()
    label = next(t.get_text() for t in ax.texts if re.fullmatch(r"[\d.]+ k?m", t.get_text()))
    value, unit = label.split()
    stated_m = float(value) * (1000.0 if unit == "km" else 1.0)
    y = quarters[0].get_y()
    to_lonlat = Transformer.from_crs(plan.frame.crs, "EPSG:4326", always_xy=True)
    (lon0, lon1), (lat0, lat1) = to_lonlat.transform([left, right], [y, y])
    ground_m = Geodesic.WGS84.Inverse(lat0, lon0, lat1, lon1)["s12"]
    assert ground_m == pytest.approx(stated_m, rel=2e-3)
    assert 900.0 / 10 <= stated_m <= 900.0 / 2

    arrows = [p for p in fig.patches if isinstance(p, FancyArrow)]
    assert len(arrows) == 1
    tip, tail = arrows[0].get_xy().max(axis=0)[1], arrows[0].get_xy().min(axis=0)[1]
    assert tip > tail and np_ptp(arrows[0].get_xy()[:, 0]) < 0.05  # upright
    assert any(t.get_text() == "N" for t in fig.texts)

    x0, y0, x1, y1 = plan.area_xy.bounds
    (vx0, vx1), (vy0, vy1) = ax.get_xlim(), ax.get_ylim()
    assert vx0 < x0 and vx1 > x1 and vy0 < y0 and vy1 > y1
    assert (x1 - x0) / (vx1 - vx0) > 0.7 and (y1 - y0) / (vy1 - vy0) > 0.7
    fig.canvas.draw()
    box = ax.get_window_extent()
    assert box.width / fig.bbox.width > 0.55  # the map, not blank canvas, takes the figure
    assert box.height / fig.bbox.height > 0.6


def np_ptp(values: object) -> float:
    import numpy as np

    return float(np.ptp(np.asarray(values)))
