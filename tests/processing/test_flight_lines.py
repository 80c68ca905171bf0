"""Flight lines and the overlaps along and across them (processing.flight_lines), on synthetic
blocks whose overlaps and spacings are set, so known."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_footprints import CAMERA, FRAME, ORIGIN_X_M, ORIGIN_Y_M, make_frames
from test_stereo import GROUND, HEIGHT_M, lawnmower, project

from planner.camera import Orientation
from processing.flight_lines import flight_lines, forward_overlaps_pct, pair_kinds, side_overlaps_pct
from processing.frames import AltitudeReference
from processing.stereo import overlapping_pairs


@pytest.mark.parametrize(("forward_pct", "side_pct"), [(80.0, 70.0), (60.0, 30.0), (75.0, 65.0)])
def test_measured_overlaps_equal_the_set_ones(forward_pct: float, side_pct: float) -> None:
    frames, station = lawnmower(forward_pct, side_pct)
    fp = project(frames)
    lines = flight_lines(frames, fp)
    # Six survey lines, each turn frame a line of its own: the turns are breaks, not lines' frames.
    assert len(np.unique(lines[station])) == 6
    assert len(np.unique(lines)) == 6 + 5
    assert not np.isin(lines[~station], lines[station]).any()
    forward = forward_overlaps_pct(frames, fp, lines)
    side = side_overlaps_pct(frames, fp, lines)
    # Flat ground, nadir: the set overlaps exactly, up to the lon/lat round trip of positions.
    tolerance = 0.01
    assert forward.size == 6 * 14
    np.testing.assert_allclose(forward, forward_pct, atol=tolerance)
    # Inner lines have two neighbours, the outer two one each.
    assert side.size == 15 * (4 * 2 + 2)
    np.testing.assert_allclose(side, side_pct, atol=tolerance)


def test_plan_line_index_is_used_as_given() -> None:
    frames, _ = lawnmower(80.0, 70.0, turn_frames=False)
    planned = np.repeat(np.arange(6), 15).astype(np.int32)
    with_plan = dataclasses.replace(frames, line_index=planned, time_utc_s=None)
    fp = project(with_plan)
    np.testing.assert_array_equal(flight_lines(with_plan, fp), planned)
    np.testing.assert_allclose(side_overlaps_pct(with_plan, fp, flight_lines(with_plan, fp)), 70.0, atol=0.01)


def test_a_jump_in_a_line_breaks_it() -> None:
    y = ORIGIN_Y_M + np.concatenate([np.arange(10) * 20.0, 400 + np.arange(10) * 20.0])
    frames = make_frames(np.full(20, ORIGIN_X_M), y, HEIGHT_M, reference=AltitudeReference.REL_HOME)
    lines = flight_lines(frames, project(frames))
    np.testing.assert_array_equal(lines, np.repeat([0, 1], 10))


def test_base_height_of_consecutive_and_of_neighbouring_line_pairs() -> None:
    frames, _ = lawnmower(80.0, 70.0, turn_frames=False)
    fp = project(frames)
    pairs = overlapping_pairs(fp, GROUND, FRAME)
    lines = flight_lines(frames, fp)
    along, across = pair_kinds(frames, pairs, lines)
    # Eq. 3-5: B = D (1 - PE / 100) along a line; the line spacing across: B/H over HEIGHT_M.
    nominal = CAMERA.footprint(HEIGHT_M, Orientation.LANDSCAPE)
    assert along.sum() == 6 * 14
    np.testing.assert_allclose(pairs.base_height_ratio[along], nominal.along_m * 0.2 / HEIGHT_M, rtol=1e-6)
    assert across.sum() == 5 * 15  # each station and its neighbour on the next line, once
    np.testing.assert_allclose(pairs.base_height_ratio[across], nominal.across_m * 0.3 / HEIGHT_M, rtol=1e-6)
    # Every other overlapping pair (two stations apart, diagonal, two lines over) is neither.
    assert (~(along | across)).sum() == len(pairs) - 6 * 14 - 5 * 15 > 0
