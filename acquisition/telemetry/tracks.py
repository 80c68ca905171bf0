"""GPS tracks in CSV files -> :class:`~acquisition.telemetry.model.FlightLog` (positions, and
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

Autopilot GPS exports (:data:`CSV_LAYOUTS`): ArduPilot GPS messages as CSV (``mavlogdump.py
--format csv --types GPS``: TimeUS, Status, GMS, GWk, NSats, HDop, Lat, Lng, Alt...; time from
GWk and GMS), PX4 ``vehicle_gps_position`` or ``sensor_gps`` from ``ulog2csv`` (time_utc_usec,
lat/lon in 1e-7 degrees and alt in mm, or latitude_deg, longitude_deg, altitude_msl_m), and a
plain UTC time with lat, lon, alt. A CSV in none of these is refused with the columns looked
for and the ones found.

GPX tracks: :mod:`acquisition.telemetry.gpx`.

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

import numpy as np

from ..errors import TelemetryError
from ..mavlink_messages import DEG_PER_E7
from .gpstime import gps_week_ms_to_utc_s, time_order
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
    """Read a CSV track: exiftool's layout (see the module docstring) or an autopilot's GPS
    export (:data:`CSV_LAYOUTS`)."""
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
    if "gpslatitude" not in index and _layout_of(header) is not None:
        return read_autopilot_csv(p, text, header)
    has_datetime = "gpsdatetime" in index
    has_split = "gpsdatestamp" in index and "gpstimestamp" in index
    missing = [c for c in CSV_REQUIRED if c not in index]
    if missing or not (has_datetime or has_split):
        need = ["GPSDateTime (or GPSDateStamp and GPSTimeStamp)"] if not (has_datetime or has_split) else []
        need += [{"gpslatitude": "GPSLatitude", "gpslongitude": "GPSLongitude"}[c] for c in missing]
        raise TelemetryError(
            f"{p}, line {header_line}: the header lacks {', '.join(need)}; found "
            f"{', '.join(h.strip() for h in header) or 'nothing'} (exiftool's CSV track layout; "
            f"also read: {'; '.join(layout.describe for layout in CSV_LAYOUTS)})"
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


def parse_iso_time_s(text: str) -> float:
    """POSIX seconds of an ISO 8601 time (UTC when it gives no offset)."""
    t = text.strip()
    try:
        stamp = dt.datetime.fromisoformat(t.replace("z", "Z"))
    except ValueError:
        raise ValueError("expected an ISO 8601 time such as 2016-11-22T15:32:01Z") from None
    if stamp.tzinfo is None:
        stamp = stamp.replace(tzinfo=dt.UTC)
    return stamp.timestamp()


# ------------------------------------------------------------- autopilot GPS exports as CSV


@dataclass(frozen=True)
class CsvLayout:
    """A CSV layout of GPS fixes, by normalized column names (:func:`normalize_heading`)."""

    name: str
    time: tuple[str, ...]  # the columns that give the time, all required
    lat: str
    lon: str
    alt: str | None
    describe: str


#: The autopilot GPS exports read, first match wins (after exiftool's own layout).
CSV_LAYOUTS = (
    CsvLayout(
        "ardupilot_gps",
        ("gwk", "gms"),
        "lat",
        "lng",
        "alt",
        "ArduPilot GPS messages (mavlogdump.py --format csv --types GPS, Mission Planner): GWk and "
        "GMS (GPS week, ms of week), Lat, Lng (degrees), Alt (m AMSL)",
    ),
    CsvLayout(
        "px4_sensor_gps",
        ("timeutcusec",),
        "latitudedeg",
        "longitudedeg",
        "altitudemslm",
        "PX4 sensor_gps (ulog2csv, PX4 1.14+): time_utc_usec, latitude_deg, longitude_deg, altitude_msl_m",
    ),
    CsvLayout(
        "px4_vehicle_gps_position",
        ("timeutcusec",),
        "lat",
        "lon",
        "alt",
        "PX4 vehicle_gps_position (ulog2csv): time_utc_usec (UTC us), lat, lon (1e-7 deg), alt (mm AMSL)",
    ),
    CsvLayout(
        "utc",
        ("timeutc",),
        "lat",
        "lon",
        "alt",
        "a UTC time (time_utc, utc, datetime, time: ISO 8601 or POSIX seconds) with lat or latitude, "
        "lon, lng or longitude (degrees) and optionally alt or altitude (m AMSL)",
    ),
    CsvLayout(
        "gps_week",
        ("gpsweek", "gpsms"),
        "lat",
        "lon",
        "alt",
        "GPS time as gps_week and gps_ms (ms of week) with lat, lon, alt",
    ),
)

# Other spellings of the generic columns, normalized.
_ALIASES = {
    "latitude": "lat",
    "lng": "lon",
    "long": "lon",
    "longitude": "lon",
    "altitude": "alt",
    "altamsl": "alt",
    "altitudemsl": "alt",
    "utc": "timeutc",
    "utctime": "timeutc",
    "datetime": "timeutc",
    "time": "timeutc",
    "gpstow": "gpsms",
    "towms": "gpsms",
    "week": "gpsweek",
}

EXIFTOOL_LAYOUT = (
    "exiftool's CSV track: GPSDateTime (or GPSDateStamp and GPSTimeStamp), GPSLatitude, GPSLongitude"
)


def _layout_of(header: list[str]) -> tuple[CsvLayout, dict[str, int]] | None:
    """The first layout whose columns the header has, and each column's index."""
    names = [normalize_heading(h) for h in header]
    exact = {n: i for i, n in enumerate(names) if n}
    for layout in CSV_LAYOUTS:
        index = dict(exact)
        if layout.name in ("utc", "gps_week"):
            for i, n in enumerate(names):
                if n in _ALIASES and _ALIASES[n] not in index:
                    index[_ALIASES[n]] = i
        needed = (*layout.time, layout.lat, layout.lon)
        if all(c in index for c in needed):
            return layout, index
    return None


