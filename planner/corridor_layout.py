"""The geometry of a corridor (planner.corridor): the corridor around its centre line, the
simplified line that is flown, the lines' fixed offsets, and the pieces the corridor is cut
into at the bisectors of its bends (steps 1 to 3 of planner.corridor's docstring)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon

from .area import polygonal
from .errors import AreaError
from .geo import LocalFrame

#: Simplification tolerance of the centre line: this share of the width ...
_SIMPLIFY_WIDTH_SHARE = 0.1
#: ... and at most this share of the frame's width across the line.
_SIMPLIFY_FRAME_SHARE = 0.2


@dataclasses.dataclass(frozen=True, kw_only=True)
class CorridorLayout:
    """The corridor as planned, in the local frame (metres)."""

    centre_xy: LineString  # as given
    flown_xy: LineString  # simplified: one straight run per segment
    width_m: float
    line_offsets_m: tuple[float, ...]  # right of the direction of the centre line
    pieces_xy: tuple[Polygon | MultiPolygon, ...]  # the part of the corridor each segment flies


def check_simple(line_xy: LineString, frame: LocalFrame, where: str) -> None:
    """Refuse a centre line that crosses or touches itself, naming where."""
    if line_xy.is_simple:
        return
    coords = np.asarray(line_xy.coords)
    segments = [LineString(coords[i : i + 2]) for i in range(len(coords) - 1)]
    tree = shapely.STRtree(segments)
    for i, seg in enumerate(segments):
        for j in tree.query(seg):
            if j <= i + 1:
                continue
            hit = seg.intersection(segments[j])
            if not hit.is_empty:
                p = hit.representative_point()
                lon, lat = frame.to_lonlat(p.x, p.y)
                raise AreaError(
                    f"{where}: the corridor's centre line crosses itself near lon {float(lon):.6f}, lat "
                    f"{float(lat):.6f} (segments {i + 1} and {j + 1}); draw it without crossings, or plan "
                    f"each side of the crossing as its own corridor"
                )
    raise AreaError(f"{where}: the corridor's centre line overlaps itself; draw it without going back on it")


def corridor_layout(
    centre_xy: LineString, width_m: float, across_m: float, spacing_m: float
) -> CorridorLayout:
    """Simplified centre line, line offsets and the pieces of the corridor (module docstring)."""
    tolerance = min(_SIMPLIFY_WIDTH_SHARE * width_m, _SIMPLIFY_FRAME_SHARE * across_m)
    flown = centre_xy.simplify(tolerance, preserve_topology=False)
    if not isinstance(flown, LineString) or len(flown.coords) < 2 or not flown.is_simple:
        flown, tolerance = centre_xy, 0.0
    span = width_m + 2.0 * tolerance
    n = max(1, math.ceil((span - across_m) / spacing_m - 1e-9) + 1)
    offsets = tuple(-(n - 1) * spacing_m / 2.0 + k * spacing_m for k in range(n))
    corridor = corridor_polygon(centre_xy, width_m)
    coords = np.asarray(flown.coords)
    tangents = np.diff(coords, axis=0)
    tangents /= np.hypot(tangents[:, 0], tangents[:, 1])[:, None]
    big = 4.0 * (flown.length + width_m) + 1000.0
    pieces: list[Polygon | MultiPolygon] = []
    taken: shapely.Geometry | None = None
    for i in range(len(tangents)):
        # Near this segment only (round ends: the outside of a bend is near both segments) ...
        region = LineString(coords[i : i + 2]).buffer(width_m / 2.0 + tolerance + 1.0, quad_segs=16)
        # ... and between the bisectors of its two bends.
        if i > 0:
            region = region.intersection(half_plane(coords[i], tangents[i - 1] + tangents[i], big))
        if i < len(tangents) - 1:
            region = region.intersection(half_plane(coords[i + 1], -(tangents[i] + tangents[i + 1]), big))
        piece = corridor.intersection(region)
        if taken is not None:
            piece = piece.difference(taken)
        taken = piece if taken is None else taken.union(piece)
        pieces.append(polygonal(piece))
    rest = corridor.difference(taken) if taken is not None else corridor
    for part in polygonal(rest).geoms:
        if part.area < 1e-6:
            continue
        k = int(
            np.argmin([LineString(coords[i : i + 2]).distance(part.centroid) for i in range(len(tangents))])
        )
        pieces[k] = polygonal(pieces[k].union(part))
    return CorridorLayout(
        centre_xy=centre_xy, flown_xy=flown, width_m=width_m, line_offsets_m=offsets, pieces_xy=tuple(pieces)
    )


def corridor_polygon(centre_xy: LineString, width_m: float) -> Polygon | MultiPolygon:
    """Every point within half the width of the centre line, flat at its two ends."""
    return centre_xy.buffer(width_m / 2.0, cap_style="flat", join_style="round", quad_segs=16)


def half_plane(point: np.ndarray, normal: np.ndarray, big: float) -> Polygon:
    """The half plane {x : (x - point) . normal >= 0} within a box of half-size ``big``."""
    n = normal / math.hypot(normal[0], normal[1])
    t = np.array([-n[1], n[0]])
    p = np.asarray(point, float)
    corners = [p + t * big, p + t * big + n * big * 2, p - t * big + n * big * 2, p - t * big]
    return Polygon(corners)


def bearing_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Grid bearing from point ``a`` to point ``b`` (x east, y north), degrees 0-360."""
    return math.degrees(math.atan2(b[0] - a[0], b[1] - a[1])) % 360.0
