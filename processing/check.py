"""The field coverage check: will these frames (or this plan) reconstruct?

:func:`run_check` projects every frame onto the ground, counts the views per ground cell over
the area, finds the gaps, measures forward and side overlap, base-height ratios, GSD, motion
blur and scale differences, and judges them against :class:`~processing.verdict.Thresholds`
(:func:`processing.verdict.judge`). This module is the pipeline: :func:`run_check` calls one
named step per stage (:func:`project`, :func:`choose_area`, :func:`count_views`,
:func:`find_gaps`, :func:`processing.check_stereo.measure_stereo`, :func:`block_warnings`, the
judgement) and fills a :class:`~processing.check_result.CheckResult`. With images, the pixels are
matched (:func:`measure_in_pixels`, :func:`match_again`); when their image scale is conclusive and
the tags' is off, the frames are projected again at the measured scale and every figure is made
from that projection (:mod:`processing.check_scale`). The CLI (``sfap check``)
presents the result; ``sfap.cli`` turns a failed check into exit code 1.

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
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon

from planner.camera import Orientation
from planner.errors import InputError
from planner.geo import LocalFrame

from .check_result import CheckResult, Gap
from .check_scale import ScaleFinding, assess_scale, moved_words, rescaled
from .check_stereo import FrameFlag, StereoFigures, measure_stereo
from .coverage import Grid, ViewCount
from .distribution import Distribution
from .errors import ProcessingError
from .footprints import Footprints
from .frames import AttitudeSource, Frames, frames_local_frame
from .ground import Ground
from .pixel_match import PixelFigures, PixelOptions
from .plan_frames import PlanInfo
from .survey_frames import AltitudeTrend, left_out_summary
from .verdict import DEFAULT_THRESHOLDS, Thresholds, above, judge, overlap_warnings

log = logging.getLogger(__name__)

#: Images whose median height differs from the plan's by more than this (and 10 %) are reported, m.
PLAN_HEIGHT_TOLERANCE_M = 10.0
#: The cell sizes a check accepts, m, and the most cells its raster may hold (int32 view counts and
#: a GSD raster: 50 million cells are 400 MB).
MIN_CELL_M = 0.01
MAX_CELL_M = 1000.0
MAX_CELLS = 50_000_000
#: View counts whose area shares are reported ("seen by at least k frames").
VIEW_LEVELS = (1, 2, 3, 5, 9)


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


# --- the steps -----------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class Projection:
    """Every frame on the ground (:func:`project`), in the check's local ``frame``.

    ``valid``: frames with a complete footprint; ``flagged``: the others, with why;
    ``median_height_m``: of the valid frames above the ground; ``short_side_m``: the shorter
    ground side of a nadir frame at that height; ``centres_xy``: where the valid frames' optical
    axes meet the ground.
    """

    frame: LocalFrame
    footprints: Footprints
    valid: NDArray[np.bool_]
    flagged: tuple[FrameFlag, ...]
    median_height_m: float
    short_side_m: float
    centres_xy: NDArray[np.float64]


def project(frames: Frames, ground: Ground) -> Projection:
    """Step 1: project every frame onto ``ground`` in a frame centred on them; ProcessingError
    when no frame has a complete footprint."""
    from .footprints import project_footprints

    frame = frames_local_frame(frames)
    fp = project_footprints(frames, frame, ground)
    valid = fp.valid
    flagged = tuple(
        FrameFlag(name=frames.name[k], kind="no footprint", detail=fp.reason[k])
        for k in np.flatnonzero(~valid)
    )
    if not valid.any():
        raise ProcessingError(
            f"no frame has a complete footprint on the ground ({fp.reason[0]}); check the ground and the "
            "attitude"
        )
    median_height = float(np.median(fp.height_above_ground_m[valid]))
    nominal = frames.camera.footprint(median_height, Orientation.LANDSCAPE)
    return Projection(
        frame=frame,
        footprints=fp,
        valid=valid,
        flagged=flagged,
        median_height_m=median_height,
        short_side_m=min(nominal.along_m, nominal.across_m),
        centres_xy=fp.principal_xyz_m[:, :2][valid],
    )


@dataclass(frozen=True, kw_only=True)
class Area:
    """The area judged, in the check's frame and in WGS84, and in words where it came from."""

    xy: Polygon | MultiPolygon
    lonlat: Polygon | MultiPolygon
    source: str


