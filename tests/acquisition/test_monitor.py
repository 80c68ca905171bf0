"""The in-flight monitor: FlightRecorder on synthetic MAVLink messages (dedup, link quality,
missed stations, durable files), then real flights of planned missions in the simulator,
one of them through a link that is cut and restored.

The flights run on simulated time (a :class:`VirtualClock` shared by the simulated vehicle, the
monitor and the test's own waits) except the one through a relay (its thread is no party of the
clock), which stays on the wall clock as the real-time flight case. On the virtual clock the
receive times in the files are the clock's UTC (its start is the wall clock's now), and every
wait of a test (``wait_until``) is in simulated seconds, bounded by wall seconds too."""

from __future__ import annotations

import contextlib
import csv
import json
import math
import socket
import struct
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from pyproj import Geod
from tcp_relay import Relay

from acquisition.clock import WALL_CLOCK, Clock, ClockQueue, VirtualClock
from acquisition.errors import LinkError
from acquisition.flight_recorder import FlightRecorder
from acquisition.link import Link
from acquisition.link_quality import SeqCounter
from acquisition.monitor import MonitorResult, StopReason, monitor
from acquisition.monitor_state import MonitorState
from acquisition.recording_files import CSV_COLUMNS
from acquisition.simulator.server import SimulatedVehicle
from acquisition.station_tracker import StationPlan, load_station_plan
from acquisition.telemetry.tlog import read_tlog
from acquisition.transfer import upload_mission
from planner.errors import OutputExistsError
from planner.mission import Autopilot
from planner.plan import SurveyPlan
from planner.plan_folder import write_outputs
from planner.spec import load_spec
from planner.survey import plan_survey

ROOT = Path(__file__).resolve().parents[2]
GEOD = Geod(ellps="WGS84")
LAT0, LON0 = 42.2012, -1.4866
T0 = 1_763_800_000.0  # a UTC time (2025-11-22) for synthetic messages


# --- synthetic messages -------------------------------------------------------------------------


class Wire:
    """Packs messages as one sender would and parses them back with pymavlink, so each one is
    a received message (with its seq, source and bytes)."""

    def __init__(self, system: int = 1, component: int = 1) -> None:
        self.encoder = mavlink2.MAVLink(None, srcSystem=system, srcComponent=component)
        self.decoder = mavlink2.MAVLink(None)
        self.seq = 0

    def __call__(self, msg: Any, seq: int | None = None) -> Any:
        self.encoder.seq = self.seq if seq is None else seq
        self.seq = (self.encoder.seq + 1) % 256
        data = msg.pack(self.encoder)
        parsed = self.decoder.parse_buffer(bytes(data))
        assert parsed is not None and len(parsed) == 1
        return parsed[0]


def heartbeat(armed: bool) -> Any:
    return mavlink2.MAVLink_heartbeat_message(2, 3, 1 | (128 if armed else 0), 3, 4, 3)


def system_time(boot_s: float) -> Any:
    return mavlink2.MAVLink_system_time_message(round((T0 + boot_s) * 1e6), round(boot_s * 1e3))


def offset(east_m: float, north_m: float) -> tuple[float, float]:
    """(lat, lon) of a point east/north of (LAT0, LON0), geodesically."""
    dist = math.hypot(east_m, north_m)
    az = math.degrees(math.atan2(east_m, north_m))
    lon, lat, _ = GEOD.fwd(LON0, LAT0, az, dist)
    return lat, lon


def position(boot_s: float, east_m: float, north_m: float, v_east: float, v_north: float) -> Any:
    lat, lon = offset(east_m, north_m)
    return mavlink2.MAVLink_global_position_int_message(
        round(boot_s * 1e3),
        round(lat * 1e7),
        round(lon * 1e7),
        80_000,
        70_000,
        round(v_north * 100),
        round(v_east * 100),
        0,
        9000,
    )


def feedback(boot_s: float, index: int, east_m: float, north_m: float) -> Any:
    lat, lon = offset(east_m, north_m)
    return mavlink2.MAVLink_camera_feedback_message(
        round((T0 + boot_s) * 1e6), 1, 0, index, round(lat * 1e7), round(lon * 1e7),
        80.0, 70.0, 1.5, -2.0, 91.0, 0.0, 0, 0,
    )  # fmt: skip


def line_plan(legs: list[tuple[float, float, int]], spacing_m: float = 10.0) -> StationPlan:
    """Stations along east-west legs: (north_m, heading_deg, count) each, from east 0 m."""
    lat, lon, pass_, line, heading = [], [], [], [], []
    for k, (north, head, count) in enumerate(legs):
        for i in range(count):
            east = i * spacing_m if head == 90.0 else (count - 1 - i) * spacing_m
            la, lo = offset(east, north)
            lat.append(la)
            lon.append(lo)
            pass_.append(0)
            line.append(k)
            heading.append(head)
    n = len(lat)
    return StationPlan(
        name="synthetic",
        lat_deg=np.array(lat),
        lon_deg=np.array(lon),
        pass_index=np.array(pass_, dtype=np.int64),
        line_index=np.array(line, dtype=np.int64),
        heading_deg=np.array(heading),
        match_radius_m=np.full(n, spacing_m / 2),
        trigger_distance_m=spacing_m,
    )


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


# --- recorder: files ----------------------------------------------------------------------------


