"""The built-in camera database (``planner/data/cameras.toml``) and cameras built from TOML keys.

Every database entry becomes a :class:`planner.camera.Camera`, which checks that its numbers are
positive and plausible. The database adds checks that a hand-made custom camera does not need:
the pixel pitch (sensor size / pixels) agrees along both image axes, it agrees with the published
pixel pitch where the entry gives one, ids are unique lowercase-hyphen words, every entry names
its source and its EXIF make and model, and no entry carries a key the loader does not know.

The same key names serve the ``[camera]`` table of a mission spec (:func:`camera_from_mapping`),
so a camera is described the same way everywhere.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import logging
import math
import re
import tomllib
from collections.abc import Mapping
from importlib import resources
from types import MappingProxyType

from .camera import _PITCH_TOLERANCE_RATIO, Camera
from .errors import CameraError

log = logging.getLogger(__name__)

#: Keys that describe a camera's geometry and timing, in the order they are listed to users.
GEOMETRY_KEYS: tuple[str, ...] = (
    "sensor_width_mm",
    "sensor_height_mm",
    "image_width_px",
    "image_height_px",
    "focal_length_mm",
)
#: Optional keys of a camera (database entry or mission spec).
OPTIONAL_KEYS: tuple[str, ...] = (
    "min_trigger_interval_s",
    "shutter_s",
    "pixel_pitch_um",
    "name",
    "exif_make",
    "exif_model",
    "source",
)
#: Keys a database entry must have besides the geometry.
_DATABASE_REQUIRED_KEYS: tuple[str, ...] = (
    "id",
    "name",
    *GEOMETRY_KEYS,
    "min_trigger_interval_s",
    "exif_make",
    "exif_model",
    "source",
)
_DATABASE_KEYS: frozenset[str] = frozenset((*_DATABASE_REQUIRED_KEYS, *OPTIONAL_KEYS))
#: Keys of a mission spec's camera table: a database model, or the camera's own numbers.
MAPPING_KEYS: tuple[str, ...] = ("model", *GEOMETRY_KEYS, *OPTIONAL_KEYS)

_INT_KEYS = frozenset({"image_width_px", "image_height_px"})
_FLOAT_KEYS = frozenset(
    {
        "sensor_width_mm",
        "sensor_height_mm",
        "focal_length_mm",
        "min_trigger_interval_s",
        "shutter_s",
        "pixel_pitch_um",
    }
)
_STR_KEYS = frozenset({"id", "name", "exif_make", "exif_model", "source", "model"})

_ID_PATTERN = re.compile(r"^[a-z0-9]+(?:-[a-z0-9]+)*$")
_DATA_FILE = "cameras.toml"

#: Relative tolerance on the focal length when matching EXIF to a database camera. EXIF focal
#: lengths are rounded (DJI writes 8.8 or 12.29, others one decimal), so a few percent is needed,
#: and distinct lenses on one body (a6000 16 and 20 mm) are still 25 % apart.
EXIF_FOCAL_TOLERANCE_RATIO = 0.05


# --- value checking -----------------------------------------------------------------------------


def _check_value(key: str, value: object, where: str) -> object:
    """Return ``value`` if its type suits ``key``; else raise CameraError naming both."""
    if key in _INT_KEYS:
        if isinstance(value, bool) or not isinstance(value, int):
            raise CameraError(f"{where}: {key} = {value!r} must be a whole number of pixels")
        return value
    if key in _FLOAT_KEYS:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise CameraError(f"{where}: {key} = {value!r} must be a number")
        if not math.isfinite(value):
            raise CameraError(f"{where}: {key} = {value!r} must be a finite number")
        return float(value)
    if key in _STR_KEYS:
        if not isinstance(value, str) or not value.strip():
            raise CameraError(f"{where}: {key} = {value!r} must be a non-empty string")
        return value.strip()
    raise AssertionError(f"unclassified camera key {key!r}")  # pragma: no cover - a bug here


def _reject_unknown(data: Mapping[str, object], valid: tuple[str, ...], where: str) -> None:
    unknown = sorted(str(key) for key in data if key not in valid)
    if not unknown:
        return
    hints = []
    for key in unknown:
        close = difflib.get_close_matches(key, valid, n=1)
        hints.append(f"{key!r} (did you mean {close[0]!r}?)" if close else repr(key))
    raise CameraError(f"{where}: unknown camera key(s) {', '.join(hints)}; valid keys: {', '.join(valid)}")


def check_published_pitch(camera: Camera, pixel_pitch_um: float, *, where: str) -> None:
    """Raise CameraError unless sensor size / pixels matches ``pixel_pitch_um`` on both axes.

    The tolerance is 3 % (``planner.camera._PITCH_TOLERANCE_RATIO``): datasheets round the
    pitch to two or three digits, and quote the nominal format (17.3 x 13.0 mm for 4/3).
    """
    if not (0.0 < pixel_pitch_um < 100.0):
        raise CameraError(f"{where}: pixel_pitch_um = {pixel_pitch_um!r} is not a pixel pitch in micrometres")
    for axis, pitch_mm in (("x", camera.pixel_pitch_x_mm), ("y", camera.pixel_pitch_y_mm)):
        pitch_um = pitch_mm * 1000.0
        if abs(pitch_um - pixel_pitch_um) > _PITCH_TOLERANCE_RATIO * pixel_pitch_um:
            raise CameraError(
                f"{where}: pixel pitch along {axis} from sensor size / pixels is "
                f"{pitch_um:.3f} um, but pixel_pitch_um = {pixel_pitch_um} um (more than "
                f"{_PITCH_TOLERANCE_RATIO:.0%} apart); check the sensor size (mm), the image size "
                f"(px) and the published pitch"
            )


def check_square_pitch(camera: Camera, *, where: str) -> None:
    """Raise CameraError unless the pitch along x and y agree within 3 %.

    Every real survey camera has square pixels; a sensor size and an image size that disagree
    (a 3:2 image on a 4:3 sensor, width and height swapped) show up here.
    """
    pitch_x, pitch_y = camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm
    if abs(pitch_x - pitch_y) > _PITCH_TOLERANCE_RATIO * max(pitch_x, pitch_y):
        raise CameraError(
            f"{where}: pixel pitch is {pitch_x * 1000:.3f} um along x "
            f"({camera.sensor_width_mm} mm / {camera.image_width_px} px) but "
            f"{pitch_y * 1000:.3f} um along y ({camera.sensor_height_mm} mm / "
            f"{camera.image_height_px} px); the sensor size must match the image's aspect ratio"
        )


# --- the database -------------------------------------------------------------------------------


def _camera_from_entry(entry: Mapping[str, object], index: int) -> Camera:
    raw_id = entry.get("id")
    where = f"{_DATA_FILE} camera {raw_id!r}" if raw_id else f"{_DATA_FILE} camera #{index + 1}"
    unknown = sorted(str(key) for key in entry if key not in _DATABASE_KEYS)
    if unknown:
        raise CameraError(
            f"{where}: unknown key(s) {', '.join(unknown)}; valid keys: "
            f"{', '.join(_DATABASE_REQUIRED_KEYS)}, shutter_s, pixel_pitch_um"
        )
    missing = [key for key in _DATABASE_REQUIRED_KEYS if key not in entry]
    if missing:
        raise CameraError(f"{where}: missing key(s) {', '.join(missing)}")
    values = {key: _check_value(key, value, where) for key, value in entry.items()}
    camera_id = str(values["id"])
    if not _ID_PATTERN.match(camera_id):
        raise CameraError(f"{where}: id {camera_id!r} must be lowercase letters and digits joined by hyphens")
    published = values.pop("pixel_pitch_um", None)
    try:
        camera = Camera(**values)  # type: ignore[arg-type]
    except CameraError as error:
        raise CameraError(f"{where}: {error}") from error
    check_square_pitch(camera, where=where)
    if published is not None:
        check_published_pitch(camera, float(published), where=where)  # type: ignore[arg-type]
    return camera


def parse_cameras(text: str, *, source: str = _DATA_FILE) -> dict[str, Camera]:
    """Parse a camera database in TOML (``[[camera]]`` tables) and check every entry.

    Raises CameraError for malformed TOML, unknown or missing keys, duplicate ids, implausible
    numbers, or a pixel pitch that differs between the axes or from the published one.
    """
    try:
        document = tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise CameraError(f"{source}: not valid TOML: {error}") from error
    extra = sorted(set(document) - {"camera"})
    if extra:
        raise CameraError(f"{source}: unknown top-level key(s) {', '.join(extra)}; expected [[camera]]")
    entries = document.get("camera", [])
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise CameraError(f"{source}: 'camera' must be an array of tables ([[camera]])")
    cameras: dict[str, Camera] = {}
    for index, entry in enumerate(entries):
        camera = _camera_from_entry(entry, index)
        if camera.id in cameras:
            raise CameraError(f"{source}: camera id {camera.id!r} appears twice")
        cameras[camera.id] = camera
    return cameras


@functools.cache
def _database_text() -> str:
    return resources.files("planner").joinpath("data", _DATA_FILE).read_text(encoding="utf-8")


@functools.cache
def _load_cameras() -> Mapping[str, Camera]:
    cameras = parse_cameras(_database_text())
    log.debug("loaded %d cameras from %s", len(cameras), _DATA_FILE)
    return MappingProxyType(cameras)


_ENTRY_START = re.compile(r"^\[\[camera\]\][ \t]*$", re.MULTILINE)
_ENTRY_ID = re.compile(r'^id[ \t]*=[ \t]*"([^"\\]*)"[ \t]*$', re.MULTILINE)


@functools.cache
def _entry_alone(camera_id: str) -> Camera | None:
    """The database entry of ``camera_id`` parsed and checked by itself: the same Camera as the
    whole database gives, without parsing 80 other entries (tomllib, in Python: 15-20 ms of a
    small plan). None when not exactly one entry's ``[[camera]]`` block names that id on an
    ``id = "..."`` line of its own, or the block does not parse alone: the caller then parses
    the whole database, which says what is wrong."""
    text = _database_text()
    starts = [match.start() for match in _ENTRY_START.finditer(text)]
    found = []
    for index, start in enumerate(starts):
        block = text[start : starts[index + 1] if index + 1 < len(starts) else len(text)]
        named = _ENTRY_ID.findall(block)
        if camera_id in named:
            found.append((index, block, len(named)))
    if len(found) != 1 or found[0][2] != 1:
        return None
    index, block, _ = found[0]
    try:
        document = tomllib.loads(block)
    except tomllib.TOMLDecodeError:
        return None
    entries = document.get("camera")
    if set(document) != {"camera"} or not isinstance(entries, list) or len(entries) != 1:
        return None
    if not isinstance(entries[0], dict) or entries[0].get("id") != camera_id:
        return None
    return _camera_from_entry(entries[0], index)


def load_cameras() -> dict[str, Camera]:
    """All built-in cameras by id, in database order (parsed and checked once, then cached)."""
    return dict(_load_cameras())


def get_camera(camera_id: str) -> Camera:
    """The built-in camera ``camera_id``; CameraError listing the closest ids if there is none.

    Only that camera's entry is parsed and checked, unless the whole database was loaded already
    or the entry cannot be found alone (the whole database is parsed then, as for any id it does
    not hold); the database file's every entry is checked by its tests."""
    if _load_cameras.cache_info().currsize == 0:
        alone = _entry_alone(camera_id)
        if alone is not None:
            return alone
    cameras = _load_cameras()
    camera = cameras.get(camera_id)
    if camera is not None:
        return camera
    close = difflib.get_close_matches(camera_id.strip().lower(), list(cameras), n=5, cutoff=0.4)
    hint = f"closest: {', '.join(close)}; " if close else ""
    raise CameraError(
        f"camera {camera_id!r} is not in the built-in database; {hint}"
        f"`sfap cameras` lists them all, or describe the camera by its own numbers "
        f"({', '.join(GEOMETRY_KEYS)})"
    )


