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
import io
import logging
import os
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..errors import TelemetryError
from ..mavlink_units import DEG_PER_E7
from .csv_cells import (
    altitude_m,
    decimal_column,
    exif_datetime_column,
    first_number,
    has_hemisphere_or_sign,
    parse_angle_deg,
    parse_exif_datetime,
    utc_cell,
)
from .gpstime import gps_week_ms_to_utc_s, time_order
from .model import AttitudeTrack, FlightLog, PositionTrack

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]

CSV_REQUIRED = ("gpslatitude", "gpslongitude")


def normalize_heading(heading: str) -> str:
    """``GPS:GPSLatitude``, ``GPS Latitude``, ``gps_latitude`` -> ``gpslatitude``; a unit in
    parentheses is dropped (``GPS Speed (km/h)`` -> ``gpsspeed``)."""
    h = heading.strip().lstrip("\ufeff")
    h = h.rsplit(":", 1)[-1]
    h = re.sub(r"\(.*?\)", "", h)
    return re.sub(r"[\s/_\-]", "", h).lower()


def _csv_rows(text: str) -> Iterator[tuple[int, list[str]]]:
    reader = csv.reader(io.StringIO(text))
    for row in reader:
        yield reader.line_num, row


@dataclass(frozen=True)
class _ExiftoolHeader:
    """The columns of an exiftool CSV track: normalized name -> index, and the optional ones
    present (key -> normalized name)."""

    path: str
    header: list[str]
    index: dict[str, int]
    optional: dict[str, str]

    def title(self, key: str) -> str:
        """The heading of an optional column as the file spells it."""
        return self.header[self.index[self.optional[key]]].strip()


@dataclass
class _Column:
    """Values of one optional column, with the first line where a cell was empty."""

    values: list[float] = field(default_factory=list)
    first_empty_line: int | None = None


