"""Rows and cells of CSV tracks: the parser of each kind of cell, and the same parse of a whole
column at once.

Rows: :func:`csv_rows` (with their line numbers), :func:`data_rows` (the non-blank rows after
the header), :func:`column_cells`; headings compare by :func:`normalize_heading`.

Cell parsers (every form a track may hold; each raises ValueError saying what it expected):
:func:`parse_exif_datetime` (``2016:11:22 15:32:01.25Z``, ``2016-11-22T15:32:01+01:00``),
:func:`parse_iso_time_s`, :func:`parse_angle_deg` (decimal or degrees minutes seconds, with
hemisphere letters), :func:`altitude_m` (``290.5 m Above Sea Level``), :func:`first_number`
and :func:`utc_cell` (a stamp or POSIX seconds).

Column parsers: :func:`decimal_column` and :func:`exif_datetime_column` read the forms nearly
every track is written in (plain decimal numbers; one ``YYYY:MM:DD HH:MM:SS[.fff][Z|+hh:mm]``
stamp layout, ISO's ``-`` and ``T`` included) for a whole column in a few C-level passes, five
to twenty times faster than cell by cell. They return exactly (bit for bit) what the cell parser
gives each cell, or None when any cell of the column is in another form: the caller then parses
that column cell by cell, so every form still reads, and every error is still the cell parser's.
"""

from __future__ import annotations

import csv
import datetime as dt
import io
import re
from collections.abc import Callable, Iterator, Sequence
from operator import itemgetter

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

