"""Geotag 1000 frames with `sfap geotag` and with `exiftool -geotag` on the same images and track.

Setup (not timed): one small real JPEG (a 640 x 480 reduction of a garfield frame, or noise when
the data are absent) copied 1000 times with capture times 2 s apart; a 5 Hz position track of
a lawnmower survey over those 2000 s, written as an exiftool CSV track. Then, each timed once,
each as the command a user would run (a fresh process, the time includes start-up):

- ``sfap geotag IN --log track.csv -o OUT_SFAP --offset-s 0 --no-progress``
- ``exiftool -geotag track.csv '-Geotime<${SubSecDateTimeOriginal}+00:00' -o OUT_EXIF/ IN``

Checked: every output's compressed image data equals its input's (pixels identical) for both
tools, and the positions written by the two agree (largest difference, metres).

Run: .venv/bin/python benchmarks/geotag_vs_exiftool.py [--count 1000] [--keep DIR]
"""

from __future__ import annotations

import argparse
import io
import math
import shutil
import subprocess
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pyexiv2
from PIL import Image

from acquisition import exif
from planner.geo import LocalFrame, geodesic_distance_m

GARFIELD = (
    Path(__file__).resolve().parents[2]
    / "shared"
    / "data"
    / "garfield_rgb"
    / "IMG_161122_163234_0000_RGB.JPG"
)
START_S = 1_700_000_000.0
INTERVAL_S = 2.0


def base_jpeg() -> bytes:
    if GARFIELD.exists():
        image = Image.open(GARFIELD).convert("RGB").resize((640, 480))
    else:
        pixels = np.random.default_rng(0).integers(0, 256, size=(480, 640, 3), dtype=np.uint8)
        image = Image.fromarray(pixels)
    buffer = io.BytesIO()
    image.save(buffer, format="JPEG", quality=85)
    return buffer.getvalue()


def make_images(folder: Path, count: int) -> None:
    data = base_jpeg()
    folder.mkdir(parents=True)
    for k in range(count):
        t = START_S + INTERVAL_S * k + 0.137
        whole = math.floor(t)
        image = pyexiv2.ImageData(data)
        image.modify_exif(
            {
                "Exif.Image.Make": "Bench",
                "Exif.Image.Model": "B1",
                "Exif.Photo.DateTimeOriginal": datetime.fromtimestamp(whole, tz=UTC).strftime(
                    "%Y:%m:%d %H:%M:%S"
                ),
                "Exif.Photo.SubSecTimeOriginal": f"{round((t - whole) * 1000):03d}",
            }
        )
        (folder / f"IMG_{k:05d}.JPG").write_bytes(image.get_bytes())
        image.close()


def make_track(path: Path, count: int) -> None:
    """A lawnmower path at 10 m/s, 5 Hz, covering every capture time."""
    frame = LocalFrame.utm_for(-93.0, 42.0)
    x0, y0 = (float(v) for v in frame.to_xy(-93.0, 42.0))
    t = np.arange(START_S - 10.0, START_S + INTERVAL_S * count + 10.0, 0.2)
    s = 10.0 * (t - t[0])
    line_m = 500.0
    line = np.floor(s / line_m)
    along = s - line * line_m
    y = np.where(line % 2 == 0, along, line_m - along) + y0
    x = x0 + 40.0 * line
    lon, lat = frame.to_lonlat(x, y)
    alt = 300.0 + 5.0 * np.sin(t / 60.0)
    lines = ["GPSDateTime,GPSLatitude,GPSLongitude,GPSAltitude"]
    for tk, la, lo, al in zip(t, lat, lon, alt, strict=True):
        moment = datetime.fromtimestamp(float(tk), tz=UTC)
        stamp = moment.strftime("%Y:%m:%d %H:%M:%S.") + f"{moment.microsecond // 1000:03d}Z"
        lines.append(f"{stamp},{la:.9f},{lo:.9f},{al:.3f}")
    path.write_text("\n".join(lines) + "\n")


def timed(command: list[str]) -> float:
    start = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    elapsed = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"{command[0]} failed ({done.returncode}):\n{done.stderr[-2000:]}")
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--count", type=int, default=1000)
    parser.add_argument("--keep", type=Path, default=None, help="work folder to keep (default: temporary)")
    args = parser.parse_args()
    exiftool = shutil.which("exiftool")
    if exiftool is None:
        sys.exit("exiftool is not installed (Debian: apt-get install libimage-exiftool-perl)")
    sfap = Path(sys.executable).with_name("sfap")
    work = args.keep or Path(tempfile.mkdtemp(prefix="geotag-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    images, track = work / "in", work / "track.csv"
    out_sfap, out_exif = work / "out_sfap", work / "out_exiftool"
    for folder in (images, out_sfap, out_exif):
        shutil.rmtree(folder, ignore_errors=True)
    make_images(images, args.count)
    make_track(track, args.count)

    sfap_s = timed(
        [
            str(sfap),
            "geotag",
            str(images),
            "--log",
            str(track),
            "-o",
            str(out_sfap),
            "--offset-s",
            "0",
            "--no-progress",
        ]
    )
    exif_s = timed(
        [
            exiftool,
            "-q",
            "-geotag",
            str(track),
            "-Geotime<${SubSecDateTimeOriginal}+00:00",
            "-o",
            f"{out_exif}/",
            str(images),
        ]
    )

    names = sorted(p.name for p in images.iterdir())
    same_sfap = sum(
        exif.compressed_image_data(out_sfap / n) == exif.compressed_image_data(images / n) for n in names
    )
    same_exif = sum(
        exif.compressed_image_data(out_exif / n) == exif.compressed_image_data(images / n) for n in names
    )
    worst_m = worst_alt_m = 0.0
    for n in names:
        a, b = exif.read_tags(out_sfap / n), exif.read_tags(out_exif / n)
        assert a.gps_lat_deg is not None and b.gps_lat_deg is not None
        assert a.gps_lon_deg is not None and b.gps_lon_deg is not None
        worst_m = max(
            worst_m, geodesic_distance_m(a.gps_lat_deg, a.gps_lon_deg, b.gps_lat_deg, b.gps_lon_deg)
        )
        worst_alt_m = max(worst_alt_m, abs((a.gps_alt_amsl_m or 0.0) - (b.gps_alt_amsl_m or 0.0)))

    print(f"images: {len(names)} x {(images / names[0]).stat().st_size} bytes; track: {track}")
    print(f"sfap geotag:     {sfap_s:7.2f} s  ({1000 * sfap_s / len(names):.2f} ms per image)")
    print(f"exiftool -geotag: {exif_s:7.2f} s  ({1000 * exif_s / len(names):.2f} ms per image)")
    print(f"speed-up (exiftool time / sfap time): {exif_s / sfap_s:.2f}x")
    print(f"pixels identical: sfap {same_sfap}/{len(names)}, exiftool {same_exif}/{len(names)}")
    print(f"largest position difference sfap vs exiftool: {worst_m:.4f} m, altitude {worst_alt_m:.4f} m")
    if args.keep is None:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
