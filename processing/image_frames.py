"""Frames from a folder of geotagged JPEGs (what a check of a flown block starts from).

Position from EXIF GPS (altitude AMSL), or DJI's XMP relative altitude when every frame carries
it; attitude from the Pix4D XMP camera tags or DJI's gimbal angles when every frame carries one,
else nadir with the image top along the track
(:attr:`~processing.frames.AttitudeSource.ASSUMED_NADIR`); the camera from the database, the
EXIF geometry or a file (:mod:`processing.image_tags`). An image without a real position, or
of another camera or image size than the block's, is never guessed: it is listed, with why.
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from planner.camera import Camera

from .errors import FramesError, NoPositionsError
from .frames import AltitudeReference, AttitudeSource, Frames
from .image_tags import CameraConfidence, choose_camera, display_name, known, pix4d_from_dji_gimbal
from .track import track_heading_deg

if TYPE_CHECKING:
    from acquisition.exif import CameraTags, ImageTags

log = logging.getLogger(__name__)

#: File suffixes read as images (case-insensitive).
IMAGE_SUFFIXES = (".jpg", ".jpeg")


@dataclass(frozen=True, kw_only=True)
class ImageFrames:
    """The frames read from an image folder and what could not be used.

    - ``frames``: one row per image that is checked, in capture order.
    - ``unpositioned``: names of the images left out for want of a real position (never guessed).
    - ``left_out``: (name, reason) of every image left out: no or placeholder position, another
      camera or image size than the block's.
    - ``camera_source``: how the camera was found, and how sure that is.
    - ``notes``: what was assumed, in words for the report (attitude, times, altitudes).
    - ``warnings``: what may make the figures wrong (altitudes that disagree or drift...).
    """

    frames: Frames
    unpositioned: tuple[str, ...] = ()
    camera_source: str = ""
    notes: tuple[str, ...] = ()
    left_out: tuple[tuple[str, str], ...] = ()
    warnings: tuple[str, ...] = ()
    camera_confidence: str = ""


def image_paths(folder: str | os.PathLike[str]) -> list[Path]:
    """The JPEG files directly in ``folder``, sorted by name."""
    root = Path(folder)
    if not root.is_dir():
        raise FramesError(f"{root} is not a folder; give the folder that holds the images")
    paths = sorted(p for p in root.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)
    if not paths:
        raise FramesError(
            f"{root} holds no JPEG image (.jpg/.jpeg); give the folder of geotagged images or a plan folder "
            "written by `sfap plan`"
        )
    return paths


def read_image_frames(
    folder: str | os.PathLike[str],
    *,
    camera: Camera | None = None,
    fallback_camera: Camera | None = None,
    progress: Callable[[int], None] | None = None,
) -> ImageFrames:
    """Read every JPEG in ``folder`` as a frame (see the module docstring for the rules).

    ``camera``: the camera that took the images; None to find it from their EXIF
    (:func:`processing.image_tags.choose_camera`: the database, else the EXIF geometry, else
    ``fallback_camera``, e.g. the plan's; else a CameraError names what is missing).
    ``progress(1)`` is called after each image read. A JPEG whose end marker is missing or
    damaged is read like any other (only its metadata is needed). Raises FramesError when no
    image has a real position.
    """
    tags, extras, unreadable = read_readable_tags(folder, progress=progress)
    if not tags:
        listed = "; ".join(f"{name} ({why})" for name, why in unreadable[:5])
        more = f"; and {len(unreadable) - 5} more" if len(unreadable) > 5 else ""
        raise FramesError(
            f"{folder}: none of its {len(unreadable)} JPEG file(s) can be read ({listed}{more}); give the "
            "folder of the survey's images"
        )
    result = frames_from_tags(
        tags, camera=camera, fallback_camera=fallback_camera, where=str(folder), camera_tags=extras
    )
    if not unreadable:
        return result
    log.warning(
        "%d unreadable file(s) left out: %s", len(unreadable), summarise_names([n for n, _ in unreadable])
    )
    return replace(result, left_out=(*unreadable, *result.left_out))


def summarise_names(names: Sequence[str], shown: int = 10) -> str:
    """The first ``shown`` names and how many more (a card's list fits one line)."""
    listed = ", ".join(names[:shown])
    return listed + (f" and {len(names) - shown} more" if len(names) > shown else "")


def summarise_reasons(left_out: Sequence[tuple[str, str]], shown: int = 4) -> str:
    """Reasons grouped by kind (the words before their figures in parentheses), most frequent
    first, each with its count and one example: a card of 123 placeholder positions is one line."""
    groups: dict[str, list[str]] = {}
    for name, why in left_out:
        groups.setdefault(why.split(" (", 1)[0], []).append(f"{name}: {why}")
    ordered = sorted(groups.items(), key=lambda item: -len(item[1]))
    parts = [f"{len(items)} x {kind}, e.g. {items[0]}" for kind, items in ordered[:shown]]
    if len(ordered) > shown:
        parts.append(f"{sum(len(items) for _, items in ordered[shown:])} more of other kinds")
    return "; ".join(parts)


def read_readable_tags(
    folder: str | os.PathLike[str], *, progress: Callable[[int], None] | None = None
) -> tuple[list[ImageTags], list[CameraTags], list[tuple[str, str]]]:
    """As :func:`read_folder_tags`, but a file that cannot be read as a JPEG (empty, truncated
    before its header, another format under a .jpg name) is left out: (tags, camera tags,
    [(name, why)] of the files left out)."""
    from acquisition.errors import GeotagError
    from acquisition.exif import read_tags_and_camera

    tags: list[ImageTags] = []
    extras: list[CameraTags] = []
    unreadable: list[tuple[str, str]] = []
    for path in image_paths(folder):
        try:
            image_tags, camera_tags = read_tags_and_camera(path)
        except (GeotagError, OSError) as error:
            why = str(error).removeprefix(f"{path}: ")
            if path.stat().st_size == 0:
                why = "an empty file (0 bytes)"
            unreadable.append((path.name, f"unreadable: {why.removesuffix('; remove it from the folder')}"))
        else:
            tags.append(image_tags)
            extras.append(camera_tags)
        if progress is not None:
            progress(1)
    return tags, extras, unreadable


def read_folder_tags(
    folder: str | os.PathLike[str], *, progress: Callable[[int], None] | None = None
) -> tuple[list[ImageTags], list[CameraTags]]:
    """The tags and camera tags of every JPEG in ``folder`` (:func:`image_paths`' order), each
    file's header read once; ``progress(1)`` after each image (the check and the hand-off)."""
    from acquisition.exif import read_tags_and_camera  # pyexiv2 is only needed for images

    tags: list[ImageTags] = []
    extras: list[CameraTags] = []
    for path in image_paths(folder):
        image_tags, camera_tags = read_tags_and_camera(path)
        tags.append(image_tags)
        extras.append(camera_tags)
        if progress is not None:
            progress(1)
    return tags, extras


def frames_from_images(folder: str | os.PathLike[str], *, camera: Camera | None = None) -> Frames:
    """The frames of every image in ``folder``; FramesError if any image has no position.

    The error lists the images; :func:`read_image_frames` reads the others and lists them.
    """
    result = read_image_frames(folder, camera=camera)
    if result.unpositioned:
        raise FramesError(
            f"{len(result.unpositioned)} image(s) in {folder} have no GPS position: "
            f"{', '.join(result.unpositioned)}; geotag them (`sfap geotag`) or move them out"
        )
    return result.frames


#: A position within this many degrees of 0 N 0 E is a placeholder a receiver writes without a
#: fix (about 110 m at the equator: the Gulf of Guinea, where nobody flies a land survey).
PLACEHOLDER_DEG = 1e-3
#: Altitudes that drift by more than this over a flight (or disagree between the relative and
#: the absolute tag by more than this) are reported, metres.
ALTITUDE_DISAGREEMENT_M = 10.0


def _position(t: ImageTags, relative: bool) -> tuple[tuple[float, float, float] | None, str]:
    """(lon, lat, alt) of a frame, or None and why not."""
    lat = t.gps_lat_deg if t.gps_lat_deg is not None else t.dji_lat_deg
    lon = t.gps_lon_deg if t.gps_lon_deg is not None else t.dji_lon_deg
    alt = t.dji_alt_rel_home_m if relative else t.gps_alt_amsl_m
    if alt is None and not relative:
        alt = t.dji_alt_amsl_m
    if lat is None or lon is None:
        return None, "no GPS position (EXIF GPSLatitude/GPSLongitude)"
    if alt is None:
        return None, "no GPS altitude (EXIF GPSAltitude)"
    if not (-90 <= lat <= 90 and -180 <= lon <= 180 and math.isfinite(alt)):
        return None, f"GPS position out of range (lat {lat}, lon {lon}, alt {alt})"
    if abs(lat) < PLACEHOLDER_DEG and abs(lon) < PLACEHOLDER_DEG:
        return None, f"placeholder position at 0/0 (lat {lat:.7f}, lon {lon:.7f}): written without a GPS fix"
    if alt == 0.0 and not relative:
        return None, "placeholder altitude of exactly 0 m (written without a GPS fix)"
    return (lon, lat, alt), ""


def _camera_key(t: ImageTags) -> tuple[Any, ...]:
    # A frame written in portrait (width and height swapped) is the same camera and size.
    focal = known(t.focal_length_mm)
    w, h = t.width_px, t.height_px
    if w is not None and h is not None and h > w:
        w, h = h, w
    return (t.make, t.model, None if focal is None else round(focal, 2), w, h)


def _describe_key(key: tuple[Any, ...]) -> str:
    make, model, focal, width, height = key
    focal_text = f"{focal:g} mm" if focal is not None else "focal length unknown"
    return f"{display_name(make, model)}, {focal_text}, {width}x{height} px"


def frames_from_tags(
    tags: Sequence[ImageTags],
    *,
    camera: Camera | None = None,
    fallback_camera: Camera | None = None,
    where: str = "images",
    camera_tags: Sequence[CameraTags] | None = None,
) -> ImageFrames:
    """Frames from tags already read (:func:`acquisition.exif.read_tags_and_camera`); rules as
    :func:`read_image_frames`.

    - Positions: an image without a position, with one outside the globe, at 0/0 (within
      :data:`PLACEHOLDER_DEG`) or at an altitude of exactly 0 m is left out, with the reason.
    - Cameras: images are grouped by make, model, focal length and image size; the largest
      group is checked and the others are left out with a note (check them in a folder of
      their own), never the whole block refused.
    - Altitudes: DJI's XMP RelativeAltitude (above take-off) when every frame carries it, else
      EXIF GPSAltitude (AMSL). Where both DJI tags are present their difference must stay
      constant; a spread over :data:`ALTITUDE_DISAGREEMENT_M` is a warning with the figures.
    - Attitude: Pix4D XMP Camera:Yaw/Pitch/Roll, or DJI's gimbal angles
      (:func:`processing.image_tags.pix4d_from_dji_gimbal`), when every frame has one of them.
    - EXIF values meaning "unknown" (exposure time or focal length 0) are unknown.
    """
    if not tags:
        raise FramesError(f"{where}: no images")
    extras: list[CameraTags | None] = list(camera_tags) if camera_tags is not None else [None] * len(tags)
    if len(extras) != len(tags):
        raise ValueError(f"{len(extras)} camera tags for {len(tags)} images")
    notes: list[str] = []
    warnings: list[str] = []
    left_out: list[tuple[str, str]] = []
    relative = all(t.dji_alt_rel_home_m is not None for t in tags)

    kept: list[tuple[ImageTags, CameraTags | None, tuple[float, float, float]]] = []
    unpositioned: list[str] = []
    for t, extra in zip(tags, extras, strict=True):
        pos, why = _position(t, relative)
        if pos is None:
            unpositioned.append(t.name)
            left_out.append((t.name, why))
        else:
            kept.append((t, extra, pos))
    if unpositioned:
        log.warning(
            "%d image(s) without a real GPS position are left out of the check: %s",
            len(unpositioned),
            summarise_names(unpositioned),
        )
    if not kept:
        raise NoPositionsError(
            f"{where}: no GPS positions: geotag first (`sfap geotag IMAGES --log FLIGHT_LOG -o TAGGED`); "
            f"none of the {len(tags)} images has a real position ({summarise_reasons(left_out)})",
            names=tuple(t.name for t in tags),
        )

    # One camera and image size per check: the largest group; the others are listed.
    groups: dict[tuple[Any, ...], list[int]] = {}
    for k, (t, _, _) in enumerate(kept):
        groups.setdefault(_camera_key(t), []).append(k)
    main_key = max(groups, key=lambda key: len(groups[key]))
    if len(groups) > 1:
        for key, members in groups.items():
            if key == main_key:
                continue
            for k in members:
                left_out.append(
                    (
                        kept[k][0].name,
                        f"another camera or image size ({_describe_key(key)}; the block's is "
                        f"{_describe_key(main_key)}): check it on its own (its own folder)",
                    )
                )
        notes.append(
            f"{len(kept) - len(groups[main_key])} image(s) of another camera or image size left out; "
            f"checked: the {len(groups[main_key])} images of {_describe_key(main_key)}"
        )
        kept = [kept[k] for k in groups[main_key]]
    first_tags, first_extra, _ = kept[0]
    choice = choose_camera(first_tags, first_extra, given=camera, fallback=fallback_camera, where=where)
    used_camera = choice.camera
    if first_tags.width_px and first_tags.height_px and camera is not None:
        size = {(first_tags.width_px, first_tags.height_px), (first_tags.height_px, first_tags.width_px)}
        if (used_camera.image_width_px, used_camera.image_height_px) not in size:
            warnings.append(
                f"the camera given ({used_camera.id}) writes {used_camera.image_width_px}x"
                f"{used_camera.image_height_px} px images but these are {first_tags.width_px}x"
                f"{first_tags.height_px} px: pixel figures (GSD per pixel, blur) assume the camera's size"
            )
    if choice.confidence is CameraConfidence.EQUIVALENT_35MM:
        warnings.append(choice.source)

    # Capture order: GPS time (UTC, sub-second on most drones) when every frame has it, else
    # the camera clock; its offset to UTC does not matter for ordering or for speeds.
    times: np.ndarray | None = None
    if all(t.gps_time_utc_s is not None for t, _, _ in kept):
        times = np.array([t.gps_time_utc_s for t, _, _ in kept], dtype=np.float64)
    elif all(t.capture_time_s is not None for t, _, _ in kept):
        times = np.array([t.capture_time_s for t, _, _ in kept], dtype=np.float64)
        if not all(t.capture_time_zone_known for t, _, _ in kept):
            notes.append(
                "capture times from the camera clock (time zone unknown): speeds are right, clock times may "
                "be offset"
            )
    else:
        notes.append("no capture time on every image: frames ordered by file name, no speeds or blur")
    order = np.argsort(times, kind="stable") if times is not None else np.arange(len(kept))
    kept = [kept[i] for i in order]
    if times is not None:
        times = times[order]

    lon = np.array([p[0] for _, _, p in kept], dtype=np.float64)
    lat = np.array([p[1] for _, _, p in kept], dtype=np.float64)
    alt = np.array([p[2] for _, _, p in kept], dtype=np.float64)
    reference = AltitudeReference.REL_HOME if relative else AltitudeReference.AMSL
    if relative:
        notes.append("altitudes from DJI XMP RelativeAltitude (above the take-off point)")
        absolute = [
            t.dji_alt_amsl_m if t.dji_alt_amsl_m is not None else t.gps_alt_amsl_m for t, _, _ in kept
        ]
        if all(a is not None for a in absolute):
            offset = np.array(absolute, dtype=np.float64) - alt
            spread = float(offset.max() - offset.min())
            if spread > ALTITUDE_DISAGREEMENT_M:
                warnings.append(
                    f"the absolute (GPS) and relative altitudes disagree: absolute minus relative runs from "
                    f"{offset.min():.1f} to {offset.max():.1f} m ({spread:.1f} m apart; it should stay the "
                    "take-off elevation): the GPS altitude drifted. Heights above ground and GSD use the "
                    "relative altitude (barometric, above take-off), which does not drift this way"
                )
    else:
        notes.append("altitudes from EXIF GPSAltitude (above mean sea level)")

    attitude, yaw, pitch, roll = _attitudes(kept, lon, lat, notes)

    exposure: np.ndarray | None = None
    exposures = [known(t.exposure_time_s) for t, _, _ in kept]
    unknown_exposure = sum(1 for e in exposures if e is None)
    if unknown_exposure < len(kept):
        fill = used_camera.shutter_s if used_camera.shutter_s is not None else math.nan
        exposure = np.array([e if e is not None else fill for e in exposures], dtype=np.float64)
        if unknown_exposure:
            notes.append(
                f"exposure time unknown (missing or 0 in EXIF) on {unknown_exposure} image(s): "
                + (
                    f"the camera's {used_camera.shutter_s:g} s used"
                    if used_camera.shutter_s is not None
                    else "blur not computed for them"
                )
            )
    elif used_camera.shutter_s is not None:
        exposure = np.full(len(kept), used_camera.shutter_s)
        notes.append(
            f"no exposure time in EXIF (missing or 0): the camera's {used_camera.shutter_s:g} s used"
        )
    else:
        notes.append("no exposure time in EXIF (missing or 0): blur not computed")

    frames = Frames(
        name=tuple(t.name for t, _, _ in kept),
        lon_deg=lon,
        lat_deg=lat,
        alt_m=alt,
        alt_reference=reference,
        yaw_deg=yaw,
        pitch_deg=pitch,
        roll_deg=roll,
        attitude_source=attitude,
        camera=used_camera,
        time_utc_s=times,
        exposure_s=exposure,
        line_index=None,
    )
    if left_out:
        shown = "; ".join(f"{name}: {why}" for name, why in left_out[:10])
        more = f"; and {len(left_out) - 10} more (report.json lists them all)" if len(left_out) > 10 else ""
        notes.append(f"{len(left_out)} image(s) left out: {shown}{more}")
    return ImageFrames(
        frames=frames,
        unpositioned=tuple(unpositioned),
        camera_source=choice.source,
        camera_confidence=choice.confidence.value,
        notes=tuple(notes),
        left_out=tuple(left_out),
        warnings=tuple(warnings),
    )


def _attitudes(
    kept: Sequence[tuple[ImageTags, CameraTags | None, tuple[float, float, float]]],
    lon: np.ndarray,
    lat: np.ndarray,
    notes: list[str],
) -> tuple[AttitudeSource, np.ndarray, np.ndarray, np.ndarray]:
    """Per-frame (yaw, pitch, roll) in the Pix4D convention, from Pix4D XMP or DJI gimbal XMP."""
    angles: list[tuple[float, float, float] | None] = []
    dji = 0
    for t, extra, _ in kept:
        if t.camera_yaw_deg is not None and t.camera_pitch_deg is not None:
            angles.append((t.camera_yaw_deg, t.camera_pitch_deg, t.camera_roll_deg or 0.0))
        elif extra is not None and extra.gimbal_yaw_deg is not None and extra.gimbal_pitch_deg is not None:
            angles.append(
                pix4d_from_dji_gimbal(
                    extra.gimbal_yaw_deg, extra.gimbal_pitch_deg, extra.gimbal_roll_deg or 0.0
                )
            )
            dji += 1
        else:
            angles.append(None)
    if all(a is not None for a in angles):
        values = np.array(angles, dtype=np.float64)
        if dji:
            notes.append(
                f"attitude from DJI XMP gimbal angles on {dji} image(s) (earth-referenced; GimbalPitch -90 = "
                "nadir: pitch = 90 + GimbalPitchDegree, yaw = GimbalYawDegree)"
                + ("" if dji == len(kept) else ", Pix4D XMP camera tags on the others")
            )
        else:
            notes.append("attitude from the images' XMP camera tags (Camera:Yaw/Pitch/Roll)")
        return AttitudeSource.XMP, values[:, 0] % 360.0, values[:, 1], values[:, 2]
    # Landscape mounting (image top forward) is what multirotor mapping cameras use; the
    # report says the attitude was assumed.
    yaw = track_heading_deg(lon, lat)
    missing = sum(1 for a in angles if a is None)
    notes.append(
        f"attitude ASSUMED: {missing} of {len(kept)} images carry no XMP camera attitude (Pix4D or DJI "
        "gimbal), "
        "so every frame is taken as nadir with the image top along the track"
    )
    log.warning(notes[-1])
    return AttitudeSource.ASSUMED_NADIR, yaw, np.zeros_like(yaw), np.zeros_like(yaw)
