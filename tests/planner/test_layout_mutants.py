"""Two layout rules held to oracles built here from the camera and the geometry alone (no figure of
the plan's own: not its trigger distance, line spacing or footprints):

- the air base comes from the frame's length ALONG the track (Eq. 3-5, B = (1 - p) x along):
  landscape and portrait give different along-track lengths with a 3:2 sensor, so the distance
  between a line's stations tells which side was used;
- a corridor flown along its simplified centre line covers the corridor the crew drew with its
  lines alone (fill runs are for what exclusions leave): the simplification's tolerance is added
  on both sides, so a meandering centre line, flown as straight lines, still has its whole width
  seen by two frames or more of the lines that run its whole length.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import shapely
from shapely.geometry import LineString
from survey_oracles import make_spec
from test_corridor import corridor_points, corridor_spec, write_line
from test_survey import to_lonlat_polygon

from planner.camera import Camera
from planner.plan import SurveyPlan
from planner.survey import plan_polygons, plan_survey


def _height_m(camera: Camera, gsd_cm: float) -> float:
    """Eq. 3-4 solved for the height: GSD = pitch x H / f (the coarser pixel pitch)."""
    pitch = max(camera.pixel_pitch_x_mm, camera.pixel_pitch_y_mm)
    return gsd_cm / 100.0 * camera.focal_length_mm / pitch


def _line_steps(plan: SurveyPlan) -> list[float]:
    """Distances between consecutive stations of each line, from their positions."""
    st = plan.stations
    out: list[float] = []
    for line in np.unique(st.line_index):
        k = np.flatnonzero(st.line_index == line)
        xy = np.column_stack([st.x_m[k], st.y_m[k]])
        out.extend(np.hypot(*np.diff(xy, axis=0).T).tolist())
    return out


@pytest.mark.parametrize("orientation", ["landscape", "portrait"])
def test_air_base_is_the_along_track_length_less_the_endlap(orientation: str) -> None:
    spec = make_spec(
        {
            "gsd_cm": 2.0,
            "front_overlap_pct": 75,
            "side_overlap_pct": 60,
            "trigger": "hover",
            "direction_deg": 0,
        },
        camera={"model": "dji-phantom-4-pro", "orientation": orientation},
    )
    camera = spec.camera
    assert camera.sensor_width_mm != camera.sensor_height_mm  # a 3:2 sensor tells the sides apart
    height = _height_m(camera, 2.0)
    # landscape: the image's width lies across the track, its height along it
    along_mm = camera.sensor_height_mm if orientation == "landscape" else camera.sensor_width_mm
    base = (1.0 - 0.75) * height * along_mm / camera.focal_length_mm
    plan = plan_polygons(spec, [to_lonlat_polygon([(0, 0), (300, 0), (300, 600), (0, 600)])], [])
    assert float(plan.stations.alt_agl_m[0]) == pytest.approx(height, rel=1e-6)
    steps = np.asarray(_line_steps(plan))
    # stations at most one air base apart, and on 600 m lines nearly that
    assert steps.max() <= base * (1 + 1e-6), (steps.max(), base)
    assert float(np.median(steps)) >= 0.95 * base, (float(np.median(steps)), base)


def _independent_footprints(plan: SurveyPlan, height_m: float) -> np.ndarray:
    """(N, 4, 2) nadir footprints: rectangles centred on the stations, their long side across
    the track in landscape, turned to the direction of motion from the stations' own positions."""
    st = plan.stations
    camera = plan.camera
    half_across = height_m * camera.sensor_width_mm / camera.focal_length_mm / 2.0
    half_along = height_m * camera.sensor_height_mm / camera.focal_length_mm / 2.0
    out = np.zeros((len(st), 4, 2))
    for line in np.unique(st.line_index):
        k = np.flatnonzero(st.line_index == line)
        xy = np.column_stack([st.x_m[k], st.y_m[k]])
        d = np.gradient(xy, axis=0) if len(k) > 1 else np.array([[0.0, 1.0]])
        d /= np.hypot(d[:, 0], d[:, 1])[:, None]
        n = np.column_stack([d[:, 1], -d[:, 0]])
        for j, (a, b) in enumerate(((1, 1), (1, -1), (-1, -1), (-1, 1))):
            out[k, j] = xy + a * half_along * d + b * half_across * n
    return out


@pytest.mark.parametrize("width_m", [112.0, 120.0, 128.0, 136.0])
def test_a_meandering_corridor_flown_straight_is_seen_twice_across_its_width_by_its_lines(
    tmp_path: Path, width_m: float
) -> None:
    # a centre line that swings 0.085 x width either side: close to what the simplification drops
    amp = 0.085 * width_m
    xy = [(amp * math.sin(2.0 * math.pi * y / 200.0), float(y)) for y in np.arange(0.0, 600.1, 5.0)]
    write_line(tmp_path, xy)
    plan = plan_survey(corridor_spec(tmp_path, width_m))
    height = _height_m(plan.camera, 2.0)
    points = corridor_points(plan, xy, width_m, 3.0)
    # the lines flown along the whole corridor must cover it: fill runs are for exclusions
    st = plan.stations
    reach = {
        int(li): float(np.hypot(np.ptp(st.x_m[st.line_index == li]), np.ptp(st.y_m[st.line_index == li])))
        for li in np.unique(st.line_index)
    }
    whole = [li for li, r in reach.items() if r >= 0.9 * max(reach.values())]
    footprints = _independent_footprints(plan, height)[np.isin(st.line_index, whole)]
    polygons = shapely.polygons(footprints)
    tree = shapely.STRtree(polygons)
    hits = tree.query(shapely.points(points), predicate="dwithin", distance=1e-6)
    counts = np.bincount(hits[0], minlength=len(points))
    missing = points[counts < 2]
    assert len(missing) == 0, (
        f"{len(missing)} of {len(points)} corridor points seen by fewer than two frames, e.g. "
        f"{missing[:3].tolist()} (the centre line runs {LineString(xy).length:.0f} m)"
    )
