"""Ground footprints of frames: their corner and edge rays cast from each camera pose onto the ground.

World frame: the local frame's x east, y north (metres) and z up, in the frames' altitude
reference (:mod:`processing.ground` checks the ground is in the same one). Camera frame
(computer-vision convention, as :mod:`planner.footprint`): x to the image's right, y to the
image's bottom, z along the optical axis.

Attitude (:mod:`processing.frames`): ``yaw_deg`` is the bearing of the image top, ``pitch_deg``
tilts the optical axis off nadir toward the image top, ``roll_deg`` then turns the camera about
the image's vertical axis in the aircraft convention that Pix4D's XMP ``Camera:Roll`` and
``sfap geotag`` use: positive is right wing down, so a belly camera (image top toward the nose)
looks to the LEFT of the image (a 5 deg roll at 100 m puts the image centre 8.7 m to the left).
Equivalently, the world(NED)-from-body rotation is ``Rz(yaw) Ry(pitch) Rx(roll)`` with the
camera's x along the body's right wing, y toward the tail and z down. With roll 0 the rotation
is exactly :func:`planner.footprint.camera_axes`.

Each footprint is the ring of ground points of ``4 * (edge_samples + 1)`` rays around the sensor's
edge: the corners top-left, top-right, bottom-right, bottom-left, each followed by
``edge_samples`` points evenly along the edge to the next, so a footprint over relief has its real
shape. A frame some of whose rays do not reach the ground (at or above the horizon), or whose
camera is not above the ground, is flagged invalid with the reason; its ring collapses onto the
camera's nadir point (zero area, it counts nowhere) rather than holding NaN.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray

from planner.camera import Camera
from planner.geo import LocalFrame

from .errors import GroundError
from .frames import Frames
from .ground import DemGround, FlatGround, Ground, check_reference

logger = logging.getLogger(__name__)

F64 = NDArray[np.float64]

#: A ray counts as reaching the ground only when it points at least this much below the horizon
#: (the cosine of its angle from the vertical); grazing rays give footprints kilometres long.
_MIN_DOWN_COMPONENT = math.sin(math.radians(0.5))
#: Most march steps per ray over a DEM; the step grows beyond one DEM cell if needed.
_MAX_MARCH_STEPS = 4000
_BISECTION_STEPS = 48


def world_from_camera(yaw_deg: ArrayLike, pitch_deg: ArrayLike, roll_deg: ArrayLike) -> F64:
    """World(ENU)-from-camera rotation matrices, shape (N, 3, 3): columns are camera x, y, z in ENU.

    ``R = camera_axes(yaw, pitch) @ R_y(-roll)``: yaw and pitch as in
    :func:`planner.footprint.camera_axes`, then the aircraft's roll about its forward axis. The
    camera's y axis points to the image bottom (toward the tail), the opposite of the body's
    forward axis, hence the minus: a positive roll (right wing down) moves the optical axis
    toward the image's LEFT (module docstring).
    """
    yaw, pitch, roll = np.broadcast_arrays(
        np.atleast_1d(np.asarray(yaw_deg, float)),
        np.atleast_1d(np.asarray(pitch_deg, float)),
        np.atleast_1d(np.asarray(roll_deg, float)),
    )
    beta, tilt, phi = np.radians(yaw), np.radians(pitch), -np.radians(roll)
    sb, cb, st, ct = np.sin(beta), np.cos(beta), np.sin(tilt), np.cos(tilt)
    sr, cr = np.sin(phi), np.cos(phi)
    zeros = np.zeros_like(sb)
    x_axis = np.stack([cb, -sb, zeros], axis=-1)
    y_axis = np.stack([-ct * sb, -ct * cb, -st], axis=-1)
    z_axis = np.stack([st * sb, st * cb, -ct], axis=-1)
    x_rolled = cr[:, None] * x_axis - sr[:, None] * z_axis
    z_rolled = sr[:, None] * x_axis + cr[:, None] * z_axis
    return np.stack([x_rolled, y_axis, z_rolled], axis=-1)


def sensor_ring_mm(camera: Camera, edge_samples: int) -> F64:
    """Points around the sensor's edge in the camera frame (mm; z = focal length), (4*(e+1), 3)."""
    half_w, half_h = camera.sensor_width_mm / 2.0, camera.sensor_height_mm / 2.0
    corners = np.array([[-half_w, -half_h], [half_w, -half_h], [half_w, half_h], [-half_w, half_h]])
    fractions = np.arange(edge_samples + 1) / (edge_samples + 1)
    start = corners[:, None, :]
    end = np.roll(corners, -1, axis=0)[:, None, :]
    ring = (start + (end - start) * fractions[None, :, None]).reshape(-1, 2)
    return np.column_stack([ring, np.full(len(ring), camera.focal_length_mm)])


