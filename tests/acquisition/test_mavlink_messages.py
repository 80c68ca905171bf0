"""The MAVLink telemetry adapter: records survive the wire (packed and parsed by pymavlink),
in the units of MAVLink's common.xml, and time_usec is read as its firmware meant it."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from acquisition import mavlink_messages as mm

GPS_EPOCH_UNIX_S = 315_964_800  # 1980-01-06T00:00:00Z
LEAP_S_SINCE_2017 = 18  # GPS - UTC from 2017-01-01 (IERS Bulletin C)


def wire(msg: Any) -> Any:
    """Pack ``msg`` as a vehicle would and parse it back with pymavlink."""
    sender = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    data = msg.pack(sender)
    parser = mavlink2.MAVLink(None)
    parsed = parser.parse_char(bytearray(data))
    assert parsed is not None and parsed.get_type() == msg.get_type()
    return parsed


lat = st.floats(-90.0, 90.0)
lon = st.floats(-180.0, 180.0)
alt = st.floats(-400.0, 8000.0)
speed = st.floats(-60.0, 60.0)
boot_s = st.floats(0.0, 2_000_000.0)
angle = st.floats(-179.0, 179.0)


@settings(max_examples=200, deadline=None)
@given(lat, lon, alt, st.floats(0.0, 500.0), speed, speed, speed, st.floats(0.0, 359.99), boot_s)
def test_global_position_survives_the_wire_in_deg_e7_mm_and_cm_s(
    lat_deg: float,
    lon_deg: float,
    amsl: float,
    rel: float,
    vn: float,
    ve: float,
    vd: float,
    hdg: float,
    t: float,
) -> None:
    record = mm.GlobalPosition(
        time_boot_s=t,
        lat_deg=lat_deg,
        lon_deg=lon_deg,
        alt_amsl_m=amsl,
        alt_rel_home_m=rel,
        north_m_s=vn,
        east_m_s=ve,
        down_m_s=vd,
        heading_deg=hdg,
    )
    msg = wire(record.to_message())

    # the raw fields in MAVLink's units, computed here independently
    def nearest(raw: int, value: float) -> bool:  # rounded to the nearest unit
        return abs(raw - value) <= 0.5 + 1e-6

    assert nearest(msg.lat, lat_deg * 1e7) and nearest(msg.lon, lon_deg * 1e7)
    assert nearest(msg.alt, amsl * 1000) and nearest(msg.relative_alt, rel * 1000)
    assert nearest(msg.vx, vn * 100) and nearest(msg.vy, ve * 100) and nearest(msg.vz, vd * 100)
    back = mm.decode(msg)
    assert isinstance(back, mm.GlobalPosition)
    assert back.lat_deg == pytest.approx(lat_deg, abs=0.6e-7)
    assert back.lon_deg == pytest.approx(lon_deg, abs=0.6e-7)
    assert back.alt_amsl_m == pytest.approx(amsl, abs=0.5e-3 + 1e-9)
    assert back.alt_rel_home_m == pytest.approx(rel, abs=0.5e-3 + 1e-9)
    assert (back.north_m_s, back.east_m_s, back.down_m_s) == pytest.approx((vn, ve, vd), abs=0.005 + 1e-9)
    assert back.time_boot_s == pytest.approx(t, abs=0.0005 + 1e-9)
    assert back.has_position == (msg.lat != 0 or msg.lon != 0)


@settings(max_examples=100, deadline=None)
@given(lat, lon, alt, st.floats(0.0, 500.0), angle, angle, st.floats(0.0, 359.0), st.integers(1, 60_000))
def test_camera_feedback_survives_the_wire(
    lat_deg: float, lon_deg: float, amsl: float, rel: float, roll: float, pitch: float, yaw: float, index: int
) -> None:
    time_usec = 1_763_800_000_123_456
    record = mm.CameraFeedback(
        time_usec=time_usec,
        camera_index=0,
        image_index=index,
        lat_deg=lat_deg,
        lon_deg=lon_deg,
        alt_amsl_m=amsl,
        alt_rel_home_m=rel,
        roll_deg=roll,
        pitch_deg=pitch,
        yaw_deg=yaw,
    )
    back = mm.decode(wire(record.to_message()))
    assert isinstance(back, mm.CameraFeedback)
    assert (back.time_usec, back.image_index) == (time_usec, index)
    assert (back.lat_deg, back.lon_deg) == pytest.approx((lat_deg, lon_deg), abs=0.6e-7)
    # CAMERA_FEEDBACK carries metres and degrees as float32
    assert (back.alt_amsl_m, back.alt_rel_home_m) == pytest.approx((amsl, rel), rel=1e-6, abs=1e-4)
    assert (back.roll_deg, back.pitch_deg, back.yaw_deg) == pytest.approx((roll, pitch, yaw), abs=1e-4)


def test_attitude_is_radians_on_the_wire_and_degrees_in_the_record() -> None:
    record = mm.Attitude(time_boot_s=12.345, roll_deg=10.0, pitch_deg=-5.0, yaw_deg=270.0)
    msg = wire(record.to_message())
    assert msg.roll == pytest.approx(math.pi / 18, rel=1e-6)
    assert msg.yaw == pytest.approx(-math.pi / 2, rel=1e-6)  # ATTITUDE's yaw is -pi..pi
    assert msg.time_boot_ms == 12345
    back = mm.decode(msg)
    assert isinstance(back, mm.Attitude)
    assert (back.roll_deg, back.pitch_deg, back.yaw_deg) == pytest.approx((10.0, -5.0, -90.0), abs=1e-5)


def test_mount_status_is_centidegrees_pitch_a_roll_b_yaw_c() -> None:
    """ArduPilot's MOUNT_STATUS: pointing_a pitch, pointing_b roll, pointing_c yaw (cdeg)."""
    msg = wire(mavlink2.MAVLink_mount_status_message(1, 1, -9000, 150, 4500, 2))
    back = mm.decode(msg)
    assert back == mm.MountStatus(roll_deg=1.5, pitch_deg=-90.0, yaw_rel_deg=45.0)


