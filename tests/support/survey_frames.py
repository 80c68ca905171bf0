"""Tiny real JPEGs with a capture time, for the end-to-end geotag test."""

from __future__ import annotations

import io
import math
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pyexiv2
from PIL import Image

_BASE: bytes | None = None


def _base_jpeg() -> bytes:
    global _BASE
    if _BASE is None:
        pixels = np.random.default_rng(0).integers(0, 256, size=(24, 32, 3), dtype=np.uint8)
        buffer = io.BytesIO()
        Image.fromarray(pixels).save(buffer, format="JPEG", quality=85)
        _BASE = buffer.getvalue()
    return _BASE


def write_frame(path: Path, capture_s: float) -> Path:
    """A JPEG whose DateTimeOriginal + SubSecTimeOriginal (ms) say ``capture_s`` (camera clock,
    written as the camera's local wall time with no zone, like most cameras)."""
    whole = math.floor(capture_s)
    millis = round((capture_s - whole) * 1000)
    if millis == 1000:
        whole, millis = whole + 1, 0
    moment = datetime.fromtimestamp(whole, tz=UTC)
    image = pyexiv2.ImageData(_base_jpeg())
    image.modify_exif(
        {
            "Exif.Image.Make": "TestCam",
            "Exif.Image.Model": "T1",
            "Exif.Photo.DateTimeOriginal": moment.strftime("%Y:%m:%d %H:%M:%S"),
            "Exif.Photo.SubSecTimeOriginal": f"{millis:03d}",
        }
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(image.get_bytes())
    image.close()
    return path
