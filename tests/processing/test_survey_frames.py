"""Which frames are survey frames (processing.survey_frames), each rule at its boundary: exactly
at it, just below and just above (a ``>`` turned ``>=`` changes the outcome exactly there)."""

from __future__ import annotations

import numpy as np
import pytest

from processing.survey_frames import (
    ALTITUDE_DRIFT_M,
    CRUISE_SHARE,
    ISOLATED_RATIO,
    LOW_RATIO,
    ON_GROUND_M,
    SUSPECT_SHARE,
    altitude_drift_warning,
    select_survey_frames,
)
from processing.verdict import Thresholds

EPS = 1e-6
T = Thresholds()


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
    # Below or not, a frame at half the height is off the cruise (CRUISE_SHARE): left out either way.
    assert not sel.keep[0]
    assert ("below the survey height" in sel.left_out[0][1]) is low


@pytest.mark.parametrize(
    ("factor", "off"),
    [(1 - CRUISE_SHARE - EPS, True), (1 - CRUISE_SHARE + EPS, False), (1 + CRUISE_SHARE + EPS, True)],
)
def test_off_the_cruise_height(factor: float, off: bool) -> None:
    h = np.array([80.0 * factor, *([80.0] * 20)])
    sel = select_survey_frames(h)
    assert (not sel.keep[0]) is off
    assert not off or sel.left_out[0][1].startswith(("climbing: ", "descending: "))


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
