"""Fixed-wing plans (planner.fixed_wing): what a plane can fly.

- The turn radius against a hand computation and the load-factor form of the same physics.
- Turns between consecutive lines, on random blocks (hypothesis): the flown polyline from one
  line's camera-off point to the next line's camera-on point can be flown by rounding every
  corner with the plane's radius r: for each leg, the tangent lengths r tan(phi / 2) of the
  roundings at its two ends fit in the leg (phi: the change of heading at the corner). For two
  lines joined by square corners this is "at least 2 r apart"; a loop must keep to r as well.
- The items as ArduPlane's documented parameters read them (NAV_TAKEOFF param1 minimum pitch,
  DO_LAND_START, NAV_LOITER_TO_ALT param1 heading required, param2 radius, NAV_LAND), read back
  from the .waypoints file with pymavlink, the glide slope measured with pyproj's geodesic.
- Refusals: hover, a speed outside the airspeed band, an impossible bank, exit code 2.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink import mavutil, mavwp
from pyproj import Geod
from shapely.geometry import Polygon

from planner.errors import SpecError
from planner.fixed_wing import G_M_S2, turn_radius_m
from planner.mission import MavCmd
from planner.plan_folder import write_outputs
from planner.spec import parse_spec
from planner.survey import plan_polygons
from sfap.cli import cli

LON0, LAT0 = -0.40, 42.11
M_PER_DEG_LAT = 111_132.0
M_PER_DEG_LON = 111_320.0 * math.cos(math.radians(LAT0))


def lonlat_polygon(xy: list[tuple[float, float]]) -> Polygon:
    return Polygon([(LON0 + x / M_PER_DEG_LON, LAT0 + y / M_PER_DEG_LAT) for x, y in xy])


def plane_spec(tmp: Path, survey: dict[str, Any] | None = None, vehicle: dict[str, Any] | None = None) -> Any:
    data = {
        "name": "plane",
        "area": "area.geojson",
        "camera": {"model": "sony-rx1r-ii", "shutter_s": 0.0005},
        "survey": {"gsd_cm": 1.5, "front_overlap_pct": 75, "side_overlap_pct": 70, "speed_m_s": 16,
                   "max_blur_px": 0.6, "turnaround_m": 10} | (survey or {}),
        "vehicle": {"type": "fixed_wing", "home": [LAT0, LON0], "takeoff_alt_m": 40,
                    "bank_limit_deg": 30, "airspeed_min_m_s": 12, "airspeed_max_m_s": 22} | (vehicle or {}),
    }  # fmt: skip
    return parse_spec(data, tmp / "spec.toml")


def test_turn_radius_by_hand_and_by_load_factor() -> None:
    # 20 m/s at 45 degrees: tan = 1, r = v^2 / g
    assert turn_radius_m(20.0, 45.0) == pytest.approx(400.0 / 9.80665, rel=1e-12)
    for v, bank in ((12.0, 20.0), (18.0, 30.0), (25.0, 50.0)):
        n = 1.0 / math.cos(math.radians(bank))  # load factor of a level coordinated turn
        assert turn_radius_m(v, bank) == pytest.approx(v * v / (G_M_S2 * math.sqrt(n * n - 1.0)), rel=1e-9)


def _corner_tangents(points: np.ndarray, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Legs of the polyline with collinear points merged, and the tangent length r tan(phi/2)
    of the rounding at each of its points (0 at the two ends)."""
    keep = [points[0]]
    for p in points[1:]:
        if np.hypot(*(p - keep[-1])) > 1e-6:
            keep.append(p)
    pts = np.asarray(keep)
    changed = True
    while changed and len(pts) > 2:  # drop straight-through points
        changed = False
        for k in range(1, len(pts) - 1):
            a, b = pts[k] - pts[k - 1], pts[k + 1] - pts[k]
            if abs(a[0] * b[1] - a[1] * b[0]) < 1e-9 * np.hypot(*a) * np.hypot(*b) and a @ b > 0:
                pts = np.delete(pts, k, axis=0)
                changed = True
                break
    legs = np.hypot(*np.diff(pts, axis=0).T)
    tangent = np.zeros(len(pts))
    for k in range(1, len(pts) - 1):
        a, b = pts[k] - pts[k - 1], pts[k + 1] - pts[k]
        phi = math.acos(max(-1.0, min(1.0, float(a @ b) / (np.hypot(*a) * np.hypot(*b)))))
        tangent[k] = radius_m * math.tan(phi / 2.0) if phi < math.pi - 1e-9 else math.inf
    return legs, tangent


