"""Terrain following and the spread over terrain, checked on what the vehicle would fly: the
mission's own waypoints (positions and altitudes above home) against the DEM."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest
import rasterio
from hypothesis import given, settings
from hypothesis import strategies as st
from rasterio.transform import from_origin
from survey_oracles import replay_at_loop_rate

from planner.errors import PlanningError, SpecError, TerrainError
from planner.mission import MavCmd
from planner.plan import SurveyPlan
from planner.spec import load_spec
from planner.survey import plan_survey
from planner.terrain import Dem
from planner.terrain_follow import rate_limited_profile

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"


def flown_agl(plan: SurveyPlan, dem: Dem, step_m: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Height above the DEM along the straight legs between the mission's waypoints, from the
    first to the last waypoint (take-off and landing at home excluded), and the leg slopes."""
    home_ground = plan.home.alt_amsl_m
    wps = [it for it in plan.mission.items if it.command == MavCmd.NAV_WAYPOINT]
    lon = np.array([w.lon_deg for w in wps])
    lat = np.array([w.lat_deg for w in wps])
    x, y = plan.frame.to_xy(lon, lat)
    alt = np.array([w.alt_m for w in wps]) + home_ground
    agl = []
    for k in range(len(wps) - 1):
        n = max(1, math.ceil(math.hypot(x[k + 1] - x[k], y[k + 1] - y[k]) / step_m))
        t = np.linspace(0.0, 1.0, n + 1)
        px, py = x[k] + t * (x[k + 1] - x[k]), y[k] + t * (y[k + 1] - y[k])
        agl.append(alt[k] + t * (alt[k + 1] - alt[k]) - dem.elevation_at(px, py, plan.frame))
    legs = np.hypot(np.diff(x), np.diff(y))
    slopes = np.diff(alt)[legs > 1e-6] / legs[legs > 1e-6]
    return np.concatenate(agl), slopes


@pytest.fixture(scope="module")
def terrain_plan() -> SurveyPlan:
    return plan_survey(load_spec(MISSIONS / "bardenas-gully-terrain.toml"))


@pytest.fixture(scope="module")
def dem() -> Dem:
    return Dem.from_geotiff(MISSIONS / "bardenas-gully-dem.tif")


def test_following_keeps_the_height_above_ground(terrain_plan: SurveyPlan, dem: Dem) -> None:
    spec = load_spec(MISSIONS / "bardenas-gully-terrain.toml")
    assert spec.terrain is not None
    target = terrain_plan.summary.altitude_agl_m
    tolerance = spec.terrain.tolerance_m
    agl, slopes = flown_agl(terrain_plan, dem)
    assert agl.min() >= target - tolerance - 0.05
    assert agl.max() <= spec.vehicle.max_alt_agl_m
    # the hill (40 m) is followed: without following the height would vary by tens of metres
    stations_agl = terrain_plan.stations.alt_agl_m
    assert stations_agl.min() >= target - tolerance - 0.05
    assert stations_agl.max() <= target + tolerance + 0.5
    # climbs and descents within the rates at the survey speed
    speed = spec.survey.speed_m_s
    assert slopes.max() <= spec.terrain.max_climb_rate_m_s / speed + 1e-6
    assert slopes.min() >= -spec.terrain.max_descent_rate_m_s / speed - 1e-6
    terrain = terrain_plan.summary.terrain
    assert terrain is not None and int(terrain["waypoints_added"]) > 0  # type: ignore[call-overload]
    # home's elevation comes from the DEM
    hx, hy = terrain_plan.frame.to_xy([terrain_plan.home.lon_deg], [terrain_plan.home.lat_deg])
    home_ground = float(dem.elevation_at(hx, hy, terrain_plan.frame)[0])
    assert terrain_plan.home.alt_amsl_m == pytest.approx(home_ground)


