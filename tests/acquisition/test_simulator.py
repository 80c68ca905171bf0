"""The simulated vehicle: mission protocol as ArduPilot and PX4 speak it, faults, commands, flight.

The ground station here is the test's own, written from the MAVLink mission protocol spec with
pymavlink's mavutil (not sfap's uploader), so the simulator is checked against the protocol and
not against the code it will serve. Oracles: pymavlink's parser on every byte the vehicle sends,
the protocol's message sequence (which request message, which ACK), ArduPilot's storage rules
(REFERENCES.md section 3) written out item by item, binomial bounds for the fault rates, and the
geometry of a survey built in the simulator's own metric frame.
"""

from __future__ import annotations

import contextlib
import itertools
import math
import socket
import struct
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from acquisition.clock import WALL_CLOCK, Clock, VirtualClock
from acquisition.errors import LinkError
from acquisition.mavlink_items import from_mission_item, to_mission_item_int
from acquisition.simulator.faults import FaultConfig, FaultyPipe
from acquisition.simulator.flight import FlightConfig, FlightSimulator
from acquisition.simulator.server import SimulatedVehicle
from acquisition.simulator.storage import WireItem, ardupilot_store, wire_item_from_message
from acquisition.simulator.transport import parse_listen_url
from planner.errors import InputError
from planner.geo import geodesic_distance_m
from planner.mission import Autopilot, HomePosition, MavFrame, MissionItem, VehicleType

HOME = HomePosition(lat_deg=41.6488, lon_deg=-0.8891, alt_amsl_m=210.0)

# MAV_MISSION_RESULT, from pymavlink's definitions (common.xml)
_ML = mavlink2
ACCEPTED, NO_SPACE, INVALID = (
    _ML.MAV_MISSION_ACCEPTED,
    _ML.MAV_MISSION_NO_SPACE,
    _ML.MAV_MISSION_INVALID,
)
INVALID_PARAM3, INVALID_SEQUENCE = _ML.MAV_MISSION_INVALID_PARAM3, _ML.MAV_MISSION_INVALID_SEQUENCE
DENIED, CANCELLED = _ML.MAV_MISSION_DENIED, _ML.MAV_MISSION_OPERATION_CANCELLED


class GroundStation:
    """A minimal ground station: the mission protocol with spec-style timeouts and retries,
    on a plain pymavlink connection; it waits on ``clock`` (the vehicle's)."""

    def __init__(self, url: str, timeout_s: float = 0.4, clock: Clock = WALL_CLOCK) -> None:
        self.clock = clock
        scheme, rest = url.split("://", 1)
        self.conn: Any = mavutil.mavlink_connection(
            f"{scheme}:{rest}", source_system=255, source_component=190, autoreconnect=False
        )
        self.timeout_s = timeout_s
        if scheme == "udpout":
            self.conn.mav.heartbeat_send(6, 8, 0, 0, 0)  # a UDP vehicle learns us from this
        self.texts: list[str] = []
        self.heartbeat = self.recv(["HEARTBEAT"], timeout_s=5)
        assert self.heartbeat is not None, "no heartbeat from the simulated vehicle"

    def close(self) -> None:
        self.conn.close()

    def recv(self, types: list[str] | None, timeout_s: float | None = None) -> Any:
        """The next message of one of ``types`` (any: None); STATUSTEXTs met on the way are kept."""
        deadline = self.clock.monotonic() + (self.timeout_s if timeout_s is None else timeout_s)
        while True:
            msg = self.conn.recv_match(type=None if types is None else [*types, "STATUSTEXT"], blocking=False)
            if msg is not None:
                if types is None or msg.get_type() in types:
                    return msg
                self.texts.append(msg.text)
                continue
            left = deadline - self.clock.monotonic()
            if left <= 0:
                return None
            self.clock.wait_readable([self.conn.fd], left)

    def drain(self) -> None:
        while self.conn.recv_match(blocking=False) is not None:
            pass

    def upload(
        self, items: list[MissionItem], mission_type: int = 0, retries: int = 40
    ) -> tuple[int | None, list[str]]:
        """Send ``items`` (ArduPilot: home first); returns (final ACK type, request types seen)."""
        self.drain()
        requests: list[str] = []
        self.conn.mav.mission_count_send(1, 1, len(items), mission_type)
        last_sent: int | None = None
        while retries > 0:
            msg = self.recv(["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"])
            if msg is None:
                retries -= 1
                if last_sent is None:
                    self.conn.mav.mission_count_send(1, 1, len(items), mission_type)
                else:  # the spec: resend the last item when the next request does not come
                    self._send_item(items, last_sent, mission_type)
                continue
            if getattr(msg, "mission_type", 0) != mission_type:
                continue
            if msg.get_type() == "MISSION_ACK":
                if msg.type == INVALID_SEQUENCE:
                    continue  # ArduPilot's notice about a duplicate item; the upload goes on
                return msg.type, requests
            requests.append(msg.get_type())
            if msg.seq < len(items):
                self._send_item(items, msg.seq, mission_type)
                last_sent = msg.seq
        return None, requests

    def _send_item(self, items: list[MissionItem], seq: int, mission_type: int) -> None:
        self.conn.mav.send(to_mission_item_int(items[seq], seq, 1, 1, mission_type))

    def download(self, mission_type: int = 0, use_int: bool = True, retries: int = 40) -> list[Any]:
        """The vehicle's items as messages (MISSION_ITEM_INT, or MISSION_ITEM when legacy)."""
        self.drain()
        count = None
        while count is None and retries > 0:
            self.conn.mav.mission_request_list_send(1, 1, mission_type)
            msg = self.recv(["MISSION_COUNT"])
            if msg is not None and msg.mission_type == mission_type:
                count = msg.count
            retries -= 1
        assert count is not None, "no MISSION_COUNT"
        wanted = "MISSION_ITEM_INT" if use_int else "MISSION_ITEM"
        out = []
        for seq in range(count):
            got = None
            while got is None and retries > 0:
                if use_int:
                    self.conn.mav.mission_request_int_send(1, 1, seq, mission_type)
                else:
                    self.conn.mav.mission_request_send(1, 1, seq, mission_type)
                deadline = self.clock.monotonic() + self.timeout_s
                while self.clock.monotonic() < deadline:
                    msg = self.recv([wanted], timeout_s=deadline - self.clock.monotonic())
                    if msg is not None and msg.seq == seq and msg.mission_type == mission_type:
                        got = msg
                        break
                retries -= 1 if got is None else 0
            assert got is not None, f"item {seq} never came"
            out.append(got)
        self.conn.mav.mission_ack_send(1, 1, ACCEPTED, mission_type)
        return out

    def clear(self, mission_type: int = 0) -> int | None:
        self.drain()
        for _ in range(20):
            self.conn.mav.mission_clear_all_send(1, 1, mission_type)
            msg = self.recv(["MISSION_ACK"])
            if msg is not None and msg.mission_type == mission_type:
                return int(msg.type)
        return None

    def command(self, command: int, *params: float) -> int | None:
        p = [*params, *([0.0] * (7 - len(params)))]
        for _ in range(10):
            self.conn.mav.command_long_send(1, 1, command, 0, *p)
            deadline = self.clock.monotonic() + 1.0
            while self.clock.monotonic() < deadline:
                msg = self.recv(["COMMAND_ACK"], timeout_s=deadline - self.clock.monotonic())
                if msg is not None and msg.command == command:
                    return int(msg.result)
        return None