def choose_area(area: Polygon | MultiPolygon | None, plan: PlanInfo | None, projection: Projection) -> Area:
    """Step 2: the area given, else the plan's, else the block the flight spans (module
    docstring); ProcessingError when it is empty."""
    frame = projection.frame
    area_lonlat: Any
    if area is not None:
        area_lonlat = area
        source = "the area given"
    elif plan is not None and plan.planned.area_lonlat is not None:
        area_lonlat = plan.planned.area_lonlat
        source = f"the plan's area ({plan.planned.folder.name}/area.geojson)"
    else:
        area_lonlat = None
        source = (
            "the block the flight spans (convex hull of the frames' ground centres); give the plan or an "
            "area for a concave block"
        )
    if area_lonlat is not None:
        area_xy = frame.geometry_to_xy(area_lonlat)
    else:
        area_xy = block_area_xy(projection.centres_xy, projection.short_side_m)
        area_lonlat = frame.geometry_to_lonlat(area_xy)
    assert isinstance(area_xy, Polygon | MultiPolygon) and isinstance(area_lonlat, Polygon | MultiPolygon)
    if area_xy.is_empty or area_xy.area <= 0:
        raise ProcessingError("the area to check is empty; check the area polygon")
    return Area(xy=area_xy, lonlat=area_lonlat, source=source)


@dataclass(frozen=True, kw_only=True)
class Coverage:
    """The view-count raster over the area and the frames (:func:`count_views`).

    ``in_area``: cells whose centre is inside the area; ``seen_pct``: share of the area seen by
    at least k frames, for k in :data:`VIEW_LEVELS`; ``gsd_cm_raster``: the finest GSD that sees
    each cell; ``stats``: :func:`processing.coverage.coverage_stats`.
    """

    grid: Grid
    cell_m: float
    counts: ViewCount
    in_area: NDArray[np.bool_]
    seen_pct: dict[int, float]
    stats: dict[str, Any]
    gsd_cm_raster: NDArray[np.float64] | None


def count_views(
    projection: Projection,
    area_xy: Polygon | MultiPolygon,
    cell_m: float | None,
    progress: Callable[[int, int], None] | None,
) -> Coverage:
    """Step 3: views per cell over the area and the footprints (cells of ``cell_m`` metres, None:
    :func:`default_cell_m`); ProcessingError for a bad cell size or an area that covers no cell."""
    from .coverage import area_mask, coverage_stats, min_value_raster, view_count_raster

    fp = projection.footprints
    rings = fp.xy_m[projection.valid]
    xmin = min(area_xy.bounds[0], float(rings[..., 0].min()))
    ymin = min(area_xy.bounds[1], float(rings[..., 1].min()))
    xmax = max(area_xy.bounds[2], float(rings[..., 0].max()))
    ymax = max(area_xy.bounds[3], float(rings[..., 1].max()))
    default = default_cell_m(projection.short_side_m, (xmax - xmin) * (ymax - ymin))
    if cell_m is None:
        cell_m = default
    elif not (math.isfinite(cell_m) and MIN_CELL_M <= cell_m <= MAX_CELL_M):
        raise InputError(
            f"cell size {cell_m:g} m (--cell-m) is outside {MIN_CELL_M:g}-{MAX_CELL_M:g} m; give a cell "
            f"in that range (the default here is {default:g} m, 1/50 of a frame's shorter ground side)"
        )
    elif (xmax - xmin) * (ymax - ymin) / cell_m**2 > MAX_CELLS:
        least = math.sqrt((xmax - xmin) * (ymax - ymin) / MAX_CELLS)
        raise InputError(
            f"cell size {cell_m:g} m (--cell-m) makes {(xmax - xmin) * (ymax - ymin) / cell_m**2:.3g} cells "
            f"over the frames' {xmax - xmin:.0f} x {ymax - ymin:.0f} m, more than {MAX_CELLS:,}; give at "
            f"least {least:.2g} m (the default here is {default:g} m)"
        )
    grid = Grid.from_bounds((xmin, ymin, xmax, ymax), cell_m, projection.frame.crs)
    log.info("view counts over %d x %d cells of %g m", grid.rows, grid.cols, cell_m)
    counts = view_count_raster(rings, grid, progress=progress)
    in_area = area_mask(area_xy, grid)
    if not in_area.any():
        raise ProcessingError(
            f"the area covers no cell of {cell_m:g} m; give a smaller --cell-m (the area is "
            f"{area_xy.area:.1f} m2)"
        )
    stats = coverage_stats(counts, in_area)
    return Coverage(
        grid=grid,
        cell_m=float(cell_m),
        counts=counts,
        in_area=in_area,
        seen_pct={k: float(stats["seen_by_at_least_pct"][str(k)]) for k in VIEW_LEVELS},
        stats=stats,
        gsd_cm_raster=min_value_raster(rings, fp.gsd_cm[projection.valid], grid),
    )


