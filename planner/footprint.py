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
from .errors import SpecError
from .geo import LocalFrame
from .terrain import Dem

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
        raise SpecError(
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
        raise SpecError(f"tilt {tilt_deg:.1f} deg looks at or above the horizon at that row; lower tilt_deg")
    f = camera.focal_length_mm
    radial = 100.0 * camera.pixel_pitch_y_mm * height_m * math.cos(phi) ** 2 / (f * math.cos(angle) ** 2)
    lateral = 100.0 * camera.pixel_pitch_x_mm * height_m * math.cos(phi) / (f * math.cos(angle))
    return radial, lateral


def pixel_gsd_cm(camera: Camera, height_m: float, tilt_deg: float, x_mm: float, y_mm: float) -> float:
    """GSD (cm) of the pixel at sensor position (x_mm right, y_mm down from the centre) on flat
    ground: the ground length of one pixel step along the image's x and y, the coarser of the two
    (cast rays through the pixel's edges)."""
    return max(pixel_steps_cm(camera, height_m, tilt_deg, x_mm, y_mm))


def motion_gsd_cm(
    camera: Camera, height_m: float, tilt_deg: float, motion_along_look: bool, orientation_along_y: bool
) -> float:
    """The finest GSD along the direction of motion in a frame over flat ground (cm): what motion
    blur is measured in. Nadir: the pixel axis the lines are flown along (``orientation_along_y``:
    the image's y axis). A tilted frame flown toward or away from where it looks
    (``motion_along_look``) moves along the image's y axis, whose ground step is finest at the
    middle of the near edge; flown across the look direction, along the x axis, finest there too."""
    if tilt_deg == 0.0:
        return camera.gsd_y_cm(height_m) if orientation_along_y else camera.gsd_x_cm(height_m)
    step_x, step_y = pixel_steps_cm(camera, height_m, tilt_deg, 0.0, camera.sensor_height_mm / 2.0)
    return step_y if motion_along_look else step_x


def pixel_steps_cm(
    camera: Camera, height_m: float, tilt_deg: float, x_mm: float, y_mm: float
) -> tuple[float, float]:
    """The ground length (cm, flat ground) of one pixel step along the image's x and along its y
    at sensor position (x_mm right, y_mm down from the centre): rays cast through the pixel's
    edges."""
    rotation = camera_axes(0.0, tilt_deg)[0]
    px, py, f = camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm, camera.focal_length_mm

    def ground(xs: float, ys: float) -> NDArray[np.float64]:
        ray = rotation @ np.array([xs, ys, f])
        if -ray[2] <= 1e-12 * f:
            raise SpecError(
                f"tilt {tilt_deg:.1f} deg looks at or above the horizon at the frame's edge; lower tilt_deg"
            )
        return np.asarray(ray[:2] * height_m / -ray[2], float)

    step_x = np.linalg.norm(ground(x_mm + px / 2, y_mm) - ground(x_mm - px / 2, y_mm))
    step_y = np.linalg.norm(ground(x_mm, y_mm + py / 2) - ground(x_mm, y_mm - py / 2))
    return 100.0 * float(step_x), 100.0 * float(step_y)


def near_far_gsd_cm(camera: Camera, height_m: float, tilt_deg: float) -> tuple[float, float]:
    """Finest and coarsest GSD in a frame over flat ground (the coarser pixel axis).

    A nadir frame over flat ground is a uniform scaling of the sensor (image plane parallel to
    the ground), so its GSD is the same everywhere: Eq. 3-4. A tilted frame's GSD grows toward
    its far edge and, along that edge, toward the far corners: the worst is at a far corner, the
    finest at the middle of the near edge."""
    if tilt_deg == 0.0:
        g = camera.gsd_cm(height_m)
        return g, g
    half_w, half_h = camera.sensor_width_mm / 2.0, camera.sensor_height_mm / 2.0
    # The far edge is the top of the image (y negative in the camera frame).
    near = pixel_gsd_cm(camera, height_m, tilt_deg, 0.0, half_h)
    far = max(pixel_gsd_cm(camera, height_m, tilt_deg, sx * half_w, -half_h) for sx in (-1.0, 1.0))
    return near, far


def image_grid_mm(camera: Camera, samples: int) -> NDArray[np.float64]:
    """Sensor points (x_mm, y_mm) of a samples x samples grid spanning the image, border
    included, row by row from the image's top-left."""
    xs = np.linspace(-camera.sensor_width_mm / 2.0, camera.sensor_width_mm / 2.0, samples)
    ys = np.linspace(-camera.sensor_height_mm / 2.0, camera.sensor_height_mm / 2.0, samples)
    gx, gy = np.meshgrid(xs, ys)
    return np.column_stack([gx.ravel(), gy.ravel()])


def cast_on_dem(
    camera: Camera,
    x_m: ArrayLike,
    y_m: ArrayLike,
    z_amsl_m: ArrayLike,
    up_bearing_deg: ArrayLike,
    tilt_deg: ArrayLike,
    dem: Dem,
    frame: LocalFrame,
    sensor_mm: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Where the rays through the sensor points ``sensor_mm`` (K, 2) of each frame first meet
    the DEM, shape (N, K, 3) (x, y, ground elevation AMSL).

    Each ray is marched from where it crosses the DEM's highest elevation to where it crosses its
    lowest, in steps of at most one DEM cell horizontally; the first step below the ground is
    refined by bisection (to a millimetre). A ray that never comes down to the ground (a
    tilt at or above the horizon) raises SpecError; ground outside the DEM raises TerrainError.
    """
    x = np.atleast_1d(np.asarray(x_m, float))
    y = np.atleast_1d(np.asarray(y_m, float))
    z = np.atleast_1d(np.asarray(z_amsl_m, float))
    up = np.atleast_1d(np.asarray(up_bearing_deg, float))
    tilt = np.atleast_1d(np.asarray(tilt_deg, float))
    x, y, z, up, tilt = np.broadcast_arrays(x, y, z, up, tilt)
    n, k = x.shape[0], sensor_mm.shape[0]
    rays_cam = np.column_stack([sensor_mm, np.full(k, camera.focal_length_mm)])
    rays = np.einsum("nij,kj->nki", camera_axes(up, tilt), rays_cam)  # (N, K, 3)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    down = -rays[..., 2]
    if np.any(down <= 1e-6):
        raise SpecError(
            f"a tilt of {float(np.max(tilt)):.1f} deg off nadir puts part of the frame at or above the "
            f"horizon; lower tilt_deg"
        )
    z_low, z_high = dem.elevation_range_m
    ox, oy, oz = (np.repeat(a[:, None], k, axis=1) for a in (x, y, z))
    t_first = np.maximum((oz - z_high) / down, 0.0)  # the ray is above all ground before this
    t_last = np.maximum((oz - z_low) / down, t_first)
    horizontal = np.hypot(rays[..., 0], rays[..., 1])
    cell = dem.cell_size_m(frame)
    steps = int(min(2000, max(2, math.ceil(float(np.max((t_last - t_first) * horizontal)) / cell) + 1)))
    ox, oy, oz, dx, dy, dz = (a.ravel() for a in (ox, oy, oz, rays[..., 0], rays[..., 1], rays[..., 2]))
    t0, t1 = t_first.ravel(), t_last.ravel()

    def height_above_ground(t: NDArray[np.float64], idx: NDArray[np.intp]) -> NDArray[np.float64]:
        px, py = ox[idx] + t * dx[idx], oy[idx] + t * dy[idx]
        return np.asarray(oz[idx] + t * dz[idx] - dem.elevation_at(px, py, frame), float)

    all_idx = np.arange(ox.shape[0])
    lo = t0.copy()
    hi = t1.copy()
    found = np.zeros(ox.shape[0], bool)
    previous = t0.copy()
    for s in range(1, steps + 1):
        todo = np.flatnonzero(~found)
        if todo.size == 0:
            break
        t = t0[todo] + (t1[todo] - t0[todo]) * s / steps
        below = height_above_ground(t, todo) <= 0.0
        hit = todo[below]
        lo[hit], hi[hit] = previous[hit], t[below]
        found[hit] = True
        previous[todo] = t
    for _ in range(40):
        mid = (lo + hi) / 2.0
        above = height_above_ground(mid, all_idx) > 0.0
        lo = np.where(above, mid, lo)
        hi = np.where(above, hi, mid)
        if float(np.max(hi - lo)) < 1e-3:
            break
    t = (lo + hi) / 2.0
    out = np.stack([ox + t * dx, oy + t * dy, oz + t * dz], axis=-1)
    return out.reshape(n, k, 3)
