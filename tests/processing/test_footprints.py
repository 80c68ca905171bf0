"""Footprints: rotations against planner.footprint, tilted-frame textbook geometry, DEM ray casting."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import rasterio
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import CRS
from rasterio.transform import Affine

from planner.camera import Camera, Orientation
from planner.camera_db import get_camera
from planner.footprint import camera_axes, footprint_corners, tilted_gsd_cm
from planner.geo import LocalFrame
from processing.errors import GroundError
from processing.footprints import project_footprints, world_from_camera
from processing.frames import AltitudeReference, AttitudeSource, Frames
from processing.ground import DemGround, FlatGround

# DJI Phantom 4 Pro: 13.2 x 8.8 mm, 5472 x 3648 px, 8.8 mm (2.41 um pitch).
CAMERA = Camera(
    id="p4p",
    name="Phantom 4 Pro",
    sensor_width_mm=13.2,
    sensor_height_mm=8.8,
    image_width_px=5472,
    image_height_px=3648,
    focal_length_mm=8.8,
)
FRAME = LocalFrame.from_crs(CRS.from_epsg(32613))  # UTM 13N
ORIGIN_X_M, ORIGIN_Y_M = 500_000.0, 4_400_000.0


def make_frames(
    x_m: np.ndarray | float,
    y_m: np.ndarray | float,
    alt_m: np.ndarray | float,
    yaw_deg: np.ndarray | float = 0.0,
    pitch_deg: np.ndarray | float = 0.0,
    roll_deg: np.ndarray | float = 0.0,
    reference: AltitudeReference = AltitudeReference.AMSL,
) -> Frames:
    x, y = np.atleast_1d(np.asarray(x_m, float)), np.atleast_1d(np.asarray(y_m, float))
    n = x.size
    lon, lat = FRAME.to_lonlat(x, y)

    def column(v: np.ndarray | float) -> np.ndarray:
        return np.broadcast_to(np.asarray(v, float), (n,)).copy()

    return Frames(
        name=tuple(f"IMG_{k:04d}.JPG" for k in range(n)),
        lon_deg=np.atleast_1d(lon),
        lat_deg=np.atleast_1d(lat),
        alt_m=column(alt_m),
        alt_reference=reference,
        yaw_deg=column(yaw_deg),
        pitch_deg=column(pitch_deg),
        roll_deg=column(roll_deg),
        attitude_source=AttitudeSource.PLAN,
        camera=CAMERA,
    )


def write_dem(
    path: Path,
    elevation: np.ndarray,
    west: float,
    north: float,
    cell: float,
    crs: str,
    nodata: float | None = None,
) -> Path:
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=elevation.shape[1],
        height=elevation.shape[0],
        count=1,
        dtype="float32",
        crs=crs,
        transform=Affine(cell, 0.0, west, 0.0, -cell, north),
        nodata=nodata,
    ) as dst:
        dst.write(elevation.astype(np.float32), 1)
    return path


# --- rotations ---------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(yaw=st.floats(-360, 360), pitch=st.floats(-89, 89))
def test_rotation_equals_planner_camera_axes_without_roll(yaw: float, pitch: float) -> None:
    np.testing.assert_allclose(world_from_camera(yaw, pitch, 0.0), camera_axes(yaw, pitch), atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(yaw=st.floats(-360, 360), pitch=st.floats(-89, 89), roll=st.floats(-89, 89))
def test_rotation_is_proper_and_roll_turns_about_image_vertical(
    yaw: float, pitch: float, roll: float
) -> None:
    r = world_from_camera(yaw, pitch, roll)[0]
    np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-12)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-12)
    base = camera_axes(yaw, pitch)[0]
    # The image's vertical axis (camera y) does not move under roll; the optical axis turns by roll.
    np.testing.assert_allclose(r[:, 1], base[:, 1], atol=1e-12)
    assert float(r[:, 2] @ base[:, 2]) == pytest.approx(math.cos(math.radians(roll)), abs=1e-12)


def _oracle_world_from_camera(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """ENU-from-camera written from the convention's definition, independently of the code.

    Pix4D's Yaw/Pitch/Roll (and sfap geotag's XMP) are the aircraft's Tait-Bryan angles:
    NED-from-body = Rz(yaw) Ry(pitch) Rx(roll), body x to the nose, y to the right wing, z down;
    the camera looks down the body z axis with the image top toward the nose, so the camera's
    x (image right) is the body's y, its y (image bottom) is minus the body's x.
    """
    y, p, r = (math.radians(v) for v in (yaw_deg, pitch_deg, roll_deg))
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    body_from_camera = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    enu_from_ned = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    return enu_from_ned @ rz @ ry @ rx @ body_from_camera


def _oracle_ground_points(
    yaw_deg: float, pitch_deg: float, roll_deg: float, height_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Corners (TL, TR, BR, BL) and principal point on flat ground, relative to the nadir point."""
    r = _oracle_world_from_camera(yaw_deg, pitch_deg, roll_deg)
    w, h, f = CAMERA.sensor_width_mm / 2, CAMERA.sensor_height_mm / 2, CAMERA.focal_length_mm
    rays = np.array([[-w, -h, f], [w, -h, f], [w, h, f], [-w, h, f], [0.0, 0.0, f]]) @ r.T
    points = rays * (height_m / -rays[:, 2])[:, None]
    return points[:4, :2], points[4, :2]


