"""Frames and ground for the coverage check: real images, plan folders, and the ground choice.

Oracles: exifread (a second EXIF parser) for the images' positions; GeographicLib for track
headings; the planner's own footprint corners for the attitude convention of plan frames.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import exifread
import numpy as np
import pytest
import rasterio
from geographiclib.geodesic import Geodesic
from rasterio.transform import Affine
from shared_data import SHARED_DATA

from acquisition.exif import GeoTag, read_tags, strip_gps, write_geotag
from planner.camera import Orientation
from planner.camera_db import get_camera
from planner.plan_folder import write_outputs
from planner.spec import load_spec, parse_spec
from planner.survey import plan_polygons, plan_survey
from processing.errors import FramesError, GroundError
from processing.footprints import project_footprints
from processing.frames import AltitudeReference, AttitudeSource
from processing.ground import DemGround, FlatGround
from processing.inputs import (
    frames_from_images,
    frames_from_plan,
    frames_from_track,
    frames_local_frame,
    ground_from_options,
    is_plan_folder,
    local_frame_at,
    read_image_frames,
    track_heading_deg,
)

GARFIELD = SHARED_DATA / "garfield_rgb"
MISSIONS = Path(__file__).resolve().parents[2] / "missions"
#: Ground elevation used for the Garfield frames, metres AMSL: the images record no height
#: above ground; Garfield Heights (Ohio) lies at 253 m where it borders Cleveland, which is where
#: the frames are (lat 41.429, lon -81.606), so about 90-96 m above ground for altitudes of
#: 348-354 m AMSL.
GARFIELD_GROUND_M = 258.0


def _exifread_position(path: Path) -> tuple[float, float, float]:
    with path.open("rb") as handle:
        tags = exifread.process_file(handle, details=False)

    def deg(key: str, ref: str) -> float:
        d, m, s = (float(v.num) / float(v.den) for v in tags[key].values)
        value = d + m / 60 + s / 3600
        return -value if str(tags[ref]) in ("S", "W") else value

    alt = tags["GPS GPSAltitude"].values[0]
    return (
        deg("GPS GPSLongitude", "GPS GPSLongitudeRef"),
        deg("GPS GPSLatitude", "GPS GPSLatitudeRef"),
        float(alt.num) / float(alt.den),
    )


@pytest.fixture(scope="module")
def garfield() -> object:
    return read_image_frames(GARFIELD)


def test_real_images_read_with_camera_attitude_and_order(garfield: object) -> None:
    images = garfield
    frames = images.frames  # type: ignore[attr-defined]
    assert len(frames) == 28 and images.unpositioned == ()  # type: ignore[attr-defined]
    assert frames.camera == get_camera("parrot-sequoia-rgb")
    assert "EXIF Parrot Sequoia" in images.camera_source  # type: ignore[attr-defined]
    assert frames.alt_reference is AltitudeReference.AMSL
    assert frames.attitude_source is AttitudeSource.XMP
    assert np.all(np.diff(frames.time_utc_s) > 0)  # capture order
    for k in (0, 13, 27):
        lon, lat, alt = _exifread_position(GARFIELD / frames.name[k])
        assert frames.lon_deg[k] == pytest.approx(lon, abs=1e-9)
        assert frames.lat_deg[k] == pytest.approx(lat, abs=1e-9)
        assert frames.alt_m[k] == pytest.approx(alt, abs=1e-6)
    # The first frame's XMP Camera:Yaw is -16.7996 deg: the same bearing, 0-360.
    assert frames.name[0] == "IMG_161122_163234_0000_RGB.JPG"
    assert frames.yaw_deg[0] == pytest.approx(360.0 - 16.7996)
    assert frames.pitch_deg[0] == pytest.approx(5.1846)
    assert frames.exposure_s is not None and frames.exposure_s[0] == pytest.approx(1 / 333, rel=0.01)


def test_images_without_position_are_listed_never_guessed(tmp_path: Path) -> None:
    names = sorted(p.name for p in GARFIELD.glob("*.JPG"))[:3]
    for name in names[:2]:
        shutil.copy(GARFIELD / name, tmp_path / name)
    strip_gps(GARFIELD / names[2], tmp_path / names[2])
    images = read_image_frames(tmp_path)
    assert images.unpositioned == (names[2],)
    assert images.frames.name == tuple(names[:2])
    assert any(names[2] in note for note in images.notes)
    with pytest.raises(FramesError, match=names[2]):
        frames_from_images(tmp_path)


def test_without_xmp_attitude_frames_are_nadir_along_the_track(tmp_path: Path) -> None:
    names = sorted(p.name for p in GARFIELD.glob("*.JPG"))[:4]  # one line flown north
    for name in names:
        tags = read_tags(GARFIELD / name)
        stripped = tmp_path / f"stripped-{name}"
        strip_gps(GARFIELD / name, stripped, attitude=True)
        assert tags.gps_lat_deg is not None and tags.gps_lon_deg is not None
        write_geotag(
            stripped,
            tmp_path / name,
            GeoTag(
                lat_deg=tags.gps_lat_deg,
                lon_deg=tags.gps_lon_deg,
                alt_amsl_m=tags.gps_alt_amsl_m,
                time_utc_s=tags.gps_time_utc_s,
            ),
        )
        stripped.unlink()
    frames = frames_from_images(tmp_path)
    assert frames.attitude_source is AttitudeSource.ASSUMED_NADIR
    assert np.all(frames.pitch_deg == 0) and np.all(frames.roll_deg == 0)
    # Heading of the middle frame: the bearing from the previous frame to the next one.
    g = Geodesic.WGS84.Inverse(frames.lat_deg[0], frames.lon_deg[0], frames.lat_deg[2], frames.lon_deg[2])
    assert frames.yaw_deg[1] == pytest.approx(g["azi1"] % 360.0, abs=1e-6)
    assert frames.yaw_deg[1] < 5.0 or frames.yaw_deg[1] > 355.0  # the line runs north


def test_track_heading_along_lines_and_at_turns() -> None:
    # Two lines flown north then south, 10 m between frames, 40 m apart (at 42 N).
    d_lat = 10.0 / 111_000.0
    d_lon = 40.0 / 82_700.0
    lat = 42.0 + d_lat * np.array([0, 1, 2, 3, 3, 2, 1, 0])
    lon = -1.5 + d_lon * np.array([0, 0, 0, 0, 1, 1, 1, 1])
    heading = track_heading_deg(lon, lat)
    # Inside a line: the bearing from the previous frame to the next (GeographicLib).
    expected = Geodesic.WGS84.Inverse(lat[0], lon[0], lat[2], lon[2])["azi1"] % 360.0
    assert heading[1] == pytest.approx(expected, abs=1e-9)
    assert heading[0] == pytest.approx(0.0, abs=1e-6)  # first frame: its one step, north
    # The last frame of the first line and the first of the second: the turn is between
    # them, so each takes its own line's direction, not the diagonal across the turn.
    assert heading[3] == pytest.approx(0.0, abs=1e-6)
    assert heading[4] == pytest.approx(180.0, abs=0.01)
    assert heading[7] == pytest.approx(180.0, abs=0.01)
    # Standing still: 0 by convention; a single frame: 0.
    still = track_heading_deg(np.array([0.0, 0.0]), np.array([1.0, 1.0]))
    assert still.tolist() == [0.0, 0.0]
    assert track_heading_deg(np.array([1.0]), np.array([2.0])).tolist() == [0.0]


def test_amsl_frames_need_a_ground(garfield: object) -> None:
    frames = garfield.frames  # type: ignore[attr-defined]
    with pytest.raises(GroundError, match="--ground-elevation-m"):
        ground_from_options(frames=frames)
    choice = ground_from_options(frames=frames, ground_elevation_m=GARFIELD_GROUND_M)
    assert isinstance(choice.ground, FlatGround) and choice.ground.elevation_m == GARFIELD_GROUND_M
    assert "258 m" in choice.description
    with pytest.raises(GroundError, match="within a few metres of the ground or under it"):
        ground_from_options(frames=frames, ground_elevation_m=350.0)
    with pytest.raises(GroundError, match="give one"):
        ground_from_options(frames=frames, ground_elevation_m=258.0, dem="x.tif")


def test_a_constant_dem_in_another_crs_gives_the_flat_ground(garfield: object, tmp_path: Path) -> None:
    frames = garfield.frames  # type: ignore[attr-defined]
    dem = tmp_path / "dem.tif"
    with rasterio.open(
        dem, "w", driver="GTiff", width=60, height=60, count=1, dtype="float32", crs="EPSG:4326",
        transform=Affine(0.0002, 0.0, -81.6120, 0.0, -0.0002, 41.4360),
    ) as dst:  # fmt: skip
        dst.write(np.full((1, 60, 60), GARFIELD_GROUND_M, dtype="float32"))
    choice = ground_from_options(frames=frames, dem=dem)
    assert isinstance(choice.ground, DemGround)
    flat = ground_from_options(frames=frames, ground_elevation_m=GARFIELD_GROUND_M)
    local = frames_local_frame(frames)
    a = project_footprints(choice.frames, local, choice.ground)
    b = project_footprints(flat.frames, local, flat.ground)
    np.testing.assert_allclose(a.height_above_ground_m, b.height_above_ground_m, atol=1e-3)
    np.testing.assert_allclose(a.xy_m, b.xy_m, atol=0.01)


@pytest.fixture(scope="module")
def gully_plan(tmp_path_factory: pytest.TempPathFactory) -> tuple[object, Path]:
    plan = plan_survey(load_spec(MISSIONS / "bardenas-gully.toml"))
    folder = tmp_path_factory.mktemp("plans") / "gully"
    write_outputs(plan, folder)
    return plan, folder


def test_plan_folder_frames_match_the_stations(gully_plan: tuple[object, Path]) -> None:
    plan, folder = gully_plan
    assert is_plan_folder(folder) and not is_plan_folder(GARFIELD)
    frames, info = frames_from_plan(folder)
    st = plan.stations  # type: ignore[attr-defined]
    assert len(frames) == len(st)
    np.testing.assert_allclose(frames.lon_deg, st.lon_deg, atol=1e-8)
    np.testing.assert_allclose(frames.lat_deg, st.lat_deg, atol=1e-8)
    np.testing.assert_allclose(frames.alt_m, st.alt_rel_home_m, atol=0.01)
    assert frames.alt_reference is AltitudeReference.REL_HOME
    assert frames.attitude_source is AttitudeSource.PLAN
    assert frames.line_index is not None and len(np.unique(frames.line_index)) == plan.summary.line_count  # type: ignore[attr-defined]
    assert info.front_overlap_pct == 80 and info.side_overlap_pct == 70
    assert info.camera.id == "canon-eos-350d-20mm"
    assert info.area_lonlat is not None
    assert info.area_lonlat.symmetric_difference(plan.area_lonlat).area < 1e-6 * plan.area_lonlat.area  # type: ignore[attr-defined]
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


def test_plan_folder_errors(tmp_path: Path, gully_plan: tuple[object, Path]) -> None:
    _, folder = gully_plan
    with pytest.raises(FramesError, match="not a plan folder"):
        frames_from_plan(tmp_path)
    broken = tmp_path / "broken"
    shutil.copytree(folder, broken)
    summary = json.loads((broken / "summary.json").read_text())
    summary["camera_id"] = "no-such-camera"
    (broken / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(FramesError, match="custom camera"):
        frames_from_plan(broken)


def test_frames_from_track_point_the_image_top_along_the_track() -> None:
    camera = get_camera("dji-phantom-4-pro")
    lon = np.array([-1.5, -1.499, -1.498])  # flying east
    lat = np.full(3, 42.0)
    kwargs: dict[str, Any] = {
        "name": ["a", "b", "c"], "lon_deg": lon, "lat_deg": lat, "alt_m": np.full(3, 60.0),
        "alt_reference": AltitudeReference.REL_HOME, "camera": camera,
    }  # fmt: skip
    landscape = frames_from_track(**kwargs)
    expected = Geodesic.WGS84.Inverse(42.0, -1.5, 42.0, -1.498)["azi1"]
    assert landscape.yaw_deg[1] == pytest.approx(expected, abs=1e-9)
    assert landscape.attitude_source is AttitudeSource.ASSUMED_NADIR
    portrait = frames_from_track(**kwargs, orientation=Orientation.PORTRAIT)
    np.testing.assert_allclose(portrait.yaw_deg, (landscape.yaw_deg - 90.0) % 360.0)
