"""Geotag frames with `sfap geotag`, with `exiftool -geotag`, and copy them with `cp -r` (the floor).

Setup (not timed): a base frame made from a real Parrot Sequoia frame (../shared/data/garfield_rgb:
its EXIF with GPS, maker data and Pix4D XMP kept), re-encoded at the size of the chosen set, then
copied COUNT times, each copy with its own capture time (2 s apart); a 5 Hz position track of a
lawnmower survey over that time, as an exiftool CSV track. The sets:

- ``small``: 1000 x 640 x 480 px (about 70 KB)
- ``1mb``: 1000 x 2736 x 1824 px, quality 90 (about 1.1 MB)
- ``full``: 300 x 4608 x 3456 px, quality 92 (about 3.0 MB, the Sequoia's own size)
- ``raw``: 20 x 8192 x 6144 px with sensor-like noise, quality 95 (about 23 MB)

Timed, each as the whole process a user runs (start-up included), in alternating pairs
(benchmarks/paired.py), into a fresh output folder each time:

- ``sfap geotag IN --log track.csv -o OUT --offset-s 0 --no-progress``
- ``exiftool -q -geotag track.csv '-Geotime<${SubSecDateTimeOriginal}+00:00' -o OUT/ IN``
- ``cp -r IN OUT``

With ``--baseline DIR`` (a tree of another commit, e.g. main: ``git archive main | tar -x -C DIR``,
then ``python -m compileall -q DIR/acquisition DIR/planner DIR/sfap``), also this tree's ``sfap
geotag`` against DIR's, each run as ``env PYTHONPATH=TREE sfap geotag ...`` in alternating pairs,
and every output file of the two compared byte for byte.

Checked after the runs: every output's compressed image data (SOS to EOI) equals its input's, for
both tools, and the positions the two tools wrote agree (largest difference, metres).

Run: .venv/bin/python benchmarks/geotag_vs_exiftool.py --set full [--pairs 5]
[--against both|exiftool|cp|none] [--baseline DIR] [--count N] [--keep DIR]
"""

from __future__ import annotations

import argparse
import filecmp
import io
import math
import os
import shutil
import statistics
import sys
import tempfile
import time
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pyexiv2
from PIL import Image

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from paired import Side, compare, machine

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

#: name -> (count, width px, height px, JPEG quality, noise amplitude)
SETS = {
    "small": (1000, 640, 480, 85, 0),
    "1mb": (1000, 2736, 1824, 90, 0),
    "full": (300, 4608, 3456, 92, 0),
    "raw": (20, 8192, 6144, 95, 12),
}


def _header_and_scan(data: bytes) -> tuple[bytes, bytes]:
    """(everything before the first SOS marker, the rest) of a JPEG."""
    pos = 2
    while True:
        marker = data[pos + 1]
        if marker == 0xDA:
            return data[:pos], data[pos:]
        pos += 2 + int.from_bytes(data[pos + 2 : pos + 4], "big")


def base_frame(width: int, height: int, quality: int, noise: int) -> bytes:
    """The Sequoia frame's pixels at ``width`` x ``height``, with its own metadata segments."""
    original = GARFIELD.read_bytes()
    image = Image.open(io.BytesIO(original)).convert("RGB")
    if image.size != (width, height):
        image = image.resize((width, height))
    if noise:
        pixels = np.asarray(image).astype(np.int16)
        pixels += np.random.default_rng(0).integers(-noise, noise + 1, size=pixels.shape, dtype=np.int16)
        image = Image.fromarray(np.clip(pixels, 0, 255).astype(np.uint8))
    buffer = io.BytesIO()
    image.save(buffer, format="JPEG", quality=quality)
    header, _ = _header_and_scan(original)
    new_header, scan = _header_and_scan(buffer.getvalue())
    # the Sequoia's APP1 segments (EXIF, XMP), then the new encoding's tables and scan
    app_segments = header[2:]
    pos, kept = 2, []
    while pos < len(new_header):
        length = int.from_bytes(new_header[pos + 2 : pos + 4], "big")
        if not 0xE0 <= new_header[pos + 1] <= 0xEF:
            kept.append(new_header[pos : pos + 2 + length])
        pos += 2 + length
    data = b"\xff\xd8" + app_segments + b"".join(kept) + scan
    stub = pyexiv2.ImageData(data[: len(data) - len(scan)] + scan[:14] + b"\x00\xff\xd9")
    stub.modify_exif({"Exif.Photo.PixelXDimension": str(width), "Exif.Photo.PixelYDimension": str(height)})
    fixed, _ = _header_and_scan(stub.get_bytes())
    stub.close()
    return fixed + scan