def survey_items(home_first: bool, n: int = 5, shift_deg: float = 0.0) -> list[MissionItem]:
    """Take-off, speed, ``n`` waypoints with odd values that storage rules touch, RTL."""
    items = [MissionItem.waypoint(HOME.lat_deg, HOME.lon_deg, 0.0)] if home_first else []
    items.append(MissionItem.takeoff(HOME.lat_deg, HOME.lon_deg, 40.0))
    items.append(MissionItem.change_speed(6.5))
    for k in range(n):
        items.append(
            MissionItem(
                command=16,
                frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
                param1=2.7,  # hold s: ArduCopter keeps 2
                param2=3.0,  # acceptance radius: ArduCopter drops it
                param3=0.0,
                param4=45.0,  # yaw: ArduCopter drops it
                param5=HOME.lat_deg + 0.0003 * (k + 1) + shift_deg,
                param6=HOME.lon_deg + 0.0001234567 * k,
                param7=40.126,  # ArduPilot keeps whole centimetres
            )
        )
    items.append(MissionItem.cam_trigger_distance(25.0))
    items.append(MissionItem.return_to_launch())
    return items


@pytest.fixture
def ardupilot() -> Iterator[SimulatedVehicle]:
    with SimulatedVehicle(boot_delay_s=0.0, gps_fix_s=0.0, home=HOME, clock=VirtualClock()) as vehicle:
        yield vehicle


@pytest.fixture
def px4() -> Iterator[SimulatedVehicle]:
    with SimulatedVehicle(autopilot=Autopilot.PX4, gps_fix_s=0.0, home=HOME, clock=VirtualClock()) as vehicle:
        yield vehicle


def connect(vehicle: SimulatedVehicle, timeout_s: float = 0.4) -> GroundStation:
    """A ground station on the vehicle's clock."""
    return GroundStation(vehicle.url_for_client, timeout_s=timeout_s, clock=vehicle.clock)


# --- identity ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("autopilot", "vehicle_type", "mav_autopilot", "mav_type"),
    [
        (Autopilot.ARDUPILOT, VehicleType.MULTIROTOR, 3, 2),
        (Autopilot.PX4, VehicleType.FIXED_WING, 12, 1),
    ],
)
def test_heartbeat_names_the_autopilot_and_says_it_is_a_simulator(
    autopilot: Autopilot, vehicle_type: VehicleType, mav_autopilot: int, mav_type: int
) -> None:
    with SimulatedVehicle(
        autopilot=autopilot, vehicle_type=vehicle_type, speedup=4, clock=VirtualClock()
    ) as vehicle:
        assert vehicle.url_for_client.startswith("tcp://127.0.0.1:")
        assert not vehicle.url_for_client.endswith(":0")
        gcs = connect(vehicle)
        assert gcs.heartbeat.autopilot == mav_autopilot
        assert gcs.heartbeat.type == mav_type
        gcs.recv(["NONE"], timeout_s=0.5)
        assert any("sfap simulated vehicle" in text for text in gcs.texts)
        if autopilot is Autopilot.ARDUPILOT:
            beats = 0
            start = vehicle.clock.monotonic()
            while vehicle.clock.monotonic() - start < 1.0:
                if gcs.recv(["HEARTBEAT"], timeout_s=0.1) is not None:
                    beats += 1
            assert 3 <= beats <= 5  # 1 Hz of simulated time at speedup 4
        gcs.close()


def test_udp_vehicle_answers_the_peer_that_spoke_first() -> None:
    with SimulatedVehicle(url="udpin://127.0.0.1:0", boot_delay_s=0, gps_fix_s=0) as vehicle:
        assert vehicle.url_for_client.startswith("udpout://127.0.0.1:")
        gcs = connect(vehicle)
        assert len(gcs.download()) == 1  # ArduPilot: home only
        gcs.close()


def test_udpout_vehicle_sends_to_a_listening_ground_station() -> None:
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    with SimulatedVehicle(url=f"udpout://127.0.0.1:{port}", autopilot=Autopilot.PX4) as vehicle:
        assert vehicle.url_for_client == f"udpin://127.0.0.1:{port}"
        gcs = connect(vehicle)
        assert gcs.heartbeat.autopilot == 12
        assert gcs.download() == []
        gcs.close()


def test_bad_urls_and_busy_ports_are_link_errors() -> None:
    for url in ("serial:///dev/ttyUSB0", "tcpin://127.0.0.1", "http://x:1", "udpout://h:0"):
        with pytest.raises(LinkError):
            parse_listen_url(url)
    assert parse_listen_url("tcpin:127.0.0.1:5760").port == 5760
    blocker = socket.socket()
    blocker.bind(("127.0.0.1", 0))
    blocker.listen(1)
    port = blocker.getsockname()[1]
    try:
        with (
            pytest.raises(LinkError, match="free port"),
            SimulatedVehicle(f"tcpin://127.0.0.1:{port}"),
        ):
            pass
    finally:
        blocker.close()


# --- ArduPilot's mission protocol --------------------------------------------------------------


def test_ardupilot_upload_legacy_requests_home_and_storage_rules(
    ardupilot: SimulatedVehicle,
) -> None:
    gcs = connect(ardupilot)
    items = survey_items(home_first=True)
    ack, requests = gcs.upload(items)
    assert ack == ACCEPTED
    assert set(requests) == {"MISSION_REQUEST"}  # id 40, never MISSION_REQUEST_INT
    assert len(requests) == len(items)
    back = [from_mission_item(m) for m in gcs.download()]
    assert back == ardupilot.stored_mission()
    assert len(back) == len(items)
    home = back[0]  # the vehicle's own home, not the uploaded item 0
    assert home.frame == MavFrame.GLOBAL
    assert (home.lat_deg, home.lon_deg) == (HOME.lat_deg, HOME.lon_deg)
    assert home.alt_m == pytest.approx(HOME.alt_amsl_m, abs=0.005)
    wp = back[3]
    assert wp.frame == MavFrame.GLOBAL_RELATIVE_ALT  # sent as GLOBAL_RELATIVE_ALT_INT
    assert (wp.param1, wp.param2, wp.param3, wp.param4) == (2.0, 0.0, 0.0, 0.0)
    assert wp.param7 == pytest.approx(40.12, abs=1e-5)  # centimetres kept, not millimetres
    assert round(wp.lat_deg * 1e7) == round(items[3].lat_deg * 1e7)  # degE7 exact
    assert round(wp.lon_deg * 1e7) == round(items[3].lon_deg * 1e7)
    speed, trigger, rtl = back[2], back[-2], back[-1]
    assert speed.frame == trigger.frame == rtl.frame == MavFrame.GLOBAL  # frame 0
    assert (speed.param1, speed.param2, speed.param3) == (1.0, 6.5, -1.0)
    assert (trigger.param1, trigger.param3) == (25.0, 1.0)
    gcs.close()


def test_ardupilot_legacy_request_is_answered_with_legacy_item(
    ardupilot: SimulatedVehicle,
) -> None:
    gcs = connect(ardupilot)
    assert gcs.upload(survey_items(home_first=True, n=1))[0] == ACCEPTED
    legacy = gcs.download(use_int=False)
    assert {m.get_type() for m in legacy} == {"MISSION_ITEM"}
    wp = legacy[3]
    assert wp.x == pytest.approx(HOME.lat_deg + 0.0003, abs=1e-5)  # float32 degrees
    gcs.recv(["NONE"], timeout_s=0.3)
    assert any("use MISSION_REQUEST_INT" in text for text in gcs.texts)
    gcs.close()