_NUMBER = re.compile(r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?")
_EXIF_DATETIME = re.compile(
    r"^\s*(\d{4})[:\-](\d{2})[:\-](\d{2})[ T](\d{2}):(\d{2}):(\d{2}(?:\.\d+)?)"
    r"\s*(Z|[+-]\d{2}:?\d{2})?\s*$"
)
_POSIX_SECONDS = re.compile(r"[-+]?\d+(\.\d*)?")
_HEMISPHERE = re.compile(r"(?<![A-Za-z])[NSEWnsew](?![A-Za-z])")

# The fast forms of a column, its cells joined one per line: ASCII digits only, no inner space,
# no exponent (a cell outside them is read by its cell parser). Each is a subset of what the cell
# parser accepts, and float() of it is what the cell parser computes.
_DECIMAL_CELLS = re.compile(r"(?:[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)\n)*")
_DECIMAL_CHARACTERS = b"0123456789+-.\n"  # what the joined cells of _DECIMAL_CELLS are made of
# The date and HH:MM are characters 0-15, the seconds and zone from 17 on.
_STAMP_CELLS = re.compile(
    r"(?:[0-9]{4}[:-][0-9]{2}[:-][0-9]{2}[ T][0-9]{2}:[0-9]{2}:[0-9]{2}(?:\.[0-9]+)?"
    r"(?:Z|[+-][0-9]{2}:?[0-9]{2})?\n)*"
)
# The seconds and the zone (maybe empty) of each line of the stamps' tails.
_SECONDS_ZONE = re.compile(r"([0-9.]+)([^\n]*)\n")


def _zone_seconds(zone: str | None) -> int:
    if not zone or zone == "Z":
        return 0
    sign = -1 if zone[0] == "-" else 1
    digits = zone[1:].replace(":", "")
    return sign * (int(digits[:2]) * 3600 + int(digits[2:4]) * 60)


def _utc_minute_s(y: int, mo: int, d: int, h: int, mi: int) -> float:
    """POSIX seconds of a UTC date and minute (raises ValueError for a date or time that is none)."""
    return dt.datetime(y, mo, d, h, mi, tzinfo=dt.UTC).timestamp()


def parse_exif_datetime(text: str) -> float:
    """UTC POSIX seconds of an EXIF/ISO date-time (``2016:11:22 15:32:01.25Z``); UTC when no
    zone is given. Raises ValueError."""
    m = _EXIF_DATETIME.match(text)
    if not m:
        raise ValueError("expected YYYY:MM:DD HH:MM:SS[.ss][Z|+HH:MM]")
    y, mo, d, h, mi = (int(m.group(i)) for i in range(1, 6))
    return _utc_minute_s(y, mo, d, h, mi) + float(m.group(6)) - _zone_seconds(m.group(7))


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


def has_hemisphere_or_sign(text: str) -> bool:
    """True when a coordinate says its own side (a sign or a hemisphere letter), so that a
    GPSLatitudeRef / GPSLongitudeRef column does not apply to it."""
    t = text.strip()
    return t.startswith(("-", "+")) or bool(_HEMISPHERE.search(t))


def altitude_m(text: str) -> float:
    """Metres of an ExifTool altitude: ``312.5``, ``312.5 m Above Sea Level``, ``12 m Below Sea
    Level`` (negative)."""
    numbers = _NUMBER.findall(text)
    if len(numbers) != 1:
        raise ValueError("expected metres, e.g. 312.5 or '312.5 m Above Sea Level'")
    value = float(numbers[0])
    return -abs(value) if "below" in text.lower() else value


def first_number(text: str) -> float:
    """The first number in a cell (``12.5 deg`` -> 12.5), or float() of the whole cell."""
    found = _NUMBER.search(text)
    return float(found.group()) if found else float(text)


def utc_cell(text: str) -> float:
    """ISO 8601 / EXIF date-time (UTC unless a zone is given), or POSIX seconds."""
    value = text.strip()
    if _POSIX_SECONDS.fullmatch(value):
        seconds = float(value)
        if not 946_684_800.0 <= seconds <= 4_102_444_800.0:  # 2000-01-01 .. 2100-01-01
            raise ValueError("not a POSIX time in seconds between 2000 and 2100")
        return seconds
    try:
        return parse_exif_datetime(value)
    except ValueError:
        return parse_iso_time_s(value)


def _all_in(cells: Sequence[str], form: re.Pattern[str]) -> str | None:
    """The cells joined one per line when every cell is in ``form``, else None (a cell holding a
    line break would make more lines than cells: the count catches it)."""
    joined = "\n".join(cells) + "\n" if cells else ""
    if joined.count("\n") != len(cells) or not form.fullmatch(joined):
        return None
    return joined


def _minute_s(minute: str) -> float:
    """POSIX seconds of ``YYYY:MM:DD HH:MM`` in UTC (ValueError when it is no date and time)."""
    return _utc_minute_s(*(int(minute[i:j]) for i, j in ((0, 4), (5, 7), (8, 10), (11, 13), (14, 16))))


def decimal_column(cells: Sequence[str]) -> F64 | None:
    """Cells that are all plain decimal numbers (``-93.124``, ``+.5``, ``290``: no exponent,
    unit, letter or space) as float64, else None. Each value is float() of its cell, which is
    what :func:`parse_angle_deg`, :func:`altitude_m` and :func:`first_number` give such a cell.

    The form is checked by the characters alone (ASCII digits, signs, points; one cell a line),
    then float() of each: on those characters float() accepts exactly the plain decimals
    (``[-+]?(\\d+(\\.\\d*)?|\\.\\d+)``) and refuses the rest (``1.2.3``, ``+-1``, ``.``), which
    are left to the cell parser; a fifth of the time of matching the form's expression."""
    joined = "\n".join(cells) + "\n" if cells else ""
    if joined.count("\n") != len(cells) or not joined.isascii():
        return None
    if joined.encode("ascii").translate(None, _DECIMAL_CHARACTERS):
        return None  # a character no plain decimal holds
    try:
        return np.fromiter(map(float, cells), dtype=np.float64, count=len(cells))
    except ValueError:
        return None


def exif_datetime_column(cells: Sequence[str]) -> F64 | None:
    """Cells that are all ``YYYY:MM:DD HH:MM:SS[.f]`` stamps (``-`` for ``:`` in the date and
    ``T`` for the space allowed; then nothing, ``Z``, ``+hh:mm`` or ``+hhmm``) as UTC POSIX
    seconds, else None (also when a date or time is not a real one: the cell parser then names
    it). Each value is :func:`parse_exif_datetime` of its cell, bit for bit: the same minute
    (from :mod:`datetime`, once per distinct minute), plus the same float() of the seconds,
    minus the same zone offset, in the same order of float operations."""
    joined = _all_in(cells, _STAMP_CELLS)
    if joined is None:
        return None
    if not cells:
        return np.empty(0, dtype=np.float64)
    minutes = [c[:16] for c in cells]  # date and HH:MM
    seconds: Sequence[str]
    zones: Sequence[str]
    if joined.count("Z") == len(cells):  # each ends with Z (exiftool's own form)
        seconds, zones = [c[17:-1] for c in cells], ("Z",)
    else:
        seconds, zones = zip(*_SECONDS_ZONE.findall("\n".join(c[17:] for c in cells) + "\n"), strict=True)
    try:
        minute_s = {minute: _minute_s(minute) for minute in set(minutes)}
    except ValueError:
        return None
    zone_s = {zone: float(_zone_seconds(zone)) for zone in set(zones)}
    n = len(cells)
    start_s = np.fromiter(map(minute_s.__getitem__, minutes), dtype=np.float64, count=n)
    second_s = np.fromiter(map(float, seconds), dtype=np.float64, count=n)
    if len(zone_s) == 1:  # one zone (or none) in the whole column
        return (start_s + second_s) - zone_s[zones[0]]
    return (start_s + second_s) - np.fromiter(map(zone_s.__getitem__, zones), dtype=np.float64, count=n)


def normalize_heading(heading: str) -> str:
    """``GPS:GPSLatitude``, ``GPS Latitude``, ``gps_latitude`` -> ``gpslatitude``; a unit in
    parentheses is dropped (``GPS Speed (km/h)`` -> ``gpsspeed``)."""
    h = heading.strip().lstrip("\ufeff")
    h = h.rsplit(":", 1)[-1]
    h = re.sub(r"\(.*?\)", "", h)
    return re.sub(r"[\s/_\-]", "", h).lower()


def csv_rows(text: str) -> Iterator[tuple[int, list[str]]]:
    """(line number where the row ends, cells) of each row, the header included."""
    reader = csv.reader(io.StringIO(text))
    for row in reader:
        yield reader.line_num, row


def data_rows(text: str) -> list[list[str]] | None:
    """The rows after the header that are not blank, or None when the text is not CSV.

    Text without quotes, carriage returns or NUL bytes, and no line longer than the csv module's
    field limit, is what the csv module splits at each line feed and comma and nowhere else: it
    is split so, in a third of the reader's time."""
    if '"' not in text and "\r" not in text and "\x00" not in text:
        lines = text.split("\n")
        if max(map(len, lines)) <= csv.field_size_limit():
            return [row for row in map(_split_commas, lines[1:]) if "".join(row).strip()]
    reader = csv.reader(io.StringIO(text))
    try:
        next(reader)  # the header
        return [row for row in reader if "".join(row).strip()]
    except csv.Error:
        return None


def _split_commas(line: str) -> list[str]:
    return line.split(",")


def column_cells(rows: list[list[str]], i: int) -> list[str]:
    """Column ``i`` of the rows, stripped ("" where a row is shorter)."""
    if not rows or min(map(len, rows)) > i:
        return list(map(str.strip, map(itemgetter(i), rows)))
    return [row[i].strip() if i < len(row) else "" for row in rows]


def per_cell(parse: Callable[[str], float], cells: Sequence[str]) -> F64:
    """``parse`` of each cell, as float64 (its ValueError passes through)."""
    return np.array([parse(c) for c in cells], dtype=np.float64)