@dataclass(frozen=True, kw_only=True)
class Footprints:
    """Footprints of N frames, in the local frame (metres) the projection was done in.

    - ``xy_m``: (N, V, 2) ground rings, V = 4 * (edge_samples + 1) (module docstring).
    - ``camera_xyz_m``: (N, 3) camera x, y and altitude (the frames' reference).
    - ``principal_xyz_m``: (N, 3) where the optical axis meets the ground (the nadir point for a
      frame whose axis misses it).
    - ``ground_nadir_m``: (N,) ground elevation below each camera.
    - ``height_above_ground_m``: (N,) camera altitude minus the ground elevation below it.
    - ``gsd_cm``: (N,) GSD at the principal point, the coarser image axis projected onto a
      horizontal ground plane; NaN only where ``valid`` is False.
    - ``area_m2``: (N,) planimetric area of each ring (0 where invalid).
    - ``valid``: (N,) every ray reached the ground below a camera above it; ``reason`` says why not.
    - ``world_from_camera``: (N, 3, 3) rotations.
    """

    xy_m: F64
    camera_xyz_m: F64
    principal_xyz_m: F64
    ground_nadir_m: F64
    height_above_ground_m: F64
    gsd_cm: F64
    area_m2: F64
    valid: NDArray[np.bool_]
    reason: tuple[str, ...]
    world_from_camera: F64
    edge_samples: int
    ground_description: str

    def __post_init__(self) -> None:
        n = self.xy_m.shape[0]
        if self.xy_m.ndim != 3 or self.xy_m.shape[2] != 2:
            raise ValueError(f"Footprints.xy_m has shape {self.xy_m.shape}, expected (N, V, 2)")
        for key in ("ground_nadir_m", "height_above_ground_m", "gsd_cm", "area_m2", "valid"):
            if getattr(self, key).shape != (n,):
                raise ValueError(f"Footprints.{key} has shape {getattr(self, key).shape}, expected ({n},)")
        if len(self.reason) != n:
            raise ValueError(f"Footprints.reason has {len(self.reason)} entries, expected {n}")

    def __len__(self) -> int:
        return int(self.xy_m.shape[0])

    def polygons(self) -> NDArray[np.object_]:
        """Shapely polygons, one per frame (empty where invalid)."""
        polys = shapely.polygons(self.xy_m)
        return np.where(self.valid, polys, shapely.Polygon())


def _shoelace_m2(xy: F64) -> F64:
    # Relative to a vertex: with UTM coordinates (1e5-1e7 m) the shoelace would lose centimetres.
    local = xy - xy[..., :1, :]
    x, y = local[..., 0], local[..., 1]
    return 0.5 * np.abs(np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1))


def _flat_hits(origins: F64, rays: F64, elevation_m: float) -> F64:
    t = (origins[..., 2] - elevation_m) / (-rays[..., 2])
    return origins + rays * t[..., None]


