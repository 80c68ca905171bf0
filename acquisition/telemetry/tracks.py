"""GPS tracks from text files -> :class:`~acquisition.telemetry.model.FlightLog` (positions, and
attitudes when the CSV has them). No camera events: frames are placed by time.

ExifTool CSV track (the layout ``exiftool -geotag`` accepts; exiftool.org/geotag.html, "ExifTool
CSV Log File Format"): the first row holds column headings, ExifTool tag names or their
descriptions, optionally with a group prefix (``GPS:GPSLatitude``, ``GPS Latitude``):

- ``GPSDateTime`` (EXIF ``YYYY:MM:DD HH:MM:SS[.ss][Z|+-HH:MM]``; UTC unless a zone is given),
  or ``GPSDateStamp`` and ``GPSTimeStamp``;
- ``GPSLatitude``, ``GPSLongitude`` in any ExifTool form: signed decimal degrees, or
  degrees/minutes/seconds with a hemisphere letter (``47 deg 7' 22.80" N``); ``GPSLatitudeRef``
  / ``GPSLongitudeRef`` (``S``/``W``) apply when the value has no sign or letter;
- optional: ``GPSAltitude`` (metres above sea level, ``Below Sea Level`` negative),
  ``GPSImgDirection`` (yaw, degrees true), ``GPSPitch`` or ``CameraElevationAngle``,
  ``GPSRoll``; other columns are ignored, as exiftool does.

GPX 1.1 (and 1.0): every ``trk/trkseg/trkpt`` with its ``lat``, ``lon`` attributes, ``ele``
(metres, taken as AMSL) and ``time`` (ISO 8601, UTC when no offset is given).

Errors name the file and line, the bad value and what was expected.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import logging
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass, field
from xml.parsers import expat

import numpy as np

from ..errors import TelemetryError
from .gpstime import time_order
from .model import AttitudeTrack, FlightLog, PositionTrack

log = logging.getLogger(__name__)

_NUMBER = re.compile(r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?")
_EXIF_DATETIME = re.compile(
    r"^\s*(\d{4})[:\-](\d{2})[:\-](\d{2})[ T](\d{2}):(\d{2}):(\d{2}(?:\.\d+)?)"
    r"\s*(Z|[+-]\d{2}:?\d{2})?\s*$"
)
_EXIF_DATE = re.compile(r"^\s*(\d{4})[:\-](\d{2})[:\-](\d{2})\s*$")
_EXIF_TIME = re.compile(r"^\s*(\d{1,2}):(\d{2}):(\d{2}(?:\.\d+)?)\s*(Z|[+-]\d{2}:?\d{2})?\s*$")

CSV_TIME_COLUMNS = ("gpsdatetime",)
CSV_REQUIRED = ("gpslatitude", "gpslongitude")


def normalize_heading(heading: str) -> str:
    """``GPS:GPSLatitude``, ``GPS Latitude``, ``gps_latitude`` -> ``gpslatitude``; a unit in
    parentheses is dropped (``GPS Speed (km/h)`` -> ``gpsspeed``)."""
    h = heading.strip().lstrip("\ufeff")
    h = h.rsplit(":", 1)[-1]
    h = re.sub(r"\(.*?\)", "", h)
    return re.sub(r"[\s/_\-]", "", h).lower()


def _zone_seconds(zone: str | None) -> int:
    if not zone or zone == "Z":
        return 0
    sign = -1 if zone[0] == "-" else 1
    digits = zone[1:].replace(":", "")
    return sign * (int(digits[:2]) * 3600 + int(digits[2:4]) * 60)


def _posix(y: int, mo: int, d: int, h: int, mi: int, s: float, zone: str | None) -> float:
    base = dt.datetime(y, mo, d, h, mi, tzinfo=dt.UTC).timestamp()
    return base + s - _zone_seconds(zone)


def parse_exif_datetime(text: str) -> float:
    """UTC POSIX seconds of an EXIF/ISO date-time (``2016:11:22 15:32:01.25Z``); UTC when no
    zone is given. Raises ValueError."""
    m = _EXIF_DATETIME.match(text)
    if not m:
        raise ValueError("expected YYYY:MM:DD HH:MM:SS[.ss][Z|+HH:MM]")
    y, mo, d, h, mi = (int(m.group(i)) for i in range(1, 6))
    return _posix(y, mo, d, h, mi, float(m.group(6)), m.group(7))


def parse_angle_deg(text: str, *, positive: str, negative: str) -> float:
    """Degrees of an ExifTool coordinate: ``-47.5``, ``47.5 S``, ``47 30 0 S``,
    ``47 deg 30' 0.00" S``. ``positive``/``negative`` are the hemisphere letters."""
    t = text.strip()
    letters = re.findall(r"(?<![A-Za-z])([NSEWnsew])(?![A-Za-z])", t)
    numbers = [float(x) for x in _NUMBER.findall(t)]
    if not numbers or len(numbers) > 3 or len(letters) > 1:
        raise ValueError("expected decimal degrees or degrees minutes seconds")
    sign = -1.0 if numbers[0] < 0 or t.startswith("-") else 1.0
    mags = [abs(v) for v in numbers]
    if any(v >= 60 for v in mags[1:]):
        raise ValueError("minutes and seconds must be below 60")
    value = mags[0] + (mags[1] / 60 if len(mags) > 1 else 0) + (mags[2] / 3600 if len(mags) > 2 else 0)
    if letters:
        letter = letters[0].upper()
        if letter not in (positive, negative):
            raise ValueError(f"hemisphere {letter!r} is not {positive} or {negative}")
        if letter == negative:
            sign = -1.0
    return sign * value


