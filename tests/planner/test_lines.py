"""Lines and stations of a pass: stereo coverage on the shapes where it is hardest (thin strips,
notches, holes, L shapes) and on the bundled examples, measured with shapely on the planned
footprints and on the frames ArduPilot's trigger really takes (survey_oracles.check_plan)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from survey_oracles import MISSIONS, check_plan, make_spec, views
from test_survey import to_lonlat_polygon

from planner.lines import Segment, split_run
from planner.spec import load_spec
from planner.survey import plan_polygons, plan_survey

# Phantom 4 Pro at 1.5 cm GSD: frames about 82 m wide (landscape) and 55 m long.


def _thin(length: float, width: float) -> list[tuple[float, float]]:
    return [(0, 0), (length, 0), (length, width), (0, width)]


def _l_shape(arm: float, width: float) -> list[tuple[float, float]]:
    return [(0, 0), (arm, 0), (arm, width), (width, width), (width, arm), (0, arm)]


def _notched(size: float, notch_w: float, notch_d: float) -> list[tuple[float, float]]:
    a = (size - notch_w) / 2
    return [(0, 0), (size, 0), (size, size), (a + notch_w, size), (a + notch_w, size - notch_d),
            (a, size - notch_d), (a, size), (0, size)]  # fmt: skip


shapes = st.one_of(
    st.builds(lambda length, width: (_thin(length, width), []), st.floats(150, 600), st.floats(8, 70)),
    st.builds(lambda arm, width: (_l_shape(arm, width), []), st.floats(150, 400), st.floats(10, 60)),
    st.builds(
        lambda size, w, d: (_notched(size, w, d), []),
        st.floats(200, 400),
        st.floats(20, 120),
        st.floats(20, 150),
    ),
    st.builds(
        lambda size, r: (
            _thin(size, size),
            [
                [
                    (size / 2 + r * math.cos(a), size / 2 + r * math.sin(a))
                    for a in np.linspace(0, 2 * math.pi, 9)[:-1]
                ]
            ],
        ),
        st.floats(200, 400),
        st.floats(10, 60),
    ),
)


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    shape=shapes,
    front=st.sampled_from([70.0, 80.0]),
    side=st.sampled_from([30.0, 60.0, 70.0]),
    direction=st.one_of(st.just("auto"), st.floats(0.0, 179.0)),
    orientation=st.sampled_from(["landscape", "portrait"]),
)
def test_thin_notched_holed_and_l_shapes_are_seen_in_stereo(
    shape: tuple[list[tuple[float, float]], list[list[tuple[float, float]]]],
    front: float,
    side: float,
    direction: object,
    orientation: str,
) -> None:
    outer, holes = shape
    spec = make_spec(
        {"gsd_cm": 1.5, "front_overlap_pct": front, "side_overlap_pct": side, "direction_deg": direction},
        camera={"model": "dji-phantom-4-pro", "orientation": orientation},
    )
    plan = plan_polygons(spec, [to_lonlat_polygon(outer, holes)], [])
    check_plan(plan, front, side, 2.0)
    # with 70 % forward overlap or more a line's frames see every point three times: the
    # promised share holds on these shapes too
    assert plan.summary.stereo_seen_3_target_pct > 0
    assert plan.summary.stereo_seen_3_pct >= plan.summary.stereo_seen_3_target_pct


def test_the_ends_of_a_line_are_seen_three_times() -> None:
    # A strip narrower than a frame: one line; its two ends are where one frame used to see them.
    strip = _thin(400.0, 30.0)
    spec = make_spec({"gsd_cm": 1.5, "front_overlap_pct": 80, "direction_deg": 90.0})
    plan = plan_polygons(spec, [to_lonlat_polygon(strip)], [])
    assert plan.summary.line_count == 1
    coords = np.unique(shapely.get_coordinates(plan.area_xy), axis=0)  # the strip's four corners
    assert len(coords) == 4
    counts = views(plan.stations.footprint_xy_m, coords)
    assert np.all(counts >= 3), counts


@pytest.mark.parametrize(
    "name",
    [
        "bardenas-gully",
        "field-concave",
        "plateau-high-home",
        pytest.param("quarry-block", marks=pytest.mark.slow),
    ],
)
def test_bundled_examples_keep_every_promise_as_ardupilot_fires(name: str) -> None:
    spec = load_spec(MISSIONS / f"{name}.toml")
    plan = plan_survey(spec)
    check_plan(
        plan, spec.survey.front_overlap_pct, spec.survey.side_overlap_pct, spec.survey.exclusion_clearance_m
    )


@settings(max_examples=60, deadline=None, derandomize=True)
@given(count=st.integers(1, 400), limit=st.integers(1, 120), spacing=st.floats(1.0, 40.0))
def test_split_runs_keep_every_station_in_place(count: int, limit: int, spacing: float) -> None:
    seg = Segment(row=3, v_m=5.0, u_first_m=-17.0, spacing_m=spacing, count=count)
    runs = split_run(seg, limit)
    assert all(1 <= r.count <= limit for r in runs)
    stations = np.concatenate([r.u_first_m + np.arange(r.count) * r.spacing_m for r in runs])
    np.testing.assert_allclose(stations, seg.u_first_m + np.arange(count) * spacing, atol=1e-9)
    # joined inside, free at the two ends
    assert not runs[0].join_lo and not runs[-1].join_hi
    assert all(r.join_hi for r in runs[:-1]) and all(r.join_lo for r in runs[1:])


@pytest.mark.parametrize("direction", [1, -1])
def test_a_one_station_run_is_a_line_of_nonzero_length(direction: int) -> None:
    # photo at the start, camera off half a spacing on: the flight line has two distinct ends
    seg = Segment(row=0, v_m=0.0, u_first_m=10.0, spacing_m=8.0, count=1, direction=direction)
    start, stop = seg.camera_on_u()
    assert start == 10.0
    assert stop == pytest.approx(10.0 + direction * 4.0)