@settings(
    max_examples=15,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    width=st.floats(150, 700),
    height=st.floats(100, 500),
    speed=st.floats(12, 22),
    bank=st.floats(15, 45),
    side=st.sampled_from([40, 60, 70, 80]),
    direction=st.floats(0, 180),
)
def test_every_turn_between_lines_keeps_the_turn_radius(
    tmp_path: Path, width: float, height: float, speed: float, bank: float, side: int, direction: float
) -> None:
    spec = plane_spec(
        tmp_path,
        {
            "speed_m_s": round(speed, 1),
            "side_overlap_pct": side,
            "adjust_speed": True,
            "direction_deg": direction,
        },
        {"bank_limit_deg": round(bank, 1)},
    )
    area = lonlat_polygon([(0, 0), (width, 0), (width, height), (0, height)])
    plan = plan_polygons(spec, [area], [])
    r = turn_radius_m(plan.summary.speed_m_s, round(bank, 1))
    path = plan.path_xy_m
    lines = [ln for p in plan.passes for ln in p.lines]

    def index_of(point: tuple[float, float], after: int) -> int:
        d = np.hypot(path[after:, 0] - point[0], path[after:, 1] - point[1])
        k = int(np.argmin(d))
        assert d[k] < 1e-6, "a line's end is not on the flown path"
        return after + k

    k = 0
    for a, b in itertools.pairwise(lines):
        i_stop = index_of(a.end_xy_m, k)
        i_start = index_of(b.start_xy_m, i_stop)
        k = i_start
        turn = (b.heading_deg - a.heading_deg + 180.0) % 360.0 - 180.0
        if abs(abs(turn) - 180.0) > 1.0:
            continue  # a run continued straight on
        legs, tangent = _corner_tangents(path[i_stop : i_start + 1], r)
        fit = tangent[:-1] + tangent[1:] <= legs * (1 + 1e-6) + 1e-6
        assert fit.all(), f"a turn tighter than r = {r:.1f} m between lines {a.line_index} and {b.line_index}"


def test_lane_skipping_when_the_lines_are_closer_than_the_turn() -> None:
    """Ten lines 30 m apart, r 45 m: every hop but the ones that cannot be skips two lanes
    or more, as Mission Planner's 'minimum lane separation' does."""
    from planner.fixed_wing import FixedWing

    plane = FixedWing(
        radius_m=45.0,
        speed_m_s=16.0,
        l1_period_s=17.0,
        takeoff_pitch_deg=12,
        glide_slope_deg=6,
        approach_alt_m=40,
        landing_heading_grid_deg=None,
    )
    rows = [[k] for k in range(10)]
    v = [30.0 * k for k in range(10)]
    order = plane.line_order(rows, v, (False, 1))
    assert sorted(k for k, _ in order) == list(range(10))
    assert [d for _, d in order] == [1 if j % 2 == 0 else -1 for j in range(10)]
    hops = [abs(v[b] - v[a]) for (a, _), (b, _) in itertools.pairwise(order)]
    assert sum(h < 90.0 for h in hops) <= 1  # at most the last hop, flown as a loop
    # and lines far enough apart are flown in order, back and forth
    wide = plane.line_order(rows, [100.0 * k for k in range(10)], (False, 1))
    assert [k for k, _ in wide] == list(range(10))


