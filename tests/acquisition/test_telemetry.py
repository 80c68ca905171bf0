"""Telemetry readers: real ArduPilot logs, a genuine ULog fixture, synthetic tlogs written with
pymavlink's own encoder, CSV/GPX/MRK fixtures, and the GPS leap-second table."""

from __future__ import annotations

import datetime as dt
import importlib.util
import shutil
import struct
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from shared_data import SHARED_DATA, needs

from acquisition.attitude import roll_pitch_yaw_deg_from_quaternion
from acquisition.errors import TelemetryError
from acquisition.telemetry import FORMATS, detect_format, read_log
from acquisition.telemetry.csv_cells import parse_angle_deg
from acquisition.telemetry.gpstime import (
    GPS_EPOCH_POSIX_S,
    SECONDS_PER_WEEK,
    fit_boot_clock,
    gps_minus_utc_s,
    gps_to_utc_s,
    gps_usec_to_utc_s,
    gps_week_ms_to_utc_s,
    gps_week_tow_to_utc_s,
    time_order,
    utc_to_gps_s,
    utc_to_gps_week_tow_s,
)
from acquisition.telemetry.model import FlightLog, VehicleType, vehicle_type_of_mav_type
from acquisition.telemetry.mrk import read_mrk_table

REAL = SHARED_DATA / "ardupilot_sitl_plane"
TLOG = REAL / "flight.tlog"
BIN = REAL / "flight.BIN"
DATA = Path(__file__).resolve().parents[1] / "data"
EARTH_M_PER_DEG = 111_195.0  # mean Earth radius 6371.0 km * pi / 180

needs_real = needs("ardupilot_sitl_plane", "flight.tlog")


def _close(actual: Any, desired: Any, atol: float) -> None:
    """Equal within ``atol``, absolutely (assert_allclose's default relative tolerance of 1e-7
    would let UTC POSIX seconds, about 1.7e9, differ by minutes)."""
    np.testing.assert_allclose(actual, desired, rtol=0, atol=atol)


def _utc(
    year: int, month: int, day: int, hour: int = 0, minute: int = 0, second: int = 0, us: int = 0
) -> float:
    return dt.datetime(year, month, day, hour, minute, second, us, tzinfo=dt.UTC).timestamp()


def _metres(lat1: np.ndarray, lon1: np.ndarray, lat2: np.ndarray, lon2: np.ndarray) -> np.ndarray:
    north = (lat1 - lat2) * EARTH_M_PER_DEG
    east = (lon1 - lon2) * EARTH_M_PER_DEG * np.cos(np.radians(lat1))
    return np.hypot(north, east)


def _frame_ends(data: bytes) -> list[int]:
    """Offsets just past each (8-byte time + MAVLink frame) record of a tlog, walked with the
    MAVLink 1/2 framing rules (independently of the reader under test)."""
    ends, ofs = [], 0
    while ofs + 10 <= len(data):
        magic, n = data[ofs + 8], data[ofs + 9]
        length = 8 + (8 + n if magic == 0xFE else 12 + n + (13 if data[ofs + 10] & 1 else 0))
        ofs += length
        if ofs > len(data):
            break
        ends.append(ofs)
    return ends


def _assert_ordered(log: FlightLog) -> None:
    for table in (log.events, log.positions, log.attitudes, log.gimbal):
        if table is not None:
            assert np.all(np.diff(table.time_utc_s) > 0), table.source


# ---------------------------------------------------------------- real ArduPilot SITL logs


@pytest.fixture(scope="module")
def tlog() -> FlightLog:
    return read_log(TLOG)


@pytest.fixture(scope="module")
def dataflash() -> FlightLog:
    return read_log(BIN)


@needs_real
def test_real_tlog_reads_70_feedback_events_in_utc(tlog: FlightLog) -> None:
    assert tlog.format == "tlog"
    assert tlog.warnings == ()
    ev = tlog.events
    assert ev is not None and len(ev) == 70
    assert ev.source == "tlog:CAMERA_FEEDBACK"
    assert ev.seq.tolist() == list(range(1, 71))  # img_idx; completed_captures stays 0
    # The flight was simulated on 2026-11-22 (GPS week 2446 in the BIN).
    day = _utc(2026, 11, 22)
    assert day < ev.time_utc_s[0] < ev.time_utc_s[-1] < day + 86_400
    assert ev.lat_deg is not None and ev.lon_deg is not None
    assert np.all(np.abs(ev.lat_deg - 42.0) < 0.01) and np.all(np.abs(ev.lon_deg + 93.0) < 0.01)
    assert ev.alt_rel_home_m is not None and np.median(ev.alt_rel_home_m) == pytest.approx(80, abs=5)
    _assert_ordered(tlog)


@needs_real
def test_real_dataflash_reads_70_cam_events(dataflash: FlightLog) -> None:
    assert dataflash.format == "dataflash"
    ev = dataflash.events
    assert ev is not None and len(ev) == 70
    assert ev.source == "dataflash:CAM"
    assert ev.seq.tolist() == list(range(1, 71))
    # The real log ends inside a PARM message: the reader says so, with the byte offset.
    assert any("stopped at byte 14547430 of 14547456" in w for w in dataflash.warnings)
    _assert_ordered(dataflash)


@needs_real
def test_tlog_and_dataflash_events_agree(tlog: FlightLog, dataflash: FlightLog) -> None:
    a, b = tlog.events, dataflash.events
    assert a is not None and b is not None
    assert a.seq.tolist() == b.seq.tolist()
    # Two clocks, two paths (CAMERA_FEEDBACK.time_usec vs CAM.TimeUS mapped through GPS).
    assert np.max(np.abs(a.time_utc_s - b.time_utc_s)) < 0.002
    assert a.lat_deg is not None and b.lat_deg is not None
    assert a.lon_deg is not None and b.lon_deg is not None
    assert np.max(_metres(a.lat_deg, a.lon_deg, b.lat_deg, b.lon_deg)) < 0.01
    assert a.alt_amsl_m is not None and b.alt_amsl_m is not None
    assert np.max(np.abs(a.alt_amsl_m - b.alt_amsl_m)) < 0.01
    assert a.yaw_deg is not None and b.yaw_deg is not None
    assert np.max(np.abs((a.yaw_deg - b.yaw_deg + 180) % 360 - 180)) < 0.02


@needs_real
def test_dataflash_event_time_is_after_its_last_gps_fix(dataflash: FlightLog) -> None:
    """CAM's GPSTime is the last fix (5 Hz in SITL): the event follows it by less than one
    period plus the fix's delivery delay (tens of ms)."""
    from pymavlink import DFReader

    reader = DFReader.DFReader_binary(str(BIN))
    fix = []
    while (m := reader.recv_match(type=["CAM"])) is not None:
        fix.append((m.GPSWeek, m.GPSTime))
    reader.filehandle.close()
    # Independent GPS -> UTC: the datetime module and the 18 s of 2017 onwards.
    fix_utc = np.array(
        [
            (dt.datetime(1980, 1, 6, tzinfo=dt.UTC) + dt.timedelta(weeks=w, milliseconds=ms)).timestamp() - 18
            for w, ms in fix
        ]
    )
    assert dataflash.events is not None
    lag = dataflash.events.time_utc_s - fix_utc
    assert np.all(lag > 0) and np.all(lag < 0.25)


