"""Block geometry for reconstruction: overlapping pairs, base-height ratios, overlaps, scale, blur.

Everything is measured on the footprints of :mod:`processing.footprints`, in the local frame
(metres, x east, y north, z the frames' altitude reference).

- Pairs: every two frames whose footprints overlap (shapely STRtree). For each: the base (3D
  distance between the camera centres), the height above the common ground point (the centroid
  of the footprints' intersection, on the ground model), B/H, the intersection angle of the two
  rays to that point, each footprint's share in the intersection, and the scale (GSD) ratio.
- Flight lines: time-consecutive frames, broken where the heading turns by more than 30 deg or
  a step exceeds 3 x the median step (the turn between lines is not a gap, it is a break).
- Forward overlap between consecutive frames of a line, side overlap of each frame with the
  union of the neighbouring lines' footprints, as distributions.
- Convergence: the share of frames more than 10 deg off nadir; none at all is a doming risk
  (James and Robson 2014, REFERENCES.md section 1).
- Frames whose GSD differs from the median of their overlapping neighbours' by more than 10 %.
- A good B/H range, 0.1-0.54 by default (intersection angles of about 6-30 deg; Wenzel et al.
  2013): the share of the area where at least one pair in that range overlaps, among the frames
  of one line and the nearest frames of neighbouring lines (every overlapping pair when there
  are none).
- Ground speed per frame (m/s): over the step to its nearer-in-time neighbour on the same flight
  line, unknown when that neighbour is more than 3 x the median capture interval away
  (:func:`ground_speeds_m_s`); motion blur, pixels: speed x exposure time / GSD, when an
  exposure time is known.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray

from planner.geo import LocalFrame

from .coverage import Grid, count_raster, min_value_raster
from .distribution import Distribution
from .errors import ProcessingError
from .footprints import Footprints
from .frames import Frames
from .ground import Ground

logger = logging.getLogger(__name__)

F64 = NDArray[np.float64]

#: Default good range of B/H (REFERENCES.md section 1): below 0.1 depth is poorly determined,
#: above 0.54 (about 30 deg of intersection) matching degrades.
GOOD_BASE_HEIGHT_RATIO = (0.1, 0.54)
CONVERGENT_OFF_NADIR_DEG = 10.0
SCALE_TOLERANCE = 0.10
LINE_BREAK_TURN_DEG = 30.0
LINE_BREAK_JUMP_RATIO = 3.0
#: A line whose nearest frame is within this factor of the nearest other line's is a neighbour.
NEIGHBOUR_LINE_RATIO = 1.5


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


def capture_order(frames: Frames) -> NDArray[np.intp]:
    """Frame indices in capture order: by time when known, else as given (a plan's order)."""
    if frames.time_utc_s is None:
        return np.arange(len(frames), dtype=np.intp)
    return np.argsort(frames.time_utc_s, kind="stable").astype(np.intp)


def flight_lines(
    frames: Frames,
    footprints: Footprints,
    *,
    max_turn_deg: float = LINE_BREAK_TURN_DEG,
    max_jump_ratio: float = LINE_BREAK_JUMP_RATIO,
) -> NDArray[np.int64]:
    """The flight line of each frame (0, 1, ... in capture order).

    The plan's ``line_index`` when the frames carry one (split where a line is interrupted
    by more than ``max_jump_ratio`` x the median step). Otherwise, in capture order, the step
    from one frame to the next stays within a line when it is at most ``max_jump_ratio`` x the
    median step and its heading is within ``max_turn_deg`` of the previous or the next step's
    (a frame taken in a turn agrees with neither and becomes a line of its own); two kept steps
    whose headings differ by more than ``max_turn_deg`` (a sharp corner) also break the line.
    """
    n = len(frames)
    if frames.line_index is not None:
        # The plan's lines, split where one is interrupted (a notch, a hole): the two pieces of
        # a line are not neighbours along it.
        given = np.asarray(frames.line_index, dtype=np.int64)
        if n < 2:
            return given
        order = capture_order(frames)
        step = np.diff(footprints.camera_xyz_m[order, :2], axis=0)
        dist = np.hypot(step[:, 0], step[:, 1])
        same_line = np.diff(given[order]) == 0
        median_step = float(np.median(dist[same_line])) if same_line.any() else 0.0
        breaks = ~same_line | (dist > max_jump_ratio * median_step)
        pieces = np.zeros(n, dtype=np.int64)
        pieces[order] = np.concatenate([[0], np.cumsum(breaks)])
        return pieces
    lines = np.zeros(n, dtype=np.int64)
    if n < 2:
        return lines
    order = capture_order(frames)
    step = np.diff(footprints.camera_xyz_m[order, :2], axis=0)
    dist = np.hypot(step[:, 0], step[:, 1])
    moving = dist > 1e-3
    if not moving.any():
        return lines
    median_step = float(np.median(dist[moving]))
    heading = np.arctan2(step[:, 0], step[:, 1])
    # A hover (no displacement) keeps the heading of the last real step.
    last = np.maximum.accumulate(np.where(moving, np.arange(n - 1), -1))
    heading = np.where(last >= 0, heading[np.maximum(last, 0)], heading)
    cos_limit = math.cos(math.radians(max_turn_deg))
    agree = np.cos(np.diff(heading)) >= cos_limit  # step k+1 agrees with step k
    agree_prev = np.concatenate([[False], agree])
    agree_next = np.concatenate([agree, [False]])
    keep = (dist <= max_jump_ratio * median_step) & (agree_prev | agree_next | (n == 2))
    corner = np.concatenate([[False], keep[:-1] & keep[1:] & ~agree])
    breaks = ~keep | corner
    lines[order] = np.concatenate([[0], np.cumsum(breaks)])
    return lines


def pair_kinds(
    frames: Frames, pairs: Pairs, lines: NDArray[np.int64]
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Which pairs matter for stereo: (along, across). ``along``: consecutive frames of a line
    (next to each other in capture order, same line), the forward-overlap pairs whose B/H the
    plan sets with its endlap; ``across``: a frame and the nearest frame of each other line it
    overlaps, if that line is a neighbouring one (its nearest frame no further than
    :data:`NEIGHBOUR_LINE_RATIO` x the nearest other line's), the side-overlap pairs whose B/H the
    line spacing sets. Other pairs (a frame and the
    one two ahead, diagonal pairs across lines) are neither."""
    order = capture_order(frames)
    rank = np.empty(len(frames), dtype=np.int64)
    rank[order] = np.arange(len(frames))
    same = lines[pairs.i] == lines[pairs.j]
    along = same & (np.abs(rank[pairs.i] - rank[pairs.j]) == 1)
    # Across lines: for each frame and each neighbouring line, the pair with that line's nearest
    # frame (the base is the line spacing there), not every diagonal or farther-line pair.
    across = np.zeros(len(pairs), dtype=bool)
    candidates = np.flatnonzero(~same)
    if candidates.size:
        frame_of = np.concatenate([pairs.i[candidates], pairs.j[candidates]])
        other_line = np.concatenate([lines[pairs.j[candidates]], lines[pairs.i[candidates]]])
        base = np.concatenate([pairs.base_m[candidates], pairs.base_m[candidates]])
        which = np.concatenate([candidates, candidates])
        sort = np.lexsort((base, other_line, frame_of))
        key = np.column_stack([frame_of[sort], other_line[sort]])
        first = np.ones(len(sort), dtype=bool)
        first[1:] = (key[1:] != key[:-1]).any(axis=1)
        nearest = which[sort][first]
        owner = frame_of[sort][first]
        base_nearest = base[sort][first]
        # Only the neighbouring lines: a line two spacings away is as far again as the nearest.
        least = np.full(len(frames), np.inf)
        np.minimum.at(least, owner, base_nearest)
        across[nearest[base_nearest <= NEIGHBOUR_LINE_RATIO * least[owner]]] = True
    return along, across


def forward_overlaps_pct(frames: Frames, footprints: Footprints, lines: NDArray[np.int64]) -> F64:
    """Overlap of each pair of consecutive frames of a line, percent of their mean footprint area."""
    order = capture_order(frames)
    a, b = order[:-1], order[1:]
    same = (lines[a] == lines[b]) & footprints.valid[a] & footprints.valid[b]
    a, b = a[same], b[same]
    polys = footprints.polygons()
    area = shapely.area(shapely.intersection(polys[a], polys[b]))
    return np.asarray(100.0 * area / (0.5 * (footprints.area_m2[a] + footprints.area_m2[b])), float)


def side_overlaps_pct(frames: Frames, footprints: Footprints, lines: NDArray[np.int64]) -> F64:
    """Overlap of each frame with the neighbouring lines on either side, percent of its area.

    A line's neighbours are the nearest parallel lines (axes within 30 deg, either direction) on
    its left and right whose along-track extents overlap its own; the overlap of a frame is its
    intersection with the union of a neighbour line's footprints.
    """
    polys = footprints.polygons()
    centre = footprints.principal_xyz_m[:, :2]
    order = capture_order(frames)
    info: dict[int, tuple[F64, F64, F64, tuple[float, float]]] = {}
    for line in np.unique(lines):
        members = order[(lines[order] == line) & footprints.valid[order]]
        if members.size < 2:
            continue
        steps = np.diff(footprints.camera_xyz_m[members, :2], axis=0)
        lengths = np.hypot(steps[:, 0], steps[:, 1])
        if not (lengths > 0).any():
            continue
        units = steps[lengths > 0] / lengths[lengths > 0, None]
        direction = units.sum(axis=0)
        norm = float(np.hypot(*direction))
        if norm == 0.0:
            continue
        direction = direction / norm
        along = centre[members] @ direction
        info[int(line)] = (
            members,
            direction,
            centre[members].mean(axis=0),
            (float(along.min()), float(along.max())),
        )
    unions = {line: shapely.union_all(polys[m]) for line, (m, _, _, _) in info.items()}
    out: list[F64] = []
    cos_limit = math.cos(math.radians(LINE_BREAK_TURN_DEG))
    for line, (members, direction, mid, _) in info.items():
        normal = np.array([direction[1], -direction[0]])
        left: tuple[float, int] | None = None
        right: tuple[float, int] | None = None
        for other, (_, other_dir, other_mid, _) in info.items():
            if other == line or abs(float(direction @ other_dir)) < cos_limit:
                continue
            along_other = centre[info[other][0]] @ direction
            lo, hi = float(along_other.min()), float(along_other.max())
            mine = centre[members] @ direction
            if hi < mine.min() or lo > mine.max():
                continue
            offset = float(normal @ (other_mid - mid))
            if offset > 1.0 and (right is None or offset < right[0]):
                right = (offset, other)
            elif offset < -1.0 and (left is None or -offset < left[0]):
                left = (-offset, other)
        for neighbour in (left, right):
            if neighbour is None:
                continue
            area = shapely.area(shapely.intersection(polys[members], unions[neighbour[1]]))
            out.append(100.0 * area / footprints.area_m2[members])
    return np.concatenate(out) if out else np.zeros(0)


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


#: A frame's nearer same-line neighbour further than this many median capture intervals away in
#: time leaves its speed unknown: over a pause, a turn or dropped frames the straight step between
#: the two positions says little about the speed at the exposure.
SPEED_MAX_INTERVAL_RATIO = 3.0


@dataclass(frozen=True, kw_only=True)
class MotionBlur:
    """Per frame: ground speed (m/s, NaN where unknown), exposure (s) and blur (pixels, NaN where
    the speed or the exposure is unknown; the worst point of the frame, ``blur_centre_px`` at the
    image centre); ``exposure_s`` and ``blur_px`` are None when no exposure time is known,
    and ``exposure_source`` then too, else it says where the exposure came from ("exif" or
    "camera"). ``max_interval_s``: the longest interval a speed may be measured over (s; 0 when no
    two frames of a line have distinct times)."""

    speed_m_s: F64
    exposure_s: F64 | None
    blur_px: F64 | None
    exposure_source: str | None
    max_interval_s: float
    blur_centre_px: F64 | None = None


def ground_velocities_m_s(
    frames: Frames,
    footprints: Footprints,
    lines: NDArray[np.int64],
    *,
    max_interval_ratio: float = SPEED_MAX_INTERVAL_RATIO,
) -> tuple[F64, float]:
    """Velocity of each camera at its exposure, (N, 3) m/s in the local frame (x east, y north,
    z up; NaN rows where unknown), and the longest interval a velocity may be measured over (s).

    The velocity of a frame is the 3D step to its nearer-in-time neighbour (previous or next frame
    in capture order) of the same flight line, over the time between them (oriented forward in
    time): the camera fires on the line, and the nearer neighbour's step is the shortest stretch
    of flight around the exposure, so a pause or dropped frames on one side do not slow it down.
    A neighbour taken at the same time (no interval) does not count. When that neighbour is more
    than ``max_interval_ratio`` x the median interval between consecutive frames of a line away (a
    frame alone on its line, or between two gaps), the velocity is unknown rather than a guess:
    the straight step across a turn or a pause is not the motion at the exposure.
    """
    n = len(frames)
    velocity = np.full((n, 3), np.nan)
    if frames.time_utc_s is None or n < 2:
        return velocity, 0.0
    order = capture_order(frames)
    t = np.asarray(frames.time_utc_s, float)[order]
    xyz = footprints.camera_xyz_m[order]
    dt = np.diff(t)
    step = np.diff(xyz, axis=0)
    usable = (lines[order][:-1] == lines[order][1:]) & (dt > 0) & np.isfinite(step).all(axis=1)
    if not usable.any():
        return velocity, 0.0
    max_interval_s = max_interval_ratio * float(np.median(dt[usable]))
    usable &= dt <= max_interval_s
    step_velocity = np.where(usable[:, None], step / np.where(usable, dt, 1.0)[:, None], np.nan)
    # Each frame's step before and after it (in capture order), infinite time where unusable.
    dt_before = np.concatenate([[np.inf], np.where(usable, dt, np.inf)])
    dt_after = np.concatenate([np.where(usable, dt, np.inf), [np.inf]])
    nan_row = np.full((1, 3), np.nan)
    v_before = np.concatenate([nan_row, step_velocity])
    v_after = np.concatenate([step_velocity, nan_row])
    velocity[order] = np.where((dt_before <= dt_after)[:, None], v_before, v_after)
    return velocity, max_interval_s


def ground_speeds_m_s(
    frames: Frames,
    footprints: Footprints,
    lines: NDArray[np.int64],
    *,
    max_interval_ratio: float = SPEED_MAX_INTERVAL_RATIO,
) -> tuple[F64, float]:
    """Ground speed of each frame at its exposure (m/s, NaN where unknown): the length of its
    velocity (:func:`ground_velocities_m_s`), and the longest interval measured over (s)."""
    velocity, max_interval_s = ground_velocities_m_s(
        frames, footprints, lines, max_interval_ratio=max_interval_ratio
    )
    return np.linalg.norm(velocity, axis=1), max_interval_s


def image_motion_px(
    footprints: Footprints,
    displacement_m: F64,
    camera_pitch_mm: tuple[float, float],
    focal_length_mm: float,
    ground_z_m: F64 | None = None,
) -> tuple[F64, F64]:
    """How far the image of the ground moves while each camera moves by ``displacement_m``
    ((N, 3) metres, x east, y north, z up): (worst over the frame, at the image centre), pixels.

    Each ground point P seen by a frame (its ring vertices and its principal point) projects to
    u = f x_c / z_c with (x_c, y_c, z_c) = R^T (P - C); after the camera moves by d it is at
    f (x_c - d_x) / (z_c - d_z). The displacement on the sensor, along x and y, over the pixel
    pitch of each axis, is the blur in pixels along the direction of motion in the image: the
    ground moves fastest across the image where it is nearest, at the near edge of a tilted
    frame. ``ground_z_m`` (N, V): the ground's elevation under each ring vertex (None: the
    principal point's elevation, i.e. flat ground under each frame).
    """
    n = len(footprints)
    worst = np.full(n, np.nan)
    centre = np.full(n, np.nan)
    if n == 0:
        return worst, centre
    xy = footprints.xy_m
    z = (
        ground_z_m
        if ground_z_m is not None
        else np.repeat(footprints.principal_xyz_m[:, 2:3], xy.shape[1], 1)
    )
    points = np.concatenate(
        [np.concatenate([xy, z[..., None]], axis=2), footprints.principal_xyz_m[:, None, :]], axis=1
    )  # (N, V+1, 3)
    r = footprints.world_from_camera
    rel = points - footprints.camera_xyz_m[:, None, :]
    cam = np.einsum("nji,nvj->nvi", r, rel)  # R^T (P - C)
    d = np.einsum("nji,nj->ni", r, displacement_m)[:, None, :]
    moved = cam - d
    pitch_x, pitch_y = camera_pitch_mm
    with np.errstate(divide="ignore", invalid="ignore"):
        du = focal_length_mm * (moved[..., 0] / moved[..., 2] - cam[..., 0] / cam[..., 2]) / pitch_x
        dv = focal_length_mm * (moved[..., 1] / moved[..., 2] - cam[..., 1] / cam[..., 2]) / pitch_y
    blur = np.hypot(du, dv)
    ok = footprints.valid & np.isfinite(displacement_m).all(axis=1)
    worst = np.where(ok, np.nanmax(np.where(np.isfinite(blur), blur, -np.inf), axis=1), np.nan)
    centre = np.where(ok, blur[:, -1], np.nan)
    return worst, centre


def motion_blur(
    frames: Frames,
    footprints: Footprints,
    lines: NDArray[np.int64] | None = None,
    *,
    ground_z_m: F64 | None = None,
) -> MotionBlur | None:
    """Ground speeds (:func:`ground_speeds_m_s`) and motion blur in pixels: how far the image of
    the ground moves during the exposure, along the direction of motion in the image, at the
    point of the frame where it moves most (:func:`image_motion_px`; for a nadir frame over flat
    ground, speed x exposure / GSD along the axis of motion).

    None without capture times; without an exposure time (neither EXIF nor the camera's
    ``shutter_s``) the speeds alone, blur None; NaN for a frame whose exposure or speed is
    unknown. ``lines``: the flight lines (:func:`flight_lines`, computed when not given).
    """
    n = len(frames)
    if frames.time_utc_s is None or n < 2:
        return None
    if lines is None:
        lines = flight_lines(frames, footprints)
    velocity, max_interval_s = ground_velocities_m_s(frames, footprints, lines)
    speed = np.linalg.norm(velocity, axis=1)
    exposure: F64 | None = None
    source: str | None = None
    if frames.exposure_s is not None:
        exposure = np.asarray(frames.exposure_s, float)
        source = "exif"
    elif frames.camera.shutter_s is not None:
        exposure = np.full(n, frames.camera.shutter_s)
        source = "camera"
    blur = centre = None
    if exposure is not None:
        camera = frames.camera
        blur, centre = image_motion_px(
            footprints,
            velocity * exposure[:, None],
            (camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm),
            camera.focal_length_mm,
            ground_z_m,
        )
    return MotionBlur(
        speed_m_s=speed,
        exposure_s=exposure,
        blur_px=blur,
        blur_centre_px=centre,
        exposure_source=source,
        max_interval_s=max_interval_s,
    )


@dataclass(frozen=True, kw_only=True)
class BlockGeometry:
    """Everything :func:`analyse_block` measures; ``summary()`` gives the report's figures."""

    pairs: Pairs
    lines: NDArray[np.int64]
    forward_overlap_pct: Distribution | None
    side_overlap_pct: Distribution | None
    base_height_ratio: Distribution | None
    intersection_angle_deg: Distribution | None
    convergent_share_pct: float
    doming_risk: bool
    scale_outliers: NDArray[np.intp]
    gsd_cm: Distribution | None
    blur: MotionBlur | None
    good_pair_area_pct: float | None

    def summary(self) -> dict[str, Any]:
        def dist(d: Distribution | None) -> dict[str, float | int] | None:
            return d.as_dict() if d is not None else None

        blur = None
        if self.blur is not None:
            speed = self.blur.speed_m_s
            px = self.blur.blur_px
            blur = {
                "exposure_source": self.blur.exposure_source,
                "blur_px": dist(Distribution.of(px[np.isfinite(px)])) if px is not None else None,
                "speed_m_s": dist(Distribution.of(speed[np.isfinite(speed)])),
                "speed_unknown_frames": int((~np.isfinite(speed)).sum()),
            }
        return {
            "pairs": len(self.pairs),
            "lines": len(np.unique(self.lines)),
            "forward_overlap_pct": dist(self.forward_overlap_pct),
            "side_overlap_pct": dist(self.side_overlap_pct),
            "base_height_ratio": dist(self.base_height_ratio),
            "intersection_angle_deg": dist(self.intersection_angle_deg),
            "convergent_share_pct": self.convergent_share_pct,
            "doming_risk": self.doming_risk,
            "scale_outliers": int(self.scale_outliers.size),
            "gsd_cm": dist(self.gsd_cm),
            "motion_blur": blur,
            "good_base_height_area_pct": self.good_pair_area_pct,
        }


def analyse_block(
    frames: Frames,
    footprints: Footprints,
    ground: Ground,
    frame: LocalFrame,
    *,
    grid: Grid | None = None,
    area_mask: NDArray[np.bool_] | None = None,
    base_height_range: tuple[float, float] = GOOD_BASE_HEIGHT_RATIO,
    convergent_deg: float = CONVERGENT_OFF_NADIR_DEG,
    scale_tolerance: float = SCALE_TOLERANCE,
) -> BlockGeometry:
    """Pairs, overlaps, convergence, scale and blur of a block (module docstring).

    With ``grid`` and ``area_mask`` also the share of the area seen by a pair in the good B/H range.
    """
    if len(footprints) != len(frames):
        raise ValueError(f"{len(footprints)} footprints for {len(frames)} frames")
    pairs = overlapping_pairs(footprints, ground, frame)
    lines = flight_lines(frames, footprints)
    valid = footprints.valid
    convergent = off_nadir_deg(footprints)[valid] > convergent_deg
    share = 100.0 * float(convergent.mean()) if convergent.size else 0.0
    good_share = None
    if grid is not None and area_mask is not None:
        # As the check counts them: frames on one line or neighbouring lines, when there are any.
        _, across = pair_kinds(frames, pairs, lines)
        kinds = (lines[pairs.i] == lines[pairs.j]) | across
        good_share = good_pair_share_pct(
            pairs, grid, area_mask, base_height_range, use=kinds if kinds.any() else None
        )
    result = BlockGeometry(
        pairs=pairs,
        lines=lines,
        forward_overlap_pct=Distribution.of(forward_overlaps_pct(frames, footprints, lines)),
        side_overlap_pct=Distribution.of(side_overlaps_pct(frames, footprints, lines)),
        base_height_ratio=Distribution.of(pairs.base_height_ratio),
        intersection_angle_deg=Distribution.of(pairs.intersection_angle_deg),
        convergent_share_pct=share,
        doming_risk=not bool(convergent.any()),
        scale_outliers=scale_outliers(footprints, pairs, scale_tolerance),
        gsd_cm=Distribution.of(footprints.gsd_cm[valid]),
        blur=motion_blur(frames, footprints, lines),
        good_pair_area_pct=good_share,
    )
    if result.doming_risk:
        logger.warning("no convergent (oblique) frames: the block risks doming")
    return result
