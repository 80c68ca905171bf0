"""View-count raster of 5000 footprints over 2 km2 at 0.25 m cells: sfap against gdal_rasterize.

Setup (not timed): a 50-line x 100-station nadir block over 1414 x 1414 m (2 km2) at 100 m above
flat ground with a DJI Phantom 4 Pro (86 % forward, 81 % side overlap), yaw jittered by 3 deg and
pitch / roll by 2 deg so the footprints are not axis-aligned rectangles; footprints projected by
``processing.footprints.project_footprints`` (20 vertices each, timed and printed too) and written
as GeoJSON (coordinates written with repr, so GDAL reads the same doubles).

Timed once each:

- sfap: ``processing.coverage.count_raster`` in this process, and the same plus writing the
  GeoTIFF uncompressed (what gdal_rasterize does);
- gdal: ``gdal_rasterize -add -burn 1 -init 0 -ot UInt16 -te ... -tr 0.25 0.25 footprints.geojson
  out.tif`` as a fresh process (includes its start-up and reading the GeoJSON).

Checked: the count rasters are identical, cell by cell. Memory: tracemalloc's peak during
``count_raster`` (numpy reports its buffers to tracemalloc) against the raster's own size, and
the maximum resident set size of both fresh processes (GNU time, /usr/bin/time).

Run: .venv/bin/python benchmarks/coverage_vs_gdal.py [--frames-per-line 100] [--lines 50]
     (needs gdal_rasterize: apt-get install gdal-bin)
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
from processing.coverage import Grid, count_raster, write_geotiff
from processing.footprints import project_footprints
from processing.frames import AltitudeReference, AttitudeSource, Frames
from processing.ground import FlatGround

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
#: GNU time prints the command's own maximum resident set size (KiB) on stderr. A child spawned
#: straight from this (large) Python process would report this process's size instead: the
#: kernel records the address space a child had before its exec.
TIME = ["/usr/bin/time", "-f", "%M"]
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

        # The peer first, so the children's maximum resident set size is its own.
        out = work / "gdal.tif"
        xmin, ymin, xmax, ymax = grid.bounds
        command = [
            gdal, "-q", "-add", "-burn", "1", "-init", "0", "-ot", "UInt16",
            "-te", repr(xmin), repr(ymin), repr(xmax), repr(ymax),
            "-tr", repr(CELL_M), repr(CELL_M), str(vector), str(out),
        ]  # fmt: skip
        start = time.perf_counter()
        gdal_run = subprocess.run(TIME + command, check=True, capture_output=True, text=True)
        gdal_s = time.perf_counter() - start
        gdal_rss_kib = int(gdal_run.stderr.split()[-1])
        with rasterio.open(out) as dataset:
            peer = dataset.read(1)
            same_transform = tuple(dataset.transform)[:6] == tuple(grid.transform)[:6]

        tracemalloc.start()
        start = time.perf_counter()
        counts = count_raster(footprints.xy_m, grid)
        sfap_s = time.perf_counter() - start
        _, sfap_peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        start = time.perf_counter()
        write_geotiff(work / "sfap.tif", counts, grid, compress=None)
        sfap_write_s = time.perf_counter() - start

        # sfap as a fresh process, like the peer: start-up, imports, reading the footprints.
        np.save(work / "footprints.npy", footprints.xy_m)
        script = (
            "import sys, numpy as np; from pyproj import CRS; "
            "from processing.coverage import Grid, count_raster, write_geotiff; "
            f"g = Grid(west_m={grid.west_m!r}, north_m={grid.north_m!r}, cell_m={grid.cell_m!r}, "
            f"rows={grid.rows}, cols={grid.cols}, crs=CRS.from_epsg({epsg})); "
            "c = count_raster(np.load(sys.argv[1]), g); write_geotiff(sys.argv[2], c, g, compress=None)"
        )
        start = time.perf_counter()
        child = subprocess.run(
            [*TIME, sys.executable, "-c", script, str(work / "footprints.npy"), str(work / "fresh.tif")],
            check=True, capture_output=True, text=True,
        )  # fmt: skip
        fresh_s = time.perf_counter() - start
        fresh_rss_kib = int(child.stderr.split()[-1])
        with rasterio.open(work / "fresh.tif") as dataset:
            fresh_identical = bool(np.array_equal(dataset.read(1), peer))

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
    print(
        f"sfap count_raster (in process): {sfap_s:.3f} s, peak traced memory "
        f"{sfap_peak / 2**20:.1f} MiB = {sfap_peak / raster_bytes:.2f} x the raster"
    )
    print(
        f"sfap count_raster + GeoTIFF:    {sfap_s + sfap_write_s:.3f} s "
        f"(uncompressed GeoTIFF write {sfap_write_s:.3f} s)"
    )
    print(
        f"sfap fresh process (start-up, load, count, GeoTIFF): {fresh_s:.3f} s, "
        f"max RSS {fresh_rss_kib / 1024:.1f} MiB"
    )
    print(f"{version}: gdal_rasterize -add: {gdal_s:.3f} s, max RSS {gdal_rss_kib / 1024:.1f} MiB")
    print(
        f"ratio gdal / sfap: {gdal_s / sfap_s:.1f} x (count only), "
        f"{gdal_s / (sfap_s + sfap_write_s):.1f} x (count + GeoTIFF), "
        f"{gdal_s / fresh_s:.1f} x (fresh process)"
    )
    print(f"counts identical: {identical} ({differing} cells differ); same geotransform: {same_transform}")
    print("command: " + " ".join(command))
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
