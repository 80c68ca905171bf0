"""Writing every output of a plan into one folder, all or nothing.

The files (what a field team opens them with):
- mission.plan: QGroundControl; mission.waypoints: Mission Planner, MAVProxy, QGC (WPL 110)
- flight_lines.geojson, stations.geojson, footprints.geojson, area.geojson: any GIS
- mission.kml: Google Earth
- map.png: a person, at a glance
- summary.json: the numbers that justify the plan
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Callable
from pathlib import Path

from .outputs import atomic_write_text, staged_output_dir
from .plan import SurveyPlan

log = logging.getLogger(__name__)

OUTPUT_FILES = (
    "mission.plan",
    "mission.waypoints",
    "flight_lines.geojson",
    "stations.geojson",
    "footprints.geojson",
    "area.geojson",
    "mission.kml",
    "map.png",
    "summary.json",
)


def summary_json(plan: SurveyPlan) -> str:
    data = plan.summary.as_dict()
    data["home"] = {
        "lat_deg": plan.home.lat_deg,
        "lon_deg": plan.home.lon_deg,
        "alt_amsl_m": plan.home.alt_amsl_m,
    }
    data["passes"] = [
        {
            "index": p.index,
            "kind": p.kind.value,
            "name": p.name,
            "direction_deg": p.direction_deg,
            "tilt_deg": p.tilt_deg,
            "look_heading_deg": p.look_heading_deg,
            "alt_agl_m": p.alt_agl_m,
            "line_spacing_m": p.line_spacing_m,
            "trigger_distance_m": p.trigger_distance_m,
            "segment_count": len(p.lines),
            "photo_count": int((plan.stations.pass_index == p.index).sum()),
            "near_gsd_cm": p.near_gsd_cm,
            "far_gsd_cm": p.far_gsd_cm,
        }
        for p in plan.passes
    ]
    return json.dumps(data, indent=2, allow_nan=False) + "\n"


def write_outputs(
    plan: SurveyPlan,
    out_dir: str | os.PathLike[str],
    *,
    overwrite: bool = False,
    progress: Callable[[int], None] | None = None,
) -> list[Path]:
    """Write every output file; on any failure nothing is left behind and ``out_dir`` is
    unchanged. ``progress(1)`` is called after each file."""
    from .formats.geojson import (
        write_area_geojson,
        write_flight_lines_geojson,
        write_footprints_geojson,
        write_stations_geojson,
    )
    from .formats.kml import write_kml
    from .formats.qgc_plan import write_plan
    from .formats.waypoints import write_waypoints
    from .mapplot import render_map_png

    writers: dict[str, Callable[[Path], object]] = {
        "mission.plan": lambda p: write_plan(plan.mission, p),
        "mission.waypoints": lambda p: write_waypoints(plan.mission, p),
        "flight_lines.geojson": lambda p: write_flight_lines_geojson(plan, p),
        "stations.geojson": lambda p: write_stations_geojson(plan, p),
        "footprints.geojson": lambda p: write_footprints_geojson(plan, p),
        "area.geojson": lambda p: write_area_geojson(plan, p),
        "mission.kml": lambda p: write_kml(plan, p),
        "map.png": lambda p: render_map_png(plan, p),
        "summary.json": lambda p: atomic_write_text(p, summary_json(plan)),
    }
    final = Path(out_dir)
    with staged_output_dir(final, overwrite=overwrite) as staging:
        for name in OUTPUT_FILES:
            log.debug("writing %s", name)
            writers[name](staging / name)
            if progress is not None:
                progress(1)
    return [final / name for name in OUTPUT_FILES]
