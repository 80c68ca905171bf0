"""View-count raster of 5000 footprints over 2 km2 at 0.25 m cells: sfap against gdal_rasterize.

Setup (not timed): a 50-line x 100-station nadir block over 1414 x 1414 m (2 km2) at 100 m above
flat ground with a DJI Phantom 4 Pro (86 % forward, 81 % side overlap), yaw jittered by 3 deg and
pitch / roll by 2 deg so the footprints are not axis-aligned rectangles; footprints projected by
``processing.footprints.project_footprints`` (20 vertices each, timed and printed too) and written
as GeoJSON (coordinates written with repr, so GDAL reads the same doubles).

Timed as whole processes in alternating pairs (benchmarks/paired.py), both reading the same
GeoJSON file and writing an uncompressed UInt16 GeoTIFF:

- sfap: ``python -c`` reading footprints.geojson (json), ``processing.coverage.count_raster``,
  ``write_geotiff``: start-up and imports included;
- gdal: ``gdal_rasterize -add -burn 1 -init 0 -ot UInt16 -te ... -tr 0.25 0.25 footprints.geojson
  out.tif``.

Beside them, labelled as in-process: ``count_raster`` alone and with the GeoTIFF write, and
tracemalloc's peak during ``count_raster``. Memory that counts is each process's peak resident set
size (GNU time, /usr/bin/time), given against the raster's own size.

Checked: the count rasters of both processes are identical, cell by cell, with the same
geotransform.

Run: .venv/bin/python benchmarks/coverage_vs_gdal.py [--frames-per-line 100] [--lines 50] [--pairs 5]
     (needs gdal_rasterize: apt-get install gdal-bin; /usr/bin/time: apt-get install time)
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np
import rasterio
from pyproj import CRS

from planner.camera import Camera
from planner.geo import LocalFrame
from processing.coverage import Grid, count_raster
from processing.footprints import project_footprints
from processing.frames import AltitudeReference, AttitudeSource, Frames
from processing.geotiff import write_geotiff
from processing.ground import FlatGround

sys.path.insert(0, str(Path(__file__).resolve().parent))
from paired import Side, compare, machine

CAMERA = Camera(
    id="dji-phantom-4-pro",
    name="DJI Phantom 4 Pro",
    sensor_width_mm=13.2,
    sensor_height_mm=8.8,
    image_width_px=5472,
    image_height_px=3648,
    focal_length_mm=8.8,
)
SIDE_M = 1414.0
CELL_M = 0.25
#: sfap's side: the library, reading the same GeoJSON as gdal_rasterize.
SFAP_SCRIPT = """
import json, sys
import numpy as np
from pyproj import CRS
from processing.coverage import Grid, count_raster
from processing.geotiff import write_geotiff
west, north, cell, rows, cols, epsg = json.loads(sys.argv[3])
with open(sys.argv[1]) as handle:
    features = json.load(handle)["features"]
