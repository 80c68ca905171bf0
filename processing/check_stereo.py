"""The stereo step of a check: pairs, overlaps, base-height classes of the cells, convergence,
scale outliers and motion blur, through :mod:`processing.stereo`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.geo import LocalFrame

from .coverage import Grid
from .distribution import Distribution
from .footprints import Footprints
from .frames import Frames
from .ground import Ground
from .verdict import LineSteps, Thresholds, above, good_base_height

#: Codes of :attr:`StereoFigures.stereo_class`: the best pair that sees a cell has a B/H in the
#: thresholds' range (GOOD), else above it (WIDE), else below it (WEAK); NONE: no pair.
STEREO_NONE, STEREO_WEAK, STEREO_GOOD, STEREO_WIDE = -1, 0, 1, 2


@dataclass(frozen=True, kw_only=True)
class FrameFlag:
    """A frame the report points out, and why (``kind``: blur, scale, low, ...)."""

    name: str
    kind: str
    detail: str


@dataclass(frozen=True, kw_only=True)
class StereoFigures:
    """What :func:`measure_stereo` finds (the check's result holds it as ``stereo``).

    ``pair_index``: (M, 2) frame rows of the overlapping pairs, with their B/H and intersection
    angles; ``pair_along_line`` / ``pair_across_lines``: which pairs are two frames of one line
    and which a frame with the nearest of a neighbouring line; ``stereo_class``: per cell of the
    check's grid, :data:`STEREO_GOOD`... ; ``speed_m_s`` / ``blur_px``: per frame, None without
    capture times (or exposure times).
    """

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


def measure_stereo(
    frames: Frames,
    fp: Footprints,
    ground: Ground,
    frame: LocalFrame,
    grid: Grid,
    in_area: NDArray[np.bool_],
    thresholds: Thresholds,
) -> StereoFigures:
    """Pairs, overlaps, convergence, scale and blur through :mod:`processing.stereo`."""
    from .coverage import count_raster
    from .flight_lines import flight_lines, forward_overlaps_pct, pair_kinds, side_overlaps_pct
    from .motion_blur import SPEED_MAX_INTERVAL_RATIO, motion_blur
    from .stereo import CONVERGENT_OFF_NADIR_DEG, off_nadir_deg, overlapping_pairs, scale_outliers

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
            height_m=float(np.median(fp.height_above_ground_m[fp.valid])) if fp.valid.any() else None,
        )
    return StereoFigures(
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
