"""QGC WPL 110 ``.waypoints`` files (Mission Planner, MAVProxy / pymavlink, QGroundControl).

The format (REFERENCES.md section 4): a header line ``QGC WPL 110``, then one row per item,
tab-separated::

    INDEX CURRENT FRAME COMMAND P1 P2 P3 P4 LAT LON ALT AUTOCONTINUE

Row 0 is the home position (frame 0, command 16, altitude AMSL), rows 1..N the mission items,
so a row's INDEX is the item's MAVLink sequence number on an autopilot that keeps home at item
0 (ArduPilot). A DO_JUMP's param1 is such a row index; :class:`~planner.mission.Mission` keeps
the same convention (DO_JUMP param1 = 1-based position of the target among the items), so
nothing is renumbered here.

Writing: every number is written exactly (the shortest decimal that reads back to the same
float, never an exponent), padded to at least 8 decimals as Mission Planner pads them, so a
degE7 coordinate survives. A parameter that is ``None`` (MAVLink NaN, "leave unchanged") is
written ``NaN``, the spelling of Mission Planner (.NET ``double.ToString`` with en-US culture);
pymavlink writes ``nan``. Both are read, in any case.

Reading is tolerant of what real files contain: CRLF line ends, a UTF-8 byte-order mark,
blank lines, ``#`` comment lines (pymavlink skips them), any run of spaces or tabs between
fields, Mission Planner's home row (``CURRENT`` 1, command 0 in very old files). It is strict
about everything else: the header must be ``QGC WPL 110``; ``QGC WPL 100`` (the pre-2012 column
order with the old action codes) and ``QGC WPL 120`` (old QGC files with no home row) are
refused with a message saying how to convert them, as QGroundControl itself refuses 100; a row
must have 12 fields, consecutive indexes from 0, integer and float fields that parse, and a
frame sfap knows. Every error names the file, the line number and the field.
"""

from __future__ import annotations

import logging
import math
import os
from decimal import Decimal
from pathlib import Path

from ..errors import MissionFileError, MissionValidationError
from ..mission import Autopilot, HomePosition, MavCmd, MavFrame, Mission, MissionItem
from ..outputs import atomic_write_text
from .mission_file import item_from_params, mav_frame, read_mission_bytes

logger = logging.getLogger(__name__)

HEADER = "QGC WPL 110"
_FIELDS = (
    "INDEX",
    "CURRENT",
    "FRAME",
    "COMMAND",
    "P1",
    "P2",
    "P3",
    "P4",
    "LAT",
    "LON",
    "ALT",
    "AUTOCONTINUE",
)
_MIN_DECIMALS = 8
_NAN_TEXT = "NaN"


def format_number(value: float | None, *, min_decimals: int = _MIN_DECIMALS) -> str:
    """A float as the exact shortest decimal (no exponent), with at least ``min_decimals``.

    ``None`` and NaN become ``NaN``. Padding with zeros never changes the value, and the digits
    come from ``repr`` (the shortest string that reads back to the same double), so
    ``float(format_number(x)) == x`` for every finite ``x``.
    """
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return _NAN_TEXT
    number = float(value)
    if math.isinf(number):
        raise MissionValidationError(f"{number} cannot be written to a mission file; give a finite number")
    text = format(Decimal(repr(number)), "f")
    whole, _, decimals = text.partition(".")
    decimals = decimals.ljust(min_decimals, "0")
    return f"{whole}.{decimals}" if decimals else whole


def _row(index: int, current: int, item: MissionItem) -> str:
    fields = [str(index), str(current), str(int(item.frame)), str(int(item.command))]
    fields += [format_number(p) for p in item.params]
    fields.append("1" if item.autocontinue else "0")
    return "\t".join(fields)


def waypoints_text(mission: Mission) -> str:
    """The mission as QGC WPL 110 text: header, home in row 0, one row per item, LF line ends."""
    home = mission.home
    home_row = MissionItem(
        command=MavCmd.NAV_WAYPOINT,
        frame=MavFrame.GLOBAL,
        param1=0.0,
        param2=0.0,
        param3=0.0,
        param4=0.0,
        param5=home.lat_deg,
        param6=home.lon_deg,
        param7=home.alt_amsl_m,
    )
    # Mission Planner marks the home row current (1); every other row 0.
    lines = [HEADER, _row(0, 1, home_row)]
    lines += [_row(i, 0, item) for i, item in enumerate(mission.items, start=1)]
    return "\n".join(lines) + "\n"


def write_waypoints(mission: Mission, path: str | os.PathLike[str], *, overwrite: bool = True) -> Path:
    """Write ``mission`` to ``path`` as QGC WPL 110, atomically. Returns the path written."""
    return atomic_write_text(path, waypoints_text(mission), overwrite=overwrite)


def _fail(source: str, line_no: int, message: str) -> MissionFileError:
    return MissionFileError(f"{source}, line {line_no}: {message}")


def _parse_int(text: str, field: str, source: str, line_no: int) -> int:
    try:
        return int(text)
    except ValueError:
        # Some writers put integer fields as "3.0"; accept them only when they are whole.
        try:
            number = float(text)
        except ValueError:
            number = math.nan
        if math.isfinite(number) and number.is_integer():
            return int(number)
        raise _fail(source, line_no, f"{field} is {text!r}, expected an integer") from None