rings = np.array([f["geometry"]["coordinates"][0][:-1] for f in features], dtype=np.float64)
grid = Grid(west_m=west, north_m=north, cell_m=cell, rows=rows, cols=cols, crs=CRS.from_epsg(epsg))
write_geotiff(sys.argv[2], count_raster(rings, grid), grid, compress=None)
"""
HEIGHT_M = 100.0
WEST_M, SOUTH_M = 500_000.0, 4_400_000.0


def block(lines: int, stations: int, frame: LocalFrame) -> Frames:
    rng = np.random.default_rng(20261122)
    spacing, base = SIDE_M / (lines - 1), SIDE_M / (stations - 1)
    line = np.repeat(np.arange(lines), stations)
    k = np.tile(np.arange(stations), lines)
    north = line % 2 == 0
    x = WEST_M + line * spacing
    y = SOUTH_M + np.where(north, k, stations - 1 - k) * base
    n = x.size
    lon, lat = frame.to_lonlat(x, y)
    return Frames(
        name=tuple(f"IMG_{i:05d}.JPG" for i in range(n)),
        lon_deg=lon,
        lat_deg=lat,
        alt_m=np.full(n, HEIGHT_M),
        alt_reference=AltitudeReference.REL_HOME,
        yaw_deg=np.where(north, 0.0, 180.0) + rng.normal(0, 3, n),
        pitch_deg=rng.normal(0, 2, n),
        roll_deg=rng.normal(0, 2, n),
        attitude_source=AttitudeSource.PLAN,
        camera=CAMERA,
    )


def write_geojson(path: Path, rings: np.ndarray, epsg: int) -> None:
    features = []
    for ring in rings:
        coords = [[float(x), float(y)] for x, y in ring]
        coords.append(coords[0])
        features.append(
            {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [coords]}}
        )
    collection = {
        "type": "FeatureCollection",
        "crs": {"type": "name", "properties": {"name": f"urn:ogc:def:crs:EPSG::{epsg}"}},
        "features": features,
    }
    path.write_text(json.dumps(collection))


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--lines", type=int, default=50)
    parser.add_argument("--frames-per-line", type=int, default=100)
    parser.add_argument("--pairs", type=int, default=5)
    args = parser.parse_args()
    gdal = shutil.which("gdal_rasterize")
    if gdal is None:
        print("gdal_rasterize not found: apt-get install gdal-bin", file=sys.stderr)
        return 2
    version = subprocess.run([gdal, "--version"], capture_output=True, text=True, check=True).stdout.strip()

    epsg = 32613
    frame = LocalFrame.from_crs(CRS.from_epsg(epsg))
    frames = block(args.lines, args.frames_per_line, frame)
    ground = FlatGround(elevation_m=0.0, reference=AltitudeReference.REL_HOME)
    start = time.perf_counter()
    footprints = project_footprints(frames, frame, ground)
    project_s = time.perf_counter() - start
    grid = Grid.from_bounds((WEST_M, SOUTH_M, WEST_M + SIDE_M, SOUTH_M + SIDE_M), CELL_M, frame.crs)
    raster_bytes = grid.rows * grid.cols * 2

    with tempfile.TemporaryDirectory(prefix="sfap-bench-") as tmp:
        work = Path(tmp)
        vector = work / "footprints.geojson"
        write_geojson(vector, footprints.xy_m, epsg)

        gdal_out, sfap_out = work / "gdal.tif", work / "sfap_process.tif"
        xmin, ymin, xmax, ymax = grid.bounds
        command = [
            gdal, "-q", "-add", "-burn", "1", "-init", "0", "-ot", "UInt16",
            "-te", repr(xmin), repr(ymin), repr(xmax), repr(ymax),
            "-tr", repr(CELL_M), repr(CELL_M), str(vector), str(gdal_out),
        ]  # fmt: skip
        grid_args = json.dumps([grid.west_m, grid.north_m, grid.cell_m, grid.rows, grid.cols, epsg])
        sfap_side = Side(
            "sfap (python -c, GeoJSON in)",
            [sys.executable, "-c", SFAP_SCRIPT, str(vector), str(sfap_out), grid_args],
            before=lambda: sfap_out.unlink(missing_ok=True),
        )
        gdal_side = Side("gdal_rasterize", command, before=lambda: gdal_out.unlink(missing_ok=True))
        result = compare("coverage raster, process against process", sfap_side, gdal_side, pairs=args.pairs)
        with rasterio.open(gdal_out) as dataset:
            peer = dataset.read(1)
            same_transform = tuple(dataset.transform)[:6] == tuple(grid.transform)[:6]
        with rasterio.open(sfap_out) as dataset:
            fresh_identical = bool(np.array_equal(dataset.read(1), peer))
            same_transform = same_transform and tuple(dataset.transform)[:6] == tuple(grid.transform)[:6]

        tracemalloc.start()
        start = time.perf_counter()
        counts = count_raster(footprints.xy_m, grid)
        sfap_s = time.perf_counter() - start
        _, sfap_peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        start = time.perf_counter()
        write_geotiff(work / "sfap.tif", counts, grid, compress=None)
        sfap_write_s = time.perf_counter() - start

    identical = peer.shape == counts.shape and bool(np.array_equal(peer, counts)) and fresh_identical
    differing = int(np.count_nonzero(peer != counts)) if peer.shape == counts.shape else -1
    cells_m = grid.rows * grid.cols / 1e6
    print(
        f"block: {len(frames)} frames, {SIDE_M:.0f} x {SIDE_M:.0f} m, {grid.cols} x {grid.rows} cells "
        f"of {CELL_M} m ({cells_m:.1f} M cells, {raster_bytes / 2**20:.1f} MiB as uint16)"
    )
    vertices = footprints.xy_m.shape[1]
    print(f"footprints: project_footprints {project_s * 1000:.0f} ms ({vertices} vertices each)")
    print(f"views per cell: median {np.median(counts):.0f}, max {counts.max()}")
    print(machine())
    print(version)
    print(result.report())
    for side in (result.sfap, result.peer):
        rss = max(x.max_rss_mib for x in side.samples)
        print(f"  {side.label}: peak RSS {rss:.1f} MiB = {rss * 2**20 / raster_bytes:.2f} x the raster")
    print(
        f"in process (labelled: no start-up, no reading): count_raster {sfap_s:.3f} s, "
        f"+ GeoTIFF write {sfap_s + sfap_write_s:.3f} s; tracemalloc peak "
        f"{sfap_peak / 2**20:.1f} MiB = {sfap_peak / raster_bytes:.2f} x the raster"
    )
    print(f"counts identical: {identical} ({differing} cells differ); same geotransform: {same_transform}")
    print("command: " + " ".join(command))
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