@needs_real
def test_real_poses_are_consistent_across_logs(tlog: FlightLog, dataflash: FlightLog) -> None:
    tp, bp = tlog.positions, dataflash.positions
    ta, ba = tlog.attitudes, dataflash.attitudes
    assert tp is not None and bp is not None and ta is not None and ba is not None
    assert len(tp) > 800 and len(bp) > 5000 and len(ta) > 800 and len(ba) > 5000
    assert tp.source == "tlog:GLOBAL_POSITION_INT" and bp.source == "dataflash:POS"
    for track in (ta, ba):
        assert np.all((track.yaw_deg >= 0) & (track.yaw_deg < 360))
    # Interpolating the BIN's 25 Hz poses at the tlog's times must give the tlog's own values
    # to within the motion between samples: any time-mapping error would show here.
    inside = (tp.time_utc_s > bp.time_utc_s[0]) & (tp.time_utc_s < bp.time_utc_s[-1])
    lat = np.interp(tp.time_utc_s, bp.time_utc_s, bp.lat_deg)
    lon = np.interp(tp.time_utc_s, bp.time_utc_s, bp.lon_deg)
    assert np.median(_metres(lat, lon, tp.lat_deg, tp.lon_deg)[inside]) < 0.1
    yaw = np.interp(ta.time_utc_s, ba.time_utc_s, np.degrees(np.unwrap(np.radians(ba.yaw_deg))))
    assert np.median(np.abs((yaw - ta.yaw_deg + 180) % 360 - 180)) < 0.1
    # And the events sit on the track.
    ev = dataflash.events
    assert ev is not None and ev.lat_deg is not None and ev.lon_deg is not None
    lat = np.interp(ev.time_utc_s, bp.time_utc_s, bp.lat_deg)
    lon = np.interp(ev.time_utc_s, bp.time_utc_s, bp.lon_deg)
    assert np.max(_metres(lat, lon, ev.lat_deg, ev.lon_deg)) < 0.5


@needs_real
def test_truncated_tlog_keeps_events_before_the_cut(tmp_path: Path, tlog: FlightLog) -> None:
    data = TLOG.read_bytes()
    cut = len(data) // 2 + 3  # inside a record
    (tmp_path / "cut.tlog").write_bytes(data[:cut])
    log = read_log(tmp_path / "cut.tlog")
    assert log.events is not None and tlog.events is not None
    n = len(log.events)
    assert 10 < n < 70
    assert log.events.seq.tolist() == tlog.events.seq[:n].tolist()
    np.testing.assert_array_equal(log.events.time_utc_s, tlog.events.time_utc_s[:n])
    last_complete = max(e for e in _frame_ends(data) if e <= cut)
    assert any(f"stopped at byte {last_complete} of {cut}" in w for w in log.warnings)


@needs_real
def test_corrupt_tlog_skips_garbage_and_says_where(tmp_path: Path, tlog: FlightLog) -> None:
    data = TLOG.read_bytes()
    at = _frame_ends(data)[13_000]
    (tmp_path / "bad.tlog").write_bytes(data[:at] + b"\x55" * 200 + data[at:])
    log = read_log(tmp_path / "bad.tlog")
    assert log.events is not None and len(log.events) == 70
    assert any(f"corrupt MAVLink packets skipped, the first after byte {at}" in w for w in log.warnings)


@needs_real
def test_truncated_dataflash_keeps_events_before_the_cut(tmp_path: Path, dataflash: FlightLog) -> None:
    data = BIN.read_bytes()
    cut = len(data) // 2
    (tmp_path / "cut.bin").write_bytes(data[:cut])
    log = read_log(tmp_path / "cut.bin")
    assert log.events is not None and dataflash.events is not None
    n = len(log.events)
    assert 10 < n < 70
    assert log.events.seq.tolist() == dataflash.events.seq[:n].tolist()
    _close(log.events.time_utc_s, dataflash.events.time_utc_s[:n], atol=1e-3)
    stopped = [w for w in log.warnings if "stopped at byte" in w]
    assert stopped
    offset = int(stopped[0].split("stopped at byte ")[1].split()[0])
    assert cut - 256 < offset <= cut  # a DataFlash message is at most 255 bytes


@needs_real
def test_corrupt_dataflash_skips_garbage_and_says_where(tmp_path: Path) -> None:
    data = bytearray(BIN.read_bytes())
    at = len(data) // 3
    data[at : at + 300] = bytes(300)
    (tmp_path / "bad.bin").write_bytes(bytes(data))
    log = read_log(tmp_path / "bad.bin")
    assert log.events is not None and len(log.events) >= 69
    corrupt = [w for w in log.warnings if "corrupt data skipped" in w]
    assert corrupt
    first = int(corrupt[0].split("the first at byte ")[1])
    assert at - 256 < first <= at + 300


@needs_real
def test_dispatch_is_by_content_not_name(tmp_path: Path) -> None:
    shutil.copy(TLOG, tmp_path / "looks_like.BIN")
    assert detect_format(tmp_path / "looks_like.BIN") == "tlog"
    (tmp_path / "flight.tlog").write_bytes(BIN.read_bytes()[:4096])
    assert detect_format(tmp_path / "flight.tlog") == "dataflash"


# ---------------------------------------------------------------- synthetic tlogs


def _tlog_writer() -> tuple[ModuleType, Any]:
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    return mavlink2, mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)


def _record(mav: Any, msg: Any, rx_us: int) -> bytes:
    return struct.pack(">Q", rx_us) + bytes(msg.pack(mav))


UTC_AT_BOOT = 1_750_000_000.25  # 2025-06-15T15:06:40.25Z
GCS_CLOCK_AHEAD_S = 3.7  # the ground station's clock is wrong: the reader must not use it


def _synthetic_tlog(path: Path, events: list[tuple[str, float]]) -> None:
    """10 Hz ATTITUDE (yaw 90 deg) and GLOBAL_POSITION_INT, 1 Hz SYSTEM_TIME (no UTC for the
    first 2 s), a vehicle-frame gimbal at 2 Hz (pitch -60, yaw +20), and CAMERA_FEEDBACK
    events given as (kind of time_usec, boot time s), each received twice."""
    mavlink2, mav = _tlog_writer()
    other = mavlink2.MAVLink(None, srcSystem=2, srcComponent=1)  # another vehicle on the link
    gcs = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    out = bytearray()
    rx0 = round((UTC_AT_BOOT + GCS_CLOCK_AHEAD_S) * 1e6)
    out += _record(gcs, gcs.heartbeat_encode(6, 8, 0, 0, 0), rx0)  # GCS, autopilot INVALID
    out += _record(mav, mav.heartbeat_encode(1, 3, 0, 0, 0), rx0)  # ArduPilot plane
    pending = sorted(events, key=lambda e: e[1])
    for k in range(0, 201):
        boot = k * 0.1
        boot_ms = round(boot * 1000)
        rx = round((UTC_AT_BOOT + boot + GCS_CLOCK_AHEAD_S + 0.05) * 1e6)
        out += _record(mav, mav.attitude_encode(boot_ms, 0.0, 0.0, np.pi / 2, 0, 0, 0), rx)
        out += _record(other, other.attitude_encode(boot_ms + 99_000, 0.5, 0.0, 0.0, 0, 0, 0), rx)
        lat = round((47.0 + 1e-5 * boot) * 1e7)
        out += _record(
            mav,
            mav.global_position_int_encode(boot_ms, lat, 80_000_000, 400_000, 50_000, 0, 0, 0, 9000),
            rx,
        )
        if k % 10 == 0:
            unix_us = 0 if boot < 2 else round((UTC_AT_BOOT + boot) * 1e6)
            out += _record(mav, mav.system_time_encode(unix_us, boot_ms), rx)
        if k % 5 == 0:
            q = _quaternion(0.0, -60.0, 20.0)
            out += _record(
                mav,
                mav.gimbal_device_attitude_status_encode(0, 0, boot_ms, 32, q, 0, 0, 0, 0),
                rx,
            )
        while pending and pending[0][1] <= boot:
            kind, t = pending.pop(0)
            utc = UTC_AT_BOOT + t
            time_usec = {
                "boot": round(t * 1e6),
                "unix": round(utc * 1e6),
                "gps": round(float(utc_to_gps_s(utc)) * 1e6),
            }[kind]
            img = len(events) - len(pending)
            msg = mav.camera_feedback_encode(
                time_usec, 0, 0, img, lat, 80_000_000, 400.0, 50.0, 1.0, 2.0, 90.0, 0.0, 0, 0
            )
            out += _record(mav, msg, rx) + _record(mav, msg, rx + 1000)
    path.write_bytes(bytes(out))


