"""Ground control: reading GCP files and splitting the points into control and check points.

Two formats:

- OpenDroneMap's ``gcp_list.txt``: the first line is the CRS (a PROJ string, ``EPSG:code`` or
  WKT: anything pyproj reads); then one image observation per line, separated by tabs or
  spaces: ``geo_x geo_y geo_z im_x im_y image_name [point_name [extra...]]``. Pixel
  coordinates are from the image's top-left corner, x right, y down.
- A CSV with a header row: ``name`` and either ``lon_deg, lat_deg`` (WGS84; ``lon``, ``lat``,
  ``longitude``, ``latitude`` also accepted) or ``easting_m, northing_m`` (``easting``,
  ``northing``, ``x``, ``y``: then the CRS is required, ``--gcp-crs``), an elevation
  ``alt_m`` (``alt``, ``elevation_m``, ``z``), then one observation per row in ``image``,
  ``x_px``, ``y_px``. A point's coordinates repeat on each of its rows (they must agree).

Every point is returned in WGS84 longitude, latitude and its elevation as given (the file's
vertical reference: say which in the report).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from pyproj import CRS, Transformer
from pyproj.exceptions import CRSError

from planner.errors import InputError

F64 = NDArray[np.float64]


class GcpError(InputError):
    """A GCP file or a check-point choice is unusable (exit code 2)."""


@dataclass(frozen=True, kw_only=True)
class Observation:
    """One measurement of a point in one image: pixel column ``x_px`` and row ``y_px`` from the
    top-left corner of the full-resolution image."""

    point: str
    image: str
    x_px: float
    y_px: float


@dataclass(frozen=True, kw_only=True)
class GroundPoint:
    """A surveyed point: WGS84 position and elevation (the file's vertical reference)."""

    name: str
    lon_deg: float
    lat_deg: float
    elevation_m: float
    source_xy: tuple[float, float]


@dataclass(frozen=True, kw_only=True)
class GcpSet:
    """The points and observations of a GCP file and the CRS it was written in."""

    points: tuple[GroundPoint, ...]
    observations: tuple[Observation, ...]
    crs: CRS
    source: str

    def point(self, name: str) -> GroundPoint:
        for p in self.points:
            if p.name == name:
                return p
        raise KeyError(name)

    def observations_of(self, name: str) -> list[Observation]:
        return [o for o in self.observations if o.point == name]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.points)


def _crs(text: str, where: str) -> CRS:
    try:
        return CRS.from_user_input(text.strip())
    except CRSError:
        raise GcpError(
            f"{where}: {text.strip()!r} is not a coordinate reference system pyproj knows; write it as "
            "'EPSG:32611', a PROJ string ('+proj=utm +zone=11 +datum=WGS84') or WKT"
        ) from None


def _to_lonlat(crs: CRS, x: F64, y: F64) -> tuple[F64, F64]:
    transformer = Transformer.from_crs(crs, CRS.from_epsg(4326), always_xy=True)
    lon, lat = transformer.transform(x, y)
    return np.asarray(lon, float), np.asarray(lat, float)


