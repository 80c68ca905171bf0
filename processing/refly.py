"""A re-fly mission over the gaps a check found, planned by the planner itself.

The gaps (WGS84 polygons) are grown by a margin so the new frames tie into the imagery around
them, merged where they touch, and planned as a survey area with
:func:`planner.survey.plan_polygons`, with the camera, orientation, flying height and overlaps
of the original plan when one is known (else the frames' camera and median height above
ground, and the planner's default overlaps). The planner guarantees edge coverage of its area,
so every gap is inside the new frames' footprints.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

from planner.camera import Camera, Orientation
from planner.camera_db import GEOMETRY_KEYS, get_camera
from planner.errors import CameraError
from planner.geo import LocalFrame
from planner.plan import SurveyPlan
from planner.spec import parse_spec
from planner.survey import plan_polygons

from .errors import ProcessingError

if TYPE_CHECKING:
    from .check_result import CheckResult

log = logging.getLogger(__name__)

#: Margin added around every gap, as a share of the frame's shorter ground side.
MARGIN_FOOTPRINT_RATIO = 0.1
#: Smallest margin, metres (a GPS position is good to a few metres).
MIN_MARGIN_M = 5.0


@dataclass(frozen=True, kw_only=True)
class ReflyParameters:
    """How the re-fly is flown: the original plan's values when known.

    ``altitude_agl_m``: flying height above ground; overlaps in percent; ``speed_m_s``: survey
    speed; ``home_lat_deg``/``home_lon_deg``/``home_alt_amsl_m``: the take-off point (None: the
    planner's default, the gap area's south-west vertex); ``margin_m``: growth of each gap
    (None: :data:`MARGIN_FOOTPRINT_RATIO` of the frame's short side, at least
    :data:`MIN_MARGIN_M`).
    """

    camera: Camera
    orientation: Orientation = Orientation.LANDSCAPE
    altitude_agl_m: float
    front_overlap_pct: float = 80.0
    side_overlap_pct: float = 70.0
    speed_m_s: float = 5.0
    home_lat_deg: float | None = None
    home_lon_deg: float | None = None
    home_alt_amsl_m: float = 0.0
    max_alt_agl_m: float = 120.0
    margin_m: float | None = None
    name: str = "re-fly"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.altitude_agl_m) and self.altitude_agl_m > 0):
            raise ProcessingError(f"re-fly altitude_agl_m = {self.altitude_agl_m} must be positive metres")
        if self.margin_m is not None and not (self.margin_m >= 0):
            raise ProcessingError(f"re-fly margin_m = {self.margin_m} must be >= 0 m")


def _camera_table(camera: Camera) -> dict[str, object]:
    """The [camera] table of a spec that gives back ``camera``."""
    try:
        if get_camera(camera.id) == camera:
            return {"model": camera.id}
    except CameraError:
        pass
    table: dict[str, object] = {key: getattr(camera, key) for key in GEOMETRY_KEYS}
    table["min_trigger_interval_s"] = camera.min_trigger_interval_s
    table["name"] = camera.name
    if camera.shutter_s is not None:
        table["shutter_s"] = camera.shutter_s
    return table


def refly_area_lonlat(
    gaps_lonlat: Sequence[Polygon], params: ReflyParameters
) -> tuple[Polygon | MultiPolygon, LocalFrame, float]:
    """The gaps grown by the margin and merged (lon/lat), the frame used, and the margin (m)."""
    if not gaps_lonlat:
        raise ProcessingError("there is no gap to re-fly: the check found full coverage")
    union = shapely.union_all(list(gaps_lonlat))
    centre = union.centroid
    frame = LocalFrame.utm_for(centre.x, centre.y)
    footprint = params.camera.footprint(params.altitude_agl_m, params.orientation)
    margin = (
        params.margin_m
        if params.margin_m is not None
        else max(MIN_MARGIN_M, MARGIN_FOOTPRINT_RATIO * min(footprint.along_m, footprint.across_m))
    )
    grown_xy = shapely.union_all([frame.geometry_to_xy(g).buffer(margin) for g in gaps_lonlat])
    # Straight edges instead of the raster's staircase; simplifying moves an edge by at most
    # half the margin, so every gap stays inside with half the margin to spare.
    grown_xy = grown_xy.simplify(margin / 2.0)
    area = frame.geometry_to_lonlat(grown_xy)
    assert isinstance(area, Polygon | MultiPolygon)
    return area, frame, margin


def refly_mission(gaps_lonlat: Sequence[Polygon], params: ReflyParameters) -> SurveyPlan:
    """A survey plan whose frames cover every gap polygon (WGS84 lon/lat)."""
    area, _, margin = refly_area_lonlat(gaps_lonlat, params)
    polygons = list(getattr(area, "geoms", [area]))
    data: dict[str, object] = {
        "name": params.name,
        "area": "gaps.geojson",  # only named in messages: the polygons are passed directly
        "camera": {**_camera_table(params.camera), "orientation": params.orientation.value},
        "survey": {
            "altitude_agl_m": params.altitude_agl_m,
            "front_overlap_pct": params.front_overlap_pct,
            "side_overlap_pct": params.side_overlap_pct,
            "speed_m_s": params.speed_m_s,
            "adjust_speed": True,
        },
        "vehicle": {
            "max_alt_agl_m": max(params.max_alt_agl_m, params.altitude_agl_m),
            "home_alt_amsl_m": params.home_alt_amsl_m,
            "takeoff_alt_m": min(30.0, params.altitude_agl_m),
        },
    }
    if params.home_lat_deg is not None and params.home_lon_deg is not None:
        data["vehicle"]["home"] = [params.home_lat_deg, params.home_lon_deg]  # type: ignore[index]
    spec = parse_spec(data, Path("re-fly.toml"))
    log.info(
        "re-fly over %d gap(s) grown by %.1f m at %.1f m above ground",
        len(gaps_lonlat),
        margin,
        params.altitude_agl_m,
    )
    return plan_polygons(spec, polygons, [])


def refly_parameters(result: CheckResult) -> ReflyParameters:
    """Re-fly as the plan did when the check had one, else with the frames' camera at their
    median height above ground and the planner's default overlaps (80/70 %)."""
    if result.plan is not None:
        planned, home = result.plan.planned.summary, result.plan.planned.home
        return ReflyParameters(
            camera=result.plan.camera,
            orientation=result.plan.planned.orientation,
            altitude_agl_m=planned.altitude_agl_m,
            front_overlap_pct=planned.front_overlap_pct,
            side_overlap_pct=planned.side_overlap_pct,
            speed_m_s=planned.speed_m_s,
            home_lat_deg=home.lat_deg if home else None,
            home_lon_deg=home.lon_deg if home else None,
            home_alt_amsl_m=(home.alt_amsl_m if home else None) or 0.0,
            max_alt_agl_m=max(120.0, planned.altitude_agl_m),
            name=f"{planned.name} re-fly",
        )
    heights = result.height_agl_m[np.isfinite(result.height_agl_m) & (result.height_agl_m > 0)]
    altitude = float(np.round(np.median(heights), 1)) if heights.size else 0.0
    return ReflyParameters(
        camera=result.frames.camera,
        altitude_agl_m=altitude,
        max_alt_agl_m=max(120.0, altitude),
    )
