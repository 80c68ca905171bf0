"""acquisition.telemetry.tlog_records: a .tlog's records walked without pymavlink's stream
parser. Oracle: pymavlink's own log reader (mavutil.mavlogfile with robust parsing, the path
the reader used alone before) on the same bytes; every field of what the reader collects
(messages counted, rows with their receive times, sources, corrupt packets, where reading
stopped) must be the same, on the real SITL flight's tlog, on that tlog damaged at random, and
on frames pymavlink itself writes (v1 and v2, unknown ids, signed)."""

from __future__ import annotations

import functools
import struct
import tempfile
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v10 import ardupilotmega as mavlink1
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from shared_data import SHARED_DATA

from acquisition.telemetry import tlog
from acquisition.telemetry.tlog_records import IrregularLogError

SITL_TLOG = SHARED_DATA / "ardupilot_sitl_plane" / "flight.tlog"
# The first 150 KB of the flight (the whole file takes 0.5-0.8 s through pymavlink): the
# vehicle's heartbeats, GPS, attitude and SYSTEM_TIME, cut at a record boundary.
_HEAD = 150_000


def _records_of(data: bytes) -> list[int]:
    """The byte offsets where each record of a regular tlog starts (header lengths by hand)."""
    starts, pos = [], 0
    while pos < len(data):
        starts.append(pos)
        magic, length = data[pos + 8], data[pos + 9]
        pos += 8 + (12 if magic == 0xFD else 8) + length
    return starts


@functools.cache
def _sitl_head() -> bytes:
    data = SITL_TLOG.read_bytes()
    return data[: max(s for s in _records_of(data) if s <= _HEAD)]


def _same_reading(path: Path) -> None:
    """What the reader collects equals what pymavlink's reader alone gives (repr: every field,
    floats to the last bit, NaN included)."""
    assert repr(tlog._collect(str(path))) == repr(tlog._collect_stream(str(path)))


def test_the_real_flight_is_read_record_by_record_with_the_same_result(tmp_path: Path) -> None:
    fast = tlog._collect_records(str(SITL_TLOG))  # raises if the file were not regular
    assert repr(fast) == repr(tlog._collect_stream(str(SITL_TLOG)))
    assert fast.n_messages == 26825 and fast.n_bad == 0
    assert len(fast.rows["CAMERA_FEEDBACK"]) == 70 and len(fast.rows["GLOBAL_POSITION_INT"]) > 800


@settings(max_examples=30, deadline=None)
@given(
    cut=st.integers(0, _HEAD),
    flips=st.lists(st.tuples(st.integers(0, _HEAD - 1), st.integers(1, 255)), max_size=3),
    inserted=st.lists(st.tuples(st.integers(0, _HEAD - 1), st.binary(min_size=1, max_size=20)), max_size=2),
)
def test_a_damaged_log_gives_what_pymavlink_gives(
    cut: int, flips: list[tuple[int, int]], inserted: list[tuple[int, bytes]]
) -> None:
    """Bytes flipped (a payload, a CRC, a length, a magic, a receive time), garbage inserted,
    the file cut anywhere: the same messages, corrupt packets and stopping point."""
    data = bytearray(_sitl_head())
    for at, mask in flips:
        data[at % len(data)] ^= mask
    for at, junk in sorted(inserted, reverse=True):
        data[at:at] = junk
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "damaged.tlog"
        path.write_bytes(bytes(data[: cut or len(data)]))
        _same_reading(path)


def _tlog(frames: list[bytes]) -> bytes:
    """Frames as a ground station logs them, 20 ms apart."""
    return b"".join(struct.pack(">Q", 1_700_000_000_000_000 + 20_000 * k) + f for k, f in enumerate(frames))


