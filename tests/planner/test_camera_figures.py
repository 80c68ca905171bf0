"""A camera's derived figures (planner.camera_figures) against its makers' datasheets and the
pinhole geometry computed here independently."""

from __future__ import annotations

import math

import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from planner.camera import Camera
from planner.camera_db import get_camera, load_cameras
from planner.camera_figures import camera_figures, camera_row
from planner.errors import CameraError


def test_figures_of_one_camera_follow_from_its_geometry() -> None:
    camera = get_camera("dji-phantom-4-pro")
    figures = camera_figures(camera, height_agl_m=100.0, gsd_targets_cm=(1.0, 2.0, 3.0))
    # DJI's datasheet: FOV 84 deg, 8.8 mm / 24 mm equivalent.
    assert figures.fov_diagonal_deg == pytest.approx(84.0, abs=0.5)
    assert figures.focal_length_35mm_equiv_mm == pytest.approx(24.0, abs=0.3)
    # 2.412 um x 100 m / 8.8 mm = 2.741 cm; footprint 5472 px x 2.741 cm = 150 m.
    assert figures.gsd_cm == pytest.approx(2.741, abs=0.001)
    assert figures.footprint_width_m == pytest.approx(150.0, abs=0.1)
    assert figures.footprint_height_m == pytest.approx(100.0, abs=0.1)
    assert [gsd for gsd, _ in figures.heights_for_gsd] == [1.0, 2.0, 3.0]
    assert figures.heights_for_gsd[1][1] == pytest.approx(2 * figures.heights_for_gsd[0][1])
    data = figures.to_dict()
    assert data["id"] == "dji-phantom-4-pro"
    assert data["at_height"]["gsd_cm"] == figures.gsd_cm  # type: ignore[index]


@settings(max_examples=60, deadline=None)
@given(
    width_mm=st.floats(2.0, 60.0), aspect=st.floats(1.0, 2.0), width_px=st.integers(800, 12000),
    focal_mm=st.floats(3.0, 100.0), height_m=st.floats(10.0, 500.0),
)  # fmt: skip
def test_figures_follow_the_pinhole_geometry(
    width_mm: float, aspect: float, width_px: int, focal_mm: float, height_m: float
) -> None:
    """Oracle: the similar triangles of a pinhole camera, written here from scratch (ground
    footprint = sensor size x height / focal length; field of view = 2 atan(half size / f);
    35 mm equivalent = f x 43.27 mm / sensor diagonal)."""
    height_px = max(100, round(width_px / aspect))
    height_mm = width_mm * height_px / width_px  # square pixels
    try:
        camera = Camera(
            id="c", name="c", sensor_width_mm=width_mm, sensor_height_mm=height_mm,
            image_width_px=width_px, image_height_px=height_px, focal_length_mm=focal_mm,
        )  # fmt: skip
    except CameraError:  # outside the plausible pitch (0.5-25 um): not a camera
        assume(False)
        return
    figures = camera_figures(camera, height_agl_m=height_m, gsd_targets_cm=(1.5,))
    assert figures.footprint_width_m == pytest.approx(width_mm * height_m / focal_mm, rel=1e-9)
    assert figures.footprint_height_m == pytest.approx(height_mm * height_m / focal_mm, rel=1e-9)
    assert figures.fov_x_deg == pytest.approx(math.degrees(2 * math.atan(width_mm / 2 / focal_mm)), rel=1e-9)
    diagonal = math.hypot(width_mm, height_mm)
    assert figures.focal_length_35mm_equiv_mm == pytest.approx(focal_mm * math.hypot(36, 24) / diagonal)
    assert figures.pixel_pitch_x_um == pytest.approx(1000 * width_mm / width_px, rel=1e-9)
    ((gsd, alt),) = figures.heights_for_gsd
    # At that height the coarser axis's GSD is the one asked for.
    coarser_cm = 100 * max(width_mm / width_px, height_mm / height_px) * alt / focal_mm
    assert (gsd, coarser_cm) == (1.5, pytest.approx(1.5, rel=1e-9))


def test_listing_rows_name_every_database_camera_with_its_coarser_pitch() -> None:
    for camera in load_cameras().values():
        row = camera_row(camera)
        assert row["id"] == camera.id
        pitch_um = 1000 * max(
            camera.sensor_width_mm / camera.image_width_px, camera.sensor_height_mm / camera.image_height_px
        )
        assert row["pixel_pitch_um"] == pytest.approx(pitch_um, rel=1e-9)