def test_tlog_is_stamped_packets_that_read_back_and_the_csv_matches(tmp_path: Path) -> None:
    wire = Wire()
    sent: list[tuple[float, Any]] = []
    with FlightRecorder(tmp_path / "rec") as rec:
        for k in range(30):
            t = k * 0.1
            for msg in (system_time(t), heartbeat(True), position(t, 5 * t, 0, 5, 0)):
                received = wire(msg)
                sent.append((T0 + t, received))
                rec.record(received, T0 + t)
            if k % 10 == 5:
                received = wire(feedback(t, k // 10 + 1, 5 * t, 0))
                sent.append((T0 + t, received))
                rec.record(received, T0 + t)
    data = (tmp_path / "rec" / "flight.tlog").read_bytes()
    expected = b"".join(struct.pack(">Q", round(t * 1e6)) + msg.get_msgbuf() for t, msg in sent)
    assert data == expected  # byte for byte what MAVProxy/QGC write
    flight = read_tlog(tmp_path / "rec" / "flight.tlog")
    assert flight.events is not None and len(flight.events) == 3
    rows = read_csv(tmp_path / "rec" / "triggers.csv")
    assert tuple(rows[0]) == CSV_COLUMNS
    ev = flight.events
    for i, row in enumerate(rows):
        assert int(row["seq"]) == ev.seq[i]
        assert float(row["time_utc_s"]) == pytest.approx(ev.time_utc_s[i], abs=1e-6)
        assert ev.lat_deg is not None and ev.lon_deg is not None and ev.yaw_deg is not None
        assert float(row["lat_deg"]) == pytest.approx(ev.lat_deg[i], abs=1e-9)
        assert float(row["lon_deg"]) == pytest.approx(ev.lon_deg[i], abs=1e-9)
        assert float(row["yaw_deg"]) == pytest.approx(ev.yaw_deg[i], abs=1e-3)
        assert row["source"] == "CAMERA_FEEDBACK"
    summary = json.loads((tmp_path / "rec" / "monitor.json").read_text())
    assert summary["photos_taken"] == 3 and summary["link_quality_pct"] == 100.0


def test_files_are_durable_while_recording_and_csv_only_grows(tmp_path: Path) -> None:
    wire = Wire()
    rec = FlightRecorder(tmp_path / "rec")
    csv_path = tmp_path / "rec" / "triggers.csv"
    sizes = [csv_path.stat().st_size]
    heads: list[bytes] = [csv_path.read_bytes()]
    rec.record(wire(system_time(0.0)), T0)
    for k in range(1, 4):
        rec.record(wire(feedback(k, k, 10 * k, 0)), T0 + k)
        # read by another handle while the recorder is open: the row is already there
        now = csv_path.read_bytes()
        assert now.startswith(heads[-1]) and len(now) > sizes[-1]
        assert now.count(b"\n") == k + 1
        heads.append(now)
        sizes.append(len(now))
    # the tlog is readable mid-recording, every message in it
    flight = read_tlog(tmp_path / "rec" / "flight.tlog")
    assert flight.events is not None and list(flight.events.seq) == [1, 2, 3]
    rec.close()
    assert csv_path.read_bytes() == heads[-1]


def test_an_existing_recording_is_not_overwritten(tmp_path: Path) -> None:
    with FlightRecorder(tmp_path / "rec") as rec:
        rec.record(Wire()(system_time(0.0)), T0)
    before = (tmp_path / "rec" / "flight.tlog").read_bytes()
    with pytest.raises(OutputExistsError, match="--overwrite"):
        FlightRecorder(tmp_path / "rec")
    assert (tmp_path / "rec" / "flight.tlog").read_bytes() == before
    with FlightRecorder(tmp_path / "rec", overwrite=True):
        pass
    assert (tmp_path / "rec" / "flight.tlog").read_bytes() == b""


# --- recorder: camera events --------------------------------------------------------------------


def test_repeated_camera_messages_are_recorded_once(tmp_path: Path) -> None:
    wire = Wire()
    with FlightRecorder(tmp_path / "rec") as rec:
        rec.record(wire(system_time(0.0)), T0)
        first = feedback(1.0, 1, 0, 0)
        rec.record(wire(first), T0 + 1)
        rec.record(wire(first), T0 + 1.01)  # the same event again (a second path, a resend)
        rec.record(wire(feedback(2.0, 2, 10, 0)), T0 + 2)
        rec.record(wire(feedback(2.0, 2, 10, 0)), T0 + 2.5)
        rec.record(wire(feedback(9.0, 1, 50, 0)), T0 + 9)  # index 1 again, later: a reboot
        state = rec.state()
    assert state.photos_taken == 3 and state.duplicate_events == 2
    rows = read_csv(tmp_path / "rec" / "triggers.csv")
    assert [int(r["seq"]) for r in rows] == [1, 2, 1]
    assert [float(r["time_utc_s"]) for r in rows] == pytest.approx([T0 + 1, T0 + 2, T0 + 9])


def test_px4_trigger_and_capture_of_one_photo_count_once(tmp_path: Path) -> None:
    wire = Wire()
    with FlightRecorder(tmp_path / "rec") as rec:
        rec.record(wire(system_time(0.0)), T0)
        for k in range(3):
            t = 1.0 + k
            lat, lon = offset(10 * k, 0)
            rec.record(wire(mavlink2.MAVLink_camera_trigger_message(round((T0 + t) * 1e6), k)))
            rec.record(
                wire(
                    mavlink2.MAVLink_camera_image_captured_message(
                        round(t * 1e3),
                        round((T0 + t) * 1e6),
                        0,
                        round(lat * 1e7),
                        round(lon * 1e7),
                        80_000,
                        70_000,
                        [1.0, 0.0, 0.0, 0.0],
                        k,
                        1,
                        b"",
                    )
                )
            )
        # a failed capture is not a photo
        rec.record(
            wire(
                mavlink2.MAVLink_camera_image_captured_message(
                    5000, round((T0 + 5) * 1e6), 0, 0, 0, 0, 0, [1.0, 0, 0, 0], 3, 0, b""
                )
            )
        )
        state = rec.state()
    assert state.photos_taken == 3 and state.failed_captures == 1
    rows = read_csv(tmp_path / "rec" / "triggers.csv")
    assert {r["source"] for r in rows} == {"CAMERA_IMAGE_CAPTURED"}
    assert [int(r["seq"]) for r in rows] == [0, 1, 2]


def test_trigger_only_vehicle_gets_the_last_position(tmp_path: Path) -> None:
    wire = Wire()
    with FlightRecorder(tmp_path / "rec") as rec:
        rec.record(wire(system_time(0.0)), T0)
        rec.record(wire(position(0.9, 20, 0, 5, 0)), T0 + 0.9)
        rec.record(wire(mavlink2.MAVLink_camera_trigger_message(round((T0 + 1) * 1e6), 7)))
        assert rec.state().photos_taken == 0  # held, waiting for a CAMERA_IMAGE_CAPTURED
    rows = read_csv(tmp_path / "rec" / "triggers.csv")
    assert len(rows) == 1 and rows[0]["source"] == "CAMERA_TRIGGER+GLOBAL_POSITION_INT"
    lat, _lon = offset(20, 0)
    assert float(rows[0]["lat_deg"]) == pytest.approx(lat, abs=1e-7)
    assert float(rows[0]["time_utc_s"]) == pytest.approx(T0 + 1, abs=1e-6)
    assert rows[0]["roll_deg"] == ""  # unknown is empty, never NaN or a sentinel


def test_flight_is_over_at_the_disarming_after_a_flight_not_after_ground_checks(
    tmp_path: Path,
) -> None:
    wire = Wire()

    def at(alt_rel_home_m: float) -> Any:
        lat, lon = offset(0, 0)
        return mavlink2.MAVLink_global_position_int_message(
            0, round(lat * 1e7), round(lon * 1e7), 0, round(alt_rel_home_m * 1e3), 0, 0, 0, 0
        )

    with FlightRecorder(tmp_path / "rec") as rec:
        for msg in (heartbeat(True), at(0.3), heartbeat(False)):  # checks on the ground
            rec.record(wire(msg), T0)
        assert not rec.state().flight_over
        for msg in (heartbeat(True), at(30.0), at(0.1)):
            rec.record(wire(msg), T0)
        assert not rec.state().flight_over and rec.state().armed
        rec.record(wire(heartbeat(False)), T0)
        assert rec.state().flight_over and not rec.state().armed
        rec.record(wire(heartbeat(True)), T0)  # a second flight in the same recording
        assert not rec.state().flight_over


# --- recorder: link quality ---------------------------------------------------------------------


def test_link_quality_from_sequence_gaps_duplicates_and_reordering(tmp_path: Path) -> None:
    vehicle, camera, other = Wire(1, 1), Wire(1, 100), Wire(2, 1)
    with FlightRecorder(tmp_path / "rec") as rec:
        # vehicle: 0 1 2 | 5 (3 and 4 lost) | 5 again (duplicate) | 4 late (one loss undone)
        for seq in (0, 1, 2, 5, 5, 4, 6):
            rec.record(vehicle(heartbeat(False), seq=seq), T0)
        # camera component of the same system, wrapping around 255 -> 0 with no loss
        for seq in (254, 255, 0, 1):
            rec.record(camera(system_time(1.0), seq=seq), T0)
        # another system: 10 then 20 (9 lost)
        for seq in (10, 20):
            rec.record(other(heartbeat(False), seq=seq), T0)
        state = rec.state()
    by_system = {q.system_id: q for q in state.link}
    one = by_system[1]
    assert (one.received, one.lost, one.duplicates, one.late) == (6 + 4, 1, 1, 1)
    assert one.quality_pct == pytest.approx(100 * 10 / 11)
    two = by_system[2]
    assert (two.received, two.lost) == (2, 9)
    assert state.link_quality_pct == pytest.approx(100 * 12 / 22)
    rec2 = FlightRecorder(tmp_path / "rec2")
    wire = Wire()
    for seq in (0, 1):
        rec2.record(wire(heartbeat(False), seq=seq), T0)
    rec2.note_drop("cut")
    rec2.note_reconnect()
    for seq in (200, 201):  # what was sent while the link was down is not counted as lost
        rec2.record(wire(heartbeat(False), seq=seq), T0)
    state2 = rec2.close()
    assert state2.link_quality_pct == 100.0 and state2.drops == 1 and state2.reconnects == 1


# --- recorder: missed stations ------------------------------------------------------------------


def fly(rec: FlightRecorder, wire: Wire, legs: list[tuple[float, float, int]], skip: set[int],
        spacing: float = 10.0, until: int | None = None) -> None:  # fmt: skip
    """Fly the legs of :func:`line_plan` at 5 m/s, positions every 0.5 m, a photo at every
    station except those in ``skip``; stop when station ``until`` is reached."""
    t = 0.0
    station = 0
    for north, head, count in legs:
        v_east = 5.0 if head == 90.0 else -5.0
        length = (count - 1) * spacing
        steps = round((length + 2 * spacing) / 0.5)
        for k in range(steps + 1):
            s = -spacing + 0.5 * k  # along the leg, from a lead-in
            east = s if head == 90.0 else length - s
            t += 0.1
            rec.record(wire(position(t, east, north, v_east, 0.0)), T0 + t)
            i = s / spacing
            if abs(i - round(i)) < 1e-9 and 0 <= round(i) < count:
                if until is not None and station == until:
                    return
                if station not in skip:
                    rec.record(wire(feedback(t, station + 1, east + 0.7, north - 0.4)), T0 + t)
                station += 1


def test_missed_stations_are_those_passed_without_a_photo(tmp_path: Path) -> None:
    legs = [(0.0, 90.0, 6), (30.0, 270.0, 6)]
    plan = line_plan(legs)
    wire = Wire()
    rec = FlightRecorder(tmp_path / "rec", plan)
    rec.record(wire(system_time(0.0)), T0)
    rec.record(wire(heartbeat(True)), T0)
    # fly up to the moment station 3 is reached: station 2 was skipped and is behind
    fly(rec, wire, legs, skip={2, 8}, until=3)
    state = rec.state()
    assert state.missed_stations == (2,)
    assert state.stations_passed == 3 and state.photos_taken == 2
    rec.close()
    rec = FlightRecorder(tmp_path / "rec2", plan)
    rec.record(wire(system_time(0.0)), T0)
    rec.record(wire(heartbeat(True)), T0)
    fly(rec, wire, legs, skip={2, 8, 11})
    state = rec.state()
    # 11 is the last station: nothing later was reached, so it is not yet known as missed
    assert state.missed_stations == (2, 8)
    # the image index says 11 photos were taken; the events of two never came (2 and 8)
    assert state.photos_taken == 11 and state.events_received == 9 and state.photos_unseen == 2
    assert state.stations_taken == 9 and state.extra_photos == 0
    rec.record(wire(heartbeat(False)), T0 + 100)  # landed and disarmed: the flight is over
    final = rec.close()
    assert final.flight_over and final.missed_stations == (2, 8, 11)


def test_late_photo_unmisses_and_far_photo_is_extra(tmp_path: Path) -> None:
    legs = [(0.0, 90.0, 5)]
    plan = line_plan(legs)
    wire = Wire()
    with FlightRecorder(tmp_path / "rec", plan) as rec:
        rec.record(wire(system_time(0.0)), T0)
        fly(rec, wire, legs, skip={1}, until=3)
        assert rec.state().missed_stations == (1,)
        # station 1's event (image index 2) arrives late, 3.2 m off
        rec.record(wire(feedback(50.0, 2, 10.0 + 3.0, 1.0)), T0 + 50)
        assert rec.state().missed_stations == ()
        rec.record(wire(feedback(51.0, 4, 500.0, 0.0)), T0 + 51)  # nowhere near a station
        state = rec.state()
    assert state.extra_photos == 1 and state.photos_taken == 4


def test_transit_across_later_lines_does_not_mark_stations_passed(tmp_path: Path) -> None:
    # two legs; the vehicle first crosses leg 1 going north (across its heading), then
    # flies along leg 1's direction over leg 1, which is not the current leg (leg 0 is)
    legs = [(0.0, 90.0, 5), (30.0, 270.0, 5), (60.0, 90.0, 5)]
    plan = line_plan(legs)
    wire = Wire()
    with FlightRecorder(tmp_path / "rec", plan) as rec:
        t = 0.0
        for k in range(200):  # northbound transit over the middle of leg 1 and leg 2
            t += 0.1
            rec.record(wire(position(t, 20.0, -10.0 + 0.5 * k, 0.0, 5.0)), T0 + t)
        for k in range(120):  # eastbound along leg 2 (heading 90 like leg 0): too far ahead
            t += 0.1
            rec.record(wire(position(t, -10.0 + 0.5 * k, 60.0, 5.0, 0.0)), T0 + t)
        assert rec.state().stations_passed == 0
        assert rec.state().missed_stations == ()
        # one photo at a station of leg 2 does not move the progress; a second one does
        rec.record(wire(feedback(t, 1, 0.0, 60.0)), T0 + t)
        assert rec.state().stations_passed == 0
        rec.record(wire(feedback(t + 2, 2, 10.0, 60.0)), T0 + t + 2)
        state = rec.state()
    assert state.stations_passed == 11
    assert state.missed_stations == tuple(range(10))


def test_plan_folder_is_read_with_radius_from_the_trigger_distance(tmp_path: Path) -> None:
    plan = planned_gully(tmp_path)[1]
    stations = load_station_plan(tmp_path / "plan")
    assert len(stations) == len(plan.stations) == plan.summary.photo_count
    d = plan.summary.trigger_distance_m
    assert stations.trigger_distance_m == pytest.approx(d)
    assert np.allclose(stations.match_radius_m, max(d / 2, 5.0))
    assert np.allclose(stations.lat_deg, plan.stations.lat_deg, atol=1e-8)
    assert np.array_equal(stations.line_index, plan.stations.line_index)


# --- flights in the simulator -------------------------------------------------------------------


def planned_gully(tmp_path: Path) -> tuple[Path, SurveyPlan]:
    spec = load_spec(ROOT / "missions" / "bardenas-gully.toml")
    plan = plan_survey(spec)
    write_outputs(plan, tmp_path / "plan")
    return tmp_path / "plan", plan


def planned_small(tmp_path: Path) -> tuple[Path, SurveyPlan]:
    """A 180 m x 160 m field with the gully's camera: 5 lines, 65 photos."""
    corners = [offset(e, n) for e, n in ((20, 20), (200, 20), (200, 180), (20, 180))]
    ring = [[lon, lat] for lat, lon in corners] + [[corners[0][1], corners[0][0]]]
    area = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {}, "geometry": {"type": "Polygon", "coordinates": [ring]}}
    ]}  # fmt: skip
    (tmp_path / "small.geojson").write_text(json.dumps(area))
    (tmp_path / "small.toml").write_text(
        (ROOT / "missions" / "bardenas-gully.toml")
        .read_text()
        .replace('name = "Bardenas gully"', 'name = "small field"')
        .replace('area = "bardenas-gully.geojson"', 'area = "small.geojson"')
        .replace("home = [42.2012, -1.4866]", f"home = [{LAT0}, {LON0}]")
    )
    plan = plan_survey(load_spec(tmp_path / "small.toml"))
    write_outputs(plan, tmp_path / "plan")
    return tmp_path / "plan", plan