def _quaternion(roll: float, pitch: float, yaw: float) -> list[float]:
    cr, sr = np.cos(np.radians(roll) / 2), np.sin(np.radians(roll) / 2)
    cp, sp = np.cos(np.radians(pitch) / 2), np.sin(np.radians(pitch) / 2)
    cy, sy = np.cos(np.radians(yaw) / 2), np.sin(np.radians(yaw) / 2)
    return [
        float(cr * cp * cy + sr * sp * sy),
        float(sr * cp * cy - cr * sp * sy),
        float(cr * sp * cy + sr * cp * sy),
        float(cr * cp * sy - sr * sp * cy),
    ]


def test_tlog_time_usec_boot_unix_and_gps_epoch_all_land_on_utc(tmp_path: Path) -> None:
    events = [("boot", 5.0123), ("unix", 7.0456), ("gps", 9.5), ("boot", 12.25)]
    _synthetic_tlog(tmp_path / "s.tlog", events)
    log = read_log(tmp_path / "s.tlog")
    ev = log.events
    assert ev is not None
    assert ev.seq.tolist() == [1, 2, 3, 4]  # each received twice, kept once
    expected = np.array([UTC_AT_BOOT + t for _, t in events])
    _close(ev.time_utc_s, expected, atol=2e-6)
    assert any("GPS-epoch" in w for w in log.warnings)
    assert any(
        "other sources than the vehicle 1/1 ignored (system/component: 2/1 (201))" in w for w in log.warnings
    )
    # Poses are on UTC through SYSTEM_TIME, not the ground station's clock (3.7 s ahead).
    assert log.attitudes is not None
    _close(log.attitudes.time_utc_s[:3], UTC_AT_BOOT + np.array([0, 0.1, 0.2]), atol=1e-6)
    assert np.allclose(log.attitudes.yaw_deg, 90.0)
    # The gimbal's vehicle-relative yaw becomes an earth yaw: 90 + 20.
    assert log.gimbal is not None
    _close(log.gimbal.yaw_deg, 110.0, atol=1e-4)
    _close(log.gimbal.pitch_deg, -60.0, atol=1e-4)
    _assert_ordered(log)


def test_tlog_image_captured_and_failed_captures(tmp_path: Path) -> None:
    _, mav = _tlog_writer()
    out = bytearray()
    base = UTC_AT_BOOT
    q = _quaternion(3.0, -4.0, 250.0)
    for i in range(5):
        utc_us = round((base + 2.0 * i) * 1e6)
        msg = mav.camera_image_captured_encode(
            1000 * i,
            utc_us,
            0,
            471_234_567,
            81_234_567,
            512_340,
            80_120,
            q,
            i,
            0 if i == 2 else 1,
            b"",
        )
        out += _record(mav, msg, utc_us)
    (tmp_path / "c.tlog").write_bytes(bytes(out))
    log = read_log(tmp_path / "c.tlog")
    ev = log.events
    assert ev is not None and ev.source == "tlog:CAMERA_IMAGE_CAPTURED"
    assert ev.seq.tolist() == [0, 1, 3, 4]
    _close(ev.time_utc_s, base + 2.0 * np.array([0, 1, 3, 4]), atol=1e-6)
    assert ev.lat_deg is not None and ev.lat_deg[0] == pytest.approx(47.1234567)
    assert ev.alt_amsl_m is not None and ev.alt_amsl_m[0] == pytest.approx(512.34)
    assert ev.alt_rel_home_m is not None and ev.alt_rel_home_m[0] == pytest.approx(80.12)
    assert ev.roll_deg is not None and ev.pitch_deg is not None and ev.yaw_deg is not None
    assert (ev.roll_deg[0], ev.pitch_deg[0], ev.yaw_deg[0]) == pytest.approx((3.0, -4.0, 250.0), abs=1e-4)
    assert any("failed capture" in w for w in log.warnings)


@settings(max_examples=200, deadline=None)
@given(st.floats(-179, 179), st.floats(-89, 89), st.floats(0, 359.99))
def test_quaternion_to_euler_round_trip(roll: float, pitch: float, yaw: float) -> None:
    r, p, y = roll_pitch_yaw_deg_from_quaternion(*_quaternion(roll, pitch, yaw))
    assert float(r) == pytest.approx(roll, abs=1e-6)
    assert float(p) == pytest.approx(pitch, abs=1e-6)
    assert (float(y) - yaw + 180) % 360 - 180 == pytest.approx(0, abs=1e-6)


# ---------------------------------------------------------------- ULog


# ---------------------------------------------------------------- what the log says the vehicle is


def _pymavlink_kind(mav_type: int) -> VehicleType:
    """The kind of a MAV_TYPE by the name pymavlink's own MAVLink enum table gives it."""
    from pymavlink.dialects.v20 import common

    name = common.enums["MAV_TYPE"][mav_type].name.removeprefix("MAV_TYPE_")
    if "VTOL" in name:
        return VehicleType.VTOL
    if name == "FIXED_WING":
        return VehicleType.FIXED_WING
    if name == "HELICOPTER":
        return VehicleType.HELICOPTER
    if name.endswith(("ROTOR", "COPTER")) or name == "COAXIAL":
        return VehicleType.MULTIROTOR
    return VehicleType.OTHER


def test_every_mav_type_is_the_kind_its_mavlink_name_says() -> None:
    from pymavlink.dialects.v20 import common

    values = [v for v in common.enums["MAV_TYPE"] if v != common.MAV_TYPE_ENUM_END]
    assert len(values) > 30
    for value in values:
        assert vehicle_type_of_mav_type(value) is _pymavlink_kind(value), common.enums["MAV_TYPE"][value].name


@needs_real
def test_real_plane_logs_say_a_fixed_wing_as_pymavlink_reads_them(
    tlog: FlightLog, dataflash: FlightLog
) -> None:
    """The oracle: pymavlink's own reading of the autopilot's first HEARTBEAT (the .tlog) and of
    the firmware's MSG naming itself (the DataFlash log)."""
    from pymavlink import mavutil

    conn = mavutil.mavlink_connection(str(TLOG))
    try:
        while (hb := conn.recv_match(type="HEARTBEAT")) is not None:
            if hb.autopilot != mavutil.mavlink.MAV_AUTOPILOT_INVALID:
                break
    finally:
        conn.close()
    assert hb is not None
    assert tlog.vehicle_type is _pymavlink_kind(hb.type) is VehicleType.FIXED_WING
    df = mavutil.mavlink_connection(str(BIN))
    first = df.recv_match(type="MSG", condition="MSG.Message.startswith('Ardu')")
    assert first is not None and first.Message.startswith("ArduPlane ")
    assert dataflash.vehicle_type is VehicleType.FIXED_WING


