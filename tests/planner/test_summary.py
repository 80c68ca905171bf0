"""Every figure of summary.json against an independent computation: the textbook's own numbers
where it gives them, a geometric construction (rays, triangulation) where it does not, and the
mission itself (replayed, measured on the WGS84 ellipsoid) for what the vehicle will fly."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pyproj import Geod
from survey_oracles import MISSIONS, make_spec, replay_at_loop_rate
from test_survey import to_lonlat_polygon

from planner.mission import MavCmd
from planner.plan import SurveyPlan
from planner.spec import load_spec
from planner.survey import plan_polygons, plan_survey

GEOD = Geod(ellps="WGS84")


def test_gsd_is_the_textbooks_for_its_example_camera() -> None:
    # Aber et al. (2019) ch. 3: the Canon EOS 350D with its 20 mm lens flown 60 to 82 m above
    # ground gives image GSDs of 1.9 to 2.6 cm (REFERENCES.md section 1).
    square = [(0, 0), (200, 0), (200, 150), (0, 150)]
    for height, gsd in ((60.0, 1.9), (82.0, 2.6)):
        spec = make_spec({"altitude_agl_m": height, "gsd_cm": None}, camera={"model": "canon-eos-350d-20mm"})
        plan = plan_polygons(spec, [to_lonlat_polygon(square)], [])
        assert round(plan.summary.gsd_cm, 1) == gsd


def _ray_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(float(a @ b) / float(np.linalg.norm(a) * np.linalg.norm(b))))


def _triangulated_depth_error_m(base_m: float, height_m: float, focal_mm: float, pitch_mm: float) -> float:
    """Two nadir cameras ``base_m`` apart at ``height_m``; a ground point between them is seen in
    both; half a pixel of error in the second image's coordinate along the base moves the
    intersection of the two rays by this much in depth (rays intersected in the base's plane)."""
    f = focal_mm / 1000.0
    c1, c2 = np.array([0.0, height_m]), np.array([base_m, height_m])
    point = np.array([base_m / 2.0, 0.0])
    # image coordinate (metres on the sensor) of the point in camera 2, then perturbed
    x2 = f * (point[0] - c2[0]) / (c2[1] - point[1]) + 0.5 * pitch_mm / 1000.0
    x1 = f * (point[0] - c1[0]) / (c1[1] - point[1])
    d1, d2 = np.array([x1, -f]), np.array([x2, -f])
    # c1 + s d1 = c2 + t d2
    s, _ = np.linalg.solve(np.column_stack([d1, -d2]), c2 - c1)
    hit = c1 + s * d1
    return abs(float(hit[1] - point[1]))


@pytest.mark.parametrize("orientation", ["landscape", "portrait"])
def test_every_summary_figure_against_an_independent_computation(orientation: str) -> None:
    # A custom camera with non-square pixels: 6 um across the image's x, 4 um along its y.
    camera = {
        "name": "non-square test camera",
        "sensor_width_mm": 24.0,
        "sensor_height_mm": 12.0,
        "image_width_px": 4000,
        "image_height_px": 3000,
        "focal_length_mm": 20.0,
        "min_trigger_interval_s": 1.0,
        "shutter_s": 0.0005,
        "orientation": orientation,
    }
    height = 80.0
    speed = 6.0
    square = [(0, 0), (500, 0), (500, 300), (0, 300)]
    spec = make_spec(
        {
            "altitude_agl_m": height,
            "gsd_cm": None,
            "front_overlap_pct": 75,
            "side_overlap_pct": 65,
            "speed_m_s": speed,
            "direction_deg": 30.0,
        },
        camera=camera,
    )
    plan = plan_polygons(spec, [to_lonlat_polygon(square)], [])
    s = plan.summary
    pitch_x_mm, pitch_y_mm = 24.0 / 4000, 12.0 / 3000  # 0.006, 0.004
    along_mm, across_mm = (12.0, 24.0) if orientation == "landscape" else (24.0, 12.0)
    pitch_along = pitch_y_mm if orientation == "landscape" else pitch_x_mm
    pitch_across = pitch_x_mm if orientation == "landscape" else pitch_y_mm

    assert s.altitude_agl_m == pytest.approx(height)
    assert s.scale_number == pytest.approx(height / 0.020)  # H / f
    assert s.gsd_along_cm == pytest.approx(100 * pitch_along * height / 20.0)
    assert s.gsd_across_cm == pytest.approx(100 * pitch_across * height / 20.0)
    assert s.gsd_cm == pytest.approx(100 * max(pitch_x_mm, pitch_y_mm) * height / 20.0)
    # similar triangles: ground = sensor x H / f
    along_m, across_m = along_mm * height / 20.0, across_mm * height / 20.0
    assert s.footprint_along_m == pytest.approx(along_m)
    assert s.footprint_across_m == pytest.approx(across_m)
    base = along_m * 0.25
    assert s.air_base_m == pytest.approx(base)
    assert s.trigger_distance_m == pytest.approx(base)
    assert s.line_spacing_m == pytest.approx(across_m * 0.35)
    assert s.exposure_interval_s == pytest.approx(base / speed)  # the along-track base, not the spacing
    assert s.speed_m_s == pytest.approx(speed)
    assert s.max_speed_trigger_m_s == pytest.approx(base / 1.0)
    # the limit enforced: blur along the motion (the lines run along the image axis of gsd_along)
    assert s.max_speed_blur_m_s == pytest.approx(0.5 * s.gsd_along_cm / 100 / 0.0005)
    assert s.max_speed_m_s == pytest.approx(min(s.max_speed_trigger_m_s, s.max_speed_blur_m_s))
    assert s.base_height_ratio == pytest.approx(base / height)
    # intersection angle: the two rays to the ground point midway between the cameras
    rays = (np.array([base / 2, -height]), np.array([-base / 2, -height]))
    assert s.intersection_angle_deg == pytest.approx(_ray_angle_deg(*rays))
    # depth precision: triangulation with half a pixel of error along the base
    assert s.depth_precision_m == pytest.approx(
        _triangulated_depth_error_m(base, height, 20.0, pitch_along), rel=0.01
    )
    assert s.direction_deg == pytest.approx(_true_bearing_of_first_line(plan), abs=0.05)
    assert s.pass_count == len(plan.passes) == 1
    assert s.line_count == len(
        {(int(p), int(ln)) for p, ln in zip(plan.stations.pass_index, plan.stations.line_index, strict=True)}
    )
    fired = replay_at_loop_rate(plan.mission)
    assert s.photo_count == len(plan.stations) == len(fired)
    assert s.item_count == len(plan.mission.items)
    assert s.max_item_count == 650
    distance, legs_s = _flown_distance_and_time(plan)
    assert s.flight_distance_m == pytest.approx(distance, rel=0.002)
    # the estimate adds the climbs, the descent and the stops to the time on the legs
    climbs = (spec.vehicle.takeoff_alt_m + abs(height - spec.vehicle.takeoff_alt_m) + height) / 2.5
    assert legs_s + climbs <= s.flight_time_s <= 1.35 * (legs_s + climbs)
    area = abs(GEOD.geometry_area_perimeter(plan.area_lonlat)[0])
    assert s.area_m2 == pytest.approx(area, rel=1e-6)


def _true_bearing_of_first_line(plan: SurveyPlan) -> float:
    line = plan.passes[0].lines[0]
    lon, lat = plan.frame.to_lonlat(np.array([line.start_xy_m[0], line.end_xy_m[0]]),
                                    np.array([line.start_xy_m[1], line.end_xy_m[1]]))  # fmt: skip
    azimuth, _, _ = GEOD.inv(lon[0], lat[0], lon[1], lat[1])
    return azimuth % 180.0


def _flown_distance_and_time(plan: SurveyPlan) -> tuple[float, float]:
    """Length of the path from home through every waypoint back home (WGS84 geodesic), and the
    time on those legs at the commanded speeds."""
    home = plan.mission.home
    points = [(home.lon_deg, home.lat_deg)]
    speeds = []
    speed = plan.mission.hover_speed_m_s
    for item in plan.mission.items:
        if item.command == MavCmd.DO_CHANGE_SPEED:
            speed = float(item.param2)  # type: ignore[arg-type]
        elif item.command == MavCmd.NAV_WAYPOINT:
            points.append((item.lon_deg, item.lat_deg))
            speeds.append(speed)
    points.append((home.lon_deg, home.lat_deg))
    speeds.append(speed)
    lon = np.array([p[0] for p in points])
    lat = np.array([p[1] for p in points])
    _, _, legs = GEOD.inv(lon[:-1], lat[:-1], lon[1:], lat[1:])
    return float(np.sum(legs)), float(np.sum(np.asarray(legs) / np.asarray(speeds)))


def test_bundled_examples_say_what_no_vehicle_can_fly() -> None:
    quarry = plan_survey(load_spec(MISSIONS / "quarry-block.toml"))
    items = len(quarry.mission.items) + 1
    assert items > 650
    assert any(f"{items} items" in w and "650" in w for w in quarry.warnings)
    hours = quarry.summary.flight_time_s / 3600.0
    assert hours > 0.5
    assert any(f"({hours:.1f} h)" in w and "battery" in w for w in quarry.warnings)
    gully = plan_survey(load_spec(MISSIONS / "bardenas-gully.toml"))
    assert not any("battery" in w or "items" in w for w in gully.warnings)


def test_warnings_speak_of_the_plan_as_flown_with_one_battery_model() -> None:
    """A vehicle with an endurance flies the plan as sorties that each fit its battery and the
    autopilot's memory: the whole plan then warns of neither; without one, the mission as planned
    warns of both, against max_flight_time_min, and names no code."""
    from planner.plan_run import plan_spec

    run = plan_spec(MISSIONS / "quarry-block-sorties.toml")
    assert run.sorties
    assert not any("items with home" in w or "battery" in w for w in run.plan.warnings), run.plan.warnings
    usable = run.spec.vehicle.usable_flight_s
    assert usable is not None
    for sortie in run.sorties:
        assert sortie.plan.summary.flight_time_s <= usable + 1e-6
        assert len(sortie.plan.mission.items) + 1 <= 650
        assert not sortie.plan.warnings, sortie.plan.warnings
    quarry = plan_survey(load_spec(MISSIONS / "quarry-block.toml"))
    assert any("ArduPilot holds (650" in w for w in quarry.warnings), quarry.warnings
    assert any("max_flight_time_min = 30" in w for w in quarry.warnings), quarry.warnings
    assert not any("planner." in w for w in quarry.warnings)