def _dem_hits(
    origins: F64,
    rays: F64,
    dem: DemGround,
    frame: LocalFrame,
    owner: NDArray[np.intp],
    names: tuple[str, ...],
) -> F64:
    """First intersection of each ray (unit direction, pointing down) with the DEM surface.

    March from where the ray descends through the DEM's highest elevation to where it reaches the
    lowest (the crossing lies between) in steps of about one DEM cell horizontally, then bisect
    the first bracket where the ray goes below the surface.
    """
    z_lo, z_hi = dem.elevation_range_m
    down = -rays[:, 2]
    t_start = np.maximum(0.0, (origins[:, 2] - z_hi) / down)
    t_end = np.maximum(t_start, (origins[:, 2] - z_lo) / down)
    horizontal = np.hypot(rays[:, 0], rays[:, 1])
    step_m = dem.cell_size_m(frame)
    span = t_end - t_start
    dt = np.where(horizontal > 1e-12, step_m / np.maximum(horizontal, 1e-12), np.inf)
    dt = np.maximum(np.minimum(dt, span), span / _MAX_MARCH_STEPS)
    dt = np.where(dt > 0, dt, 1.0)

    def height_above_surface(index: NDArray[np.intp], t: F64) -> F64:
        points = origins[index] + rays[index] * t[:, None]
        ground, known = dem.sample(points[:, 0], points[:, 1], frame)
        if not known.all():
            bad = int(np.flatnonzero(~known)[0])
            lon, lat = frame.to_lonlat(points[bad, 0], points[bad, 1])
            raise GroundError(
                f"frame {names[owner[index[bad]]]!r}: its footprint reaches lon {float(lon):.6f}, "
                f"lat {float(lat):.6f}, outside DEM {dem.path.name} or on nodata; use a DEM that "
                f"covers the whole block with a margin, or flat ground"
            )
        return points[:, 2] - ground

    lower = t_start.copy()
    upper = t_end.copy()
    active = np.arange(len(rays))
    previous = t_start.copy()
    for k in range(1, _MAX_MARCH_STEPS + 2):
        if active.size == 0:
            break
        t = np.minimum(t_start[active] + k * dt[active], t_end[active])
        below = height_above_surface(active, t) <= 0.0
        # At t_end the ray is at the DEM's lowest elevation, so a bracket always closes there.
        below |= t >= t_end[active]
        done = active[below]
        lower[done] = previous[done]
        upper[done] = t[below]
        previous[active] = t
        active = active[~below]
    everything = np.arange(len(rays))
    for _ in range(_BISECTION_STEPS):
        middle = 0.5 * (lower + upper)
        below = height_above_surface(everything, middle) <= 0.0
        upper = np.where(below, middle, upper)
        lower = np.where(below, lower, middle)
        if np.max(upper - lower) < 1e-4:
            break
    t_hit = 0.5 * (lower + upper)
    return origins + rays * t_hit[:, None]