@pytest.mark.parametrize(
    ("system_type", "is_vtol", "vehicle_type"),
    [(1, False, 2), (22, True, 1), (2, False, 1)],
    ids=["fixed-wing", "vtol-hovering", "quadrotor"],
)
def test_ulog_vehicle_status_says_the_kind(
    tmp_path: Path, system_type: int, is_vtol: bool, vehicle_type: int
) -> None:
    """vehicle_status's system_type (a MAV_TYPE), not its vehicle_type (a VTOL's is the rotary
    wing's while it hovers); a log without vehicle_status says nothing."""
    assert read_log(DATA / "px4_survey.ulg").vehicle_type is None
    gen = _ulog_fixture_module()
    path = tmp_path / "status.ulg"
    status = {"vehicle_type": vehicle_type, "is_vtol": is_vtol, "system_type": system_type}
    path.write_bytes(gen.build_ulog(vehicle_status=status))
    assert read_log(path).vehicle_type is _pymavlink_kind(system_type)


def test_tracks_say_nothing_of_the_vehicle() -> None:
    for name in ("track_exiftool.csv", "track.gpx"):
        assert read_log(DATA / name).vehicle_type is None


def _ulog_fixture_module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("make_ulog_fixture", DATA / "make_ulog_fixture.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_ulog_fixture_is_what_its_generator_writes_and_pyulog_reads_it() -> None:
    from pyulog import ULog

    gen = _ulog_fixture_module()
    assert (DATA / "px4_survey.ulg").read_bytes() == gen.build_ulog()
    ulog = ULog(str(DATA / "px4_survey.ulg"))
    assert not ulog.file_corruption
    counts = {d.name: len(d.data["timestamp"]) for d in ulog.data_list}
    assert counts == {
        "camera_capture": 26,
        "camera_trigger": 26,
        "vehicle_attitude": 601,
        "vehicle_global_position": 601,
        "vehicle_gps_position": 301,
    }
    assert ulog.msg_info_dict["sys_name"] == "PX4"


def test_ulog_events_and_poses_match_the_truth() -> None:
    gen = _ulog_fixture_module()
    log = read_log(DATA / "px4_survey.ulg")
    assert log.format == "ulog"
    ev = log.events
    assert ev is not None and ev.source == "ulog:camera_capture"
    trig = np.array(gen.TRIGGER_TIMES_S)
    keep = np.arange(len(trig)) != gen.FAILED_SEQ
    assert ev.seq.tolist() == [s for s in range(len(trig)) if s != gen.FAILED_SEQ]
    _close(ev.time_utc_s, gen.UTC0_S + gen.RATE * trig[keep], atol=2e-6)
    truth = np.array([gen.position(t) for t in trig[keep]])
    assert ev.lat_deg is not None and ev.alt_amsl_m is not None
    _close(ev.lat_deg, truth[:, 0], atol=1e-9)
    _close(ev.alt_amsl_m, truth[:, 2], atol=1e-4)
    att = np.array([gen.euler_deg(t) for t in trig[keep]])
    assert ev.roll_deg is not None and ev.pitch_deg is not None and ev.yaw_deg is not None
    _close(ev.roll_deg, att[:, 0], atol=1e-4)
    _close(ev.pitch_deg, att[:, 1], atol=1e-4)
    _close(ev.yaw_deg, att[:, 2], atol=1e-4)
    assert any("failed capture" in w for w in log.warnings)
    assert log.positions is not None and log.attitudes is not None
    assert len(log.positions) == 601 and len(log.attitudes) == 601
    t_boot = (log.attitudes.time_utc_s - gen.UTC0_S) / gen.RATE
    _close(log.attitudes.yaw_deg, [gen.euler_deg(t)[2] for t in t_boot], atol=1e-3)
    _assert_ordered(log)


def test_truncated_ulog_keeps_what_came_before(tmp_path: Path) -> None:
    data = (DATA / "px4_survey.ulg").read_bytes()
    cut = int(len(data) * 0.6) + 1
    (tmp_path / "cut.ulg").write_bytes(data[:cut])
    full = read_log(DATA / "px4_survey.ulg")
    log = read_log(tmp_path / "cut.ulg")
    assert log.events is not None and full.events is not None
    n = len(log.events)
    assert 5 < n < len(full.events)
    _close(log.events.time_utc_s, full.events.time_utc_s[:n], atol=1e-5)
    stopped = [w for w in log.warnings if "stopped at byte" in w]
    assert stopped and f"of {cut}" in stopped[0]


# ---------------------------------------------------------------- CSV, GPX, MRK


def test_exiftool_csv_track_in_all_coordinate_forms() -> None:
    log = read_log(DATA / "track_exiftool.csv")
    assert log.format == "csv" and log.warnings == ()
    pos = log.positions
    assert pos is not None
    t0 = _utc(2016, 11, 22, 15, 32, 1)
    _close(pos.time_utc_s - t0, [0, 1.5, 3, 4], atol=1e-9)  # one row in +01:00
    # 44 deg 56' 6" N = 44.935; 93 deg 7' 26.4" W = -93.124; Ref columns and letters apply.
    _close(pos.lat_deg, [44.9345, 44.935, 44.9355, 44.936], atol=1e-9)
    _close(pos.lon_deg, [-93.124] * 4, atol=1e-9)
    assert pos.alt_amsl_m is not None
    _close(pos.alt_amsl_m, [290.5, 291.0, 292.25, 293.0], atol=1e-9)
    assert log.attitudes is not None
    _close(log.attitudes.yaw_deg, [10.0, 12.5, 10.0, 15.0], atol=1e-9)  # 370 -> 10
    _close(log.attitudes.pitch_deg, [-2.5, -2.0, -1.5, -1.0], atol=1e-9)


def test_gpx_holds_the_same_track_as_the_csv() -> None:
    gpx = read_log(DATA / "track.gpx")
    csv_ = read_log(DATA / "track_exiftool.csv")
    assert gpx.format == "gpx" and gpx.positions is not None and csv_.positions is not None
    for name in ("time_utc_s", "lat_deg", "lon_deg", "alt_amsl_m"):
        _close(getattr(gpx.positions, name), getattr(csv_.positions, name), atol=1e-9)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("44.5", 44.5),
        ("-44.5", -44.5),
        ("44.5 S", -44.5),
        ("44 30 0 S", -44.5),
        ("44 deg 30' 36.00\" N", 44.51),
        ("S 44 30.6", -44.51),
    ],
)
def test_latitude_forms(text: str, expected: float) -> None:
    assert parse_angle_deg(text, positive="N", negative="S") == pytest.approx(expected)