def _has_hemisphere_or_sign(text: str) -> bool:
    t = text.strip()
    return t.startswith(("-", "+")) or bool(re.search(r"(?<![A-Za-z])[NSEWnsew](?![A-Za-z])", t))


def _altitude_m(text: str) -> float:
    numbers = _NUMBER.findall(text)
    if len(numbers) != 1:
        raise ValueError("expected metres, e.g. 312.5 or '312.5 m Above Sea Level'")
    value = float(numbers[0])
    return -abs(value) if "below" in text.lower() else value


@dataclass
class _Column:
    """Values of one optional column, with the first line where a cell was empty."""

    values: list[float] = field(default_factory=list)
    first_empty_line: int | None = None


def _csv_rows(text: str) -> Iterator[tuple[int, list[str]]]:
    reader = csv.reader(io.StringIO(text))
    for row in reader:
        yield reader.line_num, row


def read_csv_track(path: str | os.PathLike[str]) -> FlightLog:
    """Read an ExifTool CSV track log (see the module docstring)."""
    p = os.fspath(path)
    try:
        with open(p, encoding="utf-8-sig", newline="") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise TelemetryError(f"cannot read {p}: {exc}") from exc
    rows = _csv_rows(text)
    try:
        header_line, header = next(rows)
    except StopIteration:
        raise TelemetryError(f"{p}: empty file; expected a CSV header row") from None
    except csv.Error as exc:
        raise TelemetryError(f"{p}, line 1: {exc}") from exc
    names = [normalize_heading(h) for h in header]
    index = {n: i for i, n in enumerate(names) if n}
    has_datetime = "gpsdatetime" in index
    has_split = "gpsdatestamp" in index and "gpstimestamp" in index
    missing = [c for c in CSV_REQUIRED if c not in index]
    if missing or not (has_datetime or has_split):
        need = ["GPSDateTime (or GPSDateStamp and GPSTimeStamp)"] if not (has_datetime or has_split) else []
        need += [{"gpslatitude": "GPSLatitude", "gpslongitude": "GPSLongitude"}[c] for c in missing]
        raise TelemetryError(
            f"{p}, line {header_line}: the header lacks {', '.join(need)}; found "
            f"{', '.join(h.strip() for h in header) or 'nothing'} (exiftool's CSV track layout)"
        )
    optional = {
        "alt": "gpsaltitude",
        "yaw": "gpsimgdirection",
        "pitch": "gpspitch" if "gpspitch" in index else "cameraelevationangle",
        "roll": "gpsroll",
    }
    columns = {k: _Column() for k, name in optional.items() if name in index}
    times: list[float] = []
    lats: list[float] = []
    lons: list[float] = []

    def cell(row: list[str], name: str) -> str:
        i = index[name]
        return row[i].strip() if i < len(row) else ""

    line = header_line
    try:
        for line, row in rows:
            if not any(c.strip() for c in row):
                continue
            what = "GPSDateTime"
            try:
                if has_datetime:
                    value = cell(row, "gpsdatetime")
                    times.append(parse_exif_datetime(value))
                else:
                    what = "GPSDateStamp/GPSTimeStamp"
                    value = f"{cell(row, 'gpsdatestamp')} {cell(row, 'gpstimestamp')}"
                    times.append(parse_exif_datetime(value))
                what, value = "GPSLatitude", cell(row, "gpslatitude")
                lat = parse_angle_deg(value, positive="N", negative="S")
                if (
                    "gpslatituderef" in index
                    and not _has_hemisphere_or_sign(value)
                    and cell(row, "gpslatituderef").upper().startswith("S")
                ):
                    lat = -lat
                what, value = "GPSLongitude", cell(row, "gpslongitude")
                lon = parse_angle_deg(value, positive="E", negative="W")
                if (
                    "gpslongituderef" in index
                    and not _has_hemisphere_or_sign(value)
                    and cell(row, "gpslongituderef").upper().startswith("W")
                ):
                    lon = -lon
                if not -90 <= lat <= 90 or not -180 <= lon <= 180:
                    what, value = "GPSLatitude/GPSLongitude", f"{lat}, {lon}"
                    raise ValueError("outside -90..90 / -180..180 degrees")
                lats.append(lat)
                lons.append(lon)
                for key, col in columns.items():
                    what = header[index[optional[key]]].strip()
                    value = cell(row, optional[key])
                    if not value:
                        if col.first_empty_line is None:
                            col.first_empty_line = line
                        col.values.append(0.0)
                    elif key == "alt":
                        col.values.append(_altitude_m(value))
                    else:
                        col.values.append(
                            float(_NUMBER.findall(value)[0]) if _NUMBER.search(value) else float(value)
                        )
            except ValueError as exc:
                raise TelemetryError(f"{p}, line {line}: {what} {value!r}: {exc}") from None
    except csv.Error as exc:
        raise TelemetryError(f"{p}, line {line + 1}: {exc}") from exc
    if not times:
        raise TelemetryError(f"{p}: no track point after the header")
    warnings: list[str] = []
    kept: dict[str, np.ndarray] = {}
    for key, col in columns.items():
        if col.first_empty_line is not None:
            warnings.append(
                f"{p}: column {header[index[optional[key]]].strip()} is empty at line "
                f"{col.first_empty_line} (and maybe others); the column is not used"
            )
        else:
            kept[key] = np.array(col.values, dtype=np.float64)
    t = np.array(times, dtype=np.float64)
    o = time_order(t)
    if len(o) < len(t):
        warnings.append(f"{p}: {len(t) - len(o)} rows with a repeated time dropped")
    positions = PositionTrack(
        time_utc_s=t[o],
        lat_deg=np.array(lats)[o],
        lon_deg=np.array(lons)[o],
        alt_amsl_m=kept["alt"][o] if "alt" in kept else None,
        source="csv",
    )
    attitudes = None
    if {"yaw", "pitch", "roll"} <= kept.keys():
        attitudes = AttitudeTrack(
            time_utc_s=t[o],
            roll_deg=kept["roll"][o],
            pitch_deg=kept["pitch"][o],
            yaw_deg=np.mod(kept["yaw"][o], 360.0),
            source="csv",
        )
    elif kept.keys() & {"yaw", "pitch", "roll"}:
        warnings.append(
            f"{p}: attitude needs GPSImgDirection, GPSPitch (or CameraElevationAngle) and "
            f"GPSRoll; only some are present, so no attitude is read"
        )
    for w in warnings:
        log.warning("%s", w)
    return FlightLog(path=p, format="csv", positions=positions, attitudes=attitudes, warnings=tuple(warnings))


