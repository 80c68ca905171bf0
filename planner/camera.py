"""The camera model: sensor geometry, GSD and footprint (Aber et al. 2019, Eq. 3-1 to 3-4).

Pixel pitch is kept per axis, so a sensor whose pitch is not square gets the right GSD and
footprint on both axes (QGroundControl derives both from the sensor width; QGC issue 6313).

Axes: x is the image width (columns, the sensor's long side for every camera in the database),
y the image height (rows). With ``Orientation.LANDSCAPE`` the image x axis lies across the
flight line, so the footprint across track is ``image_width_px * gsd_x``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

from .errors import CameraError

#: Tolerance when checking a stated pixel pitch against sensor size / pixel count.
_PITCH_TOLERANCE_RATIO = 0.03


#: Diagonal of the 36 x 24 mm frame that "35 mm equivalent" focal lengths refer to, mm.
FULL_FRAME_DIAGONAL_MM = math.hypot(36.0, 24.0)


class Orientation(StrEnum):
    """How the camera sits relative to the flight line."""

    LANDSCAPE = "landscape"  # image x (width) across track
    PORTRAIT = "portrait"  # image x (width) along track


@dataclass(frozen=True, kw_only=True)
class Footprint:
    """Ground size of one nadir frame over flat ground, metres."""

    along_m: float
    across_m: float

    @property
    def area_m2(self) -> float:
        return self.along_m * self.across_m


@dataclass(frozen=True, kw_only=True)
class Camera:
    """A frame camera with a fixed focal length.

    Parameters (all positive):
        id: database key, e.g. ``"dji-phantom-4-pro"``; free text for a custom camera.
        name: human-readable make and model.
        sensor_width_mm, sensor_height_mm: active sensor area along image x and y.
        image_width_px, image_height_px: image size in pixels along x and y.
        focal_length_mm: real (not 35 mm equivalent) focal length.
        min_trigger_interval_s: shortest time between two photos the camera sustains.
        shutter_s: exposure time used for the blur check, or None if unknown.
        source: where the numbers come from (datasheet, EXIF of a sample image...).
        exif_make, exif_model: how the camera names itself in EXIF, for matching images.
    """

    id: str
    name: str
    sensor_width_mm: float
    sensor_height_mm: float
    image_width_px: int
    image_height_px: int
    focal_length_mm: float
    min_trigger_interval_s: float = 2.0
    shutter_s: float | None = None
    source: str = ""
    exif_make: str | None = None
    exif_model: str | None = None

    def __post_init__(self) -> None:
        positive = {
            "sensor_width_mm": self.sensor_width_mm,
            "sensor_height_mm": self.sensor_height_mm,
            "image_width_px": self.image_width_px,
            "image_height_px": self.image_height_px,
            "focal_length_mm": self.focal_length_mm,
            "min_trigger_interval_s": self.min_trigger_interval_s,
        }
        for key, value in positive.items():
            if not isinstance(value, int | float) or not math.isfinite(value) or value <= 0:
                raise CameraError(
                    f"camera {self.id!r}: {key} = {value!r} is not a positive number; "
                    f"give the real value from the camera's datasheet"
                )
        w_mm, h_mm, w_px, h_px = (
            self.sensor_width_mm, self.sensor_height_mm, self.image_width_px, self.image_height_px
        )  # fmt: skip
        # (out of range, what is wrong and the fix), checked in this order
        ranges = (
            (
                self.shutter_s is not None and not (0 < self.shutter_s < 10),
                f"shutter_s = {self.shutter_s!r} is outside 0-10 s; give the exposure time in seconds, "
                f"e.g. 0.001 for 1/1000 s",
            ),
            (
                not (1.0 <= w_mm <= 100.0 and 1.0 <= h_mm <= 100.0),
                f"sensor {w_mm} x {h_mm} mm is outside 1-100 mm per side; sensor sizes are in millimetres",
            ),
            (
                not (1.0 <= self.focal_length_mm <= 600.0),
                f"focal_length_mm = {self.focal_length_mm} is outside 1-600 mm; give the real focal "
                f"length, not the 35 mm equivalent",
            ),
            (
                not (100 <= w_px <= 40000 and 100 <= h_px <= 40000),
                f"image {w_px} x {h_px} px is outside 100-40000 px per side",
            ),
        )
        for out_of_range, message in ranges:
            if out_of_range:
                raise CameraError(f"camera {self.id!r}: {message}")
        pitch_x_um = self.pixel_pitch_x_mm * 1000.0
        pitch_y_um = self.pixel_pitch_y_mm * 1000.0
        for axis, pitch in (("x", pitch_x_um), ("y", pitch_y_um)):
            if not (0.5 <= pitch <= 25.0):
                raise CameraError(
                    f"camera {self.id!r}: pixel pitch along {axis} = {pitch:.2f} um (sensor size / "
                    f"pixels) is outside 0.5-25 um; check sensor size (mm) against image size (px)"
                )

    # --- pixel pitch and scale -------------------------------------------------------------

    @property
    def pixel_pitch_x_mm(self) -> float:
        """Pixel pitch along image x, mm (sensor width / image width)."""
        return self.sensor_width_mm / self.image_width_px

    @property
    def pixel_pitch_y_mm(self) -> float:
        """Pixel pitch along image y, mm (sensor height / image height)."""
        return self.sensor_height_mm / self.image_height_px

    @property
    def pitch_is_square(self) -> bool:
        return math.isclose(self.pixel_pitch_x_mm, self.pixel_pitch_y_mm, rel_tol=1e-3)

    def scale_number(self, height_agl_m: float) -> float:
        """Scale number s of a vertical photo: 1/s = f / Hg (Eq. 3-1)."""
        return height_agl_m * 1000.0 / self.focal_length_mm

    # --- GSD <-> height (Eq. 3-4) -------------------------------------------------------------

    def gsd_x_cm(self, height_agl_m: float) -> float:
        """GSD along image x at ``height_agl_m`` over flat ground, cm (Eq. 3-4)."""
        return 100.0 * self.pixel_pitch_x_mm * height_agl_m / self.focal_length_mm

    def gsd_y_cm(self, height_agl_m: float) -> float:
        """GSD along image y at ``height_agl_m`` over flat ground, cm (Eq. 3-4)."""
        return 100.0 * self.pixel_pitch_y_mm * height_agl_m / self.focal_length_mm

    def gsd_cm(self, height_agl_m: float) -> float:
        """The coarser of the two axes' GSD, cm: what the survey guarantees."""
        return max(self.gsd_x_cm(height_agl_m), self.gsd_y_cm(height_agl_m))

    def height_for_gsd_m(self, gsd_cm: float) -> float:
        """Height above ground that gives ``gsd_cm`` on the coarser axis (inverse of Eq. 3-4).

        With a square pitch this is QGC's ``H = GSD * f * image_width / (100 * sensor_width)``.
        """
        if not (gsd_cm > 0 and math.isfinite(gsd_cm)):
            raise CameraError(f"gsd_cm = {gsd_cm!r} must be a positive number of centimetres")
        pitch_mm = max(self.pixel_pitch_x_mm, self.pixel_pitch_y_mm)
        return gsd_cm / 100.0 * self.focal_length_mm / pitch_mm

    # --- footprint (Eq. 3-3) ----------------------------------------------------------------------

    def footprint(self, height_agl_m: float, orientation: Orientation) -> Footprint:
        """Ground footprint of a nadir frame over flat ground at ``height_agl_m``."""
        width_m = self.image_width_px * self.gsd_x_cm(height_agl_m) / 100.0
        height_m = self.image_height_px * self.gsd_y_cm(height_agl_m) / 100.0
        if Orientation(orientation) is Orientation.LANDSCAPE:
            return Footprint(along_m=height_m, across_m=width_m)
        return Footprint(along_m=width_m, across_m=height_m)

    def half_fov_rad(self) -> tuple[float, float]:
        """Half field of view along image x and y, radians."""
        return (
            math.atan(self.sensor_width_mm / 2.0 / self.focal_length_mm),
            math.atan(self.sensor_height_mm / 2.0 / self.focal_length_mm),
        )