def test_ardupilot_refuses_upload_for_a_moment_after_boot() -> None:
    with SimulatedVehicle(boot_delay_s=1.0, gps_fix_s=0.0, clock=VirtualClock()) as vehicle:
        gcs = connect(vehicle)
        items = survey_items(home_first=True, n=1)
        if vehicle.sim_time_s < 0.8:
            ack, _ = gcs.upload(items)
            assert ack == NO_SPACE
        assert vehicle.wait_sim_time(1.05)
        ack, _ = gcs.upload(items)
        assert ack == ACCEPTED
        gcs.close()


def test_home_reads_back_as_zeros_until_gps_fix() -> None:
    with SimulatedVehicle(boot_delay_s=0, gps_fix_s=1e6, clock=VirtualClock()) as vehicle:
        gcs = connect(vehicle)
        assert gcs.upload(survey_items(home_first=True, n=1))[0] == ACCEPTED
        home = gcs.download()[0]
        assert (home.x, home.y, home.z) == (0, 0, 0.0)
        assert gcs.command(400, 1.0) == 4  # arming refused without a fix (MAV_RESULT_FAILED)
        gcs.close()


def test_ardupilot_out_of_sequence_item_gets_invalid_sequence_and_upload_goes_on(
    ardupilot: SimulatedVehicle,
) -> None:
    gcs = connect(ardupilot)
    items = survey_items(home_first=True, n=2)
    gcs.conn.mav.mission_count_send(1, 1, len(items), 0)
    req = gcs.recv(["MISSION_REQUEST"], 2)
    assert req.seq == 0
    gcs.conn.mav.send(to_mission_item_int(items[3], 3, 1, 1, 0))  # not what was asked
    ack = gcs.recv(["MISSION_ACK"], 2)
    assert ack.type == INVALID_SEQUENCE
    for seq in range(len(items)):
        gcs._send_item(items, seq, 0)
        gcs.recv(["MISSION_REQUEST", "MISSION_ACK"], 2)
    assert len(ardupilot.stored_mission()) == len(items)
    gcs.close()


def test_vehicle_rerequests_then_cancels_a_silent_upload() -> None:
    with SimulatedVehicle(
        boot_delay_s=0, request_timeout_s=0.15, upload_timeout_s=0.8, clock=VirtualClock()
    ) as vehicle:
        gcs = connect(vehicle)
        gcs.conn.mav.mission_count_send(1, 1, 3, 0)
        seen: list[Any] = []
        deadline = time.monotonic() + 3
        ack = None
        while time.monotonic() < deadline and ack is None:
            msg = gcs.recv(["MISSION_REQUEST", "MISSION_ACK"], 0.5)
            if msg is None:
                continue
            if msg.get_type() == "MISSION_ACK":
                ack = msg
            else:
                seen.append(msg.seq)
        assert ack is not None and ack.type == CANCELLED
        assert seen and set(seen) == {0} and 3 <= len(seen) <= 7  # ~0.8 s / 0.15 s
        gcs.close()


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
def test_download_is_denied_during_an_upload(autopilot: Autopilot) -> None:
    with SimulatedVehicle(autopilot=autopilot, boot_delay_s=0, clock=VirtualClock()) as vehicle:
        gcs = connect(vehicle)
        gcs.conn.mav.mission_count_send(1, 1, 3, 0)
        gcs.recv(["MISSION_REQUEST", "MISSION_REQUEST_INT"], 2)
        gcs.conn.mav.mission_request_list_send(1, 1, 0)
        ack = gcs.recv(["MISSION_ACK"], 2)
        assert ack is not None and ack.type == DENIED
        gcs.close()


def test_ardupilot_rules_for_plane_copter_and_nan() -> None:
    def wire(command: int, frame: int, p: tuple[float, float, float, float], z: float = 50.0) -> WireItem:
        return WireItem(frame, command, p[0], p[1], p[2], p[3], 416500000, -8890000, z)

    wp = wire(16, 6, (7.9, 300.0, 12.6, 90.0), z=100.999)
    plane = ardupilot_store(wp, VehicleType.FIXED_WING)
    copter = ardupilot_store(wp, VehicleType.MULTIROTOR)
    assert isinstance(plane, WireItem) and isinstance(copter, WireItem)
    assert (plane.param1, plane.param2, plane.param3, plane.param4) == (0.0, 255.0, 12.0, 0.0)
    assert (copter.param1, copter.param2, copter.param3, copter.param4) == (7.0, 0.0, 0.0, 0.0)
    assert plane.frame == copter.frame == 3
    assert copter.z == pytest.approx(100.99, abs=1e-5)
    assert (copter.x, copter.y) == (416500000, -8890000)
    # Yaw NaN is allowed on a waypoint, NaN elsewhere is refused by param number
    assert isinstance(ardupilot_store(wire(16, 3, (0, 0, 0, math.nan)), VehicleType.MULTIROTOR), WireItem)
    gimbal = MissionItem.gimbal_manager_pitch_yaw(-90.0, 0.0)  # params 3-4 NaN ("unchanged")
    msg = to_mission_item_int(gimbal, 1, 1, 1, 0)

    assert ardupilot_store(wire_item_from_message(msg), VehicleType.MULTIROTOR) == INVALID_PARAM3
    mount = ardupilot_store(
        wire_item_from_message(to_mission_item_int(MissionItem.gimbal_pitch_yaw(-90, 0), 1, 1, 1, 0)),
        VehicleType.MULTIROTOR,
    )
    assert isinstance(mount, WireItem)
    assert (mount.frame, mount.param1, mount.z) == (0, -90.0, 0.0)  # mount mode (param7) dropped


# --- PX4 --------------------------------------------------------------------------------------


def test_px4_upload_uses_request_int_and_has_no_home(px4: SimulatedVehicle) -> None:
    gcs = connect(px4)
    items = survey_items(home_first=False)
    ack, requests = gcs.upload(items)
    assert ack == ACCEPTED
    assert set(requests) == {"MISSION_REQUEST_INT"}
    back = [from_mission_item(m) for m in gcs.download()]
    assert back == px4.stored_mission()
    assert len(back) == len(items)  # no home item
    assert back[2].param4 == 45.0 and back[2].param1 == pytest.approx(2.7, abs=1e-6)
    assert back[2].param7 == pytest.approx(40.126, abs=1e-5)
    gcs.close()


def test_px4_repeats_the_final_ack_when_the_last_item_comes_again(px4: SimulatedVehicle) -> None:
    gcs = connect(px4)
    items = survey_items(home_first=False, n=1)
    assert gcs.upload(items)[0] == ACCEPTED
    gcs._send_item(items, len(items) - 1, 0)
    ack = gcs.recv(["MISSION_ACK"], 2)
    assert ack is not None and ack.type == ACCEPTED
    gcs.close()


