"""View counts per ground cell, coverage statistics and gaps (GeoTIFF output: :mod:`processing.geotiff`).

The rasterizer is a scan-line polygon fill in numpy with the rule of ``gdal_rasterize`` (no
ALL_TOUCHED): a cell belongs to a polygon when its centre is inside it. For every edge and every
raster row whose centre line the edge crosses (lower end included, upper end excluded), the
crossing's x gives the first cell whose centre lies right of it, ``floor(x + 0.5)`` in pixel
coordinates. Instead of sorting crossings into spans per polygon and row, each crossing adds the
edge's winding contribution (+1 or -1 by its direction, rings oriented so that the inside has
winding +1, holes -1) into a difference raster; a cumulative sum along each row then gives, at
every cell, the number of polygons whose inside holds its centre. For simple rings this is the
even-odd fill GDAL performs, with the same boundary rule, so the counts are identical.

The difference raster is the count raster itself (unsigned, modular arithmetic: a -1 is 65535
and wraps back), so memory is the raster plus the crossings of one chunk of edges.

Grid: north-up, ``west_m``/``north_m`` the outer corner of the top-left cell, rows from north.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeAlias

import numpy as np
import rasterio
import rasterio.features
import rasterio.windows
import shapely
from numpy.typing import ArrayLike, NDArray
from pyproj import CRS
from rasterio.transform import Affine
from shapely.geometry import Polygon, shape
from shapely.geometry.base import BaseGeometry

from .errors import ProcessingError

logger = logging.getLogger(__name__)

F64 = NDArray[np.float64]
Progress = Callable[[int, int], None]

#: Shares reported by :func:`coverage_stats`: the area seen by at least this many frames.
VIEW_THRESHOLDS = (1, 2, 3, 5, 9)
#: Crossings processed at once: bounds the temporary memory (about 100 bytes each) and keeps
#: the scattered additions in cache (faster than larger chunks).
DEFAULT_CHUNK_CROSSINGS = 100_000
_MAX_CELLS = 400_000_000


@dataclass(frozen=True, kw_only=True)
class Grid:
    """A north-up raster grid in a projected CRS (metres).

    ``west_m``, ``north_m``: outer corner of the top-left cell; ``cell_m``: square cell size;
    ``rows``, ``cols``: shape; ``crs``: the CRS of x, y (None only in tests of pure geometry).
    """

    west_m: float
    north_m: float
    cell_m: float
    rows: int
    cols: int
    crs: CRS | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.cell_m) and self.cell_m > 0):
            raise ProcessingError(f"grid cell_m = {self.cell_m!r} must be a positive number of metres")
        if not (math.isfinite(self.west_m) and math.isfinite(self.north_m)):
            raise ProcessingError(f"grid origin ({self.west_m}, {self.north_m}) is not finite")
        if self.rows < 1 or self.cols < 1:
            raise ProcessingError(f"grid shape {self.rows} x {self.cols} is empty")
        if self.rows * self.cols > _MAX_CELLS:
            raise ProcessingError(
                f"grid of {self.rows} x {self.cols} cells exceeds {_MAX_CELLS:,} cells; use a larger "
                f"cell size (now {self.cell_m} m)"
            )

    @classmethod
    def from_bounds(
        cls, bounds: tuple[float, float, float, float], cell_m: float, crs: CRS | None = None
    ) -> Grid:
        """The grid of ``cell_m`` cells covering (xmin, ymin, xmax, ymax), snapped outward to
        multiples of ``cell_m`` so rasters of one block line up."""
        xmin, ymin, xmax, ymax = (float(v) for v in bounds)
        if not (cell_m > 0 and math.isfinite(cell_m)):
            raise ProcessingError(f"cell_m = {cell_m!r} must be a positive number of metres")
        if not (xmax > xmin and ymax > ymin):
            raise ProcessingError(f"bounds {bounds} are empty; expected (xmin, ymin, xmax, ymax)")
        west = math.floor(xmin / cell_m) * cell_m
        north = math.ceil(ymax / cell_m) * cell_m
        cols = max(1, math.ceil((xmax - west) / cell_m - 1e-9))
        rows = max(1, math.ceil((north - ymin) / cell_m - 1e-9))
        return cls(west_m=west, north_m=north, cell_m=float(cell_m), rows=rows, cols=cols, crs=crs)

    @property
    def shape(self) -> tuple[int, int]:
        return self.rows, self.cols

    @property
    def transform(self) -> Affine:
        """The GDAL geotransform as a rasterio Affine (pixel corner -> x, y)."""
        return Affine(self.cell_m, 0.0, self.west_m, 0.0, -self.cell_m, self.north_m)

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        return (
            self.west_m,
            self.north_m - self.rows * self.cell_m,
            self.west_m + self.cols * self.cell_m,
            self.north_m,
        )

    @property
    def cell_area_m2(self) -> float:
        return self.cell_m * self.cell_m

    def cell_centres(self) -> tuple[F64, F64]:
        """x of each column's centre (cols,), y of each row's centre (rows,)."""
        x = self.west_m + (np.arange(self.cols, dtype=np.float64) + 0.5) * self.cell_m
        y = self.north_m - (np.arange(self.rows, dtype=np.float64) + 0.5) * self.cell_m
        return x.astype(np.float64), y.astype(np.float64)


@dataclass(frozen=True, kw_only=True)
class ViewCount:
    """How many footprints hold each cell's centre: ``counts`` (rows, cols), unsigned."""

    counts: NDArray[np.unsignedinteger[Any]]
    grid: Grid

    def __post_init__(self) -> None:
        if self.counts.shape != self.grid.shape:
            raise ValueError(f"ViewCount.counts has shape {self.counts.shape}, grid is {self.grid.shape}")


