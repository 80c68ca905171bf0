"""The geographic writers of a plan: GeoJSON, KML and the map PNG.

The plans are built by hand, independently of the planner: a real UTM frame, a concave area
with a hole and an exclusion zone, a nadir pass and an oblique pass whose footprints are ray
cast here from the camera geometry (so an oblique frame is a real trapezoid), and a mission.
Oracles: the standard parsers (json, shapely.geometry.shape, xml.etree), the positions the
plan was built from, and the pixels of the rendered map.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hst
from shapely.geometry import Polygon, shape
from shapely.ops import unary_union

from planner.camera import Camera, Orientation
from planner.errors import PlanningError
from planner.formats.geojson import (
    _fixed_point,
    counter_clockwise_corners,
    write_area_geojson,
    write_flight_lines_geojson,
    write_footprints_geojson,
    write_stations_geojson,
)
from planner.formats.kml import KML_NS, ordinal, serialise, write_kml
from planner.geo import LocalFrame, geodesic_distance_m
from planner.kinds import PassKind
from planner.maplayout import scale_bar_length_m
from planner.mapplot import render_map_figure, render_map_png
from planner.mission import Autopilot, HomePosition, MavCmd, Mission, MissionItem
from planner.plan import FlightLine, FlightPass, Stations, Summary, SurveyPlan

LON0, LAT0 = -1.4963, 42.1790  # Bardenas Reales, Navarra (the textbook's gully region)

CANON_350D = Camera(
    id="canon-eos-350d-20mm",
    name="Canon EOS 350D, 20 mm",
    sensor_width_mm=22.2,
    sensor_height_mm=14.8,
    image_width_px=3456,
    image_height_px=2304,
    focal_length_mm=20.0,
    min_trigger_interval_s=1.0,
)


# --- a plan built by hand --------------------------------------------------------------------


def ray_cast_footprints(
    x_m: np.ndarray,
    y_m: np.ndarray,
    alt_agl_m: float,
    look_heading_deg: np.ndarray,
    tilt_deg: float,
    camera: Camera,
) -> np.ndarray:
    """(N, 4, 2) ground corners TL, TR, BR, BL of frames over flat ground (x east, y north).

    Landscape: image width across the look direction, image top toward it (the horizon side
    of a tilted frame), so the far edge of an oblique frame is the top edge.
    """
    t = math.radians(tilt_deg)
    lam = np.radians(look_heading_deg)
    d = np.stack([np.sin(lam) * math.sin(t), np.cos(lam) * math.sin(t), -np.full_like(lam, math.cos(t))], -1)
    u = np.stack([np.sin(lam) * math.cos(t), np.cos(lam) * math.cos(t), np.full_like(lam, math.sin(t))], -1)
    r = np.cross(d, u)
    half_w, half_h = camera.sensor_width_mm / 2, camera.sensor_height_mm / 2
    out = np.empty((x_m.shape[0], 4, 2))
    for k, (px, py) in enumerate(
        [(-half_w, half_h), (half_w, half_h), (half_w, -half_h), (-half_w, -half_h)]
    ):
        ray = camera.focal_length_mm * d + px * r + py * u
        s = alt_agl_m / -ray[:, 2]
        out[:, k, 0] = x_m + s * ray[:, 0]
        out[:, k, 1] = y_m + s * ray[:, 1]
    return out


def make_plan(
    *,
    lines_per_pass: int = 4,
    line_length_m: float = 160.0,
    trigger_distance_m: float = 11.0,
    spacing_m: float = 25.0,
    home_alt_amsl_m: float = 352.0,
    name: str = "Bardenas <gully> & co",
) -> SurveyPlan:
    """A two-pass plan (nadir north-south, oblique east-west looking east) over a concave
    area with a hole and an exclusion zone; sizes scale with the arguments."""
    frame = LocalFrame.utm_for(LON0, LAT0)
    cx, cy = (float(v) for v in frame.to_xy(LON0, LAT0))
    width_m = max(lines_per_pass * spacing_m, 100.0)
    height_m = line_length_m
    outer = Polygon(
        [
            (cx, cy),
            (cx + width_m, cy),
            (cx + width_m, cy + height_m),
            (cx + 0.5 * width_m, cy + height_m),
            (cx + 0.5 * width_m, cy + 0.6 * height_m),  # a notch: the area is concave
            (cx, cy + 0.6 * height_m),
        ]
    )
    hole = Polygon(
        [
            (cx + 0.2 * width_m, cy + 0.2 * height_m),
            (cx + 0.3 * width_m, cy + 0.2 * height_m),
            (cx + 0.3 * width_m, cy + 0.3 * height_m),
            (cx + 0.2 * width_m, cy + 0.3 * height_m),
        ]
    )
    zone = Polygon(
        [
            (cx + 0.7 * width_m, cy + 0.1 * height_m),
            (cx + 0.8 * width_m, cy + 0.1 * height_m),
            (cx + 0.75 * width_m, cy + 0.25 * height_m),
        ]
    )
    area_with_hole = Polygon(outer.exterior.coords, [hole.exterior.coords])
    area_xy = area_with_hole.difference(zone)
    exclusions_xy = (hole, zone)

    alt_m = 75.6
    home_xy = (cx - 30.0, cy - 20.0)
    # geometry is built in grid bearings; the plan stores true bearings (grid - this)
    north_grid_deg = frame.true_north_grid_bearing_deg(LON0, LAT0)

    def true_deg(grid_deg: float) -> float:
        return (grid_deg - north_grid_deg) % 360.0

    passes: list[FlightPass] = []
    cols: dict[str, list[np.ndarray]] = {k: [] for k in ("p", "l", "x", "y", "h", "look", "tilt")}
    path = [home_xy]
    for p_index, (kind, tilt, look, direction) in enumerate(
        [(PassKind.NADIR, 0.0, None, 0.0), (PassKind.OBLIQUE, 30.0, 90.0, 90.0)]
    ):
        lines: list[FlightLine] = []
        for k in range(lines_per_pass):
            forward = k % 2 == 0
            if direction == 0.0:
                x = cx + (k + 0.5) * width_m / lines_per_pass
                y0, y1 = (cy, cy + height_m) if forward else (cy + height_m, cy)
                start, end = (x, y0), (x, y1)
                heading = 0.0 if forward else 180.0
                step = np.array([0.0, 1.0 if forward else -1.0])
            else:
                y = cy + (k + 0.5) * height_m / lines_per_pass
                x0, x1 = (cx, cx + width_m) if forward else (cx + width_m, cx)
                start, end = (x0, y), (x1, y)
                heading = 90.0 if forward else 270.0
                step = np.array([1.0 if forward else -1.0, 0.0])
            entry = (start[0] - 10 * step[0], start[1] - 10 * step[1])
            exit_ = (end[0] + 10 * step[0], end[1] + 10 * step[1])
            lines.append(
                FlightLine(
                    pass_index=p_index,
                    line_index=k,
                    start_xy_m=start,
                    end_xy_m=end,
                    entry_xy_m=entry,
                    exit_xy_m=exit_,
                    heading_deg=true_deg(heading),
                )
            )
            path += [entry, exit_]
            length = math.hypot(end[0] - start[0], end[1] - start[1])
            s = np.arange(0.0, length + 1e-9, trigger_distance_m)
            cols["p"].append(np.full(s.size, p_index))
            cols["l"].append(np.full(s.size, k))
            cols["x"].append(start[0] + s * step[0])
            cols["y"].append(start[1] + s * step[1])
            cols["h"].append(np.full(s.size, heading))
            cols["look"].append(np.full(s.size, heading if look is None else look))
            cols["tilt"].append(np.full(s.size, tilt))
        gsd = CANON_350D.gsd_cm(alt_m) / math.cos(math.radians(tilt))
        passes.append(
            FlightPass(
                index=p_index,
                kind=kind,
                name="nadir" if look is None else f"oblique {tilt:g} deg looking {look:g} deg",
                direction_deg=true_deg(direction) % 180.0,
                tilt_deg=tilt,
                look_heading_deg=None if look is None else true_deg(look),
                alt_agl_m=alt_m,
                line_spacing_m=spacing_m,
                trigger_distance_m=trigger_distance_m,
                lines=tuple(lines),
                near_gsd_cm=gsd * 0.9,
                far_gsd_cm=gsd * 1.2,
            )
        )
    path.append(home_xy)
    c = {k: np.concatenate(v) for k, v in cols.items()}
    n = c["x"].shape[0]
    corners = np.empty((n, 4, 2))
    for tilt in np.unique(c["tilt"]):
        sel = c["tilt"] == tilt
        corners[sel] = ray_cast_footprints(
            c["x"][sel], c["y"][sel], alt_m, c["look"][sel], float(tilt), CANON_350D
        )
    lon, lat = frame.to_lonlat(c["x"], c["y"])
    clon, clat = frame.to_lonlat(corners[..., 0].ravel(), corners[..., 1].ravel())
    stations = Stations(
        pass_index=c["p"].astype(np.int32),
        line_index=c["l"].astype(np.int32),
        x_m=c["x"],
        y_m=c["y"],
        lon_deg=lon,
        lat_deg=lat,
        alt_rel_home_m=np.full(n, alt_m),
        alt_agl_m=np.full(n, alt_m),
        heading_deg=(c["h"] - north_grid_deg) % 360.0,
        look_heading_deg=(c["look"] - north_grid_deg) % 360.0,
        tilt_deg=c["tilt"],
        gsd_cm=100
        * CANON_350D.pixel_pitch_x_mm
        * alt_m
        / (CANON_350D.focal_length_mm * np.cos(np.radians(c["tilt"]))),
        footprint_xy_m=corners,
        footprint_lonlat_deg=np.stack([clon, clat], -1).reshape(n, 4, 2),
    )
    path_xy = np.array(path, dtype=float)
    plon, plat = frame.to_lonlat(path_xy[:, 0], path_xy[:, 1])
    hlon, hlat = (float(v) for v in frame.to_lonlat(*home_xy))
    home = HomePosition(lat_deg=hlat, lon_deg=hlon, alt_amsl_m=home_alt_amsl_m)
    items = [
        MissionItem.takeoff(hlat, hlon, 30.0),
        MissionItem.change_speed(8.0),
        MissionItem.gimbal_pitch_yaw(-90.0, 0.0),
    ]
    for fp in passes:
        for ln in fp.lines:
            (elon, elat), (xlon, xlat) = (
                (float(a) for a in frame.to_lonlat(*ln.entry_xy_m)),
                (float(a) for a in frame.to_lonlat(*ln.exit_xy_m)),
            )
            items += [
                MissionItem.waypoint(elat, elon, alt_m),
                MissionItem.cam_trigger_distance(trigger_distance_m),
                MissionItem.waypoint(xlat, xlon, alt_m),
                MissionItem.cam_trigger_distance(0.0, trigger_now=False),
            ]
    items.append(MissionItem.return_to_launch())
    mission = Mission(items=tuple(items), home=home, autopilot=Autopilot.ARDUPILOT)
    footprint = CANON_350D.footprint(alt_m, Orientation.LANDSCAPE)
    line_count = sum(len(p.lines) for p in passes)
    summary = Summary(
        name=name,
        area_m2=float(area_xy.area),
        camera_id=CANON_350D.id,
        orientation="landscape",
        gsd_cm=CANON_350D.gsd_cm(alt_m),
        gsd_along_cm=CANON_350D.gsd_y_cm(alt_m),
        gsd_across_cm=CANON_350D.gsd_x_cm(alt_m),
        altitude_agl_m=alt_m,
        scale_number=CANON_350D.scale_number(alt_m),
        footprint_along_m=footprint.along_m,
        footprint_across_m=footprint.across_m,
        front_overlap_pct=80.0,
        side_overlap_pct=70.0,
        air_base_m=trigger_distance_m,
        line_spacing_m=spacing_m,
        trigger_distance_m=trigger_distance_m,
        exposure_interval_s=trigger_distance_m / 8.0,
        speed_m_s=8.0,
        max_speed_m_s=11.0,
        max_speed_trigger_m_s=11.0,
        max_speed_blur_m_s=None,
        base_height_ratio=trigger_distance_m / alt_m,
        intersection_angle_deg=8.3,
        depth_precision_m=0.05,
        direction_deg=0.0,
        pass_count=len(passes),
        line_count=line_count,
        photo_count=n,
        flight_distance_m=float(np.sum(np.hypot(*np.diff(path_xy, axis=0).T))),
        flight_time_s=600.0,
        item_count=len(items),
        crs=frame.crs.to_string(),
    )
    return SurveyPlan(
        name=name,
        camera=CANON_350D,
        orientation=Orientation.LANDSCAPE,
        frame=frame,
        area_xy=area_xy,
        area_lonlat=frame.geometry_to_lonlat(area_xy),
        exclusions_xy=exclusions_xy,
        exclusions_lonlat=tuple(frame.geometry_to_lonlat(z) for z in exclusions_xy),
        home=home,
        home_xy_m=home_xy,
        passes=tuple(passes),
        stations=stations,
        path_xy_m=path_xy,
        path_lonlat_deg=np.column_stack([plon, plat]),
        mission=mission,
        summary=summary,
    )


@pytest.fixture(scope="module")
def plan() -> SurveyPlan:
    return make_plan()


def _ring_is_ccw(coords: list[list[float]]) -> bool:
    c = np.asarray(coords)
    x, y = c[:, 0], c[:, 1]
    return float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1])) > 0


# --- number formatting ---------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(
    hst.lists(
        hst.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False),
        min_size=1,
        max_size=30,
    ),
    hst.integers(min_value=0, max_value=8),
)
def test_fixed_point_parses_back_to_the_rounded_value(values: list[float], decimals: int) -> None:
    table = _fixed_point(np.array(values), decimals, what="x")
    for value, row in zip(values, table, strict=True):
        text = bytes(row[row != 0]).decode()
        parsed = json.loads(text)
        assert isinstance(parsed, int | float)
        assert abs(parsed - value) <= 0.5 * 10**-decimals * (1 + 1e-9) + abs(value) * 1e-15
        # shortest fixed-point text: no leading zeros, no trailing fraction zeros, no "-0"
        assert re.fullmatch(r"-?(0|[1-9][0-9]*)(\.[0-9]*[1-9])?", text), text
        assert len(text.partition(".")[2]) <= decimals
        assert text != "-0"


def test_non_finite_value_is_refused_with_its_row() -> None:
    with pytest.raises(PlanningError, match="row 2"):
        _fixed_point(np.array([1.0, 2.0, np.nan]), 3, what="station GSD")


def test_counter_clockwise_corners_turns_only_clockwise_rings() -> None:
    cw = np.array([[[0, 1], [1, 1], [1, 0], [0, 0]]], dtype=float)  # NW, NE, SE, SW
    ccw = cw[:, ::-1]
    out = counter_clockwise_corners(np.concatenate([cw, ccw]))
    for ring in out:
        closed = np.vstack([ring, ring[:1]])
        assert _ring_is_ccw(closed.tolist())
    np.testing.assert_array_equal(out[1], ccw[0])


# --- GeoJSON -------------------------------------------------------------------------------


def test_stations_geojson_positions_and_properties(plan: SurveyPlan, tmp_path: Path) -> None:
    path = write_stations_geojson(plan, tmp_path / "stations.geojson")
    doc = json.loads(path.read_text(encoding="utf-8"))
    assert doc["type"] == "FeatureCollection"
    st = plan.stations
    feats = doc["features"]
    assert len(feats) == len(st) > 20
    lon = np.array([f["geometry"]["coordinates"][0] for f in feats])
    lat = np.array([f["geometry"]["coordinates"][1] for f in feats])
    # lon/lat order, to 1e-8 deg; lon around -1.5 and lat around 42.2 cannot be swapped
    np.testing.assert_allclose(lon, st.lon_deg, atol=0.51e-8, rtol=0)
    np.testing.assert_allclose(lat, st.lat_deg, atol=0.51e-8, rtol=0)
    assert np.all(np.abs(lon - LON0) < 0.01) and np.all(np.abs(lat - LAT0) < 0.01)
    west, south, east, north = doc["bbox"]
    assert west <= lon.min() and east >= lon.max() and south <= lat.min() and north >= lat.max()
    for k in (0, len(feats) // 2, len(feats) - 1):
        props = feats[k]["properties"]
        assert props["station"] == feats[k]["id"] == k
        assert props["pass"] == st.pass_index[k] and props["line"] == st.line_index[k]
        assert props["kind"] == plan.passes[int(st.pass_index[k])].kind.value
        assert props["lat_deg"] == feats[k]["geometry"]["coordinates"][1]
        assert props["alt_rel_home_m"] == pytest.approx(st.alt_rel_home_m[k], abs=0.005)
        assert props["alt_agl_m"] == pytest.approx(st.alt_agl_m[k], abs=0.005)
        assert props["heading_deg"] == pytest.approx(st.heading_deg[k], abs=0.005)
        assert props["look_heading_deg"] == pytest.approx(st.look_heading_deg[k], abs=0.005)
        assert props["tilt_deg"] == pytest.approx(st.tilt_deg[k], abs=0.005)
        assert props["gsd_cm"] == pytest.approx(st.gsd_cm[k], abs=0.0005)
    # the distance between two stations on one line is the trigger distance, on the ellipsoid
    a, b = feats[0]["properties"], feats[1]["properties"]
    assert a["line"] == b["line"]
    d = geodesic_distance_m(a["lat_deg"], a["lon_deg"], b["lat_deg"], b["lon_deg"])
    assert d == pytest.approx(plan.passes[0].trigger_distance_m, rel=2e-3)  # UTM scale error


@pytest.mark.parametrize("bad_index", [7, -1, 2**31 - 1])
def test_stations_of_a_pass_the_plan_does_not_hold_are_refused(
    plan: SurveyPlan, tmp_path: Path, bad_index: int
) -> None:
    """A station whose pass index is not one of the plan's passes (beyond them, negative) is a
    planner bug named as such, and nothing is written."""
    pass_index = plan.stations.pass_index.copy()
    pass_index[len(pass_index) // 2] = bad_index
    broken = dataclasses.replace(plan, stations=dataclasses.replace(plan.stations, pass_index=pass_index))
    target = tmp_path / "stations.geojson"
    with pytest.raises(PlanningError, match=rf"stations refer to pass \[{bad_index}\]"):
        write_stations_geojson(broken, target)
    assert not target.exists()


def test_footprints_geojson_valid_ccw_and_at_the_stations(plan: SurveyPlan, tmp_path: Path) -> None:
    path = write_footprints_geojson(plan, tmp_path / "footprints.geojson")
    doc = json.loads(path.read_text(encoding="utf-8"))
    feats = doc["features"]
    st = plan.stations
    assert len(feats) == len(st)
    for k, f in enumerate(feats):
        ring = f["geometry"]["coordinates"][0]
        assert len(ring) == 5 and ring[0] == ring[-1]
        assert _ring_is_ccw(ring), f"footprint {k} is clockwise"
        poly = shape(f["geometry"])
        assert poly.is_valid
        # the corners written are the plan's corners (in some order), lon first
        corners = st.footprint_lonlat_deg[k]
        for c in ring[:4]:
            assert np.min(np.hypot(*(corners - np.array(c)).T)) < 1e-8
        # a nadir footprint is centred on its station; an oblique one lies toward its look
        centre = plan.frame.to_xy(*poly.centroid.coords[0])
        dx, dy = float(centre[0]) - st.x_m[k], float(centre[1]) - st.y_m[k]
        if st.tilt_deg[k] == 0:
            assert math.hypot(dx, dy) < 0.01
        else:
            bearing = math.degrees(math.atan2(dx, dy)) % 360
            # the grid bearing of the look direction is its true bearing + grid convergence
            grid_look = st.look_heading_deg[k] + plan.frame.true_north_grid_bearing_deg(LON0, LAT0)
            assert bearing == pytest.approx(grid_look, abs=0.05)
        assert f["properties"]["station"] == k
    # oblique footprints are trapezoids: the far edge is longer than the near one
    k_obl = int(np.flatnonzero(st.tilt_deg > 0)[0])
    xy = st.footprint_xy_m[k_obl]
    top, bottom = np.hypot(*(xy[1] - xy[0])), np.hypot(*(xy[2] - xy[3]))
    assert top > 1.3 * bottom


def test_flight_lines_geojson(plan: SurveyPlan, tmp_path: Path) -> None:
    path = write_flight_lines_geojson(plan, tmp_path / "flight_lines.geojson")
    doc = json.loads(path.read_text(encoding="utf-8"))
    feats = doc["features"]
    lines = [ln for p in plan.passes for ln in p.lines]
    assert len(feats) == len(lines) == plan.summary.line_count
    for f, ln in zip(feats, lines, strict=True):
        geom = shape(f["geometry"])
        assert geom.geom_type == "LineString" and geom.is_valid
        props = f["properties"]
        assert (props["pass"], props["line"]) == (ln.pass_index, ln.line_index)
        assert props["kind"] == plan.passes[ln.pass_index].kind.value
        assert props["heading_deg"] == pytest.approx(ln.heading_deg, abs=0.005)
        assert props["length_m"] == pytest.approx(ln.length_m, abs=0.001)
        assert props["lead_in_m"] == pytest.approx(10.0, abs=0.001)
        (lon0, lat0), (lon1, lat1) = f["geometry"]["coordinates"]
        assert geodesic_distance_m(lat0, lon0, lat1, lon1) == pytest.approx(ln.length_m, rel=2e-3)
        x0, y0 = plan.frame.to_xy(lon0, lat0)
        assert math.hypot(float(x0) - ln.start_xy_m[0], float(y0) - ln.start_xy_m[1]) < 0.002
    assert feats[-1]["properties"]["pass_name"] == plan.passes[-1].name


def test_area_geojson_holes_and_exclusions(plan: SurveyPlan, tmp_path: Path) -> None:
    path = write_area_geojson(plan, tmp_path / "area.geojson")
    doc = json.loads(path.read_text(encoding="utf-8"))
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds == ["area"] + ["exclusion"] * len(plan.exclusions_lonlat)
    area = shape(doc["features"][0]["geometry"])
    assert area.is_valid
    # rounding to 1e-8 deg moves the boundary by at most half of that
    assert area.symmetric_difference(plan.area_lonlat).area < 1e-8 * plan.area_lonlat.length
    polys = [area] if area.geom_type == "Polygon" else list(area.geoms)
    for poly_json in (
        [doc["features"][0]["geometry"]["coordinates"]]
        if area.geom_type == "Polygon"
        else doc["features"][0]["geometry"]["coordinates"]
    ):
        assert _ring_is_ccw(poly_json[0])
        for hole in poly_json[1:]:
            assert not _ring_is_ccw(hole)
    assert sum(len(p.interiors) for p in polys) >= 1  # the hole survives as an interior ring
    zones = [shape(f["geometry"]) for f in doc["features"][1:]]
    for zone, expected in zip(zones, plan.exclusions_lonlat, strict=True):
        assert zone.is_valid
        assert zone.symmetric_difference(expected).area < 1e-8 * expected.length
    # the area does not overlap any exclusion zone
    assert area.intersection(unary_union(zones)).area < 1e-9 * area.area
    assert doc["features"][0]["properties"]["area_m2"] == pytest.approx(plan.area_xy.area, abs=0.01)


def test_geojson_writes_are_atomic_and_escape_names(plan: SurveyPlan, tmp_path: Path) -> None:
    target = tmp_path / "out" / "flight_lines.geojson"
    write_flight_lines_geojson(plan, target)
    write_flight_lines_geojson(plan, target)  # a rewrite replaces the file
    assert sorted(p.name for p in target.parent.iterdir()) == ["flight_lines.geojson"]
    doc = json.loads(target.read_text(encoding="utf-8"))
    assert doc["name"].startswith("Bardenas <gully> & co")


def test_empty_plan_still_writes_valid_geojson(tmp_path: Path) -> None:
    full = make_plan(lines_per_pass=1)
    st = full.stations
    empty = Stations(
        **{
            name: getattr(st, name)[:0]
            for name in st.__dataclass_fields__  # every column, no rows
        }
    )
    plan = SurveyPlan(**{**{f: getattr(full, f) for f in full.__dataclass_fields__}, "stations": empty})
    for writer in (write_stations_geojson, write_footprints_geojson):
        doc = json.loads(writer(plan, tmp_path / f"{writer.__name__}.json").read_text())
        assert doc["features"] == [] and "bbox" not in doc
    root = ET.parse(write_kml(plan, tmp_path / "m.kml")).getroot()
    assert "All 0 exposure stations." in [f.findtext(_k("description")) for f in root.iter(_k("Folder"))]
    assert mpimg.imread(render_map_png(plan, tmp_path / "map.png")).shape[0] > 500


# --- KML -----------------------------------------------------------------------------------


def _k(tag: str) -> str:
    return f"{{{KML_NS}}}{tag}"


def _children(element: ET.Element) -> list[str]:
    return [child.tag.removeprefix(f"{{{KML_NS}}}") for child in element]


def _parse_coords(text: str) -> np.ndarray:
    return np.array([[float(v) for v in t.split(",")] for t in text.split()])


def test_kml_structure_and_placemarks(plan: SurveyPlan, tmp_path: Path) -> None:
    path = write_kml(plan, tmp_path / "mission.kml")
    assert path.read_bytes().startswith(b"<?xml")
    root = ET.parse(path).getroot()
    assert root.tag == _k("kml")
    doc = root.find(_k("Document"))
    assert doc is not None
    assert doc.findtext(_k("name")) == plan.name  # "<" and "&" survive the round trip
    folders = {f.findtext(_k("name")): f for f in doc.findall(_k("Folder"))}
    assert list(folders) == ["Area", "Flight path", "Survey lines", "Stations"]
    # Document: Feature elements and styles before the folders (KML 2.2 schema order)
    order = _children(doc)
    assert order.index("LookAt") < order.index("Style") < order.index("Folder")
    assert max(i for i, t in enumerate(order) if t == "Style") < order.index("Folder")
    # every placemark: name, [description], styleUrl, then exactly one geometry, last
    geometries = {"Point", "LineString", "Polygon", "MultiGeometry"}
    marks = list(root.iter(_k("Placemark")))
    for mark in marks:
        tags = _children(mark)
        assert tags[0] == "name" and tags[-1] in geometries
        assert sum(t in geometries for t in tags) == 1
        assert tags.index("styleUrl") == len(tags) - 2
        if "description" in tags:
            assert tags.index("description") < tags.index("styleUrl")
        style = mark.findtext(_k("styleUrl"))
        assert style is not None and doc.find(f"{_k('Style')}[@id='{style[1:]}']") is not None
    for coords in root.iter(_k("coordinates")):
        xyz = _parse_coords(coords.text or "")
        assert xyz.shape[1] == 3  # "lon,lat,alt"
        assert np.all(np.abs(xyz[:, 0] - LON0) < 0.02) and np.all(np.abs(xyz[:, 1] - LAT0) < 0.02)

    area_marks = folders["Area"].findall(_k("Placemark"))
    assert [m.findtext(_k("styleUrl")) for m in area_marks] == ["#area"] + ["#exclusion"] * len(
        plan.exclusions_lonlat
    )
    assert len(list(area_marks[0].iter(_k("innerBoundaryIs")))) >= 1  # the hole
    for ring in area_marks[0].iter(_k("LinearRing")):
        xyz = _parse_coords(ring.findtext(_k("coordinates")) or "")
        assert np.array_equal(xyz[0], xyz[-1])

    lines_folder = folders["Survey lines"]
    pass_folders = lines_folder.findall(_k("Folder"))
    assert len(pass_folders) == len(plan.passes)
    for pf, p in zip(pass_folders, plan.passes, strict=True):
        assert len(pf.findall(_k("Placemark"))) == len(p.lines)

    stations = folders["Stations"].findall(_k("Placemark"))
    assert len(stations) == len(plan.stations)  # a small plan: all of them
    k = 5
    xyz = _parse_coords(stations[k].findtext(f"{_k('Point')}/{_k('coordinates')}") or "")
    assert xyz[0, 0] == pytest.approx(plan.stations.lon_deg[k], abs=1e-8)
    assert xyz[0, 1] == pytest.approx(plan.stations.lat_deg[k], abs=1e-8)
    # home AMSL is known: absolute altitude = home AMSL + altitude above home
    mode = stations[k].find(f"{_k('Point')}/{_k('altitudeMode')}")
    assert mode is not None and mode.text == "absolute"
    assert xyz[0, 2] == pytest.approx(plan.home.alt_amsl_m + plan.stations.alt_rel_home_m[k], abs=0.01)

    top_names = [m.findtext(_k("name")) for m in doc.findall(_k("Placemark"))]
    assert top_names == ["Home", "Entry"]


_TEXTS = hst.text(alphabet="ab &<>\"'\n\t\r\u00e9\u6f22", max_size=6)
_PLAIN = hst.text(alphabet="ab -#\u00e9\u6f22", max_size=6)


@hst.composite
def _kml_trees(draw: hst.DrawFn, depth: int = 0) -> ET.Element:
    """What kml_document builds: KML tags, plain attributes, texts (whitespace-only too)."""
    element = ET.Element(f"{{{KML_NS}}}{draw(hst.sampled_from(['Folder', 'name', 'Placemark', 'Point']))}")
    if draw(hst.booleans()):
        element.set("id", draw(_PLAIN))
    element.text = draw(hst.none() | _TEXTS | hst.just("   \n "))
    if depth < 3:
        element.extend(draw(hst.lists(_kml_trees(depth + 1), max_size=3)))
    return element


def _spoil(element: ET.Element, how: str, text: str) -> None:
    """One thing kml_document never builds, for the general writer to take."""
    if how == "tail":
        element.tail = text or "x"
    elif how == "escaped attribute":
        element.set("id", text + "&")
    elif how == "namespaced attribute":
        element.set("{urn:other}a", text)
    elif how == "other namespace":
        element.tag = "{urn:other}x"
    else:
        element.tag = "plain"


@settings(max_examples=200, deadline=None)
@given(
    children=hst.lists(_kml_trees(), max_size=4),
    spoil=hst.none()
    | hst.tuples(
        hst.integers(0, 200),
        hst.sampled_from(["tail", "escaped attribute", "namespaced attribute", "other namespace", "none"]),
        _TEXTS,
    ),
)
def test_kml_serialiser_writes_what_elementtree_writes(
    children: list[ET.Element], spoil: tuple[int, str, str] | None
) -> None:
    """mission.kml's own writer against ElementTree's (indent by one space, KML the default
    namespace) on random trees: texts and attributes that need escaping, whitespace-only texts,
    tails, tags and attributes in another namespace or none; the tree is not changed."""
    root = ET.Element(f"{{{KML_NS}}}kml")
    doc = ET.SubElement(root, f"{{{KML_NS}}}Document")
    doc.extend(children)
    if spoil is not None:
        elements = list(doc.iter())
        _spoil(elements[spoil[0] % len(elements)], spoil[1], spoil[2])

    def shape(e: ET.Element) -> tuple[object, ...]:
        return (e.tag, e.text, e.tail, dict(e.attrib), [shape(c) for c in e])

    before = shape(root)
    expected_tree = copy.deepcopy(root)
    ET.register_namespace("", KML_NS)
    ET.indent(expected_tree, space=" ")
    assert serialise(root) == ET.tostring(expected_tree, encoding="unicode")
    assert shape(root) == before


def test_kml_flight_path_follows_the_mission(plan: SurveyPlan, tmp_path: Path) -> None:
    root = ET.parse(write_kml(plan, tmp_path / "m.kml")).getroot()
    folder = next(f for f in root.iter(_k("Folder")) if f.findtext(_k("name")) == "Flight path")
    line = folder.find(f"{_k('Placemark')}/{_k('LineString')}")
    assert line is not None
    xyz = _parse_coords(line.findtext(_k("coordinates")) or "")
    nav = [it for it in plan.mission.items if it.command in (MavCmd.NAV_TAKEOFF, MavCmd.NAV_WAYPOINT)]
    # home on the ground, every positional item, back over home, landed
    assert len(xyz) == 1 + len(nav) + 2
    amsl = plan.home.alt_amsl_m
    assert xyz[0, 2] == pytest.approx(amsl) and xyz[-1, 2] == pytest.approx(amsl)
    for row, item in zip(xyz[1:-2], nav, strict=True):
        assert row[0] == pytest.approx(item.lon_deg, abs=1e-8)
        assert row[1] == pytest.approx(item.lat_deg, abs=1e-8)
        assert row[2] == pytest.approx(amsl + item.alt_m, abs=0.01)


def test_kml_without_home_altitude_is_relative_to_ground_and_says_so(tmp_path: Path) -> None:
    plan = make_plan(home_alt_amsl_m=0.0)
    root = ET.parse(write_kml(plan, tmp_path / "m.kml")).getroot()
    doc = root.find(_k("Document"))
    assert doc is not None
    assert "unknown" in (doc.findtext(_k("description")) or "")
    airborne = [
        el.findtext(_k("altitudeMode")) for el in root.iter() if el.tag in (_k("Point"), _k("LineString"))
    ]
    assert "absolute" not in airborne and "relativeToGround" in airborne
    # a home altitude given by the caller makes them absolute again
    root = ET.parse(write_kml(plan, tmp_path / "m2.kml", home_alt_amsl_m=400.0)).getroot()
    point = next(root.iter(_k("Point")))
    assert point.findtext(_k("altitudeMode")) == "absolute"
    xyz = _parse_coords(point.findtext(_k("coordinates")) or "")
    assert xyz[0, 2] == pytest.approx(400.0 + plan.stations.alt_rel_home_m[0], abs=0.01)


def test_kml_thins_stations_and_says_so(plan: SurveyPlan, tmp_path: Path) -> None:
    n = len(plan.stations)
    step = math.ceil(n / 10)
    root = ET.parse(write_kml(plan, tmp_path / "m.kml", max_stations=10)).getroot()
    folder = next(f for f in root.iter(_k("Folder")) if f.findtext(_k("name")) == "Stations")
    marks = folder.findall(_k("Placemark"))
    assert len(marks) == len(range(0, n, step)) <= 10
    about = folder.findtext(_k("description")) or ""
    assert f"Every {step}th of the {n}" in about and f"({len(marks)} shown)" in about
    names = [int(m.findtext(_k("name")) or -1) for m in marks]
    assert names == list(range(0, n, step))  # every k-th in flight order
    marks_none = ET.parse(write_kml(plan, tmp_path / "m0.kml", max_stations=0)).getroot()
    assert not [m for m in marks_none.iter(_k("Placemark")) if m.findtext(_k("styleUrl")) == "#station"]


# --- map.png -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("span_m", "expected_m"),
    [(1000, 200), (999, 200), (400, 100), (79, 10), (81, 20), (12_000, 2000), (0.9, 0.2)],
)
def test_scale_bar_is_round(span_m: float, expected_m: float) -> None:
    assert scale_bar_length_m(span_m) == pytest.approx(expected_m)


def test_map_png_is_drawn(plan: SurveyPlan, tmp_path: Path) -> None:
    path = render_map_png(plan, tmp_path / "map.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(path)
    h, w = img.shape[:2]
    assert 600 <= w <= 3000 and 500 <= h <= 3000
    rgb = img[..., :3]
    background = np.all(rgb > 0.99, axis=-1)
    assert 0.05 < 1 - background.mean() < 0.9  # something drawn, not all ink

    # the area's light green, the exclusion red and the nadir blue are all on the map
    def has(colour: str, tol: float = 0.06) -> bool:
        c = np.array([int(colour[i : i + 2], 16) / 255 for i in (1, 3, 5)])
        return bool(np.any(np.all(np.abs(rgb - c) < tol, axis=-1)))

    assert has("#e3f1d4") and has("#d32f2f", 0.1) and has("#1565c0", 0.1) and has("#ef6c00", 0.1)


def test_map_legend_scale_bar_and_north_arrow_say_what_is_drawn(plan: SurveyPlan) -> None:
    fig = render_map_figure(plan, max_footprints=7)
    ax = fig.axes[0]
    legend = ax.get_legend()
    assert legend is not None
    labels = [t.get_text() for t in legend.get_texts()]
    n = len(plan.stations)
    assert f"frame footprints: every 15th of\n{n} shown (7)" in labels
    assert f"exposure stations (all {n})" in labels
    assert any(label.startswith("camera on, oblique (4 lines)") for label in labels)
    assert len(ax.collections[0].get_paths()) == 7  # the footprint outlines drawn
    texts = [t.get_text() for t in ax.texts]
    x0, x1 = ax.get_xlim()
    assert f"{scale_bar_length_m(x1 - x0):g} m" in texts
    assert "N" in texts  # the north arrow's letter
    caption = " ".join(t.get_text() for t in fig.texts)
    assert f"EPSG:{plan.frame.epsg}" in caption and "grid north" in caption
    assert ax.get_aspect() == 1.0
    assert ordinal(1) == "1st" and ordinal(2) == "2nd" and ordinal(13) == "13th"
    assert ordinal(22) == "22nd" and ordinal(111) == "111th"


def test_map_png_large_plan_is_thinned(tmp_path: Path) -> None:
    big = make_plan(lines_per_pass=40, line_length_m=2000.0, trigger_distance_m=2.0)
    assert len(big.stations) > 40_000
    render_map_png(big, tmp_path / "map.png", max_footprints=500)
    fig_img = mpimg.imread(tmp_path / "map.png")
    assert fig_img.shape[0] > 500


# --- the real planner's plans (when the planner is there) -----------------------------------

MISSIONS = sorted((Path(__file__).resolve().parents[2] / "missions").glob("*.toml"))


@pytest.mark.parametrize("mission", MISSIONS, ids=[m.stem for m in MISSIONS])
def test_writers_on_planned_missions(mission: Path, tmp_path: Path) -> None:
    from planner.spec import load_spec
    from planner.survey import plan_survey

    real = plan_survey(load_spec(mission))
    n = len(real.stations)
    assert n == real.summary.photo_count

    stations = json.loads(write_stations_geojson(real, tmp_path / "s.geojson").read_text())
    footprints = json.loads(write_footprints_geojson(real, tmp_path / "f.geojson").read_text())
    lines = json.loads(write_flight_lines_geojson(real, tmp_path / "l.geojson").read_text())
    area = json.loads(write_area_geojson(real, tmp_path / "a.geojson").read_text())
    assert len(stations["features"]) == len(footprints["features"]) == n
    assert len(lines["features"]) == sum(len(p.lines) for p in real.passes)
    area_shape = shape(area["features"][0]["geometry"])
    assert area_shape.is_valid
    # every station lies over (or near: turnarounds, oblique offsets) the area it surveys
    reach_deg = 0.02
    west, south, east, north = area_shape.bounds
    for f in stations["features"][:: max(1, n // 200)]:
        lon, lat = f["geometry"]["coordinates"]
        assert west - reach_deg < lon < east + reach_deg and south - reach_deg < lat < north + reach_deg
    for f in footprints["features"][:: max(1, n // 500)]:
        ring = f["geometry"]["coordinates"][0]
        assert _ring_is_ccw(ring) and shape(f["geometry"]).is_valid

    root = ET.parse(write_kml(real, tmp_path / "m.kml")).getroot()
    assert root.tag == _k("kml")
    shown = len(range(0, n, max(1, math.ceil(n / 2000))))
    stations_folder = next(f for f in root.iter(_k("Folder")) if f.findtext(_k("name")) == "Stations")
    assert len(stations_folder.findall(_k("Placemark"))) == shown

    img = mpimg.imread(render_map_png(real, tmp_path / "map.png"))
    assert np.mean(np.all(img[..., :3] > 0.99, axis=-1)) < 0.95