def test_positive_roll_is_right_wing_down_and_looks_left() -> None:
    # A 5 deg roll at 100 m: the image centre lands 100 tan 5 = 8.75 m to the LEFT of the track.
    ground = FlatGround(elevation_m=0.0, reference=AltitudeReference.AMSL)
    for yaw, left in ((0.0, (-1.0, 0.0)), (90.0, (0.0, 1.0)), (180.0, (1.0, 0.0))):
        fp = project_footprints(make_frames(ORIGIN_X_M, ORIGIN_Y_M, 100.0, yaw, 0.0, 5.0), FRAME, ground)
        offset = fp.principal_xyz_m[0, :2] - [ORIGIN_X_M, ORIGIN_Y_M]
        expected = 100.0 * math.tan(math.radians(5.0)) * np.array(left)
        np.testing.assert_allclose(offset, expected, atol=1e-6)


@settings(max_examples=150, deadline=None)
@given(
    yaw=st.floats(0, 360),
    pitch=st.floats(-30, 30),
    roll=st.floats(-30, 30),
    height=st.floats(20, 400),
)
def test_footprints_agree_with_an_independent_ray_cast(
    yaw: float, pitch: float, roll: float, height: float
) -> None:
    fp = project_footprints(
        make_frames(ORIGIN_X_M, ORIGIN_Y_M, 200.0 + height, yaw, pitch, roll),
        FRAME,
        FlatGround(elevation_m=200.0, reference=AltitudeReference.AMSL),
        edge_samples=0,
    )
    corners, principal = _oracle_ground_points(yaw, pitch, roll, height)
    origin = np.array([ORIGIN_X_M, ORIGIN_Y_M])
    np.testing.assert_allclose(fp.xy_m[0] - origin, corners, atol=0.01)
    np.testing.assert_allclose(fp.principal_xyz_m[0, :2] - origin, principal, atol=0.01)


# --- flat ground -------------------------------------------------------------------------------


def test_nadir_footprint_is_the_textbook_rectangle() -> None:
    height = 100.0
    fp = project_footprints(
        make_frames(ORIGIN_X_M, ORIGIN_Y_M, 1600.0 + height),
        FRAME,
        FlatGround(elevation_m=1600.0, reference=AltitudeReference.AMSL),
    )
    scale = height * 1000.0 / CAMERA.focal_length_mm  # Eq. 3-1: scale number
    across = CAMERA.sensor_width_mm / 1000.0 * scale
    along = CAMERA.sensor_height_mm / 1000.0 * scale
    ring = fp.xy_m[0] - [ORIGIN_X_M, ORIGIN_Y_M]
    assert ring.shape == (20, 2)
    np.testing.assert_allclose(ring[0], [-across / 2, along / 2], atol=1e-6)  # top-left is north-west
    np.testing.assert_allclose(ring[10], [across / 2, -along / 2], atol=1e-6)
    assert fp.area_m2[0] == pytest.approx(across * along, rel=1e-9)  # Eq. 3-3
    assert fp.gsd_cm[0] == pytest.approx(CAMERA.gsd_cm(height), rel=1e-12)  # Eq. 3-4
    assert fp.height_above_ground_m[0] == pytest.approx(height)
    assert fp.valid[0] and fp.reason[0] == ""


