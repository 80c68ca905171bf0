"""Tests of acquisition.clock: simulated time is honest.

A virtual clock may only jump when every party waits and no byte is in flight to any of them,
and then only to the earliest deadline: timeouts fire at exactly the simulated second they name,
never while a party still computes or has a message to read. The last tests hold the simulated
vehicle's protocol timers to the seconds they are configured with, read off the virtual clock.
"""

from __future__ import annotations

import itertools
import socket
import threading
import time
from collections.abc import Callable

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from acquisition.clock import WALL_CLOCK, VirtualClock
from acquisition.link import Link
from acquisition.simulator.server import SimulatedVehicle
from planner.mission import Autopilot


def run_party(clock: VirtualClock, body: Callable[[], object], *, start: bool = True) -> threading.Thread:
    """``body()`` in a thread that is a party from before it starts (started unless ``start``
    is False)."""

    def main() -> None:
        try:
            body()
        finally:
            clock.leave(token)

    thread = threading.Thread(target=main, daemon=True)
    token = clock.join(thread)
    if start:
        thread.start()
    return thread


def test_deadlines_fire_in_order_at_their_simulated_time_without_the_wait() -> None:
    clock = VirtualClock(start_s=100.0)
    woke: dict[str, float] = {}

    def sleeper(name: str, wait_s: float) -> Callable[[], None]:
        def body() -> None:
            clock.sleep(wait_s)
            woke[name] = clock.monotonic()

        return body

    waits = (("a", 30.0), ("b", 5.0), ("c", 3600.0))
    threads = [run_party(clock, sleeper(name, wait_s), start=False) for name, wait_s in waits]
    started = time.monotonic()
    for thread in threads:  # each is a party already: time waits until all three wait
        thread.start()
    for thread in threads:
        thread.join(10.0)
    assert woke == {"b": 105.0, "a": 130.0, "c": 3700.0}
    assert time.monotonic() - started < 5.0  # an hour of simulated time, not of waiting


def test_time_stands_still_while_a_party_computes() -> None:
    clock = VirtualClock(start_s=0.0)
    busy = threading.Event()
    release = threading.Event()
    seen: list[float] = []

    def computing() -> None:
        busy.set()
        release.wait(10.0)  # computing: not a wait on the clock
        seen.append(clock.monotonic())
        clock.sleep(1.0)

    def waiting() -> None:
        clock.sleep(0.5)
        seen.append(clock.monotonic())

    first = run_party(clock, computing)
    assert busy.wait(5.0)
    second = run_party(clock, waiting)
    time.sleep(0.3)  # real time passes; simulated time must not
    assert clock.monotonic() == 0.0 and seen == []
    release.set()
    first.join(5.0)
    second.join(5.0)
    assert seen == [0.0, 0.5]
    assert clock.monotonic() == 1.0


