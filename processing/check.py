"""The field coverage check: will these frames (or this plan) reconstruct?

:func:`run_check` projects every frame onto the ground, counts the views per ground cell over
the area, finds the gaps, measures forward and side overlap, base-height ratios, GSD, motion
blur and scale differences, and judges them against :class:`~processing.verdict.Thresholds`
(:func:`processing.verdict.judge`, re-exported here). This module is the pipeline and the result
types it fills (:class:`CheckResult`, :class:`Gap`, :class:`FrameFlag`, :class:`Distribution`).
The CLI (``sfap check``) calls it and exits 0 when the check passes, 1 when it fails.

The area judged (``CheckResult.area_source`` says which):

1. the area given (``area=``, a WGS84 polygon, e.g. from ``--area FILE``);
2. else the plan's area (``plan=``: area.geojson of the plan folder, exclusions removed);
3. else the block the flight spans: the convex hull of the points where the frames' optical
   axes meet the ground. Every point inside it lies between frame centres, so a well-flown
   block sees it several times; the outer halves of the edge frames (seen once or twice by
   nature) are outside and are not gaps, and neither are the turns between lines, which lie
   outside the area or are covered by the lines' frames. A concave block (an L shape) makes
   its notch look like a gap: give the area then.

The check works in metres in a transverse Mercator frame centred on the frames
(:func:`processing.frames.local_frame_at`), where grid north is true north: the frames' yaw
is a true bearing, and in a UTM zone (grid north up to 3 deg off) every footprint would turn
about its camera and open false gaps along the area's edges.

Gaps are the connected parts of the area seen by no frame, computed on the footprints
themselves (:func:`exact_gaps`: a sliver is one gap with its true area), smaller ones than
``Thresholds.min_gap_area_m2`` dropped (crumbs where footprint corners meet). Shares of the
area seen come from the view-count raster.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon

from planner.camera import Orientation
from planner.geo import LocalFrame

from .coverage import Grid
from .distribution import Distribution
from .errors import ProcessingError
from .footprints import Footprints
from .frames import AttitudeSource, Frames, frames_local_frame
from .ground import Ground
from .plan_frames import PlanInfo
from .verdict import (
    DEFAULT_THRESHOLDS,
    LineSteps,
    Thresholds,
    above,
    good_base_height,
    judge,
    overlap_warnings,
)

log = logging.getLogger(__name__)

#: Images whose median height differs from the plan's by more than this (and 10 %) are reported, m.
PLAN_HEIGHT_TOLERANCE_M = 10.0
#: View counts whose area shares are reported ("seen by at least k frames").
VIEW_LEVELS = (1, 2, 3, 5, 9)
#: Codes of :attr:`CheckResult.stereo_class`.
STEREO_NONE, STEREO_WEAK, STEREO_GOOD, STEREO_WIDE = -1, 0, 1, 2


@dataclass(frozen=True, kw_only=True)
class Gap:
    """A connected part of the area seen by no frame.

    ``polygon_xy`` in the check's local frame (metres), ``polygon_lonlat`` in WGS84;
    ``area_m2`` measured in the local frame.
    """

    index: int
    area_m2: float
    centroid_lon_deg: float
    centroid_lat_deg: float
    polygon_xy: Polygon
    polygon_lonlat: Polygon


@dataclass(frozen=True, kw_only=True)
class FrameFlag:
    """A frame the report points out, and why (``kind``: blur, scale, low, ...)."""

    name: str
    kind: str
    detail: str


@dataclass(frozen=True, kw_only=True)
class CheckResult:
    """Everything a check measured, and the verdict. ``as_dict`` is report.json.

    Rasters share ``grid`` (rows from north, ``extent_xy_m`` = (west, south, east, north) in
    ``frame``'s metres): ``view_count`` (views per cell), ``in_area`` (cell centre inside the
    area), ``gsd_cm_raster`` (finest GSD that sees each cell, NaN where none does),
    ``stereo_class`` (the best pair that sees the cell: :data:`STEREO_GOOD` a B/H in the
    thresholds' range, else :data:`STEREO_WIDE` above it, else :data:`STEREO_WEAK` below it,
    :data:`STEREO_NONE` no pair).
    Per-frame arrays follow ``frames``' rows.
    """

    passed: bool
    reasons: tuple[str, ...]
    warnings: tuple[str, ...]
    notes: tuple[str, ...]
    thresholds: Thresholds
    frames: Frames
    frame: LocalFrame
    ground_description: str
    area_source: str
    area_xy: Polygon | MultiPolygon
    area_lonlat: Polygon | MultiPolygon
    area_m2: float
    cell_m: float
    grid: Any
    extent_xy_m: tuple[float, float, float, float]
    view_count: NDArray[np.int32]
    in_area: NDArray[np.bool_]
    seen_pct: dict[int, float]
    gaps: tuple[Gap, ...]
    footprints_xy: NDArray[np.float64]
    footprints_lonlat: NDArray[np.float64]
    centres_xy: NDArray[np.float64]
    height_agl_m: NDArray[np.float64]
    gsd_cm: NDArray[np.float64]
    gsd_cm_raster: NDArray[np.float64] | None
    forward_overlap_pct: Distribution | None
    side_overlap_pct: Distribution | None
    pair_index: NDArray[np.int64]  # (M, 2) frame rows of the overlapping pairs
    pair_base_height_ratio: NDArray[np.float64]
    pair_intersection_deg: NDArray[np.float64]
    good_pair_pct: float | None
    stereo_class: NDArray[np.int8]
    convergent_pct: float
    doming_risk: bool
    speed_m_s: NDArray[np.float64] | None
    blur_px: NDArray[np.float64] | None
    flagged: tuple[FrameFlag, ...]
    plan: PlanInfo | None = None
    pair_along_line: NDArray[np.bool_] | None = None
    pair_across_lines: NDArray[np.bool_] | None = None
    unpositioned: tuple[str, ...] = ()
    left_out: tuple[tuple[str, str], ...] = ()
    camera_source: str = ""
    good_pair_basis: str = "frames on one line or neighbouring lines"
    stats: dict[str, Any] = field(default_factory=dict)

    @property
    def exit_code(self) -> int:
        """0 when the check passed, 1 when it failed."""
        return 0 if self.passed else 1

    @property
    def base_height_along_line(self) -> Distribution | None:
        """B/H of consecutive frames of a line (the forward-overlap pairs)."""
        if self.pair_along_line is None:
            return None
        return Distribution.of(self.pair_base_height_ratio[self.pair_along_line])

    @property
    def base_height_across_lines(self) -> Distribution | None:
        """B/H of pairs of frames on different lines (the side-overlap pairs)."""
        if self.pair_across_lines is None:
            return None
        return Distribution.of(self.pair_base_height_ratio[self.pair_across_lines])

    @property
    def gap_area_m2(self) -> float:
        return float(sum(g.area_m2 for g in self.gaps))

    def key_figures(self) -> list[tuple[str, str]]:
        """The figures a person reads first, as (label, text) rows."""
        rows: list[tuple[str, str]] = [
            (
                "frames",
                f"{len(self.frames)} ({self.frames.camera.id}, attitude {self.frames.attitude_source.value})",
            ),
            *([("camera", self.camera_source)] if self.camera_source else []),
            ("ground", self.ground_description),
            ("area", f"{self.area_m2 / 1e4:.2f} ha ({self.area_source}), cells {self.cell_m:g} m"),
            (
                "seen by >= 1 / 3 / 5 frames",
                " / ".join(f"{self.seen_pct[k]:.1f} %" for k in (1, 3, 5)),
            ),
            ("gaps", f"{len(self.gaps)}, {self.gap_area_m2:.0f} m2" if self.gaps else "none"),
        ]
        plan = self.plan
        for label, dist, planned in (
            ("forward overlap", self.forward_overlap_pct, plan.front_overlap_pct if plan else None),
            ("side overlap", self.side_overlap_pct, plan.side_overlap_pct if plan else None),
        ):
            if dist is None:
                rows.append((label, "not measured (no consecutive frames along a line)"))
                continue
            text = f"median {dist.median:.0f} % (10-90 %: {dist.p10:.0f}-{dist.p90:.0f} %)"
            if planned is not None:
                text += f", planned {planned:g} %"
            rows.append((label, text))
        for label, dist in (
            ("B/H along lines", self.base_height_along_line),
            ("B/H across lines", self.base_height_across_lines),
        ):
            if dist is None:
                rows.append((label, "no such pair"))
            else:
                text = f"median {dist.median:.2f} (10-90 %: {dist.p10:.2f}-{dist.p90:.2f})"
                rows.append((label, f"{text} over {dist.count} pairs"))
        if self.good_pair_pct is not None:
            rows.append(
                (
                    "stereo",
                    f"{self.good_pair_pct:.1f} % of the area has a pair ({self.good_pair_basis}) with B/H in "
                    f"{self.thresholds.min_base_height_ratio:g}-{self.thresholds.max_base_height_ratio:g}",
                )
            )
        gsd = Distribution.of(self.gsd_cm)
        if gsd is not None:
            rows.append(("GSD", f"median {gsd.median:.2f} cm ({gsd.min:.2f}-{gsd.max:.2f} cm)"))
        h = Distribution.of(self.height_agl_m)
        if h is not None:
            rows.append(("height above ground", f"median {h.median:.1f} m ({h.min:.1f}-{h.max:.1f} m)"))
        speed = Distribution.of(self.speed_m_s) if self.speed_m_s is not None else None
        if self.speed_m_s is None:
            rows.append(("ground speed", "not measured (no capture times)"))
        elif speed is None:
            rows.append(("ground speed", "unknown (no two frames of a line close enough in time)"))
        else:
            unknown = int(np.isnan(self.speed_m_s).sum())
            text = f"median {speed.median:.1f} m/s ({speed.min:.1f}-{speed.max:.1f} m/s)"
            rows.append(("ground speed", text + (f", unknown for {unknown} frames" if unknown else "")))
        blur = Distribution.of(self.blur_px) if self.blur_px is not None else None
        if self.speed_m_s is None:
            rows.append(("motion blur", "not computed (no capture times)"))
        elif self.blur_px is None:
            rows.append(("motion blur", "not computed (no exposure time in the images or the camera)"))
        elif blur is None:
            rows.append(("motion blur", "blur not computed for any frame (speed or exposure unknown)"))
        else:
            unknown_blur = int(np.isnan(self.blur_px).sum())
            text = f"median {blur.median:.2f} px, max {blur.max:.2f} px (where worst in each frame)"
            if unknown_blur:
                text += f"; blur not computed for {unknown_blur} frames (speed or exposure unknown)"
            rows.append(("motion blur", text))
        rows.append(
            (
                "convergent frames",
                f"{self.convergent_pct:.0f} %" + (" (doming risk)" if self.doming_risk else ""),
            )
        )
        return rows

    def as_dict(self) -> dict[str, Any]:
        """report.json: the same figures as the HTML report (units in every key)."""
        plan = self.plan
        frames = self.frames
        per_frame: list[dict[str, Any]] = []
        for k in range(len(frames)):
            row: dict[str, Any] = {
                "name": frames.name[k],
                "lon_deg": float(frames.lon_deg[k]),
                "lat_deg": float(frames.lat_deg[k]),
                f"alt_{frames.alt_reference.value}_m": float(frames.alt_m[k]),
                "height_agl_m": float(self.height_agl_m[k]),
                "yaw_deg": float(frames.yaw_deg[k]),
                "pitch_deg": float(frames.pitch_deg[k]),
                "roll_deg": float(frames.roll_deg[k]),
                "gsd_cm": float(self.gsd_cm[k]),
            }
            if self.speed_m_s is not None:
                row["speed_m_s"] = float(self.speed_m_s[k])
            if self.blur_px is not None:
                row["blur_px"] = float(self.blur_px[k])
            per_frame.append(row)
        bh = Distribution.of(self.pair_base_height_ratio)
        angle = Distribution.of(self.pair_intersection_deg)
        return {
            "verdict": "pass" if self.passed else "fail",
            "passed": self.passed,
            "exit_code": self.exit_code,
            "reasons": list(self.reasons),
            "warnings": list(self.warnings),
            "notes": list(self.notes),
            "thresholds": self.thresholds.as_dict(),
            "frames": {
                "count": len(frames),
                "camera_id": frames.camera.id,
                "camera_name": frames.camera.name,
                "camera_source": self.camera_source or None,
                "attitude_source": frames.attitude_source.value,
                "altitude_reference": frames.alt_reference.value,
                "unpositioned": list(self.unpositioned),
                "left_out": [{"name": name, "reason": why} for name, why in self.left_out],
            },
            "ground": self.ground_description,
            "area": {
                "source": self.area_source,
                "area_m2": self.area_m2,
                "crs": f"EPSG:{self.frame.epsg}" if self.frame.epsg else self.frame.crs.to_string(),
                "cell_m": self.cell_m,
                "extent_xy_m": list(self.extent_xy_m),
            },
            "coverage": {
                "seen_by_at_least_pct": {str(k): v for k, v in self.seen_pct.items()},
                "gap_count": len(self.gaps),
                "gap_area_m2": self.gap_area_m2,
                "gaps": [
                    {
                        "index": g.index,
                        "area_m2": g.area_m2,
                        "centroid_lon_deg": g.centroid_lon_deg,
                        "centroid_lat_deg": g.centroid_lat_deg,
                    }
                    for g in self.gaps
                ],
            },
            "overlap": {
                "forward_pct": self.forward_overlap_pct.as_dict() if self.forward_overlap_pct else None,
                "side_pct": self.side_overlap_pct.as_dict() if self.side_overlap_pct else None,
                "plan_front_overlap_pct": plan.front_overlap_pct if plan else None,
                "plan_side_overlap_pct": plan.side_overlap_pct if plan else None,
            },
            "stereo": {
                "pair_count": int(self.pair_index.shape[0]),
                "base_height_ratio": bh.as_dict() if bh else None,
                "base_height_ratio_along_line": (
                    d.as_dict() if (d := self.base_height_along_line) is not None else None
                ),
                "base_height_ratio_across_lines": (
                    d.as_dict() if (d := self.base_height_across_lines) is not None else None
                ),
                "intersection_angle_deg": angle.as_dict() if angle else None,
                "good_pair_area_pct": self.good_pair_pct,
                "good_pair_basis": self.good_pair_basis,
                "convergent_frames_pct": self.convergent_pct,
                "doming_risk": self.doming_risk,
            },
            "gsd_cm": (d.as_dict() if (d := Distribution.of(self.gsd_cm)) else None),
            "height_agl_m": (d.as_dict() if (d := Distribution.of(self.height_agl_m)) else None),
            "speed_m_s": (
                d.as_dict() if self.speed_m_s is not None and (d := Distribution.of(self.speed_m_s)) else None
            ),
            "blur_px": (
                d.as_dict() if self.blur_px is not None and (d := Distribution.of(self.blur_px)) else None
            ),
            "flagged_frames": [{"name": f.name, "kind": f.kind, "detail": f.detail} for f in self.flagged],
            "plan": (
                {
                    "folder": str(plan.folder),
                    "name": plan.name,
                    "camera_id": plan.camera.id,
                    "altitude_agl_m": plan.altitude_agl_m,
                    "gsd_cm": plan.gsd_cm,
                    "front_overlap_pct": plan.front_overlap_pct,
                    "side_overlap_pct": plan.side_overlap_pct,
                }
                if plan
                else None
            ),
            "stats": self.stats,
            "per_frame": per_frame,
        }


def default_cell_m(footprint_short_side_m: float, area_m2: float, max_cells: int = 4_000_000) -> float:
    """Cell size for the view-count raster: 1/50 of a frame's shorter ground side (a gap of
    2 % of a frame is resolved), rounded to 1-2-5, coarser when the area would need more than
    ``max_cells`` cells."""
    target = max(footprint_short_side_m / 50.0, math.sqrt(max(area_m2, 0.0) / max_cells), 0.01)
    exponent = math.floor(math.log10(target))
    for mantissa in (1.0, 2.0, 5.0, 10.0):
        cell = mantissa * 10.0**exponent
        if cell >= target * (1 - 1e-9):
            return float(round(cell, 6))
    return float(10.0 ** (exponent + 1))  # pragma: no cover


ProgressCallback = Callable[[str, int, int], None]


# --- the check -----------------------------------------------------------------------------------


def block_area_xy(centres_xy: NDArray[np.float64], footprint_short_side_m: float) -> Polygon | MultiPolygon:
    """The block the flight spans: the convex hull of the frames' ground centres (module
    docstring). A single line or a single frame spans no area: its hull is then grown by a
    quarter of a frame's shorter ground side."""
    points = shapely.MultiPoint(centres_xy.tolist())
    hull = points.convex_hull
    if hull.area < (0.05 * footprint_short_side_m) ** 2:
        hull = hull.buffer(0.25 * footprint_short_side_m)
    assert isinstance(hull, Polygon)
    return hull


