"""Autopilot GPS exports as CSV -> :class:`~acquisition.telemetry.model.FlightLog` positions.

The layouts (:data:`CSV_LAYOUTS`): ArduPilot GPS messages as CSV (``mavlogdump.py --format csv
--types GPS``: TimeUS, Status, GMS, GWk, NSats, HDop, Lat, Lng, Alt...; time from GWk and GMS),
PX4 ``vehicle_gps_position`` or ``sensor_gps`` from ``ulog2csv`` (time_utc_usec, lat/lon in 1e-7
degrees and alt in mm, or latitude_deg, longitude_deg, altitude_msl_m), a plain UTC time with
lat, lon, alt, and GPS week and ms. :mod:`acquisition.telemetry.tracks` reads exiftool's own
layout and sends these here.

A file is parsed a column at a time (:func:`_fixes_by_column`); a file with a bad cell is parsed
again row by row (:func:`_fixes_by_row`), which names the line, column and value.
"""

from __future__ import annotations

import csv
import logging
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..errors import TelemetryError
from ..mavlink_units import DEG_PER_E7
from .csv_cells import (
    F64,
    column_cells,
    csv_rows,
    data_rows,
    decimal_column,
    exif_datetime_column,
    normalize_heading,
    per_cell,
    utc_cell,
)
from .gpstime import gps_week_ms_to_utc_s, time_order
from .model import FlightLog, PositionTrack

log = logging.getLogger(__name__)


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
        "px4_gps_utc_usec",
        ("utcusec",),
        "lat",
        "lon",
        "alt",
        "PX4's GPS export as CSV: utc_usec (UTC microseconds), lat, lon (degrees, or 1e-7 degrees when "
        "out of the degrees' range) and alt_msl or alt (m AMSL)",
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
    "altmsl": "alt",
    "altitudemslm": "alt",
    "altmslm": "alt",
    "utc": "timeutc",
    "utctime": "timeutc",
    "datetime": "timeutc",
    "time": "timeutc",
    "gpstow": "gpsms",
    "towms": "gpsms",
    "week": "gpsweek",
}


def layout_of(header: list[str]) -> tuple[CsvLayout, dict[str, int]] | None:
    """The first layout whose columns the header has, and each column's index."""
    names = [normalize_heading(h) for h in header]
    exact = {n: i for i, n in enumerate(names) if n}
    for layout in CSV_LAYOUTS:
        index = dict(exact)
        if layout.name in ("utc", "gps_week", "px4_gps_utc_usec"):
            for i, n in enumerate(names):
                if n in _ALIASES and _ALIASES[n] not in index:
                    index[_ALIASES[n]] = i
        needed = (*layout.time, layout.lat, layout.lon)
        if all(c in index for c in needed):
            return layout, index
    return None


@dataclass
class _Fixes:
    """The GPS fixes of an autopilot CSV, in file order, and the rows without a fix."""

    time_utc_s: F64
    lat_deg: F64
    lon_deg: F64
    alt_amsl_m: F64 | None
    skipped: int


def read_autopilot_csv(path: str, text: str, layout: CsvLayout, index: dict[str, int]) -> FlightLog:
    """GPS fixes in ``layout`` (with ``index``, as :func:`layout_of` finds them in the header).
    Rows without a fix (ArduPilot Status < 3, PX4 time_utc_usec 0, a 0, 0 position) are
    skipped and counted."""
    fixes = _fixes_by_column(layout, index, text) or _fixes_by_row(path, layout, index, text)
    if not len(fixes.time_utc_s):
        raise TelemetryError(f"{path}: no GPS fix in the file ({fixes.skipped} rows without one)")
    warnings: list[str] = []
    used = {index[c] for c in (*layout.time, layout.lat, layout.lon) if c in index}
    if layout.alt is not None and layout.alt in index:
        used.add(index[layout.alt])
    header = next(csv_rows(text))[1]
    unread = [
        h.strip()
        for i, h in enumerate(header)
        if i not in used and "alt" in normalize_heading(h) and not normalize_heading(h).startswith("salt")
    ]
    if fixes.alt_amsl_m is None and unread:
        warnings.append(
            f"{path}: altitude column(s) {', '.join(unread)} not read as the altitude above mean sea level "
            f"(this layout, {layout.name}, reads {layout.alt or 'none'}): frames get no altitude from this "
            "track; name the column alt_msl"
        )
    elif unread:
        log.info("%s: column(s) %s not read (altitude from %s)", path, ", ".join(unread), layout.alt)
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
    return per_cell(utc_cell, cells) if stamps is None else stamps