def wait_until(condition: Any, timeout_s: float, clock: Clock = WALL_CLOCK) -> bool:
    """Look at ``condition()`` every 0.01 s of ``clock`` until it holds (True) or ``timeout_s``
    of ``clock`` passed; on a virtual clock also at most ``timeout_s`` + 60 wall seconds."""
    deadline = clock.monotonic() + timeout_s
    wall_deadline = time.monotonic() + timeout_s + 60.0
    while not condition():
        if clock.monotonic() >= deadline or time.monotonic() >= wall_deadline:
            return bool(condition())
        clock.sleep(0.01)
    return True


def gcs_start_mission(url: str, clock: Clock = WALL_CLOCK) -> None:
    """Arm and start the mission with COMMAND_LONG, as a ground station does."""
    with Link.open(url, heartbeat_timeout_s=5.0, source_component=191, clock=clock) as link:
        for command, params in ((400, (1.0,)), (300, ())):
            padded = list(params) + [0.0] * (7 - len(params))
            link.send(
                mavlink2.MAVLink_command_long_message(
                    link.target_system, link.target_component, command, 0, *padded
                )
            )
            ack = link.recv({"COMMAND_ACK"}, timeout_s=3.0)
            while ack is not None and ack.command != command:  # a monitor's answers too
                ack = link.recv({"COMMAND_ACK"}, timeout_s=3.0)
            assert ack is not None and ack.command == command and ack.result == 0