def exact_gaps(
    area_xy: Polygon | MultiPolygon, footprints: Sequence[Any] | NDArray[np.object_], *, min_area_m2: float
) -> list[Polygon]:
    """The gaps as they are, not as the raster sees them: the connected parts of the area that no
    footprint covers (area minus the union of the footprints), at least ``min_area_m2`` each,
    largest first. A sliver between two footprints that cuts across cells diagonally is one gap
    with its true area here; on the raster it would be a chain of cells that touch at corners
    (counted as many gaps) or none at all."""
    union = shapely.union_all(shapely.make_valid(np.asarray(footprints, dtype=object)))
    uncovered = shapely.make_valid(area_xy.difference(union))
    parts = [g for g in shapely.get_parts(uncovered) if isinstance(g, Polygon) and g.area >= min_area_m2]
    parts.sort(key=lambda p: p.area, reverse=True)
    return parts


def run_check(
    frames: Frames,
    *,
    ground: Ground,
    area: Polygon | MultiPolygon | None = None,
    plan: PlanInfo | None = None,
    cell_m: float | None = None,
    thresholds: Thresholds = DEFAULT_THRESHOLDS,
    progress: Callable[[int, int], None] | None = None,
    ground_description: str | None = None,
    notes: Sequence[str] = (),
    unpositioned: Sequence[str] = (),
    left_out: Sequence[tuple[str, str]] = (),
    warnings: Sequence[str] = (),
    camera_source: str = "",
) -> CheckResult:
    """Check ``frames`` over ``ground`` (same altitude reference; see
    :func:`processing.ground_choice.ground_from_options`) and judge them against ``thresholds``.

    ``area``: WGS84 polygon to judge (None: the plan's area, else the flown block; module
    docstring). ``plan``: the plan the frames were meant to follow (its overlaps are the
    reference of the overlap checks). ``cell_m``: raster cell size in metres (None:
    :func:`default_cell_m`). ``progress(done, total)``: called while the view counts are
    rasterized (the long part). ``notes``, ``warnings``, ``unpositioned`` (image names without a
    position) and ``left_out`` ((name, reason) of every frame not checked: no position, another
    camera, not a survey frame) go into the report as they are.
    """
    from .coverage import (
        area_mask,
        coverage_stats,
        min_value_raster,
        view_count_raster,
    )
    from .footprints import project_footprints

    if len(frames) == 0:
        raise ProcessingError("there is no frame to check")
    all_warnings: list[str] = list(warnings)
    all_notes = list(notes)
    frame = frames_local_frame(frames)
    fp = project_footprints(frames, frame, ground)
    valid = fp.valid
    flagged: list[FrameFlag] = [
        FrameFlag(name=frames.name[k], kind="no footprint", detail=fp.reason[k])
        for k in np.flatnonzero(~valid)
    ]
    if not valid.any():
        raise ProcessingError(
            f"no frame has a complete footprint on the ground ({fp.reason[0]}); check the ground and the "
            "attitude"
        )
    height = fp.height_above_ground_m
    median_height = float(np.median(height[valid]))
    nominal = frames.camera.footprint(median_height, Orientation.LANDSCAPE)
    short_side_m = min(nominal.along_m, nominal.across_m)
    centres = fp.principal_xyz_m[:, :2]

    # The area.
    if area is not None:
        area_lonlat = area
        area_source = "the area given"
    elif plan is not None and plan.area_lonlat is not None:
        area_lonlat = plan.area_lonlat
        area_source = f"the plan's area ({plan.folder.name}/area.geojson)"
    else:
        area_lonlat = None
        area_source = (
            "the block the flight spans (convex hull of the frames' ground centres); give the plan or an "
            "area for a concave block"
        )
    if area_lonlat is not None:
        area_xy = frame.geometry_to_xy(area_lonlat)
    else:
        area_xy = block_area_xy(centres[valid], short_side_m)
        area_lonlat = frame.geometry_to_lonlat(area_xy)
    assert isinstance(area_xy, Polygon | MultiPolygon) and isinstance(area_lonlat, Polygon | MultiPolygon)
    if area_xy.is_empty or area_xy.area <= 0:
        raise ProcessingError("the area to check is empty; check the area polygon")
    rings = fp.xy_m[valid]
    xmin = min(area_xy.bounds[0], float(rings[..., 0].min()))
    ymin = min(area_xy.bounds[1], float(rings[..., 1].min()))
    xmax = max(area_xy.bounds[2], float(rings[..., 0].max()))
    ymax = max(area_xy.bounds[3], float(rings[..., 1].max()))
    if cell_m is None:
        cell_m = default_cell_m(short_side_m, (xmax - xmin) * (ymax - ymin))
    elif not (math.isfinite(cell_m) and cell_m > 0):
        raise ProcessingError(f"cell_m = {cell_m} must be a positive number of metres")
    grid = Grid.from_bounds((xmin, ymin, xmax, ymax), cell_m, frame.crs)
    log.info("view counts over %d x %d cells of %g m", grid.rows, grid.cols, cell_m)
    counts = view_count_raster(rings, grid, progress=progress)
    in_area = area_mask(area_xy, grid)
    if not in_area.any():
        raise ProcessingError(
            f"the area covers no cell of {cell_m:g} m; give a smaller --cell-m (the area is "
            f"{area_xy.area:.1f} m2)"
        )
    stats = coverage_stats(counts, in_area)
    seen_pct = {k: float(stats["seen_by_at_least_pct"][str(k)]) for k in VIEW_LEVELS}
    gaps: list[Gap] = []
    for k, polygon in enumerate(
        exact_gaps(area_xy, fp.polygons()[valid], min_area_m2=thresholds.min_gap_area_m2),
        start=1,
    ):
        lonlat = frame.geometry_to_lonlat(polygon)
        assert isinstance(lonlat, Polygon)
        c = lonlat.centroid
        gaps.append(
            Gap(
                index=k,
                area_m2=float(polygon.area),
                centroid_lon_deg=float(c.x),
                centroid_lat_deg=float(c.y),
                polygon_xy=polygon,
                polygon_lonlat=lonlat,
            )
        )
    gsd_raster = min_value_raster(rings, fp.gsd_cm[valid], grid)

    stereo = _stereo(frames, fp, ground, frame, grid, in_area, thresholds)
    all_warnings.extend(stereo.warnings)
    all_notes.extend(stereo.notes)
    flagged.extend(stereo.flagged)

    from .survey_frames import altitude_drift_warning

    drift = altitude_drift_warning(frames.alt_m, frames.time_utc_s, median_height, frames.alt_reference.value)
    if drift is not None:
        all_warnings.append(drift)
    if frames.attitude_source is AttitudeSource.ASSUMED_NADIR:
        all_warnings.append(
            "the images carry no attitude: every frame was taken as nadir with the image top along the "
            "track; tilted frames would shift the footprints"
        )
    if left_out:
        all_warnings.append(
            f"{len(left_out)} frame(s) left out of coverage, GSD and scale figures: "
            + "; ".join(f"{name} ({why})" for name, why in left_out[:10])
            + (f"; and {len(left_out) - 10} more (report.json)" if len(left_out) > 10 else "")
        )
    elif unpositioned:
        all_warnings.append(
            f"{len(unpositioned)} image(s) without a position were left out: {', '.join(unpositioned)}"
        )
    if stereo.doming_risk:
        all_warnings.append(
            f"only {stereo.convergent_pct:.0f} % of the frames are convergent (oblique): a nadir-only block "
            "risks the doming effect (James and Robson 2014); add oblique frames or a crosshatch pass"
        )
    if plan is not None:
        gsd = Distribution.of(fp.gsd_cm[valid])
        if gsd is not None and gsd.median > 1.1 * plan.gsd_cm:
            all_warnings.append(
                f"median GSD {gsd.median:.2f} cm is more than 10 % coarser than the planned "
                f"{plan.gsd_cm:.2f} cm: flown higher than planned?"
            )
        if frames.alt_reference.value in ("amsl", "ellipsoid") and plan.altitude_agl_m > 0:
            off = median_height - plan.altitude_agl_m
            if abs(off) > max(PLAN_HEIGHT_TOLERANCE_M, 0.1 * plan.altitude_agl_m):
                all_warnings.append(
                    f"the frames are {abs(off):.0f} m {'higher' if off > 0 else 'lower'} above the ground "
                    f"(median {median_height:.1f} m) than the plan's {plan.altitude_agl_m:.1f} m: flown so, "
                    "or the camera altitudes are not above mean sea level (an ellipsoidal height is tens of "
                    "metres off it in most places) or the ground elevation is wrong; heights, GSD and B/H "
                    f"reported scale with it ({100 * off / plan.altitude_agl_m:+.0f} %)"
                )
    blurred_frames = (
        [
            (frames.name[k], float(stereo.blur_px[k]))
            for k in np.flatnonzero(above(stereo.blur_px, thresholds.fail_blur_px))
        ]
        if stereo.blur_px is not None
        else []
    )
    warned = [f for f in flagged if f.kind == "blur"]
    if warned:
        all_warnings.append(
            f"{len(warned)} frame(s) with motion blur above {thresholds.max_blur_px:g} px (flagged frames), "
            f"{len(blurred_frames)} of them above {thresholds.fail_blur_px:g} px"
        )
    reasons = judge(
        thresholds=thresholds,
        seen_pct=seen_pct,
        gaps=gaps,
        forward_overlap_pct=stereo.forward_overlap_pct,
        side_overlap_pct=stereo.side_overlap_pct,
        plan=plan,
        good_pair_pct=stereo.good_pair_pct,
        blurred_count=len(blurred_frames),
        blurred_frames=blurred_frames,
        frame_count=len(frames),
        blur_unknown_count=(int(np.isnan(stereo.blur_px).sum()) if stereo.blur_px is not None else 0),
        base_height_along_line=Distribution.of(stereo.pair_base_height_ratio[stereo.pair_along_line]),
        steps=stereo.steps,
        good_pair_basis=stereo.good_pair_basis,
    )
    all_warnings.extend(
        overlap_warnings(
            thresholds=thresholds,
            forward_overlap_pct=stereo.forward_overlap_pct,
            side_overlap_pct=stereo.side_overlap_pct,
            steps=stereo.steps,
        )
    )
    lonlat_rings = np.stack(frame.to_lonlat(fp.xy_m[..., 0], fp.xy_m[..., 1]), axis=-1)
    return CheckResult(
        passed=not reasons,
        reasons=reasons,
        warnings=tuple(all_warnings),
        notes=tuple(all_notes),
        thresholds=thresholds,
        frames=frames,
        frame=frame,
        ground_description=ground_description or ground.description,
        area_source=area_source,
        area_xy=area_xy,
        area_lonlat=area_lonlat,
        area_m2=float(area_xy.area),
        cell_m=float(cell_m),
        grid=grid,
        extent_xy_m=grid.bounds,
        view_count=counts.counts.astype(np.int32),
        in_area=in_area,
        seen_pct=seen_pct,
        gaps=tuple(gaps),
        footprints_xy=fp.xy_m,
        footprints_lonlat=lonlat_rings,
        centres_xy=centres[valid],
        height_agl_m=height,
        gsd_cm=fp.gsd_cm,
        gsd_cm_raster=gsd_raster,
        forward_overlap_pct=stereo.forward_overlap_pct,
        side_overlap_pct=stereo.side_overlap_pct,
        pair_index=stereo.pair_index,
        pair_base_height_ratio=stereo.pair_base_height_ratio,
        pair_intersection_deg=stereo.pair_intersection_deg,
        pair_along_line=stereo.pair_along_line,
        pair_across_lines=stereo.pair_across_lines,
        good_pair_pct=stereo.good_pair_pct,
        good_pair_basis=stereo.good_pair_basis,
        stereo_class=stereo.stereo_class,
        convergent_pct=stereo.convergent_pct,
        doming_risk=stereo.doming_risk,
        speed_m_s=stereo.speed_m_s,
        blur_px=stereo.blur_px,
        flagged=tuple(flagged),
        plan=plan,
        unpositioned=tuple(unpositioned),
        left_out=tuple(left_out),
        camera_source=camera_source,
        stats={
            "views_median": stats["views_median"],
            "views_max": stats["views_max"],
            "cells": stats["cells"],
            "pairs": int(stereo.pair_index.shape[0]),
            "lines": stereo.line_count,
        },
    )


