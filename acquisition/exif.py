"""Reading and writing the tags of a JPEG frame: the only module that knows EXIF rationals and XMP.

What is read (:func:`read_tags`): capture time (``DateTimeOriginal`` + ``SubSecTimeOriginal`` +
``OffsetTimeOriginal``, or the XMP ``exif:DateTimeOriginal`` that carries all three), make,
model, focal length, image size, exposure time, the GPS position already in the file (EXIF, with
the altitude reference applied), the Pix4D camera attitude (XMP namespace
``http://pix4d.com/camera/1.0/``) and DJI's XMP position (``drone-dji:GpsLatitude`` ...).

What is written (:func:`write_geotag`): EXIF GPS (GPSLatitude/Ref, GPSLongitude/Ref, GPSAltitude
and GPSAltitudeRef, GPSDateStamp/GPSTimeStamp, GPSImgDirection/Ref, GPSMapDatum, GPSVersionID),
Pix4D XMP ``Camera:Yaw/Pitch/Roll/GPSXYAccuracy/GPSZAccuracy``, and, when the file already carries
them, DJI's XMP ``GpsLatitude``, ``GpsLongitude`` (and the misspelt ``GpsLongtitude`` of older
firmware), ``AbsoluteAltitude`` and ``RelativeAltitude``: OpenDroneMap and Metashape prefer DJI's
XMP position over EXIF, so leaving the old ones would undo the geotag (REFERENCES.md section 4).

Writing is lossless and reads each file once: only the header segments (everything before the
first SOS marker) are read into memory and rewritten, in Python by :mod:`acquisition.jpeg_meta`
(a new GPS IFD appended to the TIFF block, nothing else moved, so maker-note offsets stay valid;
XMP edited in its text) or, for a header that module does not handle, by exiv2 (pyexiv2); reading
takes the same route. The rest of the
file, the entropy-coded image data (:func:`compressed_image_data`) and anything after it, is
copied by the kernel (``os.copy_file_range``) and is byte-identical before and after, which the
tests check. :func:`write_geotags` writes many frames at once. A frame whose image data has no
end marker (EOI), which decoders still read, is tagged with a warning that names it.

Angles: yaw clockwise from true north, 0-360; pitch and roll in degrees as in Pix4D's camera
namespace (a level, nadir-looking camera has pitch 0 and roll 0).
"""

from __future__ import annotations

import calendar
import contextlib
import logging
import math
import os
import re
import struct
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from planner.errors import OutputExistsError
from planner.outputs import atomic_file, process_umask

from . import jpeg_meta
from .errors import GeotagError
from .kernel_copy import copy_range, identity

if TYPE_CHECKING:
    import pyexiv2

    from .card_ahead import CardAhead, Copied

log = logging.getLogger(__name__)

PIX4D_CAMERA_NS = "http://pix4d.com/camera/1.0/"
DJI_NS = "http://www.dji.com/drone-dji/1.0/"

# exiv2 only knows the prefixes it has been told about; the file itself registers them when it
# carries them, a fresh file does not.
_NAMESPACES_REGISTERED = False


def _register_namespaces() -> Any:
    """pyexiv2, imported on first use (the Python path needs it only for headers it does not
    handle), quiet, and told the XMP prefixes; returns the module."""
    global _NAMESPACES_REGISTERED
    import pyexiv2

    if _NAMESPACES_REGISTERED:
        return pyexiv2
    pyexiv2.set_log_level(3)  # exiv2 warnings about vendor makernotes are not ours to show
    for namespace, prefix in ((PIX4D_CAMERA_NS, "Camera"), (DJI_NS, "drone-dji")):
        try:
            pyexiv2.registerNs(namespace, prefix)
        except (RuntimeError, KeyError, ValueError):
            # Already known to exiv2 (registered by a file read earlier): that is fine.
            log.debug("XMP namespace %s already registered", namespace)
    _NAMESPACES_REGISTERED = True
    return pyexiv2


_GPS_KEYS = (
    "Exif.GPSInfo.GPSVersionID",
    "Exif.GPSInfo.GPSLatitudeRef",
    "Exif.GPSInfo.GPSLatitude",
    "Exif.GPSInfo.GPSLongitudeRef",
    "Exif.GPSInfo.GPSLongitude",
    "Exif.GPSInfo.GPSAltitudeRef",
    "Exif.GPSInfo.GPSAltitude",
    "Exif.GPSInfo.GPSTimeStamp",
    "Exif.GPSInfo.GPSDateStamp",
    "Exif.GPSInfo.GPSImgDirectionRef",
    "Exif.GPSInfo.GPSImgDirection",
    "Exif.GPSInfo.GPSMapDatum",
)
_DJI_POSITION_KEYS = (
    "Xmp.drone-dji.GpsLatitude",
    "Xmp.drone-dji.GpsLongitude",
    "Xmp.drone-dji.GpsLongtitude",
    "Xmp.drone-dji.AbsoluteAltitude",
    "Xmp.drone-dji.RelativeAltitude",
)
_PIX4D_KEYS = (
    "Xmp.Camera.Yaw",
    "Xmp.Camera.Pitch",
    "Xmp.Camera.Roll",
    "Xmp.Camera.GPSXYAccuracy",
    "Xmp.Camera.GPSZAccuracy",
)


@dataclass(frozen=True, kw_only=True)
class ImageTags:
    """What one frame says about itself. Absent tags are None.

    - ``capture_time_s``: POSIX seconds of the capture. UTC when ``capture_time_zone_known``
      (the file carries OffsetTimeOriginal); otherwise the camera's wall clock read as if it
      were UTC (the clock offset, time zone included, is estimated by the matcher).
    - ``gps_alt_amsl_m``: EXIF GPSAltitude with its reference applied (negative below sea level).
    - ``gps_time_utc_s``: GPSDateStamp + GPSTimeStamp (UTC).
    - ``camera_yaw_deg`` ...: Pix4D XMP camera attitude; ``dji_*``: DJI XMP position.
    """

    path: str
    capture_time_s: float | None = None
    capture_time_zone_known: bool = False
    capture_time_text: str | None = None
    make: str | None = None
    model: str | None = None
    focal_length_mm: float | None = None
    width_px: int | None = None
    height_px: int | None = None
    exposure_time_s: float | None = None
    gps_lat_deg: float | None = None
    gps_lon_deg: float | None = None
    gps_alt_amsl_m: float | None = None
    gps_time_utc_s: float | None = None
    camera_yaw_deg: float | None = None
    camera_pitch_deg: float | None = None
    camera_roll_deg: float | None = None
    xy_accuracy_m: float | None = None
    z_accuracy_m: float | None = None
    dji_lat_deg: float | None = None
    dji_lon_deg: float | None = None
    dji_alt_amsl_m: float | None = None
    dji_alt_rel_home_m: float | None = None

    @property
    def name(self) -> str:
        return Path(self.path).name

    @property
    def has_dji_position(self) -> bool:
        return self.dji_lat_deg is not None or self.dji_lon_deg is not None


