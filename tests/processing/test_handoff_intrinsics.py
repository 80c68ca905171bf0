"""The hand-off's intrinsics (processing.handoff.intrinsics) come from the camera the check
chooses (processing.image_tags.camera_from_tags): focal lengths in pixels against the EXIF
definitions written out here, for each source, and the same figure for the check and the
hand-off."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from acquisition.exif import CameraTags, ImageTags
from processing.handoff.intrinsics import DEFAULT_FOCAL_FACTOR, intrinsics_for
from processing.image_tags import CameraConfidence, choose_camera


def _tags(width_px: int, height_px: int, focal_mm: float | None) -> ImageTags:
    return ImageTags(path="x.jpg", make="Acme", model="Unlisted 1", focal_length_mm=focal_mm,
                     width_px=width_px, height_px=height_px)  # fmt: skip


@settings(max_examples=60, deadline=None)
@given(
    px_per_mm=st.floats(80.0, 400.0), original_px=st.integers(2000, 8000), reduce=st.sampled_from([1, 2, 4]),
    focal_mm=st.floats(4.0, 50.0),
)  # fmt: skip
def test_focal_plane_resolution_of_a_reduced_image_counts_the_original_pixels(
    px_per_mm: float, original_px: int, reduce: int, focal_mm: float
) -> None:
    """EXIF FocalPlaneXResolution counts pixels of the image the camera wrote (PixelXDimension
    wide); a copy reduced ``reduce`` times has that many fewer per millimetre."""
    width, height = original_px // reduce, (original_px * 2 // 3) // reduce
    tags = _tags(width, height, focal_mm)
    extra = CameraTags(focal_plane_x_px_per_mm=px_per_mm, focal_plane_y_px_per_mm=px_per_mm,
                       pixel_x_dimension_px=width * reduce)  # fmt: skip
    expected_px = focal_mm * px_per_mm / reduce
    sensor_mm = width * reduce / px_per_mm
    if not (1.0 <= sensor_mm <= 100.0):  # not a plausible camera: refused, as the database would
        return
    intr = intrinsics_for(tags, extra, given=None)
    assert intr.focal_px == pytest.approx(expected_px, rel=1e-9)
    check = choose_camera(tags, extra)
    assert check.confidence is CameraConfidence.FOCAL_PLANE
    # The same camera for the check, in its own pixels (at the original size when the reduced
    # image's pixels would be larger than any sensor's): the same field of view.
    check_f_px = check.camera.focal_length_mm / check.camera.pixel_pitch_x_mm
    assert check_f_px * width / check.camera.image_width_px == pytest.approx(intr.focal_px, rel=1e-9)


def test_35mm_equivalent_and_the_guess() -> None:
    tags = _tags(4000, 3000, 4.5)
    intr = intrinsics_for(tags, CameraTags(focal_length_35mm_mm=24.0), given=None)
    # f_px = f35 x diagonal_px / diagonal of the 36 x 24 mm frame
    assert intr.focal_px == pytest.approx(24.0 * 5000.0 / math.hypot(36.0, 24.0), rel=1e-9)
    assert intr.pixel_pitch_mm is None and intr.focal_length_mm == 4.5
    guessed = intrinsics_for(tags, CameraTags(), given=None)
    assert guessed.focal_px == DEFAULT_FOCAL_FACTOR * 4000 and guessed.source.startswith("GUESSED")