def test_following_spaces_for_the_highest_ground_and_fires_every_station(terrain_plan: SurveyPlan) -> None:
    flat = plan_survey(load_spec(MISSIONS / "bardenas-gully.toml"))
    terrain = terrain_plan.summary.terrain
    assert terrain is not None
    # over the hill the frames are smaller: lines and triggers closer than over flat ground
    assert terrain_plan.summary.line_spacing_m < flat.summary.line_spacing_m
    assert terrain_plan.summary.trigger_distance_m < flat.summary.trigger_distance_m
    assert terrain["footprint_scale"] <= terrain["footprint_scale_min"] + 1e-9  # type: ignore[operator]
    # distance triggering is horizontal: ArduPilot's trigger, replayed at its loop rate, fires
    # as many photos as the plan has stations, each near its station
    fired = replay_at_loop_rate(terrain_plan.mission)
    assert len(fired) == len(terrain_plan.stations)
    x, y = terrain_plan.frame.to_xy(fired[:, 0], fired[:, 1])
    assert np.max(np.hypot(x - terrain_plan.stations.x_m, y - terrain_plan.stations.y_m)) < 5.0


def test_constant_altitude_that_opens_gaps_fails_unless_accepted(tmp_path: Path, dem: Dem) -> None:
    source = (MISSIONS / "bardenas-gully-terrain.toml").read_text().replace("follow = true", "follow = false")
    source = source.replace('"bardenas-gully', f'"{MISSIONS}/bardenas-gully')
    spec_file = tmp_path / "constant.toml"
    spec_file.write_text(source)
    with pytest.raises(
        PlanningError, match=r"-\d+\.\d % side \(a gap between the frames\).*follow = true.*accept_overlap"
    ):
        plan_survey(load_spec(spec_file))
    spec_file.write_text(source.replace("follow = false", "follow = false\naccept_overlap_loss = true"))
    plan = plan_survey(load_spec(spec_file))
    target = plan.summary.altitude_agl_m
    st_ground = dem.elevation_at(plan.stations.x_m, plan.stations.y_m, plan.frame)
    # constant above home: the height above ground is what the DEM says it is
    np.testing.assert_allclose(
        plan.stations.alt_agl_m, target - (st_ground - plan.home.alt_amsl_m), atol=1e-6
    )
    np.testing.assert_allclose(plan.stations.alt_rel_home_m, target, atol=1e-6)
    # the textbook: higher ground is closer to the camera, so its GSD is finer
    high = int(np.argmax(st_ground))
    low = int(np.argmin(st_ground))
    assert plan.stations.gsd_cm[high] < plan.stations.gsd_cm[low]
    assert plan.stations.gsd_cm[high] == pytest.approx(
        plan.camera.gsd_cm(float(plan.stations.alt_agl_m[high])), rel=1e-9
    )
    assert any("a gap between the frames" in w for w in plan.warnings)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    target=st.lists(st.floats(0.0, 200.0), min_size=2, max_size=60),
    climb=st.floats(0.5, 5.0),
    descent=st.floats(0.5, 5.0),
)
def test_rate_limited_profile_is_the_lowest_flyable_one(
    target: list[float], climb: float, descent: float
) -> None:
    s = np.arange(len(target)) * 10.0
    t = np.asarray(target)
    a = rate_limited_profile(s, t, 5.0, climb, descent)
    assert np.all(a >= t - 1e-9)
    slope = np.diff(a) / 10.0
    assert slope.max() <= climb / 5.0 + 1e-9
    assert slope.min() >= -descent / 5.0 - 1e-9
    # lowest: every point is either on the target or held up by a rate limit from a neighbour
    for k in range(len(a)):
        on_target = abs(a[k] - t[k]) < 1e-9
        held = (k > 0 and abs(a[k] - (a[k - 1] - descent / 5.0 * 10.0)) < 1e-9) or (
            k < len(a) - 1 and abs(a[k] - (a[k + 1] - climb / 5.0 * 10.0)) < 1e-9
        )
        assert on_target or held


