"""`sfap monitor` through the real click group, against the simulated vehicle: a planned
flight recorded whole, a link cut and restored mid-flight, Ctrl-C, bad input, and
a second system on the link (a scripted pymavlink peer)."""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import signal
import socket
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner, Result
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from pyproj import Geod
from tcp_relay import Relay

from acquisition.simulator.server import SimulatedVehicle
from acquisition.telemetry.tlog import read_tlog
from planner.formats import read_mission
from planner.mission import Mission
from sfap.cli import cli

ROOT = Path(__file__).resolve().parents[2]
GEOD = Geod(ellps="WGS84")
LAT0, LON0 = 42.2012, -1.4866


def _offset(east_m: float, north_m: float) -> tuple[float, float]:
    az = math.degrees(math.atan2(east_m, north_m))
    lon, lat, _ = GEOD.fwd(LON0, LAT0, az, math.hypot(east_m, north_m))
    return lon, lat


@pytest.fixture(scope="module")
def small_plan(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Mission, dict]:
    """`sfap plan` of a 180 m x 160 m field with the gully's camera (65 photos, 5 lines)."""
    folder = tmp_path_factory.mktemp("plan")
    ring = [list(_offset(e, n)) for e, n in ((20, 20), (200, 20), (200, 180), (20, 180), (20, 20))]
    area = {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [ring]}}
    (folder / "field.geojson").write_text(json.dumps(area))
    (folder / "field.toml").write_text(
        (ROOT / "missions" / "bardenas-gully.toml")
        .read_text()
        .replace('area = "bardenas-gully.geojson"', 'area = "field.geojson"')
        .replace("home = [42.2012, -1.4866]", f"home = [{LAT0}, {LON0}]")
    )
    result = CliRunner().invoke(cli, ["plan", str(folder / "field.toml"), "-o", str(folder / "out")])
    assert result.exit_code == 0, result.output
    mission = read_mission(folder / "out" / "mission.plan")
    summary = json.loads((folder / "out" / "summary.json").read_text())
    return folder / "out", mission, summary


def _run(*args: str) -> Result:
    return CliRunner().invoke(cli, ["monitor", *args])


def _start_when_listened_to(vehicle: SimulatedVehicle, timeout_s: float = 15.0) -> threading.Thread:
    """Start the mission once a ground station (the monitor) sends its heartbeat."""

    def wait_then_start() -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if vehicle.received_counts.get("HEARTBEAT", 0) > 0:
                time.sleep(0.2)  # let the monitor open its files
                vehicle.auto_start()
                return
            time.sleep(0.01)

    thread = threading.Thread(target=wait_then_start, daemon=True)
    thread.start()
    return thread


def _read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def test_monitor_records_a_planned_flight_whole(tmp_path: Path, small_plan: tuple) -> None:
    plan_dir, mission, summary = small_plan
    n = summary["photo_count"]
    out = tmp_path / "flight"
    with SimulatedVehicle(speedup=100, home=mission.home, boot_delay_s=0, gps_fix_s=0) as v:
        v.load_mission(mission.items)
        _start_when_listened_to(v)
        result = _run("--connect", v.url_for_client, "--plan", str(plan_dir), "-o", str(out))
    assert result.exit_code == 0, result.output
    assert "landed and disarmed" in result.stdout
    assert str(out / "flight.tlog") in result.stdout and str(out / "triggers.csv") in result.stdout
    assert f"photos: {n} of {n} planned" in result.stdout
    assert "stations missed: 0" in result.stdout
    assert f"/{n} | missed 0 | item " in result.stderr  # the live status line
    events = read_tlog(out / "flight.tlog").events
    assert events is not None and len(events) == n
    assert events.lat_deg is not None and events.lon_deg is not None
    stations = json.loads((plan_dir / "stations.geojson").read_text())["features"]
    lat = np.array([s["properties"]["lat_deg"] for s in stations])
    lon = np.array([s["properties"]["lon_deg"] for s in stations])
    _, _, dist = GEOD.inv(events.lon_deg, events.lat_deg, lon, lat)
    assert np.max(dist) < summary["trigger_distance_m"]
    rows = _read_csv(out / "triggers.csv")
    assert [int(r["seq"]) for r in rows] == list(events.seq)
    saved = json.loads((out / "monitor.json").read_text())
    assert saved["photos_taken"] == n and saved["missed_stations"] == []
    # the recording is not overwritten without --overwrite (exit 2: a usage error)
    before = (out / "flight.tlog").read_bytes()
    again = _run("--connect", "tcp://127.0.0.1:9", "--plan", str(plan_dir), "-o", str(out))
    assert again.exit_code == 2 and "--overwrite" in again.stderr
    assert "Traceback" not in again.output
    assert (out / "flight.tlog").read_bytes() == before


