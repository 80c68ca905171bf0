"""Flight lines of one pass over any polygon: placement, splitting, filling, slivers.

Everything here works in the pass frame (u along the line direction, v across), where each
frame surely covers the rectangle ``[u + u_min, u + u_max] x [v + v_min, v + v_max]`` around
its camera position (u, v) (:class:`planner.exposure.FrameRectangle`).

How coverage to the edges is guaranteed (QGC and Mission Planner do not guarantee it):

1. Lines: the smallest number n of lines at the requested spacing S whose rectangles span the
   area's whole v-extent, ``(n - 1) S + across >= v_max - v_min``; the block is centred on the
   area, so both outer edges get the same margin.
2. Each line is responsible for the band of v between the midpoints of its overlaps with its
   neighbours (the outer lines' bands are open). Where the area meets the band, the union of
   the u-extents gives the camera-on intervals: a line is split where the area (a notch) or an
   exclusion interrupts it; gaps shorter than a frame length that cross no exclusion are
   merged (the camera stays on over a small notch, still within the area's buffer).
3. Stations are spaced at most the trigger distance apart and span each interval exactly, so
   the first and last frames reach its ends; a camera-on interval is never inside an
   exclusion (buffered by the clearance).
4. The union of all frame rectangles is then subtracted from the area; whatever remains (beside
   an exclusion, in a sharp corner) gets fill segments, and what still cannot be covered without
   flying over an exclusion is reported as a warning with its area.
5. A short segment (a sliver) whose rectangle adds nothing the others do not cover is dropped.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon, box

from .area import polygon_parts
from .coverage import boundary_points, grid_points, view_counts
from .exposure import FrameRectangle

#: Extra stations beyond each unblocked end of a run: the area's edges are then seen by three
#: frames along the line (when the forward overlap is at least 2/3), as SfM wants.
END_STATIONS = 2
#: Residual pieces smaller than this (m2) are numerical noise, not gaps.
_RESIDUAL_NOISE_M2 = 0.01
_EPS = 1e-6


@dataclass(frozen=True, kw_only=True)
class Segment:
    """One camera-on run along a line, in the pass frame.

    Stations are at ``u_first_m + k * spacing_m`` for k in 0 .. count-1 (ascending u) at v = ``v_m``;
    the vehicle flies them in ``direction`` (+1 ascending u, -1 descending).
    """

    row: int  # index of the line (rows sorted by v), fill rows interleaved
    v_m: float
    u_first_m: float
    spacing_m: float
    count: int
    fill: bool = False
    direction: int = 1
    #: The run continues another run of the same line just below (``join_lo``) or above
    #: (``join_hi``) in u: no lead-in or lead-out on that side, the vehicle flies straight on.
    join_lo: bool = False
    join_hi: bool = False

    @property
    def u_last_m(self) -> float:
        return self.u_first_m + (self.count - 1) * self.spacing_m

    def station_u(self) -> np.ndarray:
        """Station positions along u in flight order."""
        u = self.u_first_m + np.arange(self.count) * self.spacing_m
        return u if self.direction > 0 else u[::-1]

    def camera_on_u(self) -> tuple[float, float]:
        """(start, stop) of the camera-on run in flight order: photo at start, then every
        spacing; the stop lies half a spacing past the last station, so that the last photo
        fires and the next does not (with the margins of planner.trigger), and a run of one
        station is a line of nonzero length too."""
        half = 0.5 * self.spacing_m
        if self.direction > 0:
            return self.u_first_m, self.u_last_m + half
        return self.u_last_m, self.u_first_m - half

    def rectangle(self, rect: FrameRectangle) -> Polygon:
        return box(
            self.u_first_m + rect.u_min_m,
            self.v_m + rect.v_min_m,
            self.u_last_m + rect.u_max_m,
            self.v_m + rect.v_max_m,
        )


@dataclass(frozen=True, kw_only=True)
class PassLayout:
    segments: tuple[Segment, ...]
    uncovered_m2: float  # area left uncovered (beside exclusions that cannot be flown over)
    line_count: int


def layout_pass(
    area_uv: Polygon | MultiPolygon,
    blocked_uv: Polygon | MultiPolygon | None,
    rect: FrameRectangle,
    trigger_distance_m: float,
    line_spacing_m: float,
    *,
    end_stations: int = END_STATIONS,
    max_run_stations: int | None = None,
    first_line_v_m: float | None = None,
    line_count: int | None = None,
) -> PassLayout:
    """Place the lines and camera-on segments of one pass (see the module docstring).

    ``blocked_uv`` is where the vehicle must not fly: exclusions buffered by the clearance.
    ``trigger_distance_m`` is the largest station spacing; ``end_stations`` extra stations
    (one trigger distance apart) are added beyond each unblocked end of a run, so that the
    area's edges are seen by ``end_stations + 1`` frames along the line. Runs longer than
    ``max_run_stations`` are split into consecutive runs (the trigger re-armed at a station).
    """
    v_min, v_max = area_uv.bounds[1], area_uv.bounds[3]
    across = rect.across_m
    span = v_max - v_min
    n_lines = max(1, math.ceil((span - across) / line_spacing_m - 1e-9) + 1)
    extra = (n_lines - 1) * line_spacing_m + across - span
    v0 = v_min - extra / 2.0 - rect.v_min_m
    if first_line_v_m is not None and line_count is not None:
        # Lines at given places (a corridor's offsets from its centre line, planner.corridor).
        n_lines, v0 = line_count, first_line_v_m
    centre_offset = (rect.v_min_m + rect.v_max_m) / 2.0
    u_lo, u_hi = area_uv.bounds[0] - 1.0, area_uv.bounds[2] + 1.0
    prepared_blocked = blocked_uv
    if blocked_uv is not None:
        shapely.prepare(blocked_uv)

    segments: list[Segment] = []
    for i in range(n_lines):
        v_line = v0 + i * line_spacing_m
        band_lo = v_line + centre_offset - line_spacing_m / 2.0 if i > 0 else v_min - 1.0
        band_hi = v_line + centre_offset + line_spacing_m / 2.0 if i < n_lines - 1 else v_max + 1.0
        band_lo = max(band_lo, v_line + rect.v_min_m)
        band_hi = min(band_hi, v_line + rect.v_max_m)
        piece = area_uv.intersection(box(u_lo, band_lo, u_hi, band_hi))
        intervals = _u_intervals(piece)
        segments.extend(
            _segments_for_line(
                i,
                v_line,
                intervals,
                prepared_blocked,
                rect,
                trigger_distance_m,
                (u_lo, u_hi),
                end_stations=end_stations,
            )
        )

    segments = _drop_slivers(segments, area_uv, rect)
    segments, uncovered = _fill_residual(
        segments, area_uv, prepared_blocked, rect, trigger_distance_m, (u_lo, u_hi), end_stations
    )
    segments = _fill_stereo(
        segments, area_uv, prepared_blocked, rect, trigger_distance_m, (u_lo, u_hi), end_stations
    )
    if max_run_stations is not None:
        segments = [part for s in segments for part in split_run(s, max_run_stations)]
    segments.sort(key=lambda s: (s.v_m, s.u_first_m))
    rows: dict[float, int] = {}
    for s in segments:
        rows.setdefault(round(s.v_m, 6), len(rows))
    ordered = tuple(
        Segment(
            row=rows[round(s.v_m, 6)],
            v_m=s.v_m,
            u_first_m=s.u_first_m,
            spacing_m=s.spacing_m,
            count=s.count,
            fill=s.fill,
            join_lo=s.join_lo,
            join_hi=s.join_hi,
        )
        for s in segments
    )
    return PassLayout(segments=ordered, uncovered_m2=uncovered, line_count=len(rows))


def split_run(seg: Segment, max_stations: int) -> list[Segment]:
    """``seg`` cut into consecutive runs of at most ``max_stations`` stations, same spacing."""
    if seg.count <= max_stations:
        return [seg]
    n_runs = math.ceil(seg.count / max_stations)
    base, extra = divmod(seg.count, n_runs)
    out = []
    first = 0
    for k in range(n_runs):
        count = base + (1 if k < extra else 0)
        out.append(
            dataclasses.replace(
                seg,
                u_first_m=seg.u_first_m + first * seg.spacing_m,
                count=count,
                join_lo=seg.join_lo if k == 0 else True,
                join_hi=seg.join_hi if k == n_runs - 1 else True,
            )
        )
        first += count
    return out


def _u_intervals(geom: shapely.Geometry) -> list[tuple[float, float]]:
    """Union of the u-extents of the polygonal parts of ``geom``, sorted."""
    parts = [g for g in getattr(geom, "geoms", [geom]) if not g.is_empty and g.area > 0]
    return _merged((g.bounds[0], g.bounds[2]) for g in parts)


def _merged(spans: Iterable[tuple[float, float]]) -> list[tuple[float, float]]:
    """The union of (lo, hi) intervals, sorted; intervals within _EPS of each other merge."""
    merged: list[tuple[float, float]] = []
    for lo, hi in sorted(spans):
        if merged and lo <= merged[-1][1] + _EPS:
            merged[-1] = (merged[-1][0], max(merged[-1][1], hi))
        else:
            merged.append((lo, hi))
    return merged


def _blocked_u(
    blocked: shapely.Geometry | None, v: float, u_range: tuple[float, float]
) -> list[tuple[float, float]]:
    """u-intervals where the line at v runs through a blocked zone."""
    if blocked is None:
        return []
    line = LineString([(u_range[0] - 1e4, v), (u_range[1] + 1e4, v)])
    if not blocked.intersects(line):
        return []
    hit = blocked.intersection(line)
    spans = []
    for g in getattr(hit, "geoms", [hit]):
        if g.is_empty or g.length <= 0:
            continue
        xs = [c[0] for c in g.coords]
        spans.append((min(xs), max(xs)))
    return _merged(spans)


def _subtract(
    interval: tuple[float, float], holes: Sequence[tuple[float, float]]
) -> list[tuple[float, float, bool, bool]]:
    """interval minus holes: (lo, hi, lo_is_blocked_edge, hi_is_blocked_edge)."""
    pieces = [(interval[0], interval[1], False, False)]
    for h_lo, h_hi in holes:
        out = []
        for lo, hi, lo_b, hi_b in pieces:
            if h_hi <= lo or h_lo >= hi:
                out.append((lo, hi, lo_b, hi_b))
                continue
            if h_lo > lo:
                out.append((lo, h_lo, lo_b, True))
            if h_hi < hi:
                out.append((h_hi, hi, True, hi_b))
        pieces = out
    return pieces


def _segments_for_line(
    row: int,
    v_line: float,
    coverage_intervals: Sequence[tuple[float, float]],
    blocked: shapely.Geometry | None,
    rect: FrameRectangle,
    trigger_distance_m: float,
    u_range: tuple[float, float],
    fill: bool = False,
    end_stations: int = 0,
) -> list[Segment]:
    """Camera-on segments of one line covering ``coverage_intervals`` (u-extents of area),
    with ``end_stations`` extra stations beyond each end where no blocked zone prevents it."""
    if not coverage_intervals:
        return []
    # Merge small gaps (notches) that cross no blocked zone.
    holes = _blocked_u(blocked, v_line, u_range)
    merged: list[tuple[float, float]] = [coverage_intervals[0]]
    for lo, hi in coverage_intervals[1:]:
        gap_lo, gap_hi = merged[-1][1], lo
        crosses_block = any(h_lo < gap_hi and h_hi > gap_lo for h_lo, h_hi in holes)
        if gap_hi - gap_lo < rect.along_m and not crosses_block:
            merged[-1] = (merged[-1][0], max(merged[-1][1], hi))
        else:
            merged.append((lo, hi))

    segments = []
    for lo, hi in merged:
        # Camera positions whose rectangles span [lo, hi].
        p0 = lo - rect.u_min_m
        p1 = hi - rect.u_max_m
        if p1 < p0:
            p0 = p1 = (p0 + p1) / 2.0
        # Stereo at the ends: the frame whose back edge reaches ``lo`` is the only one that sees
        # it; each extra station one trigger distance further out adds one more view of the edge
        # (a frame is longer than the trigger distance), clipped below by the blocked zones.
        # (only as many as still see the end: the frame must reach it)
        k_lo = min(end_stations, math.floor((p0 + rect.u_max_m - lo) / trigger_distance_m + 1e-9))
        k_hi = min(end_stations, math.floor((hi - p1 - rect.u_min_m) / trigger_distance_m + 1e-9))
        p0 -= max(0, k_lo) * trigger_distance_m
        p1 += max(0, k_hi) * trigger_distance_m
        for s_lo, s_hi, _, _ in _subtract((p0, p1), holes):
            # The camera-off point lies half a spacing past the last station, whichever way the
            # segment is flown: keep it out of the nearest blocked zone on either side.
            margin = trigger_distance_m / 2.0
            next_hole = min((h_lo for h_lo, _ in holes if h_lo >= s_hi - _EPS), default=math.inf)
            prev_hole = max((h_hi for _, h_hi in holes if h_hi <= s_lo + _EPS), default=-math.inf)
            t_lo = max(s_lo, prev_hole + margin)
            t_hi = min(s_hi, next_hole - margin)
            single = trigger_distance_m  # a one-station run: camera off half of this past it
            if t_hi < t_lo:
                # No room for a run with its camera-off margins: one station in the middle, its
                # camera-off point as far as the room allows (too little room: none).
                mid = (s_lo + s_hi) / 2.0
                single = min(trigger_distance_m, 2.0 * min(mid - prev_hole, next_hole - mid) * 0.9)
                if single < 0.25 * trigger_distance_m:
                    continue
                t_lo = t_hi = mid
            s_lo, s_hi = t_lo, t_hi
            length = s_hi - s_lo
            count = max(1, math.ceil(length / trigger_distance_m - 1e-9) + 1) if length > _EPS else 1
            if count > 1 and length < 0.5 * trigger_distance_m:
                # Two stations closer than half a trigger distance: an autopilot checking the
                # distance once per loop cannot hold that; spread them to half a distance (the
                # camera-off point then reaches at most the blocked zone's buffered edge).
                pad = (0.5 * trigger_distance_m - length) / 2.0
                s_lo, s_hi, length = s_lo - pad, s_hi + pad, 0.5 * trigger_distance_m
            spacing = length / (count - 1) if count > 1 else single
            segments.append(
                Segment(row=row, v_m=v_line, u_first_m=s_lo, spacing_m=spacing, count=count, fill=fill)
            )
    return segments


def _drop_slivers(segments: list[Segment], area: shapely.Geometry, rect: FrameRectangle) -> list[Segment]:
    """Drop short segments whose rectangles cover nothing the other segments do not."""
    short = [k for k, s in enumerate(segments) if s.u_last_m - s.u_first_m < rect.along_m]
    if not short:
        return segments
    rects = [s.rectangle(rect) for s in segments]
    tree = shapely.STRtree(rects)
    keep = [True] * len(segments)
    for k in short:
        own = rects[k].intersection(area)
        if own.area <= _RESIDUAL_NOISE_M2:
            keep[k] = False
            continue
        others = [j for j in tree.query(rects[k]) if j != k and keep[j]]
        if not others:
            continue
        rest = own.difference(shapely.union_all([rects[j] for j in others]))
        if rest.area <= _RESIDUAL_NOISE_M2:
            keep[k] = False
    return [s for s, kept in zip(segments, keep, strict=True) if kept]


def _fill_residual(
    segments: list[Segment],
    area: shapely.Geometry,
    blocked: shapely.Geometry | None,
    rect: FrameRectangle,
    trigger_distance_m: float,
    u_range: tuple[float, float],
    end_stations: int = 0,
    rounds: int = 3,
) -> tuple[list[Segment], float]:
    """Add fill segments for area left uncovered; return them and the area still uncovered."""
    residual = _residual(segments, area, rect)
    for _ in range(rounds):
        pieces = [p for p in polygon_parts(residual) if p.area > _RESIDUAL_NOISE_M2]
        if not pieces:
            return segments, 0.0
        added = False
        for piece in pieces:
            for sub in _slice_by_height(piece, rect.across_m * 0.95):
                new = _fill_piece(sub, blocked, rect, trigger_distance_m, u_range, end_stations)
                if new:
                    segments.extend(new)
                    added = True
        residual = _residual(segments, area, rect)
        if not added:
            break
    leftover = sum(p.area for p in polygon_parts(residual) if p.area > _RESIDUAL_NOISE_M2)
    return segments, leftover


def _fill_stereo(
    segments: list[Segment],
    area: shapely.Geometry,
    blocked: shapely.Geometry | None,
    rect: FrameRectangle,
    trigger_distance_m: float,
    u_range: tuple[float, float],
    end_stations: int,
    rounds: int = 2,
) -> list[Segment]:
    """Fill segments over the parts of the area seen by fewer than two frames, or three when the
    forward overlap gives three (beside exclusions, in the gaps a line leaves around them, where a
    short line was dropped, in thin parts): each such part, found on a grid of the area and
    along its edges, gets a run of its own (with its end stations, so enough views)."""
    cell = min(trigger_distance_m, rect.across_m) / 4.0
    points, cell = grid_points(area, cell)
    points = np.vstack([points, boundary_points(area, min(cell, 1.0))])
    if len(points) == 0:
        return segments
    # Three views where a line's own frames give three (forward overlap of 2/3 or more), else two.
    need = 3 if 3.0 * trigger_distance_m <= rect.along_m + 1e-9 else 2
    for _ in range(rounds):
        counts = view_counts(points, segments, rect)
        weak = points[counts < need]
        if len(weak) == 0:
            break
        boxes = shapely.box(weak[:, 0] - cell, weak[:, 1] - cell, weak[:, 0] + cell, weak[:, 1] + cell)
        pieces = polygon_parts(shapely.union_all(boxes).intersection(area))
        added = False
        for piece in pieces:
            if piece.area <= _RESIDUAL_NOISE_M2:
                continue
            for sub in _slice_by_height(piece, rect.across_m * 0.95):
                new = _fill_piece(sub, blocked, rect, trigger_distance_m, u_range, end_stations)
                if new:
                    segments.extend(new)
                    added = True
        if not added:
            break
    return segments


def _fill_piece(
    piece: Polygon,
    blocked: shapely.Geometry | None,
    rect: FrameRectangle,
    trigger_distance_m: float,
    u_range: tuple[float, float],
    end_stations: int = 0,
) -> list[Segment]:
    """Segments at a v whose rectangles span the piece's v-extent, avoiding blocked zones."""
    u0, pv0, u1, pv1 = piece.bounds
    lo_v = pv1 - rect.v_max_m  # lowest line v whose rectangle still reaches the top
    hi_v = pv0 - rect.v_min_m  # highest line v whose rectangle still reaches the bottom
    if hi_v < lo_v:
        lo_v = hi_v = (lo_v + hi_v) / 2.0
    best: list[Segment] = []
    best_cover = -1.0
    for v in np.linspace(lo_v, hi_v, 7):
        candidate = _segments_for_line(
            -1, float(v), [(u0, u1)], blocked, rect, trigger_distance_m, u_range, fill=True,
            end_stations=end_stations,
        )  # fmt: skip
        cover = sum(s.rectangle(rect).intersection(piece).area for s in candidate)
        if cover > best_cover + _EPS:
            best, best_cover = candidate, cover
    return best if best_cover > _RESIDUAL_NOISE_M2 else []


def _slice_by_height(piece: Polygon, height: float) -> list[Polygon]:
    u0, v0, u1, v1 = piece.bounds
    if v1 - v0 <= height:
        return [piece]
    n = math.ceil((v1 - v0) / height)
    step = (v1 - v0) / n
    out: list[Polygon] = []
    for k in range(n):
        part = piece.intersection(box(u0 - 1, v0 + k * step, u1 + 1, v0 + (k + 1) * step))
        out.extend(p for p in polygon_parts(part) if p.area > _RESIDUAL_NOISE_M2)
    return out


def _residual(segments: Sequence[Segment], area: shapely.Geometry, rect: FrameRectangle) -> shapely.Geometry:
    covered = shapely.union_all([s.rectangle(rect) for s in segments]) if segments else None
    return area if covered is None else area.difference(covered)