@dataclass(frozen=True, kw_only=True)
class GeoTag:
    """The tags to write on one frame.

    - ``lat_deg``, ``lon_deg``: WGS84; ``alt_amsl_m``: metres above mean sea level (None: no
      altitude written; COLMAP then creates no position prior).
    - ``time_utc_s``: when the frame was taken (POSIX seconds, UTC): GPSDateStamp/GPSTimeStamp.
    - ``yaw_deg`` (0-360, clockwise from true north; also written as GPSImgDirection),
      ``pitch_deg``, ``roll_deg``: camera attitude in the Pix4D convention (nadir = 0, 0).
    - ``xy_accuracy_m``, ``z_accuracy_m``: one-sigma position accuracy (Pix4D GPSXYAccuracy
      and GPSZAccuracy).
    - ``alt_rel_home_m``: written to DJI's RelativeAltitude when the file carries that tag.
    """

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float | None = None
    time_utc_s: float | None = None
    yaw_deg: float | None = None
    pitch_deg: float | None = None
    roll_deg: float | None = None
    xy_accuracy_m: float | None = None
    z_accuracy_m: float | None = None
    alt_rel_home_m: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.lat_deg) and -90.0 <= self.lat_deg <= 90.0):
            raise GeotagError(f"latitude {self.lat_deg} deg is outside -90..90")
        if not (math.isfinite(self.lon_deg) and -180.0 <= self.lon_deg <= 180.0):
            raise GeotagError(f"longitude {self.lon_deg} deg is outside -180..180")
        for name in (
            "alt_amsl_m",
            "time_utc_s",
            "yaw_deg",
            "pitch_deg",
            "roll_deg",
            "alt_rel_home_m",
        ):
            value = getattr(self, name)
            if value is not None and not math.isfinite(value):
                raise GeotagError(f"{name} is {value}; give a finite number or None")
        for name in ("xy_accuracy_m", "z_accuracy_m"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value >= 0.0):
                raise GeotagError(f"{name} is {value}; accuracies are finite and >= 0 m")


# --------------------------------------------------------------------------------------------
# Value conversions (EXIF rationals, dates)


def _rational(text: str) -> float | None:
    """'num/den' (or a plain number) as a float; None for a zero denominator or garbage."""
    text = text.strip()
    try:
        if "/" in text:
            num, den = text.split("/", 1)
            if float(den) == 0.0:
                return None
            return float(num) / float(den)
        return float(text)
    except ValueError:
        return None


def _rationals(text: str) -> list[float] | None:
    values = [_rational(part) for part in text.split()]
    if not values or any(v is None for v in values):
        return None
    return [float(v) for v in values if v is not None]


def _dms_to_deg(text: str, ref: str | None, negative_ref: str) -> float | None:
    parts = _rationals(text)
    if parts is None:
        return None
    parts = [*parts, 0.0, 0.0][:3]
    value = parts[0] + parts[1] / 60.0 + parts[2] / 3600.0
    if ref is not None and ref.strip().upper().startswith(negative_ref):
        value = -value
    return value


def _to_rational_text(value: float, denominator: int) -> str:
    return f"{round(abs(value) * denominator)}/{denominator}"


def _deg_to_dms_text(value_deg: float) -> str:
    """Degrees as EXIF degrees/minutes/seconds rationals; seconds to 1e-5 s (0.3 mm)."""
    value = abs(value_deg)
    degrees = int(value)
    minutes_f = (value - degrees) * 60.0
    minutes = int(minutes_f)
    seconds_units = round((minutes_f - minutes) * 60.0 * 100_000)
    if seconds_units >= 60 * 100_000:  # rounding carried into the next minute
        seconds_units -= 60 * 100_000
        minutes += 1
        if minutes == 60:
            minutes = 0
            degrees += 1
    return f"{degrees}/1 {minutes}/1 {seconds_units}/100000"


_DATE_RE = re.compile(r"^\s*(\d{4})[:-](\d{2})[:-](\d{2})[ T](\d{2}):(\d{2}):(\d{2})(\.\d+)?\s*(.*)$")
_ZONE_RE = re.compile(r"^([+-])(\d{2}):?(\d{2})$")


def _parse_zone(text: str | None) -> int | None:
    """'+02:00' / '-0500' / 'Z' as seconds east of UTC; None when absent or unreadable."""
    if text is None:
        return None
    text = text.strip()
    if text.upper() == "Z":
        return 0
    match = _ZONE_RE.match(text)
    if match is None:
        return None
    sign = 1 if match.group(1) == "+" else -1
    return sign * (int(match.group(2)) * 3600 + int(match.group(3)) * 60)


def parse_capture_time(
    date_time: str, sub_sec: str | None = None, zone: str | None = None
) -> tuple[float, bool] | None:
    """An EXIF/XMP date-time (with optional sub-seconds and zone) as (POSIX s, zone known).

    Without a zone the wall-clock time is read as UTC and ``zone known`` is False.
    Returns None for an unreadable or blank date (cameras write "0000:00:00 00:00:00").
    """
    match = _DATE_RE.match(date_time)
    if match is None:
        return None
    year, month, day, hour, minute, second = (int(match.group(k)) for k in range(1, 7))
    if year == 0 or month == 0 or day == 0:
        return None
    try:
        stamp = float(calendar.timegm((year, month, day, hour, minute, second, 0, 0, 0)))
        datetime(year, month, day, hour, minute, second)  # validates the day of the month
    except ValueError:
        return None
    fraction = match.group(7)
    if fraction:
        stamp += float("0" + fraction)
    elif sub_sec and sub_sec.strip().isdigit():
        digits = sub_sec.strip()
        stamp += int(digits) / 10 ** len(digits)
    zone_s = _parse_zone(match.group(8) or None)
    if zone_s is None:
        zone_s = _parse_zone(zone)
    if zone_s is not None:
        stamp -= zone_s
    return stamp, zone_s is not None


