"""Geodesy: areas in WGS84, the local projected frame metric work happens in, and checks.

Every boundary (files, MAVLink, EXIF) speaks WGS84 longitude/latitude; every distance and
area is computed in a projected CRS chosen for the area (its UTM zone), through a
:class:`LocalFrame` that travels with the coordinates. ``always_xy=True`` everywhere: x is
easting / longitude, y northing / latitude.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from geographiclib.geodesic import Geodesic
from numpy.typing import ArrayLike, NDArray
from pyproj import CRS, Transformer

from .errors import AreaError

if TYPE_CHECKING:  # shapely is imported where geometries are used: geotag does without it
    from shapely.geometry.base import BaseGeometry

WGS84 = CRS.from_epsg(4326)


@dataclass(frozen=True)
class LocalFrame:
    """A projected CRS (metres) with its transformers to and from WGS84 lon/lat."""

    crs: CRS
    _to_xy: Transformer = field(repr=False, compare=False)
    _to_lonlat: Transformer = field(repr=False, compare=False)

    @classmethod
    def from_crs(cls, crs: CRS) -> LocalFrame:
        return cls(
            crs,
            Transformer.from_crs(WGS84, crs, always_xy=True),
            Transformer.from_crs(crs, WGS84, always_xy=True),
        )

    @classmethod
    def utm_for(cls, lon_deg: float, lat_deg: float) -> LocalFrame:
        """The WGS84 UTM zone that contains the point (the area's centroid).

        The zones of EPSG's WGS 84 / UTM CRSs (326zz north of the equator, 327zz south) are the
        plain 6-degree bands from 180 W, between 80 S and 84 N: computed here directly (asking
        PROJ's database, ``pyproj.database.query_utm_crs_info``, costs about 0.1 s a call; the
        tests hold the two to the same answer)."""
        if not (-80.0 <= lat_deg <= 84.0) or not (-180.0 <= lon_deg <= 180.0):
            raise AreaError(
                f"no UTM zone covers lon {lon_deg:.6f}, lat {lat_deg:.6f}; areas beyond "
                f"84 deg N / 80 deg S are not supported"
            )
        zone = int((lon_deg + 180.0) // 6.0) % 60 + 1
        return cls.from_crs(CRS.from_epsg((32600 if lat_deg >= 0.0 else 32700) + zone))

    @property
    def epsg(self) -> int | None:
        return self.crs.to_epsg()

    def to_xy(self, lon_deg: ArrayLike, lat_deg: ArrayLike) -> tuple[NDArray[np.float64], ...]:
        x, y = self._to_xy.transform(np.asarray(lon_deg, float), np.asarray(lat_deg, float))
        return np.asarray(x, float), np.asarray(y, float)

    def to_lonlat(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[NDArray[np.float64], ...]:
        lon, lat = self._to_lonlat.transform(np.asarray(x_m, float), np.asarray(y_m, float))
        return np.asarray(lon, float), np.asarray(lat, float)

    def true_north_grid_bearing_deg(self, lon_deg: float, lat_deg: float) -> float:
        """Grid bearing of true north at a point (minus the meridian convergence).

        A true bearing b is the grid bearing ``b + true_north_grid_bearing_deg``: lines are
        planned in grid bearings and reported in true bearings.
        """
        step = Geodesic.WGS84.Direct(lat_deg, lon_deg, 0.0, 100.0)
        x0, y0 = self.to_xy(lon_deg, lat_deg)
        x1, y1 = self.to_xy(step["lon2"], step["lat2"])
        return float(np.degrees(np.arctan2(x1 - x0, y1 - y0)))

    def true_north_grid_bearing_deg_array(
        self, lon_deg: ArrayLike, lat_deg: ArrayLike
    ) -> NDArray[np.float64]:
        """:meth:`true_north_grid_bearing_deg` at many points (finite difference along the
        meridian, 1e-5 deg = about 1 m)."""
        lon = np.atleast_1d(np.asarray(lon_deg, float))
        lat = np.atleast_1d(np.asarray(lat_deg, float))
        step = np.where(lat < 89.0, 1e-5, -1e-5)
        x0, y0 = self.to_xy(lon, lat)
        x1, y1 = self.to_xy(lon, lat + step)
        return np.degrees(np.arctan2((x1 - x0) * np.sign(step), (y1 - y0) * np.sign(step)))

    def geometry_to_xy(self, geom: BaseGeometry) -> BaseGeometry:
        """A shapely geometry in lon/lat, projected into this frame."""
        import shapely

        return shapely.transform(geom, lambda c: np.column_stack(self.to_xy(c[:, 0], c[:, 1])))

    def geometry_to_lonlat(self, geom: BaseGeometry) -> BaseGeometry:
        """A shapely geometry in this frame, back to lon/lat."""
        import shapely

        return shapely.transform(geom, lambda c: np.column_stack(self.to_lonlat(c[:, 0], c[:, 1])))


def geodesic_distance_m(lat1_deg: float, lon1_deg: float, lat2_deg: float, lon2_deg: float) -> float:
    """Distance on the WGS84 ellipsoid (GeographicLib), metres: the check on projected lengths."""
    result = Geodesic.WGS84.Inverse(lat1_deg, lon1_deg, lat2_deg, lon2_deg)
    return float(result["s12"])


def geodesic_area_m2(polygon_lonlat: BaseGeometry) -> float:
    """Area of a lon/lat polygon (holes subtracted) on the WGS84 ellipsoid, square metres."""
    polys = getattr(polygon_lonlat, "geoms", [polygon_lonlat])
    total = 0.0
    for poly in polys:
        rings = [poly.exterior, *poly.interiors]
        for k, ring in enumerate(rings):
            p = Geodesic.WGS84.Polygon()
            for lon, lat in list(ring.coords)[:-1]:
                p.AddPoint(lat, lon)
            _, _, area = p.Compute(False, True)
            total += abs(area) if k == 0 else -abs(area)
    return total
