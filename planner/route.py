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
from shapely.geometry import LineString, Point, Polygon

from .errors import PlanningError

Point2 = tuple[float, float]


class Router:
    """Shortest collision-free legs around a set of no-fly polygons (metres, any planar frame)."""

    def __init__(self, zones: Sequence[Polygon], margin_m: float = 1.0) -> None:
        self._zones = [z for z in zones if not z.is_empty]
        if not self._zones:
            self._union = None
            self._nodes: list[Point2] = []
            return
        self._union = shapely.union_all(self._zones)
        shapely.prepare(self._union)
        # Corners of the zones pushed outward a little, so that legs between them graze nothing.
        grown = shapely.union_all([z.buffer(margin_m, join_style="mitre") for z in self._zones])
        nodes: list[Point2] = []
        for poly in getattr(grown, "geoms", [grown]):
            simple = poly.simplify(margin_m * 0.5, preserve_topology=True)
            for ring in [simple.exterior, *simple.interiors]:
                nodes.extend((float(x), float(y)) for x, y in list(ring.coords)[:-1])
        self._nodes = [n for n in nodes if not self._union.contains(Point(n))]
        self._adjacency: dict[int, list[tuple[int, float]]] | None = None

    def is_clear(self, a: Point2, b: Point2) -> bool:
        if self._union is None:
            return True
        if a == b:
            return not self._union.contains(Point(a))
        leg = LineString([a, b])
        return not self._union.intersects(leg) or self._union.intersection(leg).length < 1e-6

    def path(self, a: Point2, b: Point2) -> list[Point2]:
        """Points from a to b (both included) whose legs cross no zone."""
        if self.is_clear(a, b):
            return [a, b]
        graph = self._graph()
        n = len(self._nodes)
        start, goal = n, n + 1
        points = [*self._nodes, a, b]
        edges = {k: list(v) for k, v in graph.items()}
        edges[start] = []
        for i, node in enumerate(self._nodes):
            if self.is_clear(a, node):
                d = math.dist(a, node)
                edges[start].append((i, d))
            if self.is_clear(node, b):
                edges.setdefault(i, []).append((goal, math.dist(node, b)))
        best = {start: 0.0}
        previous: dict[int, int] = {}
        queue = [(0.0, start)]
        while queue:
            dist, k = heapq.heappop(queue)
            if k == goal:
                break
            if dist > best.get(k, math.inf):
                continue
            for j, w in edges.get(k, []):
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
        return [points[k] for k in reversed(route)]

    def _graph(self) -> dict[int, list[tuple[int, float]]]:
        if self._adjacency is None:
            adjacency: dict[int, list[tuple[int, float]]] = {i: [] for i in range(len(self._nodes))}
            for i, p in enumerate(self._nodes):
                for j in range(i + 1, len(self._nodes)):
                    q = self._nodes[j]
                    if self.is_clear(p, q):
                        d = math.dist(p, q)
                        adjacency[i].append((j, d))
                        adjacency[j].append((i, d))
            self._adjacency = adjacency
        return self._adjacency


def boustrophedon(rows: Sequence[Sequence[int]], reverse_rows: bool, first_direction: int) -> list[tuple[int, int]]:
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