def _gps_time(date_stamp: str | None, time_stamp: str | None) -> float | None:
    if not date_stamp or not time_stamp:
        return None
    hms = _rationals(time_stamp)
    match = re.match(r"^\s*(\d{4})[:-](\d{2})[:-](\d{2})", date_stamp)
    if hms is None or len(hms) != 3 or match is None:
        return None
    try:
        day = calendar.timegm(
            (int(match.group(1)), int(match.group(2)), int(match.group(3)), 0, 0, 0, 0, 0, 0)
        )
    except ValueError:
        return None
    return float(day) + hms[0] * 3600.0 + hms[1] * 60.0 + hms[2]


def _float(text: str | None) -> float | None:
    if text is None:
        return None
    try:
        value = float(str(text).strip())
    except ValueError:
        return None
    return value if math.isfinite(value) else None


# --------------------------------------------------------------------------------------------
# Reading


def _open(data: bytes, path: str | os.PathLike[str]) -> pyexiv2.ImageData:
    exiv2 = _register_namespaces()
    try:
        return exiv2.ImageData(data)
    except (RuntimeError, ValueError, OSError) as error:
        raise GeotagError(f"{path}: not a readable image ({error}); remove it or replace it") from error


def _read_maps(
    image: pyexiv2.ImageData, path: str | os.PathLike[str]
) -> tuple[dict[str, Any], dict[str, Any]]:
    try:
        exif = image.read_exif()
    except (RuntimeError, ValueError, UnicodeDecodeError) as error:
        raise GeotagError(f"{path}: EXIF cannot be read ({error})") from error
    try:
        xmp = image.read_xmp()
    except (RuntimeError, ValueError, UnicodeDecodeError) as error:
        log.warning("%s: XMP cannot be read (%s); ignoring it", path, error)
        xmp = {}
    return exif, xmp


@dataclass(frozen=True)
class HeaderSnapshot:
    """What reading a frame's header saw, so that writing the frame later need not walk and parse
    the header again (:class:`GeotagJob` ``seen``).

    It is used only while the file is the same one: ``identity`` (device, inode, size, mtime in
    ns) must match, and the bytes read again up to the end of the SOS segment must end with
    ``sos_segment``; otherwise the header is read afresh. The maps are what
    :func:`acquisition.jpeg_meta.header_maps` returned; the patch built from them is read back
    and compared as always, so a stale map cannot pass unnoticed."""

    identity: tuple[int, int, int, int]
    sos_offset: int
    sos_segment: bytes
    exif: dict[str, str]
    xmp: dict[str, Any]


def _read_file_maps(
    path: str | os.PathLike[str],
) -> tuple[dict[str, Any], dict[str, Any], int | None, int | None, HeaderSnapshot | None]:
    """The EXIF and XMP maps, the pixel size of one JPEG, from its metadata segments only, and
    the header's snapshot when the Python reader read it (None when exiv2 did).
    Raises :class:`GeotagError` when the file is unreadable."""
    with open(path, "rb", buffering=0) as handle:  # read with pread only: no buffer
        fd = handle.fileno()
        head = os.pread(fd, 2, 0)
        if head != b"\xff\xd8":
            raise GeotagError(f"{path}: not a JPEG file (no SOI marker); remove it from the folder")
        try:  # the header segments only, read and parsed here (exiv2 for what this does not handle)
            stat = os.fstat(fd)
            split = _split_header(lambda offset, n: os.pread(fd, n, offset), stat.st_size, str(path))
            exif, xmp, width, height = jpeg_meta.header_maps(split.header)
            seen = HeaderSnapshot(
                identity=identity(stat),
                sos_offset=split.sos_offset,
                sos_segment=split.sos_segment,
                exif=exif,
                xmp=xmp,
            )
            return exif, xmp, width, height, seen
        except (GeotagError, jpeg_meta.UnsupportedHeaderError, UnicodeDecodeError, struct.error) as error:
            log.debug("%s: read by exiv2 (%s)", path, error)
    try:
        # From the path, exiv2 reads the metadata segments only (5x faster than the whole file).
        image = _register_namespaces().Image(os.fspath(path))
    except (RuntimeError, ValueError, OSError) as error:
        raise GeotagError(f"{path}: not a readable image ({error}); remove or replace it") from error
    try:
        exif, xmp = _read_maps(image, path)
        width = image.get_pixel_width() or None
        height = image.get_pixel_height() or None
    finally:
        image.close()
    return exif, xmp, width, height, None


def read_tags(path: str | os.PathLike[str]) -> ImageTags:
    """Read the tags of one JPEG. Raises :class:`GeotagError` when the file is unreadable."""
    return read_tags_and_header(path)[0]


def read_tags_and_header(path: str | os.PathLike[str]) -> tuple[ImageTags, HeaderSnapshot | None]:
    """:func:`read_tags`, and the header's snapshot for writing the frame later (None when the
    header is one only exiv2 handles)."""
    exif, xmp, width, height, seen = _read_file_maps(path)
    return tags_from_maps(str(path), exif, xmp, width_px=width, height_px=height), seen