def csv_layout_message(path: str, header: list[str]) -> str:
    """What a CSV that is no track layout sfap reads is told: the columns looked for, and found."""
    found = ", ".join(h.strip() for h in header if h.strip()) or "nothing"
    looked = "; ".join([EXIFTOOL_LAYOUT] + [layout.describe for layout in CSV_LAYOUTS])
    return f"{path}: not a GPS track layout sfap reads. Columns found: {found}. Looked for: {looked}"


def is_csv_track(header: list[str]) -> bool:
    names = {normalize_heading(h) for h in header}
    exiftool = "gpslatitude" in names and bool(names & {"gpsdatetime", "gpsdatestamp"})
    return exiftool or _layout_of(header) is not None


def _utc_cell(text: str) -> float:
    """ISO 8601 / EXIF date-time (UTC unless a zone is given), or POSIX seconds."""
    value = text.strip()
    if re.fullmatch(r"[-+]?\d+(\.\d*)?", value):
        seconds = float(value)
        if not 946_684_800.0 <= seconds <= 4_102_444_800.0:  # 2000-01-01 .. 2100-01-01
            raise ValueError("not a POSIX time in seconds between 2000 and 2100")
        return seconds
    try:
        return parse_exif_datetime(value)
    except ValueError:
        return parse_iso_time_s(value)


def read_autopilot_csv(path: str, text: str, header: list[str]) -> FlightLog:
    """GPS fixes in one of :data:`CSV_LAYOUTS`. Rows without a fix (ArduPilot Status < 3, PX4
    time_utc_usec 0, a 0, 0 position) are skipped and counted."""
    found = _layout_of(header)
    if found is None:
        raise TelemetryError(csv_layout_message(path, header))
    layout, index = found
    rows = _csv_rows(text)
    next(rows)
    times: list[float] = []
    lats: list[float] = []
    lons: list[float] = []
    alts: list[float] = []
    has_alt = layout.alt is not None and layout.alt in index
    status_col = index.get("status") if layout.name == "ardupilot_gps" else None
    skipped = 0
    line = 1
    try:
        for line, row in rows:
            if not any(c.strip() for c in row):
                continue

            def cell(name: str, row: list[str] = row) -> str:
                i = index[name]
                return row[i].strip() if i < len(row) else ""

            column = layout.time[0]
            try:
                if status_col is not None and status_col < len(row) and float(row[status_col]) < 3:
                    skipped += 1
                    continue
                if layout.name == "ardupilot_gps":
                    t = float(gps_week_ms_to_utc_s(float(cell("gwk")), float(cell("gms"))))
                elif layout.name == "gps_week":
                    t = float(gps_week_ms_to_utc_s(float(cell("gpsweek")), float(cell("gpsms"))))
                elif layout.name.startswith("px4"):
                    usec = float(cell("timeutcusec"))
                    if usec <= 0:
                        skipped += 1
                        continue
                    t = usec / 1e6
                else:
                    t = _utc_cell(cell("timeutc"))
                column = layout.lat
                lat, lon = float(cell(layout.lat)), float(cell(layout.lon))
                if layout.name == "px4_vehicle_gps_position":
                    lat, lon = lat * DEG_PER_E7, lon * DEG_PER_E7
                if lat == 0.0 and lon == 0.0:
                    skipped += 1
                    continue
                if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                    raise ValueError(f"{lat}, {lon} is outside -90..90 / -180..180 degrees")
                if has_alt and layout.alt is not None:
                    column = layout.alt
                    alt = float(cell(layout.alt))
                    alts.append(alt * 1e-3 if layout.name == "px4_vehicle_gps_position" else alt)
            except ValueError as exc:
                raise TelemetryError(f"{path}, line {line}: {column}: {exc}") from None
            times.append(t)
            lats.append(lat)
            lons.append(lon)
    except csv.Error as exc:
        raise TelemetryError(f"{path}, line {line + 1}: {exc}") from exc
    if not times:
        raise TelemetryError(f"{path}: no GPS fix in the file ({skipped} rows without one)")
    warnings: list[str] = []
    if skipped:
        warnings.append(f"{path}: {skipped} rows without a GPS fix skipped")
    t_arr = np.array(times, dtype=np.float64)
    o = time_order(t_arr)
    if len(o) < len(t_arr):
        warnings.append(f"{path}: {len(t_arr) - len(o)} rows with a repeated time dropped")
    for w in warnings:
        log.warning("%s", w)
    positions = PositionTrack(
        time_utc_s=t_arr[o],
        lat_deg=np.array(lats)[o],
        lon_deg=np.array(lons)[o],
        alt_amsl_m=np.array(alts)[o] if has_alt else None,
        source=f"csv:{layout.name}",
    )
    return FlightLog(path=path, format="csv", positions=positions, warnings=tuple(warnings))
