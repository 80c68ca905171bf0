"""Tests of acquisition.link: URLs, errors a crew meets, identification, heartbeat, signing.

Peers are real: the simulated vehicle, plain sockets that stay silent, and a pymavlink endpoint
that signs its messages with a key.
"""

from __future__ import annotations

import hashlib
import socket
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from acquisition.clock import VirtualClock
from acquisition.errors import LinkError
from acquisition.link import Link
from acquisition.link_port import URL_EXAMPLES, LinkUrl
from acquisition.signing import load_signing_key
from acquisition.simulator.server import SimulatedVehicle
from planner.mission import Autopilot, VehicleType


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    with socket.socket(socket.AF_INET, kind) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


# --- URLs --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("url", "scheme", "host", "port", "device", "baud"),
    [
        ("serial:///dev/ttyUSB0:57600", "serial", None, None, "/dev/ttyUSB0", 57600),
        ("serial:///dev/ttyACM0", "serial", None, None, "/dev/ttyACM0", 57600),
        ("serial://COM3:115200", "serial", None, None, "COM3", 115200),
        ("udpin://0.0.0.0:14550", "udpin", "0.0.0.0", 14550, None, None),
        ("udpout://192.168.4.1:14550", "udpout", "192.168.4.1", 14550, None, None),
        ("tcp://127.0.0.1:5760", "tcp", "127.0.0.1", 5760, None, None),
        ("TCPIN://0.0.0.0:5760", "tcpin", "0.0.0.0", 5760, None, None),
    ],
)
def test_url_forms_parse(
    url: str, scheme: str, host: str | None, port: int | None, device: str | None, baud: int | None
) -> None:
    parsed = LinkUrl.parse(url)
    assert (parsed.scheme, parsed.host, parsed.port, parsed.device, parsed.baud) == (
        scheme,
        host,
        port,
        device,
        baud,
    )


def test_mavutil_device_strings() -> None:
    assert LinkUrl.parse("tcp://127.0.0.1:5760").mavutil_device == "tcp:127.0.0.1:5760"
    assert LinkUrl.parse("udpin://0.0.0.0:14550").mavutil_device == "udpin:0.0.0.0:14550"
    assert LinkUrl.parse("serial:///dev/ttyUSB0:57600").mavutil_device == "/dev/ttyUSB0"


@pytest.mark.parametrize("url", ["http://127.0.0.1:5760", "udp://127.0.0.1:14550", "com3"])
def test_bad_scheme_names_every_valid_one(url: str) -> None:
    with pytest.raises(LinkError) as caught:
        Link.open(url, heartbeat_timeout_s=0.5)
    message = str(caught.value)
    assert repr(url) in message
    for scheme, example in URL_EXAMPLES.items():
        assert scheme in message
        assert example in message


@pytest.mark.parametrize(
    ("url", "words"),
    [
        ("tcp://127.0.0.1", "needs a host and a port"),
        ("tcp://:5760", "needs a host and a port"),
        ("udpin://0.0.0.0:99999", "out of range"),
        ("serial:///dev/ttyUSB0:fast", "not a number"),
    ],
)
def test_malformed_urls(url: str, words: str) -> None:
    with pytest.raises(LinkError, match=words):
        LinkUrl.parse(url)


# --- opening failures -----------------------------------------------------------------------------


def test_serial_device_missing() -> None:
    url = "serial:///dev/sfap-no-such-radio:57600"
    with pytest.raises(LinkError) as caught:
        Link.open(url, heartbeat_timeout_s=0.5)
    assert "/dev/sfap-no-such-radio does not exist" in str(caught.value)
    assert url in str(caught.value)


def test_connection_refused_names_url() -> None:
    url = f"tcp://127.0.0.1:{free_port()}"
    started = time.monotonic()
    with pytest.raises(LinkError) as caught:
        Link.open(url, heartbeat_timeout_s=0.5)
    assert time.monotonic() - started < 2.0  # one attempt, not mavutil's sleeping retries
    assert url in str(caught.value)
    assert "connection refused" in str(caught.value)


@pytest.mark.parametrize(("scheme", "kind"), [("udpin", socket.SOCK_DGRAM), ("tcpin", socket.SOCK_STREAM)])
def test_port_busy(scheme: str, kind: int) -> None:
    with socket.socket(socket.AF_INET, kind) as holder:
        holder.bind(("127.0.0.1", 0))
        if kind == socket.SOCK_STREAM:
            holder.listen(1)
        port = holder.getsockname()[1]
        url = f"{scheme}://127.0.0.1:{port}"
        with pytest.raises(LinkError) as caught:
            Link.open(url, heartbeat_timeout_s=0.5)
    assert f"port {port} is busy" in str(caught.value)
    assert url in str(caught.value)