@pytest.fixture
def run_monitor() -> Iterator[Any]:
    threads: list[threading.Thread] = []
    stops: list[threading.Event] = []

    def start(
        url: str,
        plan_dir: Path,
        out_dir: Path,
        clock: Any = None,
        vclock: VirtualClock | None = None,
        **kw: Any,
    ) -> dict[str, Any]:
        """Run monitor() in a thread; ``box["states"]`` collects the updates, each with the
        time ``clock()`` (e.g. the simulator's) gave when it came. ``vclock``: the monitor
        runs on that virtual clock (and the test waits on it)."""
        box: dict[str, Any] = {"states": [], "clocked": [], "connected": threading.Event()}
        stop = threading.Event()

        def on_update(state: MonitorState) -> None:
            box["states"].append(state)
            if clock is not None:
                box["clocked"].append((clock(), state))
            if state.messages > 0:
                box["connected"].set()

        def body() -> None:
            try:
                if vclock is not None:
                    kw["clock"] = vclock
                kw.setdefault("update_interval_s", 0.05)
                box["result"] = monitor(url, plan_dir, out_dir, on_update=on_update, stop_event=stop, **kw)
            except BaseException as error:  # handed to the test
                box["error"] = error

        thread = threading.Thread(target=body, daemon=True)
        thread.start()
        threads.append(thread)
        stops.append(stop)
        box["thread"] = thread
        if vclock is None:
            assert box["connected"].wait(15), box.get("error")
        else:
            vclocks.append(vclock)
            assert wait_until(box["connected"].is_set, 15, vclock), box.get("error")
        return box

    vclocks: list[VirtualClock] = []
    yield start
    for stop in stops:
        stop.set()
    for vclock in vclocks:
        vclock.interrupt()
    for thread in threads:
        thread.join(timeout=10)


@pytest.mark.slow  # 20-45 s: the monitor parses about 40,000 messages in pure Python
def test_gully_flight_records_one_event_per_planned_station(tmp_path: Path, run_monitor: Any) -> None:
    plan_dir, plan = planned_gully(tmp_path)
    d = plan.summary.trigger_distance_m
    clock = VirtualClock()
    with SimulatedVehicle(
        speedup=100, home=plan.mission.home, boot_delay_s=0.0, gps_fix_s=0.5, clock=clock
    ) as vehicle:
        url = vehicle.url_for_client
        with Link.open(url, heartbeat_timeout_s=5.0, source_component=191, clock=clock) as link:
            assert vehicle.wait_sim_time(0.6)
            upload_mission(link, plan.mission)
        box = run_monitor(url, plan_dir, tmp_path / "flight", vclock=clock)
        gcs_start_mission(url, clock)
        wait_until(lambda: not box["thread"].is_alive(), 60, clock)
        assert not box["thread"].is_alive() and "error" not in box, box.get("error")
        shots = list(vehicle.flight.shots)
    result: MonitorResult = box["result"]
    assert result.reason is StopReason.LANDED
    n = len(plan.stations)
    assert len(shots) == n == 628  # the gully plan, with the planner's end stations for stereo
    state = result.state
    assert state.photos_taken == n and state.photos_planned == n
    assert state.missed_stations == () and state.extra_photos == 0
    assert state.stations_taken == n and state.flight_over
    assert state.link_quality_pct == 100.0 and state.drops == 0
    flight = read_tlog(result.tlog_path)
    ev = flight.events
    assert ev is not None and len(ev) == n and ev.source == "tlog:CAMERA_FEEDBACK"
    assert ev.lat_deg is not None and ev.lon_deg is not None
    # every event within the trigger distance of its planned station (flight order)
    _, _, dist = GEOD.inv(ev.lon_deg, ev.lat_deg, plan.stations.lon_deg, plan.stations.lat_deg)
    assert np.max(dist) < d
    # the planner commands each run's distance in ArduPilot's metre less half a loop step, so a
    # photo may drift along its run by up to 40 % of the spacing (planner/trigger.py); plus the
    # simulator's GPS noise (0.3 m RMS)
    assert np.max(dist) < 0.4 * d + 1.0
    rows = read_csv(result.csv_path)
    assert len(rows) == n
    assert [int(r["seq"]) for r in rows] == list(ev.seq) == list(range(1, n + 1))
    assert np.allclose([float(r["time_utc_s"]) for r in rows], ev.time_utc_s, atol=1e-6)
    assert np.allclose([float(r["lat_deg"]) for r in rows], ev.lat_deg, atol=1e-9)
    assert np.allclose([float(r["lon_deg"]) for r in rows], ev.lon_deg, atol=1e-9)
    assert ev.alt_rel_home_m is not None
    assert np.allclose([float(r["alt_rel_home_m"]) for r in rows], ev.alt_rel_home_m, atol=1e-3)
    summary = json.loads(result.summary_path.read_text())
    assert summary["photos_taken"] == n and summary["missed_stations"] == []