def tags_from_maps(
    path: str,
    exif: dict[str, Any],
    xmp: dict[str, Any],
    *,
    width_px: int | None = None,
    height_px: int | None = None,
) -> ImageTags:
    """Build :class:`ImageTags` from pyexiv2's key -> text maps."""

    def get(key: str) -> str | None:
        value = exif.get(key)
        if value is None:
            value = xmp.get(key)
        if isinstance(value, list):
            value = value[0] if value else None
        if isinstance(value, dict):  # XMP language alternatives
            value = next(iter(value.values()), None)
        return None if value is None else str(value)

    capture: tuple[float, bool] | None = None
    capture_text: str | None = None
    original = get("Exif.Photo.DateTimeOriginal")
    if original:
        capture_text = original
        capture = parse_capture_time(
            original, get("Exif.Photo.SubSecTimeOriginal"), get("Exif.Photo.OffsetTimeOriginal")
        )
    if capture is None:
        for key in ("Xmp.exif.DateTimeOriginal", "Xmp.photoshop.DateCreated", "Xmp.xmp.CreateDate"):
            text = get(key)
            if text:
                capture = parse_capture_time(text)
                if capture is not None:
                    capture_text = text
                    break

    lat = lon = alt = None
    if get("Exif.GPSInfo.GPSLatitude") and get("Exif.GPSInfo.GPSLongitude"):
        lat = _dms_to_deg(get("Exif.GPSInfo.GPSLatitude") or "", get("Exif.GPSInfo.GPSLatitudeRef"), "S")
        lon = _dms_to_deg(get("Exif.GPSInfo.GPSLongitude") or "", get("Exif.GPSInfo.GPSLongitudeRef"), "W")
    alt_text = get("Exif.GPSInfo.GPSAltitude")
    if alt_text:
        alt = _rational(alt_text)
        if alt is not None and (get("Exif.GPSInfo.GPSAltitudeRef") or "0").strip() == "1":
            alt = -alt

    exposure = get("Exif.Photo.ExposureTime")
    focal = get("Exif.Photo.FocalLength")
    if width_px is None:
        width_px = int(_float(get("Exif.Photo.PixelXDimension")) or 0) or None
    if height_px is None:
        height_px = int(_float(get("Exif.Photo.PixelYDimension")) or 0) or None
    dji_lon = _float(get("Xmp.drone-dji.GpsLongitude"))
    if dji_lon is None:
        dji_lon = _float(get("Xmp.drone-dji.GpsLongtitude"))
    make = get("Exif.Image.Make")
    model = get("Exif.Image.Model")
    return ImageTags(
        path=path,
        capture_time_s=None if capture is None else capture[0],
        capture_time_zone_known=False if capture is None else capture[1],
        capture_time_text=capture_text,
        make=make.strip() if make else None,
        model=model.strip() if model else None,
        focal_length_mm=_rational(focal) if focal else None,
        width_px=width_px,
        height_px=height_px,
        exposure_time_s=_rational(exposure) if exposure else None,
        gps_lat_deg=lat,
        gps_lon_deg=lon,
        gps_alt_amsl_m=alt,
        gps_time_utc_s=_gps_time(get("Exif.GPSInfo.GPSDateStamp"), get("Exif.GPSInfo.GPSTimeStamp")),
        camera_yaw_deg=_float(get("Xmp.Camera.Yaw")),
        camera_pitch_deg=_float(get("Xmp.Camera.Pitch")),
        camera_roll_deg=_float(get("Xmp.Camera.Roll")),
        xy_accuracy_m=_float(get("Xmp.Camera.GPSXYAccuracy")),
        z_accuracy_m=_float(get("Xmp.Camera.GPSZAccuracy")),
        dji_lat_deg=_float(get("Xmp.drone-dji.GpsLatitude")),
        dji_lon_deg=dji_lon,
        dji_alt_amsl_m=_float(get("Xmp.drone-dji.AbsoluteAltitude")),
        dji_alt_rel_home_m=_float(get("Xmp.drone-dji.RelativeAltitude")),
    )


# --------------------------------------------------------------------------------------------
# Reading, continued: camera-geometry and DJI attitude tags (added for the field check, issue 9;
# read side only, kept apart from read_tags so the two can be merged independently)

#: EXIF FocalPlaneResolutionUnit -> millimetres per unit (1 "no unit" is left unknown).
_FOCAL_PLANE_UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}


@dataclass(frozen=True, kw_only=True)
class CameraTags:
    """What a frame says about its camera's geometry and a DJI gimbal's attitude; absent -> None.

    - ``focal_plane_x_px_per_mm`` / ``_y_``: EXIF FocalPlaneX/YResolution converted with
      FocalPlaneResolutionUnit (2 inch, 3 cm, 4 mm, 5 um) to pixels per millimetre.
    - ``focal_length_35mm_mm``: EXIF FocalLengthIn35mmFilm (0 means unknown: None).
    - ``gimbal_*_deg``: DJI XMP ``drone-dji:GimbalYawDegree/GimbalPitchDegree/GimbalRollDegree``
      (earth-referenced; pitch -90 is nadir); ``flight_*_deg``: ``FlightYaw/Pitch/RollDegree``.
    - ``gps_altitude_ref``: EXIF GPSAltitudeRef as written (0 above, 1 below sea level).
    - ``pixel_x_dimension_px``: EXIF PixelXDimension, the width the camera wrote; an image
      reduced afterwards keeps it (and a focal plane resolution that counts those pixels).
    """

    focal_plane_x_px_per_mm: float | None = None
    focal_plane_y_px_per_mm: float | None = None
    focal_length_35mm_mm: float | None = None
    gimbal_yaw_deg: float | None = None
    gimbal_pitch_deg: float | None = None
    gimbal_roll_deg: float | None = None
    flight_yaw_deg: float | None = None
    flight_pitch_deg: float | None = None
    flight_roll_deg: float | None = None
    gps_altitude_ref: int | None = None
    pixel_x_dimension_px: int | None = None


def camera_tags_from_maps(exif: dict[str, Any], xmp: dict[str, Any]) -> CameraTags:
    """Build :class:`CameraTags` from pyexiv2's key -> text maps."""

    def get(key: str) -> str | None:
        value = exif.get(key, xmp.get(key))
        if isinstance(value, list):
            value = value[0] if value else None
        return None if value is None else str(value).strip()

    unit_text = get("Exif.Photo.FocalPlaneResolutionUnit")
    unit_mm = _FOCAL_PLANE_UNIT_MM.get(int(unit_text)) if unit_text and unit_text.isdigit() else None

    def per_mm(key: str) -> float | None:
        text = get(key)
        value = _rational(text) if text else None
        if value is None or unit_mm is None or not value > 0:
            return None
        return value / unit_mm

    f35_text = get("Exif.Photo.FocalLengthIn35mmFilm")
    f35 = _float(f35_text) if f35_text else None
    ref_text = get("Exif.GPSInfo.GPSAltitudeRef")
    width_text = get("Exif.Photo.PixelXDimension")
    return CameraTags(
        focal_plane_x_px_per_mm=per_mm("Exif.Photo.FocalPlaneXResolution"),
        focal_plane_y_px_per_mm=per_mm("Exif.Photo.FocalPlaneYResolution"),
        focal_length_35mm_mm=f35 if f35 is not None and f35 > 0 else None,
        gimbal_yaw_deg=_float(get("Xmp.drone-dji.GimbalYawDegree")),
        gimbal_pitch_deg=_float(get("Xmp.drone-dji.GimbalPitchDegree")),
        gimbal_roll_deg=_float(get("Xmp.drone-dji.GimbalRollDegree")),
        flight_yaw_deg=_float(get("Xmp.drone-dji.FlightYawDegree")),
        flight_pitch_deg=_float(get("Xmp.drone-dji.FlightPitchDegree")),
        flight_roll_deg=_float(get("Xmp.drone-dji.FlightRollDegree")),
        gps_altitude_ref=int(ref_text) if ref_text and ref_text.isdigit() else None,
        pixel_x_dimension_px=int(width_text)
        if width_text and width_text.isdigit() and int(width_text)
        else None,
    )


