"""How many frames see each point (planner.coverage): the binary-search count against shapely
rectangles counted one by one, and the area shares against exact shares on a layout whose
answer is known in closed form; the grid's jitter against SplitMix64's published outputs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shapely.geometry import Point, box

from planner.coverage import boundary_points, grid_points, splitmix64_uniform, view_counts, view_shares
from planner.exposure import FrameRectangle
from planner.lines import Segment

REPO = Path(__file__).resolve().parents[2]


@st.composite
def runs(draw: st.DrawFn) -> list[Segment]:
    return [
        Segment(
            row=k,
            v_m=draw(st.floats(-60.0, 60.0)),
            u_first_m=draw(st.floats(-80.0, 40.0)),
            spacing_m=draw(st.floats(3.0, 30.0)),
            count=draw(st.integers(1, 12)),
        )
        for k in range(draw(st.integers(1, 4)))
    ]


@settings(max_examples=60, deadline=None)
@given(
    segments=runs(),
    u_min=st.floats(-30.0, -2.0),
    u_max=st.floats(2.0, 30.0),
    v_min=st.floats(-40.0, -2.0),
    v_max=st.floats(2.0, 40.0),
    seed=st.integers(0, 2**16),
)
def test_counts_are_the_frames_whose_rectangle_holds_the_point(
    segments: list[Segment], u_min: float, u_max: float, v_min: float, v_max: float, seed: int
) -> None:
    rect = FrameRectangle(u_min_m=u_min, u_max_m=u_max, v_min_m=v_min, v_max_m=v_max)
    points = np.random.default_rng(seed).uniform(-150.0, 150.0, (300, 2))
    frames = [
        box(u + u_min, s.v_m + v_min, u + u_max, s.v_m + v_max)
        for s in segments
        for u in s.u_first_m + np.arange(s.count) * s.spacing_m
    ]
    # Oracle: every frame asked one by one (shapely; the boundary is rare in random points).
    expected = [sum(f.intersects(Point(p)) for f in frames) for p in points]
    assert view_counts(points, segments, rect).tolist() == expected


def test_shares_of_a_strip_are_the_overlap_figures() -> None:
    """One line of frames 100 m long at a spacing of a third of that (67 % forward overlap)
    over a strip as wide as the frame: every point is seen by three frames but near the ends,
    where the count falls to two then one over one spacing each (closed form)."""
    along, spacing = 100.0, 100.0 / 3.0
    rect = FrameRectangle(u_min_m=-along / 2, u_max_m=along / 2, v_min_m=-20.0, v_max_m=20.0)
    line = Segment(row=0, v_m=0.0, u_first_m=0.0, spacing_m=spacing, count=31)  # stations 0..1000 m
    strip = box(-along / 2, -19.0, 1000.0 + along / 2, 19.0)
    shares = view_shares(strip, [line], rect, spacing, 40.0)
    length = strip.bounds[2] - strip.bounds[0]
    assert shares.seen_1_pct == pytest.approx(100.0, abs=1e-9)
    assert shares.seen_2_pct == pytest.approx(100.0 * (length - 2 * spacing) / length, abs=0.3)
    assert shares.seen_3_pct == pytest.approx(100.0 * (length - 4 * spacing) / length, abs=0.3)
    assert shares.edge_weak_points > 0  # the two ends


def test_grid_and_boundary_points_lie_on_the_area() -> None:
    area = box(0, 0, 300, 200).difference(box(100, 50, 150, 120))
    points, cell = grid_points(area, 5.0)
    assert cell == 5.0 and len(points) == pytest.approx(area.area / 25.0, rel=0.02)
    assert all(area.covers(Point(p)) for p in points[::37])
    edge = boundary_points(area, 1.0)
    assert len(edge) == pytest.approx(area.length, abs=3)
    assert all(
        area.exterior.distance(Point(p)) < 1e-6 or area.interiors[0].distance(Point(p)) < 1e-6 for p in edge
    )


@settings(max_examples=80, deadline=None)
@given(
    segments=runs(),
    offset=st.sampled_from([0.0, 612_345.678, -4_321_987.25]),
    u_min=st.floats(-30.0, -2.0),
    u_max=st.floats(2.0, 30.0),
    seed=st.integers(0, 2**16),
)
def test_counts_on_the_edges_of_the_frames_are_exact(
    segments: list[Segment], offset: float, u_min: float, u_max: float, seed: int
) -> None:
    """Points placed on the edges of the frames (within a few ulps, where rounding decides),
    at the coordinates of a UTM frame: the count is, point by point, the frames whose
    inequalities hold as view_counts states them (pv in [v + v_min - 1e-9, v + v_max + 1e-9],
    the station's u in [pu - u_max - 1e-9, pu - u_min + 1e-9]), asked of every frame in turn."""
    rect = FrameRectangle(u_min_m=u_min, u_max_m=u_max, v_min_m=-20.0, v_max_m=20.0)
    segments = [
        Segment(row=s.row, v_m=s.v_m, u_first_m=s.u_first_m + offset, spacing_m=s.spacing_m, count=s.count)
        for s in segments
    ]
    rng = np.random.default_rng(seed)
    stations = np.concatenate([s.u_first_m + np.arange(s.count) * s.spacing_m for s in segments])
    edges = np.concatenate([stations + u_max + 1e-9, stations + u_min - 1e-9, stations])
    pu = rng.choice(edges, 400) + rng.integers(-3, 4, 400) * np.spacing(edges.max())
    pu = np.concatenate([pu, rng.uniform(stations.min() - 50.0, stations.max() + 50.0, 200)])
    pv = rng.choice([s.v_m for s in segments], len(pu)) + rng.choice([-20.0, 20.0, 0.0, 19.5], len(pu))
    points = np.column_stack([pu, pv])
    expected = np.zeros(len(points), np.int64)
    for s in segments:
        in_band = (pv >= s.v_m + rect.v_min_m - 1e-9) & (pv <= s.v_m + rect.v_max_m + 1e-9)
        u = s.u_first_m + np.arange(s.count) * s.spacing_m
        low = (pu - rect.u_max_m - 1e-9)[:, None]
        high = (pu - rect.u_min_m + 1e-9)[:, None]
        expected += in_band * ((u[None, :] >= low) & (u[None, :] <= high)).sum(axis=1)
    assert view_counts(points, segments, rect).tolist() == expected.tolist()


def test_the_jitter_is_splitmix64_from_seed_0() -> None:
    """The first outputs of SplitMix64 seeded with 0, as Vigna's splitmix64.c prints them (the
    generator's published test vector), to their top 53 bits; every output in [0, 1)."""
    published = [0xE220A8397B1DCDAF, 0x6E789E6AA1B965F4, 0x06C45D188009454F, 0xF88BB8A8724C81EC]
    got = splitmix64_uniform(len(published))
    assert [int(x * 2.0**53) for x in got] == [v >> 11 for v in published]
    many = splitmix64_uniform(200_000)
    assert many.min() >= 0.0 and many.max() < 1.0


def test_each_grid_point_lies_in_its_own_cell_at_an_even_spread() -> None:
    """One point per cell, inside it; where in the cell is spread evenly and independently
    along and across: each of 5 x 5 sub-cells holds its share of the points (within 5 sigma of
    a uniform draw), and the two offsets do not go together (a grid left unjittered, offsets
    tied to the cell's index or to each other all fail this)."""
    cell = 2.0
    area = box(0.0, 0.0, 600.0, 400.0)
    points, got_cell = grid_points(area, cell)
    assert got_cell == cell and len(points) == (600 // 2) * (400 // 2)
    col, row = np.floor(points[:, 0] / cell), np.floor(points[:, 1] / cell)
    assert len(set(zip(col.tolist(), row.tolist(), strict=True))) == len(points)  # one per cell
    du, dv = points[:, 0] / cell - col, points[:, 1] / cell - row
    assert (du >= 0).all() and (du < 1).all() and (dv >= 0).all() and (dv < 1).all()
    counts = np.histogram2d(du, dv, bins=5, range=[[0, 1], [0, 1]])[0]
    expected = len(points) / 25
    assert np.abs(counts - expected).max() < 5 * np.sqrt(expected)
    assert abs(np.corrcoef(du, dv)[0, 1]) < 0.02
    assert abs(np.corrcoef(du[:-1], du[1:])[0, 1]) < 0.02  # neighbours along a row


def test_planning_does_not_import_numpy_random() -> None:
    """The grid's jitter comes without numpy.random (10 ms to import, a twentieth of a small plan's
    process): `python -X importtime` of the planning of the gully names every module imported."""
    script = (
        "from pathlib import Path; from planner.spec import load_spec; "
        "from planner.survey import plan_survey; "
        "plan = plan_survey(load_spec(Path('missions/bardenas-gully.toml'))); "
        "assert plan.summary.stereo_seen_2_pct > 99"
    )
    command = [sys.executable, "-X", "importtime", "-c", script]
    done = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    lines = done.stderr.splitlines()
    imported = {line.split("|")[-1].strip() for line in lines if line.startswith("import time:")}
    assert "planner.coverage" in imported and "shapely" in imported
    assert "numpy.random" not in imported
