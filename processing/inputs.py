"""What a coverage check starts from: frames (from images or a plan folder) and the ground.

- :func:`read_image_frames` / :func:`frames_from_images`: a folder of geotagged JPEGs. Position
  from EXIF GPS (altitude AMSL), or DJI's XMP relative altitude when every frame carries it;
  attitude from the Pix4D XMP camera tags or DJI's gimbal angles when every frame carries one,
  else nadir with the image top along the track
  (:attr:`~processing.frames.AttitudeSource.ASSUMED_NADIR`); the camera from the database, the
  EXIF geometry or a file (:mod:`processing.image_tags`). An image without a real position, or
  of another camera or image size than the block's, is never guessed: it is listed, with why.
- :func:`frames_from_plan`: a folder written by ``sfap plan`` (stations.geojson, summary.json,
  area.geojson): every planned station as a frame, altitudes relative to home.
- :func:`ground_from_options`: the ground those altitudes are measured against. Height above
  ground is the critical unknown of a field check (REFERENCES.md section 5), so nothing is
  assumed silently: EXIF altitudes are AMSL and need a ground elevation or a DEM; plan
  altitudes are relative to home, over flat ground at home unless a DEM and the take-off
  elevation say otherwise. The choice is named in :attr:`GroundChoice.description`.
"""

from __future__ import annotations

import json
import logging
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pyproj import CRS, Geod
from shapely.geometry import MultiPolygon, Polygon, shape

from planner.camera import Camera, Orientation
from planner.camera_db import get_camera
from planner.errors import CameraError
from planner.geo import LocalFrame

from .errors import FramesError, GroundError
from .frames import AltitudeReference, AttitudeSource, Frames
from .image_tags import CameraConfidence, choose_camera, display_name, known, pix4d_from_dji_gimbal
from .survey_frames import ON_GROUND_M

if TYPE_CHECKING:
    from acquisition.exif import CameraTags, ImageTags

    from .ground import Ground

log = logging.getLogger(__name__)

#: File suffixes read as images (case-insensitive).
IMAGE_SUFFIXES = (".jpg", ".jpeg")

#: Files that make a folder a plan folder (written by ``sfap plan``).
PLAN_FILES = ("summary.json", "stations.geojson")

#: Lowest camera height above the ground accepted before the ground is called wrong, metres.
MIN_HEIGHT_AGL_M = 1.0

_GEOD = Geod(ellps="WGS84")


# --- images --------------------------------------------------------------------------------------


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


def is_plan_folder(path: str | os.PathLike[str]) -> bool:
    """True when ``path`` is a folder written by ``sfap plan`` (it holds summary.json and
    stations.geojson)."""
    folder = Path(path)
    return folder.is_dir() and all((folder / name).is_file() for name in PLAN_FILES)


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
    from acquisition.exif import read_tags_and_camera  # pyexiv2 is only needed for images

    paths = image_paths(folder)
    tags: list[ImageTags] = []
    extras: list[CameraTags] = []
    for path in paths:
        image_tags, camera_tags = read_tags_and_camera(path)
        tags.append(image_tags)
        extras.append(camera_tags)
        if progress is not None:
            progress(1)
    return frames_from_tags(
        tags, camera=camera, fallback_camera=fallback_camera, where=str(folder), camera_tags=extras
    )


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


#: A frame whose incoming and outgoing steps turn by more than this is at a turn (a line's end).
TURN_DEG = 30.0