def read_tags_and_camera(path: str | os.PathLike[str]) -> tuple[ImageTags, CameraTags]:
    """:func:`read_tags` and :class:`CameraTags` of one JPEG from one read of its metadata."""
    exif, xmp, width, height, _ = _read_file_maps(path)
    tags = tags_from_maps(str(path), exif, xmp, width_px=width, height_px=height)
    return tags, camera_tags_from_maps(exif, xmp)


# --------------------------------------------------------------------------------------------
# Writing


def _exif_gps_values(tag: GeoTag) -> dict[str, str | None]:
    values: dict[str, str | None] = {
        "Exif.GPSInfo.GPSVersionID": "2 3 0 0",
        "Exif.GPSInfo.GPSLatitudeRef": "N" if tag.lat_deg >= 0 else "S",
        "Exif.GPSInfo.GPSLatitude": _deg_to_dms_text(tag.lat_deg),
        "Exif.GPSInfo.GPSLongitudeRef": "E" if tag.lon_deg >= 0 else "W",
        "Exif.GPSInfo.GPSLongitude": _deg_to_dms_text(tag.lon_deg),
        "Exif.GPSInfo.GPSMapDatum": "WGS-84",
    }
    if tag.alt_amsl_m is not None:
        values["Exif.GPSInfo.GPSAltitudeRef"] = "0" if tag.alt_amsl_m >= 0 else "1"
        values["Exif.GPSInfo.GPSAltitude"] = _to_rational_text(tag.alt_amsl_m, 1000)
    else:  # an old altitude would now belong to another place
        values["Exif.GPSInfo.GPSAltitudeRef"] = None
        values["Exif.GPSInfo.GPSAltitude"] = None
    if tag.time_utc_s is not None:
        moment = datetime.fromtimestamp(tag.time_utc_s, tz=UTC)
        # milliseconds, rounded half to even (as round() of the exact fraction of microseconds)
        millis, rest = divmod(moment.second * 1_000_000 + moment.microsecond, 1000)
        millis += rest > 500 or (rest == 500 and millis % 2 == 1)
        values["Exif.GPSInfo.GPSDateStamp"] = moment.strftime("%Y:%m:%d")
        values["Exif.GPSInfo.GPSTimeStamp"] = f"{moment.hour}/1 {moment.minute}/1 {millis}/1000"
    else:
        values["Exif.GPSInfo.GPSDateStamp"] = None
        values["Exif.GPSInfo.GPSTimeStamp"] = None
    if tag.yaw_deg is not None:
        values["Exif.GPSInfo.GPSImgDirectionRef"] = "T"
        values["Exif.GPSInfo.GPSImgDirection"] = _to_rational_text(tag.yaw_deg % 360.0, 100)
    else:
        values["Exif.GPSInfo.GPSImgDirectionRef"] = None
        values["Exif.GPSInfo.GPSImgDirection"] = None
    return values


def _xmp_values(tag: GeoTag, existing_xmp: dict[str, Any]) -> dict[str, str | None]:
    values: dict[str, str | None] = {}
    pix4d = {
        "Xmp.Camera.Yaw": tag.yaw_deg,
        "Xmp.Camera.Pitch": tag.pitch_deg,
        "Xmp.Camera.Roll": tag.roll_deg,
        "Xmp.Camera.GPSXYAccuracy": tag.xy_accuracy_m,
        "Xmp.Camera.GPSZAccuracy": tag.z_accuracy_m,
    }
    for key, value in pix4d.items():
        if value is not None:
            values[key] = f"{value:.6f}"
        elif key in existing_xmp:
            values[key] = None  # stale attitude of another pose: remove it
    dji = {
        "Xmp.drone-dji.GpsLatitude": f"{tag.lat_deg:+.9f}",
        "Xmp.drone-dji.GpsLongitude": f"{tag.lon_deg:+.9f}",
        "Xmp.drone-dji.GpsLongtitude": f"{tag.lon_deg:+.9f}",
        "Xmp.drone-dji.AbsoluteAltitude": None if tag.alt_amsl_m is None else f"{tag.alt_amsl_m:+.3f}",
        "Xmp.drone-dji.RelativeAltitude": None
        if tag.alt_rel_home_m is None
        else f"{tag.alt_rel_home_m:+.3f}",
    }
    # XMP copies of the EXIF GPS tags (exif namespace), written by some cameras and editors.
    xmp_exif = {
        "Xmp.exif.GPSLatitude": _xmp_coordinate(tag.lat_deg, "N", "S"),
        "Xmp.exif.GPSLongitude": _xmp_coordinate(tag.lon_deg, "E", "W"),
        "Xmp.exif.GPSAltitude": None if tag.alt_amsl_m is None else _to_rational_text(tag.alt_amsl_m, 1000),
        "Xmp.exif.GPSAltitudeRef": None if tag.alt_amsl_m is None else ("0" if tag.alt_amsl_m >= 0 else "1"),
    }
    for key, text in {**dji, **xmp_exif}.items():
        # Only update what the file carries: adding DJI tags to another camera's file would lie
        # about its origin. A carried value we cannot replace is removed rather than left stale.
        if key in existing_xmp:
            values[key] = text
    return values


def _xmp_coordinate(value_deg: float, positive: str, negative: str) -> str:
    """XMP GPSCoordinate form 'DDD,MM.mmmmmmmk' (degrees, decimal minutes, hemisphere)."""
    value = abs(value_deg)
    degrees = int(value)
    minutes = (value - degrees) * 60.0
    return f"{degrees},{minutes:.8f}{positive if value_deg >= 0 else negative}"


# The file is handled in two parts. The header (every segment before the first SOS marker: APP1
# EXIF, APP1 XMP, quantisation and Huffman tables...) is what exiv2 rewrites; it is a few KiB to a
# few hundred KiB. Everything from the first SOS marker to the end of the file (the scans, EOI and
# any trailer such as a DJI preview) is copied by the kernel without entering Python
# (os.copy_file_range), so a 40 MB frame costs what its header costs plus a page-cache copy.
# exiv2 itself copies everything from SOS on verbatim when it writes a JPEG, so giving it the
# header and a stub scan ("SOS header, one byte, EOI") yields the same header bytes as giving it
# the whole file; the stub's tail is checked to come back unchanged.

_HEADER_CHUNK = 1 << 16
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)
_STUB_SCAN = b"\x00\xff\xd9"


@dataclass(frozen=True)
class _Split:
    """A JPEG's header (bytes before the first SOS) and where the image data starts."""

    header: bytes  # data[:sos]
    sos_segment: bytes  # the SOS marker segment itself (marker, length, component table)
    sos_offset: int
    size: int


