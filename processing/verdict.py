"""The verdict of a coverage check: what a pass needs (:class:`Thresholds`) and the reasons a
check fails (:func:`judge`), each with the figure, the threshold and what to do.

:func:`processing.check.run_check` measures; this module only compares. The thresholds' defaults
and their sources are listed on :class:`Thresholds`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .errors import ProcessingError
from .inputs import PlanInfo

if TYPE_CHECKING:
    # The result types live with the check that builds them; only their figures are read here.
    from .check import Distribution, Gap


@dataclass(frozen=True, kw_only=True)
class Thresholds:
    """What a pass needs; every default has its source.

    - ``min_seen_1_pct``: share of the area seen by at least one frame (99 %: a gap of more than
      1 % of the area is a hole in the model).
    - ``min_seen_3_pct``: share seen by at least three frames (90 %): SfM-MVS needs far more
      redundancy than a stereo pair (REFERENCES.md section 1); three views are the least that
      lets a matcher confirm a point.
    - ``max_overlap_shortfall_pct``: the median forward and side overlap may fall this many
      points under the plan's (10; "planned 80/80, got almost zero", REFERENCES.md section 5).
    - ``max_blur_px``: motion blur per frame above half a pixel (the limit QGC and Mission
      Planner plan with, REFERENCES.md section 2) flags the frame: a warning, not a failure.
    - ``fail_blur_px``, ``max_blurred_frames_pct``: blur above 2 px is where it starts to hurt
      reconstruction. A linear smear of L px has a standard deviation of L / sqrt(12), 0.58 px at
      2 px: a third of the base scale of SIFT's finest octave (sigma 1.6 px, Lowe 2004), which
      COLMAP and OpenDroneMap match with, so features survive at every scale up to about there;
      beyond it the finest features go and matching and the point cloud degrade (Sieberth,
      Wackrow and Chandler 2014, "Motion blur disturbs", The Photogrammetric Record 29(148), see
      the loss grow with blur of a few pixels; no published cut-off is sharper). The OpenDroneMap
      test set garfield (Parrot Sequoia, 1.5-1.8 px) reconstructs. More than 5 % of the frames
      above 2 px fails; fewer are listed (their neighbours cover them).
    - ``min_base_height_ratio``, ``max_base_height_ratio``: the good range of a pair's B/H:
      above 0.54 (30 deg of intersection) matching gets hard (Wenzel et al. 2013); below 0.1
      (5.7 deg) depth precision sigma_Z = (H/B)(H/f) sigma_image is ten times worse than the
      height error of the plan's pixel.
    - ``min_good_pair_pct``: share of the area seen by at least one pair in that range (90 %).
    - ``max_scale_difference_pct``: image scales differing by more than 10 % hamper matching
      (REFERENCES.md section 1): such frames are flagged (a warning).
    - ``max_gap_area_m2``: any gap larger than this fails, whatever the share seen (25 m2: a
      5 m x 5 m hole in the orthomosaic is visible; a gap at the edge of a large area can be
      well under 1 % of it).
    - ``min_gap_area_m2``: smaller holes are not reported as gaps (crumbs of a cell or two
      where footprint corners meet).
    """

    min_seen_1_pct: float = 99.0
    min_seen_3_pct: float = 90.0
    max_overlap_shortfall_pct: float = 10.0
    max_blur_px: float = 0.5
    fail_blur_px: float = 2.0
    max_blurred_frames_pct: float = 5.0
    min_base_height_ratio: float = 0.1
    max_base_height_ratio: float = 0.54
    min_good_pair_pct: float = 90.0
    max_scale_difference_pct: float = 10.0
    max_gap_area_m2: float = 25.0
    min_gap_area_m2: float = 1.0

    def __post_init__(self) -> None:
        for key in (
            "min_seen_1_pct",
            "min_seen_3_pct",
            "max_overlap_shortfall_pct",
            "max_blurred_frames_pct",
            "min_good_pair_pct",
            "max_scale_difference_pct",
        ):
            value = getattr(self, key)
            if not (math.isfinite(value) and 0.0 <= value <= 100.0):
                raise ProcessingError(f"threshold {key} = {value} is outside 0-100 %")
        if not (self.max_blur_px > 0 and math.isfinite(self.max_blur_px)):
            raise ProcessingError(f"threshold max_blur_px = {self.max_blur_px} must be positive pixels")
        if not (math.isfinite(self.fail_blur_px) and self.fail_blur_px >= self.max_blur_px):
            raise ProcessingError(
                f"threshold fail_blur_px = {self.fail_blur_px} must be at least max_blur_px = "
                f"{self.max_blur_px} (the warning comes before the failure)"
            )
        if not (0.0 < self.min_base_height_ratio < self.max_base_height_ratio):
            raise ProcessingError(
                f"B/H range {self.min_base_height_ratio}-{self.max_base_height_ratio} is empty; the minimum "
                "must be positive and below the maximum"
            )
        if not (self.min_gap_area_m2 >= 0.0 and self.max_gap_area_m2 >= self.min_gap_area_m2):
            raise ProcessingError(
                f"thresholds min_gap_area_m2 = {self.min_gap_area_m2} and max_gap_area_m2 = "
                f"{self.max_gap_area_m2} must satisfy 0 <= min <= max"
            )

    def as_dict(self) -> dict[str, float]:
        return {key: float(getattr(self, key)) for key in self.__dataclass_fields__}


#: The defaults, the thresholds a check uses when none are given.
DEFAULT_THRESHOLDS = Thresholds()


def good_base_height(ratio: NDArray[np.float64], thresholds: Thresholds) -> NDArray[np.bool_]:
    """Pairs whose B/H lies in the good range, both ends included."""
    lo, hi = thresholds.min_base_height_ratio, thresholds.max_base_height_ratio
    return np.asarray((ratio >= lo) & (ratio <= hi), dtype=bool)


def above(values_px: NDArray[np.float64], limit_px: float) -> NDArray[np.bool_]:
    """Frames whose blur is strictly above ``limit_px`` (unknown, NaN, is not above)."""
    return np.asarray(np.nan_to_num(values_px, nan=-np.inf) > limit_px, dtype=bool)


def judge(
    *,
    thresholds: Thresholds,
    seen_pct: dict[int, float],
    gaps: Sequence[Gap],
    forward_overlap_pct: Distribution | None,
    side_overlap_pct: Distribution | None,
    plan: PlanInfo | None,
    good_pair_pct: float | None,
    blurred_count: int,
    frame_count: int,
    blur_unknown_count: int = 0,
    blurred_frames: Sequence[tuple[str, float]] = (),
) -> tuple[str, ...]:
    """The reasons a check fails, each with the figure, the threshold and what it means;
    empty when it passes.

    ``blurred_count`` of ``frame_count`` frames are blurred beyond ``fail_blur_px``
    (``blurred_frames``: their names and blur in pixels, named in the reason);
    ``blur_unknown_count`` more have no known speed (so no blur): they count as not blurred,
    and the reason says how many there were.
    """
    t = thresholds
    reasons: list[str] = []
    if seen_pct[1] < t.min_seen_1_pct:
        gap_text = (
            f" ({len(gaps)} gap(s), {sum(g.area_m2 for g in gaps):.0f} m2; largest "
            f"{max(g.area_m2 for g in gaps):.0f} m2)"
            if gaps
            else ""
        )
        reasons.append(
            f"only {seen_pct[1]:.1f} % of the area is seen by any frame (at least {t.min_seen_1_pct:g} % "
            f"needed){gap_text}: fly the gaps again (--refly writes the mission)"
        )
    large = [g for g in gaps if g.area_m2 > t.max_gap_area_m2]
    if large and seen_pct[1] >= t.min_seen_1_pct:
        reasons.append(
            f"{len(large)} gap(s) larger than {t.max_gap_area_m2:g} m2 (largest "
            f"{max(g.area_m2 for g in large):.0f} m2, gap {large[0].index} in the table): holes in the "
            "model; fly them again (--refly)"
        )
    if seen_pct[3] < t.min_seen_3_pct:
        reasons.append(
            f"only {seen_pct[3]:.1f} % of the area is seen by 3 or more frames (at least "
            f"{t.min_seen_3_pct:g} % needed): too little redundancy to reconstruct reliably"
        )
    if plan is not None:
        for what, dist, planned in (
            ("forward", forward_overlap_pct, plan.front_overlap_pct),
            ("side", side_overlap_pct, plan.side_overlap_pct),
        ):
            if dist is not None and dist.median < planned - t.max_overlap_shortfall_pct:
                reasons.append(
                    f"median {what} overlap {dist.median:.0f} % is more than "
                    f"{t.max_overlap_shortfall_pct:g} points under the planned {planned:g} %"
                )
    if good_pair_pct is not None and good_pair_pct < t.min_good_pair_pct:
        reasons.append(
            f"only {good_pair_pct:.1f} % of the area is seen by a pair with a base-height ratio in "
            f"{t.min_base_height_ratio:g}-{t.max_base_height_ratio:g} (at least {t.min_good_pair_pct:g} % "
            "needed): depth will be poorly determined"
        )
    if frame_count and 100.0 * blurred_count / frame_count > t.max_blurred_frames_pct:
        unknown = f"; blur unknown for {blur_unknown_count} frames (no speed)" if blur_unknown_count else ""
        worst = sorted(blurred_frames, key=lambda item: -item[1])[:10]
        named = (
            ": "
            + ", ".join(f"{name} {px:.1f} px" for name, px in worst)
            + (" ..." if len(blurred_frames) > 10 else "")
            if worst
            else ""
        )
        reasons.append(
            f"{blurred_count} of {frame_count} frames ({100.0 * blurred_count / frame_count:.0f} %) have "
            f"motion blur above {t.fail_blur_px:g} px (at most {t.max_blurred_frames_pct:g} % allowed"
            f"{unknown}){named}: fly slower or use a shorter exposure"
        )
    return tuple(reasons)
