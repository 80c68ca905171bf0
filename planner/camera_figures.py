"""What a crew checks before choosing a camera for a survey (``sfap cameras``): pixel pitch,
fields of view, the 35 mm equivalent focal length, GSD and footprint at a height, and the
height for a GSD; derived from the camera's geometry (planner.camera), nothing looked up."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .camera import FULL_FRAME_DIAGONAL_MM, Camera


def camera_row(camera: Camera) -> dict[str, object]:
    """One camera's key figures for a listing (JSON-ready): sizes, focal length, pixel pitch."""
    return {
        "id": camera.id,
        "name": camera.name,
        "sensor_width_mm": camera.sensor_width_mm,
        "sensor_height_mm": camera.sensor_height_mm,
        "image_width_px": camera.image_width_px,
        "image_height_px": camera.image_height_px,
        "focal_length_mm": camera.focal_length_mm,
        "pixel_pitch_um": max(camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm) * 1000.0,
    }


@dataclass(frozen=True, kw_only=True)
class CameraFigures:
    """Derived figures of one camera: what a crew checks before choosing it for a survey.

    Angles are full fields of view of a nadir pinhole camera, degrees. Ground figures hold at
    ``alt_agl_m`` above flat ground; the footprint is given along the image axes (width = image
    x, across track in landscape). ``heights_for_gsd`` pairs a GSD (cm, coarser axis) with the
    height above ground that gives it (m).
    """

    camera: Camera
    pixel_pitch_x_um: float
    pixel_pitch_y_um: float
    fov_x_deg: float
    fov_y_deg: float
    fov_diagonal_deg: float
    focal_length_35mm_equiv_mm: float
    alt_agl_m: float
    gsd_x_cm: float
    gsd_y_cm: float
    gsd_cm: float
    footprint_width_m: float
    footprint_height_m: float
    scale_number: float
    heights_for_gsd: tuple[tuple[float, float], ...]

    def to_dict(self) -> dict[str, object]:
        """Plain data for JSON output; keys carry their units."""
        camera = self.camera
        return {
            **camera_row(camera),
            "min_trigger_interval_s": camera.min_trigger_interval_s,
            "shutter_s": camera.shutter_s,
            "exif_make": camera.exif_make,
            "exif_model": camera.exif_model,
            "source": camera.source,
            "pixel_pitch_x_um": self.pixel_pitch_x_um,
            "pixel_pitch_y_um": self.pixel_pitch_y_um,
            "fov_x_deg": self.fov_x_deg,
            "fov_y_deg": self.fov_y_deg,
            "fov_diagonal_deg": self.fov_diagonal_deg,
            "focal_length_35mm_equiv_mm": self.focal_length_35mm_equiv_mm,
            "at_height": {
                "alt_agl_m": self.alt_agl_m,
                "gsd_x_cm": self.gsd_x_cm,
                "gsd_y_cm": self.gsd_y_cm,
                "gsd_cm": self.gsd_cm,
                "footprint_width_m": self.footprint_width_m,
                "footprint_height_m": self.footprint_height_m,
                "footprint_area_m2": self.footprint_width_m * self.footprint_height_m,
                "scale_number": self.scale_number,
            },
            "height_for_gsd": [
                {"gsd_cm": gsd_cm, "alt_agl_m": alt_agl_m} for gsd_cm, alt_agl_m in self.heights_for_gsd
            ],
        }


def camera_figures(
    camera: Camera,
    *,
    height_agl_m: float = 100.0,
    gsd_targets_cm: tuple[float, ...] = (1.0, 2.0, 3.0),
) -> CameraFigures:
    """Pitch, field of view, GSD and footprint at ``height_agl_m`` (m above flat ground), and
    the height above ground for each GSD in ``gsd_targets_cm`` (cm, on the coarser axis)."""
    half_x, half_y = camera.half_fov_rad()
    diagonal_mm = math.hypot(camera.sensor_width_mm, camera.sensor_height_mm)
    return CameraFigures(
        camera=camera,
        pixel_pitch_x_um=camera.pixel_pitch_x_mm * 1000.0,
        pixel_pitch_y_um=camera.pixel_pitch_y_mm * 1000.0,
        fov_x_deg=math.degrees(2.0 * half_x),
        fov_y_deg=math.degrees(2.0 * half_y),
        fov_diagonal_deg=math.degrees(2.0 * math.atan(diagonal_mm / 2.0 / camera.focal_length_mm)),
        focal_length_35mm_equiv_mm=camera.focal_length_mm * FULL_FRAME_DIAGONAL_MM / diagonal_mm,
        alt_agl_m=height_agl_m,
        gsd_x_cm=camera.gsd_x_cm(height_agl_m),
        gsd_y_cm=camera.gsd_y_cm(height_agl_m),
        gsd_cm=camera.gsd_cm(height_agl_m),
        footprint_width_m=camera.image_width_px * camera.gsd_x_cm(height_agl_m) / 100.0,
        footprint_height_m=camera.image_height_px * camera.gsd_y_cm(height_agl_m) / 100.0,
        scale_number=camera.scale_number(height_agl_m),
        heights_for_gsd=tuple((gsd, camera.height_for_gsd_m(gsd)) for gsd in gsd_targets_cm),
    )
