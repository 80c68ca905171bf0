"""A synthetic survey block for the hand-off tests: small real JPEGs on a grid of nadir stations,
geotagged with acquisition.exif (GPS, Pix4D attitude and accuracy tags)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pyexiv2
from PIL import Image
from pyproj import Geod

from acquisition.exif import GeoTag, geotag_bytes

_GEOD = Geod(ellps="WGS84")

# Synthetic camera: 320 x 240 px of 0.02 mm (6.4 x 4.8 mm sensor), 4 mm lens; at 100 m a nadir
# footprint is 160 m east-west (image width, yaw 0) by 120 m north-south.
W_PX, H_PX, PITCH_MM, F_MM, HEIGHT_M = 320, 240, 0.02, 4.0, 100.0
FOOT_X_M = W_PX * PITCH_MM / F_MM * HEIGHT_M
FOOT_Y_M = H_PX * PITCH_MM / F_MM * HEIGHT_M
LAT0, LON0 = 45.0, 7.0


def jpeg(make: str = "TestCam", model: str = "Grid1") -> bytes:
    pixels = np.random.default_rng(0).integers(0, 256, size=(H_PX, W_PX, 3), dtype=np.uint8)
    buffer = io.BytesIO()
    Image.fromarray(pixels).save(buffer, format="JPEG", quality=85)
    image = pyexiv2.ImageData(buffer.getvalue())
    image.modify_exif(
        {
            "Exif.Image.Make": make,
            "Exif.Image.Model": model,
            "Exif.Photo.FocalLength": f"{int(F_MM * 100)}/100",
            "Exif.Photo.FocalPlaneXResolution": f"{int(1 / PITCH_MM * 1000)}/1000",
            "Exif.Photo.FocalPlaneYResolution": f"{int(1 / PITCH_MM * 1000)}/1000",
            "Exif.Photo.FocalPlaneResolutionUnit": "4",
        }
    )
    data = image.get_bytes()
    image.close()
    return bytes(data)


def grid(
    folder: Path, *, lines: int, per_line: int, dx_m: float, dy_m: float, positioned: bool = True
) -> list[tuple[str, float, float, int]]:
    """Lines flown north then south (boustrophedon), nadir, image top north. Returns (name, x, y, line)."""
    folder.mkdir(parents=True, exist_ok=True)
    base = jpeg()
    out = []
    k = 0
    for line in range(lines):
        ys = [s * dy_m for s in range(per_line)]
        for y in ys if line % 2 == 0 else ys[::-1]:
            x = line * dx_m
            name = f"F{k:03d}.jpg"
            lon, lat, _ = _GEOD.fwd(LON0, LAT0, 90.0, x) if x else (LON0, LAT0, 0)
            lon, lat, _ = _GEOD.fwd(lon, lat, 0.0, y) if y else (lon, lat, 0)
            tag = GeoTag(
                lat_deg=lat,
                lon_deg=lon,
                alt_amsl_m=HEIGHT_M,
                time_utc_s=1.7e9 + 3.0 * k,
                yaw_deg=0.0,
                pitch_deg=0.0,
                roll_deg=0.0,
                xy_accuracy_m=1.5,
                z_accuracy_m=3.0,
            )
            (folder / name).write_bytes(geotag_bytes(base, tag) if positioned else base)
            out.append((name, float(x), float(y), line))
            k += 1
    return out
