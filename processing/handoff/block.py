"""The block to hand off: every image, its camera, and its pose prior in a local metric frame.

Images are read with :func:`acquisition.exif.read_tags_and_camera`; images from different cameras (make,
model, focal length, image size) get one camera each. Positioned images become
:class:`~processing.frames.Frames` through :func:`processing.image_frames.frames_from_tags` (one call
per camera, so each has its camera) and are projected onto the ground with
:func:`processing.footprints.project_footprints` for the image pairs. Images without a position
stay in the block, with no prior, and the block says so.

The local frame is :func:`processing.frames.local_frame_at` the median camera position (a
transverse Mercator, metres east and north, scale 1 at its origin); z is the camera altitude
in the frames' own reference (EXIF: above mean sea level). The project files name it.

Pose-prior accuracy: Pix4D's XMP GPSXYAccuracy / GPSZAccuracy (standard deviations, metres)
when the image carries them, else :data:`DEFAULT_SIGMA_XY_M` / :data:`DEFAULT_SIGMA_Z_M`.
"""

from __future__ import annotations

import logging
import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from planner.camera import Camera
from planner.errors import CameraError
from planner.geo import LocalFrame

from ..frames import AltitudeReference, Frames, local_frame_at
from ..image_frames import frames_from_tags, read_folder_tags
from .errors import HandoffInputError
from .intrinsics import Intrinsics, intrinsics_for

if TYPE_CHECKING:
    pass

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]

#: Pose-prior standard deviations when the images carry none: a consumer GNSS receiver.
DEFAULT_SIGMA_XY_M = 5.0
DEFAULT_SIGMA_Z_M = 10.0


@dataclass(frozen=True, kw_only=True)
class Block:
    """Every image of the block (sorted by capture time when known, else by name).

    - ``camera_index``: (N,) index into ``intrinsics`` of each image's camera.
    - ``has_position``: (N,) the image carries a usable GPS position.
    - ``position_m``: (N, 3) x east, y north in ``frame``, z altitude (``alt_reference``);
      rows without a position are 0 and masked by ``has_position``.
    - ``lon_deg``, ``lat_deg``, ``alt_m``: (N,) the same in WGS84 (0 where unpositioned).
    - ``sigma_xy_m``, ``sigma_z_m``: (N,) prior standard deviations; ``sigma_source`` says whence.
    - ``frames``: the positioned images of each camera as Frames (for footprints), aligned with
      ``frame_rows`` (their rows in the block).
    """

    image_dir: Path
    names: tuple[str, ...]
    camera_index: NDArray[np.intp]
    intrinsics: tuple[Intrinsics, ...]
    has_position: NDArray[np.bool_]
    position_m: F64
    lon_deg: F64
    lat_deg: F64
    alt_m: F64
    alt_reference: AltitudeReference | None
    sigma_xy_m: F64
    sigma_z_m: F64
    sigma_source: str
    frame: LocalFrame | None
    frames: tuple[Frames, ...]
    frame_rows: tuple[NDArray[np.intp], ...]
    notes: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.names)

    @property
    def unpositioned(self) -> tuple[str, ...]:
        return tuple(n for n, ok in zip(self.names, self.has_position, strict=True) if not ok)

    @property
    def frame_description(self) -> str:
        if self.frame is None:
            return "none (no image has a position)"
        ref = self.alt_reference.value if self.alt_reference is not None else "unknown"
        return f"{proj_string(self.frame)} ; z = camera altitude ({ref})"


