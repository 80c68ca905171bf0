"""The steps a block and a corridor share (planner.survey_steps): the flying height from the
GSD (Eq. 3-4 of the textbook, written out here from the camera's numbers), home checked against
the area and the exclusions, the speed the trigger distance (Eq. 3-6) and the shutter allow, and
whole plans refused or adjusted with the fix named."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from survey_oracles import REPO, make_spec
from test_survey import to_lonlat_polygon

from planner import survey_steps as steps
from planner.errors import SpecError
from planner.kinds import PassKind
from planner.spec import MissionSpec, parse_spec
from planner.survey import plan_polygons


@settings(max_examples=50, deadline=None)
@given(gsd_cm=st.floats(0.5, 10.0))
def test_flying_height_is_the_gsd_times_focal_length_over_pixel_pitch(gsd_cm: float) -> None:
    spec = make_spec({"gsd_cm": gsd_cm})
    camera = spec.camera
    coarser_pitch_mm = max(
        camera.sensor_width_mm / camera.image_width_px, camera.sensor_height_mm / camera.image_height_px
    )
    expected_m = gsd_cm / 100.0 * camera.focal_length_mm / coarser_pitch_mm  # Eq. 3-4: H = GSD f / p
    if expected_m > 400.0:  # make_spec's vehicle limit
        with pytest.raises(
            SpecError, match=r"^\S+: gsd_cm = \S+ needs .* max_alt_agl_m = 400 m; ask for a finer gsd_cm"
        ):
            steps.flying_height(spec)
        return
    alt_agl_m, got_gsd_cm = steps.flying_height(spec)
    assert alt_agl_m == pytest.approx(expected_m, rel=1e-9)
    assert got_gsd_cm == pytest.approx(gsd_cm, rel=1e-9)


def _spec_with_home(home: list[float]) -> MissionSpec:
    data = {
        "name": "home",
        "area": "area.geojson",
        "camera": {"model": "dji-phantom-4-pro"},
        "survey": {"gsd_cm": 2.0, "front_overlap_pct": 75, "side_overlap_pct": 65},
        "vehicle": {"type": "multirotor", "max_alt_agl_m": 400, "home": home},
    }
    return parse_spec(data, REPO / "tests" / "spec.toml")


def test_home_far_from_the_area_or_inside_an_exclusion_is_refused() -> None:
    square = to_lonlat_polygon([(0, 0), (300, 0), (300, 200), (0, 200)])
    zone = to_lonlat_polygon([(-80, -80), (-20, -80), (-20, -20), (-80, -20)])
    c = square.centroid
    spec = _spec_with_home([c.x, c.y])  # [lon, lat]: swapped, thousands of km away
    site = steps.project_area(spec, [square], [zone], what="area")
    with pytest.raises(
        SpecError, match=r"more than 50 km from the area; they meet with latitude and longitude swapped"
    ):
        steps.home_position(spec, site, near=site.area_xy, default_xy=lambda: (0.0, 0.0), what="area")
    inside = zone.centroid
    spec = _spec_with_home([inside.y, inside.x])
    with pytest.raises(SpecError, match="home lies inside an exclusion zone"):
        steps.home_position(spec, site, near=site.area_xy, default_xy=lambda: (0.0, 0.0), what="area")
    spec = _spec_with_home([c.y, c.x])
    home, home_xy = steps.home_position(
        spec, site, near=site.area_xy, default_xy=lambda: (0.0, 0.0), what="area"
    )
    assert (home.lat_deg, home.lon_deg) == (c.y, c.x)
    # the lon/lat centroid projected lands within a metre of the projected area's centroid
    assert math.dist(home_xy, (site.area_xy.centroid.x, site.area_xy.centroid.y)) < 1.0


@settings(max_examples=60, deadline=None)
@given(trigger_m=st.floats(5.0, 60.0), speed_m_s=st.floats(1.0, 20.0))
def test_speed_is_kept_within_the_trigger_distance_over_the_camera_interval(
    trigger_m: float, speed_m_s: float
) -> None:
    spec = make_spec({"gsd_cm": 2.0, "speed_m_s": speed_m_s, "adjust_speed": True})
    pdef = steps.PassDef(
        kind=PassKind.NADIR, name="nadir", direction_deg=0.0, tilt_deg=0.0, look_heading_deg=None,
        front_overlap_pct=75.0, side_overlap_pct=65.0,
    )  # fmt: skip
    warnings: list[str] = []
    got = steps.check_speed(spec, pdef, trigger_m, 70.0, speed_m_s, warnings)
    camera = spec.camera
    limit = trigger_m / camera.min_trigger_interval_s  # Eq. 3-6: v <= B / dt
    if camera.shutter_s is not None:  # blur = v t / GSD along the line, at most max_blur_px
        gsd_along_m = camera.sensor_height_mm / camera.image_height_px * 70.0 / camera.focal_length_mm
        limit = min(limit, spec.survey.max_blur_px * gsd_along_m / camera.shutter_s)
    if speed_m_s <= limit:
        assert got == speed_m_s and not warnings
    else:
        assert got == math.floor(limit * 10) / 10 and "lowered" in warnings[0]


def test_speed_too_fast_is_refused_or_lowered() -> None:
    square = [(0, 0), (200, 0), (200, 150), (0, 150)]
    spec = make_spec({"gsd_cm": 1.0, "speed_m_s": 15.0, "front_overlap_pct": 90})
    with pytest.raises(SpecError, match=r"speed_m_s = 15 is too fast.*at most"):
        plan_polygons(spec, [to_lonlat_polygon(square)], [])
    spec = make_spec({"gsd_cm": 1.0, "speed_m_s": 15.0, "front_overlap_pct": 90, "adjust_speed": True})
    plan = plan_polygons(spec, [to_lonlat_polygon(square)], [])
    assert plan.summary.speed_m_s <= plan.summary.max_speed_m_s
    assert plan.warnings and "lowered" in plan.warnings[0]


def test_blur_limits_the_speed() -> None:
    square = [(0, 0), (200, 0), (200, 150), (0, 150)]
    camera = {"model": "dji-phantom-4-pro", "shutter_s": 0.01}  # 1/100 s: slow
    spec = make_spec({"gsd_cm": 1.0, "speed_m_s": 3.0, "front_overlap_pct": 60}, camera=camera)
    with pytest.raises(SpecError, match="blurs"):
        plan_polygons(spec, [to_lonlat_polygon(square)], [])


def test_gsd_above_the_height_limit_is_refused() -> None:
    square = [(0, 0), (200, 0), (200, 150), (0, 150)]
    spec = make_spec({"gsd_cm": 15.0})  # 548 m above ground with this camera; the limit is 400 m
    with pytest.raises(SpecError, match="max_alt_agl_m"):
        plan_polygons(spec, [to_lonlat_polygon(square)], [])
