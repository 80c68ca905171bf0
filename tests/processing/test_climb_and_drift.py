"""Frames on the climb and the descent left out of the block's figures, and drifting GPS altitudes
with the true ground given: no refusal, one warning that says what was assumed (issue 26)."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyexiv2
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st
from shared_data import SHARED_DATA
from test_footprints import CAMERA, ORIGIN_X_M, ORIGIN_Y_M, make_frames

from processing.check import run_check
from processing.frames import AttitudeSource, Frames
from processing.ground_choice import ground_from_options
from processing.image_frames import read_image_frames
from processing.survey_frames import altitude_trend
from sfap.cli import cli

GROUND_M = 100.0
CRUISE_M = 70.0
#: GSD of a nadir frame over flat ground at the cruise height: pixel pitch x H / f (cm).
CRUISE_GSD_CM = CAMERA.sensor_width_mm / CAMERA.image_width_px * CRUISE_M / CAMERA.focal_length_mm * 100.0
CLIMB_M = (1.0, 12.0, 24.0, 36.0, 48.0, 58.0)  # take-off, then the climb (each under 63 m)
DESCENT_M = (58.0, 45.0, 30.0, 15.0, 1.0)  # the descent, then landing


def flight(
    drift_m: float = 0.0, noise_m: float = 0.0, seed: int = 0
) -> tuple[Frames, list[str], list[str], list[str]]:
    """A card: take-off and climb at home, 4 lines of 10 frames at CRUISE_M, descent and landing
    at home, 2 s apart; the GPS altitude drifts linearly in time by ``drift_m`` over the card
    (right at mid-flight: -drift_m / 2 at take-off) and has ``noise_m`` of noise. Returns the
    frames and the names of the climb, descent and ground frames."""
    xs: list[float] = []
    ys: list[float] = []
    hs: list[float] = []
    kind: list[str] = []
    for h in CLIMB_M:
        xs.append(-20.0)
        ys.append(0.0)
        hs.append(h)
        kind.append("ground" if h < 3 else "climb")
    for line in range(4):
        for k in range(10):
            xs.append(20.0 * (k if line % 2 == 0 else 9 - k))
            ys.append(30.0 * line)
            hs.append(CRUISE_M)
            kind.append("cruise")
    for h in DESCENT_M:
        xs.append(-20.0)
        ys.append(90.0)
        hs.append(h)
        kind.append("ground" if h < 3 else "descent")
    n = len(xs)
    t = 1.7e9 + 2.0 * np.arange(n)
    alt = GROUND_M + np.array(hs) + drift_m * ((t - t[0]) / (t[-1] - t[0]) - 0.5)
    alt += np.random.default_rng(seed).uniform(-noise_m, noise_m, n) * (np.array(kind) == "cruise")
    frames = make_frames(ORIGIN_X_M + np.array(xs), ORIGIN_Y_M + np.array(ys), alt)
    frames = replace(frames, attitude_source=AttitudeSource.ASSUMED_NADIR, time_utc_s=t)
    names = frames.name

    def of(which: str) -> list[str]:
        return [names[k] for k in range(n) if kind[k] == which]

    return frames, of("climb"), of("descent"), of("ground")


def test_the_climb_and_the_descent_are_left_out_with_their_heights() -> None:
    frames, climb, descent, ground = flight()
    choice = ground_from_options(frames=frames, ground_elevation_m=GROUND_M)
    why = dict(choice.left_out)
    assert sorted(why) == sorted(climb + descent + ground)
    for name, h in zip(climb, CLIMB_M[1:], strict=True):
        assert why[name].startswith(f"climbing: {h:.1f} m above the ground"), why[name]
    for name, h in zip(descent, DESCENT_M[:-1], strict=True):
        assert why[name].startswith(f"descending: {h:.1f} m above the ground"), why[name]
    assert not choice.warnings  # no drift
    result = run_check(choice.frames, ground=choice.ground, left_out=choice.left_out)
    # The block's GSD figures are the cruise's alone (flat ground, nadir: the pinhole's).
    assert len(result.frames) == 40
    assert float(np.nanmin(result.gsd_cm)) == pytest.approx(CRUISE_GSD_CM, rel=1e-3)
    assert float(np.nanmax(result.gsd_cm)) == pytest.approx(CRUISE_GSD_CM, rel=1e-3)
    assert not any("scale" in w and "differ" in w for w in result.warnings), result.warnings


@settings(max_examples=25, deadline=None)
@given(noise=st.floats(0.0, 3.0), seed=st.integers(0, 10_000))
def test_gps_noise_in_the_cruise_leaves_every_survey_frame_in(noise: float, seed: int) -> None:
    frames, climb, descent, ground = flight(noise_m=noise, seed=seed)
    choice = ground_from_options(frames=frames, ground_elevation_m=GROUND_M)
    assert sorted(name for name, _ in choice.left_out) == sorted(climb + descent + ground)


def test_with_drifting_altitudes_the_climb_is_told_on_the_detrended_altitudes() -> None:
    # +100 m of drift over the card: the raw altitudes put the late cruise 100 m above the early,
    # and the take-off 50 m under the ground. Right at mid-flight, as the detrending assumes.
    frames, climb, descent, ground = flight(drift_m=100.0)
    choice = ground_from_options(frames=frames, ground_elevation_m=GROUND_M)
    assert sorted(name for name, _ in choice.left_out) == sorted(climb + descent + ground)
    assert len(choice.warnings) == 1
    assert "GPS altitude drifts by +100.0 m" in choice.warnings[0]
    assert "detrended altitudes" in choice.warnings[0] and "one height" in choice.warnings[0]
    # The trend removed is carried, typed, to the check (which then blames a scale that disagrees
    # on the heights); without drift there is none.
    assert choice.detrended is not None and choice.detrended.drift_m == pytest.approx(100.0, rel=0.02)
    assert ground_from_options(frames=flight()[0], ground_elevation_m=GROUND_M).detrended is None
    # One flying height: every survey frame at the same height once detrended.
    heights = choice.frames.alt_m - GROUND_M
    assert float(np.ptp(heights)) == pytest.approx(0.0, abs=1e-6)


GARFIELD = SHARED_DATA / "garfield_rgb"
GARFIELD_GROUND_M = 258.0


def test_drifting_altitudes_with_the_true_ground_do_not_make_the_check_refuse(tmp_path: Path) -> None:
    if not GARFIELD.is_dir():
        pytest.skip(f"{GARFIELD} is absent")
    card = tmp_path / "card"
    shutil.copytree(GARFIELD, card)
    images = read_image_frames(GARFIELD)
    t = images.frames.time_utc_s
    assert t is not None
    for k, name in enumerate(images.frames.name):
        # Flown at one height; the GPS altitude starts 70 m low (the first frames under the
        # ground) and drifts by +100 m over the flight.
        alt = GARFIELD_GROUND_M + 60.0 - 70.0 + 100.0 * (t[k] - t.min()) / (t.max() - t.min())
        path = card / name
        path.chmod(0o644)
        with pyexiv2.Image(str(path)) as image:
            image.modify_exif({"Exif.GPSInfo.GPSAltitude": f"{round(alt * 100)}/100"})
    args = ["check", str(card), "--ground-elevation-m", str(GARFIELD_GROUND_M), "--no-progress"]
    result = CliRunner().invoke(cli, [*args, "--no-pixels", "--json"])
    output = result.output
    assert "ellipsoid" not in output, output
    data = json.loads(output[output.index("{") :])
    assert result.exit_code == (0 if data["passed"] else 1), output
    said = [w for w in data["warnings"] if "GPS altitude drifts by +100.0 m" in w]
    assert len(said) == 1 and "detrended altitudes" in said[0] and "one height" in said[0], data["warnings"]
    # What `sfap check` hands run_check: the trend itself, not a sentence to search.
    from processing.check_inputs import gather_inputs

    inputs = gather_inputs(card, ground_elevation_m=GARFIELD_GROUND_M)
    assert inputs.detrended is not None and inputs.detrended.drift_m == pytest.approx(100.0, rel=0.1)


@settings(max_examples=25, deadline=None)
@given(drift=st.floats(-150.0, 150.0))
def test_the_trend_is_the_cruise_drift_not_the_climb(drift: float) -> None:
    # The take-off, climb, descent and landing (11 of 51 frames) do not tilt the line.
    frames, *_ = flight(drift_m=drift)
    assert frames.time_utc_s is not None
    trend = altitude_trend(frames.alt_m, frames.time_utc_s)
    assert trend is not None
    assert trend.drift_m == pytest.approx(drift, abs=1e-6)
