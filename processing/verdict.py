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
from .plan_frames import PlanInfo

if TYPE_CHECKING:
    # The result types live with the check that builds them; only their figures are read here.
    from .check_result import Gap
    from .distribution import Distribution
    from .pixel_match import PixelFigures


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
    - ``min_forward_overlap_pct``, ``recommended_forward_overlap_pct``: the median forward overlap
      (endlap) of consecutive frames of a line, with or without a plan. Below 60 % it fails: 60 %
      is the endlap of a classical stereo block (Aber et al. 2019, ch. 3, REFERENCES.md section 1),
      the least that puts every ground point in the stereo model of two consecutive frames and
      ties each frame to the next but one; SfM-MVS "needs far more redundancy" (same source).
      Below 75 % it is a warning: 75 % frontal overlap is what Pix4D recommends for the general
      case (Pix4D support, "Selecting the image acquisition plan type": at least 75 % frontal
      and 60 % side overlap). An area seen three times only because lines cross it still needs this
      overlap along each line: matching runs between neighbouring frames first.
    - ``min_side_overlap_pct``, ``recommended_side_overlap_pct``: the median side overlap of a
      frame with each neighbouring line. Below 20 % it fails: the low end of a classical block's
      sidelap (20-30 %, Aber et al. 2019 ch. 3); less leaves each line tied to the next by a strip
      too narrow to hold the block together. Below 60 % it is a warning (Pix4D's general case:
      60 % side overlap). A block with one line has no side overlap and is not judged on it.
    - ``max_base_height_ratio`` also bounds the median B/H of consecutive frames of a line:
      above it every forward pair is past 30 deg of intersection, where matching gets hard
      (Wenzel et al. 2013), and the block hangs on pairs the matcher struggles with: it fails.
    - ``max_blur_px``: motion blur per frame above half a pixel (the limit QGC and Mission
      Planner plan with, REFERENCES.md section 2) flags the frame: a warning, not a failure.
    - ``fail_blur_px``, ``max_blurred_frames_pct``: blur above 2 px is where it starts to hurt
      reconstruction. A linear smear of L px has a standard deviation of L / sqrt(12), 0.58 px at
      2 px: a third of the base scale of SIFT's finest octave (sigma 1.6 px, Lowe 2004), which
      COLMAP and OpenDroneMap match with, so features survive at every scale up to about there;
      beyond it the finest features go and matching and the point cloud degrade (Sieberth,
      Wackrow and Chandler 2014, "Motion blur disturbs", The Photogrammetric Record 29(148), see
      the loss grow with blur of a few pixels; no published cut-off is sharper). The 28-frame
      subset of the OpenDroneMap test flight garfield in ../shared/data (Parrot Sequoia, blur
      1.5-1.8 px) does not reconstruct whole (COLMAP, through sfap handoff --run, registers 12-13
      of its 28 frames in the largest of 9-10 models), but its 37 % endlap and B/H 0.61 between
      consecutive frames fail the overlap and B/H rules above: the check needs no blur failure
      to predict it. More than 5 % of the frames above 2 px fails; fewer are listed (their
      neighbours cover them).
    - ``min_base_height_ratio``, ``max_base_height_ratio``: the good range of a pair's B/H:
      above 0.54 (30 deg of intersection) matching gets hard (Wenzel et al. 2013); below 0.1
      (5.7 deg) depth precision sigma_Z = (H/B)(H/f) sigma_image is ten times worse than the
      height error of the plan's pixel.
    - ``min_good_pair_pct``: share of the area seen by at least one pair in that range (90 %), among
      the pairs that carry a block's stereo: two frames of the same line (consecutive ones, or
      further apart when a high endlap makes consecutive bases short) and a frame with the
      nearest frame of a neighbouring line; not frames two lines apart or diagonal pairs. This
      share is about the geometry of the pairs; whether consecutive frames overlap enough to be
      matched at all is the forward overlap rule's (a sparse subset of passes minutes apart can
      have good across-line pairs everywhere and still fall apart).
    - ``max_scale_difference_pct``: image scales differing by more than 10 % hamper matching
      (REFERENCES.md section 1): such frames are flagged (a warning).
    - ``max_gap_area_m2``: any gap larger than this fails, whatever the share seen (25 m2: a
      5 m x 5 m hole in the orthomosaic is visible; a gap at the edge of a large area can be
      well under 1 % of it).
    - ``min_gap_area_m2``: smaller holes are not reported as gaps (crumbs of a cell or two
      where footprint corners meet).
    - ``min_connected_frames_pct``, ``min_registered_pct``: what the pixels say
      (:mod:`processing.pixel_match`): the frames that match their neighbours must form one part
      holding 70 % of them, and a quick reconstruction of the matches (COLMAP's mapper) must
      register 70 % of them in one model. Calibrated on the real blocks in ../shared/data:
      garfield_rgb (its reconstruction falls apart: 13 of 28 frames in the largest model; the
      quick model 11, 39 %) fails, seneca_half (reconstructs at 53 % endlap: 85 % of its central
      40 frames in the quick model, 86-88 % matched into one part) passes; a third block, copr_kap
      (kite frames, no GPS; 38 of 41 in its reconstruction), registers 93 % in the quick model and
      matches into one part, on the same thresholds; DESIGN.md, "The field check's verdict". When
      both hold, the endlap floor and the B/H along the lines are advice.
    """

    min_seen_1_pct: float = 99.0
    min_seen_3_pct: float = 90.0
    max_overlap_shortfall_pct: float = 10.0
    min_forward_overlap_pct: float = 60.0
    recommended_forward_overlap_pct: float = 75.0
    min_side_overlap_pct: float = 20.0
    recommended_side_overlap_pct: float = 60.0
    max_blur_px: float = 0.5
    fail_blur_px: float = 2.0
    max_blurred_frames_pct: float = 5.0
    min_base_height_ratio: float = 0.1
    max_base_height_ratio: float = 0.54
    min_good_pair_pct: float = 90.0
    max_scale_difference_pct: float = 10.0
    max_gap_area_m2: float = 25.0
    min_gap_area_m2: float = 1.0
    min_registered_pct: float = 70.0
    min_connected_frames_pct: float = 70.0

    def __post_init__(self) -> None:
        for key in (
            "min_seen_1_pct",
            "min_seen_3_pct",
            "max_overlap_shortfall_pct",
            "min_forward_overlap_pct",
            "recommended_forward_overlap_pct",
            "min_side_overlap_pct",
            "recommended_side_overlap_pct",
            "max_blurred_frames_pct",
            "min_good_pair_pct",
            "max_scale_difference_pct",
            "min_registered_pct",
            "min_connected_frames_pct",
        ):
            value = getattr(self, key)
            if not (math.isfinite(value) and 0.0 <= value <= 100.0):
                raise ProcessingError(f"threshold {key} = {value} is outside 0-100 %")
        for floor, level in (
            ("min_forward_overlap_pct", "recommended_forward_overlap_pct"),
            ("min_side_overlap_pct", "recommended_side_overlap_pct"),
        ):
            if getattr(self, floor) > getattr(self, level):
                raise ProcessingError(
                    f"threshold {floor} = {getattr(self, floor)} must not exceed {level} = "
                    f"{getattr(self, level)} (the warning comes before the failure)"
                )
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


@dataclass(frozen=True, kw_only=True)
class LineSteps:
    """How the block was flown, for the advice: the median base between consecutive frames of a
    line (m), the median interval between them (s, None without capture times), the median
    spacing between neighbouring lines (m, the base of the across-line pairs; None with one
    line), the median B/H of consecutive frames of a line (None without such pairs) and the median
    height above ground (m, None when unknown)."""

    base_m: float
    interval_s: float | None = None
    spacing_m: float | None = None
    base_height_along: float | None = None
    height_m: float | None = None


def _trigger_advice(steps: LineSteps | None, factor: float, what: str) -> str:
    """'a trigger distance of at most X m (now Y m), or ... s between frames, or a height of at
    least ... m' for a base ``factor`` times the flown one. Never a lower speed: a fixed wing
    cannot fly below its minimum speed, and the check does not know the vehicle; the trigger
    distance (or interval) and the height are flyable by any vehicle."""
    if steps is None or not (steps.base_m > 0 and math.isfinite(steps.base_m)):
        return f"fly again with {what}: a shorter trigger distance, or higher"
    target = steps.base_m * factor
    text = f"fly again with {what}: a trigger distance of at most {target:.1f} m (now {steps.base_m:.1f} m)"
    if steps.interval_s is not None and steps.interval_s > 0:
        text += (
            f", or at the same ground speed a trigger interval of at most {steps.interval_s * factor:.1f} s "
            f"(now {steps.interval_s:.1f} s)"
        )
    if steps.height_m is not None and steps.height_m > 0 and factor > 0:
        text += (
            f", or at the same trigger distance a height of at least {steps.height_m / factor:.0f} m above "
            f"ground (now {steps.height_m:.0f} m; a coarser GSD)"
        )
    return text


def _overlap_factor(measured_pct: float, target_pct: float) -> float:
    """The base (or spacing) that turns ``measured_pct`` overlap into ``target_pct``, as a factor of
    the flown one: overlap = 1 - base / footprint, so base scales with (1 - overlap)."""
    return (1.0 - target_pct / 100.0) / max(1.0 - measured_pct / 100.0, 1e-9)


def _spacing_advice(steps: LineSteps | None, factor: float, what: str) -> str:
    if steps is None or steps.spacing_m is None:
        return f"fly again with {what}: lines closer together"
    return (
        f"fly again with {what}: lines at most {steps.spacing_m * factor:.1f} m apart "
        f"(now {steps.spacing_m:.1f} m)"
    )


def pixels_hold(thresholds: Thresholds, pixels: PixelFigures | None) -> bool:
    """The pixels say the block holds: the matched frames form one part (at least
    ``min_connected_frames_pct`` of the frames) and, when the quick reconstruction ran, its largest
    model registers at least ``min_registered_pct`` of them. False without a measurement."""
    if pixels is None or not len(pixels.matched):
        return False
    registered = pixels.registered_pct
    return pixels.largest_component_pct >= thresholds.min_connected_frames_pct and (
        registered is None or registered >= thresholds.min_registered_pct
    )


def pixel_reasons(thresholds: Thresholds, pixels: PixelFigures | None) -> list[str]:
    """The reasons the pixels give to fail: the matched frames fall apart into parts, or the quick
    reconstruction registers too few of them in one model."""
    if pixels is None or not len(pixels.matched):
        return []
    t = thresholds
    out: list[str] = []
    if pixels.largest_component_pct < t.min_connected_frames_pct:
        out.append(
            f"the frames that match their neighbours fall into {pixels.component_count} separate parts; the "
            f"largest holds {pixels.largest_component_pct:.0f} % of the frames (at least "
            f"{t.min_connected_frames_pct:g} % needed; {pixels.isolated.size} frame(s) match no neighbour): "
            "the block would reconstruct as separate pieces; fly the lines between them again"
        )
    registered = pixels.registered_pct
    if registered is not None and registered < t.min_registered_pct:
        sizes = ", ".join(str(len(m)) for m in (pixels.models or ())[:6]) or "none"
        out.append(
            f"a quick reconstruction of the matched frames (COLMAP's mapper at {pixels.match_size_px} px) "
            f"registers only {registered:.0f} % of the {pixels.frame_count} frames in its largest model "
            f"(models of {sizes} frames; at least {t.min_registered_pct:g} % needed): the block falls apart; "
            "fly it again with more overlap (the advice below)"
        )
    return out


def overlap_warnings(
    *,
    thresholds: Thresholds,
    forward_overlap_pct: Distribution | None,
    side_overlap_pct: Distribution | None,
    steps: LineSteps | None = None,
    good_pair_basis: str = "frames on one line or neighbouring lines",
    pixels: PixelFigures | None = None,
    base_height_along_line: Distribution | None = None,
) -> tuple[str, ...]:
    """Overlaps at or above the failure floor but below the recommended level, and an overlap
    that could not be measured, as warnings (they do not fail the check). When the pixels say the
    block holds (:func:`pixels_hold`), an endlap under the classical floor and a wide B/H along the
    lines are advice too, with the measured figures."""
    t = thresholds
    out: list[str] = []
    advised_forward = False
    if pixels_hold(t, pixels):
        assert pixels is not None
        measured = pixels.forward_overlap_pct
        registered = pixels.registered_pct
        held = f"{pixels.largest_component_pct:.0f} % of the frames match into one part" + (
            f" and a quick reconstruction registers {registered:.0f} % of them in one model"
            if registered is not None
            else ""
        )
        shown = measured if measured is not None else forward_overlap_pct
        if shown is not None and shown.median < t.min_forward_overlap_pct:
            source = " measured in the pixels" if measured is not None else " (from the tags)"
            tagged = (
                f" (from the tags {forward_overlap_pct.median:.0f} %)"
                if measured is not None and forward_overlap_pct is not None
                else ""
            )
            factor = _overlap_factor(shown.median, t.recommended_forward_overlap_pct)
            out.append(
                f"median forward overlap {shown.median:.0f} %{source}{tagged} is below the "
                f"classical {t.min_forward_overlap_pct:g} % of a stereo block, but {held}: advice, not a "
                "failure; for a denser model next time, "
                + _trigger_advice(steps, factor, f"{t.recommended_forward_overlap_pct:g} % endlap")
            )
            advised_forward = True
        if base_height_along_line is not None and base_height_along_line.median > t.max_base_height_ratio:
            factor = t.max_base_height_ratio / base_height_along_line.median
            out.append(
                "median base-height ratio of consecutive frames of a line "
                f"{base_height_along_line.median:.2f} "
                f"is above {t.max_base_height_ratio:g}, but {held}: advice, not a failure; next time, "
                + _trigger_advice(steps, factor, f"B/H at most {t.max_base_height_ratio:g}")
            )
    if advised_forward:
        pass
    elif forward_overlap_pct is None:
        out.append(
            "forward overlap not measured: no two consecutive frames on a line (no capture times, or "
            "frames too far apart); the endlap and the B/H of consecutive frames are not judged"
        )
    elif t.min_forward_overlap_pct <= forward_overlap_pct.median < t.recommended_forward_overlap_pct:
        factor = _overlap_factor(forward_overlap_pct.median, t.recommended_forward_overlap_pct)
        out.append(
            f"median forward overlap {forward_overlap_pct.median:.0f} % is below the "
            f"{t.recommended_forward_overlap_pct:g} % recommended for SfM (the "
            f"{t.min_forward_overlap_pct:g} % stereo minimum is met); next time, "
            + _trigger_advice(steps, factor, f"{t.recommended_forward_overlap_pct:g} % endlap")
        )
    if side_overlap_pct is not None and (
        t.min_side_overlap_pct <= side_overlap_pct.median < t.recommended_side_overlap_pct
    ):
        factor = _overlap_factor(side_overlap_pct.median, t.recommended_side_overlap_pct)
        out.append(
            f"median side overlap {side_overlap_pct.median:.0f} % is below the "
            f"{t.recommended_side_overlap_pct:g} % recommended for SfM; next time, "
            + _spacing_advice(steps, factor, f"{t.recommended_side_overlap_pct:g} % side overlap")
        )
    return tuple(out)


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
    base_height_along_line: Distribution | None = None,
    steps: LineSteps | None = None,
    good_pair_basis: str = "frames on one line or neighbouring lines",
    pixels: PixelFigures | None = None,
) -> tuple[str, ...]:
    """The reasons a check fails, each with the figure, the threshold and what it means;
    empty when it passes.

    ``blurred_count`` of ``frame_count`` frames are blurred beyond ``fail_blur_px``
    (``blurred_frames``: their names and blur in pixels, named in the reason);
    ``blur_unknown_count`` more have no known speed (so no blur): they count as not blurred,
    and the reason says how many there were.

    ``forward_overlap_pct`` and ``side_overlap_pct`` are judged against the absolute floors with or
    without a plan (and against the plan's overlaps when there is one);
    ``base_height_along_line``: the B/H of consecutive frames of a line, its median judged
    against ``max_base_height_ratio``; ``steps``: the flown base, interval and line spacing, for
    the advice (trigger distance, interval or height that would give the recommended overlap).

    ``pixels``: what matching the frames measured (:mod:`processing.pixel_match`). Its rules
    (:func:`pixel_reasons`) fail a block whose frames do not match or fall apart; when it holds
    (:func:`pixels_hold`) the endlap and B/H along the lines are advice
    (:func:`overlap_warnings`), not failures: the classical 60 % is what a stereo block needs, and
    a block whose neighbours match reconstructs below it (DESIGN.md, "The field check's verdict").
    """
    t = thresholds
    reasons: list[str] = pixel_reasons(t, pixels)
    holds = pixels_hold(t, pixels)
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
            ("forward", forward_overlap_pct, plan.planned.summary.front_overlap_pct),
            ("side", side_overlap_pct, plan.planned.summary.side_overlap_pct),
        ):
            if dist is not None and dist.median < planned - t.max_overlap_shortfall_pct:
                reasons.append(
                    f"median {what} overlap {dist.median:.0f} % is more than "
                    f"{t.max_overlap_shortfall_pct:g} points under the planned {planned:g} %"
                )
    if (
        not holds
        and forward_overlap_pct is not None
        and forward_overlap_pct.median < t.min_forward_overlap_pct
    ):
        factor = _overlap_factor(forward_overlap_pct.median, t.recommended_forward_overlap_pct)
        reasons.append(
            "median forward overlap (endlap) of consecutive frames of a line "
            f"{forward_overlap_pct.median:.0f} % "
            f"(10-90 %: {forward_overlap_pct.p10:.0f}-{forward_overlap_pct.p90:.0f} % over "
            f"{forward_overlap_pct.count} pairs) is below the {t.min_forward_overlap_pct:g} % a stereo block "
            "needs: frames do not tie to their neighbours on the line (ground seen 3 times by crossing "
            "passes does not replace it); "
            + _trigger_advice(steps, factor, f"at least {t.recommended_forward_overlap_pct:g} % endlap")
        )
    if side_overlap_pct is not None and side_overlap_pct.median < t.min_side_overlap_pct:
        factor = _overlap_factor(side_overlap_pct.median, t.recommended_side_overlap_pct)
        reasons.append(
            f"median side overlap {side_overlap_pct.median:.0f} % (10-90 %: {side_overlap_pct.p10:.0f}-"
            f"{side_overlap_pct.p90:.0f} %) is below {t.min_side_overlap_pct:g} %: the lines are not tied "
            "into one block; "
            + _spacing_advice(steps, factor, f"at least {t.recommended_side_overlap_pct:g} % side overlap")
        )
    if (
        not holds
        and base_height_along_line is not None
        and base_height_along_line.median > t.max_base_height_ratio
    ):
        angle_deg = math.degrees(2.0 * math.atan(base_height_along_line.median / 2.0))
        # At the same height the base scales with B/H.
        factor = t.max_base_height_ratio / base_height_along_line.median
        reasons.append(
            f"median base-height ratio of consecutive frames of a line {base_height_along_line.median:.2f} "
            f"({angle_deg:.0f} deg of intersection, over {base_height_along_line.count} pairs) is above "
            f"{t.max_base_height_ratio:g}: matching between neighbouring frames gets hard; "
            + _trigger_advice(steps, factor, f"B/H at most {t.max_base_height_ratio:g}")
        )
    if good_pair_pct is not None and good_pair_pct < t.min_good_pair_pct:
        reasons.append(
            f"only {good_pair_pct:.1f} % of the area is seen by a pair ({good_pair_basis}) with a "
            "base-height ratio in "
            f"{t.min_base_height_ratio:g}-{t.max_base_height_ratio:g} (at least {t.min_good_pair_pct:g} % "
            "needed): depth will be poorly determined where it is lower, matching will fail where it is "
            "higher"
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
