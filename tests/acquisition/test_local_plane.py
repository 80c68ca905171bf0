"""acquisition.local_plane against GeographicLib's geodesics (an independent construction):
distances between nearby positions, positions interpolated on the plane, the antimeridian, and
interpolate_poses placing frames on a track that crosses it."""

from __future__ import annotations

import numpy as np
import pytest
from geographiclib.geodesic import Geodesic
from hypothesis import given, settings
from hypothesis import strategies as st

from acquisition.interpolation import interpolate_poses
from acquisition.local_plane import LocalPlane, distances_m, segment_lengths_m
from acquisition.telemetry.model import PositionTrack

GEODESIC = Geodesic.WGS84

latitudes = st.floats(-85.0, 85.0)
longitudes = st.floats(-180.0, 180.0, exclude_max=True)
azimuths = st.floats(0.0, 360.0)


@settings(max_examples=300, deadline=None)
@given(lat=latitudes, lon=longitudes, azimuth=azimuths, length=st.floats(0.5, 1000.0))
def test_distance_of_nearby_positions_is_the_geodesic_one(
    lat: float, lon: float, azimuth: float, length: float
) -> None:
    end = GEODESIC.Direct(lat, lon, azimuth, length)
    measured = float(distances_m(lat, lon, end["lat2"], end["lon2"]))
    assert measured == pytest.approx(length, rel=1e-6)


@settings(max_examples=300, deadline=None)
@given(lat=st.floats(-80.0, 80.0), lon=longitudes, azimuth=azimuths, length=st.floats(1.0, 100.0))
def test_a_position_interpolated_on_the_plane_is_on_the_geodesic(
    lat: float, lon: float, azimuth: float, length: float
) -> None:
    """Half way between two track samples up to 100 m apart, on the plane tangent anywhere
    near them (here: 2 km away), within 1.5 mm of the geodesic's midpoint."""
    end = GEODESIC.Direct(lat, lon, azimuth, length)
    origin = GEODESIC.Direct(lat, lon, azimuth + 90.0, 2000.0)
    plane = LocalPlane.at(origin["lon2"], origin["lat2"])
    x, y = plane.to_xy([lon, end["lon2"]], [lat, end["lat2"]])
    mid_lon, mid_lat = plane.to_lonlat(x.mean(), y.mean())
    truth = GEODESIC.Direct(lat, lon, azimuth, length / 2.0)
    miss = GEODESIC.Inverse(float(mid_lat), float(mid_lon), truth["lat2"], truth["lon2"])["s12"]
    assert miss < 1.5e-3


@settings(max_examples=200, deadline=None)
@given(lat=latitudes, lon=longitudes, east=st.floats(-5e3, 5e3), north=st.floats(-5e3, 5e3))
def test_plane_coordinates_go_back_to_the_same_position(
    lat: float, lon: float, east: float, north: float
) -> None:
    plane = LocalPlane.at(lon, lat)
    lon2, lat2 = plane.to_lonlat(east, north)
    x, y = plane.to_xy(lon2, lat2)
    assert float(x) == pytest.approx(east, abs=1e-6)
    assert float(y) == pytest.approx(north, abs=1e-6)
    assert -180.0 <= float(lon2) < 180.0


def test_the_antimeridian_is_crossed_not_circled() -> None:
    lat = [-16.5, -16.5, -16.5]
    lon = [179.9999, -179.9999, -179.9997]
    lengths = segment_lengths_m(lat, lon)
    for k, length in enumerate(lengths):
        truth = GEODESIC.Inverse(lat[k], lon[k], lat[k + 1], lon[k + 1])["s12"]
        assert float(length) == pytest.approx(truth, rel=1e-6)
    plane = LocalPlane.centred_on(np.array(lon), np.array(lat))
    assert abs(abs(plane.lon0_deg) - 180.0) < 1e-3  # on the track, not at longitude 0


def test_interpolate_poses_across_the_antimeridian() -> None:
    """A track flying east at 10 m/s across 180 degrees, sampled at 1 Hz: frames between the
    samples are where the geodesic puts them, with the ground speed of the flight."""
    start = (-16.5, 179.9995)
    t = np.arange(0.0, 20.0)
    points = [GEODESIC.Direct(start[0], start[1], 90.0, 10.0 * s) for s in t]
    track = PositionTrack(
        time_utc_s=1.7e9 + t,
        lat_deg=np.array([p["lat2"] for p in points]),
        lon_deg=np.array([p["lon2"] for p in points]),
        alt_amsl_m=np.full(t.size, 100.0),
    )
    assert track.lon_deg.min() < -179.99 and track.lon_deg.max() > 179.99  # it crosses
    frames = 1.7e9 + np.array([3.25, 5.5, 12.75])
    poses = interpolate_poses(frames, positions=track).poses
    for time_s, pose in zip(frames, poses, strict=True):
        assert pose is not None
        truth = GEODESIC.Direct(start[0], start[1], 90.0, 10.0 * (time_s - 1.7e9))
        assert GEODESIC.Inverse(pose.lat_deg, pose.lon_deg, truth["lat2"], truth["lon2"])["s12"] < 1e-3
        assert -180.0 <= pose.lon_deg < 180.0
        assert pose.speed_m_s == pytest.approx(10.0, rel=1e-5)


def test_a_placeholder_position_half_a_world_away_is_not_used() -> None:
    """A "0, 0" sample before the fix, between real ones: the frame is placed between the real
    samples around it, not pulled towards the Gulf of Guinea."""
    t = 1.7e9 + np.arange(4.0)
    track = PositionTrack(
        time_utc_s=t,
        lat_deg=np.array([42.0, 0.0, 42.0002, 42.0003]),
        lon_deg=np.array([-93.0, 0.0, -93.0, -93.0]),
        alt_amsl_m=np.full(4, 300.0),
    )
    pose = interpolate_poses([t[0] + 1.0], positions=track, max_gap_s=5.0).poses[0]
    assert pose is not None
    assert pose.lat_deg == pytest.approx(42.0001, abs=1e-9)
    assert pose.lon_deg == pytest.approx(-93.0, abs=1e-9)