def find_gaps(
    area_xy: Polygon | MultiPolygon, projection: Projection, *, min_area_m2: float
) -> tuple[Gap, ...]:
    """Step 4: the gaps (:func:`exact_gaps`), numbered from 1, largest first, with their WGS84
    outlines and centroids."""
    gaps: list[Gap] = []
    polygons = projection.footprints.polygons()[projection.valid]
    for k, polygon in enumerate(exact_gaps(area_xy, polygons, min_area_m2=min_area_m2), start=1):
        lonlat = projection.frame.geometry_to_lonlat(polygon)
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
    return tuple(gaps)


def block_warnings(
    frames: Frames,
    projection: Projection,
    stereo: StereoFigures,
    *,
    plan: PlanInfo | None,
    unpositioned: Sequence[str],
    left_out: Sequence[tuple[str, str]],
) -> list[str]:
    """Step 6: what may make the figures wrong or the block weak, beyond the thresholds: altitude
    drift, an assumed attitude, frames left out, the doming risk, a flight that differs from its
    plan."""
    from .image_frames import summarise_names
    from .survey_frames import altitude_drift_warning

    out: list[str] = []
    median_height = projection.median_height_m
    drift = altitude_drift_warning(frames.alt_m, frames.time_utc_s, median_height, frames.alt_reference.value)
    if drift is not None:
        out.append(drift)
    if frames.attitude_source is AttitudeSource.ASSUMED_NADIR:
        out.append(
            "the images carry no attitude: every frame was taken as nadir with the image top along the "
            "track; tilted frames would shift the footprints"
        )
    if left_out:
        out.append(
            f"{len(left_out)} frame(s) left out of coverage, GSD and scale figures: "
            + left_out_summary(left_out)
        )
    elif unpositioned:
        out.append(
            f"{len(unpositioned)} image(s) without a position were left out: {summarise_names(unpositioned)}"
        )
    if stereo.doming_risk:
        out.append(
            f"only {stereo.convergent_pct:.0f} % of the frames are convergent (oblique): a nadir-only block "
            "risks the doming effect (James and Robson 2014); add oblique frames or a crosshatch pass"
        )
    if plan is not None:
        planned = plan.planned.summary
        gsd = Distribution.of(projection.footprints.gsd_cm[projection.valid])
        if gsd is not None and gsd.median > 1.1 * planned.gsd_cm:
            out.append(
                f"median GSD {gsd.median:.2f} cm is more than 10 % coarser than the planned "
                f"{planned.gsd_cm:.2f} cm: flown higher than planned?"
            )
        if frames.alt_reference.value in ("amsl", "ellipsoid") and planned.altitude_agl_m > 0:
            off = median_height - planned.altitude_agl_m
            if abs(off) > max(PLAN_HEIGHT_TOLERANCE_M, 0.1 * planned.altitude_agl_m):
                out.append(
                    f"the frames are {abs(off):.0f} m {'higher' if off > 0 else 'lower'} above the ground "
                    f"(median {median_height:.1f} m) than the plan's {planned.altitude_agl_m:.1f} m: "
                    "flown so, "
                    "or the camera altitudes are not above mean sea level (an ellipsoidal height is tens of "
                    "metres off it in most places) or the ground elevation is wrong; heights, GSD and B/H "
                    f"reported scale with it ({100 * off / planned.altitude_agl_m:+.0f} %)"
                )
    return out


def _drift(frames: Frames, projection: Projection) -> str | None:
    from .survey_frames import altitude_drift_warning

    return altitude_drift_warning(
        frames.alt_m, frames.time_utc_s, projection.median_height_m, frames.alt_reference.value
    )


