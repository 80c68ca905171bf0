"""gather_inputs on real folders: a plan folder (its stations, counted in summary.json read as
plain JSON) and the Garfield images (the JPEGs listed by the file system), with the ground."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from shared_data import SHARED_DATA

from processing.check_inputs import gather_inputs
from processing.errors import FramesError, GroundError
from processing.frames import AltitudeReference, AttitudeSource

GARFIELD = SHARED_DATA / "garfield_rgb"


def test_a_plan_folder_gives_its_stations_on_its_own_ground(gully: tuple[Any, Path]) -> None:
    _, folder = gully
    inputs = gather_inputs(folder)
    summary = json.loads((folder / "summary.json").read_text())
    assert len(inputs.frames) == summary["photo_count"]
    assert inputs.frames.attitude_source is AttitudeSource.PLAN
    assert inputs.plan is not None and inputs.plan.planned.folder == folder
    assert inputs.plan.camera.id == summary["camera_id"]
    assert "take-off point" in inputs.ground_description
    assert inputs.notes == ("frames are the plan's stations (attitude as planned)",)
    with pytest.raises(FramesError, match="plan folder already"):
        gather_inputs(folder, plan_dir=folder)


def test_images_are_read_with_progress_and_judged_on_the_ground_given(gully: tuple[Any, Path]) -> None:
    jpegs = sorted(p.name for p in GARFIELD.iterdir() if p.suffix.lower() in (".jpg", ".jpeg"))
    calls: list[tuple[int, int]] = []
    inputs = gather_inputs(GARFIELD, ground_elevation_m=258.0, progress=lambda d, t: calls.append((d, t)))
    assert calls[-1] == (len(jpegs), len(jpegs)) and len(calls) == len(jpegs)
    kept = set(inputs.frames.name)
    assert kept | {name for name, _ in inputs.left_out} | set(inputs.unpositioned) == set(jpegs)
    assert inputs.frames.alt_reference is AltitudeReference.AMSL
    assert inputs.plan is None and inputs.camera_source
    assert inputs.notes[0] == f"camera: {inputs.camera_source}"
    with pytest.raises(GroundError, match="--ground-elevation-m"):
        gather_inputs(GARFIELD)
    flown = gather_inputs(GARFIELD, plan_dir=gully[1], ground_elevation_m=258.0)
    assert flown.plan is not None and flown.plan.planned.folder == gully[1]