def make_images(folder: Path, count: int, data: bytes) -> None:
    """``count`` copies of ``data``, capture times 2 s apart (only the header is rewritten)."""
    header, scan = _header_and_scan(data)
    folder.mkdir(parents=True)
    for k in range(count):
        t = START_S + INTERVAL_S * k + 0.137
        whole = math.floor(t)
        image = pyexiv2.ImageData(header + scan[:14] + b"\x00\xff\xd9")
        image.modify_exif(
            {
                "Exif.Photo.DateTimeOriginal": datetime.fromtimestamp(whole, tz=UTC).strftime(
                    "%Y:%m:%d %H:%M:%S"
                ),
                "Exif.Photo.SubSecTimeOriginal": f"{round((t - whole) * 1000):03d}",
            }
        )
        new_header, _ = _header_and_scan(image.get_bytes())
        image.close()
        (folder / f"IMG_{k:05d}.JPG").write_bytes(new_header + scan)


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


#: Seconds to wait after removing the previous run's output (``--settle-s``). On this machine (a
#: virtual machine that hands freed memory back to its host within about a second), a copy that
#: starts at once gets the pages just freed, still mapped, and one that starts later pays for
#: fresh pages: the same ``cp -r`` of 900 MB took 0.32-0.40 s right after the removal and
#: 0.32-1.37 s (three runs in four about 1.2 s) 0.3 s after it. cp starts copying at once, and
#: any program that reads its input first does not: without a wait the floor is flattered.
SETTLE_S = 2.0


def _remover(folder: Path, settle_s: float = 0.0):  # type: ignore[no-untyped-def]
    def remove() -> None:
        shutil.rmtree(folder, ignore_errors=True)
        os.sync()  # the previous run's dirty pages are not the next run's bill
        time.sleep(settle_s)

    return remove


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--set", choices=sorted(SETS), default="full")
    parser.add_argument("--count", type=int, default=None, help="frames (default: the set's)")
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument(
        "--against", choices=("both", "exiftool", "cp", "none"), default="both", help="which peers to time"
    )
    parser.add_argument(
        "--baseline",
        type=Path,
        default=None,
        help="a tree of another commit (its modules compiled): time this sfap against that one too",
    )
    parser.add_argument("--keep", type=Path, default=None, help="work folder to keep (default: temporary)")
    parser.add_argument(
        "--settle-s",
        type=float,
        default=SETTLE_S,
        help=f"wait after removing a run's output, before the next run (default {SETTLE_S} s; 0: none)",
    )
    args = parser.parse_args()
    exiftool = shutil.which("exiftool")
    if exiftool is None:
        sys.exit("exiftool is not installed (Debian: apt-get install libimage-exiftool-perl)")
    default_count, width, height, quality, noise = SETS[args.set]
    count = args.count or default_count
    sfap = Path(sys.executable).with_name("sfap")
    work = args.keep or Path(tempfile.mkdtemp(prefix="geotag-bench-"))
    work.mkdir(parents=True, exist_ok=True)
    images, track = work / "in", work / "track.csv"
    out_sfap, out_exif, out_cp = work / "out_sfap", work / "out_exiftool", work / "out_cp"
    for folder in (images, out_sfap, out_exif, out_cp):
        shutil.rmtree(folder, ignore_errors=True)
    make_images(images, count, base_frame(width, height, quality, noise))
    make_track(track, count)
    names = sorted(p.name for p in images.iterdir())
    size = (images / names[0]).stat().st_size

    sfap_side = Side(
        "sfap geotag",
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
        ],
        before=_remover(out_sfap, args.settle_s),
    )
    exif_side = Side(
        "exiftool -geotag",
        [
            exiftool,
            "-q",
            "-geotag",
            str(track),
            "-Geotime<${SubSecDateTimeOriginal}+00:00",
            "-o",
            f"{out_exif}/",
            str(images),
        ],
        before=_remover(out_exif, args.settle_s),
    )
    cp_side = Side("cp -r", ["cp", "-r", str(images), str(out_cp)], before=_remover(out_cp, args.settle_s))
    print(machine())
    print(f"{args.set}: {count} frames x {size:,} bytes ({width} x {height} px); track {track}")
    if args.against in ("both", "exiftool"):
        against_exif = compare(f"sfap vs exiftool ({args.set})", sfap_side, exif_side, pairs=args.pairs)
        print(against_exif.report(), flush=True)
        sfap_side.samples.clear()
    else:  # the checks below compare with exiftool's output: one run of it
        exif_side.run()
    if args.against in ("both", "cp"):
        against_cp = compare(f"sfap vs cp -r ({args.set})", sfap_side, cp_side, pairs=args.pairs)
        print(against_cp.report(), flush=True)
    if args.baseline is not None:
        against_baseline(args, images, track, work, sfap)
    if not out_sfap.exists():
        sfap_side.run()

    for out in (out_sfap, out_exif):  # the last runs' outputs are still there
        assert sorted(p.name for p in out.glob("*.JPG")) == names, out
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
    print(f"image data identical: sfap {same_sfap}/{len(names)}, exiftool {same_exif}/{len(names)}")
    print(f"largest position difference sfap vs exiftool: {worst_m:.4f} m, altitude {worst_alt_m:.4f} m")
    in_process(images, out_sfap, names, work)
    if args.keep is None:
        shutil.rmtree(work, ignore_errors=True)


