"""Flight lines of a block and the overlaps along and across them.

- Flight lines: time-consecutive frames, broken where the heading turns by more than 30 deg or
  a step exceeds 3 x the median step (the turn between lines is not a gap, it is a break).
- Pair kinds: two frames of one line, or a frame and the nearest frame of a neighbouring line.
- Forward overlap between consecutive frames of a line, side overlap of each frame with the
  union of the neighbouring lines' footprints.
"""

from __future__ import annotations

import math

import numpy as np
import shapely
from numpy.typing import NDArray

from .footprints import Footprints
from .frames import Frames
from .stereo import Pairs

F64 = NDArray[np.float64]

LINE_BREAK_TURN_DEG = 30.0
LINE_BREAK_JUMP_RATIO = 3.0
#: A line whose nearest frame is within this factor of the nearest other line's is a neighbour.
NEIGHBOUR_LINE_RATIO = 1.5


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
