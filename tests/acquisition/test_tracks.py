"""CSV tracks read a column at a time (acquisition.telemetry.csv_cells and .tracks): every value
bit for bit what the cell parsers give cell by cell, every bad file refused as the row-by-row
reader refuses it, and no MAVLink import on the way (issue 14)."""

from __future__ import annotations

import csv
import datetime as dt
import io
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from acquisition.errors import TelemetryError
from acquisition.telemetry import autopilot_csv, read_log, tracks
from acquisition.telemetry.csv_cells import (
    altitude_m,
    decimal_column,
    exif_datetime_column,
    first_number,
    parse_angle_deg,
    parse_exif_datetime,
)

DATA = Path(__file__).resolve().parents[1] / "data"
DIGITS = "0123456789"


def _same_bits(actual: np.ndarray | None, expected: list[float]) -> bool:
    """Equal as float64 bit patterns (so -0.0 differs from 0.0, and no tolerance)."""
    return actual is not None and actual.tobytes() == np.array(expected, dtype=np.float64).tobytes()


# ----------------------------------------------------------------------- imports


def test_reading_csv_and_gpx_tracks_imports_no_mavlink(tmp_path: Path) -> None:
    """A fresh interpreter imports what `sfap geotag IMAGES --log track.csv` imports, reads an
    exiftool CSV, a PX4 GPS CSV (lat, lon in degE7) and a GPX track, and has not imported
    pymavlink (about 0.1 s), the MAVLink adapters or the MRK reader."""
    px4 = tmp_path / "vehicle_gps_position.csv"
    px4.write_text(
        "timestamp,time_utc_usec,lat,lon,alt\n5200000,1700000005200000,471234567,87654321,512500\n"
    )
    code = (
        "import json, sys\n"
        "import acquisition.geotag, acquisition.telemetry\n"
        "from acquisition.telemetry import read_log\n"
        "logs = [read_log(p) for p in sys.argv[1:]]\n"
        "print(json.dumps({'lat_deg': [float(g.positions.lat_deg[0]) for g in logs],\n"
        "    'modules': sorted(m for m in sys.modules if m.startswith(('pymavlink', 'acquisition')))}))\n"
    )
    paths = [DATA / "track_exiftool.csv", px4, DATA / "track.gpx"]
    done = subprocess.run(
        [sys.executable, "-c", code, *map(str, paths)],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    result = json.loads(done.stdout)
    assert result["lat_deg"] == [44.9345, 47.1234567, 44.9345]
    modules = result["modules"]
    assert "acquisition.telemetry.tracks" in modules and "acquisition.telemetry.gpx" in modules
    assert [m for m in modules if m.startswith("pymavlink")] == []
    assert "acquisition.mavlink_messages" not in modules and "acquisition.mavlink_items" not in modules
    assert "acquisition.telemetry.mrk" not in modules


# ----------------------------------------------------------------------- cells

# Plain decimals, built from their parts: sign, whole digits, fraction digits (".5", "12.", "-0").
decimal_cells = st.builds(
    lambda sign, whole, frac: sign + (whole or ("" if frac else "0")) + ("" if frac is None else "." + frac),
    st.sampled_from(["", "-", "+"]),
    st.text(DIGITS, max_size=5),
    st.none() | st.text(DIGITS, max_size=14),
).filter(lambda c: c.strip("+-") != ".")
# And as exiftool and autopilot exports print floats.
printed_decimals = st.builds(
    lambda x, places: f"{x:.{places}f}", st.floats(-400, 400, allow_nan=False), st.integers(0, 12)
)


@st.composite
def stamps(draw: st.DrawFn) -> str:
    """A stamp in the fast form: any real date and time of day, seconds 00-99 with or without a
    fraction, ``:``/``-`` and space/``T``, no zone, ``Z`` or an offset of any two digits."""
    when = draw(st.datetimes(min_value=dt.datetime(1, 1, 1), max_value=dt.datetime(9999, 12, 31, 23, 59)))
    seconds = f"{draw(st.integers(0, 99)):02d}"
    fraction = draw(st.text(DIGITS, max_size=12))
    if fraction:
        seconds += "." + fraction
    sep = draw(st.sampled_from([":", "-"]))
    zone = draw(
        st.sampled_from(["", "Z"])
        | st.builds(
            lambda sign, h, m, colon: f"{sign}{h:02d}{colon}{m:02d}",
            st.sampled_from("+-"),
            st.integers(0, 99),
            st.integers(0, 99),
            st.sampled_from(["", ":"]),
        )
    )
    return (
        f"{when.year:04d}{sep}{when.month:02d}{sep}{when.day:02d}{draw(st.sampled_from([' ', 'T']))}"
        f"{when.hour:02d}:{when.minute:02d}:{seconds}{zone}"
    )


@settings(max_examples=300, deadline=None)
@given(st.lists(decimal_cells | printed_decimals, max_size=40))
def test_decimal_column_is_each_cell_parser_bit_for_bit(cells: list[str]) -> None:
    column = decimal_column(cells)
    assert _same_bits(column, [parse_angle_deg(c, positive="N", negative="S") for c in cells])
    assert _same_bits(column, [parse_angle_deg(c, positive="E", negative="W") for c in cells])
    assert _same_bits(column, [altitude_m(c) for c in cells])
    assert _same_bits(column, [first_number(c) for c in cells])


@settings(max_examples=300, deadline=None)
@given(st.lists(stamps(), max_size=40))
def test_stamp_column_is_the_cell_parser_bit_for_bit(cells: list[str]) -> None:
    assert _same_bits(exif_datetime_column(cells), [parse_exif_datetime(c) for c in cells])


def test_stamp_column_against_known_instants() -> None:
    """1,700,000,000 s is 2023-11-14T22:13:20Z; a zone is subtracted; the fraction is kept."""
    column = exif_datetime_column(
        [
            "2023:11:14 22:13:20Z",
            "2023-11-15T00:13:20+02:00",
            "2023:11:14 17:13:20.25-0500",
            "1970:01:01 00:00:00",
        ]
    )
    assert column is not None and column.tolist() == [1_700_000_000.0, 1_700_000_000.0, 1_700_000_000.25, 0.0]


# Cells the cell parsers read (or refuse) but the fast forms do not hold: the column is then None
# and the reader parses it cell by cell.
ODD_NUMBERS = ["1e1", "44 30 0 S", "44.5 N", "\u0663.\u0665", "1 000", "12 m", "nan", "inf", "", "1\n2", "."]
ODD_STAMPS = [
    "2023:11:14 22:13:20 Z",  # a space before the zone
    "2023:11:14 22:13:20z",
    "2023:11:14 2:13:20",
    "\u0662023:11:14 22:13:20",
    "2023:11:14 22:13:20\n2023:11:14 22:13:21",  # one cell holding two lines
    "2023:02:29 00:00:00",  # no such day
    "0000:01:01 00:00:00",
    "2023:11:14 24:00:00",
    "2023:11:14 23:60:00",
    "",
]


@settings(max_examples=200, deadline=None)
@given(st.lists(decimal_cells, max_size=10), st.sampled_from(ODD_NUMBERS), st.integers(0, 10))
def test_a_column_with_one_odd_number_is_left_to_the_cell_parser(cells: list[str], odd: str, at: int) -> None:
    cells.insert(min(at, len(cells)), odd)
    assert decimal_column(cells) is None


@settings(max_examples=200, deadline=None)
@given(st.lists(stamps(), max_size=10), st.sampled_from(ODD_STAMPS), st.integers(0, 10))
def test_a_column_with_one_odd_stamp_is_left_to_the_cell_parser(cells: list[str], odd: str, at: int) -> None:
    cells.insert(min(at, len(cells)), odd)
    assert exif_datetime_column(cells) is None


def test_odd_stamps_the_cell_parser_still_reads_or_refuses() -> None:
    assert parse_exif_datetime("2023:11:14 22:13:20 Z") == 1_700_000_000.0
    for bad in ("2023:02:29 00:00:00", "0000:01:01 00:00:00", "2023:11:14 24:00:00", "2023:11:14 2:13:20"):
        with pytest.raises(ValueError):
            parse_exif_datetime(bad)


# ----------------------------------------------------------------------- whole files

OPTIONAL = ["GPSAltitude", "GPSImgDirection", "GPSPitch", "CameraElevationAngle", "GPSRoll"]


def _printed(limit: float) -> st.SearchStrategy[str]:
    return st.builds(
        lambda x, places: f"{x:.{places}f}", st.floats(-limit, limit, allow_nan=False), st.integers(0, 12)
    )


def _numbers(
    draw: st.DrawFn,
    mode: str,
    fast: st.SearchStrategy[str],
    odd: st.SearchStrategy[str],
    bad: list[str],
    n: int,
) -> list[str]:
    """A column of n cells: all in the fast form, mixed with other forms, or with one bad cell."""
    cells = [draw(fast if mode == "fast" else fast | odd) for _ in range(n)]
    if mode == "bad" and n:
        cells[draw(st.integers(0, n - 1))] = draw(st.sampled_from(bad))
    return cells


@st.composite
def exiftool_tracks(draw: st.DrawFn) -> str:
    """An exiftool CSV track: columns in any order, the time as one stamp or split in date and
    time, Ref columns or not, any optional columns; each column all in the fast form or mixed
    with the other forms exiftool writes; in about one file of two, one column with a bad cell;
    blank rows and short rows."""
    split = draw(st.booleans())
    refs = draw(st.booleans())
    names = ["SourceFile", *(["GPSDateStamp", "GPSTimeStamp"] if split else ["GPSDateTime"])]
    names += ["GPSLatitude", "GPSLongitude", *(["GPSLatitudeRef", "GPSLongitudeRef"] if refs else [])]
    names += draw(st.lists(st.sampled_from(OPTIONAL), unique=True))
    n = draw(st.integers(0, 12))
    broken = draw(st.sampled_from([None, None, None, *names]))  # the column with a bad cell, if any
    mode = {name: "bad" if name == broken else draw(st.sampled_from(["fast", "mixed"])) for name in names}
    columns: dict[str, list[str]] = {"SourceFile": [f"IMG_{i:04d}.JPG" for i in range(n)]}
    time_mode = mode["GPSDateStamp" if split else "GPSDateTime"]
    times = [draw(stamps()) for _ in range(n)]
    if time_mode == "mixed":
        odd_stamp = st.sampled_from(["2023:11:14 22:13:20 Z", "2023-11-14 22:13:20.5 +01:00"])
        times = [draw(odd_stamp) if draw(st.booleans()) else t for t in times]
    if time_mode == "bad" and n:
        times[draw(st.integers(0, n - 1))] = draw(
            st.sampled_from(["2023:11:14 24:00:00", "2023:13:01 00:00:00", ""])
        )
    if split:
        columns["GPSDateStamp"] = [t[:10] for t in times]
        columns["GPSTimeStamp"] = [t[11:] for t in times]
    else:
        columns["GPSDateTime"] = times
    for name, letters, limit in (("GPSLatitude", "NS", 90), ("GPSLongitude", "EW", 180)):
        dms = st.builds(
            lambda d, m, s, h: f"{d} deg {m}' {s:.2f}\" {h}",
            st.integers(0, 89),
            st.integers(0, 59),
            st.floats(0, 59.99),
            st.sampled_from(letters),
        )
        lettered = st.builds(lambda x, h: f"{x.lstrip('+-')} {h}", _printed(limit), st.sampled_from(letters))
        bad = ["ten", "", "95 deg", "1 2 3 4", "200"]
        columns[name] = _numbers(draw, mode[name], _printed(limit), dms | lettered, bad, n)
    if refs:
        for name, letters in (
            ("GPSLatitudeRef", ["N", "S", "s", "South", ""]),
            ("GPSLongitudeRef", ["E", "W", "w", ""]),
        ):
            columns[name] = [draw(st.sampled_from(letters)) for _ in range(n)]
    for name in OPTIONAL:
        if name in names:
            unit = " m Above Sea Level" if name == "GPSAltitude" else " deg"
            odd = st.builds(
                lambda x, u: f"{x}{u}", printed_decimals, st.sampled_from([unit, " m Below Sea Level"])
            )
            fast = printed_decimals | decimal_cells
            columns[name] = _numbers(draw, mode[name], fast, odd | st.just(""), ["abc", "1 2"], n)
    order = draw(st.permutations(names))
    out = io.StringIO()
    writer = csv.writer(out, lineterminator=draw(st.sampled_from(["\n", "\r\n"])))
    writer.writerow(order)
    for i in range(n):
        if draw(st.integers(0, 9)) == 0:
            writer.writerow(draw(st.sampled_from([[], ["", ""], [" "]])))
        row = [columns[name][i] for name in order]
        while row and row[-1] == "" and draw(st.booleans()):
            row.pop()  # a short row: the missing cells are empty
        writer.writerow(row)
    return out.getvalue()


@settings(max_examples=250, deadline=None)
@given(exiftool_tracks())
def test_by_column_reads_every_track_as_by_row_does(text: str) -> None:
    """The column-at-a-time parse against the row-by-row parse (the reader as it was, cell by
    cell): the same arrays bit for bit and the same empty-column lines for every file the
    row-by-row parse reads; None (so the row-by-row parse names the error) for every file it
    refuses."""
    header = next(csv.reader(io.StringIO(text)))
    layout = tracks._exiftool_header("t.csv", header)
    by_column = tracks._parse_by_column(layout, text)
    from hypothesis import event

    event(f"column {by_column is not None}")
    try:
        by_row = tracks._parse_by_row(layout, text)
    except TelemetryError:
        assert by_column is None
        return
    assert by_column is not None
    for name in ("time_utc_s", "lat_deg", "lon_deg"):
        assert getattr(by_column, name).tobytes() == getattr(by_row, name).tobytes(), name
    assert by_column.optional.keys() == by_row.optional.keys()
    for key, values in by_row.optional.items():
        assert by_column.optional[key].tobytes() == values.tobytes(), key
    assert by_column.first_empty_line == by_row.first_empty_line


def test_the_benchmark_form_reads_by_column(tmp_path: Path) -> None:
    """exiftool's CSV form (signed decimal degrees, UTC stamps with milliseconds): every column
    in the fast form, and read_log's track is the row-by-row parse's, bit for bit."""
    t0 = dt.datetime(2023, 11, 14, 22, 13, 10, tzinfo=dt.UTC)
    lines = ["GPSDateTime,GPSLatitude,GPSLongitude,GPSAltitude"]
    for i in range(500):
        stamp = (t0 + dt.timedelta(milliseconds=200 * i)).strftime("%Y:%m:%d %H:%M:%S.%f")[:-3]
        lines.append(f"{stamp}Z,{42 + i * 1.8013e-5:.9f},{-93 - i * 1e-6:.9f},{300 + i * 0.0167:.3f}")
    path = tmp_path / "track.csv"
    path.write_text("\n".join(lines) + "\n")
    text = path.read_text()
    layout = tracks._exiftool_header(str(path), lines[0].split(","))
    assert exif_datetime_column([line.split(",")[0] for line in lines[1:]]) is not None
    by_row = tracks._parse_by_row(layout, text)
    log = read_log(path)
    assert log.positions is not None and log.positions.alt_amsl_m is not None
    assert log.positions.time_utc_s.tobytes() == by_row.time_utc_s.tobytes()
    assert log.positions.lat_deg.tobytes() == by_row.lat_deg.tobytes()
    assert log.positions.lon_deg.tobytes() == by_row.lon_deg.tobytes()
    assert log.positions.alt_amsl_m.tobytes() == by_row.optional["alt"].tobytes()
    assert (
        log.positions.time_utc_s[0] == t0.timestamp() and log.positions.time_utc_s[1] == t0.timestamp() + 0.2
    )


# ----------------------------------------------------------------------- autopilot exports


def _fixed(low: float, high: float, places: int) -> st.SearchStrategy[str]:
    return st.floats(low, high, allow_nan=False).map(lambda x: f"{x:.{places}f}")


@st.composite
def autopilot_tracks(draw: st.DrawFn) -> str:
    """A GPS export in one of the autopilot layouts: rows without a fix (Status < 3, no UTC
    time, a 0, 0 position), times as GPS week and ms, microseconds, POSIX seconds or stamps
    (all fast, or mixed with other ISO forms), short and blank rows; in about one file of two,
    one column with a bad cell."""
    kind = draw(st.sampled_from(["ardupilot", "sensor_gps", "vehicle_gps", "utc", "gps_week"]))
    degrees = {"lat": _fixed(-90, 90, 7), "lon": _fixed(-180, 180, 7)}
    zero = st.just("0")
    if kind == "ardupilot":
        columns = {
            "TimeUS": st.integers(0, 10**10).map(str),
            "Status": st.sampled_from(["3", "4", "6", "1", "0", " 2.5 "]),
            "GMS": st.integers(0, 604_799_999).map(str),
            "GWk": st.integers(2000, 2400).map(str),
            "Lat": degrees["lat"] | zero,
            "Lng": degrees["lon"] | zero,
            "Alt": _fixed(-50, 5000, 2),
        }
    elif kind in ("sensor_gps", "vehicle_gps"):
        usec = st.integers(1_500_000_000_000_000, 2_000_000_000_000_000).map(str) | zero
        e7 = kind == "vehicle_gps"
        columns = {
            "timestamp": st.integers(0, 10**10).map(str),
            "time_utc_usec": usec,
            "lat" if e7 else "latitude_deg": (
                st.integers(-900_000_000, 900_000_000).map(str) if e7 else degrees["lat"]
            )
            | zero,
            "lon" if e7 else "longitude_deg": (
                st.integers(-1_800_000_000, 1_800_000_000).map(str) if e7 else degrees["lon"]
            )
            | zero,
            "alt" if e7 else "altitude_msl_m": st.integers(-50_000, 5_000_000).map(str)
            if e7
            else _fixed(-50, 5000, 3),
        }
    elif kind == "utc":
        seconds = _fixed(1_000_000_000, 2_000_000_000, 3)
        fast_time = draw(st.sampled_from([stamps(), seconds]))
        iso = st.sampled_from(
            ["2023-11-14T22:13:20.5+00:00", "2023-11-14 22:13:20", "2023-11-14T22:13:20.250"]
        )
        columns = {
            draw(st.sampled_from(["time_utc", "utc", "datetime", "time"])): fast_time
            if draw(st.booleans())
            else fast_time | iso,
            draw(st.sampled_from(["lat", "latitude"])): degrees["lat"],
            draw(st.sampled_from(["lon", "lng", "longitude"])): degrees["lon"],
        }
        if draw(st.booleans()):
            columns[draw(st.sampled_from(["alt", "altitude"]))] = _fixed(-50, 5000, 2)
    else:
        columns = {
            "gps_week": st.integers(2000, 2400).map(str),
            "gps_ms": st.integers(0, 604_799_999).map(str),
            "lat": degrees["lat"],
            "lon": degrees["lon"],
            "alt": _fixed(-50, 5000, 2),
        }
    names = list(columns)
    n = draw(st.integers(0, 12))
    cells = {name: [draw(columns[name]) for _ in range(n)] for name in names}
    broken = draw(st.sampled_from([None, None, None, *names]))
    if broken is not None and n:
        cells[broken][draw(st.integers(0, n - 1))] = draw(st.sampled_from(["x", "", "95", "1e999", "nan"]))
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(names)
    for i in range(n):
        if draw(st.integers(0, 9)) == 0:
            writer.writerow([])
        row = [cells[name][i] for name in names]
        if row and draw(st.integers(0, 30)) == 0:
            row.pop()  # a short row: its last cell is empty
        writer.writerow(row)
    return out.getvalue()


@settings(max_examples=300, deadline=None)
@given(autopilot_tracks())
@example(
    "timestamp,time_utc_usec,lat,lon,alt\n1,nan,100,200,300\n2,1700000000000000,100,200,300\n"
)  # NaN time
@example("time,lat,lon\n1700000000.5,1,2\n95,1,2\n")  # POSIX seconds before 2000
@example("time,lat,lon\n.5,1,2\n")
@example("TimeUS,Status,GMS,GWk,Lat,Lng,Alt\n1,nan,2,2300,1,2,3\n2,,2,2300,1,2,3\n3\n")
def test_autopilot_fixes_by_column_are_the_fixes_by_row(text: str) -> None:
    """As for exiftool's layout: the column parse of an autopilot export equals the row parse
    bit for bit (and the same count of rows without a fix), or is None where the row parse
    refuses the file."""
    header = next(csv.reader(io.StringIO(text)))
    found = autopilot_csv.layout_of(header)
    assert found is not None
    layout, index = found
    by_column = autopilot_csv._fixes_by_column(layout, index, text)
    try:
        by_row = autopilot_csv._fixes_by_row("t.csv", layout, index, text)
    except TelemetryError:
        assert by_column is None
        return
    assert by_column is not None and by_column.skipped == by_row.skipped
    for name in ("time_utc_s", "lat_deg", "lon_deg"):
        assert getattr(by_column, name).tobytes() == getattr(by_row, name).tobytes(), name
    if by_row.alt_amsl_m is None:
        assert by_column.alt_amsl_m is None
    else:
        assert (
            by_column.alt_amsl_m is not None and by_column.alt_amsl_m.tobytes() == by_row.alt_amsl_m.tobytes()
        )


# --- PX4's gps.csv (utc_usec) and a CSV's alt_msl column ----------------------------------------------


def test_px4_gps_csv_with_utc_usec_and_alt_msl_is_read(tmp_path: Path) -> None:
    """PX4's GPS export (utc_usec, lat, lon in degrees, alt_msl): every row's time, position and
    altitude as written, by hand (1700000005.2 s is 2023-11-14T22:13:25.2Z)."""
    path = tmp_path / "gps.csv"
    path.write_text(
        "utc_usec,lat,lon,alt_msl,satellites_used\n"
        "1700000005200000,47.1234567,8.7654321,512.5,14\n"
        "1700000006200000,47.1235567,8.7655321,513.0,14\n"
        "0,0,0,0,0\n"
    )
    log = read_log(path)
    assert log.positions is not None
    np.testing.assert_array_equal(log.positions.time_utc_s, [1700000005.2, 1700000006.2])
    np.testing.assert_array_equal(log.positions.lat_deg, [47.1234567, 47.1235567])
    np.testing.assert_array_equal(log.positions.lon_deg, [8.7654321, 8.7655321])
    assert log.positions.alt_amsl_m is not None
    np.testing.assert_array_equal(log.positions.alt_amsl_m, [512.5, 513.0])
    # The same in PX4's integer units (1e-7 degrees) reads as the same degrees.
    e7 = tmp_path / "gps_e7.csv"
    e7.write_text("utc_usec,lat,lon,alt_msl\n1700000005200000,471234567,87654321,512.5\n")
    track = read_log(e7).positions
    assert track is not None
    assert track.lat_deg[0] == pytest.approx(47.1234567, abs=1e-9)
    assert track.lon_deg[0] == pytest.approx(8.7654321, abs=1e-9)


def test_a_utc_track_reads_its_alt_msl_column(tmp_path: Path) -> None:
    path = tmp_path / "track.csv"
    path.write_text("time_utc,lat,lon,alt_msl\n2026-11-22T10:00:00Z,42.0,-1.5,350.25\n")
    track = read_log(path).positions
    assert track is not None and track.alt_amsl_m is not None
    assert track.alt_amsl_m.tolist() == [350.25]


def test_an_altitude_column_the_layout_cannot_read_is_said(tmp_path: Path) -> None:
    """An altitude column under a name no layout reads is not dropped silently: the log says so."""
    path = tmp_path / "track.csv"
    path.write_text("time_utc,lat,lon,alt_baro_ft\n2026-11-22T10:00:00Z,42.0,-1.5,1150\n")
    log = read_log(path)
    assert log.positions is not None and log.positions.alt_amsl_m is None
    assert any("alt_baro_ft" in w and "no altitude" in w for w in log.warnings), log.warnings


# ------------------------------------------------------------------ the forms checked by their characters


@settings(max_examples=400, deadline=None)
@given(st.lists(st.text(alphabet="0123456789+-.e \n\u0663", max_size=6), max_size=12))
def test_decimal_column_takes_exactly_the_plain_decimal_form(cells: list[str]) -> None:
    """decimal_column checks the form by the cells' characters and float(): it takes a column
    exactly when every cell is a plain decimal as the form's regular expression (the grammar of
    the docstring) writes it, and then gives float() of each cell."""
    import re

    plain = re.compile(r"[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)")
    column = decimal_column(cells)
    if all(plain.fullmatch(c) for c in cells):
        assert _same_bits(column, [float(c) for c in cells])
    else:
        assert column is None


@settings(max_examples=400, deadline=None)
@given(st.text(alphabet='ab1.,;" \t\n\r\x00', max_size=60))
@example('h\n"a,b",c\n')
@example("h\r\na,b\r\n")
@example("h\n\n, ,\na,,\n")
def test_data_rows_are_the_csv_modules_rows(text: str) -> None:
    """The rows after the header, split without the csv module when the text has no quote,
    carriage return or NUL, are the csv module's own rows (or None where it refuses the text)."""
    from acquisition.telemetry.csv_cells import data_rows

    reader = csv.reader(io.StringIO(text))
    try:
        next(reader, None)
        expected: list[list[str]] | None = [row for row in reader if "".join(row).strip()]
    except csv.Error:
        expected = None
    assert data_rows(text) == expected