@contextmanager
def silent_server(send_gcs_heartbeats: bool = False) -> Iterator[str]:
    """A TCP server that accepts and says nothing (or only ground-station heartbeats)."""
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    stop = threading.Event()

    def serve() -> None:
        server.settimeout(0.1)
        peer = None
        while not stop.is_set():
            if peer is None:
                try:
                    peer, _ = server.accept()
                except TimeoutError:
                    continue
            if send_gcs_heartbeats:
                mav = mavlink2.MAVLink(None, srcSystem=250, srcComponent=190)
                heartbeat = mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)
                peer.sendall(heartbeat.pack(mav))
            stop.wait(0.1)
        if peer is not None:
            peer.close()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join()
        server.close()


def test_no_heartbeat_within_timeout() -> None:
    with silent_server() as url:
        started = time.monotonic()
        with pytest.raises(LinkError) as caught:
            Link.open(url, heartbeat_timeout_s=0.4)
        elapsed = time.monotonic() - started
    assert 0.35 < elapsed < 5.0  # the timeout is honoured: not early, and not ignored
    message = str(caught.value)
    assert f"no heartbeat from an autopilot on {url} within 0.4 s" in message
    assert "nothing at all was received" in message
    assert "check" in message


def test_ground_station_heartbeats_are_not_a_vehicle() -> None:
    with silent_server(send_gcs_heartbeats=True) as url, pytest.raises(LinkError) as caught:
        Link.open(url, heartbeat_timeout_s=0.5)
    assert "no heartbeat from an autopilot" in str(caught.value)
    assert "bytes received" in str(caught.value)


# --- against the simulated vehicle --------------------------------------------------------------


@pytest.mark.parametrize(
    ("autopilot", "vehicle_type"),
    [
        (Autopilot.ARDUPILOT, VehicleType.MULTIROTOR),
        (Autopilot.ARDUPILOT, VehicleType.FIXED_WING),
        (Autopilot.PX4, VehicleType.MULTIROTOR),
    ],
)
def test_identifies_the_vehicle(autopilot: Autopilot, vehicle_type: VehicleType) -> None:
    with (
        SimulatedVehicle(autopilot=autopilot, vehicle_type=vehicle_type, system_id=7) as vehicle,
        Link.open(vehicle.url_for_client, heartbeat_timeout_s=5.0) as link,
    ):
        assert link.autopilot is autopilot
        assert link.vehicle_type is vehicle_type
        assert (link.target_system, link.target_component) == (7, 1)
        assert link.last_heartbeat_s is not None
    assert link.closed


def test_udp_link_to_the_vehicle() -> None:
    # the vehicle listens (udpin); we send first (udpout), so it learns where to answer
    clock = VirtualClock()
    with SimulatedVehicle(url="udpin://127.0.0.1:0", autopilot=Autopilot.PX4, clock=clock) as vehicle:
        url = vehicle.url_for_client
        assert url.startswith("udpout://")
        with Link.open(url, heartbeat_timeout_s=5.0, clock=clock) as link:
            assert link.autopilot is Autopilot.PX4
            assert link.recv({"HEARTBEAT"}, timeout_s=3.0) is not None


def test_udpin_link_hears_a_vehicle_that_sends_to_us() -> None:
    port = free_port(socket.SOCK_DGRAM)
    clock = VirtualClock()
    with (
        SimulatedVehicle(url=f"udpout://127.0.0.1:{port}", autopilot=Autopilot.ARDUPILOT, clock=clock),
        Link.open(f"udpin://127.0.0.1:{port}", heartbeat_timeout_s=5.0, clock=clock) as link,
    ):
        assert link.autopilot is Autopilot.ARDUPILOT
        assert link.target_system == 1


def test_sends_gcs_heartbeats_while_open() -> None:
    # on simulated time: the link's heartbeat thread and the vehicle wait on the same clock
    clock = VirtualClock()
    with SimulatedVehicle(autopilot=Autopilot.PX4, clock=clock) as vehicle:
        with Link.open(vehicle.url_for_client, heartbeat_timeout_s=5.0, clock=clock):
            opened = clock.monotonic()
            clock.sleep(2.5)
            during = vehicle.received_counts.get("HEARTBEAT", 0)
        assert clock.monotonic() - opened == 2.5
        clock.sleep(3.0)
        after = vehicle.received_counts.get("HEARTBEAT", 0)
    assert during == 3  # one at open, then one a second, at 1 s and 2 s
    assert after == during  # the thread stopped with the link


