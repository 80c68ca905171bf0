"""GPX tracks -> :class:`~acquisition.telemetry.model.FlightLog` (positions only).

GPX 1.1 (and 1.0): every ``trk/trkseg/trkpt`` with its ``lat``, ``lon`` attributes, ``ele``
(metres, taken as AMSL) and ``time`` (ISO 8601, UTC when no offset is given). Errors name the
file and line, the bad value and what was expected.
"""

from __future__ import annotations

import os
from xml.parsers import expat

import numpy as np

from ..errors import TelemetryError
from .csv_cells import parse_iso_time_s
from .gpstime import time_order
from .model import FlightLog, flight_log, position_track


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
                pt[tag] = float(value) if tag == "ele" else parse_iso_time_s(value)
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
    lat_lon = (np.array([pt[1] for pt in points]), np.array([pt[2] for pt in points]))
    return flight_log(p, "gpx", warnings, positions=position_track(t, lat_lon, alt, None, "gpx"))