def test_frames_pymavlink_writes_v1_v2_unknown_and_signed(tmp_path: Path) -> None:
    """Frames packed by pymavlink itself: v2 and v1 (whose short frames pymavlink's reader may
    read past: left to it), a message id no dialect knows (counted, as pymavlink does), and a
    signed frame (left to pymavlink)."""
    v2 = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    v1 = mavlink1.MAVLink(None, srcSystem=1, srcComponent=1)
    heartbeat = mavlink2.MAVLink_heartbeat_message(1, 3, 0, 0, 4, 3)  # fixed wing, ArduPilot
    attitude = mavlink2.MAVLink_attitude_message(1000, 0.1, -0.2, 1.5, 0.0, 0.0, 0.0)
    system_time = mavlink2.MAVLink_system_time_message(1_700_000_000_000_000, 1000)
    regular = [
        heartbeat.pack(v2),
        system_time.pack(v2),
        attitude.pack(v2),
        mavlink1.MAVLink_attitude_message(1200, 0.2, -0.1, 1.4, 0.0, 0.0, 0.0).pack(v1),
        attitude.pack(v2),
    ]
    path = tmp_path / "regular.tlog"
    path.write_bytes(_tlog(regular))
    fast = tlog._collect_records(str(path))
    assert repr(fast) == repr(tlog._collect_stream(str(path)))
    assert fast.n_messages == 5 and len(fast.rows["ATTITUDE"]) == 3 and fast.vehicle == (1, 1)

    unknown = bytearray(attitude.pack(v2))
    unknown[7:10] = (0xEEEEEE).to_bytes(3, "little")  # an id in no dialect: its CRC is not checked
    path.write_bytes(_tlog([*regular, bytes(unknown)]))
    assert tlog._collect_records(str(path)).n_messages == 6
    _same_reading(path)

    short = mavlink1.MAVLink_param_request_list_message(1, 1).pack(v1)  # a 10-byte frame
    path.write_bytes(_tlog([*regular, short, *regular]))
    with pytest.raises(IrregularLogError, match="10-byte frame"):
        tlog._collect_records(str(path))
    _same_reading(path)

    signer = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    signer.signing.secret_key = bytes(range(32))
    signer.signing.sign_outgoing = True
    signed = attitude.pack(signer)
    path.write_bytes(_tlog([*regular, signed]))
    with pytest.raises(IrregularLogError, match="signed"):
        tlog._collect_records(str(path))
    _same_reading(path)


def _reading_in_a_fresh_process(path: Path, collect: str) -> str:
    """repr of ``tlog.<collect>(path)`` in a new Python: pymavlink's choice of dialect (by the
    file's first frame) is process-wide state that another read in this process would have set."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k not in ("MAVLINK20", "MAVLINK_DIALECT")}
    code = f"from acquisition.telemetry import tlog; print(repr(tlog.{collect}({str(path)!r})))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.mark.parametrize("first", ["v2", "v1"])
def test_messages_past_id_255_are_read_as_pymavlink_reads_them(tmp_path: Path, first: str) -> None:
    """pymavlink's reader decodes with the MAVLink 2 dialect when the file's first frame is a
    MAVLink 2 one, else with the MAVLink 1 dialect, which knows no message past id 255
    (CAMERA_IMAGE_CAPTURED 263, GIMBAL_DEVICE_ATTITUDE_STATUS 285). Each in a fresh process."""
    v2 = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    v1 = mavlink1.MAVLink(None, srcSystem=1, srcComponent=1)
    heartbeat = (mavlink2 if first == "v2" else mavlink1).MAVLink_heartbeat_message(1, 3, 0, 0, 4, 3)
    frames = [heartbeat.pack(v2 if first == "v2" else v1)]
    for k in range(20):
        frames.append(mavlink2.MAVLink_attitude_message(100 * k, 0.0, 0.0, 1.5, 0.0, 0.0, 0.0).pack(v2))
        q = [0.7071, 0.0, -0.7071, 0.0]
        frames.append(
            mavlink2.MAVLink_gimbal_device_attitude_status_message(0, 0, 100 * k, 32, q, 0, 0, 0, 0).pack(v2)
        )
        frames.append(
            mavlink2.MAVLink_camera_image_captured_message(
                100 * k, 1_700_000_000_000_000 + 100_000 * k, 0, 0, 0, 0, 0, q, k, 1, b""
            ).pack(v2)
        )
    path = tmp_path / f"{first}.tlog"
    path.write_bytes(_tlog(frames))
    fast = _reading_in_a_fresh_process(path, "_collect_records")
    assert fast == _reading_in_a_fresh_process(path, "_collect_stream")
    assert ("'GIMBAL_DEVICE_ATTITUDE_STATUS': []" in fast) == (first == "v1")
    assert ("'CAMERA_IMAGE_CAPTURED': []" in fast) == (first == "v1")