def test_monitor_says_it_lost_the_link_and_reconnected(tmp_path: Path, small_plan: tuple) -> None:
    plan_dir, mission, summary = small_plan
    n = summary["photo_count"]
    out = tmp_path / "flight"
    with SimulatedVehicle(speedup=60, home=mission.home, boot_delay_s=0, gps_fix_s=0) as v:
        v.load_mission(mission.items)
        relay = Relay(v.url_for_client).open()

        def cut_and_restore() -> None:
            deadline = time.monotonic() + 30
            while len(v.flight.shots) < n // 3 and time.monotonic() < deadline:
                time.sleep(0.005)
            relay.cut()
            time.sleep(0.5)
            relay.restore()

        _start_when_listened_to(v)
        cutter = threading.Thread(target=cut_and_restore, daemon=True)
        cutter.start()
        try:
            result = _run("--connect", relay.url, "--plan", str(plan_dir), "-o", str(out))
        finally:
            cutter.join(timeout=5)
            relay.close()
    assert result.exit_code == 0, result.output
    assert "link lost" in result.stderr and "reconnected (1 so far)" in result.stderr
    assert "1 drops, 1 reconnections" in result.stdout
    saved = json.loads((out / "monitor.json").read_text())
    assert saved["photos_taken"] == n  # counted from the image index, events lost or not
    lost = n - saved["events_received"]
    assert saved["photos_unseen"] == lost
    assert 0 < lost < n - n // 3  # lost while cut; recorded before and after
    assert len(saved["missed_stations"]) == lost
    assert f"stations missed: {lost}" in result.stdout
    events = read_tlog(out / "flight.tlog").events
    assert events is not None and len(events) == n - lost


def test_ctrl_c_closes_the_recording_cleanly(tmp_path: Path, small_plan: tuple) -> None:
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        pytest.skip("SIGINT is not Python's KeyboardInterrupt here")
    plan_dir, mission, _ = small_plan
    out = tmp_path / "flight"
    with SimulatedVehicle(speedup=10, home=mission.home, boot_delay_s=0, gps_fix_s=0) as v:
        v.load_mission(mission.items)

        def interrupt_once_recording() -> None:
            deadline = time.monotonic() + 15
            while v.received_counts.get("HEARTBEAT", 0) < 2 and time.monotonic() < deadline:
                time.sleep(0.01)
            time.sleep(0.5)
            os.kill(os.getpid(), signal.SIGINT)

        thread = threading.Thread(target=interrupt_once_recording, daemon=True)
        thread.start()
        result = _run("--connect", v.url_for_client, "--plan", str(plan_dir), "-o", str(out), "--json")
        thread.join(timeout=5)
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["reason"] == "interrupted" and report["photos_taken"] == 0
    assert report["tlog"] == str(out / "flight.tlog") and report["connected"]
    flight = read_tlog(out / "flight.tlog")
    assert flight.positions is not None and len(flight.positions) > 10
    assert not any("truncated" in w for w in flight.warnings)  # whole packets only
    assert _read_csv(out / "triggers.csv") == []  # the header, no photo on the ground
    assert json.loads((out / "monitor.json").read_text())["photos_taken"] == 0


def test_no_vehicle_is_exit_1_and_writes_nothing(tmp_path: Path, small_plan: tuple) -> None:
    plan_dir = small_plan[0]
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    out = tmp_path / "flight"
    result = _run("--connect", f"tcp://127.0.0.1:{port}", "--plan", str(plan_dir), "-o", str(out))
    assert result.exit_code == 1
    assert "refused" in result.stderr and "Traceback" not in result.output
    assert not out.exists()


def test_a_folder_that_is_not_a_plan_is_a_usage_error(tmp_path: Path) -> None:
    result = _run("--connect", "tcp://127.0.0.1:9", "--plan", str(tmp_path), "-o", str(tmp_path / "o"))
    assert result.exit_code == 2
    assert "stations.geojson" in result.stderr and "sfap plan" in result.stderr


