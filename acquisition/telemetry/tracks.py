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

Autopilot GPS exports (ArduPilot, PX4, a plain UTC time or GPS week with lat, lon, alt):
:mod:`acquisition.telemetry.autopilot_csv`. A CSV in none of the layouts is refused with the
columns looked for and the ones found.

A track is parsed a column at a time (:func:`_parse_by_column`, with the fast column forms of
:mod:`acquisition.telemetry.csv_cells`); a track with a bad cell is parsed again row by row
(:func:`_parse_by_row`), which names the line, column and value.

GPX tracks: :mod:`acquisition.telemetry.gpx`.

Errors name the file and line, the bad value and what was expected.
"""

from __future__ import annotations

import csv
import logging
import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import TelemetryError
from .autopilot_csv import CSV_LAYOUTS, layout_of, read_autopilot_csv
from .csv_cells import (
    F64,
    altitude_m,
    column_cells,
    csv_rows,
    data_rows,
    decimal_column,
    exif_datetime_column,
    first_number,
    has_hemisphere_or_sign,
    normalize_heading,
    parse_angle_deg,
    parse_exif_datetime,
    per_cell,
)
from .gpstime import time_order
from .model import AttitudeTrack, FlightLog, PositionTrack

log = logging.getLogger(__name__)

CSV_REQUIRED = ("gpslatitude", "gpslongitude")


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
    rows = csv_rows(text)
    try:
        header_line, header = next(rows)
    except StopIteration:
        raise TelemetryError(f"{p}: empty file; expected a CSV header row") from None
    except csv.Error as exc:
        raise TelemetryError(f"{p}, line 1: {exc}") from exc
    names = [normalize_heading(h) for h in header]
    index = {n: i for i, n in enumerate(names) if n}
    autopilot = layout_of(header)
    if "gpslatitude" not in index and autopilot is not None:
        return read_autopilot_csv(p, text, *autopilot)
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


def _angle_column(cells: list[str], refs: list[str] | None, positive: str, negative: str) -> F64:
    """A latitude or longitude column (with its Ref column, when the file has one)."""
    values = decimal_column(cells)
    fast = values is not None
    if values is None:
        values = per_cell(lambda c: parse_angle_deg(c, positive=positive, negative=negative), cells)
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
    kept = data_rows(text)
    if kept is None:
        return None
    index = layout.index

    def cells(name: str) -> list[str]:
        return column_cells(kept, index[name])

    try:
        if "gpsdatetime" in index:
            stamps = cells("gpsdatetime")
        else:
            stamps = [f"{d} {t}" for d, t in zip(cells("gpsdatestamp"), cells("gpstimestamp"), strict=True)]
        time_utc_s = exif_datetime_column(stamps)
        if time_utc_s is None:
            time_utc_s = per_cell(parse_exif_datetime, stamps)
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
                per_cell(parse, [c for c in column if c])  # a bad cell is still an error
                first_empty_line[key] = _row_lines(text)[empty[0]]
                continue
            values = decimal_column(column)
            optional[key] = per_cell(parse, column) if values is None else values
    except ValueError:
        return None
    return _Rows(time_utc_s, lat, lon, optional, first_empty_line)


def _row_lines(text: str) -> list[int]:
    """The line of each row after the header that is not blank (a quoted cell may span lines)."""
    return [line for line, row in csv_rows(text) if "".join(row).strip()][1:]


def _parse_by_row(layout: _ExiftoolHeader, text: str) -> _Rows:
    """The track parsed row by row, each cell with its parser: the reference for
    :func:`_parse_by_column`, and what names the first bad row (line, column, value) in a
    TelemetryError."""
    p, header, index, optional = layout.path, layout.header, layout.index, layout.optional
    rows = csv_rows(text)
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


EXIFTOOL_LAYOUT = (
    "exiftool's CSV track: GPSDateTime (or GPSDateStamp and GPSTimeStamp), GPSLatitude, GPSLongitude"
)


def csv_layout_message(path: str, header: list[str]) -> str:
    """What a CSV that is no track layout sfap reads is told: the columns looked for, and found."""
    found = ", ".join(h.strip() for h in header if h.strip()) or "nothing"
    looked = "; ".join([EXIFTOOL_LAYOUT] + [layout.describe for layout in CSV_LAYOUTS])
    return f"{path}: not a GPS track layout sfap reads. Columns found: {found}. Looked for: {looked}"


def is_csv_track(header: list[str]) -> bool:
    names = {normalize_heading(h) for h in header}
    exiftool = "gpslatitude" in names and bool(names & {"gpsdatetime", "gpsdatestamp"})
    return exiftool or layout_of(header) is not None