def test_a_byte_in_flight_is_read_before_time_moves() -> None:
    clock = VirtualClock(start_s=0.0)
    a, b = socket.socketpair()
    got: list[tuple[bool, float]] = []
    ready = threading.Event()

    def reader() -> None:
        ready.set()
        got.append((clock.wait_readable([b.fileno()], 5.0), clock.monotonic()))

    def writer() -> None:
        ready.wait(5.0)
        time.sleep(0.1)  # the reader is waiting by now
        a.send(b"x")
        clock.sleep(10.0)  # the writer waits; the reader has a byte to read

    threads = [run_party(clock, reader, start=False), run_party(clock, writer, start=False)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(10.0)
    assert got == [(True, 0.0)]
    assert clock.monotonic() == 10.0
    a.close()
    b.close()


def test_a_party_joined_before_it_starts_holds_time_while_it_starts() -> None:
    clock = VirtualClock(start_s=0.0)

    class Starting(threading.Thread):
        """A thread as it looks while it starts: it has an id, and is not alive yet."""

        @property
        def ident(self) -> int:
            return 12345

        def is_alive(self) -> bool:
            return False

    starting = Starting()
    clock.join(starting)
    waiting = run_party(clock, lambda: clock.sleep(1.0))
    time.sleep(0.3)  # real time passes (and the waiter looks again every 50 ms)
    assert clock.monotonic() == 0.0  # the party that is starting holds simulated time
    clock.leave(starting)
    waiting.join(5.0)
    assert clock.monotonic() == 1.0


def test_a_thread_that_is_not_a_party_follows_time_without_holding_it() -> None:
    clock = VirtualClock(start_s=0.0)
    go = threading.Event()
    woke: list[float] = []

    def party_body() -> None:
        go.wait(5.0)  # computing until this thread observes: time stands still
        clock.sleep(2.0)
        woke.append(clock.monotonic())

    party = run_party(clock, party_body)
    threading.Timer(0.2, go.set).start()
    clock.sleep(10.0)  # this thread only observes: the party's earlier deadline fires first
    party.join(5.0)
    assert woke == [2.0]
    assert clock.monotonic() == 10.0


def test_a_link_times_out_on_simulated_seconds() -> None:
    clock = VirtualClock(start_s=0.0)
    with (
        SimulatedVehicle(clock=clock) as vehicle,
        Link.open(vehicle.url_for_client, heartbeat_timeout_s=5.0, clock=clock) as link,
    ):
        opened = clock.monotonic()
        started = time.monotonic()
        assert link.recv({"MISSION_COUNT"}, timeout_s=30.0) is None  # nothing asked, nothing said
        assert opened + 30.0 <= clock.monotonic() < opened + 30.0 + 0.003
        assert time.monotonic() - started < 60.0
        # the vehicle's heartbeat comes at 1 Hz of simulated time, to the loop step (2 ms)
        assert link.recv({"HEARTBEAT"}, timeout_s=2.0) is not None
        first = clock.monotonic()
        assert link.recv({"HEARTBEAT"}, timeout_s=2.0) is not None
        assert abs(clock.monotonic() - first - 1.0) <= 0.003


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
def test_vehicle_rerequests_and_cancels_at_its_configured_seconds(autopilot: Autopilot) -> None:
    """A ground station that sends MISSION_COUNT and then nothing: the vehicle asks again every
    ``request_timeout_s`` and cancels after ``upload_timeout_s`` of silence, to the loop step
    (2 ms), on the simulated clock."""
    clock = VirtualClock(start_s=0.0)
    request = "MISSION_REQUEST" if autopilot is Autopilot.ARDUPILOT else "MISSION_REQUEST_INT"
    with (
        SimulatedVehicle(
            autopilot=autopilot, boot_delay_s=0.0, request_timeout_s=0.75, upload_timeout_s=4.0, clock=clock
        ) as vehicle,
        Link.open(vehicle.url_for_client, heartbeat_timeout_s=5.0, clock=clock) as link,
    ):
        link.send(mavlink2.MAVLink_mission_count_message(1, 1, 5, 0))
        sent_at = clock.monotonic()
        times: list[float] = []
        while True:
            message = link.recv({request, "MISSION_ACK"}, timeout_s=10.0)
            assert message is not None
            if message.get_type() == "MISSION_ACK":
                assert message.type == mavlink2.MAV_MISSION_OPERATION_CANCELLED
                cancelled = clock.monotonic() - sent_at
                break
            assert message.seq == 0
            times.append(clock.monotonic() - sent_at)
    gaps = [b - a for a, b in itertools.pairwise(times)]
    assert times[0] < 0.003  # the first request answers the count at once
    assert len(gaps) == 5 and all(0.75 < gap <= 0.75 + 0.003 for gap in gaps), gaps
    assert 4.0 < cancelled <= 4.0 + 0.003


def test_the_wall_clock_is_the_default() -> None:
    with SimulatedVehicle() as vehicle, Link.open(vehicle.url_for_client, heartbeat_timeout_s=5.0) as link:
        assert vehicle.clock is WALL_CLOCK and link.clock is WALL_CLOCK