def test_dem_that_does_not_cover_the_area(tmp_path: Path) -> None:
    tif = tmp_path / "far.tif"
    with rasterio.open(
        tif, "w", driver="GTiff", height=10, width=10, count=1, dtype="float32",
        crs="EPSG:32630", transform=from_origin(100000.0, 4000000.0, 5.0, 5.0),
    ) as d:  # fmt: skip
        d.write(np.zeros((10, 10), "float32"), 1)
    source = (MISSIONS / "bardenas-gully-terrain.toml").read_text()
    spec_file = tmp_path / "far.toml"
    spec_file.write_text(
        source.replace('"bardenas-gully-dem.tif"', f'"{tif}"').replace(
            '"bardenas-gully.geojson"', f'"{MISSIONS}/bardenas-gully.geojson"'
        )
    )
    with pytest.raises(TerrainError, match="does not cover"):
        plan_survey(load_spec(spec_file))


def test_terrain_spec_errors(tmp_path: Path) -> None:
    source = (MISSIONS / "bardenas-gully-terrain.toml").read_text()
    bad = tmp_path / "bad.toml"
    bad.write_text(source.replace('"bardenas-gully-dem.tif"', '"missing.tif"'))
    with pytest.raises(SpecError, match=r"missing\.tif"):
        load_spec(bad)
    bad.write_text(source.replace("tolerance_m = 2", "tolerance = 2"))
    with pytest.raises(SpecError, match="unknown key tolerance in \\[terrain\\]"):
        load_spec(bad)


def test_cliff_steeper_than_the_vehicle_can_descend_is_refused(tmp_path: Path) -> None:
    # a 150 m drop across the area: following it at 0.1 m/s descent is impossible within 120 m AGL
    source = (MISSIONS / "bardenas-gully-terrain.toml").read_text()
    tif = tmp_path / "cliff.tif"
    with rasterio.open(MISSIONS / "bardenas-gully-dem.tif") as src:
        z = src.read(1)
        z[:, 100:] -= 150.0
        meta = src.meta.copy()
    with rasterio.open(tif, "w", **meta) as d:
        d.write(z, 1)
    spec_file = tmp_path / "cliff.toml"
    spec_file.write_text(
        source.replace('"bardenas-gully-dem.tif"', f'"{tif}"')
        .replace('"bardenas-gully.geojson"', f'"{MISSIONS}/bardenas-gully.geojson"')
        .replace("max_descent_rate_m_s = 2", "max_descent_rate_m_s = 0.1")
    )
    with pytest.raises(PlanningError, match="max_descent_rate_m_s"):
        plan_survey(load_spec(spec_file))


# --- a synthetic badlands: 12 m ridges every 60 m, parallel to the lines ---------------------------
RIDGE_HEIGHT_M, RIDGE_PERIOD_M, BADLANDS_GROUND_M = 12.0, 60.0, 400.0


def _badlands_z(easting_m: np.ndarray) -> np.ndarray:
    return BADLANDS_GROUND_M + RIDGE_HEIGHT_M * 0.5 * (1.0 - np.cos(2.0 * np.pi * easting_m / RIDGE_PERIOD_M))


def _badlands_spec(tmp_path: Path, follow: bool) -> Path:
    """A 400 x 300 m block near 42.2 N, its DEM (1 m cells, UTM 30N) made here, lines north-south."""
    from pyproj import Transformer

    to_utm = Transformer.from_crs("EPSG:4326", "EPSG:32630", always_xy=True)
    lon0, lat0 = -1.45, 42.2
    e0, n0 = to_utm.transform(lon0, lat0)
    e0, n0 = math.floor(e0 / 60.0) * 60.0, math.floor(n0)
    cells = 1200
    west, north = e0 - 400.0, n0 + 800.0
    easting = west + 0.5 + np.arange(cells)
    z = np.tile(_badlands_z(easting), (cells, 1)).astype("float32")
    tif = tmp_path / "badlands.tif"
    with rasterio.open(
        tif, "w", driver="GTiff", height=cells, width=cells, count=1, dtype="float32",
        crs="EPSG:32630", transform=from_origin(west, north, 1.0, 1.0),
    ) as d:  # fmt: skip
        d.write(z, 1)
    to_ll = Transformer.from_crs("EPSG:32630", "EPSG:4326", always_xy=True)
    corners = [
        to_ll.transform(e0 + dx, n0 + dy) for dx, dy in ((0, 0), (400, 0), (400, 300), (0, 300), (0, 0))
    ]
    (tmp_path / "block.geojson").write_text(
        '{"type": "Polygon", "coordinates": [' + str([list(c) for c in corners]) + "]}"
    )
    home_lon, home_lat = to_ll.transform(e0 - 60.0, n0 - 20.0)  # in a valley: ground 400 m
    spec = tmp_path / "badlands.toml"
    spec.write_text(
        f'name = "badlands"\narea = "block.geojson"\n[camera]\nmodel = "canon-eos-350d-20mm"\n'
        f"[survey]\ngsd_cm = 2.4\nfront_overlap_pct = 80\nside_overlap_pct = 70\nspeed_m_s = 5\n"
        f"direction_deg = 0\nturnaround_m = 10\n"
        f'[terrain]\ndem = "badlands.tif"\nfollow = {str(follow).lower()}\ntolerance_m = 2\n'
        f"accept_overlap_loss = true\n"
        f"[vehicle]\nhome = [{home_lat}, {home_lon}]\nhome_alt_amsl_m = 400\nmax_alt_agl_m = 150\n"
        f"max_flight_time_min = 60\n"
    )
    return spec


