"""GeoTIFF output of the check's rasters (views per cell, GSD): written atomically, in the UTM
zone that holds the grid when there is one (:func:`utm_epsg`), else in the grid's own CRS."""

from __future__ import annotations

import logging
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import rasterio
import rasterio.features
import rasterio.windows
from numpy.typing import NDArray
from pyproj import CRS
from rasterio.transform import Affine

from .coverage import Grid
from .errors import ProcessingError

logger = logging.getLogger(__name__)

#: Rows written to a GeoTIFF at a time.
_WRITE_ROWS = 256


def utm_epsg(
    west_lon_deg: float, south_lat_deg: float, east_lon_deg: float, north_lat_deg: float
) -> int | None:
    """The EPSG code of the WGS84 UTM zone that holds the whole box (326xx north of the equator,
    327xx south), or None when the box spans two zones, the equator, or lies beyond 84 N / 80 S
    (the zones' limits; Norway's and Svalbard's exceptions are not applied)."""
    if not (south_lat_deg >= -80.0 and north_lat_deg <= 84.0):
        return None
    if south_lat_deg < 0.0 < north_lat_deg:
        return None

    def zone(lon: float) -> int:
        return min(int((lon + 180.0) // 6.0) + 1, 60)

    if zone(west_lon_deg) != zone(east_lon_deg):
        return None
    return (32600 if south_lat_deg >= 0.0 else 32700) + zone(west_lon_deg)


def _reprojected(
    array: NDArray[Any], grid: Grid, src_crs: CRS, dst_crs: CRS, nodata: float
) -> tuple[NDArray[Any], Affine]:
    """``array`` (on ``grid`` in ``src_crs``) resampled to north-up cells of the same size in
    ``dst_crs`` (nearest neighbour: counts stay counts), nodata where the source has none."""
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    src = rasterio.crs.CRS.from_wkt(src_crs.to_wkt())
    dst = rasterio.crs.CRS.from_wkt(dst_crs.to_wkt())
    transform, width, height = calculate_default_transform(
        src, dst, grid.cols, grid.rows, *grid.bounds, resolution=grid.cell_m
    )
    out = np.full((height, width), nodata, dtype=array.dtype)
    reproject(
        source=array,
        destination=out,
        src_transform=grid.transform,
        src_crs=src,
        src_nodata=nodata,
        dst_transform=transform,
        dst_crs=dst,
        dst_nodata=nodata,
        resampling=Resampling.nearest,
    )
    return out, transform


def write_geotiff(
    path: str | os.PathLike[str],
    array: NDArray[Any],
    grid: Grid,
    crs: CRS | None = None,
    *,
    nodata: float | None = None,
    compress: str | None = "deflate",
    description: str | None = None,
    to_crs: CRS | None = None,
) -> Path:
    """Write a single-band GeoTIFF atomically (temporary file in the same folder, then rename).

    ``crs`` defaults to the grid's. ``nodata`` defaults to NaN for float arrays and none for
    integer arrays (every count is a value). ``description``: the band's description (what a GIS
    shows as its name). ``to_crs``: resample (nearest, same cell size) into this CRS first, e.g.
    the UTM zone's EPSG code so a GIS names the CRS (needs ``nodata``). Tiled above 256 x 256
    cells, ``compress`` (a GDAL GTiff compression, None for none) deflate by default; opens in QGIS.
    """
    target = Path(path)
    if array.shape != grid.shape:
        raise ValueError(f"array shape {array.shape} differs from grid {grid.shape}")
    crs = crs if crs is not None else grid.crs
    if crs is None:
        raise ProcessingError(f"no CRS for {target}; give the local frame's CRS")
    if nodata is None and np.issubdtype(array.dtype, np.floating):
        nodata = float("nan")
    transform = grid.transform
    width, height = grid.cols, grid.rows
    if to_crs is not None:
        if nodata is None:
            raise ValueError("resampling into another CRS needs a nodata value")
        array, transform = _reprojected(
            array, grid, CRS.from_user_input(crs), CRS.from_user_input(to_crs), nodata
        )
        crs = to_crs
        height, width = array.shape
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tif", dir=target.parent)
    os.close(fd)
    try:
        profile: dict[str, Any] = {
            "driver": "GTiff",
            "width": width,
            "height": height,
            "count": 1,
            "dtype": array.dtype.name,
            "crs": rasterio.crs.CRS.from_wkt(CRS.from_user_input(crs).to_wkt()),
            "transform": transform,
        }
        if compress is not None:
            profile["compress"] = compress
        if width >= 256 and height >= 256:
            profile.update(tiled=True, blockxsize=256, blockysize=256)
        if nodata is not None:
            profile["nodata"] = nodata
        if to_crs is not None:
            epsg = CRS.from_user_input(to_crs).to_epsg()
            if epsg is not None:  # an EPSG code GDAL writes as such, so a GIS names the CRS
                profile["crs"] = rasterio.crs.CRS.from_epsg(epsg)
        with rasterio.open(tmp_name, "w", **profile) as dataset:
            # In bands of rows: writing the whole array at once makes GDAL hold a second copy.
            for row in range(0, height, _WRITE_ROWS):
                stop = min(row + _WRITE_ROWS, height)
                window = rasterio.windows.Window(0, row, width, stop - row)
                dataset.write(array[row:stop], 1, window=window)
            if description is not None:
                dataset.set_band_description(1, description)
        os.chmod(tmp_name, 0o644)
        os.replace(tmp_name, target)
    except BaseException:
        if os.path.exists(tmp_name):
            os.unlink(tmp_name)
        raise
    logger.info("wrote %s (%d x %d)", target, width, height)
    return target