def test_csv_errors_name_the_line(tmp_path: Path) -> None:
    good = "GPSDateTime,GPSLatitude,GPSLongitude\n2020:01:01 00:00:00Z,10,20\n"
    (tmp_path / "a.csv").write_text(good + "2020:01:01 00:00:01Z,ten,20\n")
    with pytest.raises(TelemetryError, match=r"a\.csv, line 3: GPSLatitude 'ten'"):
        read_log(tmp_path / "a.csv")
    (tmp_path / "b.csv").write_text(good + "2020-13-01 00:00:01,10,20\n")
    with pytest.raises(TelemetryError, match=r"b\.csv, line 3: GPSDateTime"):
        read_log(tmp_path / "b.csv")
    (tmp_path / "c.csv").write_text("GPSDateTime,GPSLatitude,Lon\n2020:01:01 00:00:00Z,10,20\n")
    with pytest.raises(TelemetryError, match=r"c\.csv, line 1: the header lacks GPSLongitude"):
        read_log(tmp_path / "c.csv")
    (tmp_path / "d.csv").write_text(good + "2020:01:01 00:00:01Z,10,20,\n2020:01:01 00:00:02Z,91,20\n")
    with pytest.raises(TelemetryError, match=r"line 4: .*outside"):
        read_log(tmp_path / "d.csv")


def test_csv_split_date_and_time_and_below_sea_level(tmp_path: Path) -> None:
    (tmp_path / "t.csv").write_text(
        "GPS Date Stamp,GPS Time Stamp,GPS Latitude,GPS Longitude,GPS Altitude\n"
        "2021:06:30,23:59:59.5,1.5,-2.5,12 m Below Sea Level\n"
    )
    log = read_log(tmp_path / "t.csv")
    assert log.positions is not None and log.positions.alt_amsl_m is not None
    assert log.positions.time_utc_s[0] == _utc(2021, 6, 30, 23, 59, 59, us=500_000)
    assert log.positions.alt_amsl_m[0] == -12.0


def test_gpx_errors_name_the_line(tmp_path: Path) -> None:
    head = (
        '<?xml version="1.0"?>\n<gpx version="1.1" xmlns="http://www.topografix.com/GPX/1/1"><trk><trkseg>\n'
    )
    (tmp_path / "a.gpx").write_text(
        head + '<trkpt lat="1" lon="2">\n<time>yesterday</time></trkpt>\n</trkseg></trk></gpx>\n'
    )
    with pytest.raises(TelemetryError, match=r"a\.gpx, line 4: <time> 'yesterday'"):
        read_log(tmp_path / "a.gpx")
    (tmp_path / "b.gpx").write_text(
        head + '<trkpt lat="1" lon="2"><ele>3</ele></trkpt>\n</trkseg></trk></gpx>\n'
    )
    with pytest.raises(TelemetryError, match=r"b\.gpx, line 3: trkpt without <time>"):
        read_log(tmp_path / "b.gpx")
    (tmp_path / "c.gpx").write_text(head + '<trkpt lat="1" lon="2">\n<time>2020-01-01T00:00:00Z</trkpt>\n')
    with pytest.raises(TelemetryError, match=r"c\.gpx, line 4: not well-formed"):
        read_log(tmp_path / "c.gpx")


def test_mrk_times_positions_and_status() -> None:
    log = read_log(DATA / "p4rtk_Timestamp.MRK")
    assert log.format == "mrk"
    ev = log.events
    assert ev is not None and ev.seq.tolist() == [1, 2, 3, 4, 5]
    # Independent GPS -> UTC: datetime arithmetic and the 18 s of leap seconds since 2017.
    gps0 = dt.datetime(1980, 1, 6, tzinfo=dt.UTC)
    first = (gps0 + dt.timedelta(weeks=2404, seconds=282401.669089)).timestamp() - 18
    assert ev.time_utc_s[0] == pytest.approx(first, abs=1e-6)
    assert dt.datetime.fromtimestamp(ev.time_utc_s[0], dt.UTC).date() == dt.date(2026, 2, 4)
    assert ev.lat_deg is not None and ev.lat_deg[0] == 22.77995359
    assert ev.alt_amsl_m is None  # ellipsoidal heights have no AMSL column
    assert any("ellipsoidal" in w for w in log.warnings)
    assert any("1 of 5 photos not RTK fixed (1 RTK float)" in w for w in log.warnings)
    table = read_mrk_table(DATA / "p4rtk_Timestamp.MRK")
    assert table.alt_ellipsoid_m[2] == 139.238
    assert (table.offset_north_mm[2], table.offset_east_mm[2], table.offset_down_mm[2]) == (
        -12,
        -18,
        194,
    )
    assert table.std_vert_m[0] == 0.007622 and table.rtk_status.tolist() == [50, 50, 34, 50, 50]


def test_mrk_bad_line_is_named(tmp_path: Path) -> None:
    lines = (DATA / "p4rtk_Timestamp.MRK").read_text().splitlines()
    lines[3] = lines[3].replace(",Lon", ";Lon")
    (tmp_path / "x.MRK").write_text("\n".join(lines) + "\n")
    with pytest.raises(TelemetryError, match=r"x\.MRK, line 4: .* is not an MRK photo line"):
        read_mrk_table(tmp_path / "x.MRK")


def test_unknown_and_missing_files_are_named(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("hello\n")
    with pytest.raises(TelemetryError) as err:
        read_log(tmp_path / "notes.txt")
    assert "notes.txt" in str(err.value) and all(k in str(err.value) for k in FORMATS)
    with pytest.raises(TelemetryError, match=r"missing\.tlog"):
        read_log(tmp_path / "missing.tlog")
    (tmp_path / "empty.bin").write_bytes(b"")
    with pytest.raises(TelemetryError, match="empty"):
        read_log(tmp_path / "empty.bin")


# ---------------------------------------------------------------- GPS time and leap seconds


@pytest.mark.parametrize(
    ("utc", "offset_s"),
    [
        (_utc(1980, 1, 6), 0),
        (_utc(1981, 6, 30, 23, 59, 59), 0),
        (_utc(1981, 7, 1), 1),
        (_utc(1999, 1, 1), 13),
        (_utc(2005, 12, 31, 23, 59, 59), 13),
        (_utc(2006, 1, 1), 14),
        (_utc(2012, 7, 1), 16),
        (_utc(2016, 12, 31, 23, 59, 59), 17),
        (_utc(2017, 1, 1), 18),
        (_utc(2026, 11, 22), 18),  # not Mission Planner's 17
    ],
)
def test_published_gps_minus_utc(utc: float, offset_s: int) -> None:
    assert float(gps_minus_utc_s(utc)) == offset_s


def test_known_gps_times() -> None:
    # 2017-01-01T00:00:00Z was GPS week 1930, 18 s into the week (the week began at GPS
    # midnight, 17 s of leap seconds before UTC midnight, plus the new one).
    week, tow = utc_to_gps_week_tow_s(_utc(2017, 1, 1))
    assert (int(week), float(tow)) == (1930, 18.0)
    assert float(gps_to_utc_s(0)) == GPS_EPOCH_POSIX_S
    # The inserted second 2016-12-31T23:59:60 has no POSIX value: both GPS seconds around it
    # land on the first second of 2017.
    g = float(utc_to_gps_s(_utc(2017, 1, 1)))
    assert float(gps_to_utc_s(g - 1)) == float(gps_to_utc_s(g)) == _utc(2017, 1, 1)
    assert float(gps_to_utc_s(g - 2)) == _utc(2016, 12, 31, 23, 59, 59)
    assert float(gps_week_ms_to_utc_s(2446, 37_953_600)) == _utc(2026, 11, 22, 10, 32, 15, us=600_000)
    assert float(gps_usec_to_utc_s(np.int64(g * 1_000_000 + 123_456))) == pytest.approx(
        _utc(2017, 1, 1) + 0.123456, abs=1e-7
    )


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=GPS_EPOCH_POSIX_S, max_value=_utc(2040, 1, 1)))
def test_utc_gps_round_trip(utc: float) -> None:
    assert float(gps_to_utc_s(utc_to_gps_s(utc))) == pytest.approx(utc, abs=1e-6)