def proj_string(frame: LocalFrame) -> str:
    """The frame's PROJ string (exact for the transverse Mercator frames made here; pyproj warns
    that a PROJ string may lose information, which holds for other CRSs only)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return str(frame.crs.to_proj4())


def _camera(intr: Intrinsics, given: Camera | None = None) -> Camera:
    """A planner Camera for the footprints of images of this camera (only its field of view
    matters there)."""
    if given is not None:
        return given
    make, model, _, w, h = intr.key
    if intr.focal_length_mm and intr.pixel_pitch_mm:
        f_mm, pitch = intr.focal_length_mm, intr.pixel_pitch_mm
    else:  # the footprint only needs the field of view: a nominal 1 um pixel
        pitch = 0.001
        f_mm = intr.focal_px * pitch
    try:
        return _fov_camera(intr, make, model, w, h, f_mm, pitch)
    except CameraError as error:
        raise HandoffInputError(
            f"{intr.label}: no camera the footprints can use ({error}); give the camera: --camera ID "
            "(`sfap cameras` lists them) or --camera FILE.toml"
        ) from None


def _fov_camera(intr: Intrinsics, make: str, model: str, w: int, h: int, f_mm: float, pitch: float) -> Camera:
    return Camera(
        id=f"{make}-{model}".lower().replace(" ", "-") or "camera",
        name=intr.label,
        sensor_width_mm=w * pitch,
        sensor_height_mm=h * pitch,
        image_width_px=w,
        image_height_px=h,
        focal_length_mm=f_mm,
        source=intr.source,
        exif_make=make or None,
        exif_model=model or None,
    )


def read_block(
    image_dir: str | os.PathLike[str],
    *,
    camera: Camera | None = None,
    progress: Callable[[int], None] | None = None,
) -> Block:
    """Read every JPEG in ``image_dir`` into a :class:`Block` (module docstring)."""
    tags, camera_tags = read_folder_tags(image_dir, progress=progress)
    notes: list[str] = []
    # Cameras: one per (make, model, focal length, image size).
    groups: dict[tuple[str, str, float, int, int], list[int]] = {}
    for k, t in enumerate(tags):
        if not t.width_px or not t.height_px:
            raise HandoffInputError(f"{t.path}: the image size cannot be read; remove or replace the file")
        key = (
            t.make or "",
            t.model or "",
            float(t.focal_length_mm or 0.0),
            int(t.width_px),
            int(t.height_px),
        )
        groups.setdefault(key, []).append(k)
    intrinsics: list[Intrinsics] = []
    camera_of = np.zeros(len(tags), dtype=np.intp)
    for c, (_key, members) in enumerate(groups.items()):
        t0 = tags[members[0]]
        assert t0.width_px is not None and t0.height_px is not None
        intr = intrinsics_for(t0, camera_tags[members[0]], given=camera)
        intrinsics.append(intr)
        camera_of[members] = c
    if len(groups) > 1:
        notes.append(
            f"{len(groups)} cameras: "
            + "; ".join(f"{i.label} ({int((camera_of == c).sum())} images)" for c, i in enumerate(intrinsics))
            + " (one camera each)"
        )

    # Order: capture time when every image has one, else name.
    times = [t.gps_time_utc_s if t.gps_time_utc_s is not None else t.capture_time_s for t in tags]
    order = (
        sorted(range(len(tags)), key=lambda k: (times[k], tags[k].name))
        if all(x is not None for x in times)
        else list(range(len(tags)))
    )
    tags = [tags[k] for k in order]
    camera_of = camera_of[order]
    names = tuple(t.name for t in tags)
    row_of = {n: k for k, n in enumerate(names)}

    n = len(tags)
    lon = np.zeros(n)
    lat = np.zeros(n)
    alt = np.zeros(n)
    has = np.zeros(n, dtype=bool)
    frames_list: list[Frames] = []
    rows_list: list[NDArray[np.intp]] = []
    reference: AltitudeReference | None = None
    for c, intr in enumerate(intrinsics):
        group = [tags[k] for k in range(n) if camera_of[k] == c]
        positioned = [
            t
            for t in group
            if (t.gps_lat_deg is not None or t.dji_lat_deg is not None)
            and (
                t.gps_alt_amsl_m is not None
                or t.dji_alt_rel_home_m is not None
                or t.dji_alt_amsl_m is not None
            )
        ]
        if not positioned:
            continue
        result = frames_from_tags(positioned, camera=_camera(intr, camera), where=str(image_dir))
        f = result.frames
        if reference is not None and f.alt_reference is not reference:
            raise HandoffInputError(
                f"{image_dir}: the cameras' altitudes have different references ({reference.value} and "
                f"{f.alt_reference.value}); hand off one camera at a time"
            )
        reference = f.alt_reference
        rows = np.array([row_of[name] for name in f.name], dtype=np.intp)
        lon[rows], lat[rows], alt[rows] = f.lon_deg, f.lat_deg, f.alt_m
        has[rows] = True
        frames_list.append(f)
        rows_list.append(rows)
        notes.extend(x for x in result.notes if "without a GPS position" not in x and x not in notes)

    frame: LocalFrame | None = None
    position = np.zeros((n, 3))
    if has.any():
        frame = local_frame_at(float(np.median(lon[has])), float(np.median(lat[has])))
        x, y = frame.to_xy(lon[has], lat[has])
        position[has] = np.column_stack([x, y, alt[has]])
    missing = [names[k] for k in range(n) if not has[k]]
    if missing and has.any():
        notes.append(
            f"{len(missing)} of {n} images have no position and get no pose prior: "
            + ", ".join(missing[:10])
            + (" ..." if len(missing) > 10 else "")
        )
    elif missing:
        notes.append(
            f"none of the {n} images has a position: no pose priors, every pair is matched; the model is "
            "placed by ground control (--gcp) or not at all"
        )

    sxy = np.array([t.xy_accuracy_m if t.xy_accuracy_m else np.nan for t in tags])
    sz = np.array([t.z_accuracy_m if t.z_accuracy_m else np.nan for t in tags])
    tagged = np.isfinite(sxy) & np.isfinite(sz) & has
    if has.any() and tagged[has].all():
        source = "the images' XMP Camera:GPSXYAccuracy / GPSZAccuracy"
    elif tagged.any():
        source = (
            f"XMP GPSXYAccuracy / GPSZAccuracy where present, else {DEFAULT_SIGMA_XY_M:g} m / "
            f"{DEFAULT_SIGMA_Z_M:g} m"
        )
    else:
        source = (
            f"default {DEFAULT_SIGMA_XY_M:g} m horizontal, {DEFAULT_SIGMA_Z_M:g} m vertical "
            "(no accuracy tags)"
        )
    sxy = np.where(tagged, sxy, DEFAULT_SIGMA_XY_M)
    sz = np.where(tagged, sz, DEFAULT_SIGMA_Z_M)
    return Block(
        image_dir=Path(image_dir).resolve(),
        names=names,
        camera_index=camera_of,
        intrinsics=tuple(intrinsics),
        has_position=has,
        position_m=position,
        lon_deg=lon,
        lat_deg=lat,
        alt_m=alt,
        alt_reference=reference,
        sigma_xy_m=sxy,
        sigma_z_m=sz,
        sigma_source=source,
        frame=frame,
        frames=tuple(frames_list),
        frame_rows=tuple(rows_list),
        notes=tuple(notes),
    )
