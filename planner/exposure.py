"""Exposure geometry of a pass: air base, line spacing, exposure interval, speed limits, B/H.

Equations from Aber et al. (2019), ch. 3 (REFERENCES.md section 1):
- Eq. 3-5: air base B = D x (1 - PE/100), D the frame's ground length along the line; the same
  with the ground width and the sidelap gives the line spacing.
- Eq. 3-6: exposure interval dT = B / Vg.
- Depth precision of a normal-case pair: sigma_Z = (H / B) x (H / f) x sigma_image.
- Intersection angle of a nadir pair: 2 atan(B / 2H).

For tilted frames the "frame length" is taken from the largest axis-aligned rectangle
inscribed in the frame's ground trapezoid (in the pass's along/across axes): planning with that
rectangle guarantees the overlaps everywhere in the frame, not only at its centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely

from .camera import Camera, Orientation
from .footprint import footprint_corners, motion_gsd_cm

#: Image measurement precision assumed for the expected depth precision, pixels.
SIGMA_IMAGE_PX = 0.5


@dataclass(frozen=True, kw_only=True)
class FrameRectangle:
    """The ground rectangle a frame surely covers, relative to the camera position, in the pass
    frame: u along the line direction, v across (to the right of the line direction), metres."""

    u_min_m: float
    u_max_m: float
    v_min_m: float
    v_max_m: float

    @property
    def along_m(self) -> float:
        return self.u_max_m - self.u_min_m

    @property
    def across_m(self) -> float:
        return self.v_max_m - self.v_min_m

    def scaled(self, scale: float) -> FrameRectangle:
        """The rectangle of a frame ``scale`` times as large (a footprint on higher ground)."""
        return FrameRectangle(
            u_min_m=self.u_min_m * scale, u_max_m=self.u_max_m * scale,
            v_min_m=self.v_min_m * scale, v_max_m=self.v_max_m * scale,
        )  # fmt: skip


def to_pass_frame(x: np.ndarray, y: np.ndarray, direction_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Rotate (x east, y north) into (u along bearing ``direction_deg``, v to its right)."""
    t = math.radians(direction_deg)
    return x * math.sin(t) + y * math.cos(t), x * math.cos(t) - y * math.sin(t)


def geometry_to_pass_frame(geom: shapely.Geometry, direction_deg: float) -> shapely.Geometry:
    """A shapely geometry in (x east, y north) rotated into the pass frame (:func:`to_pass_frame`)."""

    def rotate(coords: np.ndarray) -> np.ndarray:
        u, v = to_pass_frame(coords[:, 0], coords[:, 1], direction_deg)
        return np.column_stack([u, v])

    return shapely.transform(geom, rotate)


