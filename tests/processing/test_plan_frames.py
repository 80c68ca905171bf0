"""A plan folder as frames (processing.plan_frames): the stations read back against the planner's
own stations, and the planner's own footprint corners as the oracle of the attitude convention."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from shared_data import SHARED_DATA

from planner.errors import PlanFolderError
from planner.plan_folder import is_plan_folder, write_outputs
from planner.spec import parse_spec
from planner.survey import plan_polygons
from processing.errors import FramesError, GroundError
from processing.footprints import project_footprints
from processing.frames import AltitudeReference, AttitudeSource, local_frame_at
from processing.ground_choice import ground_from_options
from processing.plan_frames import frames_from_plan

GARFIELD = SHARED_DATA / "garfield_rgb"


def test_plan_folder_frames_match_the_stations(gully: tuple[object, Path], tmp_path: Path) -> None:
    plan, folder = gully
    (tmp_path / "IMG_0001.JPG").write_bytes(b"\xff\xd8\xff\xd9")  # a folder of frames, not a plan
    assert is_plan_folder(folder) and not is_plan_folder(tmp_path)
    frames, info = frames_from_plan(folder)
    st = plan.stations  # type: ignore[attr-defined]
    assert len(frames) == len(st)
    np.testing.assert_allclose(frames.lon_deg, st.lon_deg, atol=1e-8)
    np.testing.assert_allclose(frames.lat_deg, st.lat_deg, atol=1e-8)
    np.testing.assert_allclose(frames.alt_m, st.alt_rel_home_m, atol=0.01)
    assert frames.alt_reference is AltitudeReference.REL_HOME
    assert frames.attitude_source is AttitudeSource.PLAN
    assert frames.line_index is not None and len(np.unique(frames.line_index)) == plan.summary.line_count  # type: ignore[attr-defined]
    assert info.planned.summary.front_overlap_pct == 80 and info.planned.summary.side_overlap_pct == 70
    assert info.camera.id == "canon-eos-350d-20mm"
    assert info.planned.area_lonlat is not None
    assert info.planned.area_lonlat.symmetric_difference(plan.area_lonlat).area < 1e-6 * plan.area_lonlat.area  # type: ignore[attr-defined]
    choice = ground_from_options(frames=frames)
    assert "take-off point" in choice.description
    with pytest.raises(GroundError, match="--takeoff-elevation-m"):
        ground_from_options(frames=frames, ground_elevation_m=400.0)
    shifted = ground_from_options(frames=frames, ground_elevation_m=400.0, takeoff_elevation_m=410.0)
    assert shifted.frames.alt_reference is AltitudeReference.AMSL
    np.testing.assert_allclose(shifted.frames.alt_m, frames.alt_m + 410.0)


def _spec(orientation: str, oblique: bool) -> object:
    data = {
        "name": "square",
        "area": "square.geojson",
        "camera": {"model": "dji-phantom-4-pro", "orientation": orientation},
        "survey": {"altitude_agl_m": 60.0, "front_overlap_pct": 75, "side_overlap_pct": 65},
        "vehicle": {"home": [42.0, -1.5]},
    }
    if oblique:
        data["survey"]["oblique"] = [{"tilt_deg": 30.0, "headings_deg": [0, 90]}]  # type: ignore[index]
    return parse_spec(data, Path("square.toml"))


@pytest.mark.parametrize(("orientation", "oblique"), [("landscape", True), ("portrait", False)])
def test_plan_attitude_reproduces_the_planners_footprints(
    tmp_path: Path, orientation: str, oblique: bool
) -> None:
    from shapely.geometry import box

    spec = _spec(orientation, oblique)  # a camera missing from the database is a failure, not a skip
    plan = plan_polygons(spec, [box(-1.5, 42.0, -1.4985, 42.0012)], [])  # type: ignore[arg-type]
    write_outputs(plan, tmp_path / "plan")
    frames, _ = frames_from_plan(tmp_path / "plan")
    st = plan.stations
    if oblique:
        assert (frames.pitch_deg > 0).any()
    # Projected by the check in its frame (transverse Mercator on the area: grid north is true
    # north), the frames read back from the plan files land their corners on the planner's own
    # footprint corners (the same ground points, compared in lon/lat through that frame).
    centre = plan.area_lonlat.centroid
    local = local_frame_at(centre.x, centre.y)
    choice = ground_from_options(frames=frames)
    fp = project_footprints(choice.frames, local, choice.ground, edge_samples=0)
    corners = st.footprint_lonlat_deg
    expected = np.stack(local.to_xy(corners[..., 0], corners[..., 1]), axis=-1)
    # cm: stations.geojson rounds altitudes to 1 cm; the planner's UTM metres are 0.02 % short.
    np.testing.assert_allclose(fp.xy_m, expected, atol=0.05)
    # In the plan's UTM frame (grid north 1 deg off true north here) the footprints would turn
    # about their cameras by that angle: the reason the check works in its own frame.
    convergence = plan.frame.true_north_grid_bearing_deg(centre.x, centre.y)
    assert abs(convergence) > 0.9
    assert abs(local.true_north_grid_bearing_deg(centre.x, centre.y)) < 1e-6


def test_plan_folder_errors(tmp_path: Path, gully: tuple[object, Path]) -> None:
    _, folder = gully
    with pytest.raises(PlanFolderError, match="not a plan folder"):
        frames_from_plan(tmp_path)
    broken = tmp_path / "broken"
    shutil.copytree(folder, broken)
    summary = json.loads((broken / "summary.json").read_text())
    summary["camera_id"] = "no-such-camera"
    (broken / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(FramesError, match="custom camera"):
        frames_from_plan(broken)