@dataclass
class _Rows:
    """The parsed rows of an exiftool CSV track, in file order."""

    time_utc_s: F64
    lat_deg: F64
    lon_deg: F64
    optional: dict[str, F64]  # the optional columns with a value in every row
    first_empty_line: dict[str, int]  # the optional columns with an empty cell: its first line


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
    layout = _exiftool_header(p, header, header_line)
    parsed = _parse_by_column(layout, text) or _parse_by_row(layout, text)
    if not len(parsed.time_utc_s):
        raise TelemetryError(f"{p}: no track point after the header")
    warnings = [
        f"{p}: column {layout.title(key)} is empty at line {line} (and maybe others); the column is not used"
        for key, line in parsed.first_empty_line.items()
    ]
    kept = parsed.optional
    t = parsed.time_utc_s
    o = time_order(t)
    if len(o) < len(t):
        warnings.append(f"{p}: {len(t) - len(o)} rows with a repeated time dropped")
    positions = PositionTrack(
        time_utc_s=t[o],
        lat_deg=parsed.lat_deg[o],
        lon_deg=parsed.lon_deg[o],
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


def _exiftool_header(path: str, header: list[str], header_line: int = 1) -> _ExiftoolHeader:
    """The columns of exiftool's CSV track layout in ``header``; TelemetryError naming what
    the header lacks."""
    index = {n: i for i, n in enumerate(normalize_heading(h) for h in header) if n}
    has_datetime = "gpsdatetime" in index
    has_split = "gpsdatestamp" in index and "gpstimestamp" in index
    missing = [c for c in CSV_REQUIRED if c not in index]
    if missing or not (has_datetime or has_split):
        need = ["GPSDateTime (or GPSDateStamp and GPSTimeStamp)"] if not (has_datetime or has_split) else []
        need += [{"gpslatitude": "GPSLatitude", "gpslongitude": "GPSLongitude"}[c] for c in missing]
        raise TelemetryError(
            f"{path}, line {header_line}: the header lacks {', '.join(need)}; found "
            f"{', '.join(h.strip() for h in header) or 'nothing'} (exiftool's CSV track layout; "
            f"also read: {'; '.join(layout.describe for layout in CSV_LAYOUTS)})"
        )
    optional = {
        "alt": "gpsaltitude",
        "yaw": "gpsimgdirection",
        "pitch": "gpspitch" if "gpspitch" in index else "cameraelevationangle",
        "roll": "gpsroll",
    }
    return _ExiftoolHeader(path, header, index, {k: name for k, name in optional.items() if name in index})


def _data_rows(text: str) -> list[list[str]] | None:
    """The rows after the header that are not blank, or None when the text is not CSV."""
    reader = csv.reader(io.StringIO(text))
    try:
        next(reader)  # the header
        return [row for row in reader if "".join(row).strip()]
    except csv.Error:
        return None


def _cells(rows: list[list[str]], i: int) -> list[str]:
    """Column ``i`` of the rows, stripped ("" where a row is shorter)."""
    if all(len(row) > i for row in rows):
        return [row[i].strip() for row in rows]
    return [row[i].strip() if i < len(row) else "" for row in rows]


def _per_cell(parse: Callable[[str], float], cells: Sequence[str]) -> F64:
    return np.array([parse(c) for c in cells], dtype=np.float64)


def _angle_column(cells: list[str], refs: list[str] | None, positive: str, negative: str) -> F64:
    """A latitude or longitude column (with its Ref column, when the file has one)."""
    values = decimal_column(cells)
    fast = values is not None
    if values is None:
        values = _per_cell(lambda c: parse_angle_deg(c, positive=positive, negative=negative), cells)
    if refs is not None:
        # A plain decimal cell has no letter: only a sign says its side.
        signed = (lambda c: c.startswith(("-", "+"))) if fast else has_hemisphere_or_sign
        flip = [i for i, ref in enumerate(refs) if ref.upper().startswith(negative) and not signed(cells[i])]
        values[flip] = -values[flip]
    return values


def _parse_by_column(layout: _ExiftoolHeader, text: str) -> _Rows | None:
    """The track parsed a column at a time: the fast form where a whole column is in it
    (:mod:`.csv_cells`), else cell by cell with the same parsers :func:`_parse_by_row` uses,
    so the values are the same. None when a row is not a CSV row, a cell does not parse or a
    position is out of range: :func:`_parse_by_row` then says which and where, as it always has."""
    kept = _data_rows(text)
    if kept is None:
        return None
    index = layout.index

    def cells(name: str) -> list[str]:
        return _cells(kept, index[name])

    try:
        if "gpsdatetime" in index:
            stamps = cells("gpsdatetime")
        else:
            stamps = [f"{d} {t}" for d, t in zip(cells("gpsdatestamp"), cells("gpstimestamp"), strict=True)]
        time_utc_s = exif_datetime_column(stamps)
        if time_utc_s is None:
            time_utc_s = _per_cell(parse_exif_datetime, stamps)
        lat = _angle_column(
            cells("gpslatitude"), cells("gpslatituderef") if "gpslatituderef" in index else None, "N", "S"
        )
        lon = _angle_column(
            cells("gpslongitude"), cells("gpslongituderef") if "gpslongituderef" in index else None, "E", "W"
        )
        if not (np.all((lat >= -90) & (lat <= 90)) and np.all((lon >= -180) & (lon <= 180))):
            return None
        optional: dict[str, F64] = {}
        first_empty_line: dict[str, int] = {}
        for key, name in layout.optional.items():
            column = cells(name)
            parse = altitude_m if key == "alt" else first_number
            empty = [i for i, c in enumerate(column) if not c]
            if empty:
                _per_cell(parse, [c for c in column if c])  # a bad cell is still an error
                first_empty_line[key] = _row_lines(text)[empty[0]]
                continue
            values = decimal_column(column)
            optional[key] = _per_cell(parse, column) if values is None else values
    except ValueError:
        return None
    return _Rows(time_utc_s, lat, lon, optional, first_empty_line)


def _row_lines(text: str) -> list[int]:
    """The line of each row after the header that is not blank (a quoted cell may span lines)."""
    return [line for line, row in _csv_rows(text) if "".join(row).strip()][1:]


def _parse_by_row(layout: _ExiftoolHeader, text: str) -> _Rows:
    """The track parsed row by row, each cell with its parser: the reference for
    :func:`_parse_by_column`, and what names the first bad row (line, column, value) in a
    TelemetryError."""
    p, header, index, optional = layout.path, layout.header, layout.index, layout.optional
    rows = _csv_rows(text)
    header_line, _ = next(rows)
    has_datetime = "gpsdatetime" in index
    columns = {k: _Column() for k in optional}
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
                    and not has_hemisphere_or_sign(value)
                    and cell(row, "gpslatituderef").upper().startswith("S")
                ):
                    lat = -lat
                what, value = "GPSLongitude", cell(row, "gpslongitude")
                lon = parse_angle_deg(value, positive="E", negative="W")
                if (
                    "gpslongituderef" in index
                    and not has_hemisphere_or_sign(value)
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
                        col.values.append(altitude_m(value))
                    else:
                        col.values.append(first_number(value))
            except ValueError as exc:
                raise TelemetryError(f"{p}, line {line}: {what} {value!r}: {exc}") from None
    except csv.Error as exc:
        raise TelemetryError(f"{p}, line {line + 1}: {exc}") from exc
    return _Rows(
        np.array(times, dtype=np.float64),
        np.array(lats, dtype=np.float64),
        np.array(lons, dtype=np.float64),
        {k: np.array(c.values, dtype=np.float64) for k, c in columns.items() if c.first_empty_line is None},
        {k: c.first_empty_line for k, c in columns.items() if c.first_empty_line is not None},
    )


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


@dataclass
class _Fixes:
    """The GPS fixes of an autopilot CSV, in file order, and the rows without a fix."""

    time_utc_s: F64
    lat_deg: F64
    lon_deg: F64
    alt_amsl_m: F64 | None
    skipped: int


def read_autopilot_csv(path: str, text: str, header: list[str]) -> FlightLog:
    """GPS fixes in one of :data:`CSV_LAYOUTS`. Rows without a fix (ArduPilot Status < 3, PX4
    time_utc_usec 0, a 0, 0 position) are skipped and counted."""
    found = _layout_of(header)
    if found is None:
        raise TelemetryError(csv_layout_message(path, header))
    layout, index = found
    fixes = _fixes_by_column(layout, index, text) or _fixes_by_row(path, layout, index, text)
    if not len(fixes.time_utc_s):
        raise TelemetryError(f"{path}: no GPS fix in the file ({fixes.skipped} rows without one)")
    warnings: list[str] = []
    if fixes.skipped:
        warnings.append(f"{path}: {fixes.skipped} rows without a GPS fix skipped")
    t_arr = fixes.time_utc_s
    o = time_order(t_arr)
    if len(o) < len(t_arr):
        warnings.append(f"{path}: {len(t_arr) - len(o)} rows with a repeated time dropped")
    for w in warnings:
        log.warning("%s", w)
    positions = PositionTrack(
        time_utc_s=t_arr[o],
        lat_deg=fixes.lat_deg[o],
        lon_deg=fixes.lon_deg[o],
        alt_amsl_m=fixes.alt_amsl_m[o] if fixes.alt_amsl_m is not None else None,
        source=f"csv:{layout.name}",
    )
    return FlightLog(path=path, format="csv", positions=positions, warnings=tuple(warnings))


def _floats(cells: list[str]) -> F64:
    """float() of each cell (ValueError for a cell that is no number), as the row parse does."""
    return np.fromiter(map(float, cells), dtype=np.float64, count=len(cells))


def _utc_column(cells: list[str]) -> F64:
    """:func:`.csv_cells.utc_cell` of each cell: POSIX seconds or stamps a column at a time when
    the whole column is in one fast form, else cell by cell."""
    seconds = decimal_column(cells)
    if seconds is not None:
        # A decimal in range is one of utc_cell's POSIX seconds (".5", the one decimal form
        # utc_cell reads otherwise, is out of range and refused by both).
        if not np.all((seconds >= 946_684_800.0) & (seconds <= 4_102_444_800.0)):
            raise ValueError("not a POSIX time in seconds between 2000 and 2100")
        return seconds
    stamps = exif_datetime_column(cells)
    return _per_cell(utc_cell, cells) if stamps is None else stamps


def _fixes_by_column(layout: CsvLayout, index: dict[str, int], text: str) -> _Fixes | None:
    """The fixes parsed a column at a time, each column over the rows the row parse reads it
    in (the time of the rows with a fix status, the position of the rows with a time, the
    altitude of the rows with a position), with the same float() and the same arithmetic. None
    when a row is not a CSV row, a cell does not parse or a position is out of range:
    :func:`_fixes_by_row` then says which and where."""
    data = _data_rows(text)
    if data is None:
        return None
    rows: list[list[str]] = data
    skipped = 0

    def keep(mask: NDArray[np.bool_]) -> None:
        nonlocal rows, skipped
        skipped += int(np.count_nonzero(~mask))
        rows = [row for row, k in zip(rows, mask.tolist(), strict=True) if k]

    try:
        if layout.name == "ardupilot_gps" and "status" in index:
            i = index["status"]
            status = [row[i] if i < len(row) else "3" for row in rows]  # a short row has a fix
            keep(~(_floats(status) < 3))
        if layout.name in ("ardupilot_gps", "gps_week"):
            week, ms = ("gwk", "gms") if layout.name == "ardupilot_gps" else ("gpsweek", "gpsms")
            t = gps_week_ms_to_utc_s(_floats(_cells(rows, index[week])), _floats(_cells(rows, index[ms])))
        elif layout.name.startswith("px4"):
            usec = _floats(_cells(rows, index["timeutcusec"]))
            has_time = ~(usec <= 0)
            keep(has_time)
            t = usec[has_time] / 1e6
        else:
            t = _utc_column(_cells(rows, index["timeutc"]))
        lat, lon = _floats(_cells(rows, index[layout.lat])), _floats(_cells(rows, index[layout.lon]))
        if layout.name == "px4_vehicle_gps_position":
            lat, lon = lat * DEG_PER_E7, lon * DEG_PER_E7
        has_position = ~((lat == 0.0) & (lon == 0.0))
        keep(has_position)
        t, lat, lon = t[has_position], lat[has_position], lon[has_position]
        if not (np.all((lat >= -90.0) & (lat <= 90.0)) and np.all((lon >= -180.0) & (lon <= 180.0))):
            return None
        alt = None
        if layout.alt is not None and layout.alt in index:
            alt = _floats(_cells(rows, index[layout.alt]))
            if layout.name == "px4_vehicle_gps_position":
                alt = alt * 1e-3
    except ValueError:
        return None
    return _Fixes(t, lat, lon, alt, skipped)


def _fixes_by_row(path: str, layout: CsvLayout, index: dict[str, int], text: str) -> _Fixes:
    """The fixes parsed row by row: the reference for :func:`_fixes_by_column`, and what names
    the first bad row (line, column, value) in a TelemetryError."""
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
                    t = utc_cell(cell("timeutc"))
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
    return _Fixes(
        np.array(times, dtype=np.float64),
        np.array(lats, dtype=np.float64),
        np.array(lons, dtype=np.float64),
        np.array(alts, dtype=np.float64) if has_alt else None,
        skipped,
    )
