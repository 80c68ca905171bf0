"""Camera-position files that reconstruction tools read beside the images (REFERENCES.md section 4).

- OpenDroneMap ``geo.txt``: first line the CRS (``EPSG:4326``), then per image
  ``name lon lat alt yaw pitch roll h_acc v_acc`` (x = longitude first), space separated.
- Pix4D image geolocation CSV: no header, ``name,lat,lon,alt,yaw,pitch,roll,acc_horz,acc_vert``.
- GeoJSON: a FeatureCollection of camera points (lon, lat, alt) with the pose as properties.

Altitudes are metres above mean sea level; angles in degrees in the camera convention of
:mod:`acquisition.geotag` (Pix4D's: a level nadir camera has pitch 0, roll 0; yaw clockwise
from north). Every file is written atomically. A row without an attitude is written without
one (geo.txt and the Pix4D CSV then end after the altitude, as both formats allow).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from planner.outputs import atomic_write_text

from .errors import GeotagError

ODM_GEO_TXT = "geo.txt"
PIX4D_CSV = "pix4d_geolocation.csv"
GEOJSON = "cameras.geojson"


@dataclass(frozen=True, kw_only=True)
class CameraPosition:
    """One image's position (WGS84, altitude AMSL in metres) and optional attitude/accuracy."""

    name: str
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float | None = None
    yaw_deg: float | None = None
    pitch_deg: float | None = None
    roll_deg: float | None = None
    xy_accuracy_m: float | None = None
    z_accuracy_m: float | None = None
    time_utc_s: float | None = None
    status: str | None = None

    def __post_init__(self) -> None:
        if not self.name or any(c.isspace() for c in self.name) or "," in self.name:
            raise GeotagError(
                f"image name {self.name!r} cannot go in geo.txt or a CSV (no spaces or commas); rename it"
            )
        if not (-90.0 <= self.lat_deg <= 90.0 and -180.0 <= self.lon_deg <= 180.0):
            raise GeotagError(f"{self.name}: position lat {self.lat_deg}, lon {self.lon_deg} is not WGS84")

    @property
    def has_attitude(self) -> bool:
        return self.yaw_deg is not None and self.pitch_deg is not None and self.roll_deg is not None

    @property
    def has_accuracy(self) -> bool:
        return self.xy_accuracy_m is not None and self.z_accuracy_m is not None


def _columns(row: CameraPosition, lat_first: bool) -> list[str]:
    first, second = (row.lat_deg, row.lon_deg) if lat_first else (row.lon_deg, row.lat_deg)
    values = [row.name, f"{first:.9f}", f"{second:.9f}"]
    if row.alt_amsl_m is None:
        return values
    values.append(f"{row.alt_amsl_m:.3f}")
    if not row.has_attitude:
        return values
    values += [f"{row.yaw_deg:.4f}", f"{row.pitch_deg:.4f}", f"{row.roll_deg:.4f}"]
    if row.has_accuracy:
        values += [f"{row.xy_accuracy_m:.3f}", f"{row.z_accuracy_m:.3f}"]
    return values


def odm_geo_txt(rows: Sequence[CameraPosition]) -> str:
    lines = ["EPSG:4326"] + [" ".join(_columns(row, lat_first=False)) for row in rows]
    return "\n".join(lines) + "\n"


def pix4d_csv(rows: Sequence[CameraPosition]) -> str:
    return "".join(",".join(_columns(row, lat_first=True)) + "\n" for row in rows)


def cameras_geojson(rows: Sequence[CameraPosition]) -> str:
    features = []
    for row in rows:
        coords = [row.lon_deg, row.lat_deg] + ([] if row.alt_amsl_m is None else [row.alt_amsl_m])
        props = {
            "name": row.name,
            "alt_amsl_m": row.alt_amsl_m,
            "yaw_deg": row.yaw_deg,
            "pitch_deg": row.pitch_deg,
            "roll_deg": row.roll_deg,
            "xy_accuracy_m": row.xy_accuracy_m,
            "z_accuracy_m": row.z_accuracy_m,
            "time_utc_s": row.time_utc_s,
            "status": row.status,
        }
        features.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": coords},
                "properties": props,
            }
        )
    # One feature per line: readable, and json's fast encoder (indent= uses the slow one).
    lines = ",\n".join(json.dumps(f, allow_nan=False) for f in features)
    return f'{{"type": "FeatureCollection", "features": [\n{lines}\n]}}\n'


def write_all(out_dir: str | os.PathLike[str], rows: Sequence[CameraPosition]) -> list[Path]:
    """Write geo.txt, the Pix4D CSV and the GeoJSON into ``out_dir``; returns their paths."""
    folder = Path(out_dir)
    return [
        atomic_write_text(folder / ODM_GEO_TXT, odm_geo_txt(rows)),
        atomic_write_text(folder / PIX4D_CSV, pix4d_csv(rows)),
        atomic_write_text(folder / GEOJSON, cameras_geojson(rows)),
    ]


def _parse(fields: list[str], lat_first: bool, where: str) -> CameraPosition:
    if len(fields) < 3:
        raise GeotagError(f"{where}: expected at least name, x, y; got {fields}")
    try:
        numbers = [float(v) for v in fields[1:]]
    except ValueError as error:
        raise GeotagError(f"{where}: not a number ({error})") from error
    if any(not math.isfinite(v) for v in numbers):
        raise GeotagError(f"{where}: values must be finite")
    lat, lon = (numbers[0], numbers[1]) if lat_first else (numbers[1], numbers[0])
    rest: list[float | None] = [*numbers[2:], None, None, None, None, None, None]
    return CameraPosition(
        name=fields[0],
        lat_deg=lat,
        lon_deg=lon,
        alt_amsl_m=rest[0],
        yaw_deg=rest[1],
        pitch_deg=rest[2],
        roll_deg=rest[3],
        xy_accuracy_m=rest[4],
        z_accuracy_m=rest[5],
    )


def read_odm_geo_txt(path: str | os.PathLike[str]) -> tuple[str, list[CameraPosition]]:
    """(CRS line, rows) of an OpenDroneMap geo.txt in lon/lat (EPSG:4326)."""
    lines = [ln for ln in Path(path).read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    if not lines:
        raise GeotagError(f"{path} is empty; a geo.txt starts with its CRS line")
    crs = lines[0].strip()
    if crs.upper() not in ("EPSG:4326", "WGS84"):
        raise GeotagError(f"{path}: CRS {crs!r} is not EPSG:4326; only lon/lat files are read")
    rows = [_parse(ln.split(), False, f"{path} line {k + 2}") for k, ln in enumerate(lines[1:])]
    return crs, rows


def read_pix4d_csv(path: str | os.PathLike[str]) -> list[CameraPosition]:
    """Rows of a Pix4D image geolocation CSV (no header; lat before lon)."""
    lines = [ln for ln in Path(path).read_text().splitlines() if ln.strip()]
    return [
        _parse([v.strip() for v in ln.split(",")], True, f"{path} line {k + 1}") for k, ln in enumerate(lines)
    ]