def test_link_drop_mid_flight_is_survived_and_the_recording_kept(
    tmp_path: Path, run_monitor: Any, caplog: pytest.LogCaptureFixture
) -> None:
    plan_dir, plan = planned_small(tmp_path)
    n = len(plan.stations)
    assert n >= 40
    with SimulatedVehicle(speedup=60, home=plan.mission.home, boot_delay_s=0.0, gps_fix_s=0.0) as vehicle:
        vehicle.load_mission(plan.mission.items)
        with Relay(vehicle.url_for_client) as relay:
            box = run_monitor(
                relay.url,
                plan_dir,
                tmp_path / "flight",
                clock=lambda: vehicle.sim_time_s,
                reconnect_timeout_s=20,
            )
            vehicle.auto_start()
            # cut a third of the way into the photos, for 0.5 s of wall clock (30 s of flight)
            deadline = time.monotonic() + 30
            while len(vehicle.flight.shots) < n // 3 and time.monotonic() < deadline:
                time.sleep(0.005)
            relay.cut()
            before_cut = read_csv(tmp_path / "flight" / "triggers.csv")
            time.sleep(0.5)
            relay.restore()
            box["thread"].join(timeout=60)
            assert not box["thread"].is_alive() and "error" not in box, box.get("error")
        shots = list(vehicle.flight.shots)
    result: MonitorResult = box["result"]
    state = result.state
    assert result.reason is StopReason.LANDED
    assert state.drops == 1 and state.reconnects == 1 and state.connected
    assert any("reconnected" in r.getMessage() for r in caplog.records)
    assert any(not s.connected for s in box["states"])  # the update said the link was lost
    assert len(shots) == n
    flight = read_tlog(result.tlog_path)
    ev = flight.events
    assert ev is not None and ev.lat_deg is not None and ev.lon_deg is not None
    # photos taken while the link was down (or in the pipe when it was cut) never reached
    # the monitor; all others did, and what was recorded before the cut is still there
    recorded = set(int(s) for s in ev.seq)
    lost = [s.index for s in shots if s.index not in recorded]
    assert len(lost) > 0
    assert lost == list(range(lost[0], lost[-1] + 1))  # one run, around the cut
    assert lost[-1] < n  # the photos after the reconnection were recorded
    assert len(before_cut) > 0
    rows = read_csv(result.csv_path)
    assert rows[: len(before_cut)] == before_cut
    assert max(int(r["seq"]) for r in before_cut) < lost[0]
    # none was shot after the monitor was back (the update that says so, in simulated time)
    back_at = min(t for t, st in box["clocked"] if st.reconnects == 1)
    assert max(s.time_s for s in shots if s.index in set(lost)) <= back_at
    assert len(ev) == n - len(lost) == state.events_received
    # the image index still counts every photo: the lost ones are photos unseen, not untaken
    assert state.photos_taken == n and state.photos_unseen == len(lost)
    # ... and the monitor reports exactly their stations as missed (img_idx k is station k-1)
    assert state.missed_stations == tuple(i - 1 for i in lost)
    _, _, dist = GEOD.inv(
        ev.lon_deg, ev.lat_deg,
        plan.stations.lon_deg[ev.seq - 1], plan.stations.lat_deg[ev.seq - 1],
    )  # fmt: skip
    assert np.max(dist) < plan.summary.trigger_distance_m
    assert [int(r["seq"]) for r in rows] == list(ev.seq)


def test_px4_flight_counts_each_photo_once_from_trigger_and_capture(tmp_path: Path, run_monitor: Any) -> None:
    plan_dir, plan = planned_small(tmp_path)
    n = len(plan.stations)
    clock = VirtualClock()
    with SimulatedVehicle(
        autopilot=Autopilot.PX4, speedup=100, home=plan.mission.home, gps_fix_s=0.0, clock=clock
    ) as vehicle:
        vehicle.load_mission(plan.mission.items)
        box = run_monitor(vehicle.url_for_client, plan_dir, tmp_path / "flight", vclock=clock)
        vehicle.auto_start()
        wait_until(lambda: not box["thread"].is_alive(), 60, clock)
        assert not box["thread"].is_alive() and "error" not in box, box.get("error")
        sent = dict(vehicle.sent_counts)
    assert sent["CAMERA_TRIGGER"] == sent["CAMERA_IMAGE_CAPTURED"] == n
    result: MonitorResult = box["result"]
    state = result.state
    assert result.reason is StopReason.LANDED
    assert state.photos_taken == n and state.missed_stations == () and state.extra_photos == 0
    rows = read_csv(result.csv_path)
    assert [int(r["seq"]) for r in rows] == list(range(n))  # PX4 counts from 0
    assert {r["source"] for r in rows} == {"CAMERA_IMAGE_CAPTURED"}
    lat = np.array([float(r["lat_deg"]) for r in rows])
    lon = np.array([float(r["lon_deg"]) for r in rows])
    _, _, dist = GEOD.inv(lon, lat, plan.stations.lon_deg, plan.stations.lat_deg)
    assert np.max(dist) < plan.summary.trigger_distance_m


# --- the whole traffic: other systems, other ground stations, heartbeat waits -------------------


class Sender:
    """Packs messages as one MAVLink sender (system, component) does, numbering them in turn."""

    def __init__(self, system: int, component: int, seq: int = 0) -> None:
        self.mav = mavlink2.MAVLink(None, srcSystem=system, srcComponent=component)
        self.mav.seq = seq

    def __call__(self, msg: Any) -> bytes:
        data = bytes(msg.pack(self.mav))
        self.mav.seq = (self.mav.seq + 1) % 256
        return data

    def skip(self, n: int) -> None:
        """``n`` messages sent while nobody listened."""
        self.mav.seq = (self.mav.seq + n) % 256


class ScriptedVehicle:
    """A TCP peer on the vehicle side: client k gets the packets of ``scripts[k]`` in one burst;
    every client but the last is then disconnected (a drop), the last stays connected."""

    def __init__(self, scripts: list[list[bytes]]) -> None:
        self.scripts = scripts
        self.server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(2)
        self.server.settimeout(0.1)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)

    @property
    def url(self) -> str:
        return f"tcp://127.0.0.1:{self.server.getsockname()[1]}"

    def __enter__(self) -> ScriptedVehicle:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(timeout=5)
        self.server.close()

    def _serve(self) -> None:
        last: socket.socket | None = None
        for k, packets in enumerate(self.scripts):
            peer = None
            while peer is None and not self._stop.is_set():
                with contextlib.suppress(TimeoutError):
                    peer, _ = self.server.accept()
            if peer is None:
                return
            peer.sendall(b"".join(packets))
            if k < len(self.scripts) - 1:
                # read what the monitor sends (its heartbeat, its stream requests) as a vehicle
                # does: closing with unread bytes would reset the connection and could discard
                # what was sent before the reset
                peer.settimeout(0.5)
                with contextlib.suppress(OSError):
                    while peer.recv(4096):
                        pass
                peer.shutdown(socket.SHUT_RDWR)
                peer.close()
            else:
                last = peer
        self._stop.wait(30)
        if last is not None:
            last.close()