@settings(max_examples=60, deadline=None)
@given(
    yaw=st.floats(0, 360),
    pitch=st.floats(0, 45),
    height=st.floats(20, 400),
    dx=st.floats(-500, 500),
    dy=st.floats(-500, 500),
)
def test_corners_match_planner_footprint_corners(
    yaw: float, pitch: float, height: float, dx: float, dy: float
) -> None:
    x, y = ORIGIN_X_M + dx, ORIGIN_Y_M + dy
    frames = make_frames(x, y, height, yaw, pitch, reference=AltitudeReference.REL_HOME)
    fp = project_footprints(
        frames, FRAME, FlatGround(elevation_m=0.0, reference=AltitudeReference.REL_HOME), edge_samples=3
    )
    # The frame's local position went through lon/lat and back: compare in that position.
    cx, cy = fp.camera_xyz_m[0, :2]
    # yaw is a true bearing; the planner's function takes a grid bearing
    grid_yaw = yaw + FRAME.true_north_grid_bearing_deg(float(frames.lon_deg[0]), float(frames.lat_deg[0]))
    expected = footprint_corners(CAMERA, cx, cy, height, grid_yaw, pitch)[0]
    np.testing.assert_allclose(fp.xy_m[0, ::4], expected, atol=1e-6 * height)
    # Edge samples lie on the straight edges between the corners (flat ground).
    ring = fp.xy_m[0]
    for k in range(4):
        a, b = expected[k], expected[(k + 1) % 4]
        for s in range(1, 4):
            p = ring[4 * k + s]
            cross = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
            assert abs(cross) / np.hypot(*(b - a)) < 1e-6 * height
    radial, lateral = tilted_gsd_cm(CAMERA, height, pitch)
    assert fp.gsd_cm[0] == pytest.approx(max(radial, lateral), rel=1e-9)


def test_tilted_frame_is_the_textbook_trapezoid() -> None:
    """Looking north, tilt t, half field of view a along the image height: the near and far edges
    lie at H tan(t - a) and H tan(t + a) ahead, widths w H cos(a) / (f cos(t -+ a))."""
    height, tilt = 120.0, 30.0
    fp = project_footprints(
        make_frames(ORIGIN_X_M, ORIGIN_Y_M, height, 0.0, tilt, reference=AltitudeReference.REL_HOME),
        FRAME,
        FlatGround(elevation_m=0.0, reference=AltitudeReference.REL_HOME),
        edge_samples=0,
    )
    ring = fp.xy_m[0] - fp.camera_xyz_m[0, :2]
    top_left, top_right, bottom_right, bottom_left = ring
    t, a = math.radians(tilt), math.atan(CAMERA.sensor_height_mm / 2 / CAMERA.focal_length_mm)
    f, w = CAMERA.focal_length_mm, CAMERA.sensor_width_mm
    assert top_left[1] == pytest.approx(height * math.tan(t + a), rel=1e-9)
    assert bottom_left[1] == pytest.approx(height * math.tan(t - a), rel=1e-9)
    far_width = w * height * math.cos(a) / (f * math.cos(t + a))
    near_width = w * height * math.cos(a) / (f * math.cos(t - a))
    assert top_right[0] - top_left[0] == pytest.approx(far_width, rel=1e-9)
    assert bottom_right[0] - bottom_left[0] == pytest.approx(near_width, rel=1e-9)
    assert far_width > near_width  # a trapezoid, wide side away from the camera
    # Principal point at H tan t ahead (planner.footprint.principal_point_offset_m).
    assert fp.principal_xyz_m[0, 1] - fp.camera_xyz_m[0, 1] == pytest.approx(height * math.tan(t), rel=1e-9)


