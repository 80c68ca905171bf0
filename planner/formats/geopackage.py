"""A large plan's footprints as a GeoPackage (OGC; QGIS, ArcGIS and GDAL open it with its spatial
index, where a GeoJSON of a million polygons is parsed whole): one layer ``footprints``, WGS84,
through pyogrio (GDAL's vectorized writer). planner.plan_folder writes it for plans above
:data:`~planner.plan_folder.GPKG_ABOVE_PHOTOS` photos, instead of footprints.geojson.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
import shapely

from ..plan import SurveyPlan

log = logging.getLogger(__name__)


def write_footprints_gpkg(plan: SurveyPlan, path: str | os.PathLike[str]) -> Path:
    """Layer ``footprints``: the ground footprint of every exposure (polygons, counter-clockwise),
    in flight order, with footprints.geojson's fields: ``pass``, ``line``, ``station`` (0-based, as
    in stations.geojson), ``tilt_deg``, ``look_heading_deg``, ``gsd_cm``."""
    from pyogrio.raw import write

    st = plan.stations
    target = Path(path)
    fields = ["pass", "line", "station", "tilt_deg", "look_heading_deg", "gsd_cm"]
    data = [
        st.pass_index.astype(np.int32),
        st.line_index.astype(np.int32),
        np.arange(len(st), dtype=np.int64),
        st.tilt_deg,
        st.look_heading_deg,
        st.gsd_cm,
    ]
    rings = np.concatenate([st.footprint_lonlat_deg, st.footprint_lonlat_deg[:, :1]], axis=1)
    polygons = shapely.polygons(rings)
    if hasattr(shapely, "orient_polygons"):  # shapely >= 2.1
        polygons = shapely.orient_polygons(polygons)
    else:
        polygons = np.array([shapely.geometry.polygon.orient(p, 1.0) for p in polygons], dtype=object)
    write(
        target, shapely.to_wkb(polygons), data, fields, layer="footprints", driver="GPKG",
        geometry_type="Polygon", crs="EPSG:4326",
    )  # fmt: skip
    log.debug("wrote %s: %d footprints", target, len(st))
    return target
