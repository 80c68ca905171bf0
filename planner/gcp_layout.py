"""Where to lay ground control points (GCPs) and independent check points over a planned survey.

The layout follows what the literature the textbook cites found best for SfM blocks:
control spread to the edges and the corners of the block plus a stratified interior, rather than
control along the edges alone or clustered (Martinez-Carricondo P., Aguera-Vega F., Carvajal-Ramirez
F. et al. 2018, "Assessment of UAV-photogrammetric mapping accuracy based on variation of ground
control points", Int. J. Appl. Earth Obs. Geoinf. 72: 1-10; James M.R., Robson S., d'Oleire-Oltmanns
S., Niethammer U. 2017, "Optimising UAV topographic surveys processed with structure-from-motion:
ground control quality, quantity and bundle adjustment", Geomorphology 280: 51-66). Check points are
never used in the adjustment; they measure its accuracy, so they are placed where the control is
thinnest (farthest from every GCP).

The steps:

1. Usable ground: the area shrunk by ``edge_margin_m`` (a target needs ground around it), less
   every exclusion zone and hole grown by ``clearance_m``.
2. Candidates: points along the usable ground's outline and on a grid inside it; each keeps only
   when at least ``min_frames`` planned frames see it (counted from the plan's footprints, every
   pass).
3. GCPs: first the candidate nearest each corner of the area's minimum rotated rectangle, then
   further points on the outline by farthest-point sampling, about half of the GCPs in all (at
   least the four corners); the rest in the interior, one per stratum: the interior candidates
   are split into as many compact strata of about equal size as there are interior GCPs (k-means),
   and each gets the candidate nearest its centre.
4. Check points: farthest-point sampling over every candidate, away from the GCPs and each other.

Every point keeps ``min_separation_m`` from every other. A request the area cannot meet (that many
points, that margin, that many frames) is bad input: the :class:`~planner.errors.InputError` names
the options of `sfap gcp-plan` and the figure that fits.

Expected accuracy (a rule of thumb, stated as one): with well-distributed control and a good
block, check-point RMSE of about 1-2 GSD horizontally and 1.5-3 GSD vertically; published SfM
results reach RMSE : flying height ratios of about 1:639 (mean over surface reconstructions,
Smith and Vericat 2015) to 1:1000 (James and Robson 2012), given here for the plan's height.
The survey of each target adds its own error (a GNSS RTK rover: about 1-2 cm horizontally and
2-3 cm vertically).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon

from .errors import InputError
from .plan import SurveyPlan

#: Candidates on the outline and inside, at most (the grid step grows with the area).
MAX_OUTLINE_CANDIDATES = 4000
MAX_GRID_CANDIDATES = 20000
KMEANS_ITERATIONS = 30
#: Footprints made into polygons at a time when counting the frames that see each candidate.
FOOTPRINT_BLOCK = 2_000


@dataclass(frozen=True, kw_only=True)
class GcpOptions:
    """What to lay out. Counts >= 0; distances in metres."""

    gcp_count: int = 8
    check_count: int = 4
    min_frames: int = 5  # planned frames that must see each point
    clearance_m: float = 5.0  # from every exclusion zone and hole
    edge_margin_m: float = 5.0  # inside the area's outline
    min_separation_m: float = 30.0  # between any two points

    def __post_init__(self) -> None:
        if not isinstance(self.gcp_count, int) or self.gcp_count < 3:
            raise InputError(
                f"--gcp {self.gcp_count}: a block needs at least 3 GCPs to be georeferenced "
                f"(more is better: 5 and above); ask for 3 or more"
            )
        if not isinstance(self.check_count, int) or self.check_count < 0:
            raise InputError(f"--check {self.check_count}: the number of check points must be 0 or more")
        if not isinstance(self.min_frames, int) or self.min_frames < 1:
            raise InputError(
                f"--min-frames {self.min_frames}: each point must be seen by 1 planned frame or more "
                f"(5 or more for a good intersection)"
            )
        for name in ("clearance_m", "edge_margin_m", "min_separation_m"):
            value = getattr(self, name)
            if not isinstance(value, int | float):
                raise InputError(f"{OPTION_NAMES[name]} {value!r}: give a distance in metres")
            if not (math.isfinite(value) and value >= 0):
                raise InputError(f"{OPTION_NAMES[name]} {value:g}: give a distance of 0 m or more")


#: The options of `sfap gcp-plan` that set each field, for messages.
OPTION_NAMES = {
    "gcp_count": "--gcp",
    "check_count": "--check",
    "min_frames": "--min-frames",
    "clearance_m": "--clearance-m",
    "edge_margin_m": "--edge-margin-m",
    "min_separation_m": "--min-separation-m",
}


@dataclass(frozen=True, kw_only=True)
class GroundPoint:
    name: str  # GCP01..., CHK01...
    role: str  # "gcp" or "check"
    placement: str  # "corner", "edge", "interior" (GCPs) or "check"
    x_m: float  # easting in the plan's projected CRS
    y_m: float  # northing
    lon_deg: float
    lat_deg: float
    frame_count: int  # planned frames whose footprint holds the point


@dataclass(frozen=True, kw_only=True)
class GcpLayout:
    points: tuple[GroundPoint, ...]
    crs: str
    options: GcpOptions
    gsd_cm: float
    alt_agl_m: float

    def expected_accuracy(self) -> dict[str, object]:
        gsd_m = self.gsd_cm / 100.0
        return {
            "basis": (
                "rule of thumb for well-distributed control: check-point RMSE of 1-2 GSD horizontally "
                "and 1.5-3 GSD vertically; RMSE : flying height of 1:639 (Smith and Vericat 2015) to "
                "1:1000 (James and Robson 2012); plus the rover's own error (RTK: about 1-2 cm "
                "horizontally, 2-3 cm vertically)"
            ),
            "gsd_cm": self.gsd_cm,
            "horizontal_rmse_m": [1.0 * gsd_m, 2.0 * gsd_m],
            "vertical_rmse_m": [1.5 * gsd_m, 3.0 * gsd_m],
            "vertical_rmse_from_range_m": [self.alt_agl_m / 1000.0, self.alt_agl_m / 639.0],
        }

    def as_dict(self) -> dict[str, object]:
        o = self.options
        return {
            "crs": self.crs,
            "gcp_count": sum(p.role == "gcp" for p in self.points),
            "check_count": sum(p.role == "check" for p in self.points),
            "min_frames": o.min_frames,
            "clearance_m": o.clearance_m,
            "edge_margin_m": o.edge_margin_m,
            "min_separation_m": o.min_separation_m,
            "expected_accuracy": self.expected_accuracy(),
            "points": [p.__dict__ for p in self.points],
        }


def usable_ground(plan: SurveyPlan, options: GcpOptions) -> Polygon | MultiPolygon:
    """Where a point may go: the area less its margin, less the exclusions grown by the clearance."""
    # Buffers trace arcs with chords, which come up to 0.5 % closer than the radius: pad them.
    ground = plan.area_xy.buffer(-(options.edge_margin_m * 1.01 + 0.01))
    if plan.exclusions_xy:
        pad = options.clearance_m * 1.01 + 0.01
        blocked = shapely.union_all([z.buffer(pad) for z in plan.exclusions_xy])
        ground = ground.difference(blocked)
    return ground


def _largest(leaves_ground: object, top: float) -> float:
    """The largest value in [0, top] for which ``leaves_ground(value)`` (monotonic: true below
    some value) holds, to 0.1 m below."""
    assert callable(leaves_ground)
    lo, hi = 0.0, top
    for _ in range(40):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if leaves_ground(mid) else (lo, mid)
    return math.floor(lo * 10) / 10


def _no_ground_message(plan: SurveyPlan, options: GcpOptions) -> str:
    """Why no ground is left for targets, naming the options and the figure that fits."""
    edge, clear = options.edge_margin_m, options.clearance_m
    lead = f"--edge-margin-m {edge:g} and --clearance-m {clear:g} leave no ground for targets in this area"

    def ground_with(edge_m: float, clearance_m: float) -> bool:
        trial = replace(options, edge_margin_m=edge_m, clearance_m=clearance_m)
        return not usable_ground(plan, trial).is_empty

    if ground_with(0.0, clear):
        fits = _largest(lambda e: ground_with(e, clear), edge)
        return f"{lead}: ask for --edge-margin-m {fits:g} or less (a target needs ground around it)"
    if ground_with(edge, 0.0):
        fits = _largest(lambda c: ground_with(edge, c), clear)
        return f"{lead}: ask for --clearance-m {fits:g} or less"
    return f"{lead}: lower both (the exclusions cover the area)"


def frame_counts(plan: SurveyPlan, x_m: NDArray[np.float64], y_m: NDArray[np.float64]) -> NDArray[np.int64]:
    """How many planned footprints hold each point (every pass, obliques included): a point on a
    footprint's edge is not held.

    The spatial index is built over the points (a few thousand candidates), not over the frames
    (up to millions), and the footprints are made into polygons and queried a block of
    :data:`FOOTPRINT_BLOCK` at a time: memory stays that of one block whatever the plan's size,
    and the time grows with the frames alone."""
    corners = plan.stations.footprint_xy_m
    counts = np.zeros(len(x_m), np.int64)
    if len(corners) == 0 or len(x_m) == 0:
        return counts
    tree = shapely.STRtree(shapely.points(x_m, y_m))
    for start in range(0, len(corners), FOOTPRINT_BLOCK):
        block = np.asarray(corners[start : start + FOOTPRINT_BLOCK], dtype=np.float64)
        rings = np.concatenate([block, block[:, :1]], axis=1)
        _, held = tree.query(shapely.polygons(rings), predicate="contains")
        counts += np.bincount(held, minlength=len(x_m))
    return counts


def plan_gcps(plan: SurveyPlan, options: GcpOptions) -> GcpLayout:
    """Lay out ``options.gcp_count`` GCPs and ``options.check_count`` check points (module docstring)."""
    ground = usable_ground(plan, options)
    if ground.is_empty:
        raise InputError(_no_ground_message(plan, options))
    ox, oy = _outline_candidates(ground, options.min_separation_m)
    gx, gy = _grid_candidates(ground)
    x = np.concatenate([ox, gx])
    y = np.concatenate([oy, gy])
    on_outline = np.concatenate([np.ones(len(ox), bool), np.zeros(len(gx), bool)])
    counts = frame_counts(plan, x, y)
    seen = counts >= options.min_frames
    if not seen.any():
        most = int(counts.max()) if counts.size else 0
        raise InputError(
            f"--min-frames {options.min_frames}: no point of the usable ground is seen by that many "
            f"planned frames; the most any point gets is {most}: ask for --min-frames {max(most, 1)} "
            f"or fewer, or plan with higher overlaps"
        )
    x, y, on_outline, counts = x[seen], y[seen], on_outline[seen], counts[seen]
    xy = np.column_stack([x, y])
    wanted = options.gcp_count + options.check_count
    sep = options.min_separation_m

    chosen: list[int] = []
    placement: list[str] = []
    n_outline = min(options.gcp_count, max(4, math.ceil(options.gcp_count / 2)))
    outline_idx = np.nonzero(on_outline)[0]
    if outline_idx.size == 0:
        outline_idx = np.arange(len(x))  # a tiny area: its outline candidates are all too little seen
    # Corners: the candidates nearest the corners of the area's minimum rotated rectangle.
    rect = np.asarray(plan.area_xy.minimum_rotated_rectangle.exterior.coords)[:4]
    for corner in rect[: min(4, n_outline)]:
        d = np.hypot(*(xy[outline_idx] - corner).T)
        for k in outline_idx[np.argsort(d)]:
            if _far_enough(xy, chosen, int(k), sep):
                chosen.append(int(k))
                placement.append("corner")
                break
    _farthest(xy, outline_idx, chosen, placement, n_outline - len(chosen), sep, "edge")
    n_interior = options.gcp_count - len(chosen)
    if n_interior > 0:
        interior_idx = np.nonzero(~on_outline)[0]
        if interior_idx.size == 0:
            interior_idx = np.arange(len(x))
        _stratified(xy, interior_idx, chosen, placement, n_interior, sep)
    if len(chosen) < options.gcp_count:
        _farthest(xy, np.arange(len(x)), chosen, placement, options.gcp_count - len(chosen), sep, "interior")
    n_gcp = len(chosen)
    if n_gcp == options.gcp_count:
        _farthest(xy, np.arange(len(x)), chosen, placement, options.check_count, sep, "check")
    if len(chosen) < wanted:
        fits = len(chosen)
        asked = (
            f"--gcp {options.gcp_count} --check {options.check_count} asks for {wanted} points {sep:g} m "
            f"apart where {options.min_frames} planned frames see them ({options.edge_margin_m:g} m inside "
            f"the edges, {options.clearance_m:g} m from exclusions)"
        )
        if fits < 3:
            raise InputError(
                f"{asked}: only {fits} fit{'s' if fits == 1 else ''}, and a block needs 3 GCPs: lower "
                f"--min-separation-m or --edge-margin-m"
            )
        checks = min(options.check_count, fits - 3)
        raise InputError(
            f"{asked}: only {fits} fit; ask for {fits} points or fewer (e.g. --gcp {fits - checks} "
            f"--check {checks}), or lower --min-separation-m"
        )
    lon, lat = plan.frame.to_lonlat(xy[chosen, 0], xy[chosen, 1])
    points = []
    g = c = 0
    for i, (k, where) in enumerate(zip(chosen, placement, strict=True)):
        role = "check" if where == "check" else "gcp"
        if role == "gcp":
            g += 1
            name = f"GCP{g:02d}"
        else:
            c += 1
            name = f"CHK{c:02d}"
        points.append(
            GroundPoint(
                name=name,
                role=role,
                placement=where,
                x_m=float(xy[k, 0]),
                y_m=float(xy[k, 1]),
                lon_deg=float(np.atleast_1d(lon)[i]),
                lat_deg=float(np.atleast_1d(lat)[i]),
                frame_count=int(counts[k]),
            )
        )
    frame = plan.frame
    return GcpLayout(
        points=tuple(points),
        crs=f"EPSG:{frame.epsg}" if frame.epsg else frame.crs.to_string(),
        options=options,
        gsd_cm=plan.summary.gsd_cm,
        alt_agl_m=plan.summary.altitude_agl_m,
    )


def _outline_candidates(
    ground: Polygon | MultiPolygon, separation_m: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    rings = [r for poly in getattr(ground, "geoms", [ground]) for r in [poly.exterior, *poly.interiors]]
    total = sum(r.length for r in rings)
    step = max(total / MAX_OUTLINE_CANDIDATES, min(separation_m / 4.0, total / 200.0), 0.5)
    xs, ys = [], []
    for ring in rings:
        distances = np.arange(0.0, ring.length, step)
        pts = shapely.line_interpolate_point(ring, distances)
        coords = shapely.get_coordinates(pts)
        xs.append(coords[:, 0])
        ys.append(coords[:, 1])
    return np.concatenate(xs), np.concatenate(ys)


def _grid_candidates(ground: Polygon | MultiPolygon) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    step = max(math.sqrt(ground.area / MAX_GRID_CANDIDATES), 0.5)
    x0, y0, x1, y1 = ground.bounds
    mx, my = np.meshgrid(np.arange(x0 + step / 2, x1, step), np.arange(y0 + step / 2, y1, step))
    gx, gy = mx.ravel(), my.ravel()
    inside = shapely.contains_xy(ground, gx, gy)
    return gx[inside], gy[inside]


def _far_enough(xy: NDArray[np.float64], chosen: list[int], k: int, sep: float) -> bool:
    if not chosen:
        return True
    return bool(np.min(np.hypot(*(xy[chosen] - xy[k]).T)) >= sep - 1e-9)


def _farthest(
    xy: NDArray[np.float64],
    pool: NDArray[np.intp],
    chosen: list[int],
    placement: list[str],
    count: int,
    sep: float,
    label: str,
) -> None:
    """Add up to ``count`` points of ``pool``, each the farthest from those chosen (>= sep)."""
    if count <= 0 or pool.size == 0:
        return
    pts = xy[pool]
    if chosen:
        d = np.min(
            np.hypot(pts[:, None, 0] - xy[chosen][None, :, 0], pts[:, None, 1] - xy[chosen][None, :, 1]), 1
        )
    else:
        centre = pts.mean(axis=0)
        d = np.full(len(pool), np.inf)
        first = int(np.argmax(np.hypot(*(pts - centre).T)))
        chosen.append(int(pool[first]))
        placement.append(label)
        d = np.minimum(d, np.hypot(*(pts - pts[first]).T))
        count -= 1
    for _ in range(count):
        best = int(np.argmax(d))
        if d[best] < sep - 1e-9:
            return
        chosen.append(int(pool[best]))
        placement.append(label)
        d = np.minimum(d, np.hypot(*(pts - pts[best]).T))


def _stratified(
    xy: NDArray[np.float64],
    pool: NDArray[np.intp],
    chosen: list[int],
    placement: list[str],
    count: int,
    sep: float,
) -> None:
    """One point per stratum: k-means strata of the interior candidates (about equal size and
    compact, the candidates lying on a regular grid), the candidate nearest each centre."""
    pts = xy[pool]
    if len(pts) < count:
        return
    # Seed the strata by farthest-point sampling (deterministic), then Lloyd iterations.
    seeds = [int(np.argmin(np.hypot(*(pts - pts.mean(axis=0)).T)))]
    d = np.hypot(*(pts - pts[seeds[0]]).T)
    while len(seeds) < count:
        seeds.append(int(np.argmax(d)))
        d = np.minimum(d, np.hypot(*(pts - pts[seeds[-1]]).T))
    centres = pts[seeds].copy()
    for _ in range(KMEANS_ITERATIONS):
        labels = _nearest(pts, centres)
        moved = np.array(
            [pts[labels == j].mean(axis=0) if np.any(labels == j) else centres[j] for j in range(count)]
        )
        if np.allclose(moved, centres, atol=0.01):
            break
        centres = moved
    labels = _nearest(pts, centres)
    for j in range(count):
        members = np.nonzero(labels == j)[0]
        if members.size == 0:
            continue
        order = members[np.argsort(np.hypot(*(pts[members] - centres[j]).T))]
        for m in order:
            if _far_enough(xy, chosen, int(pool[m]), sep):
                chosen.append(int(pool[m]))
                placement.append("interior")
                break


def _nearest(pts: NDArray[np.float64], centres: NDArray[np.float64]) -> NDArray[np.intp]:
    labels = np.empty(len(pts), np.intp)
    for start in range(0, len(pts), 4096):
        chunk = pts[start : start + 4096]
        d = np.hypot(chunk[:, None, 0] - centres[None, :, 0], chunk[:, None, 1] - centres[None, :, 1])
        labels[start : start + 4096] = np.argmin(d, axis=1)
    return labels
