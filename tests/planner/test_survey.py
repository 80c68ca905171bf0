"""The planner's promises, checked on random areas (hypothesis) and on the bundled examples:

- every point of the area minus the exclusions is seen by at least one planned footprint;
- adjacent lines are at most the sidelap spacing apart, consecutive stations at most the
  endlap spacing (so their footprints overlap by at least the requested overlaps);
- no camera-on segment leaves the area's buffer or enters an exclusion;
- the stations are exactly where an autopilot replaying the mission items fires the camera.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Polygon
from survey_oracles import check_plan, make_spec, replay_at_loop_rate

from planner.camera import Orientation
from planner.mission import Autopilot, MavCmd
from planner.survey import plan_polygons

LON0, LAT0 = -1.60, 42.50
M_PER_DEG_LAT = 111_132.0
M_PER_DEG_LON = 111_320.0 * math.cos(math.radians(LAT0))


def to_lonlat_polygon(xy: list[tuple[float, float]], holes: list[list[tuple[float, float]]] = ()) -> Polygon:  # type: ignore[assignment]
    def conv(ring: list[tuple[float, float]]) -> list[tuple[float, float]]:
        return [(LON0 + x / M_PER_DEG_LON, LAT0 + y / M_PER_DEG_LAT) for x, y in ring]

    return Polygon(conv(xy), [conv(h) for h in holes])


@st.composite
def star_polygon(
    draw: st.DrawFn,
    centre: tuple[float, float] = (0.0, 0.0),
    r_min: float = 150.0,
    r_max: float = 450.0,
    n_max: int = 11,
) -> list[tuple[float, float]]:
    """A random simple polygon: star-shaped around its centre, concave in general (metres)."""
    n = draw(st.integers(4, n_max))
    angles = sorted(
        draw(st.lists(st.floats(0.0, 2 * math.pi, exclude_max=True), min_size=n, max_size=n, unique=True))
    )
    gaps = np.diff([*angles, angles[0] + 2 * math.pi])
    if gaps.max() > math.pi * 0.9 or gaps.min() < 0.05:
        angles = list(np.linspace(0, 2 * math.pi, n, endpoint=False) + draw(st.floats(0, 1)))
    radii = draw(st.lists(st.floats(r_min, r_max), min_size=n, max_size=n))
    return [
        (centre[0] + r * math.sin(a), centre[1] + r * math.cos(a)) for a, r in zip(angles, radii, strict=True)
    ]


@settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    outer=star_polygon(),
    hole=star_polygon(r_min=20.0, r_max=50.0, n_max=6),
    exclusion=star_polygon(centre=(90.0, -45.0), r_min=10.0, r_max=30.0, n_max=6),
    keep=st.sampled_from([(True, True), (True, True), (True, True), (True, False), (False, True)]),
    front=st.sampled_from([60.0, 75.0, 80.0]),
    side=st.sampled_from([30.0, 60.0, 70.0]),
    direction=st.one_of(st.just("auto"), st.floats(0.0, 179.0)),
    orientation=st.sampled_from(["landscape", "portrait"]),
)
def test_random_areas_keep_every_promise(
    outer: list[tuple[float, float]],
    hole: list[tuple[float, float]],
    exclusion: list[tuple[float, float]],
    keep: tuple[bool, bool],
    front: float,
    side: float,
    direction: object,
    orientation: str,
) -> None:
    # The outer star has radii of 150 m or more around the origin: a hole of at most 50 m there
    # and an exclusion of at most 30 m at (90, -45) (20 m apart or more) fit inside it, unless a long
    # edge of the star cuts in.
    outer_poly = Polygon(outer)
    holes = [hole] if keep[0] and outer_poly.buffer(-5).contains(Polygon(hole)) else []
    fits = keep[1] and outer_poly.buffer(-5).contains(Polygon(exclusion))
    exclusions = [to_lonlat_polygon(exclusion)] if fits else []
    event("hole" if holes else "no hole")
    event("exclusion" if exclusions else "no exclusion")
    spec = make_spec(
        {
            "gsd_cm": 1.5,
            "front_overlap_pct": front,
            "side_overlap_pct": side,
            "direction_deg": direction,
            "exclusion_clearance_m": 2.0,
        },
        camera={"model": "dji-phantom-4-pro", "orientation": orientation},
    )
    plan = plan_polygons(spec, [to_lonlat_polygon(outer, holes)], exclusions)
    check_plan(plan, front, side, 2.0)


def test_concave_notch_splits_lines_and_holes_are_not_flown() -> None:
    # A U shape: the notch (200 m wide) must split every line that crosses it.
    u = [(0, 0), (600, 0), (600, 450), (420, 450), (420, 180), (200, 180), (200, 450), (0, 450)]
    pond = [(60, 60), (140, 50), (160, 120), (90, 140), (50, 110)]
    spec = make_spec({"gsd_cm": 1.5, "direction_deg": 0.0, "exclusion_clearance_m": 3.0})
    plan = plan_polygons(spec, [to_lonlat_polygon(u, [pond])], [])
    check_plan(plan, 80.0, 70.0, 3.0)
    notch = plan.frame.geometry_to_xy(to_lonlat_polygon([(230, 230), (390, 230), (390, 450), (230, 450)]))
    for line in plan.passes[0].lines:
        seg = LineString([line.start_xy_m, line.end_xy_m])
        assert not seg.intersects(notch), "camera on across the notch"


def test_exclusion_transit_goes_around() -> None:
    square = [(0, 0), (500, 0), (500, 500), (0, 500)]
    zone = [(200, 150), (300, 150), (300, 350), (200, 350)]
    spec = make_spec({"gsd_cm": 1.5, "direction_deg": 0.0, "exclusion_clearance_m": 4.0})
    plan = plan_polygons(spec, [to_lonlat_polygon(square)], [to_lonlat_polygon(zone)])
    check_plan(plan, 80.0, 70.0, 4.0)
    zone_xy = plan.exclusions_xy[0]
    path = LineString(plan.path_xy_m)
    assert path.intersection(zone_xy).length < 1e-6, "the flight path crosses the no-fly zone"


def test_crosshatch_and_obliques() -> None:
    square = [(0, 0), (400, 0), (400, 300), (0, 300)]
    spec = make_spec(
        {
            "gsd_cm": 2.0,
            "crosshatch": True,
            "oblique": [{"tilt_deg": 30.0, "headings_deg": [0, 90, 180, 270]}],
        }
    )
    plan = plan_polygons(spec, [to_lonlat_polygon(square)], [])
    kinds = [p.kind.value for p in plan.passes]
    assert kinds == ["nadir", "crosshatch", "oblique", "oblique", "oblique", "oblique"]
    nadir, cross = plan.passes[0], plan.passes[1]
    assert abs(((cross.direction_deg - nadir.direction_deg) % 180.0) - 90.0) < 1e-6
    # every pass covers the whole area by itself
    for p in plan.passes:
        mask = plan.stations.pass_index == p.index
        covered = shapely.union_all(shapely.polygons(plan.stations.footprint_xy_m[mask]))
        assert plan.area_xy.difference(covered).area < 0.05, p.name
    # oblique frames: trapezoids; their pass is shifted against the look direction
    obl = plan.passes[2]
    mask = plan.stations.pass_index == obl.index
    assert np.allclose(plan.stations.tilt_deg[mask], 30.0)
    assert obl.far_gsd_cm > obl.near_gsd_cm
    centre = plan.area_xy.centroid
    look = math.radians(float(plan.stations.look_heading_deg[mask][0]))
    cam = np.column_stack([plan.stations.x_m[mask], plan.stations.y_m[mask]]).mean(axis=0)
    offset = (cam[0] - centre.x) * math.sin(look) + (cam[1] - centre.y) * math.cos(look)
    assert offset < -0.5 * float(plan.stations.alt_agl_m[0]) * math.tan(math.radians(30.0))
    # gimbal commands: nadir at the start, then -60 deg pitch for the obliques
    pitches = [it.param1 for it in plan.mission.items if it.command == MavCmd.DO_MOUNT_CONTROL]
    assert pitches[0] == -90.0 and -60.0 in pitches
    # the crosshatch starts at the end of the nadir pass nearest to where that pass ended
    end_nadir = plan.passes[0].lines[-1].exit_xy_m
    first_cross = plan.passes[1].lines[0].entry_xy_m
    ends = [(line.entry_xy_m, line.exit_xy_m) for line in plan.passes[1].lines]
    candidates = [ends[0][0], ends[0][1], ends[-1][0], ends[-1][1]]
    assert math.dist(end_nadir, first_cross) <= min(math.dist(end_nadir, c) for c in candidates) + 1e-6
    fired = replay_at_loop_rate(plan.mission)
    assert len(fired) == len(plan.stations)


def test_hover_mode_one_capture_per_station() -> None:
    square = [(0, 0), (200, 0), (200, 150), (0, 150)]
    spec = make_spec({"gsd_cm": 1.0, "trigger": "hover", "hover_hold_s": 3.0})
    plan = plan_polygons(spec, [to_lonlat_polygon(square)], [])
    captures = [it for it in plan.mission.items if it.command == MavCmd.IMAGE_START_CAPTURE]
    assert len(captures) == len(plan.stations)
    holds = [it.param1 for it in plan.mission.items if it.command == MavCmd.NAV_WAYPOINT and it.param1]
    assert holds.count(3.0) == len(plan.stations)
    assert not any(it.command == MavCmd.DO_SET_CAM_TRIGG_DIST for it in plan.mission.items)


def test_px4_items_have_no_home_and_use_gimbal_manager() -> None:
    square = [(0, 0), (200, 0), (200, 150), (0, 150)]
    spec = make_spec({"gsd_cm": 1.5})
    spec = type(spec)(
        **{
            **spec.__dict__,
            "vehicle": type(spec.vehicle)(**{**spec.vehicle.__dict__, "autopilot": Autopilot.PX4}),
        }
    )
    plan = plan_polygons(spec, [to_lonlat_polygon(square)], [])
    commands = [int(it.command) for it in plan.mission.items]
    assert commands[0] == MavCmd.NAV_TAKEOFF
    assert MavCmd.DO_GIMBAL_MANAGER_PITCHYAW in commands and MavCmd.DO_MOUNT_CONTROL not in commands
    assert commands[-1] == MavCmd.NAV_RETURN_TO_LAUNCH


def test_edge_coverage_line_count_is_minimal() -> None:
    # A rectangle exactly k spacings wide needs the computed number of lines, no more.
    spec = make_spec({"gsd_cm": 2.0, "direction_deg": 0.0, "side_overlap_pct": 50})
    fp = spec.camera.footprint(spec.camera.height_for_gsd_m(2.0), Orientation.LANDSCAPE)
    spacing = fp.across_m * 0.5
    width = fp.across_m + 3 * spacing - 1.0  # 4 lines cover it; 3 would not
    plan = plan_polygons(spec, [to_lonlat_polygon([(0, 0), (width, 0), (width, 300), (0, 300)])], [])
    assert plan.summary.line_count == 4