@settings(max_examples=300, deadline=None)
@given(
    st.integers(min_value=0, max_value=3000),
    st.floats(min_value=0, max_value=SECONDS_PER_WEEK - 1e-3),
)
def test_gps_week_round_trip_outside_leap_seconds(week: int, tow: float) -> None:
    utc = float(gps_week_tow_to_utc_s(week, tow))
    back_week, back_tow = utc_to_gps_week_tow_s(utc)
    gps = week * SECONDS_PER_WEEK + tow
    back = float(back_week) * SECONDS_PER_WEEK + float(back_tow)
    in_leap_second = float(gps_minus_utc_s(utc)) != float(gps_minus_utc_s(utc - 1.0)) and (
        back - gps
    ) == pytest.approx(1.0, abs=1e-6)
    assert back == pytest.approx(gps, abs=1e-6) or in_leap_second


@settings(max_examples=200, deadline=None)
@given(
    st.integers(min_value=1931, max_value=2600),
    st.integers(min_value=0, max_value=SECONDS_PER_WEEK * 1000 - 1),
)
def test_matches_ardupilot_epoch_formula_since_2017(week: int, tow_ms: int) -> None:
    # From GPS week 1931 on; the first 17 s of week 1930 were still 2016 with 17 leap
    # seconds, which ArduPilot's constant 18 s gets wrong (the table does not).
    # ArduPilot AP_GPS.h: UNIX_OFFSET_MSEC = 17000 * 86400 + 52 * 10 * AP_MSEC_PER_WEEK
    # - GPS_LEAPSECONDS_MILLIS (17 days and 520 weeks, in ms, less 18 s), plus week and ms.
    unix_ms = 17_000 * 86_400 + 520 * 604_800_000 - 18_000 + week * 604_800_000 + tow_ms
    assert float(gps_week_ms_to_utc_s(week, tow_ms)) == pytest.approx(unix_ms / 1000, abs=1e-6)


def test_boot_clock_fit_recovers_drift_and_ignores_outliers() -> None:
    rng = np.random.default_rng(7)
    boot = np.sort(rng.uniform(10, 1800, 400))
    utc = 1.7e9 + 0.123 + (1 + 35e-6) * boot + rng.normal(0, 0.002, boot.size)
    utc[:5] -= 3600.0  # the RTC before it was set from GPS
    utc[200] += 0.8  # a stale pair
    fit = fit_boot_clock(boot, utc)
    assert fit.n_used == 394
    assert fit.rate == pytest.approx(1 + 35e-6, abs=2e-6)
    assert float(fit.utc_s(1000.0)) == pytest.approx(1.7e9 + 0.123 + (1 + 35e-6) * 1000, abs=0.001)
    assert fit.residual_rms_s == pytest.approx(0.002, rel=0.2)
    assert float(fit.boot_s(fit.utc_s(123.0))) == pytest.approx(123.0)
    with pytest.raises(TelemetryError):
        fit_boot_clock([], [])


def test_time_order_sorts_and_drops_exact_duplicates() -> None:
    t = np.array([3.0, 1.0, 2.0, 1.0, np.nan, 2.0])
    key = np.array([30, 10, 20, 10, 0, 21])
    order = time_order(t, key)
    assert order.tolist() == [1, 2, 5, 0]


# ---------------------------------------------------------------- synthetic DataFlash layouts

_DF_STRUCT = {"Q": "Q", "B": "B", "H": "H", "I": "I", "L": "i", "e": "i", "c": "h", "C": "H"}
_DF_STRUCT |= {"f": "f", "h": "h", "i": "i", "n": "4s", "N": "16s", "Z": "64s"}
# What DataFlash stores for a value of each format: 1e-7 deg integers, centi-units...
_DF_SCALE = {"L": 1e7, "e": 100.0, "c": 100.0, "C": 100.0}


class _DataFlashWriter:
    """ArduPilot DataFlash framing: 0xA3 0x95 type, then the packed fields; FMT (type 128)
    describes every other type: Type, Length (with the 3-byte header), Name, Format, Columns."""

    def __init__(self) -> None:
        self.out = bytearray()
        self.types: dict[str, tuple[int, str, list[str]]] = {}

    def fmt(self, name: str, fmt: str, columns: str) -> None:
        mtype = 129 + len(self.types)
        length = 3 + struct.calcsize("<" + "".join(_DF_STRUCT[c] for c in fmt))
        self.types[name] = (mtype, fmt, columns.split(","))
        body = struct.pack("<BB4s16s64s", mtype, length, name.encode(), fmt.encode(), columns.encode())
        self.out += b"\xa3\x95\x80" + body

    def msg(self, name: str, **values: float) -> None:
        mtype, fmt, columns = self.types[name]
        packed = [
            round(values[c] * _DF_SCALE.get(f, 1)) if f not in "fd" else values[c]
            for f, c in zip(fmt, columns, strict=True)
        ]
        self.out += b"\xa3\x95" + bytes([mtype])
        self.out += struct.pack("<" + "".join(_DF_STRUCT[c] for c in fmt), *packed)


DF_WEEK, DF_TOW0_MS = 2300, 100_000_000  # 2024-02-05, about 27.8 h into the week


def _df_utc(boot_s: float) -> float:
    return float(gps_week_ms_to_utc_s(DF_WEEK, DF_TOW0_MS)) + boot_s


def _df_flight(w: _DataFlashWriter, *, with_gpa: bool) -> None:
    """GPS fixes at 5 Hz received at boot time t (GPA SMS = t), logged 17 ms later when GPA is
    there; ATT at 10 Hz, yaw 200 deg."""
    w.fmt("GPS", "QBBIHBcLLeffffB", "TimeUS,I,Status,GMS,GWk,NSats,HDop,Lat,Lng,Alt,Spd,GCrs,VZ,Yaw,U")
    w.fmt("GPA", "QBCCCCfBIHfHH", "TimeUS,I,VDop,HAcc,VAcc,SAcc,YAcc,VV,SMS,Delta,Und,RTCMFU,RTCMFD")
    w.fmt("ATT", "QccccCCCCB", "TimeUS,DesRoll,Roll,DesPitch,Pitch,DesYaw,Yaw,ErrRP,ErrYaw,AEKF")
    zeros = dict.fromkeys(("NSats", "HDop", "Spd", "GCrs", "VZ", "Yaw", "U", "I"), 0.0)
    for k in range(5, 150):
        t = k * 0.2
        logged = t + (0.017 if with_gpa else 0.0)
        fix = {"Status": 6.0, "GMS": DF_TOW0_MS + round(t * 1000), "GWk": DF_WEEK}
        pos = {"Lat": 35.0 + 1e-5 * t, "Lng": 139.0, "Alt": 120.0}
        w.msg("GPS", TimeUS=round(logged * 1e6), **fix, **pos, **zeros)
        if with_gpa:
            gpa = dict.fromkeys(("VDop", "HAcc", "VAcc", "SAcc", "YAcc", "VV", "Delta", "Und"), 0.0)
            gpa |= {"RTCMFU": 0.0, "RTCMFD": 0.0, "I": 0.0}
            w.msg("GPA", TimeUS=round(logged * 1e6), SMS=round(t * 1000), **gpa)
    for k in range(10, 300):
        t = k * 0.1
        att = dict.fromkeys(("DesRoll", "DesPitch", "DesYaw", "ErrRP", "ErrYaw", "AEKF"), 0.0)
        w.msg("ATT", TimeUS=round(t * 1e6), Roll=1.5, Pitch=-3.0, Yaw=200.0, **att)