@dataclass(frozen=True, kw_only=True)
class Measured:
    """What the pixels measured (:func:`measure_in_pixels`) and what the report says of it."""

    figures: PixelFigures | None
    warnings: tuple[str, ...]
    notes: tuple[str, ...] = ()
    scale: ScaleFinding | None = None


def measure_in_pixels(
    frames: Frames,
    projection: Projection,
    stereo: StereoFigures,
    options: PixelOptions,
    *,
    camera_rough: bool,
    drift: bool,
    pairs_from: StereoFigures | None = None,
) -> Measured:
    """Step 5b: match the neighbouring frames (consecutive on a line, nearest across lines) and
    measure overlap, image scale and whether the block holds (:mod:`processing.pixel_match`); the
    measured scale against the tags' (:func:`processing.check_scale.assess_scale`: ``camera_rough``,
    the camera is known only from its 35 mm equivalent; ``drift``, the altitudes drift).
    ``pairs_from``: the pairs to match (None: ``stereo``'s); the figures and the scale compare with
    ``frames`` and ``projection``, the tags."""
    from .pixel_match import MIN_KEYPOINTS, MIN_MATCH_SIZE_PX, measure_pixels, neighbour_pairs

    camera = frames.camera
    if max(camera.image_width_px, camera.image_height_px) < MIN_MATCH_SIZE_PX:
        return Measured(
            figures=None,
            warnings=(),
            notes=(
                f"frames of {camera.image_width_px}x{camera.image_height_px} px are too small to match "
                f"(under {MIN_MATCH_SIZE_PX} px): judged on the tags alone",
            ),
        )

    try:
        import pycolmap  # noqa: F401  (the matcher's engine: an optional dependency, sfap[colmap])
    except ModuleNotFoundError:
        return Measured(
            figures=None,
            warnings=(
                "pycolmap is not installed, so the frames were not matched: the verdict rests on the tags "
                "alone (install it with `pip install 'sfap[colmap]'`, or pass --no-pixels to say so)",
            ),
        )
    chosen = pairs_from if pairs_from is not None else stereo
    index, along = neighbour_pairs(chosen.pair_index, chosen.pair_along_line, chosen.pair_across_lines)
    fp = projection.footprints
    figures = measure_pixels(
        frames,
        pair_index=index,
        pair_along=along,
        camera_xyz_m=fp.camera_xyz_m,
        tagged_gsd_cm=float(np.median(fp.gsd_cm[projection.valid])),
        options=options,
        mapper_pairs=chosen.pair_index,
    )
    warnings: list[str] = []
    if not figures.conclusive:
        return Measured(
            figures=figures,
            warnings=(
                f"the frames carry too few features to match (median {figures.keypoints_median:.0f} SIFT "
                f"features per frame, under {MIN_KEYPOINTS}): featureless ground (water, snow, fresh "
                "tarmac) will not reconstruct; the verdict rests on the tags alone",
            ),
        )
    tagged_gsd = figures.tagged_gsd_cm
    scale = (
        assess_scale(
            figures,
            tagged_gsd_cm=tagged_gsd,
            tagged_height_m=projection.median_height_m,
            camera_rough=camera_rough,
            heights_drift=drift,
        )
        if tagged_gsd is not None
        else None
    )
    said = scale.words() if scale is not None else None
    if said is not None:
        warnings.append(said)
    isolated = figures.isolated
    if isolated.size:
        names = [frames.name[int(k)] for k in isolated]
        warnings.append(
            f"{len(names)} frame(s) match none of their neighbours in the pixels (turns, blur, water or "
            f"featureless ground): {', '.join(names[:10])}"
            + (f" and {len(names) - 10} more" if len(names) > 10 else "")
        )
    return Measured(figures=figures, warnings=tuple(warnings), scale=scale)


