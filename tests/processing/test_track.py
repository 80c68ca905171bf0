"""Frames from positions alone (processing.track): headings against GeographicLib."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from geographiclib.geodesic import Geodesic

from planner.camera import Orientation
from planner.camera_db import get_camera
from processing.frames import AltitudeReference, AttitudeSource
from processing.track import frames_from_track, track_heading_deg


def test_track_heading_along_lines_and_at_turns() -> None:
    # Two lines flown north then south, 10 m between frames, 40 m apart (at 42 N).
    d_lat = 10.0 / 111_000.0
    d_lon = 40.0 / 82_700.0
    lat = 42.0 + d_lat * np.array([0, 1, 2, 3, 3, 2, 1, 0])
    lon = -1.5 + d_lon * np.array([0, 0, 0, 0, 1, 1, 1, 1])
    heading = track_heading_deg(lon, lat)
    # Inside a line: the bearing from the previous frame to the next (GeographicLib).
    expected = Geodesic.WGS84.Inverse(lat[0], lon[0], lat[2], lon[2])["azi1"] % 360.0
    assert heading[1] == pytest.approx(expected, abs=1e-9)
    assert heading[0] == pytest.approx(0.0, abs=1e-6)  # first frame: its one step, north
    # The last frame of the first line and the first of the second: the turn is between
    # them, so each takes its own line's direction, not the diagonal across the turn.
    assert heading[3] == pytest.approx(0.0, abs=1e-6)
    assert heading[4] == pytest.approx(180.0, abs=0.01)
    assert heading[7] == pytest.approx(180.0, abs=0.01)
    # Standing still: 0 by convention; a single frame: 0.
    still = track_heading_deg(np.array([0.0, 0.0]), np.array([1.0, 1.0]))
    assert still.tolist() == [0.0, 0.0]
    assert track_heading_deg(np.array([1.0]), np.array([2.0])).tolist() == [0.0]


def test_frames_from_track_point_the_image_top_along_the_track() -> None:
    camera = get_camera("dji-phantom-4-pro")
    lon = np.array([-1.5, -1.499, -1.498])  # flying east
    lat = np.full(3, 42.0)
    kwargs: dict[str, Any] = {
        "name": ["a", "b", "c"], "lon_deg": lon, "lat_deg": lat, "alt_m": np.full(3, 60.0),
        "alt_reference": AltitudeReference.REL_HOME, "camera": camera,
    }  # fmt: skip
    landscape = frames_from_track(**kwargs)
    expected = Geodesic.WGS84.Inverse(42.0, -1.5, 42.0, -1.498)["azi1"]
    assert landscape.yaw_deg[1] == pytest.approx(expected, abs=1e-9)
    assert landscape.attitude_source is AttitudeSource.ASSUMED_NADIR
    portrait = frames_from_track(**kwargs, orientation=Orientation.PORTRAIT)
    np.testing.assert_allclose(portrait.yaw_deg, (landscape.yaw_deg - 90.0) % 360.0)