def _cast_on_ridges(origin: np.ndarray, ray: np.ndarray, to_easting: object) -> np.ndarray:
    """Where a ray from ``origin`` (x, y, z AMSL in the plan's frame) meets the ridges, found on the
    analytic surface (not the raster): fine march, then bisection."""
    t = np.linspace(0.0, 400.0, 40001)
    pts = origin[None, :] + t[:, None] * ray[None, :]
    e = to_easting(pts[:, 0], pts[:, 1])  # type: ignore[operator]
    below = np.flatnonzero(pts[:, 2] <= _badlands_z(e))[0]
    lo, hi = t[below - 1], t[below]
    for _ in range(40):
        mid = (lo + hi) / 2
        p = origin + mid * ray
        if p[2] > _badlands_z(np.array([to_easting(p[0], p[1])]))[0]:  # type: ignore[operator]
            lo = mid
        else:
            hi = mid
    return origin + hi * ray


def test_badlands_sidelap_holds_on_the_ground_when_following(tmp_path: Path) -> None:
    from pyproj import Transformer

    plan = plan_survey(load_spec(_badlands_spec(tmp_path, follow=True)))
    terrain = plan.summary.terrain
    assert terrain is not None
    # The stations' real footprints, cast here on the ridges themselves: for each station and the
    # nearest station of the next line, the overlap of their facing image edges across the lines.
    to_utm = Transformer.from_crs("EPSG:4326", "EPSG:32630", always_xy=True)

    def to_easting(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        lon, lat = plan.frame.to_lonlat(x, y)
        return np.asarray(to_utm.transform(lon, lat)[0])

    st = plan.stations
    cam = plan.camera
    f = cam.focal_length_mm
    home_ground = plan.home.alt_amsl_m
    rows = sorted(set(st.line_index.tolist()), key=lambda r: float(np.mean(st.x_m[st.line_index == r])))
    worst = 100.0
    for r0, r1 in itertools.pairwise(rows):
        k0 = np.flatnonzero(st.line_index == r0)[5:-5:7]  # a sample of each line's stations
        k1 = np.flatnonzero(st.line_index == r1)
        for a in k0:
            b = k1[np.argmin(np.abs(st.y_m[k1] - st.y_m[a]))]
            edges = []
            for k, side in ((a, 1.0), (b, -1.0)):
                origin = np.array([st.x_m[k], st.y_m[k], st.alt_rel_home_m[k] + home_ground])
                # landscape, lines north-south: the image's width lies east-west; the ray through
                # the middle of the edge that faces the other line (east for a, west for b)
                ray = np.array([side * cam.sensor_width_mm / 2, 0.0, -f])
                edges.append(_cast_on_ridges(origin, ray / np.linalg.norm(ray), to_easting)[0])
            overlap = edges[0] - edges[1]
            base = st.x_m[b] - st.x_m[a]
            worst = min(worst, 100.0 * overlap / (overlap + base))
    assert worst >= 70.0 - 1.0, f"sidelap on the ground {worst:.1f} %"
    assert terrain["side_overlap_min_pct"] <= worst + 1.0  # type: ignore[operator]
    assert terrain["side_overlap_min_pct"] >= 70.0 - 1.0  # type: ignore[operator]


def test_badlands_at_constant_altitude_reports_the_loss(tmp_path: Path) -> None:
    plan = plan_survey(load_spec(_badlands_spec(tmp_path, follow=False)))
    terrain = plan.summary.terrain
    assert terrain is not None
    # 12 m ridges under a 75 m flight: the ridge tops are 16 % nearer, the sidelap there is lower
    assert terrain["side_overlap_min_pct"] < 70.0 - 3.0  # type: ignore[operator]
    assert any("% side" in w and "points below" in w and "follow = true" in w for w in plan.warnings)


def test_terrain_figures_of_the_summary(terrain_plan: SurveyPlan, dem: Dem) -> None:
    """summary.json's terrain figures against the mission's own waypoints and the DEM."""
    terrain = terrain_plan.summary.terrain
    assert terrain is not None
    home = terrain_plan.home.alt_amsl_m
    assert terrain["home_ground_amsl_m"] == pytest.approx(home)
    # stations: altitude above home from the waypoints' straight legs; height above the DEM
    st = terrain_plan.stations
    ground = dem.elevation_at(st.x_m, st.y_m, terrain_plan.frame)
    agl = st.alt_rel_home_m + home - ground
    assert terrain["station_alt_agl_min_m"] == pytest.approx(float(agl.min()), abs=1e-6)
    assert terrain["station_alt_agl_max_m"] == pytest.approx(float(agl.max()), abs=1e-6)
    # GSD = pixel pitch x height / focal length (Eq. 3-4) at the lowest and highest station
    camera = terrain_plan.camera
    pitch = max(camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm)
    assert terrain["gsd_min_cm"] == pytest.approx(100 * pitch * agl.min() / camera.focal_length_mm, rel=1e-6)
    assert terrain["gsd_max_cm"] == pytest.approx(100 * pitch * agl.max() / camera.focal_length_mm, rel=1e-6)
    # the path: the highest waypoint above home, and the lowest pass over the ground
    wps = [it for it in terrain_plan.mission.items if it.command == MavCmd.NAV_WAYPOINT]
    assert terrain["alt_rel_home_max_m"] == pytest.approx(max(w.alt_m for w in wps), abs=0.05)
    flown, _ = flown_agl(terrain_plan, dem, step_m=1.0)
    assert terrain["path_alt_agl_min_m"] == pytest.approx(float(flown.min()), abs=0.5)
    # the frames were spaced for the highest ground they see
    assert float(terrain["footprint_scale"]) <= float(terrain["footprint_scale_min"]) + 1e-9  # type: ignore[arg-type]
    assert float(terrain["front_overlap_min_pct"]) >= 80.0 - 1.0  # type: ignore[arg-type]
    assert float(terrain["side_overlap_min_pct"]) >= 70.0 - 1.0  # type: ignore[arg-type]


def test_oblique_passes_over_a_dem_are_said_to_be_unjudged(tmp_path: Path, terrain_plan: SurveyPlan) -> None:
    """The DEM cast judges the nadir frames' overlaps only: a plan with oblique passes over relief
    says, by pass name, that theirs were not judged, never leaving it silent; the nadir-only plan
    says nothing of the kind."""
    source = (MISSIONS / "bardenas-gully-terrain.toml").read_text()
    source = source.replace('"bardenas-gully', f'"{MISSIONS}/bardenas-gully')
    source = source.replace(
        'trigger = "distance"\n',
        'trigger = "distance"\n\n[[survey.oblique]]\ntilt_deg = 30\nheadings_deg = [0, 180]\n',
    )
    spec_file = tmp_path / "oblique.toml"
    spec_file.write_text(source)
    plan = plan_survey(load_spec(spec_file))
    said = [w for w in plan.warnings if "oblique" in w and "not judged" in w]
    assert len(said) == 1
    obliques = {p.name for p in plan.passes if p.tilt_deg != 0.0}
    assert len(obliques) == 2 and all(name in said[0] for name in obliques)
    assert not [w for w in terrain_plan.warnings if "not judged" in w]