@pytest.mark.parametrize(("autopilot", "period_s"), [("ardupilot", 17.0), ("px4", 20.0)])
def test_the_run_in_is_one_l1_period_of_flight(tmp_path: Path, autopilot: str, period_s: float) -> None:
    """Every line's run-in (entry to first photo) is at least the distance flown in one period
    of the autopilot's L1 guidance (ArduPlane NAVL1_PERIOD 17 s, PX4 FW_L1_PERIOD 20 s, their
    documented defaults): the cross-track error's envelope exp(-2 pi 0.75 t / P) is below 1 % by
    then. The lead-out stays the turn radius (or the spec's turnaround)."""
    spec = plane_spec(tmp_path, vehicle={"autopilot": autopilot})
    plan = plan_polygons(spec, [lonlat_polygon([(0, 0), (600, 0), (600, 400), (0, 400)])], [])
    assert math.exp(-2 * math.pi * 0.75) < 0.01
    radius = 16.0**2 / (G_M_S2 * math.tan(math.radians(30.0)))
    lines = [line for p in plan.passes for line in p.lines]
    assert len(lines) > 5
    for line in lines:
        assert math.dist(line.entry_xy_m, line.start_xy_m) >= 16.0 * period_s - 1e-6
        assert math.dist(line.end_xy_m, line.exit_xy_m) == pytest.approx(radius, rel=1e-6)
        # the run-in lies on the line
        ex, ey = line.entry_xy_m
        (sx, sy), (tx, ty) = line.start_xy_m, line.end_xy_m
        assert abs((ex - sx) * (ty - sy) - (ey - sy) * (tx - sx)) / math.dist((sx, sy), (tx, ty)) < 1e-6


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(hx=st.floats(-700.0, 1300.0), hy=st.floats(-700.0, 1100.0))
def test_the_first_line_starts_beyond_the_climb_out(tmp_path: Path, hx: float, hy: float) -> None:
    """Wherever home is, the first line's entry lies beyond the climb-out (take-off altitude /
    tan(take-off pitch)) and a U-turn's width (2 r) from home, and its run-in is at least the
    other lines'."""
    home = (LAT0 + hy / M_PER_DEG_LAT, LON0 + hx / M_PER_DEG_LON)
    spec = plane_spec(tmp_path, vehicle={"home": list(home), "takeoff_pitch_deg": 12, "takeoff_alt_m": 40})
    plan = plan_polygons(spec, [lonlat_polygon([(0, 0), (600, 0), (600, 400), (0, 400)])], [])
    first = plan.passes[0].lines[0]
    radius = 16.0**2 / (G_M_S2 * math.tan(math.radians(30.0)))
    climb_out = 40.0 / math.tan(math.radians(12.0))
    assert math.dist(plan.home_xy_m, first.entry_xy_m) >= climb_out + 2 * radius - 1e-3
    assert math.dist(first.entry_xy_m, first.start_xy_m) >= 16.0 * 17.0 - 1e-6


def test_items_as_arduplane_reads_them(tmp_path: Path) -> None:
    spec = plane_spec(tmp_path, vehicle={"takeoff_pitch_deg": 12, "landing_glide_slope_deg": 5})
    plan = plan_polygons(spec, [lonlat_polygon([(0, 0), (600, 0), (600, 400), (0, 400)])], [])
    write_outputs(plan, tmp_path / "out")
    loader = mavwp.MAVWPLoader()
    loader.load(str(tmp_path / "out" / "mission.waypoints"))
    items = [loader.wp(i) for i in range(1, loader.count())]  # row 0 is home
    commands = [int(w.command) for w in items]
    # take-off: NAV_TAKEOFF, param1 the minimum pitch (ArduPlane: "Minimum pitch (if airspeed
    # sensor present), desired pitch without sensor"), param7 the altitude
    assert commands[0] == mavutil.mavlink.MAV_CMD_NAV_TAKEOFF
    assert items[0].param1 == pytest.approx(12.0) and items[0].z == pytest.approx(40.0)
    # landing: DO_LAND_START, NAV_LOITER_TO_ALT (param1 1: heading required, param2 radius m),
    # NAV_LAND at home; no RTL, no hover captures, no waiting at waypoints
    assert commands[-3:] == [
        mavutil.mavlink.MAV_CMD_DO_LAND_START,
        mavutil.mavlink.MAV_CMD_NAV_LOITER_TO_ALT,
        mavutil.mavlink.MAV_CMD_NAV_LAND,
    ]
    assert mavutil.mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH not in commands
    assert MavCmd.IMAGE_START_CAPTURE not in commands
    assert all(w.param1 == 0 for w in items if int(w.command) == mavutil.mavlink.MAV_CMD_NAV_WAYPOINT)
    loiter, land = items[-2], items[-1]
    r = turn_radius_m(16.0, 30.0)
    assert loiter.param1 == 1 and loiter.param2 >= r
    assert land.x == pytest.approx(plan.home.lat_deg, abs=1e-7) and land.y == pytest.approx(
        plan.home.lon_deg, abs=1e-7
    )
    # the descent from the loiter's exit to the touchdown follows the glide slope
    _, _, dist = Geod(ellps="WGS84").inv(loiter.y, loiter.x, land.y, land.x)
    slope = math.degrees(math.atan2(loiter.z - land.z, dist))
    assert slope == pytest.approx(5.0, abs=0.05)
    # speed within the band, triggers by distance only
    speeds = [w.param2 for w in items if int(w.command) == mavutil.mavlink.MAV_CMD_DO_CHANGE_SPEED]
    assert speeds and all(12 <= s <= 22 for s in speeds)
    assert any(
        int(w.command) == mavutil.mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST and w.param1 > 0 for w in items
    )


