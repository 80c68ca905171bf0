"""Exposure geometry against the textbook (Aber et al. 2019, Eq. 3-1 to 3-6) and QGC's formulas."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from planner import exposure as ex
from planner.camera import Camera, Orientation
from planner.camera_db import get_camera, load_cameras
from planner.errors import SpecError
from planner.footprint import footprint_corners, near_far_gsd_cm, tilted_gsd_cm

CANON = get_camera("canon-eos-350d-20mm")


def test_textbook_gsd_at_75_6_m() -> None:
    # 22.2 mm / 3456 px = 6.42 um; x 75.6 m / 20 mm = 2.43 cm (the book rounds the pitch to
    # 6.4 um and quotes about 2.42 cm)
    assert CANON.gsd_cm(75.6) == pytest.approx(2.42, abs=0.01)
    assert CANON.scale_number(75.6) == pytest.approx(3780.0)  # Eq. 3-1: 75.6 m / 20 mm


def test_textbook_air_base_and_interval_by_hand() -> None:
    height = 75.6
    # frame along track (landscape: image height) = 2304 px x GSD_y
    along = 2304 * (14.8 / 2304) * height / 20.0  # = 14.8 mm x scale = 55.944 m
    fp = CANON.footprint(height, Orientation.LANDSCAPE)
    assert fp.along_m == pytest.approx(along)
    assert fp.across_m == pytest.approx(22.2 * height / 20.0)
    # Eq. 3-3: A = (dL x dW) s^2
    assert fp.area_m2 == pytest.approx(22.2e-3 * 14.8e-3 * (height / 0.020) ** 2)
    b = ex.air_base_m(fp.along_m, 60.0)  # Eq. 3-5 with 60 % endlap
    assert b == pytest.approx(55.944 * 0.4)
    assert ex.exposure_interval_s(b, 8.0) == pytest.approx(55.944 * 0.4 / 8.0)  # Eq. 3-6
    assert ex.base_height_ratio(b, height) == pytest.approx(0.296, abs=1e-3)
    # intersection angle: the angle between the rays of the two cameras to the ground point midway
    ray_a, ray_b = np.array([b / 2, -height]), np.array([-b / 2, -height])
    cos_angle = ray_a @ ray_b / (np.linalg.norm(ray_a) * np.linalg.norm(ray_b))
    assert ex.intersection_angle_deg(b, height) == pytest.approx(math.degrees(math.acos(cos_angle)))


@pytest.mark.parametrize(
    "camera", [c for c in load_cameras().values() if c.pitch_is_square], ids=lambda c: c.id
)
def test_qgc_formulas_exact_for_square_pitch(camera: Camera) -> None:
    # QGC CameraCalc: GSD = 100 H sw / (iw f); H = GSD iw f / (100 sw); footprints from that GSD
    height = 87.3
    qgc_gsd = 100.0 * height * camera.sensor_width_mm / (camera.image_width_px * camera.focal_length_mm)
    assert camera.gsd_x_cm(height) == pytest.approx(qgc_gsd, rel=1e-12)
    qgc_height = qgc_gsd * camera.image_width_px * camera.focal_length_mm / (100.0 * camera.sensor_width_mm)
    assert camera.height_for_gsd_m(camera.gsd_x_cm(height)) == pytest.approx(
        qgc_height,
        rel=2e-3
        if not math.isclose(camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm, rel_tol=1e-12)
        else 1e-12,
    )
    fp = camera.footprint(height, Orientation.LANDSCAPE)
    assert fp.across_m == pytest.approx(camera.image_width_px * qgc_gsd / 100.0, rel=1e-12)
    assert fp.along_m == pytest.approx(camera.image_height_px * qgc_gsd / 100.0, rel=3e-3)
    # QGC: line spacing = across (1 - side), trigger = along (1 - front)
    assert ex.air_base_m(fp.across_m, 70.0) == pytest.approx(fp.across_m * 0.3)


def test_non_square_pitch_uses_both_axes() -> None:
    cam = Camera(
        id="anamorphic", name="x", sensor_width_mm=12.0, sensor_height_mm=9.0,
        image_width_px=4000, image_height_px=2000, focal_length_mm=10.0,
    )  # fmt: skip
    # pitch x 3.0 um, y 4.5 um: QGC would give the along-track footprint from the x pitch
    fp = cam.footprint(100.0, Orientation.LANDSCAPE)
    assert fp.along_m == pytest.approx(90.0)  # 9 mm sensor height x 100 m / 10 mm
    assert fp.across_m == pytest.approx(120.0)
    assert cam.gsd_cm(100.0) == pytest.approx(4.5)  # the coarser axis is guaranteed
    assert cam.height_for_gsd_m(4.5) == pytest.approx(100.0)


def test_speed_limits() -> None:
    assert ex.max_speed_for_trigger_m_s(20.0, 2.0) == pytest.approx(10.0)
    # half a pixel of 2 cm at 1/1000 s: 0.01 m / 0.001 s = 10 m/s
    assert ex.max_speed_for_blur_m_s(2.0, 0.001, 0.5) == pytest.approx(10.0)


def test_depth_precision_by_triangulation() -> None:
    # Two nadir cameras b apart at height h see a ground point between them; half a pixel of error
    # in one image (along the base: image y for a landscape frame) moves the intersection of the
    # two rays by sigma_Z in depth.
    b, h = 20.0, 100.0
    f = CANON.focal_length_mm / 1000
    c1, c2, point = np.array([0.0, h]), np.array([b, h]), np.array([b / 2, 0.0])
    x1 = f * (point[0] - c1[0]) / h
    x2 = f * (point[0] - c2[0]) / h + ex.SIGMA_IMAGE_PX * CANON.pixel_pitch_y_mm / 1000
    d1, d2 = np.array([x1, -f]), np.array([x2, -f])
    s, _ = np.linalg.solve(np.column_stack([d1, -d2]), c2 - c1)
    sigma_z = abs(float((c1 + s * d1)[1]))
    assert ex.depth_precision_m(CANON, b, h) == pytest.approx(sigma_z, rel=0.01)
    assert ex.depth_precision_m(CANON, b, h, Orientation.LANDSCAPE) == pytest.approx(sigma_z, rel=0.01)


def test_nadir_footprint_is_the_rectangle() -> None:
    corners = footprint_corners(CANON, 10.0, 20.0, 75.6, 0.0, 0.0)[0]
    fp = CANON.footprint(75.6, Orientation.LANDSCAPE)
    assert corners[:, 0].max() - corners[:, 0].min() == pytest.approx(fp.across_m)
    assert corners[:, 1].max() - corners[:, 1].min() == pytest.approx(fp.along_m)
    assert corners[:, 0].mean() == pytest.approx(10.0)
    # top of the image points north (up bearing 0): top-left corner is north-west
    assert corners[0, 0] < 10.0 and corners[0, 1] > 20.0


@given(
    tilt=st.floats(5.0, 45.0),
    up=st.floats(0.0, 360.0),
    height=st.floats(20.0, 300.0),
)
def test_tilted_footprint_is_the_textbook_trapezoid(tilt: float, up: float, height: float) -> None:
    corners = footprint_corners(CANON, 0.0, 0.0, height, up, tilt)[0]
    # distances along the look direction of the near and far edges: H tan(t -/+ half fov)
    half = math.degrees(CANON.half_fov_rad()[1])
    look = (math.sin(math.radians(up)), math.cos(math.radians(up)))
    radial = corners @ look
    assert radial[0] == pytest.approx(height * math.tan(math.radians(tilt + half)), rel=1e-9)
    assert radial[3] == pytest.approx(height * math.tan(math.radians(tilt - half)), rel=1e-9, abs=1e-9)
    far_width = math.dist(corners[0], corners[1])
    near_width = math.dist(corners[2], corners[3])
    assert far_width > near_width  # a trapezoid, wider at the far edge
    # depth of the far edge along the optical axis: slant range to its middle x cos(half fov)
    depth_far = height / math.cos(math.radians(tilt + half)) * math.cos(math.radians(half))
    assert far_width == pytest.approx(CANON.sensor_width_mm * depth_far / CANON.focal_length_mm, rel=1e-9)


def test_tilted_gsd_reduces_to_eq_3_4() -> None:
    radial, lateral = tilted_gsd_cm(CANON, 100.0, 0.0)
    assert radial == pytest.approx(CANON.gsd_y_cm(100.0))
    assert lateral == pytest.approx(CANON.gsd_x_cm(100.0))
    near, far = near_far_gsd_cm(CANON, 100.0, 30.0)
    centre = max(tilted_gsd_cm(CANON, 100.0, 30.0))
    assert far > centre > near  # the near edge of a tilted frame is finer than its centre
    # radial GSD at the centre of a 30 deg frame: pitch H / (f cos^2 30)
    assert centre == pytest.approx(CANON.gsd_y_cm(100.0) / math.cos(math.radians(30)) ** 2)


def test_far_edge_above_horizon_is_refused() -> None:
    with pytest.raises(SpecError, match="horizon"):
        footprint_corners(CANON, 0, 0, 100.0, 0.0, 80.0)


def test_inscribed_rectangle_inside_trapezoid() -> None:
    import shapely

    for direction, look, share in [(0.0, 0.0, 0.75), (0.0, 90.0, 0.75), (30.0, 75.0, 0.3)]:
        rect = ex.frame_rectangle(CANON, 100.0, direction, look, 30.0)
        corners = footprint_corners(CANON, 0, 0, 100.0, look, 30.0)[0]
        u, v = ex.to_pass_frame(corners[:, 0], corners[:, 1], direction)
        trapezoid = shapely.Polygon(list(zip(u, v, strict=True)))
        box = shapely.box(rect.u_min_m, rect.v_min_m, rect.u_max_m, rect.v_max_m)
        assert trapezoid.buffer(1e-6).contains(box)
        assert box.area > share * trapezoid.area


def _pixel_gsd_by_construction(camera: Camera, height: float, tilt_deg: float, xs: float, ys: float) -> float:
    """GSD (cm) of the pixel at sensor point (xs right, ys down, mm) of a camera at ``height`` looking
    north, tilted ``tilt_deg`` down from the vertical: rays through the pixel's edges, built from
    the viewing geometry alone (east is the image's right, the far side its top)."""
    t = math.radians(tilt_deg)
    axis = np.array([0.0, math.sin(t), -math.cos(t)])  # optical axis: north and down
    up = np.array([0.0, math.cos(t), math.sin(t)])  # the image's top, toward the far side
    right = np.array([1.0, 0.0, 0.0])
    f = camera.focal_length_mm

    def ground(x: float, y: float) -> np.ndarray:
        ray = f * axis + x * right - y * up
        return ray[:2] * height / -ray[2]

    px, py = camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm
    step_x = np.linalg.norm(ground(xs + px / 2, ys) - ground(xs - px / 2, ys))
    step_y = np.linalg.norm(ground(xs, ys + py / 2) - ground(xs, ys - py / 2))
    return 100.0 * float(max(step_x, step_y))


def test_oblique_far_gsd_is_the_far_corners_and_nadir_gsd_is_uniform() -> None:
    camera = get_camera("dji-phantom-4-pro")
    w, h = camera.sensor_width_mm / 2, camera.sensor_height_mm / 2
    near, far = near_far_gsd_cm(camera, 70.0, 30.0)
    corner = _pixel_gsd_by_construction(camera, 70.0, 30.0, w, -h)
    mid_edge = _pixel_gsd_by_construction(camera, 70.0, 30.0, 0.0, -h)
    assert far == pytest.approx(corner, rel=1e-9)
    assert far > mid_edge * 1.01  # the corners are coarser than the middle of the far edge
    assert near == pytest.approx(_pixel_gsd_by_construction(camera, 70.0, 30.0, 0.0, h), rel=1e-9)
    # nadir over flat ground: the image plane is parallel to the ground, the GSD is the same at
    # the corners as at the centre (Eq. 3-4), and that is what is reported
    centre = _pixel_gsd_by_construction(camera, 70.0, 0.0, 0.0, 0.0)
    assert _pixel_gsd_by_construction(camera, 70.0, 0.0, w, -h) == pytest.approx(centre, rel=1e-9)
    assert near_far_gsd_cm(camera, 70.0, 0.0) == pytest.approx((centre, centre), rel=1e-9)