# --- cameras from a mission spec ----------------------------------------------------------------


def camera_from_mapping(data: Mapping[str, object], *, where: str) -> Camera:
    """A camera from TOML keys: a database ``model`` with optional overrides, or a custom camera.

    ``data`` holds the keys of :data:`MAPPING_KEYS` (units in the names). With ``model`` the
    camera is taken from the database and every other key overrides its value (a different
    ``shutter_s``, a cropped image size...); without it, the five geometry keys are required and
    the rest default (``min_trigger_interval_s`` 2 s, no shutter time). ``pixel_pitch_um``, if
    given, is checked against sensor size / pixels. ``where`` names the place for messages, e.g.
    ``"missions/gully.toml [camera]"``. Unknown keys raise CameraError listing the valid ones.
    """
    _reject_unknown(data, MAPPING_KEYS, where)
    values = {key: _check_value(key, value, where) for key, value in data.items()}
    published = values.pop("pixel_pitch_um", None)
    model = values.pop("model", None)
    try:
        if model is not None:
            base = get_camera(str(model))
            camera = base
            if values:
                # The id stays the database's (summaries name the model flown); the source
                # records what was changed and where.
                base_source = values.pop("source", base.source)
                note = f"{base_source}; overridden in {where}: {', '.join(values) or 'source'}"
                camera = dataclasses.replace(base, **values, source=note)  # type: ignore[arg-type]
                log.info("%s: camera %s with %s overridden", where, base.id, ", ".join(values))
        else:
            missing = [key for key in GEOMETRY_KEYS if key not in values]
            if missing:
                raise CameraError(
                    f'missing {", ".join(missing)}; give `model = "<id>"` for a built-in '
                    f"camera (`sfap cameras` lists them) or all of {', '.join(GEOMETRY_KEYS)}"
                )
            values.setdefault("name", "custom camera")
            values.setdefault("source", f"custom camera in {where}")
            camera = Camera(id="custom", **values)  # type: ignore[arg-type]
    except CameraError as error:
        raise CameraError(f"{where}: {error}") from error
    if published is not None:
        check_published_pitch(camera, float(published), where=where)  # type: ignore[arg-type]
    return camera