@dataclass(frozen=True, kw_only=True)
class _Stereo:
    forward_overlap_pct: Distribution | None
    side_overlap_pct: Distribution | None
    pair_index: NDArray[np.int64]
    pair_base_height_ratio: NDArray[np.float64]
    pair_intersection_deg: NDArray[np.float64]
    pair_along_line: NDArray[np.bool_]
    pair_across_lines: NDArray[np.bool_]
    good_pair_pct: float | None
    stereo_class: NDArray[np.int8]
    convergent_pct: float
    doming_risk: bool
    speed_m_s: NDArray[np.float64] | None
    blur_px: NDArray[np.float64] | None
    flagged: tuple[FrameFlag, ...]
    warnings: tuple[str, ...]
    steps: LineSteps | None
    good_pair_basis: str
    notes: tuple[str, ...]
    line_count: int


def _stereo(
    frames: Frames,
    fp: Footprints,
    ground: Ground,
    frame: LocalFrame,
    grid: Grid,
    in_area: NDArray[np.bool_],
    thresholds: Thresholds,
) -> _Stereo:
    """Pairs, overlaps, convergence, scale and blur through :mod:`processing.stereo`."""
    from .coverage import count_raster
    from .stereo import (
        CONVERGENT_OFF_NADIR_DEG,
        SPEED_MAX_INTERVAL_RATIO,
        flight_lines,
        forward_overlaps_pct,
        motion_blur,
        off_nadir_deg,
        overlapping_pairs,
        pair_kinds,
        scale_outliers,
        side_overlaps_pct,
    )

    pairs = overlapping_pairs(fp, ground, frame)
    lines = flight_lines(frames, fp)
    along, across = pair_kinds(frames, pairs, lines)
    bh = pairs.base_height_ratio
    lo, hi = thresholds.min_base_height_ratio, thresholds.max_base_height_ratio
    classes = np.full(grid.shape, STEREO_NONE, dtype=np.int8)
    good_pct: float | None = None
    # The pairs that carry a block's stereo: two frames of the same line (consecutive ones, or
    # further apart when the endlap is high and consecutive bases are short) and a frame with the
    # nearest frame of a neighbouring line (the sidelap; at the ends of the lines the only pair).
    # Not every overlapping pair: frames two lines apart or diagonal would call ground good that
    # no matcher ties through neighbours. Without such pairs (no order to the frames) every
    # overlapping pair counts, and the basis says so.
    same_line = lines[pairs.i] == lines[pairs.j]
    kinds = same_line | across
    basis = kinds if kinds.any() else np.ones(len(pairs), dtype=bool)
    basis_text = "frames on one line or neighbouring lines" if kinds.any() else "any two overlapping frames"
    if basis.any():
        # Later classes win: a cell with any good pair is good, else wide, else weak.
        good = good_base_height(bh, thresholds) & basis
        for code, select in (
            (STEREO_WEAK, basis & ~good & (bh < lo)),
            (STEREO_WIDE, basis & ~good & (bh > hi)),
            (STEREO_GOOD, good),
        ):
            if select.any():
                classes[count_raster(list(pairs.intersection[select]), grid) > 0] = code
        good_pct = 100.0 * float(((classes == STEREO_GOOD) & in_area).sum()) / float(in_area.sum())
    flagged: list[FrameFlag] = []
    tolerance = thresholds.max_scale_difference_pct / 100.0
    for k in scale_outliers(fp, pairs, tolerance):
        flagged.append(
            FrameFlag(
                name=frames.name[k],
                kind="scale",
                detail=(
                    f"GSD {fp.gsd_cm[k]:.2f} cm differs by more than "
                    f"{thresholds.max_scale_difference_pct:g} % from its overlapping neighbours' (height "
                    f"above ground {fp.height_above_ground_m[k]:.1f} m)"
                ),
            )
        )
    ring = fp.xy_m
    ground_z = np.asarray(
        ground.elevation_at(ring[..., 0].ravel(), ring[..., 1].ravel(), frame), dtype=np.float64
    ).reshape(ring.shape[:2])
    blur = motion_blur(frames, fp, lines, ground_z_m=ground_z)
    speed = blur.speed_m_s if blur is not None else None
    blur_px = blur.blur_px if blur is not None else None
    notes: list[str] = []
    if blur is not None and blur.blur_px is not None and blur.exposure_s is not None:
        for k in np.flatnonzero(above(blur.blur_px, thresholds.max_blur_px)):
            centre = blur.blur_centre_px[k] if blur.blur_centre_px is not None else math.nan
            flagged.append(
                FrameFlag(
                    name=frames.name[k],
                    kind="blur",
                    detail=(
                        f"{blur.blur_px[k]:.2f} px of motion blur where worst ({centre:.2f} px at the "
                        "centre; "
                        f"{blur.speed_m_s[k]:.1f} m/s x {blur.exposure_s[k] * 1000:.2f} ms, GSD "
                        f"{fp.gsd_cm[k]:.2f} cm)"
                        + (
                            f": above {thresholds.fail_blur_px:g} px, it hurts matching"
                            if above(blur.blur_px[k : k + 1], thresholds.fail_blur_px)[0]
                            else f": above the {thresholds.max_blur_px:g} px warning"
                        )
                    ),
                )
            )
    if blur is not None:
        unknown = int(np.isnan(blur.speed_m_s).sum())
        if unknown:
            notes.append(
                f"ground speed unknown for {unknown} of {len(frames)} frames: no neighbour on the same "
                f"flight line within {blur.max_interval_s:.1f} s ({SPEED_MAX_INTERVAL_RATIO:g} x the median "
                "capture interval); their blur is not judged"
            )
    warnings: list[str] = []
    if len(pairs) and not kinds.any():
        warnings.append(
            "no two overlapping frames on one flight line or neighbouring ones (no capture times, or "
            "frames too far apart): "
            "the stereo share is judged on any two overlapping frames"
        )
    scale_count = sum(1 for f in flagged if f.kind == "scale")
    if scale_count:
        warnings.append(
            f"{scale_count} frame(s) differ in scale by more than {thresholds.max_scale_difference_pct:g} % "
            "from their neighbours: matching across them may fail (flagged frames)"
        )
    off_nadir = off_nadir_deg(fp)[fp.valid]
    convergent_pct = 100.0 * float((off_nadir > CONVERGENT_OFF_NADIR_DEG).mean()) if off_nadir.size else 0.0
    steps = None
    if along.any():
        interval_s = None
        if frames.time_utc_s is not None:
            t_s = np.asarray(frames.time_utc_s, dtype=np.float64)
            dt = np.abs(t_s[pairs.j[along]] - t_s[pairs.i[along]])
            dt = dt[np.isfinite(dt) & (dt > 0)]
            interval_s = float(np.median(dt)) if dt.size else None
        steps = LineSteps(
            base_m=float(np.median(pairs.base_m[along])),
            interval_s=interval_s,
            spacing_m=float(np.median(pairs.base_m[across])) if across.any() else None,
            base_height_along=float(np.median(bh[along])),
        )
    return _Stereo(
        forward_overlap_pct=Distribution.of(forward_overlaps_pct(frames, fp, lines)),
        side_overlap_pct=Distribution.of(side_overlaps_pct(frames, fp, lines)),
        steps=steps,
        good_pair_basis=basis_text,
        pair_index=np.column_stack([pairs.i, pairs.j]).astype(np.int64),
        pair_base_height_ratio=np.asarray(bh, dtype=np.float64),
        pair_intersection_deg=np.asarray(pairs.intersection_angle_deg, dtype=np.float64),
        pair_along_line=along,
        pair_across_lines=across,
        good_pair_pct=good_pct,
        stereo_class=classes,
        convergent_pct=convergent_pct,
        doming_risk=not bool((off_nadir > CONVERGENT_OFF_NADIR_DEG).any()),
        speed_m_s=speed,
        blur_px=blur_px,
        flagged=tuple(flagged),
        warnings=tuple(warnings),
        notes=tuple(notes),
        line_count=int(np.unique(lines).size),
    )