def test_link_drop_is_reported() -> None:
    vehicle = SimulatedVehicle(autopilot=Autopilot.ARDUPILOT)
    vehicle.start()
    try:
        link = Link.open(vehicle.url_for_client, heartbeat_timeout_s=5.0)
    except BaseException:
        vehicle.stop()
        raise
    with link:
        vehicle.stop()
        with pytest.raises(LinkError) as caught:
            link.recv({"MISSION_COUNT"}, timeout_s=3.0)
        assert "dropped" in str(caught.value)
        assert link.url in str(caught.value)


# --- signing -----------------------------------------------------------------------------------

KEY = hashlib.sha256(b"sfap test key").digest()


@contextmanager
def signing_vehicle(key: bytes | None) -> Iterator[tuple[str, list[object]]]:
    """A pymavlink endpoint acting as an autopilot that signs with ``key`` (None: unsigned).

    Yields its URL and the list of messages it received (to check ours were signed)."""
    port = free_port()
    conn = mavutil.mavlink_connection(f"tcpin:127.0.0.1:{port}", source_system=1, source_component=1)
    conn.mav = mavlink2.MAVLink(conn, srcSystem=1, srcComponent=1)
    conn.mav.robust_parsing = True
    # or mavutil swaps in a fresh, unsigned parser on the first MAVLink 2 byte it receives
    conn.WIRE_PROTOCOL_VERSION = "2.0"
    conn.first_byte = False
    if key is not None:
        conn.setup_signing(key, sign_outgoing=True, allow_unsigned_callback=lambda m, i: True)
    received: list[object] = []
    stop = threading.Event()

    def run() -> None:
        last = 0.0
        while not stop.is_set():
            message = conn.recv_msg()
            if message is not None:
                if message.get_type() != "BAD_DATA":
                    received.append(message)
                continue
            if time.monotonic() - last > 0.1:
                last = time.monotonic()
                conn.mav.send(mavlink2.MAVLink_heartbeat_message(2, 3, 0, 0, 3, 3))
            conn.select(0.02)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{port}", received
    finally:
        stop.set()
        thread.join()
        conn.close()


def test_signed_link_signs_and_accepts_signed() -> None:
    with signing_vehicle(KEY) as (url, received):
        with Link.open(url, heartbeat_timeout_s=3.0, signing_key=KEY, require_signing=True) as link:
            assert link.autopilot is Autopilot.ARDUPILOT
            deadline = time.monotonic() + 2.0
            while not received and time.monotonic() < deadline:
                time.sleep(0.05)
        heartbeats = [m for m in received if m.get_type() == "HEARTBEAT"]  # type: ignore[attr-defined]
        assert heartbeats
        assert all(m.get_signed() for m in heartbeats)  # type: ignore[attr-defined]


@pytest.mark.parametrize("vehicle_key", [None, hashlib.sha256(b"another key").digest()])
def test_require_signing_refuses_unsigned_and_wrongly_signed(vehicle_key: bytes | None) -> None:
    with signing_vehicle(vehicle_key) as (url, _), pytest.raises(LinkError) as caught:
        Link.open(url, heartbeat_timeout_s=0.6, signing_key=KEY, require_signing=True)
    message = str(caught.value)
    assert "refused because signing is required" in message
    assert url in message


def test_signing_not_required_accepts_unsigned_vehicle() -> None:
    with (
        signing_vehicle(None) as (url, _),
        Link.open(url, heartbeat_timeout_s=3.0, signing_key=KEY) as link,
    ):
        assert link.signing


def test_require_signing_needs_a_key() -> None:
    with pytest.raises(LinkError, match="needs a key"):
        Link.open("tcp://127.0.0.1:5760", require_signing=True)


def test_signing_key_forms(tmp_path: Path) -> None:
    raw = bytes(range(200, 232))
    (tmp_path / "raw.key").write_bytes(raw)
    (tmp_path / "hex.key").write_text(raw.hex().upper() + "\n")
    (tmp_path / "phrase.key").write_text("correct horse battery staple\n")
    assert load_signing_key(tmp_path / "raw.key") == raw
    assert load_signing_key(tmp_path / "hex.key") == raw
    # MAVProxy: key = SHA-256 of the passphrase
    expected = hashlib.sha256(b"correct horse battery staple").digest()
    assert load_signing_key(tmp_path / "phrase.key") == expected
    assert load_signing_key(None, environ={"SFAP_SIGNING_KEY": raw.hex()}) == raw
    assert load_signing_key(None, environ={"SFAP_SIGNING_KEY": "correct horse battery staple"}) == (expected)
    assert load_signing_key(None, environ={}) is None


def test_signing_key_file_errors(tmp_path: Path) -> None:
    with pytest.raises(LinkError, match="cannot read the signing key file"):
        load_signing_key(tmp_path / "missing.key")
    (tmp_path / "empty.key").write_text("  \n")
    with pytest.raises(LinkError, match="empty"):
        load_signing_key(tmp_path / "empty.key")
    with pytest.raises(LinkError, match="32 bytes"):
        Link.open("tcp://127.0.0.1:1", signing_key=b"short")