# --- rings -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Rings:
    """Polygon rings packed end to end: vertices (P, 2), each ring's start and length, its weight
    (+1 an outer ring, -1 a hole) and the polygon it belongs to."""

    xy: F64
    start: NDArray[np.intp]
    length: NDArray[np.intp]
    weight: NDArray[np.int64]
    owner: NDArray[np.intp]


PolygonsLike: TypeAlias = ArrayLike | Sequence[BaseGeometry] | BaseGeometry


def _rings(polygons: PolygonsLike) -> _Rings:
    """Rings of (N, V, 2) vertex arrays (one simple ring per polygon) or shapely geometries."""
    if isinstance(polygons, BaseGeometry):
        polygons = [polygons]
    if (isinstance(polygons, np.ndarray) and polygons.dtype != object) or (
        isinstance(polygons, list | tuple) and polygons and not isinstance(polygons[0], BaseGeometry)
    ):
        xy = np.asarray(polygons, dtype=float)
        if xy.ndim == 2:
            xy = xy[None]
        if xy.ndim != 3 or xy.shape[2] != 2:
            raise ValueError(f"polygon vertices have shape {xy.shape}, expected (N, V, 2)")
        if not np.isfinite(xy).all():
            raise ProcessingError(
                "polygon vertices hold NaN or infinite values; drop invalid footprints first"
            )
        n, v = xy.shape[:2]
        return _Rings(
            xy=xy.reshape(-1, 2),
            start=np.arange(n, dtype=np.intp) * v,
            length=np.full(n, v, dtype=np.intp),
            weight=np.ones(n, dtype=np.int64),
            owner=np.arange(n, dtype=np.intp),
        )
    geoms = np.asarray(polygons if isinstance(polygons, np.ndarray) else list(polygons), dtype=object)  # type: ignore[arg-type]
    if geoms.size == 0:
        return _Rings(
            np.zeros((0, 2)), *(np.zeros(0, dtype=np.intp),) * 2, np.zeros(0, np.int64), np.zeros(0, np.intp)
        )
    parts, part_owner = shapely.get_parts(geoms, return_index=True)
    keep = shapely.get_type_id(parts) == 3  # polygons only
    parts, part_owner = parts[keep], part_owner[keep]
    rings, ring_part = shapely.get_rings(parts, return_index=True)
    is_outer = np.ones(len(rings), dtype=bool)
    is_outer[1:] = ring_part[1:] != ring_part[:-1]
    coords, ring_of = shapely.get_coordinates(rings, return_index=True)
    counts = np.bincount(ring_of, minlength=len(rings)).astype(np.intp)
    start = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.intp)
    return _Rings(
        xy=np.asarray(coords, float),
        start=start,
        length=counts,
        weight=np.where(is_outer, 1, -1).astype(np.int64),
        owner=part_owner[ring_part].astype(np.intp),
    )


