"""Multi-scale passes ([[survey.scale]]): each pass's line spacing and trigger distance against
the textbook's equations computed here from the sensor, each pass's footprints cover the area,
the stations carry their pass and height, and the flight time counts the climb between heights."""

from __future__ import annotations

import itertools
import math
from typing import Any

import pytest
import shapely
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from shapely.geometry import Polygon
from survey_oracles import REPO

from planner.errors import SpecError
from planner.spec import MissionSpec, parse_spec
from planner.survey import plan_polygons

LON0, LAT0 = -1.60, 42.50
M_PER_DEG_LAT = 111_132.0
M_PER_DEG_LON = 111_320.0 * math.cos(math.radians(LAT0))
# DJI Phantom 4 Pro: 13.2 x 8.8 mm sensor, 8.8 mm lens, 5472 x 3648 px (DJI's specifications)
SENSOR_W_MM, SENSOR_H_MM, FOCAL_MM = 13.2, 8.8, 8.8


def lonlat_polygon(xy: list[tuple[float, float]]) -> Polygon:
    return Polygon([(LON0 + x / M_PER_DEG_LON, LAT0 + y / M_PER_DEG_LAT) for x, y in xy])


def spec_with(survey: dict[str, Any], vehicle: dict[str, Any] | None = None) -> MissionSpec:
    data = {
        "name": "multiscale",
        "area": "area.geojson",
        "camera": {"model": "dji-phantom-4-pro"},
        "survey": {"front_overlap_pct": 75, "side_overlap_pct": 65, "speed_m_s": 5.0, **survey},
        "vehicle": {"type": "multirotor", "max_alt_agl_m": 400, **(vehicle or {})},
    }
    return parse_spec(data, REPO / "tests" / "spec.toml")


@settings(max_examples=12, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    base=st.floats(40.0, 90.0),
    heights=st.lists(st.floats(60.0, 200.0), min_size=1, max_size=2),
    front=st.sampled_from([None, 60.0, 80.0]),
    side=st.sampled_from([None, 30.0, 70.0]),
    skew=st.floats(0.0, 0.4),
)
def test_each_pass_is_spaced_for_its_height_and_covers_the_area(
    base: float, heights: list[float], front: float | None, side: float | None, skew: float
) -> None:
    levels = [base, *heights]  # a scale at a height already flown is refused (below)
    assume(all(abs(a - b) >= 0.05 * max(a, b) for a, b in itertools.combinations(levels, 2)))
    scales = []
    for h in heights:
        table: dict[str, float] = {"altitude_agl_m": h}
        if front is not None:
            table["front_overlap_pct"] = front
        if side is not None:
            table["side_overlap_pct"] = side
        scales.append(table)
    spec = spec_with({"altitude_agl_m": base, "scale": scales})
    area_xy = [(0, 0), (400, 0), (400 + 200 * skew, 300), (0, 250)]
    plan = plan_polygons(spec, [lonlat_polygon(area_xy)], [])
    assert len(plan.passes) == 1 + len(heights)
    expected = [(base, 75.0, 65.0)] + [(h, front or 75.0, side or 65.0) for h in heights]
    area = plan.area_xy
    for p, (h, f, s) in zip(plan.passes, expected, strict=True):
        across_m = SENSOR_W_MM * h / FOCAL_MM  # landscape: image width across the lines
        along_m = SENSOR_H_MM * h / FOCAL_MM
        assert p.alt_agl_m == pytest.approx(h)
        assert p.line_spacing_m == pytest.approx(across_m * (1 - s / 100.0), rel=1e-6)
        assert p.trigger_distance_m == pytest.approx(along_m * (1 - f / 100.0), rel=1e-6)
        mask = plan.stations.pass_index == p.index
        assert mask.any()
        assert plan.stations.alt_agl_m[mask] == pytest.approx(h)
        assert plan.stations.gsd_cm[mask] == pytest.approx(SENSOR_W_MM / 5472 * h / FOCAL_MM * 100, rel=1e-3)
        # the footprints of this pass alone, corner to corner, cover the whole area
        rings = plan.stations.footprint_xy_m[mask]
        union = shapely.union_all([Polygon(r) for r in rings])
        assert area.difference(union).area <= 1e-6 * area.area
        # neighbouring footprints of a line overlap by the pass's forward overlap (or more)
        xs, ys = plan.stations.x_m[mask], plan.stations.y_m[mask]
        lines = plan.stations.line_index[mask]
        steps = [
            math.dist((xs[k], ys[k]), (xs[k + 1], ys[k + 1]))
            for k in range(len(xs) - 1)
            if lines[k] == lines[k + 1]
        ]
        assert max(steps) <= along_m * (1 - f / 100.0) + 1e-6