def _number(text: str, what: str, where: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise GcpError(f"{where}: {what} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise GcpError(f"{where}: {what} {text!r} is not a finite number")
    return value


def _assemble(
    rows: Sequence[tuple[str, float, float, float, str | None, float | None, float | None, str]],
    crs: CRS,
    source: str,
) -> GcpSet:
    """rows: (point, x, y, z, image, x_px, y_px, where) in ``crs``."""
    coords: dict[str, tuple[float, float, float, str]] = {}
    observations: list[Observation] = []
    for name, x, y, z, image, px, py, where in rows:
        known = coords.get(name)
        if known is None:
            coords[name] = (x, y, z, where)
        elif max(abs(known[0] - x), abs(known[1] - y), abs(known[2] - z)) > 1e-6:
            raise GcpError(
                f"{where}: point {name} has coordinates ({x}, {y}, {z}) but ({known[0]}, {known[1]}, "
                f"{known[2]}) at {known[3]}; one point, one position: fix the file"
            )
        if image is not None and px is not None and py is not None:
            observations.append(Observation(point=name, image=image, x_px=px, y_px=py))
    if not coords:
        raise GcpError(f"{source}: no ground control point in the file")
    names = list(coords)
    xs = np.array([coords[n][0] for n in names])
    ys = np.array([coords[n][1] for n in names])
    lon, lat = _to_lonlat(crs, xs, ys)
    if not (np.all(np.isfinite(lon)) and np.all(np.isfinite(lat))):
        raise GcpError(f"{source}: some coordinates do not convert from {crs.name} to WGS84; check the CRS")
    points = tuple(
        GroundPoint(
            name=n,
            lon_deg=float(lon[k]),
            lat_deg=float(lat[k]),
            elevation_m=coords[n][2],
            source_xy=(coords[n][0], coords[n][1]),
        )
        for k, n in enumerate(names)
    )
    return GcpSet(points=points, observations=tuple(observations), crs=crs, source=source)


def read_odm_gcp(path: str | os.PathLike[str]) -> GcpSet:
    """Read OpenDroneMap's gcp_list.txt (module docstring)."""
    p = Path(path)
    lines = p.read_text(encoding="utf-8-sig").splitlines()
    content = [(k + 1, line) for k, line in enumerate(lines) if line.strip() and not line.startswith("#")]
    if not content:
        raise GcpError(f"{p}: the file is empty; its first line must be the CRS")
    crs = _crs(content[0][1], f"{p} line {content[0][0]}")
    rows = []
    for number, line in content[1:]:
        where = f"{p} line {number}"
        fields = line.split()
        if len(fields) < 6:
            raise GcpError(
                f"{where}: {len(fields)} fields; expected geo_x geo_y geo_z im_x im_y image_name [gcp_name]"
            )
        x = _number(fields[0], "geo_x", where)
        y = _number(fields[1], "geo_y", where)
        z = _number(fields[2], "geo_z", where)
        px = _number(fields[3], "im_x", where)
        py = _number(fields[4], "im_y", where)
        image = fields[5]
        name = fields[6] if len(fields) > 6 else f"{x:.3f}_{y:.3f}_{z:.3f}"
        rows.append((name, x, y, z, image, px, py, where))
    return _assemble(rows, crs, str(p))


_LON = ("lon_deg", "lon", "longitude")
_LAT = ("lat_deg", "lat", "latitude")
_EAST = ("easting_m", "easting", "x", "x_m")
_NORTH = ("northing_m", "northing", "y", "y_m")
_ALT = ("alt_m", "alt", "elevation_m", "elevation", "z", "z_m", "height_m")
_IMAGE = ("image", "image_name", "photo")
_XPX = ("x_px", "px", "im_x", "col_px")
_YPX = ("y_px", "py", "im_y", "row_px")


def _column(header: list[str], names: Sequence[str]) -> int | None:
    for k, h in enumerate(header):
        if h in names:
            return k
    return None


def read_csv_gcp(path: str | os.PathLike[str], *, crs: str | None = None) -> GcpSet:
    """Read the plain CSV format (module docstring); ``crs`` for easting/northing columns."""
    p = Path(path)
    with p.open(newline="", encoding="utf-8-sig") as handle:
        table = [row for row in csv.reader(handle) if any(cell.strip() for cell in row)]
    if not table:
        raise GcpError(f"{p}: the file is empty; expected a header row (name, lon_deg, lat_deg, alt_m, ...)")
    header = [h.strip().lower() for h in table[0]]
    name_col = _column(header, ("name", "point", "point_name", "gcp_name"))
    lon_col, lat_col = _column(header, _LON), _column(header, _LAT)
    east_col, north_col = _column(header, _EAST), _column(header, _NORTH)
    alt_col = _column(header, _ALT)
    img_col, xpx_col, ypx_col = _column(header, _IMAGE), _column(header, _XPX), _column(header, _YPX)
    if name_col is None or alt_col is None:
        raise GcpError(f"{p}: the header {table[0]} needs a 'name' and an 'alt_m' column")
    if lon_col is not None and lat_col is not None:
        if crs is not None and not _crs(crs, "--gcp-crs").is_geographic:
            raise GcpError(f"{p}: lon/lat columns with a projected --gcp-crs {crs!r}; drop --gcp-crs")
        the_crs = _crs(crs, "--gcp-crs") if crs is not None else CRS.from_epsg(4326)
        xc, yc = lon_col, lat_col
    elif east_col is not None and north_col is not None:
        if crs is None:
            raise GcpError(f"{p}: easting/northing columns need their CRS: pass --gcp-crs (e.g. EPSG:32611)")
        the_crs = _crs(crs, "--gcp-crs")
        xc, yc = east_col, north_col
    else:
        raise GcpError(
            f"{p}: the header {table[0]} has neither lon_deg/lat_deg nor easting_m/northing_m columns"
        )
    rows = []
    for number, row in enumerate(table[1:], start=2):
        where = f"{p} row {number}"
        cells = [c.strip() for c in row] + [""] * (len(header) - len(row))
        name = cells[name_col]
        if not name:
            raise GcpError(f"{where}: the point has no name")
        x = _number(cells[xc], header[xc], where)
        y = _number(cells[yc], header[yc], where)
        z = _number(cells[alt_col], header[alt_col], where)
        image = cells[img_col] if img_col is not None and cells[img_col] else None
        px = py = None
        if image is not None:
            if xpx_col is None or ypx_col is None:
                raise GcpError(f"{p}: an image column needs x_px and y_px columns")
            px = _number(cells[xpx_col], "x_px", where)
            py = _number(cells[ypx_col], "y_px", where)
        rows.append((name, x, y, z, image, px, py, where))
    return _assemble(rows, the_crs, str(p))


def read_gcp(path: str | os.PathLike[str], *, crs: str | None = None) -> GcpSet:
    """Read a GCP file: CSV when it ends in .csv, else OpenDroneMap's gcp_list.txt."""
    p = Path(path)
    if p.suffix.lower() == ".csv":
        return read_csv_gcp(p, crs=crs)
    if crs is not None:
        raise GcpError(f"{p}: an OpenDroneMap GCP file names its CRS on its first line; drop --gcp-crs")
    return read_odm_gcp(p)


def choose_check_points(
    names: Sequence[str], xy_m: F64, spec: str | None
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Split ``names`` into (control, check). ``spec``: None (no check points), a count ("3"),
    or names separated by commas. A count picks points spread over the block: the point nearest
    the centroid first, then each time the point farthest from those already picked."""
    if spec is None or not spec.strip():
        return tuple(names), ()
    text = spec.strip()
    if text.isdigit():
        count = int(text)
        if count >= len(names):
            raise GcpError(
                f"--check-points {count}: only {len(names)} usable points; keep at least three for control"
            )
        chosen: list[int] = []
        if count > 0:
            centre = xy_m.mean(axis=0)
            chosen.append(int(np.argmin(np.linalg.norm(xy_m - centre, axis=1))))
            while len(chosen) < count:
                d = np.min(np.linalg.norm(xy_m[:, None, :] - xy_m[None, chosen, :], axis=2), axis=1)
                d[chosen] = -1.0
                chosen.append(int(np.argmax(d)))
        check = tuple(names[k] for k in sorted(chosen))
    else:
        check = tuple(n.strip() for n in text.split(",") if n.strip())
        unknown = [n for n in check if n not in names]
        if unknown:
            raise GcpError(
                f"--check-points: {', '.join(unknown)} is not a usable point of the GCP file (usable: "
                f"{', '.join(names)})"
            )
    control = tuple(n for n in names if n not in check)
    return control, check