def against_baseline(args: argparse.Namespace, images: Path, track: Path, work: Path, sfap: Path) -> None:
    """This tree's sfap against the baseline tree's, paired; then one more run of each into the
    same folder (the report names it), their outputs compared file by file."""
    here = Path(__file__).resolve().parents[1]
    baseline = args.baseline.resolve()
    out, kept = work / "out_pair", work / "out_baseline"

    def side(tree: Path) -> Side:
        command = ["env", f"PYTHONPATH={tree}", str(sfap), "geotag", str(images), "--log", str(track)]
        command += ["-o", str(out), "--offset-s", "0", "--no-progress"]
        return Side(f"sfap geotag ({tree.name})", command, before=_remover(out, args.settle_s))

    this, base = side(here), side(baseline)
    result = compare(f"sfap vs sfap at {baseline} ({args.set})", this, base, pairs=args.pairs)
    print(result.report(), flush=True)
    base.run()
    _remover(kept)()
    out.rename(kept)
    this.run()
    names = sorted(p.name for p in out.iterdir())
    same_names = names == sorted(p.name for p in kept.iterdir())
    _, mismatch, errors = filecmp.cmpfiles(out, kept, names, shallow=False)
    print(
        f"outputs of the two trees: {len(names) - len(mismatch) - len(errors)}/{len(names)} files "
        f"byte-identical{'' if same_names else ' (the folders hold different names)'}"
        + (f"; differ: {', '.join((mismatch + errors)[:5])}" if mismatch or errors else "")
    )
    for folder in (out, kept):
        _remover(folder)()


def _copy_floor(images: Path, names: list[str], out: Path) -> None:
    """What cp does for each file: one in-kernel copy of the whole file."""
    for n in names:
        with open(images / n, "rb") as src, open(out / n, "wb") as dst:
            size = os.fstat(src.fileno()).st_size
            done = 0
            while done < size:
                done += os.copy_file_range(src.fileno(), dst.fileno(), size - done, done)


def in_process(images: Path, tagged: Path, names: list[str], work: Path, rounds: int = 3) -> None:
    """Labelled in-process figures: exif.write_geotags (1 and 2 threads) on the same frames and
    tags as sfap wrote, against a copy loop in the same process (the part exif.py owns, without
    start-up, log reading and matching)."""
    jobs = []
    for n in names:
        t = exif.read_tags(tagged / n)
        assert t.gps_lat_deg is not None and t.gps_lon_deg is not None
        tag = exif.GeoTag(lat_deg=t.gps_lat_deg, lon_deg=t.gps_lon_deg, alt_amsl_m=t.gps_alt_amsl_m)
        jobs.append((n, tag))
    timings: dict[str, list[float]] = {}
    for _ in range(rounds):
        for label in ("copy loop (floor)", "write_geotags, 1 thread", "write_geotags, 2 threads"):
            out = work / "in_process"
            _remover(out)()
            out.mkdir()
            start = time.perf_counter()
            if label.startswith("copy"):
                _copy_floor(images, names, out)
            else:
                exif.write_geotags(
                    [exif.GeotagJob(src=str(images / n), dst=str(out / n), tag=t) for n, t in jobs],
                    workers=1 if "1 thread" in label else 2,
                    atomic=False,
                )
            timings.setdefault(label, []).append(time.perf_counter() - start)
    _remover(work / "in_process")()
    floor = statistics.median(timings["copy loop (floor)"])
    print(
        f"in process (labelled; {rounds} rounds, median; "
        f"load {' '.join(format(v, '.2f') for v in os.getloadavg())}):"
    )
    for label, values in timings.items():
        median = statistics.median(values)
        print(f"  {label:<28} {median:7.3f} s  ({median / floor:.2f} x the copy loop)")


if __name__ == "__main__":
    main()