def _parse_iso_time(text: str) -> float:
    t = text.strip()
    try:
        stamp = dt.datetime.fromisoformat(t.replace("z", "Z"))
    except ValueError:
        raise ValueError("expected an ISO 8601 time such as 2016-11-22T15:32:01Z") from None
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=dt.UTC)
    return stamp.timestamp()


def read_gpx(path: str | os.PathLike[str]) -> FlightLog:
    """Read the track points of a GPX 1.1 (or 1.0) file (see the module docstring)."""
    p = os.fspath(path)
    parser = expat.ParserCreate(namespace_separator=" ")
    points: list[tuple[int, float, float, float | None, float | None]] = []
    state: dict[str, object] = {"pt": None, "text": None}
    errors: list[str] = []

    def local(name: str) -> str:
        return name.rsplit(" ", 1)[-1]

    def start(name: str, attrs: dict[str, str]) -> None:
        tag = local(name)
        if tag == "trkpt":
            line = parser.CurrentLineNumber
            try:
                lat = float(attrs["lat"])
                lon = float(attrs["lon"])
            except (KeyError, ValueError):
                errors.append(
                    f"{p}, line {line}: trkpt needs numeric lat and lon attributes, got "
                    f"{attrs.get('lat')!r}, {attrs.get('lon')!r}"
                )
                lat = lon = float("nan")
            if not (-90 <= lat <= 90 and -180 <= lon <= 180) and not errors:
                errors.append(f"{p}, line {line}: trkpt lat {lat}, lon {lon} out of range")
            state["pt"] = {"line": line, "lat": lat, "lon": lon, "ele": None, "time": None}
        elif tag in ("ele", "time") and state["pt"] is not None:
            state["text"] = []
            state["tag_line"] = parser.CurrentLineNumber

    def chars(data: str) -> None:
        buf = state["text"]
        if isinstance(buf, list):
            buf.append(data)

    def end(name: str) -> None:
        tag = local(name)
        pt = state["pt"]
        if not isinstance(pt, dict):
            return
        if tag in ("ele", "time") and isinstance(state["text"], list):
            value = "".join(state["text"]).strip()
            state["text"] = None
            try:
                pt[tag] = float(value) if tag == "ele" else _parse_iso_time(value)
            except ValueError as exc:
                errors.append(f"{p}, line {state['tag_line']}: <{tag}> {value!r}: {exc}")
        elif tag == "trkpt":
            if pt["time"] is None and not errors:
                errors.append(f"{p}, line {pt['line']}: trkpt without <time>; cannot place it")
            points.append((pt["line"], pt["lat"], pt["lon"], pt["ele"], pt["time"]))
            state["pt"] = None

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        with open(p, "rb") as f:
            parser.ParseFile(f)
    except OSError as exc:
        raise TelemetryError(f"cannot read {p}: {exc}") from exc
    except expat.ExpatError as exc:
        raise TelemetryError(
            f"{p}, line {exc.lineno}: not well-formed XML ({expat.ErrorString(exc.code)})"
        ) from None
    if errors:
        raise TelemetryError(errors[0] + (f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""))
    if not points:
        raise TelemetryError(f"{p}: no <trkpt> in the file; a GPX track is needed")
    t = np.array([pt[4] for pt in points], dtype=np.float64)
    warnings: list[str] = []
    eles = [pt[3] for pt in points]
    alt = None
    if all(e is not None for e in eles):
        alt = np.array(eles, dtype=np.float64)
    elif any(e is not None for e in eles):
        first = next(pt[0] for pt in points if pt[3] is None)
        warnings.append(f"{p}: trkpt without <ele> at line {first}; elevations not used")
    o = time_order(t)
    if len(o) < len(t):
        warnings.append(f"{p}: {len(t) - len(o)} track points with a repeated time dropped")
    for w in warnings:
        log.warning("%s", w)
    return FlightLog(
        path=p,
        format="gpx",
        positions=PositionTrack(
            time_utc_s=t[o],
            lat_deg=np.array([pt[1] for pt in points])[o],
            lon_deg=np.array([pt[2] for pt in points])[o],
            alt_amsl_m=alt[o] if alt is not None else None,
            source="gpx",
        ),
        warnings=tuple(warnings),
    )