def test_a_link_that_does_not_come_back_is_exit_1_with_the_recording_kept(
    tmp_path: Path, small_plan: tuple
) -> None:
    plan_dir, mission, _ = small_plan
    out = tmp_path / "flight"
    with SimulatedVehicle(speedup=10, home=mission.home, boot_delay_s=0, gps_fix_s=0) as v:
        relay = Relay(v.url_for_client).open()

        def cut_for_good() -> None:
            deadline = time.monotonic() + 15
            while v.received_counts.get("HEARTBEAT", 0) < 2 and time.monotonic() < deadline:
                time.sleep(0.01)
            time.sleep(0.3)
            relay.cut()

        thread = threading.Thread(target=cut_for_good, daemon=True)
        thread.start()
        try:
            result = _run(
                "--connect", relay.url, "--plan", str(plan_dir), "-o", str(out),
                "--reconnect-timeout-s", "1",
            )  # fmt: skip
        finally:
            thread.join(timeout=5)
            relay.close()
    assert result.exit_code == 1
    assert "did not come back within 1 s" in result.stderr and str(out) in result.stderr
    assert "link lost" in result.stderr and "Traceback" not in result.output
    flight = read_tlog(out / "flight.tlog")
    assert flight.positions is not None and len(flight.positions) > 0
    saved = json.loads((out / "monitor.json").read_text())
    assert saved["drops"] == 1 and saved["reconnects"] == 0 and not saved["connected"]


# --- the whole traffic of the link --------------------------------------------------------------


def _packer(system: int, component: int, seq: int = 0) -> Any:
    """Packs messages as one MAVLink sender does, numbering them in turn."""
    mav = mavlink2.MAVLink(None, srcSystem=system, srcComponent=component)
    mav.seq = seq

    def pack(msg: Any) -> bytes:
        data = bytes(msg.pack(mav))
        mav.seq = (mav.seq + 1) % 256
        return data

    return pack


def test_monitor_logs_a_second_system_and_counts_no_false_loss(tmp_path: Path) -> None:
    vehicle, other = _packer(1, 1, 100), _packer(2, 1, 7)
    boot_ms = [0]

    def vehicle_heartbeat(armed: bool) -> Any:
        return mavlink2.MAVLink_heartbeat_message(2, 3, 1 | (128 if armed else 0), 3, 4, 3)

    def position(alt_rel_home_m: float) -> Any:
        boot_ms[0] += 200
        return mavlink2.MAVLink_global_position_int_message(
            boot_ms[0], 422012000, -14866000, 400_000, round(alt_rel_home_m * 1000), 0, 0, 0, 0
        )

    ack_to_other_gcs = mavlink2.MAVLink_command_ack_message(400, 0, 0, 0, 254, 190)
    packets = [other(mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3))]  # another GCS, first
    packets.append(vehicle(vehicle_heartbeat(False)))
    packets.append(vehicle(ack_to_other_gcs))  # the vehicle answers the other ground station
    packets.append(vehicle(vehicle_heartbeat(True)))
    for alt in (1.0, 5.0, 10.0, 5.0, 0.5):
        packets.append(vehicle(position(alt)))
        packets.append(other(mavlink2.MAVLink_system_time_message(0, boot_ms[0])))
        packets.append(vehicle(ack_to_other_gcs))
    packets.append(vehicle(vehicle_heartbeat(False)))  # landed: the monitor ends

    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    server.settimeout(15)
    done = threading.Event()

    def serve() -> None:
        with contextlib.suppress(OSError):
            peer, _ = server.accept()
            with peer:
                peer.sendall(b"".join(packets))
                done.wait(20)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    out = tmp_path / "flight"
    try:
        result = _run("--connect", f"tcp://127.0.0.1:{server.getsockname()[1]}", "-o", str(out), "--json")
    finally:
        done.set()
        thread.join(timeout=5)
        server.close()
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["reason"] == "landed"
    assert report["messages"] == len(packets)
    by_system = {q["system_id"]: q for q in report["link"]}
    assert by_system[1]["received"] == sum(p[5] == 1 for p in packets) and by_system[1]["lost"] == 0
    assert by_system[2]["received"] == sum(p[5] == 2 for p in packets) and by_system[2]["lost"] == 0
    assert report["link_quality_pct"] == 100.0
    data = (out / "flight.tlog").read_bytes()
    at = 0
    for packet in packets:  # every packet, in order, after its 8-byte time stamp
        assert data[at + 8 : at + 8 + len(packet)] == packet
        at += 8 + len(packet)
    assert at == len(data)
