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

from processing.check import exact_gaps
from processing.check_result import Gap
from processing.distribution import Distribution
from processing.image_frames import PLACEHOLDER_DEG, _position
from processing.stereo import Pairs, scale_outliers
from processing.survey_frames import (
    ALTITUDE_DRIFT_M,
    ISOLATED_RATIO,
    LOW_RATIO,
    ON_GROUND_M,
    SUSPECT_SHARE,
    altitude_drift_warning,
    select_survey_frames,
)
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
    class Plan:  # the two figures judge reads from a plan
        front_overlap_pct = 80.0
        side_overlap_pct = 70.0

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


@pytest.mark.parametrize(("delta", "kept"), [(-0.001, False), (0.0, True), (0.001, True)])
def test_smallest_gap_reported(delta: float, kept: bool) -> None:
    # A 10 m x 10 m area, one footprint covering all of it but a strip of min_gap_area_m2 + delta.
    width = (T.min_gap_area_m2 + delta) / 10.0
    area = shapely.box(0, 0, 10, 10)
    footprint = shapely.box(width, -1, 11, 11)
    gaps = exact_gaps(area, [footprint], min_area_m2=T.min_gap_area_m2)
    assert (len(gaps) == 1) is kept
    if kept:
        assert gaps[0].area == pytest.approx(T.min_gap_area_m2 + delta, abs=1e-9)


def test_a_diagonal_sliver_is_one_gap_with_its_true_area() -> None:
    # Two footprints whose edges run diagonally 0.3 m apart across a 100 m square: on a 1 m grid
    # the sliver is a chain of cells touching at corners; here it is one gap of 0.3 x 141.4 m.
    area = shapely.box(0, 0, 100, 100)
    lower = shapely.Polygon(
        [(-1, -1), (101, -1), (101, 101 - 0.3 * math.sqrt(2)), (-1, -1 - 0.3 * math.sqrt(2))]
    )
    lower = shapely.Polygon([(-10, -10), (110, -10), (110, 110)])  # below the diagonal y = x
    upper = shapely.affinity.translate(shapely.Polygon([(-10, -10), (-10, 110), (110, 110)]), -0.3, 0.3)
    gaps = exact_gaps(area, [lower, upper], min_area_m2=1.0)
    assert len(gaps) == 1
    # Strip between y = x and y = x + 0.6, clipped to the square: 0.6 x 100 minus two corner triangles.
    assert gaps[0].area == pytest.approx(0.6 * 100 - 0.6**2 / 2 * 2 / 2, rel=1e-3)


@pytest.mark.parametrize(("ratio", "flagged"), [(1.25 - EPS, False), (1.25, False), (1.25 + EPS, True)])
def test_scale_difference(ratio: float, flagged: bool) -> None:
    class Fp:
        gsd_cm = np.array([1.0, ratio, 1.0])

    pairs = Pairs(
        i=np.array([0, 0]),
        j=np.array([1, 2]),
        base_m=np.zeros(2),
        height_m=np.ones(2),
        base_height_ratio=np.zeros(2),
        intersection_angle_deg=np.zeros(2),
        overlap_i_pct=np.zeros(2),
        overlap_j_pct=np.zeros(2),
        scale_ratio=np.ones(2),
        ground_xyz_m=np.zeros((2, 3)),
        intersection=np.zeros((2, 8, 2)),
    )
    outliers = scale_outliers(Fp(), pairs, 0.25)  # type: ignore[arg-type]
    assert (1 in outliers) is flagged


@pytest.mark.parametrize(
    ("height", "ground"), [(ON_GROUND_M - EPS, True), (ON_GROUND_M, True), (ON_GROUND_M + EPS, False)]
)
def test_on_the_ground(height: float, ground: bool) -> None:
    # A low block (5 m) so that the low-height rule (below 2.5 m) does not decide.
    h = np.array([height, *([5.0] * 20)])
    sel = select_survey_frames(h)
    assert (not sel.keep[0]) is ground
    assert not ground or "on the ground" in sel.left_out[0][1]


@pytest.mark.parametrize(
    ("factor", "low"), [(LOW_RATIO - EPS, True), (LOW_RATIO, False), (LOW_RATIO + EPS, False)]
)
def test_below_the_survey_height(factor: float, low: bool) -> None:
    h = np.array([80.0 * factor, *([80.0] * 20)])
    sel = select_survey_frames(h)
    assert (not sel.keep[0]) is low


@pytest.mark.parametrize(("count", "suspect"), [(7, False), (8, True)])
def test_ground_suspect_share(count: int, suspect: bool) -> None:
    # 21 frames: a third is 7.
    assert pytest.approx(1 / 3) == SUSPECT_SHARE
    h = np.array([0.0] * count + [80.0] * (21 - count))
    assert select_survey_frames(h).ground_suspect is suspect


@pytest.mark.parametrize(("factor", "transit"), [(1.0 - 1e-9, False), (1.0, False), (1.0 + 1e-6, True)])
def test_in_transit(factor: float, transit: bool) -> None:
    # Frames 10 m apart along a line; the last one ISOLATED_RATIO x 10 m (x factor) from its neighbour.
    x = np.arange(20) * 10.0
    x = np.append(x, x[-1] + ISOLATED_RATIO * 10.0 * factor)
    xy = np.column_stack([x, np.zeros_like(x)])
    sel = select_survey_frames(np.full(len(x), 80.0), xy, frame_length_m=1.0)
    assert (not sel.keep[-1]) is transit


@pytest.mark.parametrize(
    ("drift", "warned"),
    [(ALTITUDE_DRIFT_M - 0.01, False), (ALTITUDE_DRIFT_M, False), (ALTITUDE_DRIFT_M + 0.01, True)],
)
def test_altitude_drift(drift: float, warned: bool) -> None:
    t = np.linspace(0.0, 600.0, 31)
    alt = 400.0 + drift * t / 600.0
    assert (altitude_drift_warning(alt, t, 90.0, "amsl") is not None) is warned
    assert altitude_drift_warning(alt, t, 90.0, "rel_home") is None  # barometric: not judged


@pytest.mark.parametrize(
    ("offset", "placeholder"),
    [(PLACEHOLDER_DEG * 0.999, True), (PLACEHOLDER_DEG, False), (PLACEHOLDER_DEG * 1.001, False)],
)
def test_placeholder_position(offset: float, placeholder: bool) -> None:
    from acquisition.exif import ImageTags

    tags = ImageTags(path="x.jpg", gps_lat_deg=offset, gps_lon_deg=offset, gps_alt_amsl_m=100.0)
    position, why = _position(tags, relative=False)
    assert (position is None) is placeholder
    if placeholder:
        assert "placeholder position at 0/0" in why


def test_a_lower_pass_of_a_multi_scale_block_is_not_a_climb() -> None:
    # 40 frames at 120 m and 20 at 50 m (two flying heights, as the textbook advises: the lower
    # pass is 70 m under the block's median altitude), and the take-off climb shot every 2 m from
    # 4 to 14 m: only the climb is left out; the 50 m level of 20 frames is a pass.
    climb = np.arange(6) * 2.0 + 4.0
    h = np.concatenate([np.full(40, 120.0), climb, np.full(20, 50.0)])
    sel = select_survey_frames(h)
    assert sel.median_height_m == 120.0
    assert sel.keep[:40].all() and sel.keep[46:].all()
    assert [k for k, _ in sel.left_out] == list(range(40, 46))
    assert all("below the survey height" in why for _, why in sel.left_out)
