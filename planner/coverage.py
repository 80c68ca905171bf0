"""How many frames of a pass see each part of the area: the stereo figures of summary.json.

In the pass frame every frame surely covers the rectangle ``[u + u_min, u + u_max] x
[v + v_min, v + v_max]`` around its station (planner.exposure.FrameRectangle), so the number of
frames that see a point (pu, pv) is, summed over the runs whose band of v holds pv, the number
of the run's stations with u in ``[pu - u_max, pu - u_min]`` (two binary searches). The area is
sampled on a jittered grid (cells of an eighth of the smaller of the trigger distance and the line
spacing, at most about a million points), so the shares are area shares to within the sampling.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon

from .exposure import FrameRectangle

if TYPE_CHECKING:  # planner.lines counts the views of its segments with this module
    from .lines import Segment

_MAX_POINTS = 1_000_000


@dataclass(frozen=True, kw_only=True)
class ViewShares:
    """Shares (percent) of the area seen by at least one, two and three frames of a pass."""

    seen_1_pct: float
    seen_2_pct: float
    seen_3_pct: float
    cell_m: float
    #: Points along the area's edge (every metre) seen by fewer than two frames.
    edge_weak_points: int = 0


def view_counts(
    points_uv: NDArray[np.float64], segments: Sequence[Segment], rect: FrameRectangle
) -> NDArray[np.int64]:
    """Number of the segments' frames whose rectangle holds each point (pass frame).

    The points are sorted by v once, so that each segment's band of v is one slice of them;
    in it the stations below each point's u range are counted by :func:`_stations_below`."""
    pu, pv = points_uv[:, 0], points_uv[:, 1]
    order = np.argsort(pv, kind="stable")
    pv_sorted = pv[order]
    pu_sorted = pu[order]
    counts_sorted = np.zeros(len(points_uv), np.int64)
    finite = bool(np.isfinite(pu).all())
    for seg in segments:
        lo = np.searchsorted(pv_sorted, seg.v_m + rect.v_min_m - 1e-9, side="left")
        hi = np.searchsorted(pv_sorted, seg.v_m + rect.v_max_m + 1e-9, side="right")
        if hi <= lo:
            continue
        band = pu_sorted[lo:hi]
        u = seg.u_first_m + np.arange(seg.count) * seg.spacing_m
        first = _stations_below(u, seg, band - rect.u_max_m - 1e-9, finite, inclusive=False)
        last = _stations_below(u, seg, band - rect.u_min_m + 1e-9, finite, inclusive=True)
        counts_sorted[lo:hi] += last - first
    counts = np.empty_like(counts_sorted)
    counts[order] = counts_sorted
    return counts


def _stations_below(
    u: NDArray[np.floating], seg: Segment, x: NDArray[np.floating], finite: bool, *, inclusive: bool
) -> NDArray[np.intp]:
    """How many of the stations ``u`` (``seg``'s, ascending) lie below each ``x`` (``inclusive``:
    at or below): ``np.searchsorted(u, x, side)``, exactly.

    The stations are evenly spaced, so the count is first estimated as ``(x - u_first) /
    spacing`` rounded, then moved one station at a time until the stations on either side of
    it are on the right side of ``x`` (rounding leaves the estimate at most one off, so this
    is usually one step and one check): several times faster than a binary search per point."""
    if not (finite and seg.spacing_m > 0.0 and math.isfinite(seg.spacing_m) and seg.count > 1):
        return np.searchsorted(u, x, side="right" if inclusive else "left")
    n = len(u)
    ext = np.concatenate(([-np.inf], u, [np.inf]))  # ext[k] = u[k - 1], ext[k + 1] = u[k]
    steps = (x - seg.u_first_m) / seg.spacing_m
    estimate = np.floor(steps) + 1.0 if inclusive else np.ceil(steps)
    k = np.clip(estimate, 0, n, out=estimate).astype(np.intp)
    while True:
        # The answer k is the one with ext[k] < x <= ext[k + 1] (inclusive: ext[k] <= x < ext[k + 1]).
        if inclusive:
            too_high, too_low = ext[k] > x, ext[k + 1] <= x
        else:
            too_high, too_low = ext[k] >= x, ext[k + 1] < x
        if not (too_high.any() or too_low.any()):
            return k
        k -= too_high
        k += too_low