def test_frame_looking_above_the_horizon_is_flagged_not_nan() -> None:
    frames = make_frames(
        np.array([ORIGIN_X_M, ORIGIN_X_M + 50]),
        np.array([ORIGIN_Y_M] * 2),
        100.0,
        0.0,
        np.array([0.0, 75.0]),
        reference=AltitudeReference.REL_HOME,
    )
    fp = project_footprints(frames, FRAME, FlatGround(elevation_m=0.0, reference=AltitudeReference.REL_HOME))
    assert fp.valid.tolist() == [True, False]
    assert "horizon" in fp.reason[1]
    assert np.isfinite(fp.xy_m).all()
    assert fp.area_m2[1] == 0.0
    assert fp.polygons()[1].is_empty
    # The optical axis (75 deg) still reaches the ground: its GSD is known.
    assert np.isfinite(fp.gsd_cm[1])


def test_camera_below_the_ground_is_flagged_with_the_reason() -> None:
    frames = make_frames(ORIGIN_X_M, ORIGIN_Y_M, 1500.0)
    fp = project_footprints(frames, FRAME, FlatGround(elevation_m=1600.0, reference=AltitudeReference.AMSL))
    assert not fp.valid[0]
    assert "below" in fp.reason[0] and "-100.0 m" in fp.reason[0]


def test_ground_in_another_reference_is_refused() -> None:
    frames = make_frames(ORIGIN_X_M, ORIGIN_Y_M, 100.0, reference=AltitudeReference.REL_HOME)
    with pytest.raises(GroundError, match=r"rel_home.*amsl"):
        project_footprints(frames, FRAME, FlatGround(elevation_m=1600.0, reference=AltitudeReference.AMSL))


def test_five_thousand_random_frames_all_project_on_flat_ground() -> None:
    rng = np.random.default_rng(5)
    n = 5000
    frames = make_frames(
        ORIGIN_X_M + rng.uniform(0, 1500, n),
        ORIGIN_Y_M + rng.uniform(0, 1500, n),
        rng.uniform(60, 120, n),
        rng.uniform(0, 360, n),
        rng.uniform(0, 20, n),
        rng.uniform(-5, 5, n),
        reference=AltitudeReference.REL_HOME,
    )
    ground = FlatGround(elevation_m=0.0, reference=AltitudeReference.REL_HOME)
    fp = project_footprints(frames, FRAME, ground)
    assert fp.valid.all()


# --- DEM ---------------------------------------------------------------------------------------


def test_constant_dem_gives_the_flat_ground_footprints(tmp_path: Path) -> None:
    elevation = np.full((200, 200), 1650.0)
    dem = DemGround.from_geotiff(
        write_dem(tmp_path / "flat.tif", elevation, ORIGIN_X_M - 500, ORIGIN_Y_M + 500, 5.0, "EPSG:32613")
    )
    frames = make_frames(
        np.array([ORIGIN_X_M, ORIGIN_X_M + 40]),
        np.array([ORIGIN_Y_M, ORIGIN_Y_M - 30]),
        np.array([1750.0, 1770.0]),
        np.array([10.0, 250.0]),
        np.array([0.0, 25.0]),
        np.array([0.0, 8.0]),
    )
    on_dem = project_footprints(frames, FRAME, dem)
    flat = project_footprints(frames, FRAME, FlatGround(elevation_m=1650.0, reference=AltitudeReference.AMSL))
    np.testing.assert_allclose(on_dem.xy_m, flat.xy_m, atol=1e-3)
    np.testing.assert_allclose(on_dem.gsd_cm, flat.gsd_cm, rtol=1e-6)
    assert "flat.tif" in dem.description and "amsl" in dem.description