# --- the on_message observer --------------------------------------------------------------------


class Sender:
    """Packs messages as one MAVLink sender (system, component) does, numbering them in turn."""

    def __init__(self, system: int, component: int, seq: int = 0) -> None:
        self.mav = mavlink2.MAVLink(None, srcSystem=system, srcComponent=component)
        self.mav.seq = seq

    def __call__(self, msg: Any) -> bytes:
        data = bytes(msg.pack(self.mav))
        self.mav.seq = (self.mav.seq + 1) % 256
        return data


@contextmanager
def scripted_vehicle(packets: list[bytes]) -> Iterator[str]:
    """A TCP peer that sends ``packets`` in one burst to the first client, then stays open."""
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    stop = threading.Event()

    def serve() -> None:
        server.settimeout(5.0)
        try:
            peer, _ = server.accept()
        except OSError:
            return
        with peer:
            peer.sendall(b"".join(packets))
            stop.wait(10.0)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join()
        server.close()


def traffic_with_a_second_system() -> tuple[list[bytes], int]:
    """Packets of a vehicle (1/1), its camera (1/100), a second vehicle (2/1) and a gimbal
    (2/154), some addressed to another ground station (254); and how many come before and
    including the vehicle's heartbeat."""
    vehicle, camera, other, gimbal = Sender(1, 1, 17), Sender(1, 100), Sender(2, 1, 200), Sender(2, 154)
    ack_to_other_gcs = mavlink2.MAVLink_command_ack_message(400, 0, 0, 0, 254, 190)
    packets = [
        other(mavlink2.MAVLink_system_time_message(1_763_800_000_000_000, 1000)),
        # a generic-autopilot heartbeat of another system: not the vehicle
        gimbal(mavlink2.MAVLink_heartbeat_message(26, 0, 0, 0, 4, 3)),
        vehicle(mavlink2.MAVLink_system_time_message(1_763_800_000_500_000, 2000)),
        vehicle(mavlink2.MAVLink_heartbeat_message(2, 3, 1, 3, 4, 3)),
        vehicle(ack_to_other_gcs),
        other(mavlink2.MAVLink_heartbeat_message(2, 3, 1, 3, 4, 3)),
        camera(mavlink2.MAVLink_heartbeat_message(30, 8, 0, 0, 4, 3)),
        vehicle(mavlink2.MAVLink_statustext_message(6, b"for us")),
    ]
    return packets, 4


def test_on_message_sees_every_message_before_filtering_from_the_heartbeat_wait_on() -> None:
    packets, until_heartbeat = traffic_with_a_second_system()
    seen: list[tuple[Any, float]] = []
    before = time.time()
    with scripted_vehicle(packets) as url:
        with Link.open(url, heartbeat_timeout_s=5.0, on_message=lambda m, t: seen.append((m, t))) as link:
            assert (link.target_system, link.target_component) == (1, 1)
            # what the heartbeat wait read, up to and including the vehicle's heartbeat
            assert [m.get_msgbuf() for m, _ in seen] == packets[:until_heartbeat]
            # recv still hands back only what is for us, from the vehicle
            mine = link.recv(None, timeout_s=2.0, all_components=False)
            assert mine is not None and mine.get_type() == "STATUSTEXT" and mine.text == "for us"
            assert link.recv(None, timeout_s=0.3, all_components=True) is None
        after = time.time()
    assert [bytes(m.get_msgbuf()) for m, _ in seen] == packets  # every one, in arrival order
    senders = {(m.get_srcSystem(), m.get_srcComponent()) for m, _ in seen}
    assert senders == {(1, 1), (1, 100), (2, 1), (2, 154)}
    times = [t for _, t in seen]
    assert all(before <= t <= after for t in times) and times == sorted(times)


def test_what_the_observer_raises_reaches_the_caller_of_open() -> None:
    packets, _ = traffic_with_a_second_system()

    def refuse(message: Any, rx_time_utc_s: float) -> None:
        raise OSError(28, "No space left on device")

    with scripted_vehicle(packets) as url, pytest.raises(OSError, match="No space left"):
        Link.open(url, heartbeat_timeout_s=5.0, on_message=refuse)


def test_without_observer_recv_filters_as_before() -> None:
    packets, _ = traffic_with_a_second_system()
    with scripted_vehicle(packets) as url, Link.open(url, heartbeat_timeout_s=5.0) as link:
        got = []
        while (message := link.recv(None, timeout_s=0.5, all_components=True)) is not None:
            got.append((message.get_srcSystem(), message.get_srcComponent(), message.get_type()))
    assert got == [(1, 100, "HEARTBEAT"), (1, 1, "STATUSTEXT")]