def test_landing_heading_sets_the_approach_side(tmp_path: Path) -> None:
    spec = plane_spec(tmp_path, vehicle={"landing_heading_deg": 90})  # land flying east
    plan = plan_polygons(spec, [lonlat_polygon([(0, 0), (600, 0), (600, 400), (0, 400)])], [])
    loiter = plan.mission.items[-2]
    assert loiter.lon_deg < plan.home.lon_deg  # the approach comes from the west
    assert loiter.lat_deg == pytest.approx(plan.home.lat_deg, abs=2e-4)


@pytest.mark.parametrize(
    ("survey", "vehicle", "message"),
    [
        ({"trigger": "hover"}, {}, 'trigger = "hover" needs a vehicle that can hover'),
        ({"speed_m_s": 8}, {}, r"speed_m_s = 8 is outside the plane's airspeed band 12 to 22 m/s"),
        ({"speed_m_s": 16, "transit_speed_m_s": 30}, {}, "speed_m_s = 30 is outside"),
        (
            {},
            {"bank_limit_deg": 75},
            r"bank_limit_deg = 75 is not a bank .* set bank_limit_deg from 10 to 60",
        ),
        ({}, {"bank_limit_deg": 3}, "bank_limit_deg = 3 is not a bank"),
        ({}, {"airspeed_min_m_s": 0}, "airspeed_min_m_s = 0: a plane needs a positive minimum"),
        ({}, {"airspeed_min_m_s": 25}, "give a band with the maximum above the minimum"),
    ],
)
def test_what_a_plane_cannot_fly_is_refused(
    tmp_path: Path, survey: dict[str, Any], vehicle: dict[str, Any], message: str
) -> None:
    with pytest.raises(SpecError, match=message):
        spec = plane_spec(tmp_path, survey, vehicle)
        plan_polygons(spec, [lonlat_polygon([(0, 0), (600, 0), (600, 400), (0, 400)])], [])


def test_plane_keys_on_a_multirotor_are_refused(tmp_path: Path) -> None:
    data = {"area": "a.geojson", "camera": {"model": "dji-phantom-4-pro"}, "survey": {"gsd_cm": 2},
            "vehicle": {"type": "multirotor", "bank_limit_deg": 30}}  # fmt: skip
    with pytest.raises(SpecError, match='bank_limit_deg only apply to type = "fixed_wing"'):
        parse_spec(data, tmp_path / "s.toml")


def test_cli_impossible_bank_exits_2_naming_the_value(tmp_path: Path) -> None:
    repo = Path(__file__).resolve().parents[2]
    text = (repo / "missions" / "huesca-plane-block.toml").read_text()
    text = text.replace("bank_limit_deg = 30", "bank_limit_deg = 80")
    text = text.replace(
        'area = "huesca-plane-block.geojson"', f'area = "{repo / "missions" / "huesca-plane-block.geojson"}"'
    )
    (tmp_path / "plane.toml").write_text(text)
    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["plan", str(tmp_path / "plane.toml"), "-o", str(out)])
    assert result.exit_code == 2, result.output
    assert "bank_limit_deg = 80" in result.output and "from 10 to 60" in result.output
    assert not out.exists() or not any(out.iterdir())