def test_sloping_dem_matches_the_analytic_ray_plane_intersection(tmp_path: Path) -> None:
    # z = 1600 + 0.2 (x - x0) - 0.1 (y - y0): bilinear interpolation of a plane is the plane.
    cell = 2.0
    west, north = ORIGIN_X_M - 400, ORIGIN_Y_M + 400
    cols = rows = 400
    xc = west + (np.arange(cols) + 0.5) * cell
    yc = north - (np.arange(rows) + 0.5) * cell
    elevation = 1600.0 + 0.2 * (xc[None, :] - ORIGIN_X_M) - 0.1 * (yc[:, None] - ORIGIN_Y_M)
    dem = DemGround.from_geotiff(
        write_dem(tmp_path / "slope.tif", elevation, west, north, cell, "EPSG:32613")
    )
    frames = make_frames(ORIGIN_X_M + 20, ORIGIN_Y_M - 10, 1720.0, 35.0, 20.0, -6.0)
    fp = project_footprints(frames, FRAME, dem, edge_samples=2)
    cam = fp.camera_xyz_m[0]
    normal = np.array([0.2, -0.1, -1.0])
    plane_point = np.array([ORIGIN_X_M, ORIGIN_Y_M, 1600.0])
    from processing.footprints import sensor_ring_mm

    rays = (fp.world_from_camera[0] @ sensor_ring_mm(CAMERA, 2).T).T
    t = ((plane_point - cam) @ normal) / (rays @ normal)
    expected = cam + rays * t[:, None]
    np.testing.assert_allclose(fp.xy_m[0], expected[:, :2], atol=2e-3)
    # The height above ground is measured at the nadir point on the slope.
    ground_below = 1600.0 + 0.2 * (cam[0] - ORIGIN_X_M) - 0.1 * (cam[1] - ORIGIN_Y_M)
    assert fp.height_above_ground_m[0] == pytest.approx(1720.0 - ground_below, abs=1e-4)


def gaussian_hill(
    west: float, north: float, cell: float, size: int, peak_m: float, sigma_m: float
) -> np.ndarray:
    xc = west + (np.arange(size) + 0.5) * cell - ORIGIN_X_M
    yc = north - (np.arange(size) + 0.5) * cell - ORIGIN_Y_M
    r2 = xc[None, :] ** 2 + yc[:, None] ** 2
    return 1600.0 + peak_m * np.exp(-r2 / (2 * sigma_m**2))


def test_footprint_shrinks_and_gsd_gets_finer_over_a_hill(tmp_path: Path) -> None:
    """Higher ground is closer to the camera: smaller footprint, finer GSD (Aber et al. ch. 3)."""
    cell, size = 2.0, 800
    west, north = ORIGIN_X_M - 800, ORIGIN_Y_M + 800
    elevation = gaussian_hill(west, north, cell, size, peak_m=40.0, sigma_m=250.0)
    dem = DemGround.from_geotiff(write_dem(tmp_path / "hill.tif", elevation, west, north, cell, "EPSG:32613"))
    # One frame over the summit, one over the plain far from it; both 140 m above 1600 m.
    frames = make_frames(np.array([ORIGIN_X_M, ORIGIN_X_M + 600]), np.array([ORIGIN_Y_M, ORIGIN_Y_M]), 1740.0)
    fp = project_footprints(frames, FRAME, dem)
    summit, plain = 0, 1
    assert fp.height_above_ground_m[summit] == pytest.approx(100.0, abs=0.05)
    plain_ground = 1600.0 + 40.0 * math.exp(-(600.0**2) / (2 * 250.0**2))
    assert fp.height_above_ground_m[plain] == pytest.approx(1740.0 - plain_ground, abs=0.01)
    assert fp.gsd_cm[summit] == pytest.approx(CAMERA.gsd_cm(100.0), rel=1e-3)
    assert fp.gsd_cm[summit] < fp.gsd_cm[plain]
    # Over the summit the ground falls away toward the corners: the footprint lies between the
    # flat-ground ones at the summit's height (100 m) and the plain's (140 m).
    flat_at = {h: CAMERA.footprint(h, Orientation.LANDSCAPE).area_m2 for h in (100.0, 140.0)}
    assert fp.area_m2[summit] < fp.area_m2[plain]
    assert flat_at[100.0] < fp.area_m2[summit] < flat_at[140.0]
    # The top edge bows toward the camera: its middle meets higher ground than its corners.
    ring = fp.xy_m[summit]
    corner_line_y = 0.5 * (ring[0, 1] + ring[5, 1])
    assert ring[2, 1] < corner_line_y - 0.1


