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


def test_the_advice_gives_the_trigger_distance_and_speed_for_the_recommended_endlap() -> None:
    """Eq. 3-5 and 3-6 (REFERENCES.md section 1), by hand: 60 m between frames at 40 % endlap is a
    100 m footprint along the track; 75 % endlap needs a base of 25 m, and at the same 5 s interval
    5 m/s instead of 12. 72 m between lines at 28 % side overlap is a 100 m wide footprint: 60 %
    needs lines 40 m apart. B/H 0.675 at 60 m: B/H 0.54 needs 48 m; the intersection angle is
    2 atan(B / 2H)."""
    steps = LineSteps(base_m=60.0, interval_s=5.0, spacing_m=72.0)
    forward = _judge(forward_overlap_pct=_flat(40.0), steps=steps)
    assert "trigger distance of at most 25.0 m (now 60.0 m)" in forward[0]
    assert "ground speed of at most 5.0 m/s (now 12.0 m/s)" in forward[0]
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