def _pixel_xy(xy: F64, grid: Grid) -> tuple[F64, F64]:
    # The same arithmetic as GDAL's inverse geotransform, so ties fall the same way.
    inv = 1.0 / grid.cell_m
    px = -grid.west_m * inv + xy[:, 0] * inv
    py = grid.north_m * inv + xy[:, 1] * -inv
    return px, py


@dataclass(frozen=True)
class _Edges:
    """Non-horizontal edges in pixel coordinates, lower end (smaller row coordinate) first."""

    x_lo: F64
    y_lo: F64
    x_hi: F64
    y_hi: F64
    row_start: NDArray[np.int64]
    n_rows: NDArray[np.int64]
    contribution: NDArray[np.int64]  # winding contribution of the ring's polygon (0 if degenerate)
    owner: NDArray[np.intp]


def _edges(rings: _Rings, grid: Grid) -> _Edges:
    px, py = _pixel_xy(rings.xy, grid)
    total = len(px)
    nxt = np.arange(1, total + 1, dtype=np.intp)
    if total:
        nxt[rings.start + rings.length - 1] = rings.start
    ring_of = np.repeat(np.arange(len(rings.start)), rings.length)
    # Orientation of each ring in pixel space (signed area, shoelace), so every ring's inside has
    # winding +1 whatever way it was drawn.
    cross = px * py[nxt] - px[nxt] * py
    signed = np.bincount(ring_of, weights=cross, minlength=len(rings.start))
    orient = np.sign(signed).astype(np.int64) * rings.weight
    x1, y1, x2, y2 = px, py, px[nxt], py[nxt]
    going_down = y2 > y1  # row coordinate grows southward
    keep = (y1 != y2) & (orient[ring_of] != 0)
    direction = np.where(going_down, 1, -1)
    contribution = (-direction * orient[ring_of])[keep]
    x_lo = np.where(going_down, x1, x2)[keep]
    y_lo = np.where(going_down, y1, y2)[keep]
    x_hi = np.where(going_down, x2, x1)[keep]
    y_hi = np.where(going_down, y2, y1)[keep]
    # Rows whose centre line (row + 0.5) satisfies y_lo <= row + 0.5 < y_hi, inside the raster.
    first = np.clip(np.ceil(y_lo - 0.5), 0, grid.rows).astype(np.int64)
    stop = np.clip(np.ceil(y_hi - 0.5), 0, grid.rows).astype(np.int64)
    n_rows = np.maximum(stop - first, 0)
    return _Edges(x_lo, y_lo, x_hi, y_hi, first, n_rows, contribution, rings.owner[ring_of][keep])


def _chunks(n_rows: NDArray[np.int64], budget: int) -> list[tuple[int, int]]:
    """Split edges into consecutive runs of at most ``budget`` crossings (one edge may exceed it)."""
    ends = np.cumsum(n_rows)
    out: list[tuple[int, int]] = []
    begin = 0
    done = 0
    while begin < len(n_rows):
        end = int(np.searchsorted(ends, done + budget, side="right"))
        end = max(end, begin + 1)
        out.append((begin, end))
        done = int(ends[end - 1])
        begin = end
    return out


def _crossings(edges: _Edges, sel: slice, grid: Grid) -> tuple[NDArray[np.intp], NDArray[np.int64], F64]:
    """(edge index within ``sel``, row, x of the crossing) for every crossing of the edges."""
    counts = edges.n_rows[sel]
    total = int(counts.sum())
    local = np.repeat(np.arange(len(counts), dtype=np.intp), counts)
    first_of_edge = np.cumsum(counts) - counts
    rows = edges.row_start[sel][local] + (np.arange(total, dtype=np.int64) - first_of_edge[local])
    x_lo, y_lo = edges.x_lo[sel][local], edges.y_lo[sel][local]
    dx = edges.x_hi[sel][local] - x_lo
    dy = edges.y_hi[sel][local] - y_lo
    # GDAL's expression: (dy - dy1) * (dx2 - dx1) / (dy2 - dy1) + dx1.
    x = (rows + 0.5 - y_lo) * dx / dy + x_lo
    return local, rows, x