# --- refusals, clear, fence ---------------------------------------------------------------------


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
def test_refusals_and_what_they_leave_stored(autopilot: Autopilot) -> None:
    home_first = autopilot is Autopilot.ARDUPILOT
    first = survey_items(home_first=home_first, n=2)
    second = survey_items(home_first=home_first, n=6, shift_deg=0.0001)
    with SimulatedVehicle(autopilot=autopilot, boot_delay_s=0, gps_fix_s=0, home=HOME) as v:
        gcs = connect(v)
        assert gcs.upload(first)[0] == ACCEPTED
        before = v.stored_mission()
    with SimulatedVehicle(
        autopilot=autopilot,
        boot_delay_s=0,
        gps_fix_s=0,
        home=HOME,
        faults=FaultConfig(refuse="no_space"),
    ) as v:
        v.load_mission(first[1:] if home_first else first)
        assert v.stored_mission() == before
        gcs = connect(v)
        assert gcs.upload(second)[0] == NO_SPACE
        assert v.stored_mission() == before  # unchanged
    with SimulatedVehicle(
        autopilot=autopilot,
        boot_delay_s=0,
        gps_fix_s=0,
        home=HOME,
        faults=FaultConfig(refuse="invalid"),
    ) as v:
        v.load_mission(first[1:] if home_first else first)
        gcs = connect(v)
        ack, requests = gcs.upload(second)
        assert ack == INVALID
        assert len(requests) == len(second) // 2 + 1
        stored = v.stored_mission()
        if autopilot is Autopilot.PX4:
            assert stored == before  # PX4 commits only a complete upload
        else:
            # ArduPilot writes as items arrive: the first half is new, the rest old: partial
            assert stored != before
            assert len(stored) == len(before)
            assert stored[3].lat_deg == pytest.approx(second[3].lat_deg, abs=1e-7)
            assert stored[5:] == before[5:]


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
def test_clear_and_fence_are_separate_lists(autopilot: Autopilot) -> None:
    fence = [
        MissionItem(
            command=5001,
            frame=MavFrame.GLOBAL,
            param1=3.0,
            param5=HOME.lat_deg + d,
            param6=HOME.lon_deg + e,
            param7=0.0,
        )
        for d, e in ((0.001, 0.0), (0.0, 0.001), (-0.001, 0.0))
    ]  # MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 3 vertices
    with SimulatedVehicle(autopilot=autopilot, boot_delay_s=0, gps_fix_s=0, home=HOME) as v:
        gcs = connect(v)
        home_first = autopilot is Autopilot.ARDUPILOT
        assert gcs.upload(survey_items(home_first=home_first, n=2))[0] == ACCEPTED
        assert gcs.upload(fence, mission_type=1)[0] == ACCEPTED
        got = [from_mission_item(m) for m in gcs.download(mission_type=1)]
        assert [(round(i.lat_deg * 1e7), round(i.lon_deg * 1e7)) for i in got] == [
            (round(i.lat_deg * 1e7), round(i.lon_deg * 1e7)) for i in fence
        ]
        assert gcs.clear(mission_type=0) == ACCEPTED
        assert len(gcs.download()) == (1 if home_first else 0)  # ArduPilot keeps home
        assert len(gcs.download(mission_type=1)) == 3  # the fence is untouched
        assert gcs.clear(mission_type=1) == ACCEPTED
        assert gcs.download(mission_type=1) == []
        gcs.close()


def test_corrupt_stored_item_is_what_a_download_sees(ardupilot: SimulatedVehicle) -> None:
    gcs = connect(ardupilot)
    assert gcs.upload(survey_items(home_first=True, n=2))[0] == ACCEPTED
    before = [from_mission_item(m) for m in gcs.download()]
    ardupilot.corrupt_stored_item(3, param7=41.0)
    after = [from_mission_item(m) for m in gcs.download()]
    assert [k for k, (a, b) in enumerate(zip(before, after, strict=True)) if a != b] == [3]
    assert after[3].param7 == 41.0
    gcs.close()


# --- faults ------------------------------------------------------------------------------------


def test_fault_pipe_rates_match_the_configuration() -> None:
    import random

    n = 20000
    faults = FaultConfig(loss_pct=30, duplicate_pct=10, reorder_pct=10, seed=7)
    pipe = FaultyPipe(faults, random.Random(7))
    for k in range(n):
        pipe.offer(k, now=0.0)
    out = pipe.release(10.0)
    s = pipe.stats
    kept = n - s.dropped

    def within(count: int, trials: int, p: float) -> bool:  # 5 sigma binomial band
        return abs(count - trials * p) < 5 * math.sqrt(trials * p * (1 - p))

    assert within(s.dropped, n, 0.30)
    assert within(s.duplicated, kept, 0.10)
    assert len(out) == kept + s.duplicated
    inversions = sum(1 for a, b in itertools.pairwise(out) if b < a)
    assert inversions == s.reordered  # each held message lands after exactly one later one
    assert 0.05 * kept < s.reordered < 0.10 * kept  # held only when nothing is held already


def test_faults_on_the_wire_loss_duplication_reordering_latency() -> None:
    faults = FaultConfig(loss_pct=20, duplicate_pct=10, reorder_pct=10, seed=3)
    with SimulatedVehicle(speedup=60, faults=faults, gps_fix_s=0, clock=VirtualClock()) as vehicle:
        gcs = connect(vehicle)
        gcs.recv(["NONE"], timeout_s=0.3)
        sent_before = sum(vehicle.sent_counts.values())
        seqs: list[int] = []
        deadline = vehicle.clock.monotonic() + 1.2
        while vehicle.clock.monotonic() < deadline:
            msg = gcs.recv(None, timeout_s=0.2)
            if msg is not None and msg.get_type() != "BAD_DATA":
                seqs.append(msg.get_seq())
        sent = sum(vehicle.sent_counts.values()) - sent_before
        gcs.close()
    # received = sent x (1 - loss) x (1 + duplication), give or take the messages in flight
    assert len(seqs) == pytest.approx(sent * 0.8 * 1.1, rel=0.06)
    steps = [(b - a) % 256 for a, b in itertools.pairwise(seqs)]
    repeats = steps.count(0)
    backwards = sum(1 for d in steps if d > 128)
    assert repeats == pytest.approx(0.1 * len(seqs) / 1.1, rel=0.25)
    # a message held back lands after the next one: one step backwards per reordering
    assert 0.04 * len(seqs) < backwards < 0.12 * len(seqs)

    with SimulatedVehicle(
        faults=FaultConfig(latency_s=0.15), boot_delay_s=0, clock=VirtualClock()
    ) as vehicle:
        gcs = connect(vehicle, timeout_s=2.0)
        gcs.drain()
        start = vehicle.clock.monotonic()
        gcs.conn.mav.mission_request_list_send(1, 1, 0)
        assert gcs.recv(["MISSION_COUNT"], 2) is not None
        # 0.15 s each way, on simulated time: no sooner (float sums aside), and no later than a step
        assert 0.3 - 1e-9 <= vehicle.clock.monotonic() - start <= 0.3 + 0.003
        gcs.close()


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
def test_transfer_through_loss_duplication_and_reordering(autopilot: Autopilot) -> None:
    faults = FaultConfig(loss_pct=15, duplicate_pct=15, reorder_pct=15, seed=11)
    home_first = autopilot is Autopilot.ARDUPILOT
    items = survey_items(home_first=home_first, n=15)
    with SimulatedVehicle(
        autopilot=autopilot,
        boot_delay_s=0,
        gps_fix_s=0,
        faults=faults,
        request_timeout_s=0.1,
        home=HOME,
        clock=VirtualClock(),
    ) as v:
        gcs = connect(v, timeout_s=0.15)
        ack, _ = gcs.upload(items, retries=400)
        stored = v.stored_mission()
        if ack is None and home_first:
            # ArduPilot does not repeat a lost final ACK: the read-back decides
            assert len(stored) == len(items)
        else:
            assert ack == ACCEPTED
        assert [round(i.lat_deg * 1e7) for i in stored[1:]] == [round(i.lat_deg * 1e7) for i in items[1:]]
        back = [from_mission_item(m) for m in gcs.download(retries=400)]
        assert back == stored
        assert v.receive_stats.dropped > 0 and v.send_stats.duplicated > 0
        gcs.close()


