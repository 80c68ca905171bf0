"""Ground speed and motion blur per frame.

Ground speed per frame (m/s): over the step to its nearer-in-time neighbour on the same flight
line, unknown when that neighbour is more than 3 x the median capture interval away
(:func:`ground_speeds_m_s`); motion blur, pixels: how far the image of the ground moves during
the exposure (speed x exposure time / GSD for a nadir frame over flat ground), when an exposure
time is known.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .flight_lines import capture_order, flight_lines
from .footprints import Footprints
from .frames import Frames

F64 = NDArray[np.float64]


#: A frame's nearer same-line neighbour further than this many median capture intervals away in
#: time leaves its speed unknown: over a pause, a turn or dropped frames the straight step between
#: the two positions says little about the speed at the exposure.
SPEED_MAX_INTERVAL_RATIO = 3.0


@dataclass(frozen=True, kw_only=True)
class MotionBlur:
    """Per frame: ground speed (m/s, NaN where unknown), exposure (s) and blur (pixels, NaN where
    the speed or the exposure is unknown; the worst point of the frame, ``blur_centre_px`` at the
    image centre); ``exposure_s`` and ``blur_px`` are None when no exposure time is known,
    and ``exposure_source`` then too, else it says where the exposure came from ("exif" or
    "camera"). ``max_interval_s``: the longest interval a speed may be measured over (s; 0 when no
    two frames of a line have distinct times)."""

    speed_m_s: F64
    exposure_s: F64 | None
    blur_px: F64 | None
    exposure_source: str | None
    max_interval_s: float
    blur_centre_px: F64 | None = None


def ground_velocities_m_s(
    frames: Frames,
    footprints: Footprints,
    lines: NDArray[np.int64],
    *,
    max_interval_ratio: float = SPEED_MAX_INTERVAL_RATIO,
) -> tuple[F64, float]:
    """Velocity of each camera at its exposure, (N, 3) m/s in the local frame (x east, y north,
    z up; NaN rows where unknown), and the longest interval a velocity may be measured over (s).

    The velocity of a frame is the 3D step to its nearer-in-time neighbour (previous or next frame
    in capture order) of the same flight line, over the time between them (oriented forward in
    time): the camera fires on the line, and the nearer neighbour's step is the shortest stretch
    of flight around the exposure, so a pause or dropped frames on one side do not slow it down.
    A neighbour taken at the same time (no interval) does not count. When that neighbour is more
    than ``max_interval_ratio`` x the median interval between consecutive frames of a line away (a
    frame alone on its line, or between two gaps), the velocity is unknown rather than a guess:
    the straight step across a turn or a pause is not the motion at the exposure.
    """
    n = len(frames)
    velocity = np.full((n, 3), np.nan)
    if frames.time_utc_s is None or n < 2:
        return velocity, 0.0
    order = capture_order(frames)
    t = np.asarray(frames.time_utc_s, float)[order]
    xyz = footprints.camera_xyz_m[order]
    dt = np.diff(t)
    step = np.diff(xyz, axis=0)
    usable = (lines[order][:-1] == lines[order][1:]) & (dt > 0) & np.isfinite(step).all(axis=1)
    if not usable.any():
        return velocity, 0.0
    max_interval_s = max_interval_ratio * float(np.median(dt[usable]))
    usable &= dt <= max_interval_s
    step_velocity = np.where(usable[:, None], step / np.where(usable, dt, 1.0)[:, None], np.nan)
    # Each frame's step before and after it (in capture order), infinite time where unusable.
    dt_before = np.concatenate([[np.inf], np.where(usable, dt, np.inf)])
    dt_after = np.concatenate([np.where(usable, dt, np.inf), [np.inf]])
    nan_row = np.full((1, 3), np.nan)
    v_before = np.concatenate([nan_row, step_velocity])
    v_after = np.concatenate([step_velocity, nan_row])
    velocity[order] = np.where((dt_before <= dt_after)[:, None], v_before, v_after)
    return velocity, max_interval_s


def ground_speeds_m_s(
    frames: Frames,
    footprints: Footprints,
    lines: NDArray[np.int64],
    *,
    max_interval_ratio: float = SPEED_MAX_INTERVAL_RATIO,
) -> tuple[F64, float]:
    """Ground speed of each frame at its exposure (m/s, NaN where unknown): the length of its
    velocity (:func:`ground_velocities_m_s`), and the longest interval measured over (s)."""
    velocity, max_interval_s = ground_velocities_m_s(
        frames, footprints, lines, max_interval_ratio=max_interval_ratio
    )
    return np.linalg.norm(velocity, axis=1), max_interval_s


def image_motion_px(
    footprints: Footprints,
    displacement_m: F64,
    camera_pitch_mm: tuple[float, float],
    focal_length_mm: float,
    ground_z_m: F64 | None = None,
) -> tuple[F64, F64]:
    """How far the image of the ground moves while each camera moves by ``displacement_m``
    ((N, 3) metres, x east, y north, z up): (worst over the frame, at the image centre), pixels.

    Each ground point P seen by a frame (its ring vertices and its principal point) projects to
    u = f x_c / z_c with (x_c, y_c, z_c) = R^T (P - C); after the camera moves by d it is at
    f (x_c - d_x) / (z_c - d_z). The displacement on the sensor, along x and y, over the pixel
    pitch of each axis, is the blur in pixels along the direction of motion in the image: the
    ground moves fastest across the image where it is nearest, at the near edge of a tilted
    frame. ``ground_z_m`` (N, V): the ground's elevation under each ring vertex (None: the
    principal point's elevation, i.e. flat ground under each frame).
    """
    n = len(footprints)
    worst = np.full(n, np.nan)
    centre = np.full(n, np.nan)
    if n == 0:
        return worst, centre
    xy = footprints.xy_m
    z = (
        ground_z_m
        if ground_z_m is not None
        else np.repeat(footprints.principal_xyz_m[:, 2:3], xy.shape[1], 1)
    )
    points = np.concatenate(
        [np.concatenate([xy, z[..., None]], axis=2), footprints.principal_xyz_m[:, None, :]], axis=1
    )  # (N, V+1, 3)
    r = footprints.world_from_camera
    rel = points - footprints.camera_xyz_m[:, None, :]
    cam = np.einsum("nji,nvj->nvi", r, rel)  # R^T (P - C)
    d = np.einsum("nji,nj->ni", r, displacement_m)[:, None, :]
    moved = cam - d
    pitch_x, pitch_y = camera_pitch_mm
    with np.errstate(divide="ignore", invalid="ignore"):
        du = focal_length_mm * (moved[..., 0] / moved[..., 2] - cam[..., 0] / cam[..., 2]) / pitch_x
        dv = focal_length_mm * (moved[..., 1] / moved[..., 2] - cam[..., 1] / cam[..., 2]) / pitch_y
    blur = np.hypot(du, dv)
    ok = footprints.valid & np.isfinite(displacement_m).all(axis=1)
    worst = np.where(ok, np.nanmax(np.where(np.isfinite(blur), blur, -np.inf), axis=1), np.nan)
    centre = np.where(ok, blur[:, -1], np.nan)
    return worst, centre


def motion_blur(
    frames: Frames,
    footprints: Footprints,
    lines: NDArray[np.int64] | None = None,
    *,
    ground_z_m: F64 | None = None,
) -> MotionBlur | None:
    """Ground speeds (:func:`ground_speeds_m_s`) and motion blur in pixels: how far the image of
    the ground moves during the exposure, along the direction of motion in the image, at the
    point of the frame where it moves most (:func:`image_motion_px`; for a nadir frame over flat
    ground, speed x exposure / GSD along the axis of motion).

    None without capture times; without an exposure time (neither EXIF nor the camera's
    ``shutter_s``) the speeds alone, blur None; NaN for a frame whose exposure or speed is
    unknown. ``lines``: the flight lines (:func:`flight_lines`, computed when not given).
    """
    n = len(frames)
    if frames.time_utc_s is None or n < 2:
        return None
    if lines is None:
        lines = flight_lines(frames, footprints)
    velocity, max_interval_s = ground_velocities_m_s(frames, footprints, lines)
    speed = np.linalg.norm(velocity, axis=1)
    exposure: F64 | None = None
    source: str | None = None
    if frames.exposure_s is not None:
        exposure = np.asarray(frames.exposure_s, float)
        source = "exif"
    elif frames.camera.shutter_s is not None:
        exposure = np.full(n, frames.camera.shutter_s)
        source = "camera"
    blur = centre = None
    if exposure is not None:
        camera = frames.camera
        blur, centre = image_motion_px(
            footprints,
            velocity * exposure[:, None],
            (camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm),
            camera.focal_length_mm,
            ground_z_m,
        )
    return MotionBlur(
        speed_m_s=speed,
        exposure_s=exposure,
        blur_px=blur,
        blur_centre_px=centre,
        exposure_source=source,
        max_interval_s=max_interval_s,
    )