def _split_header(read_at: Any, size: int, name: str) -> _Split:
    """Find the first SOS marker by walking the header segments; ``read_at(offset, n)`` reads."""
    # bytes, grown by concatenation when a header runs past the first chunk (rare): most headers
    # are parsed from the first read without copying it again
    buffer: bytes = bytes(read_at(0, min(size, _HEADER_CHUNK)))

    def need(end: int) -> None:
        nonlocal buffer
        if end > len(buffer) and len(buffer) < size:
            buffer += read_at(len(buffer), min(size, max(end, len(buffer) + _HEADER_CHUNK)) - len(buffer))

    if not buffer.startswith(b"\xff\xd8"):
        raise GeotagError(f"{name}: not a JPEG file (no SOI marker); remove it from the folder")
    pos = 2
    while True:
        need(pos + 4)
        while pos + 1 < len(buffer) and buffer[pos] == 0xFF and buffer[pos + 1] == 0xFF:
            pos += 1  # fill bytes
            need(pos + 4)
        if pos + 4 > len(buffer) or buffer[pos] != 0xFF:
            raise GeotagError(
                f"{name}: JPEG structure broken at byte {pos} before the image data; "
                f"the file is damaged, replace it from the card"
            )
        marker = buffer[pos + 1]
        if marker in _STANDALONE_MARKERS:
            pos += 2
            continue
        if marker == 0xD9:
            raise GeotagError(f"{name}: JPEG ends (EOI) before any image data; the file is damaged")
        length = int.from_bytes(buffer[pos + 2 : pos + 4], "big")
        if length < 2:
            raise GeotagError(f"{name}: JPEG segment at byte {pos} has length {length}; the file is damaged")
        if marker == 0xDA:
            need(pos + 2 + length)
            if pos + 2 + length > len(buffer):
                raise GeotagError(f"{name}: JPEG truncated in its scan header at byte {pos}")
            return _Split(
                header=bytes(buffer[:pos]),
                sos_segment=bytes(buffer[pos : pos + 2 + length]),
                sos_offset=pos,
                size=size,
            )
        pos += 2 + length


def _split_bytes(data: bytes, name: str) -> _Split:
    return _split_header(lambda offset, n: data[offset : offset + n], len(data), name)


def _compose_header(split: _Split, name: str, change: Any) -> bytes:
    """Run ``change(image, exif, xmp)`` on the header through exiv2; the new header bytes.

    ``change`` gets the pyexiv2 image of the header plus a stub scan and the EXIF and XMP
    key -> value maps it carries, and makes its modifications.
    """
    _register_namespaces()
    stub_tail = split.sos_segment + _STUB_SCAN
    image = _open(split.header + stub_tail, name)
    try:
        exif, xmp = _read_maps(image, name)
        try:
            change(image, exif, xmp)
        except (RuntimeError, ValueError) as error:
            raise GeotagError(f"{name}: tags cannot be written ({error})") from error
        composed: bytes = image.get_bytes()
    finally:
        image.close()
    out = _split_bytes(composed, name)
    # exiv2 copies everything from SOS on verbatim: anything else means it touched the image data.
    if composed[out.sos_offset :] != stub_tail:
        raise GeotagError(f"{name}: writing the tags would change the image data; file left as it was")
    return out.header


def _geotag_change(tag: GeoTag) -> Any:
    def change(image: pyexiv2.ImageData, exif: dict[str, Any], xmp: dict[str, Any]) -> None:
        exif_values = _exif_gps_values(tag)
        # Everything else in the GPS IFD (speed, track, DOP, status...) described the old fix.
        for key in exif:
            if key.startswith("Exif.GPSInfo.") and key not in exif_values:
                exif_values[key] = None
        # Deleting an absent tag is not an error worth a call into exiv2.
        exif_values = {k: v for k, v in exif_values.items() if v is not None or k in exif}
        image.modify_exif(exif_values)
        xmp_values = _xmp_values(tag, xmp)
        if xmp_values:
            image.modify_xmp(xmp_values)

    return change


#: ``fast(header, maps)``: the new header, or UnsupportedHeaderError; ``maps`` are the header's
#: (EXIF, XMP) maps when already read (:class:`HeaderSnapshot`), else None.
FastChange = Callable[[bytes, "tuple[dict[str, str], dict[str, Any]] | None"], bytes]


def _geotag_fast(tag: GeoTag) -> FastChange:
    """What :func:`_geotag_change` does, without exiv2: a new GPS IFD, the XMP edited in place."""
    gps = {key: value for key, value in _exif_gps_values(tag).items() if value is not None}

    def fast(header: bytes, maps: tuple[dict[str, str], dict[str, Any]] | None) -> bytes:
        return jpeg_meta.patch_header(header, gps, lambda xmp: _xmp_values(tag, xmp), maps=maps)

    return fast


def _strip_change(attitude: bool) -> Any:
    def change(image: pyexiv2.ImageData, exif: dict[str, Any], xmp: dict[str, Any]) -> None:
        gps_keys = {key: None for key in exif if key.startswith("Exif.GPSInfo.")}
        if gps_keys:
            image.modify_exif(gps_keys)
        xmp_keys = [k for k in _DJI_POSITION_KEYS if k in xmp]
        if attitude:
            xmp_keys += [k for k in _PIX4D_KEYS if k in xmp]
        if xmp_keys:
            image.modify_xmp(dict.fromkeys(xmp_keys))

    return change


def geotag_bytes(data: bytes, tag: GeoTag, *, name: str = "<bytes>") -> bytes:
    """The JPEG ``data`` with ``tag`` written into its EXIF and XMP; image data untouched."""
    split = _split_bytes(data, name)
    return _compose_header(split, name, _geotag_change(tag)) + data[split.sos_offset :]


def _split_seen(fd: int, stat: os.stat_result, seen: HeaderSnapshot | None) -> _Split | None:
    """The header as ``seen`` found it, read in one call, when the file is still the one it
    read (same identity, and the SOS segment where it was); else None."""
    if seen is None or identity(stat) != seen.identity:
        return None
    end = seen.sos_offset + len(seen.sos_segment)
    data = os.pread(fd, end, 0)
    if len(data) != end or not data.startswith(b"\xff\xd8") or data[seen.sos_offset :] != seen.sos_segment:
        return None
    return _Split(
        header=data[: seen.sos_offset],
        sos_segment=seen.sos_segment,
        sos_offset=seen.sos_offset,
        size=stat.st_size,
    )


