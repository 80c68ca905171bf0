"""Plans for the sortie and resume tests: rectangles near Bardenas (lon/lat from metres on a
local tangent plane) and specs with survey and vehicle overrides."""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

from pyproj import Geod
from shapely.geometry import Polygon
from survey_oracles import REPO

from planner.plan import SurveyPlan
from planner.spec import MissionSpec, parse_spec

LON0, LAT0 = -1.60, 42.50
M_PER_DEG_LAT = 111_132.0
M_PER_DEG_LON = 111_320.0 * math.cos(math.radians(LAT0))
GEOD_WGS84 = Geod(ellps="WGS84")


def lonlat_polygon(xy: list[tuple[float, float]]) -> Polygon:
    return Polygon([(LON0 + x / M_PER_DEG_LON, LAT0 + y / M_PER_DEG_LAT) for x, y in xy])


def spec_with(survey: dict[str, Any], vehicle: dict[str, Any]) -> MissionSpec:
    base = {"gsd_cm": 2.0, "front_overlap_pct": 75, "side_overlap_pct": 65, "speed_m_s": 8.0}
    data = {
        "name": "sorties",
        "area": "area.geojson",
        "camera": {"model": "dji-phantom-4-pro"},
        "survey": {**base, **survey},
        "vehicle": {"type": "multirotor", "max_alt_agl_m": 400, **vehicle},
    }
    return parse_spec(data, REPO / "tests" / "spec.toml")


def station_keys(plan: SurveyPlan) -> Counter[tuple[int, float, float]]:
    st_ = plan.stations
    return Counter(
        (int(p), round(float(x), 1), round(float(y), 1))
        for p, x, y in zip(st_.pass_index, st_.x_m, st_.y_m, strict=True)
    )
