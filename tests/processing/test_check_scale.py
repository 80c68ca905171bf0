"""The measured image scale put to use (processing/check_scale.py, processing/check.py).

The oracle is a construction: frames cut from one texture whose ground pixel is known (5 cm), at
GPS positions that follow the cuts, tagged with a height of 40 m that the right camera (800 px
focal length) turns into that 5 cm. A wrong camera, a rough camera or a wrong ground then disagree
with the pixels by a known factor, and the check must come back to the construction's GSD,
footprints, overlap and height."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image
from textures import blob_texture

from planner.camera import Camera
from processing.check import run_check
from processing.check_scale import (
    MAX_SCALE_ERROR_RATIO,
    Blame,
    assess_scale,
    median_error_ratio,
)
from processing.frames import AltitudeReference, AttitudeSource, Frames, local_frame_at
from processing.ground import FlatGround
from processing.pixel_match import PixelFigures, PixelOptions
from processing.survey_frames import AltitudeTrend

#: The construction: ground pixel, frame size, steps between frames and lines (texture pixels).
GSD_CM = 5.0
WIDTH_PX, HEIGHT_PX = 800, 600
STEP_PX = 180  # along the line (north, the image's y): 70 % endlap
LINE_STEP_PX = 400  # between lines (east, the image's x): 50 % sidelap
PER_LINE = 6
LINES = 2
GROUND_M = 100.0
RIGHT = Camera(
    id="synthetic",
    name="synthetic 800 px",
    sensor_width_mm=8.0,
    sensor_height_mm=6.0,
    image_width_px=WIDTH_PX,
    image_height_px=HEIGHT_PX,
    focal_length_mm=8.0,  # 800 px: 40 m above ground gives 5 cm
)
HEIGHT_M = GSD_CM / 100.0 * 800.0


@pytest.fixture(scope="module")
def block(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Frames]:
    """Two lines flown north, image top north: frame k of line j is cut at column j x 400 and
    row (rows from the south) k x 180 of the texture, and tagged at the ground position of its
    centre."""
    folder = tmp_path_factory.mktemp("synthetic_block")
    tex_h = HEIGHT_PX + STEP_PX * (PER_LINE - 1)
    tex_w = WIDTH_PX + LINE_STEP_PX * (LINES - 1)
    texture = blob_texture(tex_w, tex_h, seed=7)
    names, xs, ys, times = [], [], [], []
    for j in range(LINES):
        for k in range(PER_LINE):
            top = tex_h - HEIGHT_PX - k * STEP_PX  # flying north: each frame higher in the texture
            left = j * LINE_STEP_PX
            name = f"L{j}_{k:02d}.jpg"
            Image.fromarray(texture[top : top + HEIGHT_PX, left : left + WIDTH_PX]).save(
                folder / name, quality=95
            )
            names.append(name)
            xs.append((left + WIDTH_PX / 2) * GSD_CM / 100.0)
            ys.append((tex_h - (top + HEIGHT_PX / 2)) * GSD_CM / 100.0)
            times.append(1.7e9 + 60.0 * j + 3.0 * k)
    origin = local_frame_at(-83.0, 41.0)
    lon, lat = origin.to_lonlat(np.array(xs), np.array(ys))
    n = len(names)
    frames = Frames(
        name=tuple(names),
        lon_deg=lon,
        lat_deg=lat,
        alt_m=np.full(n, GROUND_M + HEIGHT_M),
        alt_reference=AltitudeReference.AMSL,
        yaw_deg=np.zeros(n),
        pitch_deg=np.zeros(n),
        roll_deg=np.zeros(n),
        attitude_source=AttitudeSource.XMP,
        camera=RIGHT,
        time_utc_s=np.array(times),
    )
    return folder, frames


def _check(folder: Path, frames: Frames, ground_m: float = GROUND_M, **kwargs: object):  # type: ignore[no-untyped-def]
    ground = FlatGround(elevation_m=ground_m, reference=AltitudeReference.AMSL)
    return run_check(
        frames,
        ground=ground,
        pixels=PixelOptions(image_dir=folder, max_image_size_px=WIDTH_PX, reconstruct=False),
        **kwargs,  # type: ignore[arg-type]
    )


@pytest.mark.slow  # COLMAP's SIFT and matching on 12 synthetic frames, once or twice: 30-90 s
def test_the_right_camera_agrees_with_the_pixels_and_nothing_is_changed(block: tuple[Path, Frames]) -> None:
    folder, frames = block
    result = _check(folder, frames)
    assert result.scale is not None and not result.scale.used and result.scale.blame is None
    assert result.scale.measured_gsd_cm == pytest.approx(GSD_CM, rel=0.03)
    assert float(np.median(result.gsd_cm)) == pytest.approx(GSD_CM, rel=0.01)
    # The construction's endlap, from the tags' footprints.
    assert result.stereo.forward_overlap_pct is not None
    assert result.stereo.forward_overlap_pct.median == pytest.approx(100 * (1 - STEP_PX / HEIGHT_PX), abs=2)


@pytest.mark.slow  # COLMAP's SIFT and matching on 12 synthetic frames, once or twice: 30-90 s
def test_a_camera_given_2_4x_off_gets_the_measured_gsd_footprints_and_overlap(
    block: tuple[Path, Frames],
) -> None:
    """A camera given with its focal length 2.4x too long: the tags say 2.08 cm and 29 % endlap
    (footprints 2.4x too small); the pixels say 5 cm, and the figures come back to the
    construction. The pixels cannot tell a wrong camera from wrong heights: both readings given,
    the heights kept as tagged."""
    folder, frames = block
    wrong = replace(frames, camera=replace(RIGHT, focal_length_mm=8.0 * 2.4))
    tags_only = run_check(wrong, ground=FlatGround(elevation_m=GROUND_M, reference=AltitudeReference.AMSL))
    assert float(np.median(tags_only.gsd_cm)) == pytest.approx(GSD_CM / 2.4, rel=0.01)
    assert tags_only.stereo.forward_overlap_pct is not None
    assert tags_only.stereo.forward_overlap_pct.median < 40

    result = _check(folder, wrong)
    scale = result.scale
    assert scale is not None and scale.used and scale.blame is Blame.EITHER
    assert float(np.median(result.gsd_cm)) == pytest.approx(GSD_CM, rel=0.03)
    assert result.stereo.forward_overlap_pct is not None
    assert result.stereo.forward_overlap_pct.median == pytest.approx(100 * (1 - STEP_PX / HEIGHT_PX), abs=3)
    assert float(np.median(result.height_agl_m)) == pytest.approx(HEIGHT_M, rel=1e-6)  # as tagged
    assert scale.measured_focal_px == pytest.approx(800.0, rel=0.03)
    assert scale.measured_height_m == pytest.approx(HEIGHT_M * 2.4, rel=0.03)
    said = [w for w in result.warnings if "image scale measured in the pixels" in w]
    assert len(said) == 1 and "either" in said[0] and "800 px" in said[0] and "1920 px" in said[0]
    data = result.as_dict()
    assert data["scale"]["used"] is True and data["scale"]["gsd_cm"]["tagged"] == pytest.approx(
        GSD_CM / 2.4, rel=0.01
    )
    assert data["gsd_cm"]["median"] == pytest.approx(GSD_CM, rel=0.03)
    figures = dict(result.key_figures())
    assert "the tags give 2.08 cm" in figures["GSD"] and "focal length" in figures


@pytest.mark.slow  # COLMAP's SIFT and matching on 12 synthetic frames, once or twice: 30-90 s
def test_a_rough_camera_is_blamed_and_replaced_by_the_measured_focal_length(
    block: tuple[Path, Frames],
) -> None:
    folder, frames = block
    rough = replace(frames, camera=replace(RIGHT, focal_length_mm=8.0 / 1.8))
    result = _check(folder, rough, camera_rough=True)
    scale = result.scale
    assert scale is not None and scale.used and scale.blame is Blame.CAMERA
    assert scale.measured_focal_px == pytest.approx(800.0, rel=0.03)
    assert result.frames.camera.focal_length_mm == pytest.approx(8.0, rel=0.03)
    assert float(np.median(result.gsd_cm)) == pytest.approx(GSD_CM, rel=0.03)
    said = [w for w in result.warnings if "focal length is unknown, measured" in w]
    assert len(said) == 1 and "444 px" in said[0]


@pytest.mark.slow  # COLMAP's SIFT and matching on 12 synthetic frames, once or twice: 30-90 s
def test_drifting_heights_are_blamed_and_replaced_by_the_measured_height(block: tuple[Path, Frames]) -> None:
    """Detrended altitudes with a ground given 20 m too high: the tags say 20 m above ground and
    2.5 cm; the pixels say 5 cm, hence 40 m: the ground is moved 20 m down."""
    folder, frames = block
    trend = AltitudeTrend(slope_m_per_s=0.5, start_s=float(frames.time_utc_s[0]), span_s=75.0)  # type: ignore[index]
    result = _check(folder, frames, ground_m=GROUND_M + 20.0, detrended=trend)
    scale = result.scale
    assert scale is not None and scale.used and scale.blame is Blame.HEIGHTS
    assert float(np.median(result.height_agl_m)) == pytest.approx(HEIGHT_M, rel=0.03)
    assert float(np.median(result.gsd_cm)) == pytest.approx(GSD_CM, rel=0.03)
    assert scale.as_dict()["ground_moved_m"] == pytest.approx(-20.0, abs=1.2)
    assert "moved down" in result.ground_description
    said = [w for w in result.warnings if "image scale measured in the pixels" in w]
    assert len(said) == 1 and "m lower than given" in said[0] and "the altitudes drift" in said[0]
    assert "from the image scale; the tags give 20.0 m" in dict(result.key_figures())["height above ground"]
    # The same wrong ground without the drift flag: either is to blame, the heights kept as tagged.
    plain = _check(folder, frames, ground_m=GROUND_M + 20.0)
    assert plain.scale is not None and plain.scale.blame is Blame.EITHER
    assert float(np.median(plain.height_agl_m)) == pytest.approx(20.0, rel=1e-6)


# --- the rules, without pixels -------------------------------------------------------------------


def _figures(gsd_cm: np.ndarray, focal_px: float = 1000.0) -> PixelFigures:
    m = len(gsd_cm)
    return PixelFigures(
        pair_index=np.column_stack([np.arange(m), np.arange(1, m + 1)]).astype(np.int64),
        pair_along=np.ones(m, dtype=bool),
        inliers=np.full(m, 500, dtype=np.int64),
        matched=np.ones(m, dtype=bool),
        overlap_pct=np.full(m, 60.0),
        shift_px=np.full(m, 400.0),
        gsd_cm=np.asarray(gsd_cm, dtype=np.float64),
        component=np.zeros(m + 1, dtype=np.int64),
        frame_count=m + 1,
        match_size_px=640,
        seconds=1.0,
        tagged_gsd_cm=None,
        focal_px=focal_px,
        keypoints_median=2000.0,
    )


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(min_value=30, max_value=400),
    sigma=st.floats(min_value=0.01, max_value=0.3),
    seed=st.integers(min_value=0, max_value=2**31),
)
def test_the_median_error_is_the_spread_of_medians_of_normal_samples(n: int, sigma: float, seed: int) -> None:
    """Oracle: the standard error of the median of n normal draws is 1.2533 sigma / sqrt(n); the
    estimate from one sample is within its sampling error of it (a factor of 2 at n >= 30)."""
    rng = np.random.default_rng(seed)
    sample = rng.normal(1.0, sigma, size=n)
    truth = 1.2533 * sigma / math.sqrt(n)
    assert median_error_ratio(sample) == pytest.approx(truth, rel=1.0)
    assert 0.5 * truth < median_error_ratio(sample) * float(np.median(sample)) < 2.0 * truth


def test_a_scattered_or_short_scale_replaces_nothing() -> None:
    # 4 pairs: too few, however far off.
    few = assess_scale(
        _figures(np.full(4, 5.0)),
        tagged_gsd_cm=2.0,
        tagged_height_m=20.0,
        camera_rough=True,
        heights_drift=False,
    )
    assert few is not None and not few.used and few.blame is None
    assert "too few pairs or too scattered" in (few.words() or "")
    # 12 pairs scattered +-60 %: the median is known to +-25 %, beyond the 5 % needed.
    rng = np.random.default_rng(3)
    scattered = 5.0 * (1 + 0.6 * rng.standard_normal(12))
    spread = assess_scale(
        _figures(scattered), tagged_gsd_cm=2.0, tagged_height_m=20.0, camera_rough=True, heights_drift=False
    )
    assert spread is not None and spread.error_ratio > MAX_SCALE_ERROR_RATIO and not spread.used
    # Within the 15 % the tags are good to: nothing said, nothing used.
    close = assess_scale(
        _figures(np.full(20, 2.2)),
        tagged_gsd_cm=2.0,
        tagged_height_m=20.0,
        camera_rough=True,
        heights_drift=False,
    )
    assert close is not None and not close.used and close.words() is None


@pytest.mark.parametrize(
    ("rough", "drift", "blame"),
    [
        (True, False, Blame.CAMERA),
        (False, True, Blame.HEIGHTS),
        (False, False, Blame.EITHER),
        (True, True, Blame.EITHER),
    ],
)
def test_which_tag_is_blamed(rough: bool, drift: bool, blame: Blame) -> None:
    finding = assess_scale(
        _figures(np.full(20, 5.0)),
        tagged_gsd_cm=2.0,
        tagged_height_m=20.0,
        camera_rough=rough,
        heights_drift=drift,
    )
    assert finding is not None and finding.used and finding.blame is blame
    # 5 / 2 = 2.5: the height if the camera is right, the focal length if the heights are.
    assert finding.measured_height_m == pytest.approx(50.0) and finding.measured_focal_px == pytest.approx(
        400.0
    )
