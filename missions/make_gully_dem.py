"""Writes bardenas-gully-dem.tif: a SYNTHETIC elevation model for the terrain example
(bardenas-gully-terrain.toml). It is not survey data: a gentle eastward slope (8 %) and a
40 m hill, in UTM 30N at 5 m cells, float32, deflate-compressed.

    .venv/bin/python missions/make_gully_dem.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rasterio
from rasterio.transform import from_origin

from planner.geo import LocalFrame


def main() -> None:
    frame = LocalFrame.utm_for(-1.483, 42.203)
    x0, y0 = frame.to_xy(-1.4885, 42.2055)  # north-west corner
    cell_m, rows, cols = 5.0, 140, 200
    xs = float(x0) + (np.arange(cols) + 0.5) * cell_m
    ys = float(y0) - (np.arange(rows) + 0.5) * cell_m
    x, y = np.meshgrid(xs, ys)
    hill_x, hill_y = frame.to_xy(-1.4830, 42.2030)
    hill = 40.0 * np.exp(-((x - hill_x) ** 2 + (y - hill_y) ** 2) / (2 * 120.0**2))
    z = 300.0 + 0.08 * (x - float(x0)) + hill
    out = Path(__file__).with_name("bardenas-gully-dem.tif")
    profile = {
        "driver": "GTiff", "height": rows, "width": cols, "count": 1, "dtype": "float32",
        "crs": frame.crs.to_wkt(), "transform": from_origin(float(x0), float(y0), cell_m, cell_m),
        "nodata": -9999.0, "compress": "deflate",
    }  # fmt: skip
    with rasterio.open(out, "w", **profile) as dataset:
        dataset.write(z.astype("float32"), 1)


if __name__ == "__main__":
    main()
