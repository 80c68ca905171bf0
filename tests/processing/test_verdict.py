"""Every verdict threshold at its boundary: exactly at it, just below and just above.

A mutation that turns a comparison's ``>`` into ``>=`` (or ``<`` into ``<=``) changes the outcome
exactly at the threshold, so each case below tests the value itself; the neighbours on either
side pin the direction. Values are chosen representable in binary floating point (25.0, 0.5,
0.25...) so "exactly at" is exact.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
import shapely

from processing.check_result import Gap
from processing.distribution import Distribution
from processing.verdict import LineSteps, Thresholds, above, good_base_height, judge, overlap_warnings

EPS = 1e-6
T = Thresholds()
FULL = {1: 100.0, 2: 100.0, 3: 100.0, 5: 100.0, 9: 100.0}


def _gap(area_m2: float) -> Gap:
    square = shapely.box(0, 0, math.sqrt(area_m2), math.sqrt(area_m2))
    return Gap(
        index=1,
        area_m2=area_m2,
        centroid_lon_deg=0.0,
        centroid_lat_deg=0.0,
        polygon_xy=square,
        polygon_lonlat=square,
    )


def _judge(**changes: Any) -> tuple[str, ...]:
    base: dict[str, Any] = {
        "thresholds": T,
        "seen_pct": FULL,
        "gaps": [],
        "forward_overlap_pct": None,
        "side_overlap_pct": None,
        "plan": None,
        "good_pair_pct": 100.0,
        "blurred_count": 0,
        "frame_count": 1000,
    }
    return judge(**{**base, **changes})


@pytest.mark.parametrize(("delta", "fails"), [(-EPS, True), (0.0, False), (EPS, False)])
def test_seen_by_one_frame(delta: float, fails: bool) -> None:
    reasons = _judge(seen_pct={**FULL, 1: T.min_seen_1_pct + delta})
    assert bool(reasons) is fails and (not fails or "seen by any frame" in reasons[0])


@pytest.mark.parametrize(("delta", "fails"), [(-EPS, True), (0.0, False), (EPS, False)])
def test_seen_by_three_frames(delta: float, fails: bool) -> None:
    reasons = _judge(seen_pct={**FULL, 3: T.min_seen_3_pct + delta})
    assert bool(reasons) is fails and (not fails or "3 or more" in reasons[0])


@pytest.mark.parametrize(("delta", "fails"), [(-EPS, False), (0.0, False), (EPS, True)])
def test_largest_gap(delta: float, fails: bool) -> None:
    reasons = _judge(gaps=[_gap(T.max_gap_area_m2 + delta)])
    assert bool(reasons) is fails and (not fails or "larger than 25 m2" in reasons[0])


@pytest.mark.parametrize(("delta", "fails"), [(-EPS, True), (0.0, False), (EPS, False)])
def test_good_pair_share(delta: float, fails: bool) -> None:
    reasons = _judge(good_pair_pct=T.min_good_pair_pct + delta)
    assert bool(reasons) is fails and (not fails or "base-height ratio" in reasons[0])


@pytest.mark.parametrize(("blurred", "fails"), [(49, False), (50, False), (51, True)])
def test_share_of_frames_blurred_beyond_the_failure_threshold(blurred: int, fails: bool) -> None:
    # 5 % of 1000 frames is 50.
    reasons = _judge(blurred_count=blurred, blurred_frames=[(f"IMG_{k}.JPG", 2.5) for k in range(blurred)])
    assert bool(reasons) is fails
    if fails:
        assert "motion blur above 2 px" in reasons[0] and "IMG_0.JPG 2.5 px" in reasons[0]


@pytest.mark.parametrize(("delta", "fails"), [(-EPS, True), (0.0, False), (EPS, False)])
def test_overlap_shortfall(delta: float, fails: bool) -> None:
    class Summary:  # the two figures judge reads from a plan (PlanInfo.planned.summary)
        front_overlap_pct = 80.0
        side_overlap_pct = 70.0

    class Planned:
        summary = Summary

    class Plan:
        planned = Planned

    planned = 80.0 - T.max_overlap_shortfall_pct
    dist = Distribution.of(np.full(5, planned + delta))
    reasons = _judge(plan=Plan(), forward_overlap_pct=dist)
    assert bool(reasons) is fails and (not fails or "forward overlap" in reasons[0])


def _flat(value: float) -> Distribution:
    dist = Distribution.of(np.full(5, value))
    assert dist is not None and dist.median == value
    return dist


@pytest.mark.parametrize(("delta", "fails"), [(-EPS, True), (0.0, False), (EPS, False)])
def test_forward_overlap_floor_without_a_plan(delta: float, fails: bool) -> None:
    reasons = _judge(forward_overlap_pct=_flat(T.min_forward_overlap_pct + delta))
    assert bool(reasons) is fails
    if fails:
        assert reasons[0].startswith("median forward overlap (endlap)") and "below the 60 %" in reasons[0]


@pytest.mark.parametrize(("delta", "fails"), [(-EPS, True), (0.0, False), (EPS, False)])
def test_side_overlap_floor_without_a_plan(delta: float, fails: bool) -> None:
    reasons = _judge(side_overlap_pct=_flat(T.min_side_overlap_pct + delta))
    assert bool(reasons) is fails and (not fails or reasons[0].startswith("median side overlap"))


@pytest.mark.parametrize(("delta", "fails"), [(-EPS, False), (0.0, False), (EPS, True)])
def test_base_height_ratio_of_consecutive_frames(delta: float, fails: bool) -> None:
    reasons = _judge(base_height_along_line=_flat(T.max_base_height_ratio + delta))
    assert bool(reasons) is fails
    assert not fails or "base-height ratio of consecutive frames of a line 0.54" in reasons[0]


@pytest.mark.parametrize(
    ("what", "level", "floor"),
    [
        ("forward", T.recommended_forward_overlap_pct, T.min_forward_overlap_pct),
        ("side", T.recommended_side_overlap_pct, T.min_side_overlap_pct),
    ],
)
@pytest.mark.parametrize(("delta", "warned"), [(-EPS, True), (0.0, False), (EPS, False)])
def test_overlap_below_the_recommendation_is_a_warning(
    what: str, level: float, floor: float, delta: float, warned: bool
) -> None:
    other = "side" if what == "forward" else "forward"
    figures = {f"{what}_overlap_pct": _flat(level + delta), f"{other}_overlap_pct": _flat(90.0)}
    warnings = overlap_warnings(thresholds=T, **figures)  # type: ignore[arg-type]
    assert bool(warnings) is warned and (not warned or warnings[0].startswith(f"median {what} overlap"))
    assert _judge(**figures) == ()  # a warning, never a failure
    # At the floor it is still only a warning; under it a failure, not also a warning.
    assert overlap_warnings(thresholds=T, **{**figures, f"{what}_overlap_pct": _flat(floor)})  # type: ignore[arg-type]
    below = {**figures, f"{what}_overlap_pct": _flat(floor - EPS)}
    assert overlap_warnings(thresholds=T, **below) == ()  # type: ignore[arg-type]
    assert _judge(**below)


def test_unmeasured_forward_overlap_is_said() -> None:
    warnings = overlap_warnings(thresholds=T, forward_overlap_pct=None, side_overlap_pct=None)
    assert len(warnings) == 1 and warnings[0].startswith("forward overlap not measured")


def test_the_advice_gives_the_trigger_distance_and_interval_for_the_recommended_endlap() -> None:
    """Eq. 3-5 and 3-6 (REFERENCES.md section 1), by hand: 60 m between frames at 40 % endlap is a
    100 m footprint along the track; 75 % endlap needs a base of 25 m, and at the same speed an
    interval of 25 / 60 x 5 s = 2.1 s; never a lower speed (a fixed wing cannot fly below its
    minimum). 72 m between lines at 28 % side overlap is a 100 m wide footprint: 60 %
    needs lines 40 m apart. B/H 0.675 at 60 m: B/H 0.54 needs 48 m; the intersection angle is
    2 atan(B / 2H)."""
    steps = LineSteps(base_m=60.0, interval_s=5.0, spacing_m=72.0)
    forward = _judge(forward_overlap_pct=_flat(40.0), steps=steps)
    assert "trigger distance of at most 25.0 m (now 60.0 m)" in forward[0]
    assert "trigger interval of at most 2.1 s (now 5.0 s)" in forward[0] and "m/s" not in forward[0]
    side = overlap_warnings(
        thresholds=T, forward_overlap_pct=_flat(80.0), side_overlap_pct=_flat(28.0), steps=steps
    )
    assert "lines at most 40.0 m apart (now 72.0 m)" in side[0]
    wide = _judge(base_height_along_line=_flat(0.675), steps=steps)
    assert (
        "trigger distance of at most 48.0 m (now 60.0 m)" in wide[0] and "37 deg" in wide[0]
    )  # 2 atan(0.3375)
    # Without capture times: the distance, and no speed.
    no_time = _judge(forward_overlap_pct=_flat(40.0), steps=LineSteps(base_m=60.0))
    assert "at most 25.0 m (now 60.0 m)" in no_time[0] and "m/s" not in no_time[0]


@pytest.mark.parametrize("limit", [T.max_blur_px, T.fail_blur_px])
def test_blur_limits_are_strict(limit: float) -> None:
    values = np.array([limit - EPS, limit, limit + EPS, np.nan])
    np.testing.assert_array_equal(above(values, limit), [False, False, True, False])


def test_good_base_height_range_includes_both_ends() -> None:
    lo, hi = T.min_base_height_ratio, T.max_base_height_ratio
    values = np.array([lo - EPS, lo, lo + EPS, hi - EPS, hi, hi + EPS])
    np.testing.assert_array_equal(good_base_height(values, T), [False, True, True, True, True, False])


# --- what the pixels say (processing/pixel_match.PixelFigures) -------------------------------------


def _pixels(*, connected: int, registered: int | None, forward_pct: float = 50.0, n: int = 100) -> Any:
    """Figures of ``n`` frames along one line: the first ``connected`` matched into one part, a quick
    reconstruction whose largest model registers the first ``registered`` (None: not run), every
    matched pair with ``forward_pct`` overlap."""
    from processing.pixel_match import PixelFigures

    pair_index = np.column_stack([np.arange(n - 1), np.arange(1, n)]).astype(np.int64)
    matched = np.arange(n - 1) < connected - 1
    component = np.concatenate([np.zeros(connected), np.arange(1, n - connected + 1)]).astype(np.int64)
    return PixelFigures(
        pair_index=pair_index,
        pair_along=np.ones(n - 1, dtype=bool),
        inliers=np.where(matched, 200, 0).astype(np.int64),
        matched=matched,
        overlap_pct=np.where(matched, forward_pct, np.nan),
        shift_px=np.full(n - 1, np.nan),
        gsd_cm=np.full(n - 1, np.nan),
        component=component,
        frame_count=n,
        match_size_px=640,
        seconds=1.0,
        tagged_gsd_cm=None,
        focal_px=1000.0,
        models=None if registered is None else (tuple(range(registered)),),
    )


def test_an_endlap_under_60_is_advice_when_the_pixels_say_the_block_holds() -> None:
    """53 % endlap whose frames all match and reconstruct (seneca_half's case): no failure, and the
    advice names the measured overlap and a trigger distance, never a speed."""
    steps = LineSteps(base_m=30.0, interval_s=4.0, spacing_m=40.0, height_m=60.0)
    pixels = _pixels(connected=100, registered=100, forward_pct=53.0)
    fwd = _flat(45.0)
    assert _judge(forward_overlap_pct=fwd, pixels=pixels, steps=steps) == ()
    advice = overlap_warnings(
        thresholds=T, forward_overlap_pct=fwd, side_overlap_pct=None, steps=steps, pixels=pixels
    )
    assert len(advice) == 1 and "53 % measured in the pixels (from the tags 45 %)" in advice[0]
    # 75 % endlap from 53 %: the base shrinks by (1 - 0.75) / (1 - 0.53); the height grows by its inverse.
    factor = 0.25 / 0.47
    assert f"trigger distance of at most {30.0 * factor:.1f} m (now 30.0 m)" in advice[0]
    assert f"height of at least {60.0 / factor:.0f} m" in advice[0]
    assert "m/s" not in advice[0]
    # Without the pixels the classical floor fails it.
    assert any(
        "below the 60 % a stereo block needs" in r for r in _judge(forward_overlap_pct=fwd, steps=steps)
    )


@pytest.mark.parametrize(("delta", "fails"), [(-1, True), (0, False), (1, False)])
def test_the_quick_reconstruction_must_register_enough_frames(delta: int, fails: bool) -> None:
    registered = int(T.min_registered_pct) + delta  # of 100 frames: the share in percent
    reasons = _judge(pixels=_pixels(connected=100, registered=registered), forward_overlap_pct=_flat(50.0))
    assert any("quick reconstruction" in r for r in reasons) is fails
    # A block that falls apart still fails on its endlap too (the advice is then a failure).
    assert any("below the 60 % a stereo block needs" in r for r in reasons) is fails


@pytest.mark.parametrize(("delta", "fails"), [(-1, True), (0, False), (1, False)])
def test_the_matched_frames_must_hold_together(delta: int, fails: bool) -> None:
    connected = int(T.min_connected_frames_pct) + delta
    reasons = _judge(pixels=_pixels(connected=connected, registered=None))
    assert any("separate parts" in r for r in reasons) is fails