def test_tlog_holds_every_system_and_the_heartbeat_waits_and_no_false_loss_is_counted(tmp_path: Path) -> None:
    vehicle, other, gimbal = Sender(1, 1, 40), Sender(2, 1, 250), Sender(2, 154)
    ack_to_other_gcs = mavlink2.MAVLink_command_ack_message(400, 0, 0, 0, 254, 190)
    gimbal_heartbeat = mavlink2.MAVLink_heartbeat_message(26, 0, 0, 0, 4, 3)  # generic autopilot
    first = [
        # read while the link waits for the vehicle's heartbeat
        other(system_time(0.5)),
        gimbal(gimbal_heartbeat),
        vehicle(system_time(1.0)),
        vehicle(heartbeat(True)),
        # the vehicle's answers to another ground station, and a second vehicle
        vehicle(ack_to_other_gcs),
        vehicle(mavlink2.MAVLink_mission_current_message(3)),
        other(mavlink2.MAVLink_mission_current_message(9)),
        other(heartbeat(False)),
        vehicle(ack_to_other_gcs),
        vehicle(system_time(2.0)),
    ]
    vehicle.skip(30)  # sent while the link was down: not losses
    other.skip(7)
    second = [
        # read while the reconnection waits for the vehicle's heartbeat
        vehicle(mavlink2.MAVLink_statustext_message(6, b"early")),
        vehicle(ack_to_other_gcs),
        other(system_time(3.0)),
        vehicle(heartbeat(True)),
        other(heartbeat(False)),
        vehicle(ack_to_other_gcs),
        vehicle(mavlink2.MAVLink_mission_current_message(4)),
        other(mavlink2.MAVLink_mission_current_message(10)),
        vehicle(system_time(4.0)),
    ]
    total = len(first) + len(second)
    states: list[MonitorState] = []
    done = threading.Event()
    stop = threading.Event()
    box: dict[str, Any] = {}

    def on_update(state: MonitorState) -> None:
        states.append(state)
        if state.reconnects == 1 and state.messages == total:
            done.set()

    def body() -> None:
        try:
            box["result"] = monitor(
                peer.url, None, tmp_path / "flight", on_update=on_update, stop_event=stop,
                update_interval_s=0.02, reconnect_timeout_s=10.0, heartbeat_timeout_s=5.0,
            )  # fmt: skip
        except BaseException as error:  # handed to the test
            box["error"] = error

    started = time.time()
    with ScriptedVehicle([first, second]) as peer:
        thread = threading.Thread(target=body, daemon=True)
        thread.start()
        reached = done.wait(15)
        stop.set()
        thread.join(timeout=10)
    ended = time.time()
    assert "error" not in box, box.get("error")
    assert reached, states[-1] if states else "no update"
    result: MonitorResult = box["result"]
    state = result.state
    # the tlog: every packet of both connections, byte for byte, in order, each stamped
    data = result.tlog_path.read_bytes()
    at = 0
    stamps = []
    for packet in first + second:
        stamps.append(struct.unpack(">Q", data[at : at + 8])[0] / 1e6)
        assert data[at + 8 : at + 8 + len(packet)] == packet
        at += 8 + len(packet)
    assert at == len(data)
    assert all(started <= t <= ended for t in stamps) and stamps == sorted(stamps)
    assert state.messages == total and state.drops == 1 and state.reconnects == 1
    # sequence counts of the second connection: from its first message, every system, no loss
    by_system = {q.system_id: q for q in state.link}
    assert (by_system[1].received, by_system[1].lost) == (sum(p[5] == 1 for p in second), 0)
    assert (by_system[2].received, by_system[2].lost) == (sum(p[5] == 2 for p in second), 0)
    assert state.link_quality_pct == 100.0
    # the recorder follows the vehicle the link identified, not the other system
    assert state.mission_seq == 4 and state.armed and state.heartbeat_age_s is not None
    # the tlog reader sees the vehicle and names the other sources
    flight = read_tlog(result.tlog_path)
    assert any("2/1" in w and "2/154" in w for w in flight.warnings)


# --- loss counting: the 8-bit sequence rule, and a fast sender ---------------------------------


def test_a_burst_of_200_lost_is_200_lost_not_one_late(tmp_path: Path) -> None:
    # the old rule read every jump of 128 or more as a late arrival: 200 lost counted as -1
    wire = Wire()
    with FlightRecorder(tmp_path / "rec") as rec:
        for seq in [*range(0, 50), *range(250, 256), *range(0, 10)]:  # 50..249 lost: 200
            rec.record(wire(heartbeat(False), seq=seq), T0)
        one = rec.state().link[0]
    assert (one.received, one.lost, one.late, one.duplicates) == (66, 200, 0, 0)


@settings(max_examples=80, deadline=None)
@given(
    st.lists(st.tuples(st.integers(2, 40), st.integers(0, 230)), min_size=1, max_size=12),
    st.lists(st.integers(min_value=0, max_value=5000), max_size=8),
    st.integers(min_value=0, max_value=255),
)
def test_loss_is_counted_exactly_for_any_bursts_and_swaps(
    runs: list[tuple[int, int]], swaps: list[int], start: int
) -> None:
    # Truth by construction: a sender numbers its messages 0, 1, 2... (sent mod 256); runs
    # are delivered, bursts of up to 250 (8 bits tell 254 at most; a swap after a burst adds
    # one to the jump) are not, and a few pairs
    # of consecutive messages arrive swapped. The counter must find every burst message lost,
    # each swap as one late arrival, and every delivered message received.
    delivered: list[int] = []
    n = 0
    for run_length, burst in runs:
        delivered.extend(range(n, n + run_length))
        n += run_length + burst
    lost_truth = delivered[-1] + 1 - len(delivered)  # a burst after the last run is not seen
    late_truth = 0
    last_swap = -10
    for where in sorted(set(swaps)):
        k = where % len(delivered)
        # (from the second message: one older than the first received cannot be told late)
        if k >= 1 and k - last_swap >= 3 and k + 1 < len(delivered) and delivered[k + 1] == delivered[k] + 1:
            delivered[k], delivered[k + 1] = delivered[k + 1], delivered[k]
            late_truth += 1
            last_swap = k
    counter = SeqCounter()
    for number in delivered:
        counter.add((number + start) % 256)
    assert counter.received == len(delivered)
    assert counter.late == late_truth
    assert counter.lost == lost_truth
    assert counter.duplicates == 0