def match_again(
    frames: Frames,
    ground: Ground,
    projection: Projection,
    stereo: StereoFigures,
    measured: Measured,
    scale: ScaleFinding,
    options: PixelOptions,
    *,
    area: Polygon | MultiPolygon | None,
    plan: PlanInfo | None,
    cell_m: float | None,
    thresholds: Thresholds,
    camera_rough: bool,
    drift: bool,
) -> Measured:
    """Step 5c: the tags' footprints chose the pairs to match, and the pixels say the tags' scale
    is off (``scale.rematch``): a footprint too small misses its neighbours, one too large pairs
    frames that do not overlap. Match the pairs that footprints at the measured scale choose; keep
    that matching when its scale is conclusive (it is then used), else the first (``measured``)."""
    moved_frames, moved_ground = rescaled(frames, ground, scale.provisional())
    try:
        moved = project(moved_frames, moved_ground)
        moved_area = choose_area(area, plan, moved)
        moved_views = count_views(moved, moved_area.xy, cell_m, None)
    except (ProcessingError, InputError) as error:
        log.warning("the pairs were not matched again at the measured scale: %s", error)
        return measured
    moved_stereo = measure_stereo(
        moved_frames,
        moved.footprints,
        moved_ground,
        moved.frame,
        moved_views.grid,
        moved_views.in_area,
        thresholds,
    )
    again = measure_in_pixels(
        frames, projection, stereo, options, camera_rough=camera_rough, drift=drift, pairs_from=moved_stereo
    )
    if again.figures is None or not again.figures.conclusive or again.scale is None or not again.scale.used:
        return measured
    return replace(
        again,
        notes=(
            *again.notes,
            "the pairs matched were chosen again on footprints at the image scale measured in a first "
            f"matching ({scale.measured_gsd_cm:.2f} cm against the tags' {scale.tagged_gsd_cm:.2f} cm, "
            f"{scale.pairs} pairs)",
        ),
    )