def splitmix64_uniform(count: int) -> NDArray[np.float64]:
    """The first ``count`` outputs of SplitMix64 from seed 0 (Steele, Lea and Flood 2014, with
    Vigna's constants, as in his splitmix64.c), as doubles in [0, 1) (their top 53 bits).

    Output k (from 1) is a fixed mix of ``k`` times the golden ratio's 64-bit constant, so the
    whole run is a few operations on an array; numpy.random would give numbers as good, but it
    costs about 10 ms to import, a twentieth of a small plan's whole process."""
    z = np.arange(1, count + 1, dtype=np.uint64)
    shifted = np.empty_like(z)  # in place, one scratch array: new memory is slow to touch
    z *= np.uint64(0x9E3779B97F4A7C15)
    for shift, multiplier in ((30, 0xBF58476D1CE4E5B9), (27, 0x94D049BB133111EB)):
        z ^= np.right_shift(z, np.uint64(shift), out=shifted)
        z *= np.uint64(multiplier)
    z ^= np.right_shift(z, np.uint64(31), out=shifted)
    uniform = np.right_shift(z, np.uint64(11), out=z).astype(np.float64)
    uniform *= 2.0**-53
    return uniform


def grid_points(area_uv: Polygon | MultiPolygon, cell_m: float) -> tuple[NDArray[np.float64], float]:
    """One point in each cell of a regular grid, those inside the area (cell enlarged if needed
    to keep to about a million points)."""
    u0, v0, u1, v1 = area_uv.bounds
    cells = (u1 - u0) * (v1 - v0) / (cell_m * cell_m)
    if cells > _MAX_POINTS:
        cell_m *= math.sqrt(cells / _MAX_POINTS)
    us = np.arange(u0 + cell_m / 2, u1, cell_m)
    vs = np.arange(v0 + cell_m / 2, v1, cell_m)
    gu, gv = np.meshgrid(us, vs)
    # One point at random in each cell (a fixed seed: the same plan gives the same figures), so
    # that the regular pattern of the frames cannot alias with the grid.
    jitter = splitmix64_uniform(2 * gu.size).reshape(2, gu.size)
    jitter -= 0.5
    jitter *= cell_m
    gu, gv = gu.ravel() + jitter[0], gv.ravel() + jitter[1]
    inside = shapely.contains_xy(area_uv, gu, gv)
    return np.column_stack([gu[inside], gv[inside]]), cell_m


def view_shares(
    area_uv: Polygon | MultiPolygon,
    segments: Sequence[Segment],
    rect: FrameRectangle,
    trigger_distance_m: float,
    line_spacing_m: float,
) -> ViewShares:
    """Shares of the area seen by >= 1, 2, 3 frames of one pass (module docstring)."""
    points, cell = grid_points(area_uv, min(trigger_distance_m, line_spacing_m) / 8.0)
    if len(points) == 0:
        # An area smaller than a cell: sample its representative point.
        p = area_uv.representative_point()
        points = np.array([[p.x, p.y]])
    counts = view_counts(points, segments, rect)
    n = len(counts)
    edge = boundary_points(area_uv, 1.0)
    edge_weak = int(np.count_nonzero(view_counts(edge, segments, rect) < 2)) if len(edge) else 0
    return ViewShares(
        edge_weak_points=edge_weak,
        seen_1_pct=100.0 * np.count_nonzero(counts >= 1) / n,
        seen_2_pct=100.0 * np.count_nonzero(counts >= 2) / n,
        seen_3_pct=100.0 * np.count_nonzero(counts >= 3) / n,
        cell_m=cell,
    )


def boundary_points(area_uv: Polygon | MultiPolygon, step_m: float) -> NDArray[np.float64]:
    """Points every ``step_m`` along the area's outer and inner rings (its edges, where a grid
    sees least)."""
    polygons = getattr(area_uv, "geoms", [area_uv])
    rings = [r for p in polygons for r in (p.exterior, *p.interiors)]
    parts = [shapely.get_coordinates(r.interpolate(np.arange(0.0, r.length, step_m))) for r in rings]
    return np.vstack(parts) if parts else np.zeros((0, 2))