def test_monitor_keeps_up_with_a_fast_relay_and_counts_loss_exactly(tmp_path: Path) -> None:
    """A ground station relaying over UDP at about 1,500 messages/s for 4 s, with bursts of 1,
    31, 108 and 200 messages never sent: the monitor reads in its own thread, so the
    kernel drops nothing, and every message it did not get is counted lost, no more."""
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    port = receiver.getsockname()[1]
    receiver.close()
    encoder = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    packets: list[bytes] = []
    index = 0
    for k in range(6000):
        if k % 100 == 0:
            msg: Any = heartbeat(False)
        elif k % 40 == 0:
            index += 1
            msg = feedback(k / 1500, index, 0.0, 0.0)
        else:
            msg = mavlink2.MAVLink_attitude_message(k, 0.01, -0.02, 1.5, 0.0, 0.0, 0.0)
        packets.append(bytes(msg.pack(encoder)))
        encoder.seq = (encoder.seq + 1) % 256  # pack() numbers the message; send() would count
    omitted: set[int] = set()
    for start, length in ((1000, 1), (2000, 31), (3000, 108), (4000, 200)):
        omitted.update(range(start, start + length))
    events_omitted = sum(1 for k in omitted if k % 40 == 0 and k % 100 != 0)
    stop = threading.Event()
    box: dict[str, Any] = {}

    def run() -> None:
        try:
            box["result"] = monitor(f"udpin://127.0.0.1:{port}", None, tmp_path / "fast", stop_event=stop)
        except BaseException as error:  # handed to the test
            box["error"] = error

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    # heartbeats until the monitor has opened its port and heard the vehicle
    # (numbered 255, just before the stream's 0: repeated, they are duplicates, not losses)
    encoder.seq = 255
    deadline = time.monotonic() + 10
    while not (tmp_path / "fast" / "flight.tlog").exists() and time.monotonic() < deadline:
        sender.sendto(bytes(heartbeat(False).pack(encoder)), ("127.0.0.1", port))
        time.sleep(0.05)
    assert (tmp_path / "fast" / "flight.tlog").exists(), box.get("error")
    time.sleep(0.3)
    encoder_first = len(packets)
    started = time.monotonic()
    chunk = 15  # every 10 ms: 1,500 messages/s
    for k in range(0, len(packets), chunk):
        for j in range(k, min(k + chunk, len(packets))):
            if j not in omitted:
                sender.sendto(packets[j], ("127.0.0.1", port))
        time.sleep(max(0.0, started + (k + chunk) / 1500 - time.monotonic()))
    elapsed = time.monotonic() - started
    time.sleep(1.0)
    stop.set()
    thread.join(timeout=15)
    sender.close()
    assert "error" not in box, box.get("error")
    assert encoder_first / elapsed > 1000, f"the sender managed only {encoder_first / elapsed:.0f} msg/s"
    state = box["result"].state
    vehicle = next(q for q in state.link if q.system_id == 1)
    # the packed stream: the heartbeats before it were packed by the same encoder, so its
    # sequence numbers run on from them; every number not delivered is lost, exactly
    assert vehicle.lost == len(omitted), (vehicle, len(omitted))
    assert vehicle.late == 0 and vehicle.received == len(packets) - len(omitted) + 1
    assert state.events_received == index - events_omitted
    assert state.photos_taken == index and state.photos_unseen == events_omitted
    assert state.link_quality_pct is not None and state.link_quality_pct < 100 * (1 - 300 / 6300)


# --- what the monitor asks of the vehicle, late joins, a new mission ----------------------------


def short_line(east_m: float = 60.0, north_m: float = 0.0, trigger_m: float = 10.0) -> list[Any]:
    """Take off to 20 m, fly to a line's start, photos every ``trigger_m`` along ``east_m``, RTL:
    the simulator fires at the start and every ``trigger_m``: east_m // trigger_m + 1 photos."""
    from planner.mission import MissionItem

    a = offset(10.0, north_m)
    b = offset(10.0 + east_m + trigger_m / 2, north_m)  # the last photo half a step before
    return [
        MissionItem.takeoff(LAT0, LON0, 20.0),
        MissionItem.waypoint(a[0], a[1], 20.0),
        MissionItem.cam_trigger_distance(trigger_m),
        MissionItem.waypoint(b[0], b[1], 20.0),
        MissionItem.cam_trigger_distance(0.0, trigger_now=False),
        MissionItem.return_to_launch(),
    ]


def test_monitor_asks_ardupilot_for_its_streams_and_stops_after_landing(
    tmp_path: Path, run_monitor: Any
) -> None:
    from acquisition.telemetry.tlog import read_tlog as read
    from planner.mission import HomePosition

    home = HomePosition(lat_deg=LAT0, lon_deg=LON0)
    clock = VirtualClock()
    with SimulatedVehicle(speedup=60, home=home, boot_delay_s=0.0, gps_fix_s=0.2, clock=clock) as vehicle:
        assert vehicle.streams_on_request  # ArduPilot's flavour: nothing periodic until asked
        vehicle.load_mission(short_line())
        url = vehicle.url_for_client
        box = run_monitor(url, None, tmp_path / "flight", vclock=clock)
        gcs_start_mission(url, clock)
        wait_until(lambda: not box["thread"].is_alive(), 60, clock)
        assert not box["thread"].is_alive() and "error" not in box, box.get("error")
        shots = list(vehicle.flight.shots)
        rates = vehicle.flight.stream_rates_hz()
        asked = vehicle.received_counts.get("COMMAND_LONG", 0)
    result: MonitorResult = box["result"]
    assert result.reason is StopReason.LANDED  # landed and disarmed: it stopped by itself
    assert rates["GLOBAL_POSITION_INT"] == pytest.approx(10.0) and rates["SYSTEM_TIME"] == pytest.approx(1.0)
    assert rates["ATTITUDE"] == pytest.approx(10.0) and rates["MISSION_CURRENT"] == pytest.approx(1.0)
    assert asked >= 5
    state = result.state
    assert state.missing_streams == () and state.landed_state == 1
    flight = read(result.tlog_path)
    assert flight.positions is not None and len(flight.positions) > 50  # positions recorded
    assert flight.attitudes is not None and len(flight.attitudes) > 50
    assert len(shots) == 7 and state.photos_taken == 7
    # no plan folder: the stations are the vehicle's own mission, read back and replayed
    assert state.stations_from == "vehicle" and state.photos_planned == 7
    assert state.missed_stations == () and state.extra_photos == 0


class _Mute(SimulatedVehicle):
    """A vehicle whose firmware honours no stream request (neither way)."""

    def _on_request_data_stream(self, msg: Any) -> None:
        return

    def _run_command(self, command: int, params: Any) -> int:
        if command == 511:
            return int(mavlink2.MAV_RESULT_UNSUPPORTED)
        return super()._run_command(command, params)