def count_raster(
    polygons: PolygonsLike,
    grid: Grid,
    *,
    progress: Progress | None = None,
    chunk_crossings: int = DEFAULT_CHUNK_CROSSINGS,
) -> NDArray[np.unsignedinteger[Any]]:
    """How many of ``polygons`` hold each cell centre of ``grid``, (rows, cols).

    ``polygons``: (N, V, 2) vertex rings in the grid's CRS, or shapely (multi)polygons (holes
    subtract). uint16 while N < 65536, else uint32. ``progress(done, total)`` is called per chunk
    of edges.
    """
    rings = _rings(polygons)
    n_polygons = int(rings.owner.max()) + 1 if len(rings.owner) else 0
    dtype: type[np.unsignedinteger[Any]] = np.uint16 if n_polygons < np.iinfo(np.uint16).max else np.uint32
    counts = np.zeros(grid.shape, dtype=dtype)
    flat = counts.reshape(-1)
    edges = _edges(rings, grid)
    chunks = _chunks(edges.n_rows, chunk_crossings)
    for begin, end in chunks:
        sel = slice(begin, end)
        local, rows, x = _crossings(edges, sel, grid)
        col = np.floor(x + 0.5)
        # A crossing right of the raster changes no cell; one left of it changes them all.
        inside = col < grid.cols
        col = np.maximum(col[inside], 0).astype(np.int64)
        index = rows[inside] * grid.cols + col
        values = edges.contribution[sel][local[inside]].astype(dtype)  # -1 wraps to the maximum
        np.add.at(flat, index, values)
        if progress is not None:
            progress(end, len(edges.n_rows))
    np.cumsum(counts, axis=1, dtype=dtype, out=counts)
    return counts


def view_count_raster(
    footprints_xy: PolygonsLike,
    bounds: tuple[float, float, float, float] | Grid,
    cell_m: float | None = None,
    *,
    crs: CRS | None = None,
    progress: Progress | None = None,
) -> ViewCount:
    """Views per cell: how many footprints hold each cell centre (``gdal_rasterize -add -burn 1``).

    ``footprints_xy``: (N, V, 2) rings in local metres (:attr:`Footprints.xy_m`; invalid frames'
    collapsed rings count nowhere). ``bounds``: (xmin, ymin, xmax, ymax) in metres, snapped outward
    to ``cell_m``, or a ready :class:`Grid`.
    """
    if isinstance(bounds, Grid):
        grid = bounds
    else:
        if cell_m is None:
            raise ProcessingError("view_count_raster needs cell_m with bounds; give the cell size in metres")
        grid = Grid.from_bounds(bounds, cell_m, crs)
    return ViewCount(counts=count_raster(footprints_xy, grid, progress=progress), grid=grid)


def area_mask(area_polygon_xy: PolygonsLike, grid: Grid) -> NDArray[np.bool_]:
    """Cells whose centre is inside the area (a shapely polygon with holes, or (V, 2) vertices)."""
    if not isinstance(area_polygon_xy, BaseGeometry) and not (
        isinstance(area_polygon_xy, list | tuple | np.ndarray)
        and len(area_polygon_xy)
        and isinstance(np.asarray(area_polygon_xy, dtype=object).flat[0], BaseGeometry)
    ):
        area_polygon_xy = Polygon(np.asarray(area_polygon_xy, float))
    counts = count_raster(area_polygon_xy, grid)
    # Overlapping parts count more than once, and a hole only takes back its own polygon's one:
    # inside the area is any positive count.
    return counts > 0


def min_value_raster(
    polygons_xy: ArrayLike, values: ArrayLike, grid: Grid, *, chunk_cells: int = 4_000_000
) -> F64:
    """The smallest value among the polygons holding each cell centre; NaN where none does.

    ``polygons_xy``: (N, V, 2) simple rings; ``values``: (N,). Same cell rule as
    :func:`count_raster`; spans are formed by pairing each row's sorted crossings per polygon.
    """
    xy = np.asarray(polygons_xy, float)
    vals = np.asarray(values, float)
    if xy.ndim != 3 or xy.shape[2] != 2 or vals.shape != (xy.shape[0],):
        raise ValueError(f"polygons_xy {xy.shape} and values {vals.shape} must be (N, V, 2) and (N,)")
    out = np.full(grid.rows * grid.cols, np.inf)
    use = np.isfinite(vals) & np.isfinite(xy).all(axis=(1, 2))
    index_of = np.flatnonzero(use)
    if index_of.size:
        extent = xy[index_of].max(axis=1) - xy[index_of].min(axis=1)
        cells = (extent[:, 0] / grid.cell_m + 2) * (extent[:, 1] / grid.cell_m + 2)
        ends = np.cumsum(cells)
        begin = 0
        while begin < index_of.size:
            done = ends[begin - 1] if begin else 0.0
            end = max(int(np.searchsorted(ends, done + chunk_cells, side="right")), begin + 1)
            _burn_min(out, xy[index_of[begin:end]], vals[index_of[begin:end]], grid)
            begin = end
    out[np.isinf(out)] = np.nan
    return out.reshape(grid.shape)