def from_pass_frame(u: np.ndarray, v: np.ndarray, direction_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of :func:`to_pass_frame`."""
    t = math.radians(direction_deg)
    return u * math.sin(t) + v * math.cos(t), u * math.cos(t) - v * math.sin(t)


def frame_rectangle(
    camera: Camera,
    height_m: float,
    direction_deg: float,
    up_bearing_deg: float,
    tilt_deg: float,
) -> FrameRectangle:
    """The largest axis-aligned (u, v) rectangle inside the frame's ground footprint."""
    corners = footprint_corners(camera, 0.0, 0.0, height_m, up_bearing_deg, tilt_deg)[0]
    u, v = to_pass_frame(corners[:, 0], corners[:, 1], direction_deg)
    # Snap numerical noise so that a nadir frame gives its exact rectangle.
    u = np.round(u, 9)
    v = np.round(v, 9)
    if _is_axis_aligned_rectangle(u, v):
        return FrameRectangle(
            u_min_m=float(u.min()),
            u_max_m=float(u.max()),
            v_min_m=float(v.min()),
            v_max_m=float(v.max()),
        )
    return _inscribed_rectangle(u, v)


def _is_axis_aligned_rectangle(u: np.ndarray, v: np.ndarray) -> bool:
    tol = 1e-6 * max(float(np.ptp(u)), float(np.ptp(v)), 1.0)
    return len({round(float(x) / tol) for x in u}) == 2 and len({round(float(y) / tol) for y in v}) == 2


def _inscribed_rectangle(u: np.ndarray, v: np.ndarray, samples: int = 121) -> FrameRectangle:
    """Largest-area axis-aligned rectangle inside a convex quadrilateral (grid search over the
    v-range; for a convex polygon the u-chord over [a, b] is bounded at a and b)."""
    v_grid = np.linspace(v.min(), v.max(), samples)
    left = np.empty(samples)
    right = np.empty(samples)
    ring_u = np.append(u, u[0])
    ring_v = np.append(v, v[0])
    for k, vv in enumerate(v_grid):
        crossings = []
        for i in range(4):
            v0, v1 = ring_v[i], ring_v[i + 1]
            if (v0 - vv) * (v1 - vv) <= 0 and v0 != v1:
                s = (vv - v0) / (v1 - v0)
                crossings.append(ring_u[i] + s * (ring_u[i + 1] - ring_u[i]))
        left[k], right[k] = (min(crossings), max(crossings)) if crossings else (np.nan, np.nan)
    best = (0.0, 0, 0)
    for i in range(samples):
        for j in range(i + 1, samples):
            lo = max(left[i], left[j])
            hi = min(right[i], right[j])
            area = (hi - lo) * (v_grid[j] - v_grid[i])
            if hi > lo and area > best[0]:
                best = (area, i, j)
    _, i, j = best
    return FrameRectangle(
        u_min_m=float(max(left[i], left[j])),
        u_max_m=float(min(right[i], right[j])),
        v_min_m=float(v_grid[i]),
        v_max_m=float(v_grid[j]),
    )


def up_bearing_deg(heading_deg: float, orientation: Orientation) -> float:
    """Bearing of the top of a nadir image for a vehicle flying ``heading_deg``."""
    if orientation is Orientation.LANDSCAPE:
        return heading_deg % 360.0  # image width across track, top forward
    return (heading_deg - 90.0) % 360.0  # image width along track, top to the left


def air_base_m(frame_length_m: float, overlap_pct: float) -> float:
    """Eq. 3-5: B = D (1 - PE/100); with the frame width and sidelap: the line spacing."""
    return frame_length_m * (1.0 - overlap_pct / 100.0)


def exposure_interval_s(air_base: float, ground_speed_m_s: float) -> float:
    """Eq. 3-6: dT = B / Vg."""
    return air_base / ground_speed_m_s


def max_speed_for_trigger_m_s(air_base: float, min_trigger_interval_s: float) -> float:
    """Fastest ground speed at which the camera keeps up with one photo per air base."""
    return air_base / min_trigger_interval_s


def blur_speed_limit_m_s(
    camera: Camera,
    orientation: Orientation,
    max_blur_px: float,
    alt_agl_m: float,
    tilt_deg: float,
    direction_deg: float,
    look_heading_deg: float | None,
) -> float | None:
    """The fastest ground speed whose motion blur stays within ``max_blur_px`` on a pass (None:
    no shutter time known), from the finest GSD along the motion (planner.footprint.motion_gsd_cm:
    an oblique flown toward or away from where it looks moves along the image's tilted axis;
    bearings in one frame, degrees)."""
    if camera.shutter_s is None:
        return None
    along_look = False
    if look_heading_deg is not None:
        off = abs((direction_deg - look_heading_deg + 90.0) % 180.0 - 90.0)  # 0: along, 90: across
        along_look = off < 45.0
    gsd = motion_gsd_cm(
        camera, alt_agl_m, tilt_deg, along_look, orientation_along_y=orientation is Orientation.LANDSCAPE
    )
    return max_speed_for_blur_m_s(gsd, camera.shutter_s, max_blur_px)


def max_speed_for_blur_m_s(gsd_along_cm: float, shutter_s: float, max_blur_px: float) -> float:
    """Fastest ground speed with motion blur at most ``max_blur_px`` pixels: v = blur x GSD / t
    (QGC and Mission Planner use half a pixel)."""
    return max_blur_px * gsd_along_cm / 100.0 / shutter_s


def base_height_ratio(air_base: float, height_m: float) -> float:
    return air_base / height_m


def intersection_angle_deg(air_base: float, height_m: float) -> float:
    return math.degrees(2.0 * math.atan(air_base / (2.0 * height_m)))


def depth_precision_m(
    camera: Camera, air_base: float, height_m: float, orientation: Orientation = Orientation.LANDSCAPE
) -> float:
    """sigma_Z = (H/B) (H/f) sigma_image, with sigma_image = SIGMA_IMAGE_PX pixels measured along
    the base: the along-track axis of the image (y in landscape, x in portrait), whose pixel
    pitch is the one that matters when the pixels are not square."""
    pitch_mm = camera.pixel_pitch_y_mm if orientation is Orientation.LANDSCAPE else camera.pixel_pitch_x_mm
    sigma_image_m = SIGMA_IMAGE_PX * pitch_mm / 1000.0
    return (height_m / air_base) * (height_m / (camera.focal_length_mm / 1000.0)) * sigma_image_m
