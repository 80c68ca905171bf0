"""The plan's large layers as a GeoPackage (OGC; QGIS, ArcGIS and GDAL open it with a spatial
index, unlike a GeoJSON of a million features): the stations as points and their footprints as
polygons, WGS84, through pyogrio (GDAL's vectorized writer). planner.plan_folder writes it for
plans above :data:`~planner.plan_folder.GPKG_ABOVE_PHOTOS` photos, instead of footprints.geojson.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import shapely

from ..plan import SurveyPlan

log = logging.getLogger(__name__)


def write_layers_gpkg(plan: SurveyPlan, path: str | os.PathLike[str]) -> Path:
    """Layers ``stations`` (points) and ``footprints`` (polygons, counter-clockwise) of every
    exposure, in flight order; fields as stations.geojson's: ``pass``, ``line``, ``station``
    (0-based), ``alt_rel_home_m``, ``alt_agl_m``, ``heading_deg``, ``look_heading_deg``,
    ``tilt_deg``, ``gsd_cm``."""
    from pyogrio.raw import write

    st = plan.stations
    target = Path(path)
    fields = ["pass", "line", "station", "alt_rel_home_m", "alt_agl_m", "heading_deg", "look_heading_deg",
              "tilt_deg", "gsd_cm"]  # fmt: skip
    data = [
        st.pass_index.astype(np.int32),
        st.line_index.astype(np.int32),
        np.arange(len(st), dtype=np.int64),
        st.alt_rel_home_m,
        st.alt_agl_m,
        st.heading_deg,
        st.look_heading_deg,
        st.tilt_deg,
        st.gsd_cm,
    ]
    points = shapely.to_wkb(shapely.points(st.lon_deg, st.lat_deg))
    rings = np.concatenate([st.footprint_lonlat_deg, st.footprint_lonlat_deg[:, :1]], axis=1)
    polygons = shapely.polygons(rings)
    if hasattr(shapely, "orient_polygons"):  # shapely >= 2.1
        polygons = shapely.orient_polygons(polygons)
    else:
        polygons = np.array([shapely.geometry.polygon.orient(p, 1.0) for p in polygons], dtype=object)
    write(
        target, points, data, fields, layer="stations", driver="GPKG", geometry_type="Point", crs="EPSG:4326"
    )
    write(
        target, shapely.to_wkb(polygons), data, fields, layer="footprints", driver="GPKG",
        geometry_type="Polygon", crs="EPSG:4326", append=True,
    )  # fmt: skip
    log.debug("wrote %s: %d stations and footprints", target, len(st))
    return target