def _parse_float(text: str, field: str, source: str, line_no: int) -> float:
    try:
        number = float(text)
    except ValueError:
        raise _fail(source, line_no, f"{field} is {text!r}, expected a number") from None
    if math.isinf(number):
        raise _fail(source, line_no, f"{field} is {text!r}, expected a finite number")
    return number


def _parse_row(fields: list[str], source: str, line_no: int) -> tuple[int, int, MissionItem]:
    """One row -> (index, current, item); params 1-4 NaN become None."""
    index = _parse_int(fields[0], "INDEX", source, line_no)
    current = _parse_int(fields[1], "CURRENT", source, line_no)
    frame_number = _parse_int(fields[2], "FRAME", source, line_no)
    command = _parse_int(fields[3], "COMMAND", source, line_no)
    params = [_parse_float(fields[4 + k], _FIELDS[4 + k], source, line_no) for k in range(7)]
    autocontinue = _parse_int(fields[11], "AUTOCONTINUE", source, line_no)
    if autocontinue not in (0, 1):
        raise _fail(source, line_no, f"AUTOCONTINUE is {autocontinue}, expected 0 or 1")
    frame = mav_frame(frame_number)
    if isinstance(frame, str):
        raise _fail(source, line_no, frame.replace("frame", "FRAME", 1))
    if command < 0 or command > 65535:
        raise _fail(source, line_no, f"COMMAND {command} is not a MAV_CMD (0-65535)")
    item = item_from_params(command, frame, params, bool(autocontinue))
    return index, current, item


def parse_waypoints(text: str, *, source: str = "<waypoints>") -> Mission:
    """Parse QGC WPL 110 text (see the module docstring for what is accepted).

    Row 0 becomes :attr:`Mission.home` (latitude, longitude, altitude AMSL); the other rows the
    items. The file does not say which autopilot it is for: the mission is marked ArduPilot
    (whose format this is) and ``metadata["autopilot_from_file"]`` is False.
    """
    if text.startswith("\ufeff"):
        text = text[1:]
    lines = text.splitlines()  # handles LF, CRLF and CR
    numbered = [(n, line.strip()) for n, line in enumerate(lines, start=1)]
    content = [(n, line) for n, line in numbered if line and not line.startswith("#")]
    if not content:
        raise MissionFileError(f"{source} is empty; expected a first line {HEADER!r}")
    header_no, header = content[0]
    header_words = " ".join(header.split())
    if header_words != HEADER:
        if header_words == "QGC WPL 100":
            hint = (
                "this is the pre-2012 QGC WPL 100 format; open it in Mission Planner and save it "
                "again to get QGC WPL 110"
            )
        elif header_words == "QGC WPL 120":
            hint = (
                "this is an old QGroundControl file with no home row; open it in QGroundControl "
                "and save it as a .plan"
            )
        else:
            hint = f"a .waypoints file starts with {HEADER!r}"
        raise _fail(source, header_no, f"header is {header!r}: {hint}")

    home: HomePosition | None = None
    items: list[MissionItem] = []
    home_frame: MavFrame | None = None
    for line_no, line in content[1:]:
        fields = line.split()
        if len(fields) != len(_FIELDS):
            raise _fail(
                source,
                line_no,
                f"{len(fields)} fields, expected {len(_FIELDS)} ({' '.join(_FIELDS)})",
            )
        index, _current, item = _parse_row(fields, source, line_no)
        expected = 0 if home is None else len(items) + 1
        if index != expected:
            raise _fail(
                source,
                line_no,
                f"INDEX is {index}, expected {expected} (rows are numbered 0, 1, 2... in order, "
                f"row 0 the home position)",
            )
        if home is None:
            for name, value in (("LAT", item.lat_deg), ("LON", item.lon_deg), ("ALT", item.alt_m)):
                if math.isnan(value):
                    raise _fail(source, line_no, f"the home row's {name} is NaN; give a number")
            home = HomePosition(lat_deg=item.lat_deg, lon_deg=item.lon_deg, alt_amsl_m=item.alt_m)
            home_frame = item.frame
            continue
        items.append(item)
    if home is None:
        raise MissionFileError(f"{source} has a header but no rows; expected row 0, the home position")
    if home_frame is not MavFrame.GLOBAL:
        logger.warning(
            "%s: the home row has frame %s, not 0 (GLOBAL); its altitude %.2f m is taken as AMSL",
            source,
            int(home_frame) if home_frame is not None else "?",
            home.alt_amsl_m,
        )
    return Mission(
        items=tuple(items),
        home=home,
        autopilot=Autopilot.ARDUPILOT,
        metadata={"source_format": "qgc_wpl_110", "source": source, "autopilot_from_file": False},
    )


def read_waypoints(path: str | os.PathLike[str]) -> Mission:
    """Read a QGC WPL 110 file. Raises :class:`MissionFileError` naming the file, line and field."""
    file = Path(path)
    raw = read_mission_bytes(file, ".waypoints")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        # Old Mission Planner builds wrote the system code page; the format itself is ASCII.
        text = raw.decode("latin-1")
    return parse_waypoints(text, source=str(file))
