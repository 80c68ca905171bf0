"""Corridor surveys (planner.corridor), checked on random centre lines with bends (hypothesis):

- every point within half the width of the centre line (flat ends) is seen by at least two
  planned footprints (stereo), edges included; the footprints are the camera model's ground
  corners, counted with shapely, and the corridor is built here from distances to the line;
- the camera is never on over an exclusion (no station, no camera-on leg in a zone);
- each camera-on run follows the bearing of a segment of the centre line, and the photos an
  autopilot takes flying the items are the planned stations;
- bad centre lines are refused with the fix; a corridor narrower than a frame is one line.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import shapely
from click.testing import CliRunner
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Polygon
from survey_oracles import replay_at_loop_rate, views

from planner.errors import AreaError, SpecError
from planner.mission import MavCmd
from planner.plan import SurveyPlan
from planner.spec import parse_spec
from planner.survey import plan_survey
from sfap.cli import cli

LON0, LAT0 = -1.49, 42.20
M_PER_DEG_LAT = 111_132.0
M_PER_DEG_LON = 111_320.0 * math.cos(math.radians(LAT0))


def lonlat(xy: list[tuple[float, float]]) -> list[list[float]]:
    return [[LON0 + x / M_PER_DEG_LON, LAT0 + y / M_PER_DEG_LAT] for x, y in xy]


def write_line(folder: Path, xy: list[tuple[float, float]], name: str = "centre.geojson") -> Path:
    path = folder / name
    feature = {
        "type": "Feature",
        "properties": {},
        "geometry": {"type": "LineString", "coordinates": lonlat(xy)},
    }
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [feature]}))
    return path


def write_polygon(folder: Path, xy: list[tuple[float, float]], name: str) -> Path:
    ring = lonlat([*xy, xy[0]])
    path = folder / name
    path.write_text(json.dumps({"type": "Polygon", "coordinates": [ring]}))
    return path


def corridor_spec(
    folder: Path,
    width_m: float,
    survey: dict[str, Any] | None = None,
    area: str = "centre.geojson",
    exclude: list[str] | None = None,
    vehicle: dict[str, Any] | None = None,
) -> Any:
    data: dict[str, Any] = {
        "name": "corridor test",
        "area": area,
        "corridor_width_m": width_m,
        "camera": {"model": "dji-phantom-4-pro"},
        "survey": {"gsd_cm": 2.0, "front_overlap_pct": 75, "side_overlap_pct": 65, "speed_m_s": 5.0}
        | (survey or {}),
        "vehicle": {"type": "multirotor", "max_alt_agl_m": 400} | (vehicle or {}),
    }
    if exclude:
        data["exclude"] = exclude
    return parse_spec(data, folder / "spec.toml")


def corridor_points(
    plan: SurveyPlan, xy: list[tuple[float, float]], width_m: float, cell_m: float
) -> np.ndarray:
    """Points of the corridor, built here: within half the width of the centre line (projected
    into the plan's frame) and not beyond its two ends (flat caps), on a grid and along the edges."""
    lon_lat = np.asarray(lonlat(xy))
    x, y = plan.frame.to_xy(lon_lat[:, 0], lon_lat[:, 1])
    line = LineString(np.column_stack([x, y]))
    x0, y0, x1, y1 = line.bounds
    half = width_m / 2.0
    gx, gy = np.meshgrid(np.arange(x0 - half, x1 + half, cell_m), np.arange(y0 - half, y1 + half, cell_m))
    pts = shapely.points(gx.ravel(), gy.ravel())
    # the edges: offsets of the line at +-(half - 1 mm), every metre
    edges = []
    for side in ("left", "right"):
        off = line.offset_curve(half - 1e-3 if side == "left" else -(half - 1e-3), join_style="round")
        for part in getattr(off, "geoms", [off]):
            edges.append(shapely.get_coordinates(part.interpolate(np.arange(0.0, part.length, 1.0))))
    pts = np.concatenate([pts, shapely.points(np.vstack(edges))])
    d = shapely.distance(line, pts)
    s = shapely.line_locate_point(line, pts)
    keep = (d <= half - 1e-3) & (s > 1e-3) & (s < line.length - 1e-3)
    return shapely.get_coordinates(pts[keep])


@st.composite
def bent_line(draw: st.DrawFn) -> list[tuple[float, float]]:
    """A centre line of 2-5 segments, 150-500 m each, bending up to 75 degrees either way."""
    n = draw(st.integers(2, 5))
    heading = draw(st.floats(0, 360))
    points = [(0.0, 0.0)]
    for k in range(n):
        if k:
            heading += draw(st.floats(-75, 75))
        length = draw(st.floats(150, 500))
        x, y = points[-1]
        points.append(
            (x + length * math.sin(math.radians(heading)), y + length * math.cos(math.radians(heading)))
        )
    return points


@settings(
    max_examples=12,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(xy=bent_line(), width=st.floats(20, 160), front=st.sampled_from([70, 80]))
@example(  # a narrow corridor whose bend leaves a sliver that rotated into the line frame was invalid
    xy=[
        (0.0, 0.0),
        (-225.06319509623071, 31.95858861740158),
        (-414.52642245206385, 58.86204272770762),
        (-530.5914999812621, 543.6332180004028),
        (-432.90085011094425, 812.2257956217193),
        (-376.7414385019573, 951.3161277362569),
    ],
    width=21.95703125,
    front=70,
)
def test_random_bent_corridors_are_seen_twice_to_the_edges(
    tmp_path: Path, xy: list[tuple[float, float]], width: float, front: int
) -> None:
    if not LineString(xy).is_simple:
        return
    write_line(tmp_path, xy)
    plan = plan_survey(corridor_spec(tmp_path, width, {"front_overlap_pct": front}))
    st_ = plan.stations
    points = corridor_points(plan, xy, width, 3.0)
    counts = views(st_.footprint_xy_m, points)
    assert counts.min() >= 2, f"{int(np.sum(counts < 2))} corridor points seen by fewer than two frames"
    # every corridor line is flown along the whole corridor: each point of its offset curve is
    # seen by two frames of that line alone (the side overlap is the planned one everywhere)
    lon_lat = np.asarray(lonlat(xy))
    cx, cy = plan.frame.to_xy(lon_lat[:, 0], lon_lat[:, 1])
    centre = LineString(np.column_stack([cx, cy]))
    assert plan.summary.corridor is not None
    for k, offset in enumerate(plan.summary.corridor["line_offsets_m"]):  # type: ignore[arg-type]
        curve = centre.offset_curve(-offset, join_style="round") if abs(offset) > 1e-9 else centre
        along = [
            shapely.get_coordinates(part.interpolate(np.arange(1.0, part.length - 1.0, 2.0)))
            for part in getattr(curve, "geoms", [curve])
        ]
        pts = np.vstack(along)
        s_on = shapely.line_locate_point(centre, shapely.points(pts))
        pts = pts[(s_on > 1.0) & (s_on < centre.length - 1.0)]  # within the flat ends
        own = views(st_.footprint_xy_m[st_.line_index == k], pts)
        assert own.min() >= 2, f"line {k} leaves {int(np.sum(own < 2))} points of its course unseen"
    # each camera-on run follows one segment of the centre line (each segment its own bearing)
    lon_lat = np.asarray(lonlat(xy))
    cx, cy = plan.frame.to_xy(lon_lat[:, 0], lon_lat[:, 1])
    seg_bearings = np.degrees(np.arctan2(np.diff(cx), np.diff(cy))) % 180.0
    for line in plan.passes[0].lines:
        dx, dy = line.end_xy_m[0] - line.start_xy_m[0], line.end_xy_m[1] - line.start_xy_m[1]
        if math.hypot(dx, dy) < 1.0:
            continue
        b = math.degrees(math.atan2(dx, dy)) % 180.0
        gap = np.abs((seg_bearings - b + 90.0) % 180.0 - 90.0)
        assert gap.min() < 3.0, f"a run on bearing {b:.1f} follows no segment ({seg_bearings})"
    # the autopilot's photos are the stations
    assert len(replay_at_loop_rate(plan.mission)) == len(st_)
    # one DO_SET_CAM_TRIGG_DIST on and one off per run
    trig = [i for i in plan.mission.items if int(i.command) == MavCmd.DO_SET_CAM_TRIGG_DIST]
    assert len(trig) == 2 * len(plan.passes[0].lines)


@settings(
    max_examples=8,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(xy=bent_line(), where=st.floats(0.2, 0.8), size=st.floats(10, 40))
def test_camera_never_on_over_an_exclusion(
    tmp_path: Path, xy: list[tuple[float, float]], where: float, size: float
) -> None:
    if not LineString(xy).is_simple:
        return
    line = LineString(xy)
    p = line.interpolate(where, normalized=True)
    zone = [
        (p.x - size, p.y - size),
        (p.x + size, p.y - size),
        (p.x + size, p.y + size),
        (p.x - size, p.y + size),
    ]
    write_line(tmp_path, xy)
    write_polygon(tmp_path, zone, "zone.geojson")
    plan = plan_survey(
        corridor_spec(tmp_path, 80.0, exclude=["zone.geojson"], survey={"exclusion_clearance_m": 2})
    )
    (zone_xy,) = plan.exclusions_xy
    stations = shapely.points(plan.stations.x_m, plan.stations.y_m)
    assert not np.any(shapely.intersects(zone_xy, stations)), "a photo over the exclusion"
    for run in plan.passes[0].lines:
        assert not zone_xy.intersects(LineString([run.start_xy_m, run.end_xy_m])), "camera on over the zone"
    # and what is left of the corridor is seen twice, or the plan says how much is not
    points = corridor_points(plan, xy, 80.0, 4.0)
    points = points[~shapely.contains_xy(zone_xy.buffer(2.0), points[:, 0], points[:, 1])]
    weak = views(plan.stations.footprint_xy_m, points) < 2
    if weak.any():
        assert any("exclusion" in w or "fewer than two" in w for w in plan.warnings)


def test_bends_waste_no_photos_on_the_inside(tmp_path: Path) -> None:
    """A corridor with a 30 degree bend takes about as many photos as its lines are long (the
    runs of the two segments do not both cover the bend), and as many as the straight corridor
    of the same centre-line length give or take the end stations the bend needs."""
    straight = [(0.0, 0.0), (0.0, 800.0)]
    bent = [
        (0.0, 0.0),
        (0.0, 400.0),
        (400.0 * math.sin(math.radians(30)), 400.0 + 400.0 * math.cos(math.radians(30))),
    ]
    counts = []
    for k, xy in enumerate((straight, bent)):
        folder = tmp_path / str(k)
        folder.mkdir()
        write_line(folder, xy)
        plan = plan_survey(corridor_spec(folder, 60.0))
        counts.append((len(plan.stations), len(plan.summary.corridor["line_offsets_m"])))  # type: ignore[index]
    (n_straight, lines_s), (n_bent, lines_b) = counts
    assert lines_s == lines_b
    # per line and bend: at most two photos more than the straight corridor
    assert n_bent <= n_straight + 2 * lines_b, (n_straight, n_bent)


def test_a_long_meander_is_flown_line_by_line(tmp_path: Path) -> None:
    """A 6 km centre line of 25 segments bending up to 35 degrees: as many lines as the width
    needs, no extra rows, and photos about the lines' length over the air base."""
    rng = np.random.default_rng(3)
    heading, xy = 60.0, [(0.0, 0.0)]
    for _ in range(25):
        heading += float(rng.uniform(-35, 35))
        length = float(rng.uniform(150, 350))
        x, y = xy[-1]
        xy.append(
            (x + length * math.sin(math.radians(heading)), y + length * math.cos(math.radians(heading)))
        )
    assert LineString(xy).is_simple
    write_line(tmp_path, xy)
    plan = plan_survey(corridor_spec(tmp_path, 150.0))
    corridor = plan.summary.corridor
    assert corridor is not None
    n = len(corridor["line_offsets_m"])  # type: ignore[arg-type]
    assert n >= 2 and plan.summary.line_count == n
    expected = n * LineString(xy).length / plan.summary.air_base_m
    assert abs(len(plan.stations) - expected) < 0.1 * expected
    # the flight: each line once along the corridor and home (no back-and-forth per segment)
    assert plan.summary.flight_distance_m < (n + 1.5) * LineString(xy).length


def test_a_corridor_narrower_than_a_frame_is_one_line(tmp_path: Path) -> None:
    xy = [(0.0, 0.0), (0.0, 300.0), (200.0, 500.0)]
    write_line(tmp_path, xy)
    plan = plan_survey(corridor_spec(tmp_path, 10.0))
    assert plan.summary.corridor is not None and plan.summary.corridor["single_line"] is True
    assert plan.summary.line_count == 1
    counts = views(plan.stations.footprint_xy_m, corridor_points(plan, xy, 10.0, 1.0))
    assert counts.min() >= 2


def test_kml_and_geojson_centre_lines_plan_the_same(tmp_path: Path) -> None:
    xy = [(0.0, 0.0), (100.0, 300.0), (50.0, 600.0)]
    write_line(tmp_path, xy)
    coords = " ".join(f"{lon},{lat},0" for lon, lat in lonlat(xy))
    (tmp_path / "centre.kml").write_text(
        '<?xml version="1.0"?><kml xmlns="http://www.opengis.net/kml/2.2"><Document><Placemark>'
        f"<LineString><coordinates>{coords}</coordinates></LineString></Placemark></Document></kml>"
    )
    a = plan_survey(corridor_spec(tmp_path, 50.0))
    b = plan_survey(corridor_spec(tmp_path, 50.0, area="centre.kml"))
    assert len(a.stations) == len(b.stations)
    np.testing.assert_allclose(a.stations.x_m, b.stations.x_m, atol=1e-6)


def test_self_crossing_centre_line_is_refused(tmp_path: Path) -> None:
    write_line(tmp_path, [(0.0, 0.0), (300.0, 300.0), (300.0, 0.0), (0.0, 300.0)])
    with pytest.raises(AreaError, match=r"crosses itself near lon .* draw it without crossings"):
        plan_survey(corridor_spec(tmp_path, 40.0))


def test_a_polygon_file_is_not_a_centre_line(tmp_path: Path) -> None:
    write_polygon(tmp_path, [(0, 0), (100, 0), (100, 100)], "centre.geojson")
    with pytest.raises(AreaError, match="holds 0 LineStrings"):
        plan_survey(corridor_spec(tmp_path, 40.0))


def test_corridor_refuses_crosshatch_and_obliques(tmp_path: Path) -> None:
    write_line(tmp_path, [(0.0, 0.0), (0.0, 300.0)])
    with pytest.raises(SpecError, match="remove crosshatch"):
        plan_survey(corridor_spec(tmp_path, 40.0, {"crosshatch": True}))
    oblique = {"oblique": [{"tilt_deg": 30, "headings_deg": [0, 180]}]}
    with pytest.raises(SpecError, match=r"remove \[\[survey.oblique\]\]"):
        plan_survey(corridor_spec(tmp_path, 40.0, oblique))


def test_cli_self_crossing_exits_2_and_writes_nothing(tmp_path: Path) -> None:
    write_line(tmp_path, [(0.0, 0.0), (300.0, 300.0), (300.0, 0.0), (0.0, 300.0)])
    (tmp_path / "spec.toml").write_text(
        'area = "centre.geojson"\ncorridor_width_m = 40\n[camera]\nmodel = "dji-phantom-4-pro"\n'
        "[survey]\ngsd_cm = 2.0\n"
    )
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["plan", str(tmp_path / "spec.toml"), "-o", str(out)])
    assert result.exit_code == 2, result.output
    assert "crosses itself" in result.output
    assert not out.exists() or not any(out.iterdir())


def test_corridor_over_terrain_follows_it(tmp_path: Path) -> None:
    """The corridor example's line over the gully DEM: altitudes follow the ground as a block's do."""
    repo = Path(__file__).resolve().parents[2]
    dem = repo / "missions" / "bardenas-gully-dem.tif"
    write_line(tmp_path, [(350.0, 250.0), (500.0, 320.0), (650.0, 300.0)])  # inside the DEM
    data = {
        "name": "t", "area": "centre.geojson", "corridor_width_m": 60,
        "camera": {"model": "dji-phantom-4-pro"},
        "survey": {"gsd_cm": 2.0, "front_overlap_pct": 75, "side_overlap_pct": 65},
        "vehicle": {"max_alt_agl_m": 400},
        "terrain": {"dem": str(dem)},
    }  # fmt: skip
    plan = plan_survey(parse_spec(data, tmp_path / "spec.toml"))
    assert plan.summary.terrain is not None
    terrain = plan.summary.terrain
    target = plan.summary.altitude_agl_m
    # the ground rises by about 8 % eastward and over a hill: the altitudes above home follow it
    assert np.ptp(plan.stations.alt_rel_home_m) > 5.0
    assert abs(float(terrain["station_alt_agl_min_m"]) - target) < 5  # type: ignore[arg-type]
    assert abs(float(terrain["station_alt_agl_max_m"]) - target) < 5  # type: ignore[arg-type]


def test_corridor_polygon_is_not_a_block_polygon(tmp_path: Path) -> None:
    """The corridor is the buffered line, not its convex hull: a U-shaped line's inside is left."""
    xy = [(0.0, 0.0), (0.0, 400.0), (300.0, 400.0), (300.0, 0.0)]
    write_line(tmp_path, xy)
    plan = plan_survey(corridor_spec(tmp_path, 40.0))
    inside = Polygon([(80, 80), (220, 80), (220, 320), (80, 320)])
    lon_lat = np.asarray(lonlat(list(inside.exterior.coords)))
    x, y = plan.frame.to_xy(lon_lat[:, 0], lon_lat[:, 1])
    assert not plan.area_xy.intersects(Polygon(np.column_stack([x, y])))