# --- matching images to cameras -----------------------------------------------------------------


def _norm(text: str) -> str:
    return " ".join(text.split()).casefold()


def match_exif(
    make: str | None,
    model: str | None,
    focal_length_mm: float | None,
    image_width_px: int | None,
    image_height_px: int | None,
) -> Camera | None:
    """The database camera that took an image, from its EXIF tags, or None if no single one fits.

    Make and model compare case-insensitively with surrounding and repeated spaces ignored
    (``make`` None: any make); the focal length must agree within 5 %; the image size may be in
    either orientation (a camera rotated to portrait writes height x width). A tag that is None
    does not constrain. Without a model there is no match. When several cameras remain and they
    differ in geometry (one body with two lenses and no focal length given), the answer is None,
    because guessing would give a wrong GSD.
    """
    if model is None or not model.strip():
        return None
    wanted_model = _norm(model)
    wanted_make = _norm(make) if make and make.strip() else None
    candidates: list[Camera] = []
    for camera in _load_cameras().values():
        if camera.exif_model is None or _norm(camera.exif_model) != wanted_model:
            continue
        if wanted_make is not None and (camera.exif_make is None or _norm(camera.exif_make) != wanted_make):
            continue
        if focal_length_mm is not None and (
            abs(focal_length_mm - camera.focal_length_mm)
            > EXIF_FOCAL_TOLERANCE_RATIO * camera.focal_length_mm
        ):
            continue
        if image_width_px is not None and image_height_px is not None:
            size = {(image_width_px, image_height_px), (image_height_px, image_width_px)}
            if (camera.image_width_px, camera.image_height_px) not in size:
                continue
        elif image_width_px is not None or image_height_px is not None:
            side = image_width_px if image_width_px is not None else image_height_px
            if side not in (camera.image_width_px, camera.image_height_px):
                continue
        candidates.append(camera)
    if not candidates:
        return None
    geometries = {_geometry(camera) for camera in candidates}
    if len(geometries) > 1:
        log.debug(
            "EXIF %s %s matches %d cameras of different geometry: %s",
            make,
            model,
            len(candidates),
            ", ".join(camera.id for camera in candidates),
        )
        return None
    return candidates[0]


def _geometry(camera: Camera) -> tuple[float, float, int, int, float]:
    return (
        camera.sensor_width_mm,
        camera.sensor_height_mm,
        camera.image_width_px,
        camera.image_height_px,
        camera.focal_length_mm,
    )