# --- the pipeline --------------------------------------------------------------------------------


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
    pixels: PixelOptions | None = None,
    camera_rough: bool = False,
    detrended: AltitudeTrend | None = None,
) -> CheckResult:
    """Check ``frames`` over ``ground`` (same altitude reference; see
    :func:`processing.ground_choice.ground_from_options`) and judge them against ``thresholds``.

    ``area``: WGS84 polygon to judge (None: the plan's area, else the flown block; module
    docstring). ``plan``: the plan the frames were meant to follow (its overlaps are the
    reference of the overlap checks). ``cell_m``: raster cell size in metres (None:
    :func:`default_cell_m`). ``progress(done, total)``: called while the view counts are
    rasterized (the long part). ``notes``, ``warnings``, ``unpositioned`` (image names without a
    position) and ``left_out`` ((name, reason) of every frame not checked: no position, another
    camera, not a survey frame) go into the report as they are. ``pixels``: match the
    neighbouring frames in that folder and measure overlap, scale and whether the block holds
    (:mod:`processing.pixel_match`; None: the tags alone); ``camera_rough``: the camera is known
    only roughly (35 mm equivalent), so a scale the pixels contradict is blamed on it;
    ``detrended``: the trend removed from drifting GPS altitudes before the check
    (:attr:`processing.ground_choice.GroundChoice.detrended`), so such a scale is blamed on the
    heights. When the pixels' scale is conclusive and the tags' is off
    (:mod:`processing.check_scale`), the footprints, coverage, GSD (and, for the heights, heights
    and B/H) come from the measured scale; ``CheckResult.scale`` says so.
    """
    if len(frames) == 0:
        raise ProcessingError("there is no frame to check")
    projection = project(frames, ground)
    judged = choose_area(area, plan, projection)
    coverage = count_views(projection, judged.xy, cell_m, progress)
    gaps = find_gaps(judged.xy, projection, min_area_m2=thresholds.min_gap_area_m2)
    stereo = measure_stereo(
        frames, projection.footprints, ground, projection.frame, coverage.grid, coverage.in_area, thresholds
    )
    drift = _drift(frames, projection)
    # Altitudes detrended by the ground choice drift as much: a scale that disagrees is the heights'.
    heights_drift = drift is not None or detrended is not None
    measured = (
        measure_in_pixels(frames, projection, stereo, pixels, camera_rough=camera_rough, drift=heights_drift)
        if pixels is not None
        else None
    )
    scale = measured.scale if measured is not None else None
    if pixels is not None and measured is not None and scale is not None and scale.rematch:
        measured = match_again(
            frames,
            ground,
            projection,
            stereo,
            measured,
            scale,
            pixels,
            area=area,
            plan=plan,
            cell_m=cell_m,
            thresholds=thresholds,
            camera_rough=camera_rough,
            drift=heights_drift,
        )
        scale = measured.scale
    if scale is not None and scale.used:
        # The pixels' scale is conclusive and the tags' is off: every figure from the frames on the
        # ground again, with the camera or the ground that gives the measured scale.
        given_ground = ground_description or ground.description
        frames, ground = rescaled(frames, ground, scale)
        projection = project(frames, ground)
        judged = choose_area(area, plan, projection)
        coverage = count_views(projection, judged.xy, cell_m, progress)
        gaps = find_gaps(judged.xy, projection, min_area_m2=thresholds.min_gap_area_m2)
        stereo = measure_stereo(
            frames,
            projection.footprints,
            ground,
            projection.frame,
            coverage.grid,
            coverage.in_area,
            thresholds,
        )
        if scale.height_offset_m:
            ground_description = f"{given_ground}{moved_words(scale.height_offset_m)}"
    fp, frame = projection.footprints, projection.frame
    pixel_notes = measured.notes if measured is not None else ()
    all_warnings = [
        *warnings,
        *stereo.warnings,
        *block_warnings(frames, projection, stereo, plan=plan, unpositioned=unpositioned, left_out=left_out),
        *(measured.warnings if measured is not None else ()),
    ]
    pixel_figures = measured.figures if measured is not None else None
    judged_pixels = pixel_figures if pixel_figures is not None and pixel_figures.conclusive else None
    blurred_frames = (
        [
            (frames.name[k], float(stereo.blur_px[k]))
            for k in np.flatnonzero(above(stereo.blur_px, thresholds.fail_blur_px))
        ]
        if stereo.blur_px is not None
        else []
    )
    flagged = (*projection.flagged, *stereo.flagged)
    warned = [f for f in flagged if f.kind == "blur"]
    if warned:
        all_warnings.append(
            f"{len(warned)} frame(s) with motion blur above {thresholds.max_blur_px:g} px (flagged frames), "
            f"{len(blurred_frames)} of them above {thresholds.fail_blur_px:g} px"
        )
    reasons = judge(
        thresholds=thresholds,
        seen_pct=coverage.seen_pct,
        gaps=list(gaps),
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
        pixels=judged_pixels,
    )
    all_warnings.extend(
        overlap_warnings(
            thresholds=thresholds,
            forward_overlap_pct=stereo.forward_overlap_pct,
            side_overlap_pct=stereo.side_overlap_pct,
            steps=stereo.steps,
            pixels=judged_pixels,
            base_height_along_line=Distribution.of(stereo.pair_base_height_ratio[stereo.pair_along_line]),
        )
    )
    lonlat_rings = np.stack(frame.to_lonlat(fp.xy_m[..., 0], fp.xy_m[..., 1]), axis=-1)
    return CheckResult(
        passed=not reasons,
        reasons=reasons,
        warnings=tuple(all_warnings),
        notes=(*notes, *stereo.notes, *pixel_notes),
        thresholds=thresholds,
        frames=frames,
        frame=frame,
        ground_description=ground_description or ground.description,
        area_source=judged.source,
        area_xy=judged.xy,
        area_lonlat=judged.lonlat,
        area_m2=float(judged.xy.area),
        cell_m=coverage.cell_m,
        grid=coverage.grid,
        extent_xy_m=coverage.grid.bounds,
        view_count=coverage.counts.counts.astype(np.int32),
        in_area=coverage.in_area,
        seen_pct=coverage.seen_pct,
        gaps=gaps,
        footprints_xy=fp.xy_m,
        footprints_lonlat=lonlat_rings,
        centres_xy=projection.centres_xy,
        height_agl_m=fp.height_above_ground_m,
        gsd_cm=fp.gsd_cm,
        gsd_cm_raster=coverage.gsd_cm_raster,
        stereo=stereo,
        flagged=flagged,
        plan=plan,
        unpositioned=tuple(unpositioned),
        left_out=tuple(left_out),
        camera_source=camera_source,
        pixels=pixel_figures,
        scale=scale,
        stats={
            "views_median": coverage.stats["views_median"],
            "views_max": coverage.stats["views_max"],
            "cells": coverage.stats["cells"],
            "pairs": int(stereo.pair_index.shape[0]),
            "lines": stereo.line_count,
        },
    )
