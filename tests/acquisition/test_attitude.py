"""Camera attitude: vehicle and gimbal combined, checked against vectors built from definitions.

The truth here is built with plain rotation matrices written in this file, not with
:mod:`acquisition.attitude`: a forward-looking gimbal camera (x the optical axis, y image right,
z image down) turned by its mount angles, and the written Pix4D (yaw, pitch, roll) turned back
into the optical axis (the down axis of an airframe with those angles) and the image-up vector
(its nose), as REFERENCES.md section 6 defines them.
"""

from __future__ import annotations

import math
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shared_data import SHARED_DATA

from acquisition import attitude
from acquisition.interpolation import interpolate_poses
from acquisition.telemetry import read_log
from acquisition.telemetry.model import AttitudeTrack, PositionTrack

SITL = SHARED_DATA / "ardupilot_sitl_plane"


def rz(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def ry(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rx(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def ned_from_body(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Aerospace yaw-pitch-roll: turn about down, then the new right axis, then the new nose."""
    return rz(yaw) @ ry(pitch) @ rx(roll)


X, Y, Z = np.eye(3)


def gimbal_camera_vectors(camera: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(optical axis, image up) in NED of a forward-looking camera frame: x looks, -z is up."""
    return camera @ X, -(camera @ Z)


def pix4d_vectors(yaw: float, pitch: float, roll: float) -> tuple[np.ndarray, np.ndarray]:
    """(optical axis, image up) of Pix4D angles: the airframe's down axis and its nose."""
    frame = ned_from_body(yaw, pitch, roll)
    return frame @ Z, frame @ X


def written_vectors(ypr: tuple[Any, Any, Any]) -> tuple[np.ndarray, np.ndarray]:
    y, p, r = (float(np.asarray(a).ravel()[0]) for a in ypr)
    assert 0.0 <= y < 360.0 and -90.0 <= p <= 90.0 and -180.0 <= r <= 180.0
    return pix4d_vectors(y, p, r)


def assert_same_pointing(
    written: tuple[np.ndarray, np.ndarray], truth: tuple[np.ndarray, np.ndarray]
) -> None:
    # 1e-7: the Euler angles of a rotation within 1e-8 rad of gimbal lock are taken as locked.
    np.testing.assert_allclose(written[0], truth[0], atol=1e-7)
    np.testing.assert_allclose(written[1], truth[1], atol=1e-7)


angles = st.floats(-180, 180, allow_nan=False)
# Gimbal pitches: straight down (gimbal lock of the Euler angles) and near it are the survey case.
gimbal_pitch = st.one_of(
    st.just(-90.0), st.floats(-90, -89.999), st.floats(-90, 30), st.just(90.0), st.floats(89.999, 90)
)
vehicle = st.tuples(st.floats(0, 359.999), st.floats(-30, 30), st.floats(-45, 45))
gimbal = st.tuples(angles, gimbal_pitch, st.floats(-20, 20))


@settings(max_examples=300, deadline=None)
@given(v=vehicle, g=gimbal)
def test_earth_frame_gimbal(v: tuple[float, float, float], g: tuple[float, float, float]) -> None:
    """Gimbal yaw from north, pitch and roll from the horizon (GIMBAL_DEVICE_ATTITUDE_STATUS
    with YAW_IN_EARTH_FRAME, DataFlash MNT YawE): the vehicle's attitude does not matter."""
    truth = gimbal_camera_vectors(ned_from_body(g[0], g[1], g[2]))
    written = attitude.camera_attitude_deg(([v[0]], [v[1]], [v[2]]), ([g[0]], [g[1]], [g[2]]))
    assert_same_pointing(written_vectors(written), truth)


@settings(max_examples=300, deadline=None)
@given(v=vehicle, g=gimbal)
def test_stabilized_gimbal(v: tuple[float, float, float], g: tuple[float, float, float]) -> None:
    """Yaw from the vehicle's nose, pitch and roll from the horizon (ArduPilot MOUNT_STATUS,
    MNT YawB, GIMBAL_DEVICE_ATTITUDE_STATUS with YAW_IN_VEHICLE_FRAME)."""
    truth = gimbal_camera_vectors(rz(v[0]) @ ned_from_body(g[0], g[1], g[2]))
    written = attitude.camera_attitude_deg(
        ([v[0]], [v[1]], [v[2]]), ([g[0]], [g[1]], [g[2]]), attitude.GimbalMode.STABILIZED
    )
    assert_same_pointing(written_vectors(written), truth)


@settings(max_examples=300, deadline=None)
@given(v=vehicle, g=gimbal)
def test_body_frame_gimbal(v: tuple[float, float, float], g: tuple[float, float, float]) -> None:
    """All three mount angles relative to the airframe (an unstabilized mount)."""
    truth = gimbal_camera_vectors(ned_from_body(*v) @ ned_from_body(g[0], g[1], g[2]))
    written = attitude.camera_attitude_deg(
        ([v[0]], [v[1]], [v[2]]), ([g[0]], [g[1]], [g[2]]), attitude.GimbalMode.BODY
    )
    assert_same_pointing(written_vectors(written), truth)


@settings(max_examples=200, deadline=None)
@given(v=vehicle)
def test_camera_fixed_to_the_airframe(v: tuple[float, float, float]) -> None:
    """No gimbal: the camera looks along the airframe's down axis, image top to the nose."""
    frame = ned_from_body(*v)
    written = attitude.camera_attitude_deg(([v[0]], [v[1]], [v[2]]))
    assert_same_pointing(written_vectors(written), (frame @ Z, frame @ X))


@settings(max_examples=300, deadline=None)
@given(yaw=st.floats(0, 359.999), pitch=gimbal_pitch, roll=angles)
def test_euler_angles_of_a_quaternion_give_back_its_rotation(yaw: float, pitch: float, roll: float) -> None:
    """Also in gimbal lock (pitch +-90), where yaw and roll turn about one axis: the angles read
    back describe the same rotation, yaw carries the turn, roll is 0."""
    y, p, r = attitude.euler_deg_from_quat(attitude.quat_from_euler_deg(yaw, pitch, roll))
    np.testing.assert_allclose(
        ned_from_body(float(y[0]), float(p[0]), float(r[0])), ned_from_body(yaw, pitch, roll), atol=1e-7
    )
    if abs(pitch) == 90.0:
        assert float(r[0]) == 0.0


# ------------------------------------------------ the case, through a real tlog reader

UTC_AT_BOOT = 1_760_000_000.0
LINE_YAW = 96.0


def _vehicle_yaw(t: float) -> float:
    return LINE_YAW + 3.0 * math.sin(t / 4.0)  # crabbing in gusts along a line flown at 96 deg


def _vehicle_roll(t: float) -> float:
    return 4.0 * math.sin(t / 3.0)


def _record(mav: Any, msg: Any, rx_us: int) -> bytes:
    return struct.pack(">Q", rx_us) + bytes(msg.pack(mav))


def _mavlink_quaternion(camera: np.ndarray) -> list[float]:
    """(w, x, y, z) of a rotation matrix (Shepperd's method, written out here)."""
    m = camera
    w = math.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2.0
    x = math.copysign(math.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2.0, m[2, 1] - m[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2.0, m[0, 2] - m[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2.0, m[1, 0] - m[0, 1])
    return [w, x, y, z]


def _gimbal_tlog(path: Path, gimbal: str) -> None:
    """40 s of a line flown at about 96 deg, 10 Hz ATTITUDE and position, SYSTEM_TIME, and a
    gimbal held straight down sent as ``gimbal``: GIMBAL_DEVICE_ATTITUDE_STATUS with its yaw in
    the vehicle frame (flags 32, ArduPilot's mount drivers), GIMBAL_DEVICE_ATTITUDE_STATUS in
    the earth frame (flags 64, holding 96 deg), or ArduPilot's MOUNT_STATUS (yaw relative)."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    out = bytearray(_record(mav, mav.heartbeat_encode(1, 3, 0, 0, 0), round(UTC_AT_BOOT * 1e6)))
    for k in range(401):
        boot = k * 0.1
        boot_ms = round(boot * 1000)
        rx_us = round((UTC_AT_BOOT + boot + 0.02) * 1e6)
        yaw, roll = _vehicle_yaw(boot), _vehicle_roll(boot)
        out += _record(
            mav,
            mav.attitude_encode(boot_ms, math.radians(roll), math.radians(1.5), math.radians(yaw), 0, 0, 0),
            rx_us,
        )
        lat = round((-35.0 + 1e-6 * boot) * 1e7)
        out += _record(
            mav,
            mav.global_position_int_encode(boot_ms, lat, 1_490_000_000, 600_000, 80_000, 0, 0, 0, 0),
            rx_us,
        )
        if k % 10 == 0:
            out += _record(mav, mav.system_time_encode(round((UTC_AT_BOOT + boot) * 1e6), boot_ms), rx_us)
        if k % 2 == 0:
            if gimbal == "vehicle_frame":
                q = _mavlink_quaternion(ry(-90.0))  # yaw 0 from the nose, pitch -90
                msg = mav.gimbal_device_attitude_status_encode(0, 0, boot_ms, 32, q, 0, 0, 0, 0)
            elif gimbal == "earth_frame":
                q = _mavlink_quaternion(rz(LINE_YAW) @ ry(-90.0))
                msg = mav.gimbal_device_attitude_status_encode(0, 0, boot_ms, 64, q, 0, 0, 0, 0)
            else:
                msg = mav.mount_status_encode(0, 0, -9000, 0, 0)
            out += _record(mav, msg, rx_us)
    path.write_bytes(bytes(out))


@pytest.mark.parametrize("gimbal", ["vehicle_frame", "earth_frame", "mount_status"])
def test_nadir_gimbal_keeps_the_heading(tmp_path: Path, gimbal: str) -> None:
    """The issue: a line flown at 96 deg with the gimbal at -90 got camera yaws of 180, 153.4,
    135, 53.1... A gimbal looking straight down must give a camera that looks down (pitch 0,
    roll 0) with the image top where the gimbal's yaw points."""
    _gimbal_tlog(tmp_path / "g.tlog", gimbal)
    log = read_log(tmp_path / "g.tlog")
    assert log.gimbal is not None and log.attitudes is not None and log.positions is not None
    boot_times = np.arange(2.0, 38.0, 0.37)
    poses = interpolate_poses(
        UTC_AT_BOOT + boot_times, positions=log.positions, attitudes=log.attitudes, gimbal=log.gimbal
    ).poses
    for boot, pose in zip(boot_times, poses, strict=True):
        assert pose is not None and pose.yaw_deg is not None
        heading = LINE_YAW if gimbal == "earth_frame" else _vehicle_yaw(float(boot))
        # Truth from the definitions: straight down, image top toward the gimbal's heading.
        truth = gimbal_camera_vectors(rz(heading) @ ry(-90.0))
        written = pix4d_vectors(pose.yaw_deg, pose.pitch_deg or 0.0, pose.roll_deg or 0.0)
        # Interpolating 10 Hz attitude over a yaw that changes by up to 0.75 deg/s: 1e-3.
        np.testing.assert_allclose(written[0], truth[0], atol=1e-6)
        np.testing.assert_allclose(written[1], truth[1], atol=2e-3)


# ------------------------------------------------------------- the real ArduPilot SITL flight


def _dataflash_truth() -> tuple[np.ndarray, np.ndarray]:
    """(roll, pitch, yaw) of the autopilot at each CAM, from the BIN's 25 Hz ATT messages read
    with pymavlink and interpolated at the CAM's boot time (TimeUS), and the CAM's own R, P, Y."""
    from pymavlink import DFReader

    reader = DFReader.DFReader_binary(str(SITL / "flight.BIN"))
    att, cam = [], []
    try:
        while (m := reader.recv_match(type=["CAM", "ATT"])) is not None:
            if m.get_type() == "ATT":
                att.append((m.TimeUS / 1e6, m.Roll, m.Pitch, m.Yaw))
            else:
                cam.append((m.TimeUS / 1e6, m.R, m.P, m.Y))
    finally:
        reader.filehandle.close()
    a, c = np.array(att), np.array(cam)
    yaw = np.degrees(np.unwrap(np.radians(a[:, 3])))
    truth = np.column_stack(
        [
            np.interp(c[:, 0], a[:, 0], a[:, 1]),
            np.interp(c[:, 0], a[:, 0], a[:, 2]),
            np.interp(c[:, 0], a[:, 0], yaw),
        ]
    )
    return truth, c[:, 1:]


# Worst (roll, pitch, yaw) difference allowed, degrees: the BIN's ATT is logged at 25 Hz; the
# tlog's ATTITUDE arrives at 4 Hz, and the plane rolls into its turns (it fires there too).
SITL_TOLERANCE_DEG = {"flight.BIN": (0.01, 0.01, 0.01), "flight.tlog": (2.5, 0.5, 1.0)}


@pytest.mark.parametrize("name", sorted(SITL_TOLERANCE_DEG))
def test_sitl_written_attitude_agrees_with_the_autopilot(name: str) -> None:
    """ArduPlane SITL (no gimbal): the camera attitude placed at each camera event is the
    autopilot's own attitude there (the BIN's ATT read by pymavlink at each CAM's TimeUS)."""
    truth, cam_rpy = _dataflash_truth()
    log = read_log(SITL / name)
    assert log.events is not None and log.positions is not None and log.attitudes is not None
    poses = interpolate_poses(log.events.time_utc_s, positions=log.positions, attitudes=log.attitudes).poses
    assert len(poses) == truth.shape[0] == 70
    written = np.array([[p.roll_deg, p.pitch_deg, p.yaw_deg] for p in poses if p is not None], dtype=float)
    diff = written - truth
    diff[:, 2] = (diff[:, 2] + 180.0) % 360.0 - 180.0
    worst = np.abs(diff).max(axis=0)
    assert np.all(worst < SITL_TOLERANCE_DEG[name]), worst
    assert np.all(np.median(np.abs(diff), axis=0) < 0.05)
    # And the attitude CAM itself logged at the trigger (rounded to 0.01 deg in the log).
    cam_diff = written - cam_rpy
    cam_diff[:, 2] = (cam_diff[:, 2] + 180.0) % 360.0 - 180.0
    assert np.all(np.median(np.abs(cam_diff), axis=0) < 0.1)


def test_quaternion_and_angles_from_the_tlog_reader_agree_at_nadir() -> None:
    """The reader's own quaternion-to-angles conversion is the locked one of attitude."""
    from acquisition.attitude import roll_pitch_yaw_deg_from_quaternion

    for heading in (0.0, 20.0, 96.0, 185.0, 359.0):
        q = _mavlink_quaternion(rz(heading) @ ry(-90.0))
        roll, pitch, yaw = roll_pitch_yaw_deg_from_quaternion(*q)
        assert float(pitch) == pytest.approx(-90.0, abs=1e-6)
        assert float(roll) == 0.0
        assert (float(yaw) - heading + 180.0) % 360.0 - 180.0 == pytest.approx(0.0, abs=1e-6)


def test_tracks_are_plain_tables() -> None:
    """A gimbal track and a vehicle track combine sample by sample (interpolation on the samples)."""
    t = np.array([0.0, 1.0, 2.0])
    positions = PositionTrack(time_utc_s=t, lat_deg=np.full(3, 10.0), lon_deg=np.full(3, 20.0))
    vehicle_track = AttitudeTrack(
        time_utc_s=t, roll_deg=np.zeros(3), pitch_deg=np.zeros(3), yaw_deg=np.array([350.0, 0.0, 10.0])
    )
    gimbal_track = AttitudeTrack(
        time_utc_s=t, roll_deg=np.zeros(3), pitch_deg=np.full(3, -90.0), yaw_deg=np.array([350.0, 0.0, 10.0])
    )
    poses = interpolate_poses(
        [0.5, 1.5], positions=positions, attitudes=vehicle_track, gimbal=gimbal_track
    ).poses
    yaws = [p.yaw_deg for p in poses if p is not None]
    assert len(yaws) == 2
    assert (yaws[0] - 355.0) == pytest.approx(0.0, abs=1e-6)
    assert yaws[1] == pytest.approx(5.0, abs=1e-6)


def _write_frame(path: Path, capture_s: float) -> None:
    import io
    import math as m
    from datetime import UTC, datetime

    import pyexiv2
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.full((16, 24, 3), 128, dtype=np.uint8)).save(buffer, format="JPEG")
    image = pyexiv2.ImageData(buffer.getvalue())
    whole = m.floor(capture_s)
    image.modify_exif(
        {
            "Exif.Photo.DateTimeOriginal": datetime.fromtimestamp(whole, tz=UTC).strftime(
                "%Y:%m:%d %H:%M:%S"
            ),
            "Exif.Photo.SubSecTimeOriginal": f"{min(999, round((capture_s - whole) * 1000)):03d}",
        }
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(image.get_bytes())
    image.close()


def test_every_output_carries_the_heading_of_a_nadir_gimbal(tmp_path: Path) -> None:
    """geo.txt, the Pix4D CSV, the XMP Camera:Yaw/Pitch/Roll and GPSImgDirection of frames taken
    with the gimbal straight down (ArduPilot MOUNT_STATUS, yaw relative to the nose) all say
    yaw = the vehicle's heading at the frame, pitch 0, roll 0 (read back with pyexiv2)."""
    import pyexiv2

    from acquisition import geotag

    _gimbal_tlog(tmp_path / "g.tlog", "mount_status")
    log = read_log(tmp_path / "g.tlog")
    boots = [3.3, 7.9, 12.2, 18.6, 25.1, 31.4]
    for k, boot in enumerate(boots):
        _write_frame(tmp_path / "card" / f"F{k}.JPG", UTC_AT_BOOT + boot)
    result = geotag.geotag_images(tmp_path / "card", log, tmp_path / "out", offset_s=0.0)
    assert len(result.tagged) == len(boots)
    geo = {r.split()[0]: r.split() for r in (tmp_path / "out" / "geo.txt").read_text().splitlines()[1:]}
    pix4d = {
        r.split(",")[0]: r.split(",")
        for r in (tmp_path / "out" / "pix4d_geolocation.csv").read_text().splitlines()
    }
    for k, boot in enumerate(boots):
        name = f"F{k}.JPG"
        heading = _vehicle_yaw(boot)
        image = pyexiv2.Image(str(tmp_path / "out" / name))
        xmp, exif_tags = image.read_xmp(), image.read_exif()
        image.close()
        num, den = (int(v) for v in exif_tags["Exif.GPSInfo.GPSImgDirection"].split("/"))
        readings = {
            "geo.txt": [float(v) for v in geo[name][4:7]],
            "pix4d": [float(v) for v in pix4d[name][4:7]],
            "xmp": [float(xmp[f"Xmp.Camera.{a}"]) for a in ("Yaw", "Pitch", "Roll")],
        }
        for source, (yaw, pitch, roll) in readings.items():
            assert abs((yaw - heading + 180.0) % 360.0 - 180.0) < 0.2, (source, name, yaw, heading)
            assert abs(pitch) < 1e-3 and abs(roll) < 1e-3, (source, name, pitch, roll)
        assert abs((num / den - heading + 180.0) % 360.0 - 180.0) < 0.2