def track_heading_deg(lon_deg: np.ndarray, lat_deg: np.ndarray) -> np.ndarray:
    """True bearing of the track at each point, degrees 0-360 (clockwise from north).

    Central difference (previous to next point) on the WGS84 ellipsoid, one-sided at the
    track's ends. At a turn (the steps in and out differ by more than :data:`TURN_DEG`: the
    first or last frame of a line) the shorter step's bearing: the neighbour on the frame's
    own line is the one a trigger distance away, the other is across the turn. A point that
    has not moved from either neighbour gets 0.
    """
    n = lon_deg.shape[0]
    if n < 2:
        return np.zeros(n)
    prev = np.r_[0, np.arange(n - 1)]
    nxt = np.r_[np.arange(1, n), n - 1]
    azimuth, _, distance = _GEOD.inv(lon_deg[prev], lat_deg[prev], lon_deg[nxt], lat_deg[nxt])
    heading = np.where(np.asarray(distance) > 0.0, np.asarray(azimuth, float) % 360.0, 0.0)
    if n >= 3:
        step_az, _, step_len = _GEOD.inv(lon_deg[:-1], lat_deg[:-1], lon_deg[1:], lat_deg[1:])
        step_az = np.asarray(step_az, float) % 360.0
        step_len = np.asarray(step_len, float)
        az_in, az_out = step_az[:-1], step_az[1:]  # for points 1..n-2
        len_in, len_out = step_len[:-1], step_len[1:]
        turn = np.abs((az_out - az_in + 180.0) % 360.0 - 180.0)
        at_turn = (turn > TURN_DEG) & (len_in > 0) & (len_out > 0)
        shorter = np.where(len_in <= len_out, az_in, az_out)
        heading[1:-1] = np.where(at_turn, shorter, heading[1:-1])
    return np.asarray(heading, dtype=np.float64)


