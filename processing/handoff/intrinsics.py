"""Camera intrinsics for a reconstruction: focal length in pixels and principal point.

The camera is the one the check would use (:func:`processing.image_tags.camera_from_tags`: the
given camera, the database, a database camera's images scaled, the EXIF focal plane
resolution, the 35 mm equivalent focal length); its focal length over its pixel pitch at the
images' own size is the focal length in pixels. Where nothing gives one, COLMAP's own default
(1.2 x the longer image side), said so. The principal point is the image centre; the engine
refines both.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from planner.camera import Camera

from ..image_tags import CameraConfidence, camera_from_tags, given_choice, known

if TYPE_CHECKING:
    from acquisition.exif import CameraTags, ImageTags

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


def intrinsics_for(tags: ImageTags, camera_tags: CameraTags | None, *, given: Camera | None) -> Intrinsics:
    """The intrinsics of images whose tags are ``tags`` (one representative of a group that
    shares make, model, focal length and image size), taken with ``given`` (``--camera``) or
    the camera their tags say (module docstring)."""
    assert tags.width_px and tags.height_px
    width_px, height_px = int(tags.width_px), int(tags.height_px)
    key = (tags.make or "", tags.model or "", float(tags.focal_length_mm or 0.0), width_px, height_px)
    choice = given_choice(given) if given is not None else camera_from_tags(tags, camera_tags)
    if choice is None:
        return Intrinsics(
            key=key,
            width_px=width_px,
            height_px=height_px,
            focal_px=DEFAULT_FOCAL_FACTOR * max(width_px, height_px),
            focal_length_mm=known(tags.focal_length_mm),
            pixel_pitch_mm=None,
            source=f"GUESSED: no database camera, focal-plane resolution or 35 mm focal length in EXIF; "
            f"{DEFAULT_FOCAL_FACTOR} x the longer side (the engine must refine it)",
        )
    camera = choice.camera
    # A scaled copy keeps the field of view, so the focal length in pixels scales with the
    # width; a portrait image of a landscape sensor swaps the axes.
    landscape_image = width_px >= height_px
    landscape_sensor = camera.image_width_px >= camera.image_height_px
    across_mm = camera.sensor_width_mm if landscape_image == landscape_sensor else camera.sensor_height_mm
    pitch = across_mm / width_px
    focal_mm: float | None = camera.focal_length_mm
    pitch_mm: float | None = pitch
    f_mm = camera.focal_length_mm
    if choice.confidence is CameraConfidence.GIVEN:
        source = f"given: {camera.id} ({f_mm:g} mm, {across_mm:g} mm across {width_px} px)"
    elif choice.confidence is CameraConfidence.DATASHEET:
        source = f"camera database: {camera.id} ({f_mm:g} mm / {pitch * 1000:.3f} um pixels)"
    elif choice.confidence is CameraConfidence.FOCAL_PLANE:
        original = camera_tags.pixel_x_dimension_px if camera_tags is not None else None
        note = "" if not original or original == width_px else f", image reduced from {original} px wide"
        source = (
            f"EXIF focal length {f_mm:g} mm and focal-plane resolution ({pitch * 1000:.3f} um pixels{note})"
        )
    else:  # the 35 mm equivalent: a field of view, no pixel pitch
        f35 = camera_tags.focal_length_35mm_mm if camera_tags is not None else None
        focal_mm, pitch_mm = known(tags.focal_length_mm), None
        source = f"EXIF 35 mm equivalent focal length {f35:g} mm (diagonal field of view)"
    return Intrinsics(
        key=key,
        width_px=width_px,
        height_px=height_px,
        focal_px=f_mm / pitch,
        focal_length_mm=focal_mm,
        pixel_pitch_mm=pitch_mm,
        source=source,
    )