def _burn_min(out: F64, xy: F64, vals: F64, grid: Grid) -> None:
    rings = _rings(xy)
    edges = _edges(rings, grid)
    local, rows, x = _crossings(edges, slice(0, len(edges.n_rows)), grid)
    owner = edges.owner[local]
    order = np.lexsort((x, rows, owner))
    owner, rows, x = owner[order], rows[order], x[order]
    # Each polygon crosses each row an even number of times; consecutive pairs are the spans.
    start = np.clip(np.floor(x[0::2] + 0.5), 0, grid.cols).astype(np.int64)
    stop = np.clip(np.floor(x[1::2] + 0.5), 0, grid.cols).astype(np.int64)
    span_rows, span_owner = rows[0::2], owner[0::2]
    length = np.maximum(stop - start, 0)
    total = int(length.sum())
    if total == 0:
        return
    span = np.repeat(np.arange(len(length)), length)
    first = np.cumsum(length) - length
    cols = start[span] + (np.arange(total) - first[span])
    np.minimum.at(out, span_rows[span] * grid.cols + cols, vals[span_owner[span]])


# --- statistics and gaps ---------------------------------------------------------------------


def coverage_stats(view_count: ViewCount | NDArray[Any], area_mask: NDArray[np.bool_]) -> dict[str, Any]:
    """Coverage of the area: its size, and the share seen by at least 1, 2, 3, 5 and 9 frames.

    Returns ``{"area_m2", "cells", "views_median", "views_max", "seen_by_at_least_pct":
    {"1": pct, "2": ..., "9": ...}}`` (percent of the area's cells).
    """
    counts = view_count.counts if isinstance(view_count, ViewCount) else np.asarray(view_count)
    if counts.shape != area_mask.shape:
        raise ValueError(f"view count {counts.shape} and area mask {area_mask.shape} differ in shape")
    inside = counts[area_mask]
    cells = int(inside.size)
    cell_area = view_count.grid.cell_area_m2 if isinstance(view_count, ViewCount) else float("nan")
    if cells == 0:
        raise ProcessingError("the area covers no cell centre of the grid; use a smaller cell size")
    histogram = np.bincount(inside.astype(np.int64))
    at_least = np.cumsum(histogram[::-1])[::-1]
    shares = {
        str(k): (100.0 * float(at_least[k]) / cells if k < len(at_least) else 0.0) for k in VIEW_THRESHOLDS
    }
    return {
        "area_m2": cells * cell_area,
        "cells": cells,
        "views_median": float(np.median(inside)),
        "views_max": int(inside.max()),
        "seen_by_at_least_pct": shares,
    }


def gap_polygons(
    view_count: ViewCount | NDArray[Any],
    area_mask: NDArray[np.bool_],
    grid: Grid | None = None,
    *,
    min_views: int = 1,
    min_area_m2: float = 1.0,
) -> list[Polygon]:
    """Parts of the area seen by fewer than ``min_views`` frames, as polygons (grid CRS), largest first.

    Cells below ``min_views`` inside the area are vectorized (rasterio.features.shapes,
    8-connected: cells that touch at a corner, as along a diagonal sliver, are one gap);
    polygons smaller than ``min_area_m2`` are dropped.
    Cells outside the area, such as turns between lines, are never gaps.
    """
    if grid is None:
        if not isinstance(view_count, ViewCount):
            raise ProcessingError("gap_polygons needs the grid of a plain count array")
        grid = view_count.grid
    counts = view_count.counts if isinstance(view_count, ViewCount) else np.asarray(view_count)
    low = (counts < min_views) & area_mask
    if not low.any():
        return []
    gaps: list[Polygon] = []
    for geometry, value in rasterio.features.shapes(
        low.astype(np.uint8), mask=low, transform=grid.transform, connectivity=8
    ):
        if value != 1:
            continue
        polygon = shape(geometry)
        if polygon.area >= min_area_m2:
            gaps.append(polygon)
    gaps.sort(key=lambda p: p.area, reverse=True)
    return gaps