def _fixes_by_column(layout: CsvLayout, index: dict[str, int], text: str) -> _Fixes | None:
    """The fixes parsed a column at a time, each column over the rows the row parse reads it
    in (the time of the rows with a fix status, the position of the rows with a time, the
    altitude of the rows with a position), with the same float() and the same arithmetic. None
    when a row is not a CSV row, a cell does not parse or a position is out of range:
    :func:`_fixes_by_row` then says which and where."""
    data = data_rows(text)
    if data is None:
        return None
    rows: list[list[str]] = data
    skipped = 0

    def keep(mask: NDArray[np.bool_]) -> None:
        nonlocal rows, skipped
        skipped += int(np.count_nonzero(~mask))
        rows = [row for row, k in zip(rows, mask.tolist(), strict=True) if k]

    def column(name: str) -> F64:
        return _floats(column_cells(rows, index[name]))

    try:
        if layout.name == "ardupilot_gps" and "status" in index:
            i = index["status"]
            status = [row[i] if i < len(row) else "3" for row in rows]  # a short row has a fix
            keep(~(_floats(status) < 3))
        if layout.name in ("ardupilot_gps", "gps_week"):
            week, ms = ("gwk", "gms") if layout.name == "ardupilot_gps" else ("gpsweek", "gpsms")
            t = gps_week_ms_to_utc_s(
                _floats(column_cells(rows, index[week])), _floats(column_cells(rows, index[ms]))
            )
        elif layout.name.startswith("px4"):
            usec = column(layout.time[0])
            has_time = ~(usec <= 0)
            keep(has_time)
            t = usec[has_time] / 1e6
        else:
            t = _utc_column(column_cells(rows, index["timeutc"]))
        lat, lon = (
            _floats(column_cells(rows, index[layout.lat])),
            _floats(column_cells(rows, index[layout.lon])),
        )
        if layout.name == "px4_vehicle_gps_position":
            lat, lon = lat * DEG_PER_E7, lon * DEG_PER_E7
        elif layout.name == "px4_gps_utc_usec":
            e7 = (np.abs(lat) > 90.0) | (np.abs(lon) > 180.0)
            lat, lon = np.where(e7, lat * DEG_PER_E7, lat), np.where(e7, lon * DEG_PER_E7, lon)
        has_position = ~((lat == 0.0) & (lon == 0.0))
        keep(has_position)
        t, lat, lon = t[has_position], lat[has_position], lon[has_position]
        if not (np.all((lat >= -90.0) & (lat <= 90.0)) and np.all((lon >= -180.0) & (lon <= 180.0))):
            return None
        alt = None
        if layout.alt is not None and layout.alt in index:
            alt = column(layout.alt)
            if layout.name == "px4_vehicle_gps_position":
                alt = alt * 1e-3
    except ValueError:
        return None
    return _Fixes(t, lat, lon, alt, skipped)


def _fixes_by_row(path: str, layout: CsvLayout, index: dict[str, int], text: str) -> _Fixes:
    """The fixes parsed row by row: the reference for :func:`_fixes_by_column`, and what names
    the first bad row (line, column, value) in a TelemetryError."""
    rows = csv_rows(text)
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
                    usec = float(cell(layout.time[0]))
                    if usec <= 0:
                        skipped += 1
                        continue
                    t = usec / 1e6
                else:
                    t = utc_cell(cell("timeutc"))
                column = layout.lat
                lat, lon = float(cell(layout.lat)), float(cell(layout.lon))
                if layout.name == "px4_vehicle_gps_position" or (
                    layout.name == "px4_gps_utc_usec" and (abs(lat) > 90.0 or abs(lon) > 180.0)
                ):
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
    t_s, lat_deg, lon_deg = (np.array(values, dtype=np.float64) for values in (times, lats, lons))
    return _Fixes(t_s, lat_deg, lon_deg, np.array(alts, dtype=np.float64) if has_alt else None, skipped)