def project_footprints(
    frames: Frames, frame: LocalFrame, ground: Ground, *, edge_samples: int = 4
) -> Footprints:
    """Cast each frame's edge rays from its pose onto ``ground``; see :class:`Footprints`.

    Flat ground is intersected analytically; a :class:`~processing.ground.DemGround` by marching
    along each ray and bisecting (vectorized over all frames). Raises GroundError when the ground
    is in another vertical reference than the frames, or a ray leaves the DEM before meeting it.
    """
    if not (isinstance(edge_samples, int) and 0 <= edge_samples <= 64):
        raise ValueError(f"edge_samples = {edge_samples!r} must be an integer in 0..64")
    check_reference(ground, frames.alt_reference)
    n = len(frames)
    camera = frames.camera
    ring_cam = sensor_ring_mm(camera, edge_samples)  # (V, 3)
    n_vertices = ring_cam.shape[0]
    x, y = frame.to_xy(frames.lon_deg, frames.lat_deg)
    cam_xyz = np.column_stack([np.atleast_1d(x), np.atleast_1d(y), frames.alt_m.astype(float)])
    # Yaw is a true bearing; the frame's grid north is off true north by the meridian
    # convergence (up to 3 deg in a UTM zone), so turn each yaw into a grid bearing.
    grid_yaw = frames.yaw_deg + frame.true_north_grid_bearing_deg_array(frames.lon_deg, frames.lat_deg)
    rotation = world_from_camera(grid_yaw, frames.pitch_deg, frames.roll_deg)
    if n == 0:
        rotation = np.zeros((0, 3, 3))

    ground_nadir = ground.elevation_at(cam_xyz[:, 0], cam_xyz[:, 1], frame) if n else np.zeros(0)
    height = cam_xyz[:, 2] - ground_nadir

    # Rays: the ring, then the optical axis; unit length so t is a distance in metres.
    rays_cam = np.vstack([ring_cam, [[0.0, 0.0, camera.focal_length_mm]]])
    rays_cam = rays_cam / np.linalg.norm(rays_cam, axis=1, keepdims=True)
    rays = np.einsum("nij,vj->nvi", rotation, rays_cam)  # (N, V+1, 3)
    reaches = -rays[..., 2] >= _MIN_DOWN_COMPONENT  # (N, V+1)
    above = height > 0.0
    valid = reaches[:, :n_vertices].all(axis=1) & above
    axis_ok = reaches[:, n_vertices] & above

    reasons: list[str] = []
    off_nadir_deg = np.degrees(np.arccos(np.clip(-rotation[:, 2, 2], -1.0, 1.0))) if n else np.zeros(0)
    half_diag_deg = math.degrees(
        math.atan(math.hypot(camera.sensor_width_mm, camera.sensor_height_mm) / 2.0 / camera.focal_length_mm)
    )
    for i in range(n):
        if not above[i]:
            reasons.append(
                f"camera {height[i]:.1f} m above the ground ({ground.description}): at or below it; "
                f"check the altitude reference and the ground elevation"
            )
        elif not valid[i]:
            reasons.append(
                f"optical axis {off_nadir_deg[i]:.1f} deg off nadir with half a diagonal field of view "
                f"of {half_diag_deg:.1f} deg: part of the frame looks at or above the horizon"
            )
        else:
            reasons.append("")

    hit_ok = np.concatenate([np.broadcast_to(valid[:, None], (n, n_vertices)), axis_ok[:, None]], axis=1)
    origins = np.broadcast_to(cam_xyz[:, None, :], rays.shape)
    if isinstance(ground, FlatGround):
        safe_rays = np.where(hit_ok[..., None], rays, np.array([0.0, 0.0, -1.0]))
        hits = _flat_hits(origins, safe_rays, float(ground.elevation_m))
    elif isinstance(ground, DemGround):
        owner = np.broadcast_to(np.arange(n)[:, None], hit_ok.shape)[hit_ok]
        hits = np.array(origins)
        if hit_ok.any():
            hits[hit_ok] = _dem_hits(origins[hit_ok], rays[hit_ok], ground, frame, owner, frames.name)
    else:
        raise GroundError(f"unsupported ground model {type(ground).__name__}; use FlatGround or DemGround")

    nadir = np.column_stack([cam_xyz[:, :2], ground_nadir])
    xy = np.where(valid[:, None, None], hits[:, :n_vertices, :2], nadir[:, None, :2])
    principal = np.where(axis_ok[:, None], hits[:, n_vertices, :], nadir)

    # GSD at the principal point: a pixel step along each image axis, moved along the ray onto a
    # horizontal plane through the hit point (planner.footprint.tilted_gsd_cm at the centre row).
    axis = rotation[:, :, 2]
    slant = np.linalg.norm(principal - cam_xyz, axis=1)
    dz = np.where(axis_ok, axis[:, 2], -1.0)
    pitches = (camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm)
    per_axis = []
    for column, pitch in zip((0, 1), pitches, strict=True):
        a = rotation[:, :, column]
        projected = a - axis * (a[:, 2] / dz)[:, None]
        per_axis.append(100.0 * pitch * slant / camera.focal_length_mm * np.linalg.norm(projected, axis=1))
    gsd = np.where(axis_ok, np.maximum(per_axis[0], per_axis[1]), np.nan)

    area = np.where(valid, _shoelace_m2(xy), 0.0)
    if n and not valid.all():
        logger.warning(
            "%d of %d frames have no complete footprint: %s",
            int((~valid).sum()),
            n,
            next(r for r in reasons if r),
        )
    return Footprints(
        xy_m=xy,
        camera_xyz_m=cam_xyz,
        principal_xyz_m=principal,
        ground_nadir_m=ground_nadir,
        height_above_ground_m=height,
        gsd_cm=gsd,
        area_m2=area,
        valid=valid,
        reason=tuple(reasons),
        world_from_camera=rotation,
        edge_samples=edge_samples,
        ground_description=ground.description,
    )
