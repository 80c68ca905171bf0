"""Ordering the segments of a pass and routing the transits between them around no-fly zones.

- Order: boustrophedon over the rows (lines sorted across the pass), the segments of a row in the
  row's direction; of the four ways to start (first or last row, either direction) the one whose
  entry is nearest the vehicle's position (home for the first pass, the end of the previous pass
  for the others) is taken.
- Transit: a straight leg when it crosses no no-fly zone; otherwise the shortest path over the
  visibility graph of the zones' (slightly enlarged) corners.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence

import numpy as np
import shapely
from shapely.geometry import Polygon

from .errors import PlanningError

Point2 = tuple[float, float]


class Router:
    """Shortest collision-free legs around a set of no-fly polygons (metres, any planar frame).

    A leg is clear when it does not enter the zones shrunk by 1 cm: legs that only touch a
    zone's edge (a camera-off point placed on the clearance boundary) are allowed. Visibility
    tests are batched through shapely's vectorized predicates.
    """

    _TOUCH_TOLERANCE_M = 0.01

    def __init__(self, zones: Sequence[Polygon], margin_m: float = 1.0) -> None:
        zones = [z for z in zones if not z.is_empty]
        self._core: shapely.Geometry | None = None
        self._nodes = np.zeros((0, 2))
        self._adjacency: dict[int, list[tuple[int, float]]] | None = None
        if not zones:
            return
        union = shapely.union_all(zones)
        self._core = union.buffer(-self._TOUCH_TOLERANCE_M)
        shapely.prepare(self._core)
        # Corners of the zones pushed outward a little, so that legs between them graze nothing.
        grown = union.buffer(margin_m, join_style="mitre")
        nodes: list[Point2] = []
        for poly in getattr(grown, "geoms", [grown]):
            simple = poly.simplify(margin_m * 0.5, preserve_topology=True)
            for ring in [simple.exterior, *simple.interiors]:
                nodes.extend((float(x), float(y)) for x, y in list(ring.coords)[:-1])
        points = np.asarray(nodes, float).reshape(-1, 2)
        inside = shapely.intersects(self._core, shapely.points(points))
        self._nodes = points[~inside]

    def is_clear(self, a: Point2, b: Point2) -> bool:
        if self._core is None:
            return True
        return bool(self._clear_from(a, np.asarray([b], float))[0])

    def _clear_from(self, a: Point2, targets: np.ndarray) -> np.ndarray:
        """For each target, whether the leg a -> target is clear (vectorized)."""
        if self._core is None or len(targets) == 0:
            return np.ones(len(targets), bool)
        coords = np.empty((len(targets), 2, 2))
        coords[:, 0] = a
        coords[:, 1] = targets
        legs = shapely.linestrings(coords)
        return ~shapely.intersects(self._core, legs)

    def path(self, a: Point2, b: Point2) -> list[Point2]:
        """Points from a to b (both included) whose legs cross no zone."""
        if self.is_clear(a, b):
            return [a, b]
        graph = self._graph()
        n = len(self._nodes)
        start, goal = n, n + 1
        edges: dict[int, list[tuple[int, float]]] = {start: []}
        from_a = np.nonzero(self._clear_from(a, self._nodes))[0]
        to_b = set(np.nonzero(self._clear_from(b, self._nodes))[0].tolist())
        for i in from_a:
            edges[start].append((int(i), math.dist(a, self._nodes[i])))
        best = {start: 0.0}
        previous: dict[int, int] = {}
        queue = [(0.0, start)]
        while queue:
            dist, k = heapq.heappop(queue)
            if k == goal:
                break
            if dist > best.get(k, math.inf):
                continue
            neighbours = edges.get(k) or graph.get(k, [])
            if k in to_b:
                neighbours = [*neighbours, (goal, math.dist(tuple(self._nodes[k]), b))]
            for j, w in neighbours:
                nd = dist + w
                if nd < best.get(j, math.inf):
                    best[j] = nd
                    previous[j] = k
                    heapq.heappush(queue, (nd, j))
        if goal not in previous:
            raise PlanningError(
                f"no route from ({a[0]:.1f}, {a[1]:.1f}) to ({b[0]:.1f}, {b[1]:.1f}) that avoids the "
                f"exclusion zones; check that the zones do not enclose part of the area"
            )
        route = [goal]
        while route[-1] != start:
            route.append(previous[route[-1]])
        points = {start: a, goal: b}
        return [
            points.get(k) or (float(self._nodes[k][0]), float(self._nodes[k][1])) for k in reversed(route)
        ]

    def _graph(self) -> dict[int, list[tuple[int, float]]]:
        if self._adjacency is None:
            adjacency: dict[int, list[tuple[int, float]]] = {i: [] for i in range(len(self._nodes))}
            for i in range(len(self._nodes) - 1):
                others = self._nodes[i + 1 :]
                clear = self._clear_from((self._nodes[i][0], self._nodes[i][1]), others)
                for j in np.nonzero(clear)[0]:
                    k = i + 1 + int(j)
                    d = float(np.hypot(*(self._nodes[k] - self._nodes[i])))
                    adjacency[i].append((k, d))
                    adjacency[k].append((i, d))
            self._adjacency = adjacency
        return self._adjacency


def boustrophedon(
    rows: Sequence[Sequence[int]], reverse_rows: bool, first_direction: int
) -> list[tuple[int, int]]:
    """(segment index, direction) in flight order.

    ``rows`` lists, per row in ascending v, its segment indices in ascending u.
    """
    order: list[tuple[int, int]] = []
    direction = first_direction
    row_sequence = list(reversed(rows)) if reverse_rows else list(rows)
    for row in row_sequence:
        members = list(row) if direction > 0 else list(reversed(row))
        order.extend((k, direction) for k in members)
        direction = -direction
    return order


def nearest_start(
    rows: Sequence[Sequence[int]],
    entry_points: dict[tuple[int, int], Point2],
    position: Point2,
) -> tuple[bool, int]:
    """Which of the four boustrophedon starts puts the first entry nearest ``position``."""
    best = (math.inf, False, 1)
    for reverse_rows in (False, True):
        first_row = rows[-1] if reverse_rows else rows[0]
        for direction in (1, -1):
            first = first_row[0] if direction > 0 else first_row[-1]
            d = math.dist(entry_points[(first, direction)], position)
            if d < best[0] - 1e-9:
                best = (d, reverse_rows, direction)
    return best[1], best[2]


def polyline_length_m(points: np.ndarray) -> float:
    if len(points) < 2:
        return 0.0
    return float(np.sum(np.hypot(*np.diff(points, axis=0).T)))