CAM_BOOT_S = [5.5, 7.25, 9.0]


def test_dataflash_old_centidegree_cam_layout(tmp_path: Path) -> None:
    """ArduPilot 3.x: ``QIHLLeeeccC`` TimeUS,GPSTime,GPSWeek,Lat,Lng,Alt,RelAlt,GPSAlt,Roll,
    Pitch,Yaw (centi-degrees, no image number), no GPA: the clock comes from GPS.TimeUS."""
    w = _DataFlashWriter()
    _df_flight(w, with_gpa=False)
    w.fmt("CAM", "QIHLLeeeccC", "TimeUS,GPSTime,GPSWeek,Lat,Lng,Alt,RelAlt,GPSAlt,Roll,Pitch,Yaw")
    for t in CAM_BOOT_S:
        w.msg(
            "CAM", TimeUS=round(t * 1e6), GPSTime=DF_TOW0_MS + round(t // 0.2 * 200),
            GPSWeek=DF_WEEK,
            Lat=35.001, Lng=139.002, Alt=150.25, RelAlt=30.5, GPSAlt=151.0,
            Roll=-12.34, Pitch=4.56, Yaw=350.5,
        )  # fmt: skip
    (tmp_path / "old.bin").write_bytes(bytes(w.out))
    log = read_log(tmp_path / "old.bin")
    ev = log.events
    assert ev is not None and ev.source == "dataflash:CAM"
    assert ev.seq.tolist() == [1, 2, 3]
    _close(ev.time_utc_s, [_df_utc(t) for t in CAM_BOOT_S], atol=2e-6)
    assert ev.roll_deg is not None and ev.pitch_deg is not None and ev.yaw_deg is not None
    _close(ev.roll_deg, -12.34, atol=1e-9)
    _close(ev.pitch_deg, 4.56, atol=1e-9)
    _close(ev.yaw_deg, 350.5, atol=1e-9)
    assert ev.alt_amsl_m is not None and ev.alt_rel_home_m is not None
    _close(ev.alt_amsl_m, 150.25, atol=1e-9)
    _close(ev.alt_rel_home_m, 30.5, atol=1e-9)
    assert log.positions is not None and log.positions.source == "dataflash:GPS"
    assert log.attitudes is not None and np.allclose(log.attitudes.yaw_deg, 200.0)


def test_dataflash_new_float_cam_layout_with_gpa_trig_and_mount(tmp_path: Path) -> None:
    """Since ArduPilot PR 30375: ``QBHIHLLeeefff`` ...,R,P,Y in float degrees; GPA's SMS pins
    the GPS time (the GPS messages are logged 17 ms after the fix arrived)."""
    w = _DataFlashWriter()
    _df_flight(w, with_gpa=True)
    cols = "TimeUS,I,Img,GPSTime,GPSWeek,Lat,Lng,Alt,RelAlt,GPSAlt,R,P,Y"
    w.fmt("CAM", "QBHIHLLeeefff", cols)
    w.fmt("TRIG", "QBHIHLLeeefff", cols)
    w.fmt("MNT", "QBfffffffff", "TimeUS,I,DRoll,Roll,DPitch,Pitch,DYawB,YawB,DYawE,YawE,Dist")
    for n, t in enumerate(CAM_BOOT_S, start=11):
        values = {
            "I": 0.0, "Img": n, "GPSTime": DF_TOW0_MS, "GPSWeek": DF_WEEK, "Lat": 35.001,
            "Lng": 139.002, "Alt": 150.25, "RelAlt": 30.5, "GPSAlt": 151.0,
            "R": -12.345678, "P": 4.5, "Y": 359.9,
        }  # fmt: skip
        w.msg("TRIG", TimeUS=round((t - 0.08) * 1e6), **values)
        w.msg("CAM", TimeUS=round(t * 1e6), **values)
    for k in range(20, 100):
        mnt = dict.fromkeys(("I", "DRoll", "DPitch", "DYawB", "DYawE", "Dist"), 0.0)
        w.msg("MNT", TimeUS=k * 100_000, Roll=0.5, Pitch=-89.0, YawB=15.0, YawE=215.0, **mnt)
    (tmp_path / "new.bin").write_bytes(bytes(w.out))
    log = read_log(tmp_path / "new.bin")
    ev = log.events
    assert ev is not None and ev.seq.tolist() == [11, 12, 13]
    _close(ev.time_utc_s, [_df_utc(t) for t in CAM_BOOT_S], atol=2e-6)
    assert ev.roll_deg is not None and ev.yaw_deg is not None
    _close(ev.roll_deg, -12.345678, atol=1e-5)
    _close(ev.yaw_deg, 359.9, atol=1e-4)
    assert any("TRIG (3, at the trigger command) not used" in w_ for w_ in log.warnings)
    assert log.gimbal is not None and log.gimbal.source == "dataflash:MNT"
    _close(log.gimbal.yaw_deg, 215.0, atol=1e-9)
    _close(log.gimbal.pitch_deg, -89.0, atol=1e-9)
    assert len(log.warnings) == 1  # the TRIG note only: nothing truncated, nothing corrupt


def test_dataflash_without_gps_falls_back_to_cam_gpstime(tmp_path: Path) -> None:
    w = _DataFlashWriter()
    w.fmt("CAM", "QIHLLeeeccC", "TimeUS,GPSTime,GPSWeek,Lat,Lng,Alt,RelAlt,GPSAlt,Roll,Pitch,Yaw")
    w.msg(
        "CAM", TimeUS=5_000_000, GPSTime=DF_TOW0_MS, GPSWeek=DF_WEEK, Lat=1.0, Lng=2.0,
        Alt=3.0, RelAlt=4.0, GPSAlt=5.0, Roll=0.0, Pitch=0.0, Yaw=0.0,
    )  # fmt: skip
    (tmp_path / "nogps.bin").write_bytes(bytes(w.out))
    log = read_log(tmp_path / "nogps.bin")
    assert log.events is not None
    assert log.events.time_utc_s[0] == _df_utc(0.0)
    assert any("no GPS messages" in w_ for w_ in log.warnings)
    assert any("last GPS fix" in w_ for w_ in log.warnings)
    assert log.positions is None and log.attitudes is None


def test_tlog_mount_status_yaw_is_made_earth_frame(tmp_path: Path) -> None:
    """ArduPilot MOUNT_STATUS: centi-degrees, pointing_a pitch, pointing_b roll, pointing_c yaw
    relative to the nose; no time field (the vehicle boot time of arrival stands in)."""
    _, mav = _tlog_writer()
    out = bytearray()
    for k in range(50):
        boot_ms = 100 * k
        rx = round((UTC_AT_BOOT + boot_ms / 1000 + GCS_CLOCK_AHEAD_S) * 1e6)
        yaw = np.radians(350.0 + 0.4 * k)  # the vehicle turns through north
        out += _record(mav, mav.attitude_encode(boot_ms, 0.0, 0.0, yaw, 0, 0, 0), rx)
        out += _record(mav, mav.system_time_encode(round((UTC_AT_BOOT + boot_ms / 1000) * 1e6), boot_ms), rx)
        out += _record(mav, mav.mount_status_encode(0, 0, -9000, 150, 2500), rx)
    (tmp_path / "m.tlog").write_bytes(bytes(out))
    log = read_log(tmp_path / "m.tlog")
    assert log.events is None and log.gimbal is not None
    assert log.gimbal.source == "tlog:MOUNT_STATUS"
    _close(log.gimbal.pitch_deg, -90.0, atol=1e-9)
    _close(log.gimbal.roll_deg, 1.5, atol=1e-9)
    expected = (350.0 + 0.4 * np.arange(50) + 25.0) % 360
    _close(log.gimbal.yaw_deg, expected, atol=1e-4)


def test_tlog_positions_start_at_the_first_gps_fix() -> None:
    # ArduPilot reports estimator positions near 0, 0 before its GPS has a fix; they are not
    # positions of the vehicle and must not reach the geotagger.
    log = read_log(REAL / "flight.tlog")
    assert log.positions is not None
    near_null_island = (np.abs(log.positions.lat_deg) < 1.0) & (np.abs(log.positions.lon_deg) < 1.0)
    assert not near_null_island.any()


# ---------------------------------------------------------------- autopilot GPS exports as CSV


@needs_real
def test_ardupilot_gps_csv_from_mavlogdump(tmp_path: Path, dataflash: FlightLog) -> None:
    """The real tool's output: pymavlink's mavlogdump.py --format csv --types GPS of the SITL
    BIN. Times come from GWk/GMS (checked against the datetime module and 18 leap seconds),
    positions lie on the BIN's own POS track (within the receiver's lag)."""
    import subprocess
    import sys

    script = Path(sys.executable).parent / "mavlogdump.py"
    dump = subprocess.run(
        [sys.executable, str(script), "--format", "csv", "--types", "GPS", str(BIN)],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    (tmp_path / "gps.csv").write_text(dump.stdout)
    header = dump.stdout.splitlines()[0].split(",")
    assert {"TimeUS", "Status", "GMS", "GWk", "NSats", "HDop", "Lat", "Lng", "Alt"} <= set(header)
    log = read_log(tmp_path / "gps.csv")
    assert log.format == "csv" and log.positions is not None
    assert log.positions.source == "csv:ardupilot_gps" and log.positions.alt_amsl_m is not None
    rows = [line.split(",") for line in dump.stdout.splitlines()[1:]]
    week, ms = header.index("GWk"), header.index("GMS")
    expected = sorted(
        (
            dt.datetime(1980, 1, 6, tzinfo=dt.UTC) + dt.timedelta(weeks=int(r[week]), milliseconds=int(r[ms]))
        ).timestamp()
        - 18
        for r in rows
    )
    _close(log.positions.time_utc_s, np.unique(expected), atol=1e-6)
    pos = dataflash.positions
    assert pos is not None
    inside = (log.positions.time_utc_s > pos.time_utc_s[0]) & (log.positions.time_utc_s < pos.time_utc_s[-1])
    lat = np.interp(log.positions.time_utc_s, pos.time_utc_s, pos.lat_deg)
    lon = np.interp(log.positions.time_utc_s, pos.time_utc_s, pos.lon_deg)
    distance = _metres(lat, lon, log.positions.lat_deg, log.positions.lon_deg)[inside]
    # The GPS fix lags the EKF's POS (SITL's simulated receiver delay) by a few metres at 20 m/s.
    assert np.median(distance) < 5.0 and inside.sum() > 100


def test_px4_gps_csv_from_ulog2csv(tmp_path: Path) -> None:
    """pyulog's ulog2csv of the PX4 fixture: vehicle_gps_position with lat, lon in 1e-7 deg and
    alt in mm, time from time_utc_usec; compared with the fixture generator's truth."""
    import subprocess
    import sys

    script = Path(sys.executable).parent / "ulog2csv"
    subprocess.run(
        [str(script), "-o", str(tmp_path), "-m", "vehicle_gps_position", str(DATA / "px4_survey.ulg")],
        capture_output=True,
        check=True,
        timeout=120,
    )
    csv_path = tmp_path / "px4_survey_vehicle_gps_position_0.csv"
    log = read_log(csv_path)
    assert log.positions is not None and log.positions.source == "csv:px4_vehicle_gps_position"
    gen = _ulog_fixture_module()
    boot = np.array([float(line.split(",")[0]) / 1e6 for line in csv_path.read_text().splitlines()[1:]])
    truth = np.array([gen.position(t) for t in boot])
    _close(log.positions.time_utc_s, gen.UTC0_S + gen.RATE * boot, atol=1e-5)
    _close(log.positions.lat_deg, truth[:, 0], atol=1e-7)
    _close(log.positions.lon_deg, truth[:, 1], atol=1e-7)
    assert log.positions.alt_amsl_m is not None
    _close(log.positions.alt_amsl_m, truth[:, 2], atol=1e-3)


def test_newer_px4_and_plain_utc_csv(tmp_path: Path) -> None:
    (tmp_path / "sensor_gps.csv").write_text(
        "timestamp,time_utc_usec,latitude_deg,longitude_deg,altitude_msl_m,fix_type\n"
        "5000000,0,0,0,0,0\n"  # before the fix: skipped
        "5200000,1700000005200000,47.1234567,8.7654321,512.5,3\n"
        "5400000,1700000005400000,47.1234667,8.7654321,512.6,3\n"
    )
    log = read_log(tmp_path / "sensor_gps.csv")
    assert log.positions is not None and log.positions.source == "csv:px4_sensor_gps"
    _close(log.positions.time_utc_s, [1_700_000_005.2, 1_700_000_005.4], atol=1e-6)
    _close(log.positions.lat_deg, [47.1234567, 47.1234667], atol=1e-9)
    assert any("1 rows without a GPS fix" in w for w in log.warnings)
    (tmp_path / "plain.csv").write_text(
        "time_utc,latitude,longitude,altitude\n2023-11-14T22:13:20.5Z,-35.5,149.25,600\n"
        "2023-11-14T22:13:21.5Z,-35.50001,149.25,601\n"
    )
    log = read_log(tmp_path / "plain.csv")
    assert log.positions is not None and log.positions.alt_amsl_m is not None
    _close(log.positions.time_utc_s, [1_700_000_000.5, 1_700_000_001.5], atol=1e-6)
    _close(log.positions.lat_deg, [-35.5, -35.50001], atol=1e-12)


def test_a_csv_in_no_known_layout_names_what_it_looked_for_and_found(tmp_path: Path) -> None:
    (tmp_path / "mystery.csv").write_text("when,north,east,height\n1,2,3,4\n")
    with pytest.raises(TelemetryError) as caught:
        read_log(tmp_path / "mystery.csv")
    message = str(caught.value)
    assert "Columns found: when, north, east, height" in message
    for looked in ("GPSDateTime", "GWk and GMS", "time_utc_usec", "latitude_deg", "time_utc"):
        assert looked in message


@needs_real
@pytest.mark.parametrize("path", [TLOG, BIN], ids=["tlog", "dataflash"])
def test_readers_report_progress_by_bytes(path: Path) -> None:
    """Progress while a log is read: (done, total) calls that never go back and end at the
    total, with intermediate steps on a file of more than a megabyte."""
    calls: list[tuple[int, int]] = []
    read_log(path, lambda done, total: calls.append((done, total)))
    done = [d for d, _ in calls]
    totals = {t for _, t in calls}
    assert len(totals) == 1 and done == sorted(done)
    (total,) = totals
    assert done[-1] == total and total >= path.stat().st_size
    assert len([d for d in done if 0 < d < total]) >= 1
