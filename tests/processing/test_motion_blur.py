"""Ground speed and motion blur (processing.motion_blur) on synthetic lines whose speeds, bases
and exposures are set, so known."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from test_footprints import CAMERA, ORIGIN_X_M, ORIGIN_Y_M, make_frames
from test_stereo import HEIGHT_M, SPEED_M_S, START_S, lawnmower, project

from processing.distribution import Distribution
from processing.flight_lines import flight_lines
from processing.frames import AltitudeReference, Frames
from processing.motion_blur import motion_blur


def test_motion_blur_is_speed_times_exposure_over_gsd() -> None:
    frames, station = lawnmower(80.0, 70.0)
    fp = project(frames)
    blur = motion_blur(frames, fp)
    assert blur is not None and blur.exposure_source == "exif"
    assert blur.exposure_s is not None and blur.blur_px is not None
    # blur = v t / GSD, the GSD from the planner's formula (Eq. 3-4) at the set height.
    expected_px = SPEED_M_S * (1 / 500) / (CAMERA.gsd_cm(HEIGHT_M) / 100)
    np.testing.assert_allclose(blur.speed_m_s[station], SPEED_M_S, rtol=1e-6)
    np.testing.assert_allclose(blur.blur_px[station], expected_px, rtol=1e-6)
    # A frame in a turn is a line of its own: no neighbour on its line, so no speed to measure.
    assert np.isnan(blur.speed_m_s[~station]).all() and np.isnan(blur.blur_px[~station]).all()
    # Without an EXIF exposure, the camera's shutter.
    no_exif = dataclasses.replace(frames, exposure_s=None)
    shutter = dataclasses.replace(no_exif, camera=dataclasses.replace(CAMERA, shutter_s=1 / 1000))
    from_camera = motion_blur(shutter, fp)
    assert from_camera is not None and from_camera.exposure_source == "camera"
    assert from_camera.blur_px is not None
    np.testing.assert_allclose(from_camera.blur_px[station], expected_px / 2, rtol=1e-6)


def test_without_an_exposure_time_the_speeds_remain() -> None:
    frames, station = lawnmower(80.0, 70.0, exposure_s=None)
    assert frames.camera.shutter_s is None
    fp = project(frames)
    blur = motion_blur(frames, fp)
    assert blur is not None
    assert blur.blur_px is None and blur.exposure_s is None and blur.exposure_source is None
    np.testing.assert_allclose(blur.speed_m_s[station], SPEED_M_S, rtol=1e-6)
    speed = Distribution.of(blur.speed_m_s)
    assert speed is not None and speed.median == pytest.approx(SPEED_M_S)
    assert int(np.isnan(blur.speed_m_s).sum()) == int((~station).sum())
    # Without capture times there is no speed either.
    assert motion_blur(dataclasses.replace(frames, time_utc_s=None), fp) is None


def line_at(speed_m_s: float, base_m: float, times_s: np.ndarray) -> Frames:
    """One line north, a frame every ``base_m``, taken at ``times_s`` (speed set by the caller)."""
    n = times_s.size
    frames = make_frames(
        np.full(n, ORIGIN_X_M),
        ORIGIN_Y_M + base_m * np.arange(n),
        HEIGHT_M,
        reference=AltitudeReference.REL_HOME,
    )
    return dataclasses.replace(frames, time_utc_s=START_S + times_s, exposure_s=np.full(n, 1 / 500))


def test_a_pause_in_a_line_does_not_lower_the_speed() -> None:
    """Frames every 16 m at 8 m/s (2 s apart); the vehicle hovers 10 s after frame 9, and frame 15
    is taken between two hovers. The slower-neighbour rule gave frames 9 and 10 1.3 m/s."""
    base_m, interval_s = 16.0, 2.0
    steps = np.full(24, interval_s)
    steps[9] += 10.0  # between frames 9 and 10
    steps[14] += 10.0  # between 14 and 15
    steps[15] += 10.0  # between 15 and 16
    frames = line_at(SPEED_M_S, base_m, np.concatenate([[0.0], np.cumsum(steps)]))
    fp = project(frames)
    assert len(np.unique(flight_lines(frames, fp))) == 1
    blur = motion_blur(frames, fp)
    assert blur is not None and blur.blur_px is not None
    # The median interval is 2 s: neighbours further than 6 s do not count.
    assert blur.max_interval_s == pytest.approx(3 * interval_s)
    known = np.arange(25) != 15
    np.testing.assert_allclose(blur.speed_m_s[known], base_m / interval_s, rtol=1e-9)
    assert np.isnan(blur.speed_m_s[15]) and np.isnan(blur.blur_px[15])
    expected_px = SPEED_M_S * (1 / 500) / (CAMERA.gsd_cm(HEIGHT_M) / 100)
    np.testing.assert_allclose(blur.blur_px[known], expected_px, rtol=1e-6)


def test_the_nearer_neighbour_in_time_gives_the_speed() -> None:
    """Frames 16 m apart, 2 s apart up to frame 5 (8 m/s), then 4 s apart (4 m/s, the vehicle
    slowed down): frame 5 takes the speed of its nearer neighbour, frame 4."""
    times = np.concatenate([2.0 * np.arange(6), 10.0 + 4.0 * np.arange(1, 6)])
    frames = line_at(SPEED_M_S, 16.0, times)
    blur = motion_blur(frames, project(frames))
    assert blur is not None
    np.testing.assert_allclose(blur.speed_m_s, np.where(np.arange(11) <= 5, 8.0, 4.0), rtol=1e-9)


def test_frames_of_another_line_are_not_neighbours() -> None:
    """Two lines 60 m apart at 8 m/s, frames 2 s apart; the first frame of the second line is
    taken 1 s after the last of the first (a 60 m/s chord). Nearer in time, but on another line:
    the last frame of the first line keeps the speed of its own line."""
    ys = ORIGIN_Y_M + 16.0 * np.arange(10)
    frames = make_frames(
        np.concatenate([np.full(10, ORIGIN_X_M), np.full(10, ORIGIN_X_M + 60.0)]),
        np.concatenate([ys, ys[::-1]]),
        HEIGHT_M,
        np.repeat([0.0, 180.0], 10),
        reference=AltitudeReference.REL_HOME,
    )
    times = np.concatenate([2.0 * np.arange(10), 19.0 + 2.0 * np.arange(10)])
    frames = dataclasses.replace(frames, time_utc_s=START_S + times, exposure_s=np.full(20, 1 / 500))
    fp = project(frames)
    np.testing.assert_array_equal(flight_lines(frames, fp), np.repeat([0, 1], 10))
    blur = motion_blur(frames, fp)
    assert blur is not None
    np.testing.assert_allclose(blur.speed_m_s, SPEED_M_S, rtol=1e-9)


def test_blur_of_a_tilted_frame_is_worst_at_its_near_edge() -> None:
    from test_footprints import _oracle_world_from_camera

    pitch_deg, exposure_s = 30.0, 1 / 100
    y = ORIGIN_Y_M + np.arange(5) * 10.0
    frames = make_frames(
        np.full(5, ORIGIN_X_M), y, HEIGHT_M, 0.0, pitch_deg, reference=AltitudeReference.REL_HOME
    )
    frames = dataclasses.replace(
        frames, time_utc_s=START_S + np.arange(5) * 10.0 / SPEED_M_S, exposure_s=np.full(5, exposure_s)
    )
    fp = project(frames)
    blur = motion_blur(frames, fp)
    assert blur is not None and blur.blur_px is not None and blur.blur_centre_px is not None
    d = SPEED_M_S * exposure_s  # metres flown north during the exposure
    f_px = CAMERA.focal_length_mm / CAMERA.pixel_pitch_y_mm
    # The centre: the ground point H tan(p) ahead of the nadir is seen p off the vertical, on the
    # axis; after the camera moves d it is seen atan((H tan p - d) / H) off the vertical, so
    # f tan(that - p) pixels from the centre, along the image's vertical (the track).
    p = math.radians(pitch_deg)
    centre = f_px * abs(math.tan(math.atan((HEIGHT_M * math.tan(p) - d) / HEIGHT_M) - p))
    np.testing.assert_allclose(blur.blur_centre_px, centre, rtol=1e-6)
    # Everywhere: an independent pinhole projection of each ground ring point before and after.
    r = _oracle_world_from_camera(0.0, pitch_deg, 0.0)
    worst = []
    for k in range(5):
        cam = fp.camera_xyz_m[k]
        shifts = []
        for x, yy in fp.xy_m[k]:
            for offset in (0.0, d):
                v = r.T @ (np.array([x, yy, 0.0]) - (cam + np.array([0.0, offset, 0.0])))
                shifts.append((f_px * v[0] / v[2], f_px * v[1] / v[2]))
        pts = np.array(shifts).reshape(-1, 2, 2)
        worst.append(np.hypot(*(pts[:, 1] - pts[:, 0]).T).max())
    np.testing.assert_allclose(blur.blur_px, worst, rtol=1e-6)
    # The near edge (image bottom, closest ground) smears more than the centre: tilt makes it worse.
    assert (blur.blur_px > 1.3 * blur.blur_centre_px).all()
