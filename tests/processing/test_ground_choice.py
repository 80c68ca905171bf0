"""The ground a check projects onto (processing.ground_choice): refused rather than guessed, and a
constant DEM in another CRS gives the same footprints as the flat ground it describes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.transform import Affine
from shared_data import SHARED_DATA

from processing.errors import GroundError
from processing.footprints import project_footprints
from processing.frames import frames_local_frame
from processing.ground import DemGround, FlatGround
from processing.ground_choice import ground_from_options
from processing.image_frames import read_image_frames

GARFIELD = SHARED_DATA / "garfield_rgb"
#: Ground elevation used for the Garfield frames, metres AMSL: the images record no height
#: above ground; Garfield Heights (Ohio) lies at 253 m where it borders Cleveland, which is where
#: the frames are (lat 41.429, lon -81.606), so about 90-96 m above ground for altitudes of
#: 348-354 m AMSL.
GARFIELD_GROUND_M = 258.0


@pytest.fixture(scope="module")
def garfield() -> object:
    return read_image_frames(GARFIELD)


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
