"""Block geometry for reconstruction: overlapping pairs, base-height ratios, convergence, scale.

Everything is measured on the footprints of :mod:`processing.footprints`, in the local frame
(metres, x east, y north, z the frames' altitude reference).

- Pairs: every two frames whose footprints overlap (shapely STRtree). For each: the base (3D
  distance between the camera centres), the height above the common ground point (the centroid
  of the footprints' intersection, on the ground model), B/H, the intersection angle of the two
  rays to that point, each footprint's share in the intersection, and the scale (GSD) ratio.
- Flight lines and the overlaps along and across them: :mod:`processing.flight_lines`.
- Convergence: the share of frames more than 10 deg off nadir; none at all is a doming risk
  (James and Robson 2014, REFERENCES.md section 1).
- Frames whose GSD differs from the median of their overlapping neighbours' by more than 10 %.
- A good B/H range, 0.1-0.54 by default (intersection angles of about 6-30 deg; Wenzel et al.
  2013): the share of the area where at least one pair in that range overlaps, among the frames
  of one line and the nearest frames of neighbouring lines (every overlapping pair when there
  are none).
- Ground speed and motion blur: :mod:`processing.motion_blur`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray

from planner.geo import LocalFrame

from .coverage import Grid, count_raster, min_value_raster
from .errors import ProcessingError
from .footprints import Footprints
from .ground import Ground

F64 = NDArray[np.float64]

#: Default good range of B/H (REFERENCES.md section 1): below 0.1 depth is poorly determined,
#: above 0.54 (about 30 deg of intersection) matching degrades.
GOOD_BASE_HEIGHT_RATIO = (0.1, 0.54)
CONVERGENT_OFF_NADIR_DEG = 10.0
SCALE_TOLERANCE = 0.10


@dataclass(frozen=True, kw_only=True)
class Pairs:
    """Overlapping frame pairs (i < j), one row per pair; see the module docstring.

    ``ground_xyz_m``: the common ground point; ``overlap_i_pct`` / ``overlap_j_pct``: the
    intersection's share of each footprint; ``scale_ratio``: coarser GSD / finer GSD (>= 1);
    ``intersection``: (M, 8, 2) vertices of each overlap (counter-clockwise, padded by repeating
    the last vertex), ready for :func:`processing.coverage.count_raster`.
    """

    i: NDArray[np.intp]
    j: NDArray[np.intp]
    base_m: F64
    height_m: F64
    base_height_ratio: F64
    intersection_angle_deg: F64
    overlap_i_pct: F64
    overlap_j_pct: F64
    scale_ratio: F64
    ground_xyz_m: F64
    intersection: F64

    def __len__(self) -> int:
        return int(self.i.shape[0])


#: Vertices of a pair's intersection: two convex quadrilaterals meet in at most 8.
_MAX_INTERSECTION_VERTICES = 8
_PAIR_CHUNK = 50_000


def _signed_area_m2(ring: F64) -> F64:
    # Relative to a vertex: with UTM coordinates (1e5-1e7 m) the shoelace would lose centimetres.
    local = ring - ring[..., :1, :]
    x, y = local[..., 0], local[..., 1]
    return np.asarray(0.5 * np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1))


def _convex_corners(footprints: Footprints) -> F64:
    """Each footprint's four corners as a counter-clockwise convex quadrilateral, (N, 4, 2).

    On flat ground the footprint is exactly this quadrilateral; over relief the edge samples
    are dropped (pair geometry needs the overlap's size and centre, not its outline). A
    quadrilateral that is not convex (a pose far from any survey's) is replaced by its hull.
    """
    step = footprints.edge_samples + 1
    quads = np.array(footprints.xy_m[:, ::step, :], dtype=float)
    flip = _signed_area_m2(quads) < 0
    quads[flip] = quads[flip, ::-1]
    edge = np.roll(quads, -1, axis=1) - quads
    turn = edge[..., 0] * np.roll(edge, -1, axis=1)[..., 1] - edge[..., 1] * np.roll(edge, -1, axis=1)[..., 0]
    for k in np.flatnonzero((turn < 0).any(axis=1) & footprints.valid):
        hull = np.asarray(shapely.convex_hull(shapely.multipoints(quads[k])).exterior.coords)[:-1]
        hull = hull if _signed_area_m2(hull) > 0 else hull[::-1]
        quads[k] = np.vstack([hull, np.repeat(hull[-1:], 4 - len(hull), axis=0)])[:4]
    return quads


def _clip_convex(subject: F64, clip: F64) -> tuple[F64, NDArray[np.int64]]:
    """Sutherland-Hodgman, vectorized: each convex CCW ``subject`` (M, 4, 2) clipped by the
    convex CCW ``clip`` (M, 4, 2). Returns the vertices (M, 8, 2), padded by repeating the last
    one (zero-length edges, harmless to areas and to the rasterizer), and their counts."""
    m = subject.shape[0]
    poly = subject
    count = np.full(m, 4, dtype=np.int64)
    rows = np.arange(m)[:, None]
    for e in range(4):
        # Clipping a convex polygon by a half-plane adds at most one vertex.
        width = poly.shape[1]
        slots = np.arange(width)
        a = clip[:, e][:, None, :]
        edge = (clip[:, (e + 1) % 4] - clip[:, e])[:, None, :]
        nxt = np.where(slots[None, :] + 1 < count[:, None], slots[None, :] + 1, 0)
        p = poly
        q = poly[rows, nxt]
        dp = edge[..., 0] * (p[..., 1] - a[..., 1]) - edge[..., 1] * (p[..., 0] - a[..., 0])
        dq = edge[..., 0] * (q[..., 1] - a[..., 1]) - edge[..., 1] * (q[..., 0] - a[..., 0])
        present = slots[None, :] < count[:, None]
        keep = present & (dp >= 0)
        crosses = present & ((dp >= 0) != (dq >= 0))
        t = np.where(crosses, dp / np.where(crosses, dp - dq, 1.0), 0.0)
        crossing = p + t[..., None] * (q - p)
        candidates = np.stack([p, crossing], axis=2).reshape(m, 2 * width, 2)
        emitted = np.stack([keep, crosses], axis=2).reshape(m, 2 * width)
        # Compact each row's emitted vertices to its front, in order.
        position = np.cumsum(emitted, axis=1) - 1
        out_width = width + 1
        emitted &= position < out_width
        r, c = np.nonzero(emitted)
        poly = np.empty((m, out_width, 2))
        poly[r, position[r, c]] = candidates[r, c]
        count = emitted.sum(axis=1)
        last = poly[np.arange(m), np.maximum(count - 1, 0)]
        last = np.where((count > 0)[:, None], last, subject[:, 0])
        pad = np.arange(out_width)[None, :] >= count[:, None]
        poly = np.where(pad[..., None], last[:, None, :], poly)
    return poly, count


def _polygon_area_centroid(poly: F64) -> tuple[F64, F64]:
    """Area (m2, >= 0) and centroid (M, 2) of CCW rings (padding contributes nothing)."""
    origin = poly[:, 0, :]
    local = poly - origin[:, None, :]
    x, y = local[..., 0], local[..., 1]
    xn, yn = np.roll(x, -1, axis=1), np.roll(y, -1, axis=1)
    cross = x * yn - xn * y
    area = 0.5 * cross.sum(axis=1)
    safe = np.where(np.abs(area) > 1e-12, area, 1.0)
    cx = ((x + xn) * cross).sum(axis=1) / (6.0 * safe)
    cy = ((y + yn) * cross).sum(axis=1) / (6.0 * safe)
    centre = np.where((np.abs(area) > 1e-12)[:, None], np.column_stack([cx, cy]) + origin, poly.mean(axis=1))
    return np.abs(area), centre


def overlapping_pairs(
    footprints: Footprints, ground: Ground, frame: LocalFrame, *, min_overlap_pct: float = 0.1
) -> Pairs:
    """All pairs of valid frames whose footprints overlap by at least ``min_overlap_pct`` of the
    smaller one's area.

    Candidates come from an STRtree of the footprints' bounding boxes; the overlaps are clipped
    in numpy on the corner quadrilaterals (:func:`_convex_corners`: exact on flat ground), so
    hundreds of thousands of pairs take seconds, not the minutes GEOS overlays would.
    """
    valid = np.flatnonzero(footprints.valid)
    quads = _convex_corners(footprints)
    quad_area = np.abs(_signed_area_m2(quads))
    boxes = shapely.box(
        quads[valid, :, 0].min(axis=1),
        quads[valid, :, 1].min(axis=1),
        quads[valid, :, 0].max(axis=1),
        quads[valid, :, 1].max(axis=1),
    )
    tree = shapely.STRtree(boxes)
    a, b = tree.query(boxes, predicate="intersects")
    keep = a < b
    i_all, j_all = valid[a[keep]], valid[b[keep]]
    parts: list[tuple[NDArray[np.intp], NDArray[np.intp], F64, F64, F64]] = []
    for start in range(0, len(i_all), _PAIR_CHUNK):
        i = i_all[start : start + _PAIR_CHUNK]
        j = j_all[start : start + _PAIR_CHUNK]
        poly, _ = _clip_convex(quads[i], quads[j])
        area, centre = _polygon_area_centroid(poly)
        smaller = np.minimum(quad_area[i], quad_area[j])
        ok = area >= smaller * min_overlap_pct / 100.0
        parts.append((i[ok], j[ok], poly[ok], area[ok], centre[ok]))
    if parts:
        i = np.concatenate([p[0] for p in parts])
        j = np.concatenate([p[1] for p in parts])
        inter = np.concatenate([p[2] for p in parts])
        area = np.concatenate([p[3] for p in parts])
        centroid = np.concatenate([p[4] for p in parts])
    else:
        i = j = np.zeros(0, dtype=np.intp)
        inter, area, centroid = np.zeros((0, _MAX_INTERSECTION_VERTICES, 2)), np.zeros(0), np.zeros((0, 2))
    share_i = 100.0 * area / quad_area[i]
    share_j = 100.0 * area / quad_area[j]
    ground_z = ground.elevation_at(centroid[:, 0], centroid[:, 1], frame) if len(i) else np.zeros(0)
    point = np.column_stack([centroid, ground_z])
    cam_i = footprints.camera_xyz_m[i]
    cam_j = footprints.camera_xyz_m[j]
    base = np.linalg.norm(cam_i - cam_j, axis=1)
    height = 0.5 * (cam_i[:, 2] + cam_j[:, 2]) - ground_z
    ray_i = point - cam_i
    ray_j = point - cam_j
    cos_angle = np.sum(ray_i * ray_j, axis=1) / (
        np.linalg.norm(ray_i, axis=1) * np.linalg.norm(ray_j, axis=1)
    )
    angle = np.degrees(np.arccos(np.clip(cos_angle, -1.0, 1.0)))
    gsd_i, gsd_j = footprints.gsd_cm[i], footprints.gsd_cm[j]
    return Pairs(
        i=i.astype(np.intp),
        j=j.astype(np.intp),
        base_m=base,
        height_m=height,
        base_height_ratio=base / height,
        intersection_angle_deg=angle,
        overlap_i_pct=share_i,
        overlap_j_pct=share_j,
        scale_ratio=np.maximum(gsd_i, gsd_j) / np.minimum(gsd_i, gsd_j),
        ground_xyz_m=point,
        intersection=inter,
    )


def off_nadir_deg(footprints: Footprints) -> F64:
    """Angle of each optical axis from the vertical, degrees."""
    down = -footprints.world_from_camera[:, 2, 2]
    return np.asarray(np.degrees(np.arccos(np.clip(down, -1.0, 1.0))), float)


def scale_outliers(
    footprints: Footprints, pairs: Pairs, tolerance: float = SCALE_TOLERANCE
) -> NDArray[np.intp]:
    """Frames whose GSD differs by more than ``tolerance`` from the median of their overlapping
    neighbours' GSDs (image scales that differ by more than about 10 % hamper matching)."""
    if len(pairs) == 0:
        return np.zeros(0, dtype=np.intp)
    frame_of = np.concatenate([pairs.i, pairs.j])
    other_gsd = np.concatenate([footprints.gsd_cm[pairs.j], footprints.gsd_cm[pairs.i]])
    order = np.lexsort((other_gsd, frame_of))
    frame_of, other_gsd = frame_of[order], other_gsd[order]
    frames_with, starts, counts = np.unique(frame_of, return_index=True, return_counts=True)
    # The median of each frame's sorted neighbour GSDs: the middle one, or the mean of the two.
    medians = 0.5 * (other_gsd[starts + (counts - 1) // 2] + other_gsd[starts + counts // 2])
    ratio = footprints.gsd_cm[frames_with] / medians
    return frames_with[np.abs(ratio - 1.0) > tolerance].astype(np.intp)


def gsd_raster(footprints: Footprints, grid: Grid) -> F64:
    """The finest GSD (cm) among the frames that see each cell; NaN where none does."""
    use = footprints.valid & np.isfinite(footprints.gsd_cm)
    return min_value_raster(footprints.xy_m[use], footprints.gsd_cm[use], grid)


def good_pair_share_pct(
    pairs: Pairs,
    grid: Grid,
    area_mask: NDArray[np.bool_],
    base_height_range: tuple[float, float] = GOOD_BASE_HEIGHT_RATIO,
    use: NDArray[np.bool_] | None = None,
) -> float:
    """Percent of the area's cells that at least one pair with B/H in range overlaps; ``use``:
    only these pairs count (e.g. those of :func:`pair_kinds` and the same line)."""
    lo, hi = base_height_range
    good = (pairs.base_height_ratio >= lo) & (pairs.base_height_ratio <= hi)
    if use is not None:
        good &= use
    cells = int(area_mask.sum())
    if cells == 0:
        raise ProcessingError("the area covers no cell of the grid; use a smaller cell size")
    if not good.any():
        return 0.0
    counts = count_raster(pairs.intersection[good], grid)
    return 100.0 * float(((counts > 0) & area_mask).sum()) / cells