def _write_out(out_fd: int, header: bytes, src_fd: int, split: _Split) -> None:
    """The new file: ``header``, then the source from its SOS marker on, copied in the kernel.

    A header of the old one's length (the usual case, see :func:`acquisition.jpeg_meta.patch_header`)
    leaves the image data at its offset: the whole file is copied, page for page as ``cp`` does
    (a third less kernel time than a copy shifted by a few bytes), and the header written over
    its first bytes."""
    if len(header) == split.sos_offset:
        copy_range(src_fd, out_fd, 0, split.size)
        if os.pwrite(out_fd, header, 0) != len(header):
            raise GeotagError("the new header could not be written whole")
        return
    if os.write(out_fd, header) != len(header):
        raise GeotagError("the new header could not be written whole")
    copy_range(src_fd, out_fd, split.sos_offset, split.size - split.sos_offset)


def _write_over_copy(target: Path, header: bytes, src_fd: int, split: _Split, copied: Copied) -> None:
    """The new header written over a byte copy of the source at ``target``: over its first bytes
    when it has the old header's length, else the copy rewritten whole (and a file reserved
    empty, written whole). The file is removed when that fails (it holds the frame without its
    tags)."""
    try:
        out = os.open(target, os.O_RDWR | _CLOEXEC)
        try:
            if copied.identity is not None and len(header) == split.sos_offset:
                if os.pwrite(out, header, 0) != len(header):
                    raise GeotagError("the new header could not be written whole")
            else:
                os.ftruncate(out, 0)
                _write_out(out, header, src_fd, split)
        finally:
            os.close(out)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            target.unlink()
        raise


def _has_eoi(fd: int, split: _Split, name: str) -> bool:
    """True when the image data ends with an EOI marker.

    The common case costs one 2-byte read: the file ends with EOI. Otherwise (a trailer after EOI
    such as a DJI preview, padding, or a damaged end) the scans are walked to find out.
    """
    if os.pread(fd, 2, split.size - 2) == b"\xff\xd9":
        return True
    data = os.pread(fd, split.size, 0)
    try:
        compressed_image_data(data)
    except GeotagError:
        return False
    return True


def _remove_copy(copied: Copied) -> None:
    with contextlib.suppress(FileNotFoundError):
        copied.path.unlink()


def _write_file(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    change: Any,
    *,
    overwrite: bool,
    atomic: bool,
    check_end: bool = True,
    fast: FastChange | None = None,
    seen: HeaderSnapshot | None = None,
    copied: Copied | None = None,
) -> tuple[Path, list[str]]:
    """``src`` with its header changed by ``change`` written to ``dst``; (path, warnings).

    ``fast(header, maps)``, when given, makes the same change without exiv2
    (:mod:`acquisition.jpeg_meta`); a header it does not handle goes to exiv2. ``seen``: what an
    earlier read of ``src`` saw (:class:`HeaderSnapshot`), used while the file is the same.
    ``copied``: a byte copy of ``src`` already at ``dst`` (:mod:`acquisition.card_ahead`),
    written over when it is of the file as it is now, else removed and ``dst`` written whole;
    the caller removes it when this raises (:func:`_run_job`)."""
    name = str(src)
    warnings: list[str] = []
    same = os.path.abspath(src) == os.path.abspath(dst)
    target = Path(dst)
    with open(src, "rb", buffering=0) as source:  # read with pread only: no buffer
        fd = source.fileno()
        stat = os.fstat(fd)
        size = stat.st_size
        split = _split_seen(fd, stat, seen)
        maps = None if split is None or seen is None else (seen.exif, seen.xmp)
        if split is None:
            split = _split_header(lambda offset, n: os.pread(fd, n, offset), size, name)
        header = None
        if fast is not None:
            try:
                header = fast(split.header, maps)
            except (jpeg_meta.UnsupportedHeaderError, UnicodeDecodeError, struct.error, ValueError) as error:
                log.debug("%s: tags written by exiv2 (%s)", name, error)
        if header is None:
            header = _compose_header(split, name, change)
        # A byte copy already at the target is used when it is of the file as it is now.
        if copied is not None and (
            atomic or same or copied.path != target or copied.identity not in (None, identity(stat))
        ):
            _remove_copy(copied)  # of another version of the file, or meant for another path
            copied = None
        if copied is not None:
            _write_over_copy(target, header, fd, split, copied)
        elif atomic or same:
            with atomic_file(target, overwrite=overwrite or same, buffering=0) as out:
                _write_out(out.fileno(), header, fd, split)
        else:
            created = False
            try:
                with target.open("wb" if overwrite else "xb", buffering=0) as out:
                    created = True
                    _write_out(out.fileno(), header, fd, split)
            except FileExistsError as error:
                raise OutputExistsError(f"{target} exists; pass --overwrite to replace it") from error
            except BaseException:
                if created:
                    with contextlib.suppress(FileNotFoundError):
                        target.unlink()
                raise
        # After the copy, which brought the file's end into the page cache: one 2-byte read.
        if check_end and not _has_eoi(fd, split, name):
            warnings.append(
                f"{name}: the image data has no end marker (EOI): the file was cut short or "
                f"damaged on the card; decoders still read it, tags written, image data copied "
                f"unchanged"
            )
    for text in warnings:
        log.warning("%s", text)
    return target, warnings


def write_geotag(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    tag: GeoTag,
    *,
    overwrite: bool = False,
    check_image_data: bool = True,
    atomic: bool = True,
) -> Path:
    """Write ``src`` with ``tag`` to ``dst`` (``dst`` may equal ``src``: in place).

    ``src`` is read once: its header segments (up to the first SOS marker) are rewritten with
    the new tags and the rest of the file, image data and any trailer, is copied byte for byte
    by the kernel. A file whose image data has no end marker (EOI; cut short on the card) is
    still tagged, with a logged warning that names it (:func:`write_geotags` returns it).

    ``check_image_data`` is kept for compatibility: the image data is never re-encoded or
    passed through exiv2, and exiv2's handling of the scan it is given is always checked.
    With ``atomic`` (always for in-place writes) the file goes through a synced temporary file
    and a rename; without, it is written directly, for a caller that stages a whole folder and
    moves it into place at once (:func:`planner.outputs.staged_output_dir`).
    """
    del check_image_data
    path, _ = _write_file(
        src, dst, _geotag_change(tag), overwrite=overwrite, atomic=atomic, fast=_geotag_fast(tag)
    )
    return path


