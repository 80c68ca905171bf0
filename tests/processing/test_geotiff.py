"""GeoTIFF output read back with rasterio (a real reader): cells, transform, CRS and nodata."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import pytest
import rasterio
from pyproj import CRS

from processing.coverage import Grid
from processing.errors import ProcessingError
from processing.geotiff import utm_epsg, write_geotiff


def test_write_geotiff_round_trips_and_leaves_no_temporary(tmp_path: Path) -> None:
    crs = CRS.from_epsg(32613)
    grid = Grid.from_bounds((500_000.0, 4_400_000.0, 500_100.0, 4_400_050.0), 0.5, crs)
    counts = np.arange(grid.rows * grid.cols, dtype=np.uint16).reshape(grid.shape)
    path = write_geotiff(tmp_path / "out" / "coverage.tif", counts, grid)
    gsd = np.where(counts % 3 == 0, np.nan, counts / 7.0)
    write_geotiff(tmp_path / "out" / "gsd.tif", gsd, grid)
    assert sorted(os.listdir(tmp_path / "out")) == ["coverage.tif", "gsd.tif"]
    with rasterio.open(path) as ds:
        assert ds.crs.to_epsg() == 32613
        assert tuple(ds.transform)[:6] == (0.5, 0.0, 500_000.0, 0.0, -0.5, 4_400_050.0)
        assert ds.nodata is None
        np.testing.assert_array_equal(ds.read(1), counts)
    with rasterio.open(tmp_path / "out" / "gsd.tif") as ds:
        assert math.isnan(ds.nodata)
        np.testing.assert_array_equal(ds.read(1, masked=True).mask, np.isnan(gsd))
    with pytest.raises(ProcessingError, match="no CRS"):
        write_geotiff(tmp_path / "x.tif", counts, Grid.from_bounds((0, 0, 100, 50), 0.5))


def test_utm_epsg_is_the_zone_of_the_whole_box_or_none() -> None:
    # The zones are 6 deg wide from 180 W (zone 1); 326zz north of the equator, 327zz south.
    assert utm_epsg(-1.50, 42.0, -1.49, 42.1) == 32630
    assert utm_epsg(-81.61, 41.42, -81.60, 41.44) == 32617
    assert utm_epsg(151.2, -33.9, 151.3, -33.8) == 32756
    assert utm_epsg(-0.01, 42.0, 0.01, 42.1) is None  # two zones
    assert utm_epsg(10.0, -0.1, 10.1, 0.1) is None  # across the equator
    assert utm_epsg(10.0, 84.0, 10.1, 84.5) is None  # beyond the zones' limit