def test_the_climb_between_heights_is_in_the_flight_time() -> None:
    area = [lonlat_polygon([(0, 0), (300, 0), (300, 200), (0, 200)])]
    one = plan_polygons(spec_with({"altitude_agl_m": 60.0}), area, [])
    two = plan_polygons(spec_with({"altitude_agl_m": 60.0, "scale": [{"altitude_agl_m": 160.0}]}), area, [])
    hi = plan_polygons(spec_with({"altitude_agl_m": 160.0}), area, [])
    # Flying both takes at least both passes' camera-on time and the 100 m climb between them.
    on_s = sum(line.length_m for p in two.passes for line in p.lines) / 5.0
    assert two.summary.flight_time_s >= on_s + 100.0 / 2.5
    assert two.summary.flight_time_s > max(one.summary.flight_time_s, hi.summary.flight_time_s)
    assert two.summary.photo_count == one.summary.photo_count + hi.summary.photo_count
    # Only the vertical part depends on the climb rate: take-off to 30 m, on to 60 m, up to
    # 160 m between the passes, down from 160 m: 320 m, at 2.5 then at 5 m/s.
    survey = {"altitude_agl_m": 60.0, "scale": [{"altitude_agl_m": 160.0}]}
    slow = plan_polygons(spec_with(survey, {"climb_rate_m_s": 2.5, "takeoff_alt_m": 30}), area, [])
    fast = plan_polygons(spec_with(survey, {"climb_rate_m_s": 5.0, "takeoff_alt_m": 30}), area, [])
    assert slow.summary.flight_time_s - fast.summary.flight_time_s == pytest.approx(320 / 2.5 - 320 / 5.0)


def test_a_scale_above_the_height_limit_or_without_a_height_is_refused() -> None:
    with pytest.raises(SpecError, match="scale 1: give exactly one of gsd_cm and altitude_agl_m"):
        spec_with({"altitude_agl_m": 60.0, "scale": [{"front_overlap_pct": 70}]})
    spec = spec_with({"altitude_agl_m": 60.0, "scale": [{"altitude_agl_m": 450.0}]})
    with pytest.raises(SpecError, match=r"needs a flying height of 450\.0 m"):
        plan_polygons(spec, [lonlat_polygon([(0, 0), (300, 0), (300, 200), (0, 200)])], [])


@pytest.mark.parametrize(
    "scale", [{"altitude_agl_m": 60.0}, {"altitude_agl_m": 61.5}, {"altitude_agl_m": 160.0, "twice": True}]
)
def test_a_scale_at_a_height_already_flown_is_refused(scale: dict[str, object]) -> None:
    scales = [{"altitude_agl_m": scale["altitude_agl_m"]}]
    if scale.get("twice"):
        scales.append({"altitude_agl_m": 158.0})
    spec = spec_with({"altitude_agl_m": 60.0, "scale": scales})
    with pytest.raises(SpecError, match=r"the same photos twice"):
        plan_polygons(spec, [lonlat_polygon([(0, 0), (300, 0), (300, 200), (0, 200)])], [])


def test_a_scale_at_the_main_gsd_is_refused() -> None:
    same = spec_with({"altitude_agl_m": 60.0}).camera.gsd_cm(60.0)
    spec = spec_with({"altitude_agl_m": 60.0, "scale": [{"gsd_cm": round(same, 4)}]})
    with pytest.raises(SpecError, match=r"height of the main pass"):
        plan_polygons(spec, [lonlat_polygon([(0, 0), (300, 0), (300, 200), (0, 200)])], [])
