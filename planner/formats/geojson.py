"""GeoJSON (RFC 7946) writers for a :class:`~planner.plan.SurveyPlan`.

Four files, each a ``FeatureCollection`` in WGS84 longitude/latitude (RFC 7946 section 4),
coordinates rounded to 1e-8 degree (about 1 mm), polygon exterior rings counter-clockwise and
holes clockwise (section 3.1.6), a ``bbox`` member (section 5):

- flight lines (:func:`write_flight_lines_geojson`): one ``LineString`` per survey line, the
  camera-on segment from its first to its last exposure position, in flight direction;
- stations (:func:`write_stations_geojson`): one ``Point`` per planned exposure;
- footprints (:func:`write_footprints_geojson`): one ``Polygon`` per exposure, the ground
  footprint of the frame (a trapezoid for oblique frames);
- area (:func:`write_area_geojson`): the area to cover and every exclusion zone.

Geometry is two-dimensional on purpose: a third GeoJSON coordinate means height above the
WGS84 ellipsoid (section 3.1.1), and the plan's altitudes are relative to home or to the
ground, so they travel as properties whose names say their reference (``alt_rel_home_m``,
``alt_agl_m``).

A plan can hold hundreds of thousands of stations, so features are not built with
``json.dumps`` one by one: every numeric column is rounded to an integer count of its last
decimal and turned into text four digits at a time through lookup tables, into a fixed-width
byte table (one row per feature, NUL bytes as padding: leading and trailing zeros, the sign
of positive numbers), and the padding is removed in one pass per chunk of rows. NUL never
occurs in JSON text (``json.dumps`` escapes it as ``\\u0000``), so removing it cannot change
any string value.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray
from shapely.geometry import MultiPolygon, Polygon, mapping
from shapely.geometry.polygon import orient

from ..errors import PlanningError
from ..outputs import atomic_write_bytes
from ..plan import SurveyPlan

log = logging.getLogger(__name__)

#: Decimals of every coordinate written: 1e-8 degree is about 1.1 mm of latitude.
COORD_DECIMALS = 8

#: Rows formatted at once; bounds the memory of the byte table (about 0.5 kB per footprint).
_CHUNK_ROWS = 50_000

_NUL = 0
_DIGIT_0 = ord("0")


# --- vectorized JSON text -------------------------------------------------------------------


def _digit_tables() -> dict[str, NDArray[np.uint32]]:
    """Text of 0000-9999 as four ASCII bytes packed in a uint32, in four variants.

    ``plain``: zero-padded; ``lead_low``: leading zeros as NUL but at least one digit (the
    units group of an integer part); ``lead_high``: leading zeros as NUL, 0 all NUL (a higher
    group with nothing above it); ``trail``: trailing zeros as NUL, 0 all NUL (fraction groups).
    """
    k = np.arange(10_000)
    digits = np.stack([(k // 10**p) % 10 for p in (3, 2, 1, 0)], axis=1)
    nonzero = digits != 0
    seen_from_left = np.logical_or.accumulate(nonzero, axis=1)
    seen_from_right = np.logical_or.accumulate(nonzero[:, ::-1], axis=1)[:, ::-1]
    text = (digits + _DIGIT_0).astype(np.uint8)

    def pack(keep: NDArray[np.bool_]) -> NDArray[np.uint32]:
        table = np.where(keep, text, _NUL).astype(np.uint8)
        return np.ascontiguousarray(table).view(np.uint32).ravel()

    units = np.zeros_like(nonzero)
    units[:, 3] = True
    return {
        "plain": pack(np.ones_like(nonzero)),
        "lead_low": pack(seen_from_left | units),
        "lead_high": pack(seen_from_left),
        "trail": pack(seen_from_right),
    }


_TEXT4 = _digit_tables()


def _fixed_point(values: ArrayLike, decimals: int, *, what: str) -> NDArray[np.uint8]:
    """Numbers as JSON text, one per row of a NUL-padded uint8 table.

    Rounded to ``decimals`` places (0-8), trailing zeros of the fraction dropped (``30``
    rather than ``30.00``), no ``-0``. ``what`` names the column in the error for a
    non-finite value. Layout: a sign column, the integer part in groups of four digits,
    the dot, the fraction in groups of four digits; padding is NUL.
    """
    if not 0 <= decimals <= 8:
        raise ValueError(f"decimals = {decimals}, expected 0-8")
    v = np.asarray(values, dtype=np.float64)
    n = v.shape[0]
    if not np.isfinite(v).all():
        row = int(np.flatnonzero(~np.isfinite(v))[0])
        raise PlanningError(
            f"{what} of row {row} is {v[row]}; the plan holds a non-finite number and cannot be "
            f"written as GeoJSON (a planner bug: report it with the mission spec)"
        )
    scale = 10**decimals
    magnitude = np.abs(v)
    if n and float(magnitude.max()) * scale >= 2.0**62:
        row = int(np.argmax(magnitude))
        raise PlanningError(
            f"{what} of row {row} is {v[row]}, too large to write as GeoJSON; a planner bug: "
            f"report it with the mission spec"
        )
    q = np.rint(magnitude * scale).astype(np.int64)
    int_part = q // scale if decimals else q
    int_groups = -(-len(str(int(int_part.max()))) // 4) if n else 1
    frac_groups = -(-decimals // 4)
    width = 1 + 4 * int_groups + (1 + 4 * frac_groups if decimals else 0)
    out = np.empty((n, width), dtype=np.uint8)
    if n == 0:
        return out
    out[:, 0] = np.where((v < 0) & (q > 0), ord("-"), _NUL)  # no "-0"
    rest = int_part
    for g in range(int_groups):  # least significant group first
        group = rest % 10_000
        rest = rest // 10_000
        lead = _TEXT4["lead_low" if g == 0 else "lead_high"][group]
        text = lead if g == int_groups - 1 else np.where(rest == 0, lead, _TEXT4["plain"][group])
        column = 1 + 4 * (int_groups - 1 - g)
        out[:, column : column + 4] = text.view(np.uint8).reshape(n, 4)
    if decimals:
        # the fraction, padded with zeros to whole groups of four (they become NUL)
        frac = (q - int_part * scale) * 10 ** (4 * frac_groups - decimals)
        dot = 1 + 4 * int_groups
        out[:, dot] = np.where(frac == 0, _NUL, ord("."))
        rest = frac
        all_zero_below = np.ones(n, dtype=bool)
        for g in range(frac_groups):  # least significant group first
            group = rest % 10_000
            rest = rest // 10_000
            text = np.where(all_zero_below, _TEXT4["trail"][group], _TEXT4["plain"][group])
            all_zero_below &= group == 0
            column = dot + 1 + 4 * (frac_groups - 1 - g)
            out[:, column : column + 4] = text.view(np.uint8).reshape(n, 4)
    return out


def _choice(index: NDArray[np.intp], texts: Sequence[str]) -> NDArray[np.uint8]:
    """Per row, one of a few JSON texts (already escaped), picked by ``index``."""
    encoded = [t.encode("utf-8") for t in texts]
    if any(b"\x00" in e for e in encoded):  # pragma: no cover - json.dumps escapes NUL
        raise ValueError("JSON text with a raw NUL byte")
    width = max((len(e) for e in encoded), default=0)
    table = np.zeros((max(len(encoded), 1), width), dtype=np.uint8)
    for k, e in enumerate(encoded):
        table[k, : len(e)] = np.frombuffer(e, dtype=np.uint8)
    return table[index]


@dataclass(frozen=True)
class _Lit:
    text: str


@dataclass(frozen=True)
class _Num:
    values: NDArray[np.float64]
    decimals: int
    what: str


@dataclass(frozen=True)
class _Pick:
    index: NDArray[np.intp]
    texts: tuple[str, ...]


_Field = _Lit | _Num | _Pick


def _props(*props: tuple[str, NDArray[np.float64], int, str]) -> list[_Field]:
    """Number properties after the first: ``,"key":value`` for each (key, values, decimals, what)."""
    return [
        field
        for key, values, decimals, what in props
        for field in (_Lit(f',"{key}":'), _Num(values, decimals, what))
    ]


def _render_rows(fields: Sequence[_Field], n: int, separator: str = ",\n") -> Iterator[bytes]:
    """The rows described by ``fields`` as text, a chunk of rows at a time, rows joined by
    ``separator`` (a generator, so that only one chunk's table is alive at a time)."""
    sep = np.frombuffer(separator.encode(), dtype=np.uint8)
    literals = {
        id(f): np.frombuffer(f.text.encode("utf-8"), dtype=np.uint8) for f in fields if isinstance(f, _Lit)
    }
    for start in range(0, n, _CHUNK_ROWS):
        stop = min(n, start + _CHUNK_ROWS)
        m = stop - start
        blocks: list[NDArray[np.uint8]] = []
        formatted: dict[tuple[int, int], NDArray[np.uint8]] = {}  # a column written twice
        for f in fields:
            if isinstance(f, _Lit):
                blocks.append(literals[id(f)])
            elif isinstance(f, _Num):
                key = (id(f.values), f.decimals)
                if key not in formatted:
                    formatted[key] = _fixed_point(f.values[start:stop], f.decimals, what=f.what)
                blocks.append(formatted[key])
            else:
                blocks.append(_choice(f.index[start:stop], f.texts))
        blocks.append(sep)
        widths = [b.shape[-1] for b in blocks]
        table = np.empty((m, sum(widths)), dtype=np.uint8)
        column = 0
        for block, w in zip(blocks, widths, strict=True):
            table[:, column : column + w] = block  # a literal broadcasts over the rows
            column += w
        piece = table.tobytes().translate(None, b"\x00")
        yield piece[: -sep.shape[0]] if stop == n else piece  # none after the last row


def _collection(name: str, kind: str, bbox: Sequence[float] | None, features: Iterable[bytes]) -> bytes:
    """The FeatureCollection text around ``features``."""
    head: dict[str, object] = {"type": "FeatureCollection", "name": name, "sfap_layer": kind}
    if bbox is not None and all(np.isfinite(bbox)):
        head["bbox"] = [round(float(b), COORD_DECIMALS) for b in bbox]
    text = json.dumps(head, ensure_ascii=False)
    opening = text[:-1] + ',"features":[\n'
    return b"".join([opening.encode("utf-8"), *features, b"\n]}\n"])


def _bbox(lon_deg: NDArray[np.float64], lat_deg: NDArray[np.float64]) -> list[float] | None:
    if lon_deg.size == 0:
        return None
    return [
        float(np.min(lon_deg)),
        float(np.min(lat_deg)),
        float(np.max(lon_deg)),
        float(np.max(lat_deg)),
    ]


def _pass_lookup(plan: SurveyPlan, pass_index: NDArray[np.int32]) -> NDArray[np.intp]:
    """Position in ``plan.passes`` of each row's pass index (passes are looked up by index)."""
    positions = {p.index: k for k, p in enumerate(plan.passes)}
    if pass_index.size == 0:
        return np.zeros(0, dtype=np.intp)
    # A table over 0 .. the largest index; not np.unique, which imports numpy.ma (15 ms).
    top = max(positions, default=-1)
    known = np.zeros(top + 1, dtype=bool)
    lookup = np.zeros(top + 1, dtype=np.intp)
    for index, k in positions.items():
        known[index] = True
        lookup[index] = k
    in_table = (pass_index >= 0) & (pass_index <= top)
    held = np.zeros(pass_index.shape, dtype=bool)
    held[in_table] = known[pass_index[in_table]]
    if not held.all():
        unknown = set(pass_index[~held].tolist())
        raise PlanningError(
            f"stations refer to pass {sorted(unknown)} that the plan does not hold "
            f"(passes: {sorted(positions)}); a planner bug: report it with the mission spec"
        )
    return lookup[pass_index]


# --- the writers --------------------------------------------------------------------------------


def flight_lines_geojson_bytes(plan: SurveyPlan) -> bytes:
    """The flight lines file as bytes (see :func:`write_flight_lines_geojson`)."""
    lines = [(k, p, line) for k, p in enumerate(plan.passes) for line in p.lines]
    n = len(lines)
    start = np.array([ln.start_xy_m for _, _, ln in lines], dtype=np.float64).reshape(n, 2)
    end = np.array([ln.end_xy_m for _, _, ln in lines], dtype=np.float64).reshape(n, 2)
    entry = np.array([ln.entry_xy_m for _, _, ln in lines], dtype=np.float64).reshape(n, 2)
    exit_ = np.array([ln.exit_xy_m for _, _, ln in lines], dtype=np.float64).reshape(n, 2)
    lon0, lat0 = plan.frame.to_lonlat(start[:, 0], start[:, 1])
    lon1, lat1 = plan.frame.to_lonlat(end[:, 0], end[:, 1])
    pos = np.array([k for k, _, _ in lines], dtype=np.intp)
    kinds = tuple(json.dumps(p.kind.value) for p in plan.passes)
    names = tuple(json.dumps(p.name, ensure_ascii=False) for p in plan.passes)

    def col(values: Sequence[float]) -> NDArray[np.float64]:
        return np.asarray(values, dtype=np.float64).reshape(n)

    look = col(
        [p.look_heading_deg if p.look_heading_deg is not None else ln.heading_deg for _, p, ln in lines]
    )
    fields: list[_Field] = [
        _Lit('{"type":"Feature","geometry":{"type":"LineString","coordinates":[['),
        _Num(lon0, COORD_DECIMALS, "line start longitude"),
        _Lit(","),
        _Num(lat0, COORD_DECIMALS, "line start latitude"),
        _Lit("],["),
        _Num(lon1, COORD_DECIMALS, "line end longitude"),
        _Lit(","),
        _Num(lat1, COORD_DECIMALS, "line end latitude"),
        _Lit(']]},"properties":{"pass":'),
        _Num(col([p.index for _, p, _ in lines]), 0, "pass index"),
        _Lit(',"line":'),
        _Num(col([ln.line_index for _, _, ln in lines]), 0, "line index"),
        _Lit(',"kind":'),
        _Pick(pos, kinds),
        _Lit(',"pass_name":'),
        _Pick(pos, names),
        *_props(
            ("heading_deg", col([ln.heading_deg for _, _, ln in lines]), 2, "line heading"),
            ("length_m", np.hypot(*(end - start).T), 3, "line length"),
            ("lead_in_m", np.hypot(*(start - entry).T), 3, "line lead-in"),
            ("overshoot_m", np.hypot(*(exit_ - end).T), 3, "line overshoot"),
            ("alt_agl_m", col([p.alt_agl_m for _, p, _ in lines]), 2, "pass altitude"),
            ("tilt_deg", col([p.tilt_deg for _, p, _ in lines]), 2, "pass tilt"),
            ("look_heading_deg", look, 2, "look heading"),
            ("trigger_distance_m", col([p.trigger_distance_m for _, p, _ in lines]), 3, "trigger distance"),
        ),
        _Lit("}}"),
    ]
    body = _render_rows(fields, n)
    bbox = _bbox(np.concatenate([lon0, lon1]), np.concatenate([lat0, lat1]))
    return _collection(f"{plan.name}: flight lines", "flight_lines", bbox, body)


def stations_geojson_bytes(plan: SurveyPlan) -> bytes:
    """The stations file as bytes (see :func:`write_stations_geojson`)."""
    st = plan.stations
    n = len(st)
    pos = _pass_lookup(plan, st.pass_index)
    kinds = tuple(json.dumps(p.kind.value) for p in plan.passes)
    index = np.arange(n, dtype=np.float64)
    fields: list[_Field] = [
        _Lit('{"type":"Feature","id":'),
        _Num(index, 0, "station index"),
        _Lit(',"geometry":{"type":"Point","coordinates":['),
        _Num(st.lon_deg, COORD_DECIMALS, "station longitude"),
        _Lit(","),
        _Num(st.lat_deg, COORD_DECIMALS, "station latitude"),
        _Lit(']},"properties":{"pass":'),
        _Num(st.pass_index.astype(np.float64), 0, "pass index"),
        _Lit(',"line":'),
        _Num(st.line_index.astype(np.float64), 0, "line index"),
        _Lit(',"station":'),
        _Num(index, 0, "station index"),
        _Lit(',"kind":'),
        _Pick(pos, kinds),
        *_props(
            ("lat_deg", st.lat_deg, COORD_DECIMALS, "station latitude"),
            ("lon_deg", st.lon_deg, COORD_DECIMALS, "station longitude"),
            ("alt_rel_home_m", st.alt_rel_home_m, 2, "station altitude above home"),
            ("alt_agl_m", st.alt_agl_m, 2, "station altitude above ground"),
            ("heading_deg", st.heading_deg, 2, "station heading"),
            ("look_heading_deg", st.look_heading_deg, 2, "station look heading"),
            ("tilt_deg", st.tilt_deg, 2, "station tilt"),
            ("gsd_cm", st.gsd_cm, 3, "station GSD"),
        ),
        _Lit("}}"),
    ]
    body = _render_rows(fields, n)
    bbox = _bbox(st.lon_deg, st.lat_deg)
    return _collection(f"{plan.name}: exposure stations", "stations", bbox, body)


def counter_clockwise_corners(corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(N, 4, 2)`` quadrilaterals with each ring turned counter-clockwise (x east, y north).

    Image corners projected on the ground run clockwise for a nadir frame seen from above
    (top-left, top-right, bottom-right, bottom-left); the rows whose signed area is negative
    are reversed, the others kept, so the result holds for any tilt and heading.
    """
    c = np.asarray(corners, dtype=np.float64)
    x, y = c[..., 0], c[..., 1]
    twice_area = np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)
    clockwise = twice_area < 0
    out = c.copy()
    out[clockwise] = c[clockwise][:, ::-1]
    return out


def footprints_geojson_bytes(plan: SurveyPlan) -> bytes:
    """The footprints file as bytes (see :func:`write_footprints_geojson`)."""
    st = plan.stations
    n = len(st)
    corners = np.asarray(st.footprint_lonlat_deg, dtype=np.float64).reshape(n, 4, 2)
    ring = counter_clockwise_corners(corners)
    lon = [np.ascontiguousarray(ring[:, k, 0]) for k in range(4)]
    lat = [np.ascontiguousarray(ring[:, k, 1]) for k in range(4)]
    index = np.arange(n, dtype=np.float64)
    fields: list[_Field] = [
        _Lit('{"type":"Feature","id":'),
        _Num(index, 0, "station index"),
        _Lit(',"geometry":{"type":"Polygon","coordinates":[['),
    ]
    for k in (0, 1, 2, 3, 0):  # closed ring: the first corner again (formatted once)
        fields += [
            _Lit("[" if len(fields) == 3 else ",["),
            _Num(lon[k], COORD_DECIMALS, "footprint longitude"),
            _Lit(","),
            _Num(lat[k], COORD_DECIMALS, "footprint latitude"),
            _Lit("]"),
        ]
    fields += [
        _Lit(']]},"properties":{"pass":'),
        _Num(st.pass_index.astype(np.float64), 0, "pass index"),
        *_props(
            ("line", st.line_index.astype(np.float64), 0, "line index"),
            ("station", index, 0, "station index"),
            ("tilt_deg", st.tilt_deg, 2, "station tilt"),
            ("look_heading_deg", st.look_heading_deg, 2, "station look heading"),
            ("gsd_cm", st.gsd_cm, 3, "station GSD"),
        ),
        _Lit("}}"),
    ]
    body = _render_rows(fields, n)
    bbox = _bbox(corners[..., 0].ravel(), corners[..., 1].ravel())
    return _collection(f"{plan.name}: frame footprints", "footprints", bbox, body)


def _rounded_polygon(poly: Polygon | MultiPolygon) -> dict[str, object]:
    """GeoJSON geometry of a lon/lat polygon: RFC 7946 winding, coordinates rounded."""
    if isinstance(poly, MultiPolygon):
        oriented: Polygon | MultiPolygon = MultiPolygon([orient(p, sign=1.0) for p in poly.geoms])
    else:
        oriented = orient(poly, sign=1.0)
    rounded = shapely.transform(oriented, lambda c: np.round(c, COORD_DECIMALS))
    geometry: dict[str, object] = mapping(rounded)
    return geometry


def area_geojson_bytes(plan: SurveyPlan) -> bytes:
    """The area file as bytes (see :func:`write_area_geojson`)."""
    features: list[bytes] = []
    area = plan.area_lonlat
    features.append(
        json.dumps(
            {
                "type": "Feature",
                "geometry": _rounded_polygon(area),
                "properties": {
                    "kind": "area",
                    "name": plan.name,
                    "area_m2": round(float(plan.area_xy.area), 2),
                    "crs_of_area_m2": plan.frame.crs.to_string(),
                },
            },
            ensure_ascii=False,
        ).encode("utf-8")
    )
    for k, (zone_ll, zone_xy) in enumerate(zip(plan.exclusions_lonlat, plan.exclusions_xy, strict=True)):
        features.append(
            json.dumps(
                {
                    "type": "Feature",
                    "geometry": _rounded_polygon(zone_ll),
                    "properties": {
                        "kind": "exclusion",
                        "exclusion": k,
                        "area_m2": round(float(zone_xy.area), 2),
                    },
                }
            ).encode("utf-8")
        )
    bounds = [area.bounds] + [z.bounds for z in plan.exclusions_lonlat]
    b = np.array(bounds, dtype=np.float64)
    bbox = None if area.is_empty else [b[:, 0].min(), b[:, 1].min(), b[:, 2].max(), b[:, 3].max()]
    return _collection(f"{plan.name}: area", "area", bbox, [b",\n".join(features)])


def write_flight_lines_geojson(plan: SurveyPlan, path: str | os.PathLike[str]) -> Path:
    """Write every survey line as a GeoJSON ``LineString`` (WGS84 lon/lat), atomically.

    Geometry: the camera-on segment, first to last exposure position, in flight direction.
    Properties: ``pass``, ``line`` (indices), ``kind`` (nadir | crosshatch | oblique),
    ``pass_name``, ``heading_deg`` (true bearing of flight, degrees clockwise from true north),
    ``length_m`` (camera-on length), ``lead_in_m`` / ``overshoot_m`` (turnaround extensions
    before and after), ``alt_agl_m``, ``tilt_deg`` (off nadir), ``look_heading_deg`` (true
    bearing the camera looks toward), ``trigger_distance_m``. Returns the path written.
    """
    return _write(path, flight_lines_geojson_bytes(plan), "flight lines")


def write_stations_geojson(plan: SurveyPlan, path: str | os.PathLike[str]) -> Path:
    """Write every planned exposure as a GeoJSON ``Point`` (WGS84 lon/lat), atomically.

    Feature ``id`` and property ``station`` are the 0-based index in flight order. Properties:
    ``pass``, ``line``, ``station``, ``kind``, ``lat_deg``, ``lon_deg``, ``alt_rel_home_m``
    (commanded altitude above home), ``alt_agl_m`` (above the ground below), ``heading_deg``
    (true bearing of flight), ``look_heading_deg`` (true bearing the optical axis points toward),
    ``tilt_deg`` (off nadir), ``gsd_cm`` (where the optical axis meets the ground).
    """
    return _write(path, stations_geojson_bytes(plan), "stations")


def write_footprints_geojson(plan: SurveyPlan, path: str | os.PathLike[str]) -> Path:
    """Write the ground footprint of every exposure as a GeoJSON ``Polygon``, atomically.

    Rings are counter-clockwise (RFC 7946) whatever the heading and tilt. Feature ``id`` and
    property ``station`` match the stations file. Properties: ``pass``, ``line``, ``station``,
    ``tilt_deg``, ``look_heading_deg``, ``gsd_cm``.
    """
    return _write(path, footprints_geojson_bytes(plan), "footprints")


def write_area_geojson(plan: SurveyPlan, path: str | os.PathLike[str]) -> Path:
    """Write the area to cover (``kind`` "area", holes as interior rings) and every
    exclusion zone (``kind`` "exclusion") as GeoJSON polygons, atomically.

    ``area_m2`` is measured in the plan's projected frame (``crs_of_area_m2``).
    """
    return _write(path, area_geojson_bytes(plan), "area")


def _write(path: str | os.PathLike[str], data: bytes, what: str) -> Path:
    written = atomic_write_bytes(path, data)
    log.debug("wrote %s GeoJSON: %s (%d bytes)", what, written, len(data))
    return written