# --- commands ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("autopilot", "mode_params", "custom_mode"),
    [
        (Autopilot.ARDUPILOT, (1, 3, 0), 3),
        (Autopilot.PX4, (1, 4, 4), (4 << 16) | (4 << 24)),
    ],
)
def test_arm_and_auto_by_commands(
    autopilot: Autopilot, mode_params: tuple[int, int, int], custom_mode: int
) -> None:
    with SimulatedVehicle(
        autopilot=autopilot, boot_delay_s=0, gps_fix_s=0, home=HOME, clock=VirtualClock()
    ) as v:
        v.load_mission(survey_items(home_first=False, n=1))
        gcs = connect(v)
        assert gcs.command(400, 1.0) == 0  # MAV_RESULT_ACCEPTED
        assert gcs.command(176, *mode_params) == 0
        deadline = time.monotonic() + 3
        while time.monotonic() < deadline:
            hb = gcs.recv(["HEARTBEAT"], 1.5)
            if hb is not None and hb.custom_mode == custom_mode:
                break
        assert hb is not None and hb.custom_mode == custom_mode
        assert hb.base_mode & 128  # armed
        assert gcs.command(400, 0.0) == 4  # flying: disarm refused
        assert gcs.command(31000) == 3  # unknown: MAV_RESULT_UNSUPPORTED
        gcs.close()


def test_set_mode_message_and_set_current() -> None:
    with SimulatedVehicle(autopilot=Autopilot.PX4, gps_fix_s=0, home=HOME, clock=VirtualClock()) as v:
        v.load_mission(survey_items(home_first=False, n=3))
        gcs = connect(v)
        # SET_MODE with PX4's custom mode: main AUTO (4) << 16 | sub RTL (5) << 24
        gcs.conn.mav.set_mode_send(1, 1, (4 << 16) | (5 << 24))
        deadline = time.monotonic() + 3
        while time.monotonic() < deadline:
            hb = gcs.recv(["HEARTBEAT"], 1.5)
            if hb is not None and hb.custom_mode == (4 << 16) | (5 << 24):
                break
        assert hb is not None and hb.custom_mode == (4 << 16) | (5 << 24)
        assert gcs.command(224, 3) == 0  # DO_SET_MISSION_CURRENT
        assert gcs.command(224, 99) == 2  # no such item: denied
        assert v.flight.mission.current == 3
        gcs.close()


def test_ground_station_can_cancel_its_upload() -> None:
    with SimulatedVehicle(boot_delay_s=0, request_timeout_s=0.1, clock=VirtualClock()) as vehicle:
        gcs = connect(vehicle)
        gcs.conn.mav.mission_count_send(1, 1, 5, 0)
        assert gcs.recv(["MISSION_REQUEST"], 2) is not None
        gcs.conn.mav.mission_ack_send(1, 1, CANCELLED, 0)
        gcs.recv(["NONE"], 0.2)
        gcs.drain()
        assert gcs.recv(["MISSION_REQUEST"], 0.5) is None  # no more re-requests
        gcs.close()


def test_serial_link_speed_bounds_the_transfer_time() -> None:
    items = survey_items(home_first=False, n=36)
    baud = 19200
    packer = mavlink2.MAVLink(None, 255, 190)  # MAVLink 2, as both sides speak
    floor_bytes = 0
    for seq, item in enumerate(items):
        request = mavlink2.MAVLink_mission_request_int_message(255, 190, seq, 0)
        floor_bytes += len(to_mission_item_int(item, seq, 1, 1, 0).pack(packer))
        floor_bytes += len(request.pack(packer))
    floor_s = floor_bytes * 10 / baud  # stop and wait: every request, then every item
    with SimulatedVehicle(autopilot=Autopilot.PX4, gps_fix_s=0, link_baud=baud, clock=VirtualClock()) as v:
        gcs = connect(v, timeout_s=1.0)
        start = v.clock.monotonic()
        ack, _ = gcs.upload(items)
        elapsed = v.clock.monotonic() - start
        gcs.close()
    assert ack == ACCEPTED
    # The paced link cannot be beaten (how much slower it is, is the benchmark's business).
    assert elapsed > floor_s * 0.95


def test_fault_pipe_says_when_its_next_message_is_due() -> None:
    import random

    pipe = FaultyPipe(FaultConfig(latency_s=0.1), random.Random(1))
    assert pipe.next_due_s() is None
    pipe.offer(b"x", now=5.0)
    assert pipe.next_due_s() == pytest.approx(5.1)
    assert pipe.release(5.09) == []
    assert pipe.release(5.1) == [b"x"]
    assert pipe.next_due_s() is None
    # a 9600-baud line (8N1): 100 bytes take 100 x 10 / 9600 s, one message after the other
    serial = FaultyPipe(FaultConfig(), random.Random(1), baud=9600)
    serial.offer(bytes(100), now=0.0)
    serial.offer(bytes(100), now=0.0)
    assert serial.next_due_s() == pytest.approx(1000 / 9600)
    assert len(serial.release(1000 / 9600)) == 1
    assert serial.next_due_s() == pytest.approx(2000 / 9600)


def _round_trip_s(sock: socket.socket, parser: Any, packer: Any, seq: int) -> float:
    """Send MISSION_REQUEST_INT ``seq`` and wait for its MISSION_ITEM_INT; seconds taken."""
    start = time.perf_counter()
    sock.sendall(mavlink2.MAVLink_mission_request_int_message(1, 1, seq, 0).pack(packer))
    while True:
        for msg in parser.parse_buffer(sock.recv(4096)) or []:
            if msg.get_type() == "MISSION_ITEM_INT" and msg.seq == seq:
                return time.perf_counter() - start


def test_serial_link_is_never_faster_than_its_baud_rate() -> None:
    # Telemetry at 20x real time floods a 9600-baud link: bytes reach the ground station as
    # fast as the line allows and never faster (8N1: 960 bytes/s), give or take one packet.
    baud = 9600
    clock = VirtualClock()
    with SimulatedVehicle(
        speedup=20, gps_fix_s=0, link_baud=baud, streams_on_request=False, clock=clock
    ) as vehicle:
        host, port = vehicle.url_for_client.removeprefix("tcp://").split(":")
        with socket.create_connection((host, int(port)), timeout=2.0) as sock:
            clock.sleep(1.2)  # let the link's buffer fill: from here the line is the limit
            sock.setblocking(False)
            with contextlib.suppress(BlockingIOError):
                while sock.recv(65536):
                    pass
            arrivals: list[tuple[float, int]] = []
            end = clock.monotonic() + 1.5
            while clock.monotonic() < end:
                if clock.wait_readable([sock.fileno()], end - clock.monotonic()):
                    arrivals.append((clock.monotonic(), len(sock.recv(65536))))
    t0 = arrivals[0][0]
    total = 0
    for t, n in arrivals[1:]:
        total += n
        assert total <= (t - t0) * baud / 10 + 300, f"{total} bytes {t - t0:.3f} s after the first"
    rate = total / (arrivals[-1][0] - t0)
    assert rate > 0.5 * baud / 10  # and the line is used, not left idle (speed: the benchmark)


# --- flight (no sockets) -----------------------------------------------------------------------


