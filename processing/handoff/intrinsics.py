"""Camera intrinsics for a reconstruction: focal length in pixels and principal point.

From the camera database when the EXIF matches a camera there (focal length over pixel pitch),
else from the EXIF focal length and the focal-plane resolution (the pixel pitch the camera
writes), else from the 35 mm equivalent focal length; as a last resort COLMAP's own default
(1.2 x the longer image side), said so. The principal point is the image centre; the engine
refines both.

Images reduced after capture (as copr_kap's) keep their original EXIF: the focal-plane
resolution counts pixels of the original width (``PixelXDimension``), so it is scaled to the
file's real width.

pyexiv2 is read here for the three focal-plane tags that :mod:`acquisition.exif` does not
expose (FocalPlaneXResolution, FocalPlaneResolutionUnit, PixelXDimension).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from fractions import Fraction

from planner.camera import Camera
from planner.camera_db import match_exif

#: Millimetres per FocalPlaneResolutionUnit (EXIF: 2 inch, 3 cm, 4 mm, 5 um).
_UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}
#: The 35 mm film frame's diagonal, mm.
_FULL_FRAME_DIAGONAL_MM = 43.2666
#: COLMAP's default focal length for an unknown camera, times the longer image side.
DEFAULT_FOCAL_FACTOR = 1.2


@dataclass(frozen=True, kw_only=True)
class Intrinsics:
    """One camera model: pinhole focal length in pixels and the principal point (image centre).

    ``key``: what groups images into this camera (make, model, focal length, image size).
    ``focal_length_mm`` and ``pixel_pitch_mm`` are None when not known. ``source`` says where
    the focal length came from.
    """

    key: tuple[str, str, float, int, int]
    width_px: int
    height_px: int
    focal_px: float
    focal_length_mm: float | None
    pixel_pitch_mm: float | None
    source: str

    @property
    def principal_xy_px(self) -> tuple[float, float]:
        return self.width_px / 2.0, self.height_px / 2.0

    @property
    def label(self) -> str:
        make, model, focal, w, h = self.key
        return f"{make} {model} {focal:g} mm {w}x{h}".strip()

    def as_dict(self) -> dict[str, object]:
        return {
            "camera": self.label,
            "width_px": self.width_px,
            "height_px": self.height_px,
            "focal_px": self.focal_px,
            "principal_xy_px": list(self.principal_xy_px),
            "focal_length_mm": self.focal_length_mm,
            "pixel_pitch_mm": self.pixel_pitch_mm,
            "source": self.source,
        }


def _rational(text: str | None) -> float | None:
    if not text:
        return None
    try:
        value = float(Fraction(text.strip().split()[0]))
    except (ValueError, ZeroDivisionError):
        return None
    return value if value > 0 else None


def _focal_plane_tags(path: str | os.PathLike[str]) -> dict[str, str]:
    import pyexiv2

    image = pyexiv2.Image(os.fspath(path))
    try:
        exif = image.read_exif()
    finally:
        image.close()
    keys = (
        "Exif.Photo.FocalPlaneXResolution",
        "Exif.Photo.FocalPlaneResolutionUnit",
        "Exif.Photo.PixelXDimension",
        "Exif.Photo.FocalLengthIn35mmFilm",
    )
    return {k: str(exif[k]) for k in keys if k in exif}


def given_intrinsics(
    camera: Camera,
    *,
    make: str | None,
    model: str | None,
    focal_length_mm: float | None,
    width_px: int,
    height_px: int,
) -> Intrinsics:
    """The intrinsics of images taken with ``camera`` (``--camera``), at the images' own size: a
    scaled copy keeps the field of view, so the focal length in pixels scales with the width."""
    key = (make or "", model or "", float(focal_length_mm or 0.0), int(width_px), int(height_px))
    landscape_image = width_px >= height_px
    landscape_sensor = camera.image_width_px >= camera.image_height_px
    across_mm = camera.sensor_width_mm if landscape_image == landscape_sensor else camera.sensor_height_mm
    pitch = across_mm / width_px
    return Intrinsics(
        key=key,
        width_px=width_px,
        height_px=height_px,
        focal_px=camera.focal_length_mm / pitch,
        focal_length_mm=camera.focal_length_mm,
        pixel_pitch_mm=pitch,
        source=f"given: {camera.id} ({camera.focal_length_mm:g} mm, {across_mm:g} mm across {width_px} px)",
    )


def intrinsics_for(
    *,
    sample_path: str | os.PathLike[str],
    make: str | None,
    model: str | None,
    focal_length_mm: float | None,
    width_px: int,
    height_px: int,
) -> Intrinsics:
    """The intrinsics of the camera that took ``sample_path`` (module docstring for the order)."""
    key = (make or "", model or "", float(focal_length_mm or 0.0), int(width_px), int(height_px))
    camera = match_exif(make, model, focal_length_mm, width_px, height_px)
    if camera is not None:
        # A portrait image of a landscape sensor swaps the axes.
        same = camera.image_width_px == width_px
        pitch = camera.pixel_pitch_x_mm if same else camera.pixel_pitch_y_mm
        return Intrinsics(
            key=key,
            width_px=width_px,
            height_px=height_px,
            focal_px=camera.focal_length_mm / pitch,
            focal_length_mm=camera.focal_length_mm,
            pixel_pitch_mm=pitch,
            source=(
                f"camera database: {camera.id} ({camera.focal_length_mm:g} mm / {pitch * 1000:.3f} um pixels)"
            ),
        )
    tags = _focal_plane_tags(sample_path)
    resolution = _rational(tags.get("Exif.Photo.FocalPlaneXResolution"))
    unit = _UNIT_MM.get(int(_rational(tags.get("Exif.Photo.FocalPlaneResolutionUnit")) or 2))
    original_width = _rational(tags.get("Exif.Photo.PixelXDimension")) or float(width_px)
    if focal_length_mm and resolution and unit:
        pitch_original = unit / resolution  # mm per pixel of the original image
        pitch = pitch_original * original_width / width_px
        note = "" if original_width == width_px else f", image reduced from {original_width:.0f} px wide"
        return Intrinsics(
            key=key,
            width_px=width_px,
            height_px=height_px,
            focal_px=focal_length_mm / pitch,
            focal_length_mm=focal_length_mm,
            pixel_pitch_mm=pitch,
            source=f"EXIF focal length {focal_length_mm:g} mm and focal-plane resolution "
            f"({pitch * 1000:.3f} um pixels{note})",
        )
    f35 = _rational(tags.get("Exif.Photo.FocalLengthIn35mmFilm"))
    diagonal_px = (width_px**2 + height_px**2) ** 0.5
    if f35:
        return Intrinsics(
            key=key,
            width_px=width_px,
            height_px=height_px,
            focal_px=f35 * diagonal_px / _FULL_FRAME_DIAGONAL_MM,
            focal_length_mm=focal_length_mm,
            pixel_pitch_mm=None,
            source=f"EXIF 35 mm equivalent focal length {f35:g} mm (diagonal field of view)",
        )
    return Intrinsics(
        key=key,
        width_px=width_px,
        height_px=height_px,
        focal_px=DEFAULT_FOCAL_FACTOR * max(width_px, height_px),
        focal_length_mm=focal_length_mm,
        pixel_pitch_mm=None,
        source=f"GUESSED: no database camera, focal-plane resolution or 35 mm focal length in EXIF; "
        f"{DEFAULT_FOCAL_FACTOR} x the longer side (the engine must refine it)",
    )