def test_dem_in_geographic_crs_gives_the_same_footprint(tmp_path: Path) -> None:
    cell, size = 2.0, 800
    west, north = ORIGIN_X_M - 800, ORIGIN_Y_M + 800
    elevation = gaussian_hill(west, north, cell, size, peak_m=40.0, sigma_m=250.0)
    utm = DemGround.from_geotiff(write_dem(tmp_path / "hill.tif", elevation, west, north, cell, "EPSG:32613"))
    # The same hill on a lon/lat grid (about 1.5 m cells), sampled from the analytic surface.
    lon0, lat0 = FRAME.to_lonlat(west, north)
    lon1, lat1 = FRAME.to_lonlat(west + size * cell, north - size * cell)
    dlon, dlat = (float(lon1) - float(lon0)) / 1100, (float(lat0) - float(lat1)) / 1100
    lon_c = float(lon0) + (np.arange(1100) + 0.5) * dlon
    lat_c = float(lat0) - (np.arange(1100) + 0.5) * dlat
    lon_g, lat_g = np.meshgrid(lon_c, lat_c)
    gx, gy = FRAME.to_xy(lon_g, lat_g)
    geo_elev = 1600.0 + 40.0 * np.exp(-((gx - ORIGIN_X_M) ** 2 + (gy - ORIGIN_Y_M) ** 2) / (2 * 250.0**2))
    path = tmp_path / "hill_lonlat.tif"
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=1100,
        height=1100,
        count=1,
        dtype="float64",
        crs="EPSG:4326",
        transform=Affine(dlon, 0.0, float(lon0), 0.0, -dlat, float(lat0)),
    ) as dst:
        dst.write(geo_elev, 1)
    geo = DemGround.from_geotiff(path)
    frames = make_frames(np.array([ORIGIN_X_M + 30]), np.array([ORIGIN_Y_M - 60]), 1740.0, 20.0, 15.0)
    a = project_footprints(frames, FRAME, utm)
    b = project_footprints(frames, FRAME, geo)
    # Both are bilinear samples of the same smooth surface: they agree to centimetres.
    np.testing.assert_allclose(a.xy_m, b.xy_m, atol=0.05)
    assert a.height_above_ground_m[0] == pytest.approx(b.height_above_ground_m[0], abs=0.01)


def test_footprint_leaving_the_dem_names_the_frame(tmp_path: Path) -> None:
    elevation = np.full((50, 50), 1600.0)
    elevation[:, 45:] = -9999.0
    dem = DemGround.from_geotiff(
        write_dem(
            tmp_path / "small.tif",
            elevation,
            ORIGIN_X_M - 100,
            ORIGIN_Y_M + 100,
            4.0,
            "EPSG:32613",
            nodata=-9999.0,
        )
    )
    inside = make_frames(ORIGIN_X_M - 60, ORIGIN_Y_M, 1620.0)
    assert project_footprints(inside, FRAME, dem).valid.all()
    frames = make_frames(np.array([ORIGIN_X_M - 60, ORIGIN_X_M + 60]), np.array([ORIGIN_Y_M] * 2), 1700.0)
    with pytest.raises(GroundError, match=r"IMG_000[01]\.JPG.*outside DEM small\.tif or on nodata"):
        project_footprints(frames, FRAME, dem)
    with pytest.raises(GroundError, match="no elevation at lon"):
        dem.elevation_at(np.array([ORIGIN_X_M + 90]), np.array([ORIGIN_Y_M]), FRAME)


def test_flat_ground_refuses_nonsense() -> None:
    with pytest.raises(GroundError, match="elevation_m"):
        FlatGround(elevation_m=float("nan"), reference=AltitudeReference.AMSL)
    with pytest.raises(GroundError, match="not one of"):
        FlatGround(elevation_m=0.0, reference="feet")  # type: ignore[arg-type]
    assert FlatGround(elevation_m=12.5, reference="amsl", source="take-off point").description == (  # type: ignore[arg-type]
        "flat ground at 12.50 m (amsl), take-off point"
    )