def two_line_survey(
    sim: FlightSimulator, trigger_m: float, line_m: float, spacing_m: float, hold_s: float
) -> tuple[list[MissionItem], list[tuple[float, float]]]:
    """Home, take-off 50 m, speed 8 m/s, two lines east then west with distance triggering
    (QGC's pattern: E + TRIGG(d, 0, 1), X + TRIGG(0)), RTL. Returns items and line ends (x, y)."""

    def wp(x: float, y: float, hold: float = 0.0) -> MissionItem:
        lon, lat = sim.frame.to_lonlat(x, y)
        return MissionItem.waypoint(float(lat), float(lon), 50.0, hold_s=hold)

    ends = [
        (40.0, 60.0),
        (40.0 + line_m, 60.0),
        (40.0 + line_m, 60.0 + spacing_m),
        (40.0, 60.0 + spacing_m),
    ]
    items = [
        MissionItem.waypoint(HOME.lat_deg, HOME.lon_deg, 0.0),
        MissionItem.takeoff(HOME.lat_deg, HOME.lon_deg, 50.0),
        MissionItem.change_speed(8.0),
        wp(*ends[0]),
        MissionItem.cam_trigger_distance(trigger_m),
        wp(*ends[1], hold=hold_s),
        MissionItem.cam_trigger_distance(0.0, trigger_now=False),
        wp(*ends[2]),
        MissionItem.cam_trigger_distance(trigger_m),
        wp(*ends[3]),
        MissionItem.cam_trigger_distance(0.0, trigger_now=False),
        MissionItem.return_to_launch(),
    ]
    return items, ends


def fly(sim: FlightSimulator, items: list[MissionItem], dt_s: float) -> list[Any]:
    sim.set_mission(items)
    msgs = sim.step(2.0)
    assert sim.arm() == (True, "")
    assert sim.set_mode(1, 3)
    while not sim.has_landed_after_flight and sim.time_s < 3000:
        msgs += sim.step(dt_s)
    return msgs


def expected_stations(ends: list[tuple[float, float]], trigger_m: float) -> list[tuple[float, float]]:
    """Photo positions of ArduPilot's rule on a line: the start, then every trigger_m."""
    out = []
    for (x0, y0), (x1, y1) in (ends[0:2], ends[2:4]):
        length = math.hypot(x1 - x0, y1 - y0)
        for k in range(int(length / trigger_m + 1e-9) + 1):
            f = k * trigger_m / length
            out.append((x0 + f * (x1 - x0), y0 + f * (y1 - y0)))
    return out


@pytest.mark.parametrize("dt_s", [0.05, 0.37, 3.0])
def test_two_line_survey_triggers_where_geometry_says(dt_s: float) -> None:
    sim = FlightSimulator(
        autopilot=Autopilot.ARDUPILOT, vehicle_type=VehicleType.MULTIROTOR, home=HOME, gps_fix_s=1.0
    )
    items, ends = two_line_survey(sim, trigger_m=20.0, line_m=190.0, spacing_m=30.0, hold_s=3.0)
    msgs = fly(sim, items, dt_s)
    stations = expected_stations(ends, 20.0)
    assert len(stations) == 20
    feedback = [m for m in msgs if m.get_type() == "CAMERA_FEEDBACK"]
    assert len(feedback) == len(sim.shots) == len(stations)
    assert [m.img_idx for m in feedback] == list(range(1, 21))
    assert all(m.completed_captures == 0 for m in feedback)
    for shot, (x, y), msg in zip(sim.shots, stations, feedback, strict=True):
        assert math.hypot(shot.x_m - x, shot.y_m - y) < 1e-6  # geometric truth
        assert shot.alt_rel_home_m == pytest.approx(50.0, abs=1e-9)
        # reported: noise of 0.3 m RMS per axis; 1.5 m is 5 sigma
        reported = geodesic_distance_m(msg.lat / 1e7, msg.lng / 1e7, shot.lat_deg, shot.lon_deg)
        assert 0.0 < reported < 1.5
        assert msg.time_usec == round(shot.utc_s * 1e6)
        assert msg.alt_rel == pytest.approx(50.0, abs=2.5)
        assert msg.alt_msl == pytest.approx(msg.alt_rel + HOME.alt_amsl_m, abs=1e-3)
    # timing: 8 m/s along the line, 20 m apart -> 2.5 s
    line1 = [s.time_s for s in sim.shots[:10]]
    assert all(b - a == pytest.approx(2.5, abs=1e-6) for a, b in itertools.pairwise(line1))
    # hold of 3 s at the end of line 1: reached 3 s after arrival
    arrive_x = sim.shots[9].time_s + 10.0 / 8.0
    reached = dict((seq, t) for t, seq in sim.reached)
    assert reached[5] == pytest.approx(arrive_x + 3.0, abs=1e-6)
    # RTL lands at home and disarms
    assert sim.has_landed_after_flight and not sim.armed
    assert math.hypot(sim.pos[0], sim.pos[1]) < 1e-6 and sim.pos[2] == 0.0


def test_flight_is_independent_of_the_step_size() -> None:
    runs = []
    for dt in (0.02, 1.3):
        sim = FlightSimulator(autopilot=Autopilot.ARDUPILOT, vehicle_type=VehicleType.MULTIROTOR, home=HOME)
        items, _ = two_line_survey(sim, 17.0, 120.0, 25.0, 0.0)
        msgs = fly(sim, items, dt)
        shots = [(m.lat, m.lng, m.time_usec) for m in msgs if m.get_type() == "CAMERA_FEEDBACK"]
        track = {
            m.time_boot_ms: (m.lat, m.lon, m.relative_alt)
            for m in msgs
            if m.get_type() == "GLOBAL_POSITION_INT"
        }
        runs.append((shots, track))
    assert runs[0][0] == runs[1][0]
    common = sorted(set(runs[0][1]) & set(runs[1][1]))
    assert len(common) > 500
    for t in common:  # the same track to the last degE7 unit / millimetre (float rounding)
        a, b = runs[0][1][t], runs[1][1][t]
        assert all(abs(u - v) <= 1 for u, v in zip(a, b, strict=True))


def test_telemetry_rates_and_fields() -> None:
    sim = FlightSimulator(autopilot=Autopilot.ARDUPILOT, vehicle_type=VehicleType.MULTIROTOR, home=HOME)
    items, _ = two_line_survey(sim, 20.0, 100.0, 20.0, 0.0)
    msgs = fly(sim, items, 0.5)
    counts = Counter(m.get_type() for m in msgs)
    duration = sim.time_s
    assert counts["HEARTBEAT"] == pytest.approx(duration, abs=2)
    assert counts["SYSTEM_TIME"] == pytest.approx(duration, abs=2)
    assert counts["GLOBAL_POSITION_INT"] == pytest.approx(10 * duration, abs=2)
    assert counts["ATTITUDE"] == pytest.approx(10 * duration, abs=2)
    assert counts["GPS_RAW_INT"] == pytest.approx(5 * duration, abs=2)
    assert counts["MISSION_ITEM_REACHED"] == 5  # take-off and four waypoints
    gpi = [m for m in msgs if m.get_type() == "GLOBAL_POSITION_INT"]
    top = max(m.relative_alt for m in gpi)
    assert top == pytest.approx(50000, abs=2500)
    assert gpi[-1].relative_alt == 0
    boot = [m.time_boot_ms for m in gpi]
    assert boot == sorted(boot)
    fast = [m for m in gpi if m.relative_alt > 45000 and math.hypot(m.vx, m.vy) > 700]
    assert fast and all(math.hypot(m.vx, m.vy) == pytest.approx(800, abs=2) for m in fast)


