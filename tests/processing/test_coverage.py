"""The scan-line rasterizer against shapely, coverage statistics, gaps of a block."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from pyproj import CRS
from shapely.geometry import Polygon, box
from test_footprints import CAMERA, FRAME, ORIGIN_X_M, ORIGIN_Y_M, make_frames

from planner.camera import Orientation
from processing.coverage import (
    Grid,
    area_mask,
    count_raster,
    coverage_stats,
    gap_polygons,
    min_value_raster,
    view_count_raster,
)
from processing.errors import ProcessingError
from processing.footprints import project_footprints
from processing.frames import AltitudeReference
from processing.ground import FlatGround

# A grid origin and cell sizes no hypothesis value is likely to line up with.
WEST_M, NORTH_M = -13.0 - math.pi, 17.0 + math.e


def star_polygon(cx: float, cy: float, radii: list[float], angles: list[float]) -> np.ndarray:
    """A simple polygon: vertices at increasing angles around (cx, cy)."""
    theta = np.cumsum(np.asarray(angles))
    theta = theta / theta[-1] * 2 * np.pi
    r = np.asarray(radii)
    return np.column_stack([cx + r * np.cos(theta), cy + r * np.sin(theta)])


polygon_strategy = st.integers(3, 12).flatmap(
    lambda n: st.builds(
        star_polygon,
        cx=st.floats(-5, 25),
        cy=st.floats(-10, 20),
        radii=st.lists(st.floats(0.5, 12), min_size=n, max_size=n),
        angles=st.lists(st.floats(0.05, 1.0), min_size=n, max_size=n),
    )
)


def pad(polygons: list[np.ndarray]) -> np.ndarray:
    """(N, V, 2) from rings of different lengths, repeating last vertices (zero-length edges)."""
    v = max(len(p) for p in polygons)
    return np.stack([np.vstack([p, np.repeat(p[-1:], v - len(p), axis=0)]) for p in polygons])


def centres(grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    x, y = grid.cell_centres()
    return np.meshgrid(x, y)


def no_centre_on_an_edge(polygons: list[np.ndarray], grid: Grid) -> bool:
    x, y = centres(grid)
    for p in polygons:
        if (shapely.distance(Polygon(p).boundary, shapely.points(x, y)) < 1e-9).any():
            return False
    return True


@settings(max_examples=150, deadline=None)
@given(
    polygons=st.lists(polygon_strategy, min_size=1, max_size=6),
    cell_m=st.sampled_from([0.37, 0.5 + 1e-3 * math.sqrt(2), 1.3, 2.9]),
    rows=st.integers(1, 60),
    cols=st.integers(1, 60),
)
def test_counts_equal_shapely_contains_over_cell_centres(
    polygons: list[np.ndarray], cell_m: float, rows: int, cols: int
) -> None:
    grid = Grid(west_m=WEST_M, north_m=NORTH_M, cell_m=cell_m, rows=rows, cols=cols)
    assume(all(Polygon(p).is_valid for p in polygons))
    assume(no_centre_on_an_edge(polygons, grid))
    x, y = centres(grid)
    expected = sum(shapely.contains_xy(Polygon(p), x, y).astype(int) for p in polygons)
    counts = count_raster(pad(polygons), grid)
    assert counts.dtype == np.uint16
    np.testing.assert_array_equal(counts, expected)
    # Shapely input, and tiny chunks, give the same counts.
    np.testing.assert_array_equal(
        count_raster([Polygon(p) for p in polygons], grid, chunk_crossings=7), expected
    )


@settings(max_examples=60, deadline=None)
@given(outer=polygon_strategy, hole_scale=st.floats(0.1, 0.6))
def test_area_mask_with_a_hole_equals_shapely(outer: np.ndarray, hole_scale: float) -> None:
    area = Polygon(outer)
    assume(area.is_valid)
    hole = shapely.affinity.scale(area, hole_scale, hole_scale, origin=area.centroid)
    assume(area.contains(hole))
    polygon = Polygon(outer, [list(hole.exterior.coords)[::-1]])
    assume(polygon.is_valid)
    grid = Grid(west_m=WEST_M, north_m=NORTH_M, cell_m=0.61, rows=70, cols=70)
    assume(no_centre_on_an_edge([outer, np.asarray(hole.exterior.coords)], grid))
    x, y = centres(grid)
    np.testing.assert_array_equal(area_mask(polygon, grid), shapely.contains_xy(polygon, x, y))


@settings(max_examples=60, deadline=None)
@given(polygons=st.lists(polygon_strategy, min_size=1, max_size=5), data=st.data())
def test_min_value_raster_equals_brute_force(polygons: list[np.ndarray], data: st.DataObject) -> None:
    assume(all(Polygon(p).is_valid for p in polygons))
    values = np.array(
        data.draw(st.lists(st.floats(0.5, 9.0), min_size=len(polygons), max_size=len(polygons)))
    )
    grid = Grid(west_m=WEST_M, north_m=NORTH_M, cell_m=0.83, rows=50, cols=50)
    assume(no_centre_on_an_edge(polygons, grid))
    x, y = centres(grid)
    expected = np.full(grid.shape, np.inf)
    for p, v in zip(polygons, values, strict=True):
        inside = shapely.contains_xy(Polygon(p), x, y)
        expected[inside] = np.minimum(expected[inside], v)
    expected[np.isinf(expected)] = np.nan
    result = min_value_raster(pad(polygons), values, grid, chunk_cells=37)
    np.testing.assert_array_equal(result, expected)


def test_grid_snaps_outward_to_whole_cells() -> None:
    grid = Grid.from_bounds((10.1, 20.2, 30.05, 40.0), 0.5, CRS.from_epsg(32613))
    assert (grid.west_m, grid.north_m, grid.cell_m) == (10.0, 40.0, 0.5)
    assert grid.shape == (40, 41)
    xmin, ymin, xmax, ymax = grid.bounds
    assert xmin <= 10.1 and ymin <= 20.2 and xmax >= 30.05 and ymax >= 40.0
    with pytest.raises(ProcessingError, match="cell_m"):
        Grid.from_bounds((0, 0, 1, 1), 0.0)
    with pytest.raises(ProcessingError, match="larger cell size"):
        Grid.from_bounds((0, 0, 100_000, 100_000), 0.1)


def test_coverage_stats_of_two_overlapping_strips() -> None:
    grid = Grid.from_bounds((0, 0, 100, 100), 1.0)
    strips = np.array(
        [[[0, 0], [60, 0], [60, 100], [0, 100]], [[40, 0], [100, 0], [100, 100], [40, 100]]], float
    )
    # Shift by a quarter cell so no cell centre lies on a strip's edge.
    counts = view_count_raster(strips + 0.25, grid)
    mask = area_mask(box(0.25, 0.25, 100.25, 100.25), grid)
    stats = coverage_stats(counts, mask)
    assert stats["cells"] == 100 * 100
    assert stats["area_m2"] == pytest.approx(10_000.0)
    assert stats["seen_by_at_least_pct"] == {"1": 100.0, "2": 20.0, "3": 0.0, "5": 0.0, "9": 0.0}
    assert stats["views_max"] == 2


def regular_block(
    skip: tuple[int, int] | None = None, lines: int = 9, stations: int = 26
) -> tuple[np.ndarray, Polygon, Polygon]:
    """A nadir block at 100 m over flat ground, 80 % forward and 70 % side overlap, landscape,
    flying north and south. ``skip`` drops stations skip[0]..skip[1]-1 of every line. Returns the
    footprints, the area (the block minus a margin) and the union of the kept footprints."""
    height = 100.0
    across = CAMERA.footprint(height, Orientation.LANDSCAPE).across_m
    along = CAMERA.footprint(height, Orientation.LANDSCAPE).along_m
    spacing, base = across * 0.3, along * 0.2
    xs, ys, yaws = [], [], []
    for line in range(lines):
        for k in range(stations):
            if skip is not None and skip[0] <= k < skip[1]:
                continue
            xs.append(ORIGIN_X_M + line * spacing)
            ys.append(ORIGIN_Y_M + (k if line % 2 == 0 else stations - 1 - k) * base)
            yaws.append(0.0 if line % 2 == 0 else 180.0)
    frames = make_frames(
        np.array(xs), np.array(ys), height, np.array(yaws), reference=AltitudeReference.REL_HOME
    )
    fp = project_footprints(frames, FRAME, FlatGround(elevation_m=0.0, reference=AltitudeReference.REL_HOME))
    area = box(ORIGIN_X_M, ORIGIN_Y_M, ORIGIN_X_M + (lines - 1) * spacing, ORIGIN_Y_M + (stations - 1) * base)
    return fp.xy_m, area, shapely.union_all(fp.polygons())


def test_a_full_block_has_no_gap() -> None:
    xy, area, _ = regular_block()
    grid = Grid.from_bounds(area.buffer(80).bounds, 0.5)
    counts = view_count_raster(xy, grid)
    mask = area_mask(area, grid)
    assert gap_polygons(counts, mask) == []
    stats = coverage_stats(counts, mask)
    assert stats["seen_by_at_least_pct"]["3"] == 100.0


def test_a_removed_strip_is_found_with_its_true_area() -> None:
    xy, area, covered = regular_block(skip=(10, 16))
    cell = 0.3  # 40 m and 360 m are not whole numbers of cells
    snapped = Grid.from_bounds(area.buffer(80).bounds, cell)
    # Off the footprints' round coordinates by a fraction of a cell, so cells straddle the edges.
    grid = Grid(
        west_m=snapped.west_m + cell / 3,
        north_m=snapped.north_m - cell / 7,
        cell_m=cell,
        rows=snapped.rows,
        cols=snapped.cols,
    )
    view = view_count_raster(xy, grid)
    gaps = gap_polygons(view, area_mask(area, grid), min_area_m2=10.0)
    truth = area.difference(covered)  # exact geometry
    assert truth.geom_type == "Polygon" and truth.area > 1000.0
    assert len(gaps) == 1
    # Cells either side of the true boundary are in or out: the error stays within half a cell
    # along the gap's perimeter.
    tolerance_m2 = truth.length * cell / 2
    assert gaps[0].area == pytest.approx(truth.area, abs=tolerance_m2)
    assert gaps[0].symmetric_difference(truth).area < truth.length * cell
    # A higher threshold also finds the thinly seen band around the gap.
    assert sum(g.area for g in gap_polygons(view, area_mask(area, grid), min_views=4)) > gaps[0].area


def test_progress_is_reported_and_many_polygons_switch_to_uint32() -> None:
    grid = Grid(west_m=0.0, north_m=4.0, cell_m=1.0, rows=4, cols=4)
    square = np.array([[0.2, 0.2], [2.7, 0.2], [2.7, 2.7], [0.2, 2.7]])
    calls: list[tuple[int, int]] = []
    counts = view_count_raster(
        np.repeat(square[None], 3, axis=0), grid, progress=lambda d, t: calls.append((d, t))
    )
    assert calls and calls[-1][0] == calls[-1][1]
    assert counts.counts[1:4, 0:3].tolist() == [[3] * 3] * 3 and counts.counts.sum() == 27
    many = count_raster(np.repeat(square[None], 70_000, axis=0), grid)
    assert many.dtype == np.uint32 and int(many.max()) == 70_000 and int(many[0, 3]) == 0
