"""What an image's tags say about its camera and attitude, beyond position: the camera that took
it (database, EXIF geometry, a camera file) and DJI's gimbal angles in the check's convention.

Camera sources, most to least sure (:class:`CameraChoice` says which was used):

1. given (``--camera ID`` or ``--camera FILE.toml``): what the crew says;
2. the database (:func:`planner.camera_db.match_exif`): a datasheet, matched by EXIF make,
   model, focal length and image size; images of a database camera scaled to another size of
   the same aspect ratio keep its sensor and lens (:func:`resized`);
3. EXIF FocalLength with FocalPlaneX/YResolution (and its unit): the focal length in pixels
   as the camera maker states it. Good to about 1 %; some makers give the resolution of the
   full sensor while the image is a crop, which the check cannot see (hence not "sure"). An
   image reduced after capture keeps its original EXIF: the resolution counts pixels of the
   original width (PixelXDimension), so it is scaled to the file's real width;
4. EXIF FocalLengthIn35mmFilm with the image size: the focal length in pixels from the
   diagonal, f_px = f35 x diagonal_px / 43.27 mm. Rough: the value is a whole number of
   millimetres (+-2 % at 28 mm) and some makers scale by the width instead of the diagonal
   (up to 4 % more for a 4:3 sensor), so GSD and footprints may be off by about 5 %.

Nothing else gives a focal length in pixels: without one of these the check refuses (and the
hand-off guesses, saying so: processing.handoff.intrinsics). :func:`camera_from_tags` makes the
choice from the images' tags for both.

DJI gimbal angles (``drone-dji:GimbalYawDegree``, ``GimbalPitchDegree``, ``GimbalRollDegree``)
are earth-referenced Tait-Bryan angles of the camera (NED-from-gimbal = Rz(yaw) Ry(pitch)
Rx(roll)) whose x axis is the optical axis and z axis the image's down direction; pitch -90
looks straight down with the image top toward the yaw. The check's convention (Pix4D's) has the
camera looking down the body z axis with the image top along the body x axis, which is the
gimbal frame turned by Ry(90). So NED-from-body = Rz(gy) Ry(gp) Rx(gr) Ry(90) = Rz(gy) Ry(gp + 90)
Rz(gr) (a gimbal roll turns the image about the optical axis), and the Pix4D angles are read
back from that matrix: with roll 0 exactly yaw = GimbalYaw, pitch = 90 + GimbalPitch, roll 0.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.camera import FULL_FRAME_DIAGONAL_MM, Camera
from planner.camera_db import camera_from_mapping, get_camera, match_exif
from planner.errors import CameraError

if TYPE_CHECKING:
    from acquisition.exif import CameraTags, ImageTags


class CameraConfidence(StrEnum):
    GIVEN = "given"  # the crew named the camera or gave its numbers
    DATASHEET = "datasheet"  # matched to the database
    FOCAL_PLANE = "focal plane resolution"  # EXIF focal length x focal plane resolution, ~1 %
    EQUIVALENT_35MM = "35 mm equivalent"  # EXIF 35 mm equivalent focal length, ~5 %
    PLAN = "plan"  # the plan's camera, EXIF matched nothing


@dataclass(frozen=True, kw_only=True)
class CameraChoice:
    """The camera of a group of images, where it came from and how sure that is (words)."""

    camera: Camera
    confidence: CameraConfidence
    source: str


def known(value: float | None) -> float | None:
    """An EXIF number that means "unknown" when it is 0 or negative (an exposure time of 0, a
    focal length of 0): None."""
    if value is None or not math.isfinite(value) or value <= 0.0:
        return None
    return float(value)


def display_name(make: str | None, model: str | None) -> str:
    """Make and model as a person says them, without the make twice ("Canon Canon EOS 5D")."""
    make = (make or "").strip()
    model = (model or "").strip()
    if make and model.casefold().startswith(make.casefold()):
        return model
    return " ".join(part for part in (make, model) if part) or "unknown camera"


def load_camera_file(path: str | Path) -> Camera:
    """A camera from a TOML file with the keys of a mission spec's ``[camera]`` table (a database
    ``model`` with overrides, or the five geometry keys); a ``[camera]`` table or the keys at the
    top level. ``orientation`` is accepted and ignored (the images' own attitude says it)."""
    file = Path(path)
    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as error:
        raise CameraError(f"{file}: cannot be read ({error}); give a TOML camera file") from None
    except tomllib.TOMLDecodeError as error:
        raise CameraError(f"{file}: not valid TOML ({error})") from None
    table = data.get("camera", data)
    if not isinstance(table, dict):
        raise CameraError(f"{file}: [camera] must be a table of camera keys")
    fields = {k: v for k, v in table.items() if k != "orientation"}
    return camera_from_mapping(fields, where=str(file))


def camera_option(value: str) -> Camera:
    """``--camera``: a database id, or a path to a TOML camera file (ends in .toml)."""
    if value.lower().endswith(".toml") or Path(value).is_file():
        return load_camera_file(value)
    return get_camera(value)


def _exif_camera(
    *,
    make: str | None,
    model: str | None,
    focal_mm: float | None,
    width_px: int,
    height_px: int,
    focal_plane_x_px_per_mm: float | None,
    focal_plane_y_px_per_mm: float | None,
    focal_35mm_mm: float | None,
    original_width_px: int | None,
) -> CameraChoice | None:
    name = display_name(make, model)
    if focal_mm is not None and focal_plane_x_px_per_mm and focal_plane_y_px_per_mm:
        reduced = ""
        scale = 1.0
        if original_width_px and original_width_px != width_px:
            # The resolution counts pixels of the original image: fewer of the file's own per mm.
            scale = width_px / original_width_px
            reduced = f", image reduced from {original_width_px} px wide"
        # The camera at the images' size; an image reduced so far that its pixels are larger
        # than any sensor's stays the camera at its original size (the same field of view).
        camera = None
        for size_scale in (scale, 1.0) if scale != 1.0 else (1.0,):
            px_mm_x, px_mm_y = focal_plane_x_px_per_mm * size_scale, focal_plane_y_px_per_mm * size_scale
            w_px, h_px = round(width_px * size_scale / scale), round(height_px * size_scale / scale)
            try:
                camera = Camera(
                    id="exif",
                    name=f"{name} (from EXIF)",
                    sensor_width_mm=w_px / px_mm_x,
                    sensor_height_mm=h_px / px_mm_y,
                    image_width_px=w_px,
                    image_height_px=h_px,
                    focal_length_mm=focal_mm,
                    source=(
                        f"EXIF of the images: FocalLength {focal_mm:g} mm, FocalPlaneX/YResolution "
                        f"{px_mm_x:.1f}/{px_mm_y:.1f} px/mm"
                    ),
                    exif_make=make,
                    exif_model=model,
                )
                break
            except CameraError:
                camera = None
        focal_plane_x_px_per_mm *= scale
        if camera is not None:
            f_px = focal_mm * focal_plane_x_px_per_mm
            return CameraChoice(
                camera=camera,
                confidence=CameraConfidence.FOCAL_PLANE,
                source=(
                    f"{name} is not in the database: camera from its EXIF focal length {focal_mm:g} mm and "
                    f"focal plane resolution ({f_px:.0f} px focal length, sensor "
                    f"{camera.sensor_width_mm:.2f} x {camera.sensor_height_mm:.2f} mm{reduced}); good to "
                    "about 1 % unless the maker states the resolution of a larger sensor than the image uses"
                ),
            )
    if focal_35mm_mm is not None:
        diagonal_px = math.hypot(width_px, height_px)
        f_px = focal_35mm_mm * diagonal_px / FULL_FRAME_DIAGONAL_MM
        # Any focal length in mm gives the same pixels; the real one when EXIF has it.
        f_mm = focal_mm if focal_mm is not None else focal_35mm_mm
        pitch_mm = f_mm / f_px
        try:
            camera = Camera(
                id="exif-35mm",
                name=f"{name} (from its 35 mm equivalent focal length)",
                sensor_width_mm=width_px * pitch_mm,
                sensor_height_mm=height_px * pitch_mm,
                image_width_px=width_px,
                image_height_px=height_px,
                focal_length_mm=f_mm,
                source=f"EXIF of the images: FocalLengthIn35mmFilm {focal_35mm_mm:g} mm, image size",
                exif_make=make,
                exif_model=model,
            )
        except CameraError:
            return None
        return CameraChoice(
            camera=camera,
            confidence=CameraConfidence.EQUIVALENT_35MM,
            source=(
                f"{name} is not in the database: camera from its EXIF 35 mm equivalent focal length "
                f"{focal_35mm_mm:g} mm and the image size ({f_px:.0f} px focal length); ROUGH: GSD and "
                "footprints may be off by about 5 % (give --camera FILE.toml for a sure result)"
            ),
        )
    return None


def camera_from_tags(tags: ImageTags, camera_tags: CameraTags | None) -> CameraChoice | None:
    """The camera that took images whose tags are ``tags`` (one representative of a group that
    shares make, model, focal length and image size) from the tags alone: the database, a
    database camera's images scaled, the EXIF geometry (module docstring for the order); None
    when nothing gives a focal length in pixels."""
    name = display_name(tags.make, tags.model)
    focal = known(tags.focal_length_mm)
    matched = match_exif(tags.make, tags.model, focal, tags.width_px, tags.height_px)
    if matched is not None:
        return CameraChoice(
            camera=matched,
            confidence=CameraConfidence.DATASHEET,
            source=(
                f"EXIF {name} matched to the database camera {matched.id} ({matched.source.split(';')[0]})"
            ),
        )
    if tags.width_px and tags.height_px:
        # A database camera whose images were scaled (a copy resized for the web or a test set):
        # the same sensor and lens, fewer pixels. EXIF focal plane tags copied along with the
        # rest would describe the original size, so the database wins.
        same_body = match_exif(tags.make, tags.model, focal, None, None)
        if same_body is not None:
            w, h = int(tags.width_px), int(tags.height_px)
            if w < h and same_body.image_width_px > same_body.image_height_px:
                w, h = h, w
            if abs(w / h - same_body.image_width_px / same_body.image_height_px) < 0.01 * w / h:
                camera = resized(same_body, w, h)
                return CameraChoice(
                    camera=camera,
                    confidence=CameraConfidence.DATASHEET,
                    source=(
                        f"EXIF {name} matched to the database camera {same_body.id}, its images scaled from "
                        f"{same_body.image_width_px}x{same_body.image_height_px} to {w}x{h} px (same sensor "
                        "and lens; EXIF focal plane tags of a scaled copy describe the original size)"
                    ),
                )
    if tags.width_px and tags.height_px and camera_tags is not None:
        return _exif_camera(
            make=tags.make,
            model=tags.model,
            focal_mm=focal,
            width_px=int(tags.width_px),
            height_px=int(tags.height_px),
            focal_plane_x_px_per_mm=camera_tags.focal_plane_x_px_per_mm,
            focal_plane_y_px_per_mm=camera_tags.focal_plane_y_px_per_mm,
            focal_35mm_mm=camera_tags.focal_length_35mm_mm,
            original_width_px=camera_tags.pixel_x_dimension_px,
        )
    return None


def given_choice(camera: Camera) -> CameraChoice:
    """The camera the crew gave (``--camera``)."""
    return CameraChoice(
        camera=camera, confidence=CameraConfidence.GIVEN, source=f"given: {camera.id} ({camera.name})"
    )


def choose_camera(
    tags: ImageTags,
    camera_tags: CameraTags | None,
    *,
    given: Camera | None = None,
    fallback: Camera | None = None,
    where: str = "images",
) -> CameraChoice:
    """The camera of images whose tags are ``tags``: ``given``, else :func:`camera_from_tags`,
    else ``fallback`` (the plan's camera). Raises CameraError naming what is missing when
    nothing gives a focal length in pixels."""
    if given is not None:
        return given_choice(given)
    choice = camera_from_tags(tags, camera_tags)
    if choice is not None:
        return choice
    name = display_name(tags.make, tags.model)
    if fallback is not None:
        return CameraChoice(
            camera=fallback,
            confidence=CameraConfidence.PLAN,
            source=f"the plan's camera {fallback.id} (EXIF {name} matches no database camera)",
        )
    focal = known(tags.focal_length_mm)
    focal_text = f"{focal:g} mm" if focal is not None else "unknown"
    raise CameraError(
        f"{where}: no focal length in pixels for {name} (EXIF focal length {focal_text}, image "
        f"{tags.width_px}x{tags.height_px} px; no focal plane resolution and no 35 mm equivalent focal "
        "length in EXIF, and not in the database); give the camera: --camera ID (`sfap cameras` lists them) "
        "or --camera FILE.toml with sensor_width_mm, sensor_height_mm, image_width_px, image_height_px, "
        "focal_length_mm"
    )


def resized(camera: Camera, width_px: int, height_px: int) -> Camera:
    """The same camera writing images of another size (a scaled copy keeps the field of view)."""
    return dataclasses.replace(camera, image_width_px=width_px, image_height_px=height_px)


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def pix4d_from_dji_gimbal(
    gimbal_yaw_deg: float, gimbal_pitch_deg: float, gimbal_roll_deg: float
) -> tuple[float, float, float]:
    """Pix4D (yaw, pitch, roll) degrees of a camera from DJI's earth-referenced gimbal angles
    (module docstring). Yaw in 0-360."""
    r = (
        _rz(math.radians(gimbal_yaw_deg))
        @ _ry(math.radians(gimbal_pitch_deg + 90.0))
        @ _rz(math.radians(gimbal_roll_deg))
    )
    # r = Rz(yaw) Ry(pitch) Rx(roll): read the Tait-Bryan angles back.
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, -r[2, 0]))))
    yaw = math.degrees(math.atan2(r[1, 0], r[0, 0])) % 360.0
    roll = math.degrees(math.atan2(r[2, 1], r[2, 2]))
    return yaw, pitch, roll