def test_px4_camera_messages_and_gimbal() -> None:
    sim = FlightSimulator(autopilot=Autopilot.PX4, vehicle_type=VehicleType.MULTIROTOR, home=HOME)
    items, _ = two_line_survey(sim, 25.0, 110.0, 20.0, 0.0)
    items = items[1:]  # PX4: no home item
    items.insert(1, MissionItem.gimbal_manager_pitch_yaw(-90.0, 0.0))
    items.insert(2, MissionItem.image_start_capture())
    sim.set_mission(items)
    sim.step(2.0)
    assert sim.arm()[0]
    assert sim.set_mode(1, 4, 4)
    msgs: list[Any] = []
    while not sim.has_landed_after_flight and sim.time_s < 1000:
        msgs += sim.step(0.5)
    captured = [m for m in msgs if m.get_type() == "CAMERA_IMAGE_CAPTURED"]
    triggers = [m for m in msgs if m.get_type() == "CAMERA_TRIGGER"]
    assert [m.image_index for m in captured] == list(range(len(sim.shots)))
    assert len(triggers) == len(captured) == 1 + 5 + 5  # one single capture + 2 lines of 5
    assert sim.shots[0].alt_rel_home_m == pytest.approx(50.0)  # after take-off
    assert all(s.gimbal_pitch_deg == -90.0 for s in sim.shots)
    assert any(m.get_type() == "GIMBAL_DEVICE_ATTITUDE_STATUS" for m in msgs)


def test_fixed_wing_ardupilot_mount_status() -> None:
    sim = FlightSimulator(autopilot=Autopilot.ARDUPILOT, vehicle_type=VehicleType.FIXED_WING, home=HOME)
    items, _ = two_line_survey(sim, 30.0, 310.0, 60.0, hold_s=5.0)
    items.insert(2, MissionItem.gimbal_pitch_yaw(-80.0, 0.0))
    sim.set_mission(items)
    sim.step(2.0)
    assert sim.arm()[0] and sim.set_mode(1, 10)
    msgs: list[Any] = []
    while not sim.has_landed_after_flight and sim.time_s < 1000:
        msgs += sim.step(1.0)
    mounts = [m for m in msgs if m.get_type() == "MOUNT_STATUS"]
    assert mounts and mounts[-1].pointing_a == -8000
    hb = sim.heartbeat_message()
    assert hb.type == 1 and hb.autopilot == 3  # type: ignore[attr-defined]
    # Plane ignores the hold: the same mission without holds reaches every waypoint at the
    # same times (a multirotor would wait 5 s at each)
    again = FlightSimulator(autopilot=Autopilot.ARDUPILOT, vehicle_type=VehicleType.FIXED_WING, home=HOME)
    no_hold, _ = two_line_survey(again, 30.0, 310.0, 60.0, hold_s=0.0)
    no_hold.insert(2, MissionItem.gimbal_pitch_yaw(-80.0, 0.0))
    assert [i.param1 for i in no_hold] != [i.param1 for i in items]
    again.set_mission(no_hold)
    again.step(2.0)
    assert again.arm()[0] and again.set_mode(1, 10)
    while not again.has_landed_after_flight and again.time_s < 1000:
        again.step(1.0)
    assert len(sim.reached) >= 5
    assert [s for _, s in again.reached] == [s for _, s in sim.reached]
    assert [t for t, _ in again.reached] == pytest.approx([t for t, _ in sim.reached], abs=1e-9)


# --- flight through the server, with a tlog -----------------------------------------------------


def read_tlog(path: Path) -> list[Any]:
    log = mavutil.mavlink_connection(str(path))
    out: list[Any] = []
    while True:
        msg = log.recv_match()
        if msg is None:
            return out
        out.append(msg)


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
def test_flight_through_the_link_writes_a_readable_tlog(autopilot: Autopilot, tmp_path: Path) -> None:
    tlog = tmp_path / "flight.tlog"
    with SimulatedVehicle(autopilot=autopilot, speedup=100, tlog_path=tlog, home=HOME, boot_delay_s=0.0) as v:
        items, ends = two_line_survey(v.flight, 20.0, 190.0, 30.0, hold_s=2.0)
        if autopilot is Autopilot.PX4:
            items = items[1:]
        gcs = connect(v, timeout_s=1.0)
        # every stream at 4 Hz, as MAVProxy asks at connection (REQUEST_DATA_STREAM, ALL)
        gcs.conn.mav.request_data_stream_send(1, 1, 0, 4, 1)
        assert v.wait_sim_time(1.5)
        assert gcs.upload(items)[0] == ACCEPTED
        assert gcs.command(400, 1.0) == 0
        assert gcs.command(300) == 0  # MISSION_START
        assert v.wait_landed(60.0)
        shots = list(v.flight.shots)
        gcs.close()
    msgs = read_tlog(tlog)
    stamps = [m._timestamp for m in msgs]
    assert stamps == sorted(stamps)
    assert len(msgs) > 1000
    kind = "CAMERA_FEEDBACK" if autopilot is Autopilot.ARDUPILOT else "CAMERA_IMAGE_CAPTURED"
    events = [m for m in msgs if m.get_type() == kind]
    stations = expected_stations(ends, 20.0)
    assert len(events) == len(shots) == len(stations) == 20
    frame = FlightSimulator(autopilot=autopilot, vehicle_type=VehicleType.MULTIROTOR, home=HOME)
    for msg, (x, y) in zip(events, stations, strict=True):
        lon = (msg.lng if kind == "CAMERA_FEEDBACK" else msg.lon) / 1e7
        ex, ey = frame.frame.to_xy(lon, msg.lat / 1e7)
        assert math.hypot(float(ex) - x, float(ey) - y) < 1.5
        # the tlog's time stamp is the photo's time (simulated UTC) to within a millisecond
        t_event = (msg.time_usec if kind == "CAMERA_FEEDBACK" else msg.time_utc) / 1e6
        assert msg._timestamp == pytest.approx(t_event, abs=0.15)
    first = struct.unpack(">Q", tlog.read_bytes()[:8])[0] / 1e6
    assert abs(first - time.time()) < 3600  # UTC microseconds, big-endian


def test_gps_noise_has_the_configured_size_and_seed() -> None:
    def track(seed: int) -> list[tuple[float, float]]:
        sim = FlightSimulator(
            autopilot=Autopilot.ARDUPILOT,
            vehicle_type=VehicleType.MULTIROTOR,
            home=HOME,
            config=FlightConfig(seed=seed, horizontal_noise_m=0.3),
            gps_fix_s=0.0,
        )
        out = []
        for m in sim.step(600.0):
            if m.get_type() == "GLOBAL_POSITION_INT":  # type: ignore[attr-defined]
                x, y = sim.frame.to_xy(m.lon / 1e7, m.lat / 1e7)  # type: ignore[attr-defined]
                out.append((float(x), float(y)))
        return out

    a, b = track(1), track(2)
    assert a[:100] == track(1)[:100] and a != b  # seeded, deterministic
    for axis in (0, 1):
        rms = math.sqrt(sum(p[axis] ** 2 for p in a) / len(a))
        assert 0.2 < rms < 0.4  # 0.3 m RMS per axis, on a vehicle standing at home


def test_configs_refuse_impossible_values() -> None:
    with pytest.raises(InputError, match="loss_pct"):
        FaultConfig(loss_pct=120)
    with pytest.raises(InputError, match="refuse"):
        FaultConfig(refuse="sometimes")
    with pytest.raises(InputError, match="climb_rate_m_s"):
        FlightConfig(climb_rate_m_s=0)
    with pytest.raises(InputError, match="speedup"):
        SimulatedVehicle(speedup=0)


# --- telemetry on request (ArduPilot's SRn_ rates are 0 on its serial ports) -----------------