@dataclass(frozen=True, kw_only=True)
class GeotagJob:
    """One frame to write: ``src`` with ``tag`` to ``dst`` (``dst`` may equal ``src``)."""

    src: str
    dst: str
    tag: GeoTag
    #: what reading ``src`` earlier saw (:func:`read_tags_and_header`): spares a second parse
    seen: HeaderSnapshot | None = None


@dataclass(frozen=True, kw_only=True)
class GeotagWriteResult:
    """What became of one :class:`GeotagJob`: ``error`` (None when written, else the message,
    which names the file) and ``warnings`` (e.g. a missing end marker)."""

    src: str
    dst: str
    error: str | None = None
    warnings: tuple[str, ...] = ()

    @property
    def written(self) -> bool:
        return self.error is None


def _run_job(job: GeotagJob, overwrite: bool, atomic: bool, ahead: CardAhead | None) -> GeotagWriteResult:
    copied = None if ahead is None else ahead.take(job.src)
    try:
        _, warnings = _write_file(
            job.src,
            job.dst,
            _geotag_change(job.tag),
            overwrite=overwrite,
            atomic=atomic,
            fast=_geotag_fast(job.tag),
            seen=job.seen,
            copied=copied,
        )
    except BaseException as error:
        if copied is not None:  # the untagged copy must not stay where the tagged frame belongs
            _remove_copy(copied)
        if isinstance(error, GeotagError | OSError):
            return GeotagWriteResult(src=job.src, dst=job.dst, error=str(error))
        raise
    return GeotagWriteResult(src=job.src, dst=job.dst, warnings=tuple(warnings))


def write_geotags(
    jobs: Iterable[GeotagJob],
    *,
    workers: int | None = None,
    overwrite: bool = False,
    atomic: bool = True,
    progress: Callable[[int], None] | None = None,
    ahead: CardAhead | None = None,
) -> list[GeotagWriteResult]:
    """Write many frames, ``workers`` at a time (default: the CPUs this process may use, at most 4).

    ``ahead``: the frames being copied byte for byte to their destinations by a worker
    (:mod:`acquisition.card_ahead`); each job takes its copy and writes the header over it.
    A frame that cannot be written does not stop the others: its result carries the error.
    Results come back in the order of ``jobs``; ``progress(n)`` is called with the number done.
    Threads suffice: the copy runs in the kernel without the GIL, and exiv2's share is small.
    """
    job_list = list(jobs)
    if workers is None:
        workers = min(4, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 1)
    if workers < 1:
        raise GeotagError(f"workers is {workers}; give 1 or more")
    process_umask()  # read (it is set and reset) before any thread creates a file
    # Behind the copier, in its order (see acquisition.card_ahead).
    order = list(range(len(job_list))) if ahead is None else ahead.writing_order([j.src for j in job_list])

    def run(k: int) -> GeotagWriteResult:
        return _run_job(job_list[k], overwrite, atomic, ahead)

    results: dict[int, GeotagWriteResult] = {}
    with contextlib.ExitStack() as stack:
        if workers == 1 or len(job_list) < 2:
            outcomes: Iterable[GeotagWriteResult] = map(run, order)
        else:
            outcomes = stack.enter_context(ThreadPoolExecutor(max_workers=workers)).map(run, order)
        for n, (k, result) in enumerate(zip(order, outcomes, strict=True), start=1):
            results[k] = result
            if progress is not None:
                progress(n)
    return [results[k] for k in range(len(job_list))]


def strip_gps(
    src: str | os.PathLike[str],
    dst: str | os.PathLike[str],
    *,
    attitude: bool = False,
    overwrite: bool = False,
) -> Path:
    """Copy ``src`` to ``dst`` without its position: EXIF GPS and DJI XMP position tags removed.

    With ``attitude`` the Pix4D XMP camera attitude and accuracy tags go too. Image data untouched.
    """
    path, _ = _write_file(src, dst, _strip_change(attitude), overwrite=overwrite, atomic=True)
    return path


# --------------------------------------------------------------------------------------------
# The image data itself


_STANDALONE_MARKERS = {0x01, *range(0xD0, 0xD8)}
_SCAN_MARKER = re.compile(rb"\xff[^\x00\xd0-\xd7\xff]")


def compressed_image_data(source: bytes | str | os.PathLike[str]) -> bytes:
    """The JPEG's compressed image: every byte from the first SOS marker to the EOI marker.

    This covers all scans (and the tables between the scans of a progressive JPEG) and excludes
    every metadata segment before the first scan and anything appended after EOI (DJI and phones
    append preview images there). Raises :class:`GeotagError` for a file that is not a JPEG or
    ends before its EOI.
    """
    data = source if isinstance(source, bytes) else Path(source).read_bytes()
    name = "<bytes>" if isinstance(source, bytes) else str(source)
    if not data.startswith(b"\xff\xd8"):
        raise GeotagError(f"{name}: not a JPEG (no SOI marker)")
    pos = 2
    size = len(data)
    while True:
        # Header segments: marker, 2-byte big-endian length (which counts itself).
        while pos < size and data[pos] == 0xFF and pos + 1 < size and data[pos + 1] == 0xFF:
            pos += 1  # fill bytes
        if pos + 4 > size or data[pos] != 0xFF:
            raise GeotagError(f"{name}: JPEG structure broken at byte {pos} before any scan")
        marker = data[pos + 1]
        if marker == 0xDA:
            break
        if marker in _STANDALONE_MARKERS:
            pos += 2
            continue
        if marker == 0xD9:
            raise GeotagError(f"{name}: JPEG ends (EOI) before any scan")
        length = int.from_bytes(data[pos + 2 : pos + 4], "big")
        pos += 2 + length
    start = pos
    # Scan data: 0xFF is followed by 0x00 (stuffing), a restart marker, 0xFF (fill) or a marker
    # that starts a segment; EOI ends. The regular expression finds the next real marker in C.
    search = pos + 2 + int.from_bytes(data[pos + 2 : pos + 4], "big")  # past the SOS header
    while True:
        found = _SCAN_MARKER.search(data, search)
        if found is None:
            raise GeotagError(f"{name}: JPEG truncated: no EOI marker after the image data")
        ff = found.start()
        if data[ff + 1] == 0xD9:
            return data[start : ff + 2]
        # A segment between scans (DHT, SOS, DRI of a progressive JPEG): skip it by its length.
        if ff + 4 > size:
            raise GeotagError(f"{name}: JPEG truncated inside a segment at byte {ff}")
        length = int.from_bytes(data[ff + 2 : ff + 4], "big")
        search = ff + 2 + length
