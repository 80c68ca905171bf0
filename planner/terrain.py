"""Terrain: a digital elevation model (GeoTIFF, any CRS) sampled bilinearly in a local frame.

The planner uses it for terrain-following altitudes and for the GSD and overlap spread over the
ground; the coverage check (processing.ground.DemGround) builds on the same sampler.
Horizontal coordinates are metres in a :class:`planner.geo.LocalFrame` (x east, y north).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray
from pyproj import CRS, Transformer

from .errors import SfapError, TerrainError
from .geo import LocalFrame

if TYPE_CHECKING:  # rasterio is imported when a DEM is read: a plan without one does without it
    import rasterio
    import rasterio.io
    import rasterio.windows

logger = logging.getLogger(__name__)

F64 = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class Dem:
    """A gridded elevation model, sampled bilinearly between cell centres.

    Built with :meth:`from_geotiff`. ``elevation`` holds the first band (rows from north), ``valid``
    marks cells with data; ``transform`` is the GDAL affine (rasterio ``Affine``) of the file and
    ``crs`` its CRS, into which queries are reprojected (any CRS, including geographic).
    """

    path: Path
    elevation: F64
    valid: NDArray[np.bool_]
    transform: rasterio.Affine
    crs: CRS
    #: The error raised for a DEM problem (a subclass may raise its own branch of the tree).
    error: ClassVar[type[SfapError]] = TerrainError
    _transformers: dict[str, Transformer] = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.elevation.ndim != 2 or self.elevation.shape != self.valid.shape:
            raise self.error(
                f"DEM {self.path}: elevation shape {self.elevation.shape} and valid shape "
                f"{self.valid.shape} must be equal and two-dimensional"
            )
        if not self.valid.any():
            raise self.error(f"DEM {self.path} holds no valid elevation (every cell is nodata)")
        if abs(self.transform.b) > 1e-12 or abs(self.transform.d) > 1e-12:
            raise self.error(
                f"DEM {self.path} is rotated (geotransform {tuple(self.transform)[:6]}); warp it "
                f"north-up first, e.g. gdalwarp in.tif out.tif"
            )

    @classmethod
    def from_geotiff(
        cls,
        path: str | Path,
        *,
        bounds_lonlat: tuple[float, float, float, float] | None = None,
        **fields: Any,
    ) -> Self:
        """Read band 1 of a GeoTIFF (or any raster GDAL reads) as the elevation model.

        Nodata cells (the file's nodata value, NaN) are invalid. ``bounds_lonlat`` (west, south,
        east, north in WGS84 degrees) reads only the part of a large DEM that covers them.
        ``fields`` are passed on to the class (a subclass's extra fields).
        """
        import rasterio
        from rasterio.errors import RasterioIOError

        target = Path(path)
        try:
            with rasterio.open(target) as dataset:
                if dataset.crs is None:
                    raise cls.error(
                        f"DEM {target} has no CRS; assign one, e.g. gdal_edit.py -a_srs EPSG:32633"
                    )
                crs = CRS.from_user_input(dataset.crs.to_wkt())
                window = None
                if bounds_lonlat is not None:
                    window = _window_for(dataset, crs, bounds_lonlat, target, cls.error)
                band = dataset.read(1, masked=True, window=window)
                t = dataset.transform
                if window is not None:
                    # The window's own geotransform: its top-left cell's corner.
                    col, row = window.col_off, window.row_off
                    t = rasterio.Affine(
                        t.a, t.b, t.c + col * t.a + row * t.b, t.d, t.e, t.f + col * t.d + row * t.e
                    )
                transform = t
        except RasterioIOError as exc:
            raise cls.error(f"cannot read DEM {target}: {exc}") from None
        # Float before filling: integer DEMs (SRTM is int16) cannot hold NaN.
        elevation = np.asarray(band.astype(np.float64).filled(np.nan), dtype=np.float64)
        valid = ~np.ma.getmaskarray(band) & np.isfinite(elevation)
        logger.info("DEM %s: %d x %d cells read", target.name, elevation.shape[1], elevation.shape[0])
        return cls(path=target, elevation=elevation, valid=valid, transform=transform, crs=crs, **fields)

    def write_geotiff(self, path: str | Path) -> None:
        """Write the DEM as read (the part read, when it was clipped to bounds) as a GeoTIFF of its
        own: float32 (exact for the float32 and integer DEMs GIS tools write), nodata NaN,
        DEFLATE-compressed, same CRS and geotransform."""
        import rasterio

        rows, cols = self.elevation.shape
        data = np.where(self.valid, self.elevation, np.nan).astype(np.float32)
        with rasterio.open(
            Path(path), "w", driver="GTiff", height=rows, width=cols, count=1, dtype="float32",
            crs=self.crs.to_wkt(), transform=self.transform, nodata=float("nan"), compress="deflate",
        ) as out:  # fmt: skip
            out.write(data, 1)

    @property
    def description(self) -> str:
        rows, cols = self.elevation.shape
        lo, hi = self.elevation_range_m
        return (
            f"DEM {self.path.name} ({cols} x {rows} cells, {self.crs.name}, elevation "
            f"{lo:.1f}-{hi:.1f} m), bilinear"
        )

    @property
    def elevation_range_m(self) -> tuple[float, float]:
        values = self.elevation[self.valid]
        return float(values.min()), float(values.max())

    def _transformer(self, frame: LocalFrame) -> Transformer | None:
        if frame.crs == self.crs:
            return None
        key = frame.crs.to_wkt()
        if key not in self._transformers:
            self._transformers[key] = Transformer.from_crs(frame.crs, self.crs, always_xy=True)
        return self._transformers[key]

    def cell_size_m(self, frame: LocalFrame) -> float:
        """The DEM cell size in local metres (the smaller axis), near the DEM's centre."""
        rows, cols = self.elevation.shape
        col0, row0 = cols / 2.0, rows / 2.0
        cols_px = np.array([col0, col0 + 1.0, col0])
        rows_px = np.array([row0, row0, row0 + 1.0])
        t = self.transform
        xs = t.a * cols_px + t.b * rows_px + t.c
        ys = t.d * cols_px + t.e * rows_px + t.f
        to_local = Transformer.from_crs(self.crs, frame.crs, always_xy=True)
        lx, ly = to_local.transform(np.asarray(xs), np.asarray(ys))
        return float(min(math.hypot(lx[1] - lx[0], ly[1] - ly[0]), math.hypot(lx[2] - lx[0], ly[2] - ly[0])))

    def sample(self, x_m: ArrayLike, y_m: ArrayLike, frame: LocalFrame) -> tuple[F64, NDArray[np.bool_]]:
        """Bilinear elevation at local-frame points and whether each is known.

        A point is known when it lies inside the DEM's extent and the cells its interpolation uses
        all hold data. Between the outer cell centres and the edge the edge cells are extended.
        """
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        transformer = self._transformer(frame)
        if transformer is not None:
            qx, qy = transformer.transform(x, y)
            qx, qy = np.asarray(qx, float), np.asarray(qy, float)
        else:
            qx, qy = x, y
        inverse = ~self.transform
        col = inverse.a * qx + inverse.b * qy + inverse.c
        row = inverse.d * qx + inverse.e * qy + inverse.f
        rows, cols = self.elevation.shape
        inside = np.isfinite(col) & np.isfinite(row) & (col >= 0) & (col <= cols) & (row >= 0) & (row <= rows)
        # Cell centres sit at half-integer pixel coordinates.
        fc = np.clip(np.where(inside, col, 0.0) - 0.5, 0.0, cols - 1.0)
        fr = np.clip(np.where(inside, row, 0.0) - 0.5, 0.0, rows - 1.0)
        c0 = np.minimum(np.floor(fc).astype(np.intp), max(cols - 2, 0))
        r0 = np.minimum(np.floor(fr).astype(np.intp), max(rows - 2, 0))
        c1 = np.minimum(c0 + 1, cols - 1)
        r1 = np.minimum(r0 + 1, rows - 1)
        tc = fc - c0
        tr = fr - r0
        z = self.elevation
        v = self.valid
        known = inside & v[r0, c0] & v[r0, c1] & v[r1, c0] & v[r1, c1]
        top = z[r0, c0] * (1.0 - tc) + z[r0, c1] * tc
        bottom = z[r1, c0] * (1.0 - tc) + z[r1, c1] * tc
        value = top * (1.0 - tr) + bottom * tr
        return np.where(known, value, 0.0), known

    def elevation_at(self, x_m: ArrayLike, y_m: ArrayLike, frame: LocalFrame) -> F64:
        value, known = self.sample(x_m, y_m, frame)
        if not known.all():
            x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
            bad = np.flatnonzero(~known.ravel())[0]
            lon, lat = frame.to_lonlat(x.ravel()[bad], y.ravel()[bad])
            raise self.error(
                f"DEM {self.path.name} has no elevation at lon {float(lon):.6f}, lat {float(lat):.6f} "
                f"({int((~known).sum())} of {known.size} points outside the DEM or on nodata); use a "
                f"DEM that covers the whole block, or flat ground"
            )
        return value


def _window_for(
    dataset: rasterio.io.DatasetReader,
    crs: CRS,
    bounds_lonlat: tuple[float, float, float, float],
    path: Path,
    error: type[SfapError],
) -> rasterio.windows.Window:
    """The window of ``dataset`` covering lon/lat bounds (one cell of margin), or GroundError."""
    import rasterio.windows

    west, south, east, north = bounds_lonlat
    if not (west < east and south < north):
        raise error(f"bounds_lonlat {bounds_lonlat} are empty; expected (west, south, east, north)")
    to_dem = Transformer.from_crs(CRS.from_epsg(4326), crs, always_xy=True)
    xmin, ymin, xmax, ymax = to_dem.transform_bounds(west, south, east, north, densify_pts=21)
    window = rasterio.windows.from_bounds(xmin, ymin, xmax, ymax, transform=dataset.transform)
    col0 = max(math.floor(window.col_off) - 1, 0)
    row0 = max(math.floor(window.row_off) - 1, 0)
    col1 = min(math.ceil(window.col_off + window.width) + 1, dataset.width)
    row1 = min(math.ceil(window.row_off + window.height) + 1, dataset.height)
    if col1 <= col0 or row1 <= row0:
        raise error(
            f"DEM {path.name} does not cover lon {west:.5f}..{east:.5f}, lat {south:.5f}..{north:.5f}; "
            f"use a DEM of the survey area"
        )
    return rasterio.windows.Window(col0, row0, col1 - col0, row1 - row0)