def test_image_captured_without_utc_and_failed_captures_are_typed() -> None:
    msg = wire(
        mavlink2.MAVLink_camera_image_captured_message(
            5000, 0, 0, 422012000, -14866000, 400_000, 80_000, [1.0, 0.0, 0.0, 0.0], 7, 0, b""
        )
    )
    back = mm.decode(msg)
    assert isinstance(back, mm.CameraImageCaptured)
    assert back.time_utc_s is None and back.time_boot_s == 5.0 and not back.captured
    assert (back.lat_deg, back.lon_deg) == pytest.approx((42.2012, -1.4866), abs=1e-9)
    assert (back.alt_amsl_m, back.alt_rel_home_m) == (400.0, 80.0)


def test_heartbeat_says_who_and_whether_armed() -> None:
    gcs = mm.decode(wire(mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3)))
    copter = mm.decode(wire(mavlink2.MAVLink_heartbeat_message(2, 3, 128 | 1, 3, 4, 3)))
    assert isinstance(gcs, mm.Heartbeat) and isinstance(copter, mm.Heartbeat)
    assert not gcs.is_autopilot and gcs.is_ground_station and not gcs.armed
    assert copter.is_autopilot and not copter.is_ground_station and copter.armed
    assert mm.decode(wire(mavlink2.MAVLink_statustext_message(6, b"hello"))) is None


@pytest.mark.parametrize(
    ("flags", "earth"),
    [
        (0, False),  # nothing said: vehicle-relative (follow)
        (16, True),  # YAW_LOCK alone: locked to north
        (16 | 32, False),  # YAW_LOCK in the vehicle frame
        (64, True),  # YAW_IN_EARTH_FRAME
        (32, False),  # YAW_IN_VEHICLE_FRAME
        (4 | 8, False),  # roll and pitch lock say nothing of the yaw
    ],
)
def test_gimbal_yaw_frame_from_the_device_flags(flags: int, earth: bool) -> None:
    """GIMBAL_DEVICE_FLAGS of common.xml (values written out here, not read from pymavlink)."""
    assert bool(mm.gimbal_yaw_in_earth_frame(np.array([flags]))[0]) is earth


@settings(max_examples=200, deadline=None)
@given(st.floats(1_483_228_800.0, 1_893_456_000.0))  # 2017-2030: 18 leap seconds
def test_epoch_time_usec_is_unix_unless_gps_lands_nearer_the_arrival(utc_s: float) -> None:
    unix_us = round(utc_s * 1e6)
    gps_us = unix_us - GPS_EPOCH_UNIX_S * 10**6 + LEAP_S_SINCE_2017 * 10**6
    arrival = utc_s + 0.3
    t = mm.event_time_utc_s(np.array([unix_us, gps_us]), np.nan, arrival)
    assert t.utc_s == pytest.approx([unix_us / 1e6, unix_us / 1e6], abs=2e-6)
    assert list(t.gps_epoch) == [False, True] and not t.no_time.any()
    # with no arrival time known, the MAVLink definition (Unix) stands
    alone = mm.event_time_utc_s(gps_us, np.nan, np.nan)
    assert float(alone.utc_s) == pytest.approx(gps_us / 1e6, abs=2e-6) and not alone.gps_epoch.any()


def test_boot_and_zero_time_usec() -> None:
    t = mm.event_time_utc_s(
        np.array([0, 12_000_000, mm.BOOT_US_LIMIT - 1]), np.array([9.0, 100.0, 5.0]), 42.0
    )
    # 0: the arrival time; below the limit: the caller's boot clock
    assert list(t.utc_s) == [42.0, 100.0, 5.0]
    assert list(t.no_time) == [True, False, False] and not t.gps_epoch.any()
