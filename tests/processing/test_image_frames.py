"""Frames from real images (processing.image_frames): positions against exifread (a second EXIF
parser), attitude from the XMP tags or assumed along the track, images without a position listed."""

from __future__ import annotations

import shutil
from pathlib import Path

import exifread
import numpy as np
import pytest
from geographiclib.geodesic import Geodesic
from shared_data import SHARED_DATA

from acquisition.exif import GeoTag, read_tags, strip_gps, write_geotag
from planner.camera_db import get_camera
from processing.errors import FramesError
from processing.frames import AltitudeReference, AttitudeSource
from processing.image_frames import PLACEHOLDER_DEG, _position, frames_from_images, read_image_frames

GARFIELD = SHARED_DATA / "garfield_rgb"


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


# --- thresholds at their boundaries (exactly at, just below, just above) ---


@pytest.mark.parametrize(
    ("offset", "placeholder"),
    [(PLACEHOLDER_DEG * 0.999, True), (PLACEHOLDER_DEG, False), (PLACEHOLDER_DEG * 1.001, False)],
)
def test_placeholder_position(offset: float, placeholder: bool) -> None:
    from acquisition.exif import ImageTags

    tags = ImageTags(path="x.jpg", gps_lat_deg=offset, gps_lon_deg=offset, gps_alt_amsl_m=100.0)
    position, why = _position(tags, relative=False)
    assert (position is None) is placeholder
    if placeholder:
        assert "placeholder position at 0/0" in why