def _count(gcs: GroundStation, seconds: float) -> Counter[str]:
    """Messages received in ``seconds`` of the ground station's clock, by type."""
    seen: Counter[str] = Counter()
    end = gcs.clock.monotonic() + seconds
    while (left := end - gcs.clock.monotonic()) > 0:
        msg = gcs.recv(None, timeout_s=left)
        if msg is not None:
            seen[msg.get_type()] += 1
    return seen


def test_ardupilot_sends_only_heartbeats_until_asked_then_what_was_asked() -> None:
    with SimulatedVehicle(gps_fix_s=0.0, home=HOME, speedup=5, clock=VirtualClock()) as vehicle:
        gcs = connect(vehicle)
        quiet = _count(gcs, 1.0)
        assert quiet["HEARTBEAT"] >= 3  # 1 Hz of simulated time, 5x
        for name in ("GLOBAL_POSITION_INT", "ATTITUDE", "SYSTEM_TIME", "MISSION_CURRENT", "GPS_RAW_INT"):
            assert quiet[name] == 0, name
        # SET_MESSAGE_INTERVAL (511): GLOBAL_POSITION_INT (33) every 0.5 s of simulated time
        assert gcs.command(511, 33, 500_000) == mavlink2.MAV_RESULT_ACCEPTED
        asked = _count(gcs, 2.0)
        # 2 wall s x 5 = 10 simulated s at 2 Hz: about 20 (the wall clock of the test is loose)
        assert 12 <= asked["GLOBAL_POSITION_INT"] <= 26, asked
        assert asked["ATTITUDE"] == 0 and asked["SYSTEM_TIME"] == 0
        # a message it cannot send: UNSUPPORTED, as ArduPilot answers an unknown id
        assert gcs.command(511, 12345, 100_000) == mavlink2.MAV_RESULT_UNSUPPORTED
        # -1 stops it
        assert gcs.command(511, 33, -1) == mavlink2.MAV_RESULT_ACCEPTED
        gcs.drain()
        assert _count(gcs, 0.6)["GLOBAL_POSITION_INT"] <= 1
        # the legacy REQUEST_DATA_STREAM: group EXTRA1 (10) is ATTITUDE, as in ArduCopter
        gcs.conn.mav.request_data_stream_send(1, 1, 10, 4, 1)
        legacy = _count(gcs, 1.0)
        assert legacy["ATTITUDE"] >= 10 and legacy["GLOBAL_POSITION_INT"] == 0, legacy
        gcs.close()


def test_px4_streams_from_boot() -> None:
    with SimulatedVehicle(
        autopilot=Autopilot.PX4, gps_fix_s=0.0, home=HOME, speedup=5, clock=VirtualClock()
    ) as vehicle:
        gcs = connect(vehicle)
        seen = _count(gcs, 1.0)
        assert seen["GLOBAL_POSITION_INT"] >= 20 and seen["SYSTEM_TIME"] >= 2, seen
        gcs.close()


def test_vehicle_moves_to_the_uploaded_missions_home_before_its_first_flight() -> None:
    far = HomePosition(lat_deg=HOME.lat_deg + 0.65, lon_deg=HOME.lon_deg - 0.3, alt_amsl_m=412.5)
    items = survey_items(home_first=True, n=3, shift_deg=0.65)
    items[0] = MissionItem(
        command=16, frame=MavFrame.GLOBAL, param5=far.lat_deg, param6=far.lon_deg, param7=412.5
    )
    with SimulatedVehicle(
        boot_delay_s=0.0, gps_fix_s=0.0, home=HOME, follow_mission_home=True, clock=VirtualClock()
    ) as vehicle:
        gcs = connect(vehicle)
        result, _ = gcs.upload(items)
        assert result == ACCEPTED
        assert (vehicle.home.lat_deg, vehicle.home.lon_deg, vehicle.home.alt_amsl_m) == pytest.approx(
            (far.lat_deg, far.lon_deg, 412.5), abs=1e-7
        )
        assert gcs.command(511, 33, 100_000) == mavlink2.MAV_RESULT_ACCEPTED
        pos = gcs.recv(["GLOBAL_POSITION_INT"], timeout_s=2.0)
        assert pos is not None
        # on the ground at the new home: its elevation is the mission's home elevation
        assert geodesic_distance_m(pos.lat * 1e-7, pos.lon * 1e-7, far.lat_deg, far.lon_deg) < 3.0
        assert abs(pos.alt / 1000 - 412.5) < 2.0 and abs(pos.relative_alt / 1000) < 2.0
        gcs.close()
    # without follow_mission_home the vehicle stays where it was put
    with SimulatedVehicle(boot_delay_s=0.0, gps_fix_s=0.0, home=HOME) as vehicle:
        gcs = connect(vehicle)
        assert gcs.upload(items)[0] == ACCEPTED
        assert vehicle.home == HOME
        gcs.close()


def test_camera_card_stamps_frames_on_its_clock_and_drops_and_adds_on_request(tmp_path: Path) -> None:
    from PIL import Image

    from acquisition.exif import read_tags
    from acquisition.simulator.camera import FrameCard

    offset_s = -3723.25  # the camera is 1 h 2 min 3.25 s behind UTC
    card = FrameCard(tmp_path / "card", clock_offset_s=offset_s, drop={2}, extra={3})
    times = [1_760_000_000.0 + 2.213 * k for k in range(5)]
    for t in times:
        card.photo(t)
    names = sorted(p.name for p in (tmp_path / "card").iterdir())
    # 5 photos, the 2nd not written, one extra after the 3rd: 5 frames, nothing half-written
    assert names == [f"IMG_{k:04d}.JPG" for k in range(1, 6)]
    tags = [read_tags(tmp_path / "card" / name) for name in names]
    # UTC of each exposure, frame by frame: photos 1, 3, the extra 0.4 s after 3, then 4, 5
    truth = [times[0], times[2], times[2] + 0.4, times[3], times[4]]
    for tag, t in zip(tags, truth, strict=True):
        assert tag.capture_time_s is not None and not tag.capture_time_zone_known
        assert tag.capture_time_s == pytest.approx(t + offset_s, abs=0.0015)  # milliseconds
    with Image.open(tmp_path / "card" / names[0]) as image:  # a real JPEG that decodes
        assert image.format == "JPEG" and image.size == (64, 48)
    # a card that already holds frames is refused: two flights would mix
    with pytest.raises(InputError, match="already holds frames"):
        FrameCard(tmp_path / "card")


def test_simulated_flight_writes_one_frame_per_photo(tmp_path: Path) -> None:
    from acquisition.exif import read_tags
    from acquisition.simulator.camera import FrameCard

    card = FrameCard(tmp_path / "frames", clock_offset_s=12.5)
    with SimulatedVehicle(
        boot_delay_s=0.0,
        gps_fix_s=0.0,
        home=HOME,
        speedup=40,
        frames=card,
        streams_on_request=False,
        clock=VirtualClock(),
    ) as vehicle:
        items = survey_items(home_first=False, n=3)
        items.insert(2, MissionItem.cam_trigger_distance(15.0))
        vehicle.load_mission(items)
        vehicle.auto_start()
        assert vehicle.wait_landed(60)
        shots = list(vehicle.flight.shots)
    assert len(shots) >= 5
    frames = sorted((tmp_path / "frames").glob("*.JPG"))
    assert len(frames) == len(shots) == card.frames
    for frame, shot in zip(frames, shots, strict=True):
        stamp = read_tags(frame).capture_time_s
        assert stamp == pytest.approx(shot.utc_s + 12.5, abs=0.0015)