def test_a_window_of_a_large_dem_samples_the_same_elevations(tmp_path: Path) -> None:
    cell, size = 2.0, 800
    west, north = ORIGIN_X_M - 800, ORIGIN_Y_M + 800
    path = write_dem(tmp_path / "hill.tif", gaussian_hill(west, north, cell, size, 40.0, 250.0), west, north,
                     cell, "EPSG:32613")  # fmt: skip
    whole = DemGround.from_geotiff(path)
    lon0, lat0 = FRAME.to_lonlat(ORIGIN_X_M - 150, ORIGIN_Y_M - 100)
    lon1, lat1 = FRAME.to_lonlat(ORIGIN_X_M + 150, ORIGIN_Y_M + 100)
    part = DemGround.from_geotiff(path, bounds_lonlat=(float(lon0), float(lat0), float(lon1), float(lat1)))
    assert part.elevation.size < whole.elevation.size / 20
    x = ORIGIN_X_M + np.linspace(-150, 150, 31)
    y = ORIGIN_Y_M + np.linspace(-100, 100, 31)
    np.testing.assert_allclose(part.elevation_at(x, y, FRAME), whole.elevation_at(x, y, FRAME), atol=1e-9)
    far_lon, far_lat = FRAME.to_lonlat(ORIGIN_X_M + 5000, ORIGIN_Y_M)
    with pytest.raises(GroundError, match="does not cover"):
        DemGround.from_geotiff(path, bounds_lonlat=(float(far_lon), float(far_lat), float(far_lon) + 0.01,
                                                    float(far_lat) + 0.01))  # fmt: skip


def test_an_integer_dem_with_nodata_reads(tmp_path: Path) -> None:
    """SRTM tiles are int16 with nodata -32768."""
    elevation = np.full((60, 60), 1600, dtype=np.int16)
    elevation[:5, :5] = -32768
    path = tmp_path / "srtm.tif"
    with rasterio.open(
        path, "w", driver="GTiff", width=60, height=60, count=1, dtype="int16", crs="EPSG:32613",
        transform=Affine(5.0, 0.0, ORIGIN_X_M - 150, 0.0, -5.0, ORIGIN_Y_M + 150), nodata=-32768,
    ) as dst:  # fmt: skip
        dst.write(elevation, 1)
    dem = DemGround.from_geotiff(path)
    assert int(dem.valid.sum()) == 60 * 60 - 25
    assert dem.elevation_range_m == (1600.0, 1600.0)
    fp = project_footprints(make_frames(ORIGIN_X_M, ORIGIN_Y_M, 1700.0), FRAME, dem)
    assert fp.height_above_ground_m[0] == pytest.approx(100.0)


def test_yaw_is_a_true_bearing_in_any_grid() -> None:
    """A frame whose image top points true north has a footprint whose top edge is square to
    the meridian, whether the local frame is a UTM zone (grid north off true north) or not."""
    lon, lat = -1.0, 42.0  # 2 deg west of UTM 30N's central meridian: about 1.3 deg convergence
    camera = get_camera("dji-phantom-4-pro")
    frames = Frames(
        name=("a",),
        lon_deg=np.array([lon]),
        lat_deg=np.array([lat]),
        alt_m=np.array([100.0]),
        alt_reference=AltitudeReference.AGL,
        yaw_deg=np.array([0.0]),
        pitch_deg=np.array([0.0]),
        roll_deg=np.array([0.0]),
        attitude_source=AttitudeSource.XMP,
        camera=camera,
    )
    utm = LocalFrame.utm_for(lon, lat)
    assert abs(utm.true_north_grid_bearing_deg(lon, lat)) > 1.0
    fp = project_footprints(frames, utm, FlatGround(elevation_m=0.0, reference="agl"), edge_samples=0)
    ring = fp.xy_m[0]
    clon, clat = utm.to_lonlat(ring[:, 0], ring[:, 1])
    # top-left and top-right corners (image top = north) lie on one parallel
    assert clat[0] == pytest.approx(clat[1], abs=1e-8)
    assert clon[1] > clon[0]