def frames_from_track(
    *,
    name: Sequence[str],
    lon_deg: np.ndarray,
    lat_deg: np.ndarray,
    alt_m: np.ndarray,
    alt_reference: AltitudeReference,
    camera: Camera,
    time_utc_s: np.ndarray | None = None,
    exposure_s: np.ndarray | None = None,
    orientation: Orientation = Orientation.LANDSCAPE,
) -> Frames:
    """Frames from positions alone (camera events of a flight log, a simulated flight): nadir,
    the image top along the track (:func:`track_heading_deg`; landscape: forward, portrait:
    90 deg to the left), :attr:`AttitudeSource.ASSUMED_NADIR`. Rows are taken in the order
    given, which must be the capture order."""
    lon = np.asarray(lon_deg, dtype=np.float64)
    lat = np.asarray(lat_deg, dtype=np.float64)
    heading = track_heading_deg(lon, lat)
    yaw = heading if orientation is Orientation.LANDSCAPE else (heading - 90.0) % 360.0
    return Frames(
        name=tuple(name),
        lon_deg=lon,
        lat_deg=lat,
        alt_m=np.asarray(alt_m, dtype=np.float64),
        alt_reference=alt_reference,
        yaw_deg=yaw,
        pitch_deg=np.zeros_like(yaw),
        roll_deg=np.zeros_like(yaw),
        attitude_source=AttitudeSource.ASSUMED_NADIR,
        camera=camera,
        time_utc_s=None if time_utc_s is None else np.asarray(time_utc_s, dtype=np.float64),
        exposure_s=None if exposure_s is None else np.asarray(exposure_s, dtype=np.float64),
    )


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
            ", ".join(unpositioned),
        )
    if not kept:
        reasons = sorted({why for _, why in left_out})
        raise FramesError(
            f"{where}: no GPS positions: geotag first (`sfap geotag IMAGES --log FLIGHT_LOG -o TAGGED`); "
            f"none of the {len(tags)} images has a real position ({'; '.join(reasons)})"
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


# --- plans ---------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class PlanInfo:
    """What a check needs from a plan folder (summary.json and area.geojson).

    Overlaps in percent, altitudes above ground (``altitude_agl_m``) or home, areas in WGS84
    lon/lat; ``summary`` is summary.json as read.
    """

    folder: Path
    name: str
    camera: Camera
    orientation: Orientation
    front_overlap_pct: float
    side_overlap_pct: float
    altitude_agl_m: float
    gsd_cm: float
    speed_m_s: float
    home_lat_deg: float | None
    home_lon_deg: float | None
    home_alt_amsl_m: float | None
    area_lonlat: Polygon | MultiPolygon | None
    exclusions_lonlat: tuple[Polygon, ...] = ()
    summary: dict[str, Any] = field(default_factory=dict, compare=False)


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise FramesError(f"{path} cannot be read as JSON ({error}); re-run `sfap plan`") from None


def read_plan_info(plan_dir: str | os.PathLike[str], *, camera: Camera | None = None) -> PlanInfo:
    """The plan's numbers and area from a folder written by ``sfap plan``.

    ``camera``: needed only when the plan used a custom camera (summary.json names the
    camera by id, and a custom camera is not in the database).
    """
    folder = Path(plan_dir)
    if not is_plan_folder(folder):
        raise FramesError(
            f"{folder} is not a plan folder (it needs {' and '.join(PLAN_FILES)}); give the folder `sfap "
            "plan ... -o FOLDER` wrote"
        )
    summary = _read_json(folder / "summary.json")
    if not isinstance(summary, dict):
        raise FramesError(f"{folder / 'summary.json'} is not a JSON object; re-run `sfap plan`")
    try:
        camera_id = str(summary["camera_id"])
        used = camera if camera is not None else get_camera(camera_id)
        orientation = Orientation(summary.get("orientation", "landscape"))
        home = summary.get("home") or {}
        info_numbers = {
            key: float(summary[key])
            for key in (
                "front_overlap_pct",
                "side_overlap_pct",
                "altitude_agl_m",
                "gsd_cm",
                "speed_m_s",
            )
        }
    except CameraError as error:
        raise FramesError(
            f"{folder / 'summary.json'}: {error}; a plan made with a custom camera needs that camera given "
            "to the check"
        ) from None
    except (KeyError, TypeError, ValueError) as error:
        raise FramesError(
            f"{folder / 'summary.json'}: missing or bad value {error}; re-run `sfap plan`"
        ) from None

    area: Polygon | MultiPolygon | None = None
    exclusions: list[Polygon] = []
    area_file = folder / "area.geojson"
    if area_file.is_file():
        data = _read_json(area_file)
        areas = []
        for feature in data.get("features", []):
            geom = shape(feature["geometry"])
            kind = feature.get("properties", {}).get("kind")
            if kind == "exclusion" and isinstance(geom, Polygon):
                exclusions.append(geom)
            elif kind == "area" and isinstance(geom, Polygon | MultiPolygon):
                areas.append(geom)
        if areas:
            area = (
                areas[0]
                if len(areas) == 1
                else MultiPolygon([p for a in areas for p in getattr(a, "geoms", [a])])
            )
    return PlanInfo(
        folder=folder,
        name=str(summary.get("name", folder.name)),
        camera=used,
        orientation=orientation,
        home_lat_deg=_opt_float(home.get("lat_deg")),
        home_lon_deg=_opt_float(home.get("lon_deg")),
        home_alt_amsl_m=_opt_float(home.get("alt_amsl_m")),
        area_lonlat=area,
        exclusions_lonlat=tuple(exclusions),
        summary=summary,
        **info_numbers,
    )


def _opt_float(value: Any) -> float | None:
    return None if value is None else float(value)


def frames_from_plan(
    plan_dir: str | os.PathLike[str], *, camera: Camera | None = None
) -> tuple[Frames, PlanInfo]:
    """Every planned station of a plan folder as a frame, and the plan's numbers.

    Altitudes are relative to home (:attr:`AltitudeReference.REL_HOME`). Attitude (the module
    docstring of :mod:`processing.frames`): yaw is the bearing of the image top: the look
    heading for tilted (oblique) stations, for nadir stations the flight heading in landscape
    and heading - 90 in portrait; pitch is the tilt off nadir; roll 0. ``line_index`` numbers
    the (pass, line) pairs in flight order, so lines of different passes stay apart.
    """
    info = read_plan_info(plan_dir, camera=camera)
    path = Path(plan_dir) / "stations.geojson"
    data = _read_json(path)
    features = data.get("features", []) if isinstance(data, dict) else []
    if not features:
        raise FramesError(f"{path} holds no station; the plan has no photo to check")
    try:
        props = [f["properties"] for f in features]
        lon = np.array([p["lon_deg"] for p in props], dtype=np.float64)
        lat = np.array([p["lat_deg"] for p in props], dtype=np.float64)
        alt = np.array([p["alt_rel_home_m"] for p in props], dtype=np.float64)
        heading = np.array([p["heading_deg"] for p in props], dtype=np.float64)
        look = np.array([p["look_heading_deg"] for p in props], dtype=np.float64)
        tilt = np.array([p["tilt_deg"] for p in props], dtype=np.float64)
        pass_index = np.array([p["pass"] for p in props], dtype=np.int64)
        line = np.array([p["line"] for p in props], dtype=np.int64)
        station = [int(p.get("station", k)) for k, p in enumerate(props)]
    except (KeyError, TypeError, ValueError) as error:
        raise FramesError(f"{path}: a station lacks {error}; re-run `sfap plan`") from None
    landscape = info.orientation is Orientation.LANDSCAPE
    nadir_up = heading % 360.0 if landscape else (heading - 90.0) % 360.0
    yaw = np.where(tilt > 0.0, look % 360.0, nadir_up)
    line_ids: dict[tuple[int, int], int] = {}
    line_index = np.array(
        [line_ids.setdefault((int(a), int(b)), len(line_ids)) for a, b in zip(pass_index, line, strict=True)],
        dtype=np.int32,
    )
    frames = Frames(
        name=tuple(f"{a}-{b}-{s}" for a, b, s in zip(pass_index, line, station, strict=True)),
        lon_deg=lon,
        lat_deg=lat,
        alt_m=alt,
        alt_reference=AltitudeReference.REL_HOME,
        yaw_deg=yaw,
        pitch_deg=tilt,
        roll_deg=np.zeros_like(yaw),
        attitude_source=AttitudeSource.PLAN,
        camera=info.camera,
        time_utc_s=None,
        exposure_s=None,
        line_index=line_index,
    )
    return frames, info


# --- the ground ----------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class GroundChoice:
    """The ground a check projects onto, the frames in the ground's altitude reference, and
    in words where the ground came from (for the report)."""

    ground: Ground
    frames: Frames
    description: str
    left_out: tuple[tuple[str, str], ...] = ()


def ground_from_options(
    *,
    frames: Frames,
    dem: str | os.PathLike[str] | None = None,
    ground_elevation_m: float | None = None,
    takeoff_elevation_m: float | None = None,
) -> GroundChoice:
    """Choose the ground from what the user gave; refuse (GroundError) rather than guess.

    - ``dem``: a GeoTIFF of ground elevations above mean sea level (any CRS).
    - ``ground_elevation_m``: flat ground at this elevation above mean sea level.
    - ``takeoff_elevation_m``: elevation above mean sea level of the take-off point.

    Frames with AMSL altitudes need a DEM, a ground elevation or a take-off elevation (flat
    ground at take-off). Frames relative to home lie over flat ground at home unless a DEM or
    a ground elevation is given, which then needs the take-off elevation to put the frames on
    the same reference (their altitudes are rebased to AMSL). AGL frames lie over flat ground at
    0. Frames that are not survey frames over that ground (on the ground, climbing, in transit:
    :mod:`processing.survey_frames`) are left out and listed in ``GroundChoice.left_out``; a
    ground that puts many frames at or under it is refused.
    """
    from .ground import DemGround, FlatGround, check_reference

    if dem is not None and ground_elevation_m is not None:
        raise GroundError(
            "both --dem and --ground-elevation-m were given; give one (the DEM for uneven ground, the "
            "elevation for flat ground)"
        )
    for name, value in (
        ("ground_elevation_m", ground_elevation_m),
        ("takeoff_elevation_m", takeoff_elevation_m),
    ):
        if value is not None and not (math.isfinite(value) and -500.0 <= value <= 9000.0):
            raise GroundError(f"{name} = {value} is outside -500..9000 m above mean sea level")
    ref = frames.alt_reference
    ground: Ground
    if ref in (AltitudeReference.AMSL, AltitudeReference.ELLIPSOID):
        what = "above mean sea level" if ref is AltitudeReference.AMSL else "above the WGS84 ellipsoid"
        if dem is not None:
            ground = DemGround.from_geotiff(Path(dem), reference=AltitudeReference.AMSL)
            description = f"DEM {Path(dem).name} (heights AMSL); camera altitudes {what}"
        elif ground_elevation_m is not None or takeoff_elevation_m is not None:
            given = ground_elevation_m if ground_elevation_m is not None else takeoff_elevation_m
            assert given is not None
            where = "the ground" if ground_elevation_m is not None else "the take-off point"
            ground = FlatGround(elevation_m=given, reference=ref, source=f"elevation of {where}, given")
            description = f"flat ground at {given:g} m (elevation of {where}, given); camera altitudes {what}"
        else:
            median = float(np.median(frames.alt_m)) if len(frames) else float("nan")
            raise GroundError(
                f"the camera altitudes are {what} (median {median:.1f} m) and the height above ground is "
                "unknown; give the ground elevation (--ground-elevation-m, metres AMSL) or a DEM (--dem "
                "FILE.tif)"
            )
    elif ref is AltitudeReference.REL_HOME:
        if dem is None and ground_elevation_m is None:
            ground = FlatGround(elevation_m=0.0, reference=ref, source="the take-off point")
            description = (
                "flat ground at the take-off point (altitudes are relative to home; ground that rises or "
                "falls away from home changes the real height: give a DEM to account for it)"
            )
        else:
            if takeoff_elevation_m is None:
                raise GroundError(
                    "the camera altitudes are relative to the take-off point; to use "
                    + ("a DEM" if dem is not None else "a ground elevation")
                    + " give the take-off elevation above mean sea level too "
                    "(--takeoff-elevation-m)"
                )
            frames = replace(
                frames,
                alt_m=frames.alt_m + takeoff_elevation_m,
                alt_reference=AltitudeReference.AMSL,
            )
            if dem is not None:
                ground = DemGround.from_geotiff(Path(dem), reference=AltitudeReference.AMSL)
                description = (
                    f"DEM {Path(dem).name} (heights AMSL); camera altitudes relative to a take-off point at "
                    f"{takeoff_elevation_m:g} m AMSL"
                )
            else:
                assert ground_elevation_m is not None
                ground = FlatGround(
                    elevation_m=ground_elevation_m, reference=AltitudeReference.AMSL, source="given"
                )
                description = (
                    f"flat ground at {ground_elevation_m:g} m AMSL (given); camera altitudes relative to a "
                    f"take-off point at {takeoff_elevation_m:g} m AMSL"
                )
    else:  # AGL
        if dem is not None or ground_elevation_m is not None:
            raise GroundError(
                "the camera altitudes are already above the ground below each frame; drop --dem and "
                "--ground-elevation-m"
            )
        ground = FlatGround(elevation_m=0.0, reference=ref, source="altitudes above ground")
        description = "camera altitudes above the ground below each frame"
    check_reference(ground, frames.alt_reference)
    keep, left_out = _survey_frames(frames, ground, description)
    return GroundChoice(ground=ground, frames=frames.select(keep), description=description, left_out=left_out)


def plan_dem_path(info: PlanInfo) -> Path | None:
    """The DEM a terrain plan was made on (summary.json ``terrain.dem``), where it can be found:
    in the plan folder, or at the recorded path (absolute, or relative to the working folder)."""
    terrain = info.summary.get("terrain")
    if not isinstance(terrain, dict) or not terrain.get("dem"):
        return None
    recorded = Path(str(terrain["dem"]))
    for candidate in (info.folder / recorded.name, info.folder / recorded, recorded):
        if candidate.is_file():
            return candidate
    return None


def plan_takeoff_elevation_m(info: PlanInfo) -> float | None:
    """The take-off elevation (m AMSL) a plan recorded: its terrain's ground at home, else home."""
    terrain = info.summary.get("terrain")
    if isinstance(terrain, dict) and terrain.get("home_ground_amsl_m") is not None:
        return float(terrain["home_ground_amsl_m"])
    return info.home_alt_amsl_m if terrain else None


def ground_for_plan(
    *,
    frames: Frames,
    info: PlanInfo,
    dem: str | os.PathLike[str] | None = None,
    ground_elevation_m: float | None = None,
    takeoff_elevation_m: float | None = None,
) -> GroundChoice:
    """The ground a plan's own stations are judged on: the plan is the plan.

    A terrain plan (summary.json has ``terrain``) is judged on its own DEM (``dem`` if given,
    else the DEM it recorded, :func:`plan_dem_path`) with its own take-off elevation
    (:func:`plan_takeoff_elevation_m`) unless ``takeoff_elevation_m`` is given. With a DEM and no
    take-off elevation (a flat plan), the take-off elevation is the DEM's at the plan's home. When its DEM
    cannot be found, on the heights above ground the planner computed for each station (over
    flat ground under each frame), and the description says so. A flat plan: as
    :func:`ground_from_options`.
    """
    terrain = info.summary.get("terrain")
    if ground_elevation_m is not None or (not isinstance(terrain, dict) and dem is None):
        return ground_from_options(
            frames=frames,
            dem=dem,
            ground_elevation_m=ground_elevation_m,
            takeoff_elevation_m=takeoff_elevation_m,
        )
    takeoff = takeoff_elevation_m if takeoff_elevation_m is not None else plan_takeoff_elevation_m(info)
    takeoff_source = "given" if takeoff_elevation_m is not None else "the plan's"
    dem_path = Path(dem) if dem is not None else plan_dem_path(info)
    if dem_path is not None and takeoff is None:
        takeoff = _dem_elevation_at_home(dem_path, info)
        takeoff_source = "the DEM's at the plan's home"
    if dem_path is not None and takeoff is not None:
        choice = ground_from_options(frames=frames, dem=dem_path, takeoff_elevation_m=takeoff)
        source = "given" if dem is not None else "the plan's own"
        return replace(
            choice, description=f"{choice.description} ({source} DEM; take-off elevation {takeoff_source})"
        )
    if not isinstance(terrain, dict):
        raise GroundError(
            f"the plan records no home position to read the take-off elevation off {dem}; give it "
            "(--takeoff-elevation-m, metres AMSL)"
        )
    agl = _plan_station_agl(info)
    if agl is None:
        raise GroundError(
            f"{info.folder} is a terrain plan made on DEM {terrain.get('dem')!r}, which is not in the plan "
            "folder or at that path, and its stations carry no height above ground; give the DEM "
            "(--dem FILE.tif)"
        )
    agl_frames = replace(frames, alt_m=agl, alt_reference=AltitudeReference.AGL)
    choice = ground_from_options(frames=agl_frames)
    return replace(
        choice,
        description=(
            f"the plan's heights above its DEM {terrain.get('dem')!r} at each station (the DEM itself was "
            "not "
            "found: flat ground under each frame; give --dem for footprints over the real relief)"
        ),
    )


def images_ground(
    *,
    frames: Frames,
    plan: PlanInfo | None,
    dem: str | os.PathLike[str] | None = None,
    ground_elevation_m: float | None = None,
    takeoff_elevation_m: float | None = None,
) -> GroundChoice:
    """The ground for images flown from ``plan``: as :func:`ground_from_options`, except that
    with neither a DEM nor a ground elevation given, a terrain plan's own DEM (found by
    :func:`plan_dem_path`) is the ground, with the plan's take-off elevation for altitudes
    relative to home (unless ``takeoff_elevation_m`` is given)."""
    plan_dem = plan_dem_path(plan) if plan is not None else None
    if dem is None and ground_elevation_m is None and plan is not None and plan_dem is not None:
        takeoff = takeoff_elevation_m
        if takeoff is None and frames.alt_reference is AltitudeReference.REL_HOME:
            takeoff = plan_takeoff_elevation_m(plan)
        choice = ground_from_options(frames=frames, dem=plan_dem, takeoff_elevation_m=takeoff)
        return replace(choice, description=f"{choice.description} (the plan's own DEM)")
    return ground_from_options(
        frames=frames, dem=dem, ground_elevation_m=ground_elevation_m, takeoff_elevation_m=takeoff_elevation_m
    )


def _dem_elevation_at_home(dem: Path, info: PlanInfo) -> float | None:
    """The ground elevation (m AMSL) at the plan's home on ``dem``: the take-off point is on the
    ground. None when the plan records no home or the DEM does not cover it."""
    from .ground import DemGround

    if info.home_lon_deg is None or info.home_lat_deg is None:
        return None
    frame = local_frame_at(info.home_lon_deg, info.home_lat_deg)
    ground = DemGround.from_geotiff(dem, reference=AltitudeReference.AMSL)
    try:
        return float(np.asarray(ground.elevation_at(np.array([0.0]), np.array([0.0]), frame))[0])
    except GroundError:
        return None


def _plan_station_agl(info: PlanInfo) -> np.ndarray | None:
    data = _read_json(info.folder / "stations.geojson")
    try:
        values = [f["properties"]["alt_agl_m"] for f in data.get("features", [])]
        return np.array(values, dtype=np.float64) if values and None not in values else None
    except (KeyError, TypeError, AttributeError):
        return None


def local_frame_at(lon_deg: float, lat_deg: float) -> LocalFrame:
    """A transverse Mercator frame (WGS84, scale 1) centred on a point, metres east and north.

    Grid north is true north along its central meridian, so a bearing (a camera's yaw, a
    flight heading) is a grid bearing to within the meridian convergence a few kilometres
    away (0.01 deg at 1 km): unlike a UTM zone, whose grid north is off true north by up to
    3 deg at the zone's edges, which would turn every footprint about its camera. Distances
    are true to 1e-8 within a few kilometres.
    """
    crs = CRS.from_proj4(
        f"+proj=tmerc +lat_0={lat_deg!r} +lon_0={lon_deg!r} +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m +no_defs"
    )
    return LocalFrame.from_crs(crs)


def frames_local_frame(frames: Frames) -> LocalFrame:
    """The frame a check of ``frames`` works in: :func:`local_frame_at` their median position."""
    return local_frame_at(float(np.median(frames.lon_deg)), float(np.median(frames.lat_deg)))


def _survey_frames(
    frames: Frames, ground: Ground, description: str
) -> tuple[np.ndarray, tuple[tuple[str, str], ...]]:
    """The survey frames over ``ground`` (:mod:`processing.survey_frames`) and the others with
    their reasons; GroundError when the ground itself must be wrong (most frames at or under it)."""
    from .survey_frames import select_survey_frames

    if len(frames) == 0:
        return np.zeros(0, dtype=bool), ()
    frame = frames_local_frame(frames)
    x, y = frame.to_xy(frames.lon_deg, frames.lat_deg)
    elevation = np.asarray(ground.elevation_at(x, y, frame), dtype=np.float64)
    height = frames.alt_m - elevation
    airborne = height > MIN_HEIGHT_AGL_M
    median = float(np.median(height[airborne])) if airborne.any() else 0.0
    frame_length_m = (
        max(frames.camera.footprint(median, Orientation.LANDSCAPE).along_m, 1.0) if median > 0 else None
    )
    plan = frames.attitude_source is AttitudeSource.PLAN
    xy = None if plan else np.column_stack([x, y])
    selection = select_survey_frames(height, xy, frame_length_m, alt_m=frames.alt_m)
    if plan:  # every station of a plan is a survey frame; only the ground is judged
        selection = replace(selection, keep=np.ones(len(frames), dtype=bool), left_out=())
    if selection.ground_suspect or not selection.keep.any():
        low = ~(height >= MIN_HEIGHT_AGL_M)
        k = int(np.argmin(height))
        raise GroundError(
            f"{int((height <= ON_GROUND_M).sum())} of {len(frames)} frame(s) are within a few metres of "
            f"the ground or under it, {int(low.sum())} less than {MIN_HEIGHT_AGL_M:g} m above it "
            f"({description}); e.g. {frames.name[k]} at {frames.alt_m[k]:.1f} m over ground at "
            f"{elevation[k]:.1f} m: check the ground elevation (metres AMSL) or the DEM; camera altitudes "
            "above the WGS84 ellipsoid where mean sea level is expected are tens of metres off"
        )
    left = tuple((frames.name[k], why) for k, why in selection.left_out)
    if left:
        log.warning(
            "%d frame(s) are not survey frames and are left out: %s",
            len(left),
            "; ".join(f"{name}: {why}" for name, why in left),
        )
    return selection.keep, left
