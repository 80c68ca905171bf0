"""The check's stereo step (processing.check_stereo) on a synthetic block: convergence and
the doming risk, overlaps, the share of the area with a good pair, the lines."""

from __future__ import annotations

import dataclasses

import pytest
from shapely.geometry import box
from test_footprints import FRAME, ORIGIN_X_M, ORIGIN_Y_M
from test_stereo import GROUND, lawnmower, project

from processing.check_stereo import measure_stereo
from processing.coverage import Grid, area_mask
from processing.verdict import DEFAULT_THRESHOLDS


def test_a_nadir_block_warns_of_doming_and_obliques_lift_it() -> None:
    frames, _ = lawnmower(80.0, 70.0, turn_frames=False)
    area = box(ORIGIN_X_M, ORIGIN_Y_M, ORIGIN_X_M + 200, ORIGIN_Y_M + 200)
    grid = Grid.from_bounds(area.bounds, 1.0)
    mask = area_mask(area, grid)
    nadir = measure_stereo(frames, project(frames), GROUND, FRAME, grid, mask, DEFAULT_THRESHOLDS)
    assert nadir.doming_risk and nadir.convergent_pct == 0.0
    pitch = frames.pitch_deg.copy()
    pitch[::10] = 20.0  # 9 of 90 frames looking 20 deg forward
    oblique = dataclasses.replace(frames, pitch_deg=pitch)
    result = measure_stereo(oblique, project(oblique), GROUND, FRAME, grid, mask, DEFAULT_THRESHOLDS)
    assert not result.doming_risk
    assert result.convergent_pct == pytest.approx(100.0 * 9 / 90)
    assert nadir.forward_overlap_pct is not None and nadir.side_overlap_pct is not None
    assert nadir.forward_overlap_pct.median == pytest.approx(80.0, abs=0.01)
    assert nadir.side_overlap_pct.median == pytest.approx(70.0, abs=0.01)
    assert nadir.good_pair_pct == pytest.approx(100.0)
    assert nadir.line_count == 6