def test_streams_that_never_come_are_named(
    tmp_path: Path, run_monitor: Any, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    import acquisition.monitor_link as monitor_link

    monkeypatch.setattr(monitor_link, "STREAM_CHECK_S", 0.8)
    with _Mute(speedup=10, boot_delay_s=0.0, gps_fix_s=0.2) as vehicle:
        box = run_monitor(vehicle.url_for_client, None, tmp_path / "flight")
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline and not (box["states"] and box["states"][-1].missing_streams):
            time.sleep(0.1)
        legacy = vehicle.received_counts.get("REQUEST_DATA_STREAM", 0)
    states = box["states"]
    assert states and set(states[-1].missing_streams) == {
        "GLOBAL_POSITION_INT",
        "ATTITUDE",
        "SYSTEM_TIME",
        "MISSION_CURRENT",
    }
    assert legacy >= 4  # the fallback was tried: REQUEST_DATA_STREAM for each group
    warning = next(r.getMessage() for r in caplog.records if "does not send" in r.getMessage())
    assert "GLOBAL_POSITION_INT" in warning and "SRn_POSITION" in warning


def test_a_monitor_started_mid_flight_says_so_and_misses_nothing(tmp_path: Path, run_monitor: Any) -> None:
    from planner.mission import HomePosition

    home = HomePosition(lat_deg=LAT0, lon_deg=LON0)
    clock = VirtualClock()
    with SimulatedVehicle(
        speedup=15, home=home, boot_delay_s=0.0, gps_fix_s=0.2, streams_on_request=False, clock=clock
    ) as vehicle:
        vehicle.load_mission(short_line(east_m=100.0))
        assert vehicle.wait_sim_time(0.3)  # a GPS fix, or no arming
        gcs_start_mission(vehicle.url_for_client, clock)
        wait_until(lambda: len(vehicle.flight.shots) >= 3, 30, clock)
        box = run_monitor(vehicle.url_for_client, None, tmp_path / "flight", vclock=clock)
        wait_until(lambda: not box["thread"].is_alive(), 60, clock)
        assert not box["thread"].is_alive() and "error" not in box, box.get("error")
        shots = list(vehicle.flight.shots)
    state: MonitorState = box["result"].state
    seen = sorted(int(s) for s in read_tlog(box["result"].tlog_path).events.seq)
    assert len(shots) == 11
    assert state.joined_late and state.photos_before_join == seen[0] - 1 >= 3
    assert state.photos_taken == 11 and state.events_received == len(seen) == 11 - state.photos_before_join
    # the stations before the join are not counted as missed
    assert state.missed_stations == () and state.photos_planned == 11


def test_a_new_mission_uploaded_in_the_field_is_followed(tmp_path: Path, run_monitor: Any) -> None:
    from planner.mission import HomePosition, Mission

    home = HomePosition(lat_deg=LAT0, lon_deg=LON0)
    first, refly = short_line(east_m=40.0), short_line(east_m=80.0, north_m=30.0)
    refly.insert(1, refly[1])  # another item count: MISSION_CURRENT's total changes
    clock = VirtualClock()
    with SimulatedVehicle(speedup=30, home=home, boot_delay_s=0.0, gps_fix_s=0.2, clock=clock) as vehicle:
        vehicle.load_mission(first)
        url = vehicle.url_for_client
        box = run_monitor(url, None, tmp_path / "flight", stop_when_landed=False, vclock=clock)
        wait_until(lambda: bool(box["states"]) and box["states"][-1].photos_planned == 5, 15, clock)
        assert box["states"][-1].photos_planned == 5  # the first mission: 40 m / 10 m + 1
        with Link.open(url, heartbeat_timeout_s=5.0, source_component=191, clock=clock) as link:
            upload_mission(link, Mission(items=tuple(refly), home=home, autopilot=Autopilot.ARDUPILOT))
        gcs_start_mission(url, clock)
        assert vehicle.wait_landed(60)
        clock.sleep(1.5)
        shots = len(vehicle.flight.shots)
        states = box["states"]
    assert shots == 9
    last = states[-1]
    assert last.mission_changes >= 1 and last.stations_from == "vehicle"
    assert last.photos_planned == 9 and last.stations_taken == 9 and last.missed_stations == ()


# --- the monitor's timers on simulated time -------------------------------------------------------


def test_an_item_put_in_a_clock_queue_wakes_its_taker_at_that_simulated_instant() -> None:
    clock = VirtualClock()
    inbox = ClockQueue(clock)
    start = clock.monotonic()
    party = clock.join()

    def putter() -> None:
        try:
            clock.sleep(3.0)
            inbox.put("photo")
            clock.sleep(1.0)  # time may move on only once the item is taken
        finally:
            clock.leave(token)

    thread = threading.Thread(target=putter, daemon=True)
    token = clock.join(thread)
    thread.start()
    try:
        assert inbox.get(10.0) == "photo"
        assert clock.monotonic() - start == pytest.approx(3.0, abs=1e-9)
        assert inbox.get(0.5) is None  # nothing else: the wait runs out at its simulated second
        assert clock.monotonic() - start == pytest.approx(3.5, abs=1e-9)
    finally:
        clock.leave(party)
        thread.join(timeout=5)
        inbox.close()


def test_the_monitor_lingers_its_simulated_seconds_after_the_landing(
    tmp_path: Path, run_monitor: Any
) -> None:
    from planner.mission import HomePosition

    linger_s = 2.5
    clock = VirtualClock()
    home = HomePosition(lat_deg=LAT0, lon_deg=LON0)
    with SimulatedVehicle(speedup=60, home=home, boot_delay_s=0.0, gps_fix_s=0.2, clock=clock) as vehicle:
        vehicle.load_mission(short_line())
        url = vehicle.url_for_client
        box = run_monitor(
            url, None, tmp_path / "flight", vclock=clock, clock=clock.monotonic, linger_s=linger_s,
            update_interval_s=0.0,  # an update at every turn of the loop, at the clock's reading then
        )  # fmt: skip
        gcs_start_mission(url, clock)
        wait_until(lambda: not box["thread"].is_alive(), 60, clock)
        assert not box["thread"].is_alive() and "error" not in box, box.get("error")
    assert box["result"].reason is StopReason.LANDED
    clocked = box["clocked"]
    landed_seen_s = min(t for t, st in clocked if st.flight_over)  # the turn that saw the landing
    ended_s = clocked[-1][0]  # the last update, as the recording closed
    # it ends at the first turn of the loop after linger_s: the loop turns at least every 0.1 s
    assert linger_s <= ended_s - landed_seen_s <= linger_s + 0.1 + 1e-6


def test_the_reconnection_gives_up_after_its_simulated_timeout(tmp_path: Path, run_monitor: Any) -> None:
    from planner.mission import HomePosition

    timeout_s = 7.3
    clock = VirtualClock()
    home = HomePosition(lat_deg=LAT0, lon_deg=LON0)
    with SimulatedVehicle(speedup=10, home=home, boot_delay_s=0.0, gps_fix_s=0.2, clock=clock) as vehicle:
        box = run_monitor(
            vehicle.url_for_client, None, tmp_path / "flight", vclock=clock, clock=clock.monotonic,
            reconnect_timeout_s=timeout_s,
        )  # fmt: skip
        assert vehicle.wait_sim_time(1.0)
    # the vehicle is gone (its port refuses): the monitor tries again until its timeout; then
    # nobody waits on the clock any more, so it stands at the second the monitor gave up
    box["thread"].join(timeout=60)
    assert not box["thread"].is_alive()
    gave_up_s = clock.monotonic()
    error = box.get("error")
    assert isinstance(error, LinkError) and f"within {timeout_s:g} s" in str(error)
    dropped_s = min(t for t, st in box["clocked"] if not st.connected)
    # each attempt waits at least 0.5 s (a refused port is tried every 0.2 s, then 0.5 s pause),
    # so the last one may end up to 0.5 s past the timeout, never before it
    assert timeout_s <= gave_up_s - dropped_s <= timeout_s + 0.5 + 1e-6
    assert (tmp_path / "flight" / "flight.tlog").stat().st_size > 0  # the recording is kept
