"""The Frames table and the check's local frame: local_frame_at against GeographicLib (distances
and true bearings from the centre), select keeping every column of the same rows."""

from __future__ import annotations

import math

import numpy as np
import pytest
from geographiclib.geodesic import Geodesic
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.camera_db import get_camera
from processing.frames import AltitudeReference, AttitudeSource, Frames, frames_local_frame, local_frame_at


@settings(max_examples=40, deadline=None)
@given(
    st.floats(-179.0, 179.0),
    st.floats(-75.0, 75.0),
    st.floats(0.0, 360.0, exclude_max=True),
    st.floats(10.0, 3000.0),
)
def test_local_frame_keeps_distances_and_true_bearings(
    lon_deg: float, lat_deg: float, azimuth_deg: float, distance_m: float
) -> None:
    frame = local_frame_at(lon_deg, lat_deg)
    there = Geodesic.WGS84.Direct(lat_deg, lon_deg, azimuth_deg, distance_m)
    x, y = frame.to_xy(np.array([lon_deg, there["lon2"]]), np.array([lat_deg, there["lat2"]]))
    # the centre is the origin (PROJ keeps the centre's latitude to about 1e-9 deg: 0.1 mm)
    assert abs(x[0]) < 1e-3 and abs(y[0]) < 1e-3
    dx, dy = x[1] - x[0], y[1] - y[0]
    assert math.hypot(dx, dy) == pytest.approx(distance_m, rel=1e-6)
    # grid north is true north at the centre: the bearing of the point is its azimuth there
    bearing = math.degrees(math.atan2(dx, dy)) % 360.0
    assert abs((bearing - azimuth_deg + 180.0) % 360.0 - 180.0) < 1e-3


def _frames(n: int) -> Frames:
    k = np.arange(n, dtype=np.float64)
    return Frames(
        name=tuple(f"f{i}" for i in range(n)),
        lon_deg=-1.5 + 1e-4 * k,
        lat_deg=42.0 + 2e-4 * k,
        alt_m=100.0 + k,
        alt_reference=AltitudeReference.REL_HOME,
        yaw_deg=10.0 * k,
        pitch_deg=0.5 * k,
        roll_deg=-0.25 * k,
        attitude_source=AttitudeSource.PLAN,
        camera=get_camera("dji-phantom-4-pro"),
        time_utc_s=1_700_000_000.0 + 2.0 * k,
        exposure_s=1e-3 * (1 + k),
        line_index=(np.arange(n) // 3).astype(np.int32),
    )


def test_select_takes_the_same_rows_of_every_column() -> None:
    frames = _frames(9)
    for keep in (np.array([True, False, True] * 3), np.array([7, 2, 4])):
        rows = np.flatnonzero(keep) if keep.dtype == np.bool_ else keep
        chosen = frames.select(keep)
        assert chosen.name == tuple(f"f{i}" for i in rows)
        for column in ("lon_deg", "lat_deg", "alt_m", "yaw_deg", "pitch_deg", "roll_deg", "time_utc_s"):
            np.testing.assert_array_equal(getattr(chosen, column), getattr(frames, column)[rows])
        assert chosen.exposure_s is not None and chosen.line_index is not None
        np.testing.assert_array_equal(chosen.exposure_s, 1e-3 * (1 + rows))
        np.testing.assert_array_equal(chosen.line_index, rows // 3)
        assert chosen.camera == frames.camera and chosen.alt_reference is frames.alt_reference


def test_the_frames_local_frame_is_centred_on_their_median_position() -> None:
    frames = _frames(9)
    x, y = frames_local_frame(frames).to_xy(np.median(frames.lon_deg), np.median(frames.lat_deg))
    assert abs(float(x)) < 1e-6 and abs(float(y)) < 1e-6
