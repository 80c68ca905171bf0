"""Ground footprints of frames by casting corner rays onto flat ground, and the GSD of tilted frames.

World frame: local east-north-up metres (x east, y north, z up); bearings clockwise from north.
Camera frame (computer-vision convention): x to the image's right, y to the image's bottom,
z along the optical axis.

A frame's pose is given as:
- ``up_bearing_deg``: the bearing the top of the image points toward. For a tilted camera this
  is the bearing it looks toward (the far edge is the top of the image).
- ``tilt_deg``: the optical axis off nadir, 0 = straight down, toward ``up_bearing_deg``.
- ``height_m``: camera height above the flat ground.

Orientation on the vehicle (landscape: image width across track) is the caller's business: it
picks ``up_bearing_deg`` = flight heading for landscape, heading - 90 for portrait.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .camera import Camera
from .errors import PlanningError

#: Corner order: image top-left, top-right, bottom-right, bottom-left.
_CORNER_SIGNS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


def camera_axes(up_bearing_deg: ArrayLike, tilt_deg: ArrayLike) -> NDArray[np.float64]:
    """World-from-camera rotation matrices, shape (N, 3, 3): columns are camera x, y, z in ENU."""
    beta = np.radians(np.atleast_1d(np.asarray(up_bearing_deg, float)))
    tilt = np.radians(np.atleast_1d(np.asarray(tilt_deg, float)))
    beta, tilt = np.broadcast_arrays(beta, tilt)
    sb, cb, st, ct = np.sin(beta), np.cos(beta), np.sin(tilt), np.cos(tilt)
    zeros = np.zeros_like(sb)
    x_axis = np.stack([cb, -sb, zeros], axis=-1)
    y_axis = np.stack([-ct * sb, -ct * cb, -st], axis=-1)
    z_axis = np.stack([st * sb, st * cb, -ct], axis=-1)
    return np.stack([x_axis, y_axis, z_axis], axis=-1)


def footprint_corners(
    camera: Camera,
    x_m: ArrayLike,
    y_m: ArrayLike,
    height_m: ArrayLike,
    up_bearing_deg: ArrayLike,
    tilt_deg: ArrayLike = 0.0,
) -> NDArray[np.float64]:
    """Ground corners of each frame on flat ground, shape (N, 4, 2) (x, y in metres).

    Raises PlanningError when a corner ray does not reach the ground (tilt + half the field of
    view at or above the horizon).
    """
    x = np.atleast_1d(np.asarray(x_m, float))
    y = np.atleast_1d(np.asarray(y_m, float))
    h = np.atleast_1d(np.asarray(height_m, float))
    x, y, h, up, tilt = np.broadcast_arrays(
        x,
        y,
        h,
        np.atleast_1d(np.asarray(up_bearing_deg, float)),
        np.atleast_1d(np.asarray(tilt_deg, float)),
    )
    rays_cam = np.column_stack(
        [
            _CORNER_SIGNS[:, 0] * camera.sensor_width_mm / 2.0,
            _CORNER_SIGNS[:, 1] * camera.sensor_height_mm / 2.0,
            np.full(4, camera.focal_length_mm),
        ]
    )  # (4, 3)
    rotation = camera_axes(up, tilt)  # (N, 3, 3)
    rays = np.einsum("nij,cj->nci", rotation, rays_cam)  # (N, 4, 3)
    down = -rays[..., 2]
    if np.any(down <= 1e-9 * camera.focal_length_mm):
        worst = float(np.max(tilt))
        raise PlanningError(
            f"a tilt of {worst:.1f} deg off nadir puts the far edge of the frame at or above the "
            f"horizon (half field of view {math.degrees(camera.half_fov_rad()[1]):.1f} deg); "
            f"lower tilt_deg"
        )
    scale = h[:, None] / down  # (N, 4)
    corners = np.empty((x.shape[0], 4, 2))
    corners[..., 0] = x[:, None] + rays[..., 0] * scale
    corners[..., 1] = y[:, None] + rays[..., 1] * scale
    return corners


def principal_point_offset_m(height_m: float, tilt_deg: float) -> float:
    """Horizontal distance from the camera to where its optical axis meets flat ground."""
    return height_m * math.tan(math.radians(tilt_deg))


def tilted_gsd_cm(
    camera: Camera, height_m: float, tilt_deg: float, row_offset_mm: float = 0.0
) -> tuple[float, float]:
    """GSD (radial, lateral) in cm of a tilted frame at an image row.

    ``row_offset_mm`` is the row's distance from the image centre on the sensor, positive
    toward the top of the image (the far side). On flat ground with the ray at angle
    phi = atan(row/f) from the axis and t + phi from the vertical:
    radial GSD = pitch_y * H * cos^2(phi) / (f * cos^2(t + phi)),
    lateral GSD = pitch_x * H * cos(phi) / (f * cos(t + phi)).
    For tilt 0 and the centre row they are Eq. 3-4.
    """
    phi = math.atan2(row_offset_mm, camera.focal_length_mm)
    angle = math.radians(tilt_deg) + phi
    if angle >= math.pi / 2 - 1e-9:
        raise PlanningError(
            f"tilt {tilt_deg:.1f} deg looks at or above the horizon at that row; lower tilt_deg"
        )
    f = camera.focal_length_mm
    radial = 100.0 * camera.pixel_pitch_y_mm * height_m * math.cos(phi) ** 2 / (f * math.cos(angle) ** 2)
    lateral = 100.0 * camera.pixel_pitch_x_mm * height_m * math.cos(phi) / (f * math.cos(angle))
    return radial, lateral


def near_far_gsd_cm(camera: Camera, height_m: float, tilt_deg: float) -> tuple[float, float]:
    """Finest and coarsest GSD in a frame (the coarser axis at the near and far edges)."""
    if tilt_deg == 0.0:
        # Nadir over flat ground: the GSD grows toward the corners by 1/cos(phi); the figure
        # quoted for a nadir frame is the centre's, as in Eq. 3-4.
        g = camera.gsd_cm(height_m)
        return g, g
    half_h = camera.sensor_height_mm / 2.0
    near = tilted_gsd_cm(camera, height_m, tilt_deg, -half_h)
    far = tilted_gsd_cm(camera, height_m, tilt_deg, half_h)
    return max(near), max(far)
