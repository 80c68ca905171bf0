"""The motion-blur speed limit is taken along the motion: for an oblique flown toward or away from
where it looks, the GSD of the image's tilted axis at the near edge (finer than the lateral one
there), for one flown across, the lateral GSD; and the summary's limit is the one enforced.

The oracle is the pinhole camera over flat ground in closed form (no planner code): a ray at
angle a off the optical axis in the tilt plane meets the ground at theta = tilt - a from the
vertical; one pixel step along the tilt covers p H cos(a)^2 / (f cos(theta)^2) there, and one
across it p H cos(a) / (f cos(theta)).
"""

from __future__ import annotations

import dataclasses
import math

import pytest
from survey_oracles import MISSIONS

from planner.camera import Camera
from planner.errors import SpecError
from planner.spec import MissionSpec, load_spec
from planner.survey import plan_survey


def _step_along_motion_m(camera: Camera, height_m: float, tilt_deg: float, along_look: bool) -> float:
    f = camera.focal_length_mm
    if tilt_deg == 0.0:  # landscape: the lines run along the image's y axis
        return camera.pixel_pitch_y_mm * height_m / f
    a = math.atan(camera.sensor_height_mm / 2.0 / f)
    theta = math.radians(tilt_deg) - a
    if along_look:
        return camera.pixel_pitch_y_mm * height_m * math.cos(a) ** 2 / (f * math.cos(theta) ** 2)
    return camera.pixel_pitch_x_mm * height_m * math.cos(a) / (f * math.cos(theta))


def _quarry(shutter_s: float, speed_m_s: float) -> MissionSpec:
    spec = load_spec(MISSIONS / "quarry-block.toml")
    camera = dataclasses.replace(spec.camera, shutter_s=shutter_s)
    survey = dataclasses.replace(spec.survey, speed_m_s=speed_m_s)
    return dataclasses.replace(spec, camera=camera, survey=survey)


def test_oblique_blur_limit_is_taken_along_the_motion() -> None:
    shutter = 1.0 / 1000.0
    plan = plan_survey(_quarry(shutter, 5.0))
    st = plan.stations
    height = float(plan.summary.altitude_agl_m)
    assert plan.camera.shutter_s == shutter
    limits = []
    for index in sorted(set(st.pass_index.tolist())):
        k = int((st.pass_index == index).argmax())
        tilt = float(st.tilt_deg[k])
        off = abs((float(st.heading_deg[k]) - float(st.look_heading_deg[k]) + 90.0) % 180.0 - 90.0)
        limits.append(0.5 * _step_along_motion_m(plan.camera, height, tilt, off < 45.0) / shutter)
    expected = min(limits)
    assert plan.summary.max_speed_blur_m_s == pytest.approx(expected, rel=1e-3)
    # at the limit the plan is accepted, above it refused
    plan_survey(_quarry(shutter, math.floor(expected * 10.0) / 10.0))
    with pytest.raises(SpecError, match=r"blurs more than 0\.5 px"):
        plan_survey(_quarry(shutter, expected * 1.01))


def test_a_fore_aft_oblique_blurs_more_than_its_lateral_gsd_says() -> None:
    """The quarry's camera at 30 degrees: the along-look step at the near edge is finer than the
    lateral one, so the fore/aft limit is the lower."""
    spec = load_spec(MISSIONS / "quarry-block.toml")
    height = 100.0
    assert _step_along_motion_m(spec.camera, height, 30.0, True) < _step_along_motion_m(
        spec.camera, height, 30.0, False
    )
