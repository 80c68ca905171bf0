"""Ordering and transit routing (planner.route), against constructions that need no planner code:
the shortest way around a square is known in closed form, a path must not enter a zone, and the
best of the four boustrophedon starts is found by trying them all."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import LineString, Polygon, box

from planner.errors import PlanningError
from planner.route import Router, boustrophedon, nearest_start, polyline_length_m


def test_the_way_around_a_square_is_the_shortest() -> None:
    # From (-50, 0) to (50, 0) past a 20 m square centred on the origin: the shortest path
    # touches two corners, (-10, 10) and (10, 10) (or the two below): 2 x hypot(40, 10) + 20.
    square = box(-10, -10, 10, 10)
    router = Router([square], margin_m=0.001)
    path = router.path((-50.0, 0.0), (50.0, 0.0))
    assert path[0] == (-50.0, 0.0) and path[-1] == (50.0, 0.0)
    expected = 2 * math.hypot(40.0, 10.0) + 20.0
    assert abs(polyline_length_m(np.asarray(path)) - expected) < 0.05
    assert LineString(path).intersection(square.buffer(-0.01)).length == 0.0


def test_a_clear_leg_is_flown_straight() -> None:
    router = Router([box(100, 100, 120, 120)])
    assert router.path((0.0, 0.0), (50.0, 10.0)) == [(0.0, 0.0), (50.0, 10.0)]


@settings(max_examples=40, deadline=None, derandomize=True)
@given(
    zones=st.lists(
        st.tuples(st.floats(-200, 200), st.floats(-200, 200), st.floats(5, 40), st.floats(5, 40)),
        min_size=1,
        max_size=4,
    ),
    a=st.tuples(st.floats(-300, 300), st.floats(-300, 300)),
    b=st.tuples(st.floats(-300, 300), st.floats(-300, 300)),
)
def test_transits_never_enter_a_zone_and_are_no_shorter_than_straight(
    zones: list[tuple[float, float, float, float]], a: tuple[float, float], b: tuple[float, float]
) -> None:
    polygons = [box(x, y, x + w, y + h) for x, y, w, h in zones]
    union = shapely.union_all(polygons)
    if union.buffer(1.0).contains(shapely.Point(a)) or union.buffer(1.0).contains(shapely.Point(b)):
        return  # the ends must be outside the zones
    path = Router(polygons).path(a, b)
    assert path[0] == a and path[-1] == b
    leg = LineString(path)
    assert leg.intersection(union.buffer(-0.02)).length < 1e-6
    assert polyline_length_m(np.asarray(path)) >= math.dist(a, b) - 1e-9


@settings(max_examples=50, deadline=None, derandomize=True)
@given(
    sizes=st.lists(st.integers(1, 3), min_size=1, max_size=6),
    position=st.tuples(st.floats(-100, 100), st.floats(-100, 100)),
)
def test_the_nearest_of_the_four_starts_is_taken(sizes: list[int], position: tuple[float, float]) -> None:
    # rows of segments along x, rows 10 m apart in y; entries at the segment's start in its direction
    rows, entries, k = [], {}, 0
    for r, n in enumerate(sizes):
        members = []
        for j in range(n):
            x0, x1 = 30.0 * j, 30.0 * j + 20.0
            entries[(k, 1)] = (x0 - 5.0, 10.0 * r)
            entries[(k, -1)] = (x1 + 5.0, 10.0 * r)
            members.append(k)
            k += 1
        rows.append(members)
    reverse, direction = nearest_start(rows, entries, position)
    order = boustrophedon(rows, reverse, direction)
    first = entries[order[0]]
    candidates = []
    for rev, d in itertools.product((False, True), (1, -1)):
        o = boustrophedon(rows, rev, d)
        candidates.append(math.dist(entries[o[0]], position))
    assert math.dist(first, position) <= min(candidates) + 1e-9
    # every segment once; directions alternate row by row
    assert sorted(s for s, _ in order) == list(range(k))
    row_of = {s: r for r, members in enumerate(rows) for s in members}
    seen_rows = []
    for s, d in order:
        if not seen_rows or seen_rows[-1][0] != row_of[s]:
            seen_rows.append((row_of[s], d))
    assert all(d0 == -d1 for (_, d0), (_, d1) in itertools.pairwise(seen_rows))


def test_zones_that_enclose_the_start_are_refused() -> None:
    ring = Polygon(box(-50, -50, 50, 50).exterior.coords, [box(-30, -30, 30, 30).exterior.coords])
    with pytest.raises(PlanningError, match=r"no route.*exclusion zones"):
        Router([ring]).path((0.0, 0.0), (100.0, 100.0))
