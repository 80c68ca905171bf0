"""Tests of the mission protocol (acquisition.transfer) and its adapter (acquisition.mavlink_items).

The peer is the simulated vehicle in both flavours (ArduPilot: legacy MISSION_REQUEST, home at
item 0, compressed storage; PX4: MISSION_REQUEST_INT, no home), with its injected link faults.
The oracle of every upload is the vehicle's own store (``stored_mission``), checked exactly,
not only our read-back. A TCP relay between ground station and vehicle drops the link mid-way or
alters an item in flight, as a bad radio or a buggy autopilot would.
"""

from __future__ import annotations

import math
import socket
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from acquisition.clock import WALL_CLOCK, VirtualClock
from acquisition.errors import TransferError
from acquisition.link import Link
from acquisition.mavlink_items import (
    MissionType,
    deg_to_e7,
    float32,
    from_mission_item,
    to_mission_item_int,
)
from acquisition.mission_protocol import TransferPhase
from acquisition.readback import verify_readback
from acquisition.simulator.faults import FaultConfig
from acquisition.simulator.server import SimulatedVehicle
from acquisition.transfer import clear_mission, download_mission, downloaded_mission, upload_mission
from acquisition.transfer_outcome import (
    MissionInterruptedError,
    MissionState,
    MissionTooLargeError,
    MissionTransferError,
    MissionVerificationError,
    describe_mission_result,
)
from planner.errors import MissionValidationError
from planner.mission import (
    Autopilot,
    HomePosition,
    MavCmd,
    MavFrame,
    Mission,
    MissionItem,
    VehicleType,
)

HOME = HomePosition(lat_deg=41.6488, lon_deg=-0.8891, alt_amsl_m=210.0)
FAST: dict[str, Any] = {"timeout_s": 0.2, "retries": 10, "no_space_wait_s": 0.1}


def survey_items(count: int, *, seed: int = 0, nan_params: bool = False) -> list[MissionItem]:
    """``count`` items like a planned survey: take-off, camera, waypoints with odd values, RTL.

    Coordinates are not on the degE7 grid and altitudes not on whole centimetres, so every
    rounding on the way shows up.
    """
    items: list[MissionItem] = [MissionItem.takeoff(HOME.lat_deg, HOME.lon_deg, 30.0)]
    if count >= 4:
        items.append(MissionItem.change_speed(7.25))
        items.append(MissionItem.cam_trigger_distance(23.456))
    if nan_params and count >= 5:
        items.append(MissionItem.gimbal_manager_pitch_yaw(-90.0, 0.0))
    i = 0
    while len(items) < count - (1 if count >= 3 else 0):
        lat = HOME.lat_deg + 0.000123456789 * (i + seed) % 0.01
        lon = HOME.lon_deg + 0.0000987654321 * ((i * 7 + seed) % 97)
        items.append(MissionItem.waypoint(lat, lon, 45.678 + 0.0317 * i, hold_s=(i % 3) * 1.5))
        i += 1
    if count >= 3:
        items.append(MissionItem.return_to_launch())
    assert len(items) == count
    return items


def mission_of(items: list[MissionItem], autopilot: Autopilot = Autopilot.ARDUPILOT) -> Mission:
    return Mission(items=tuple(items), home=HOME, autopilot=autopilot)


def vehicle(
    autopilot: Autopilot,
    faults: FaultConfig | None = None,
    vehicle_type: VehicleType = VehicleType.MULTIROTOR,
    **options: Any,
) -> SimulatedVehicle:
    options.setdefault("boot_delay_s", 0.0)
    options.setdefault("request_timeout_s", 0.1)  # the vehicle re-requests fast in tests
    options.setdefault("clock", VirtualClock())
    return SimulatedVehicle(autopilot=autopilot, faults=faults, vehicle_type=vehicle_type, **options)


def connect(sim: SimulatedVehicle) -> Link:
    """A link to ``sim`` on the vehicle's clock (simulated time unless it is the wall clock)."""
    return Link.open(sim.url_for_client, heartbeat_timeout_s=5.0, clock=sim.clock)


def assert_stored_exactly(sim: SimulatedVehicle, sent: list[MissionItem]) -> None:
    """The vehicle's own store (not our read-back) holds what was sent, by the storage rules."""
    stored = sim.stored_mission()
    assert verify_readback(sent, stored, sim.autopilot, sim.vehicle_type) == []
    body = stored[1:] if sim.autopilot is Autopilot.ARDUPILOT else stored
    assert len(body) == len(sent)
    for a, b in zip(sent, body, strict=True):
        assert a.command == b.command
        if a.frame.is_global and MavCmd(a.command).is_nav:
            assert (deg_to_e7(a.lat_deg), deg_to_e7(a.lon_deg)) == (
                deg_to_e7(b.lat_deg),
                deg_to_e7(b.lon_deg),
            )


# --- the adapter: MissionItem <-> MISSION_ITEM_INT ---------------------------------------------

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, width=32)
param = st.one_of(st.none(), finite)


@settings(max_examples=200, deadline=None)
@given(
    lat=st.floats(min_value=-90, max_value=90),
    lon=st.floats(min_value=-180, max_value=180),
    alt=finite,
    p=st.tuples(param, param, param, param),
    frame=st.sampled_from([MavFrame.GLOBAL, MavFrame.GLOBAL_RELATIVE_ALT, MavFrame.GLOBAL_TERRAIN_ALT]),
    autocontinue=st.booleans(),
)
def test_item_round_trip_through_pymavlink_wire(
    lat: float,
    lon: float,
    alt: float,
    p: tuple[float | None, ...],
    frame: MavFrame,
    autocontinue: bool,
) -> None:
    item = MissionItem(
        command=MavCmd.NAV_WAYPOINT,
        frame=frame,
        param1=p[0],
        param2=p[1],
        param3=p[2],
        param4=p[3],
        param5=lat,
        param6=lon,
        param7=alt,
        autocontinue=autocontinue,
    )
    message = to_mission_item_int(item, 5, 1, 1, MissionType.MISSION)
    # through real bytes: pack with one MAVLink object, parse with another
    wire = message.pack(mavlink2.MAVLink(None, srcSystem=255, srcComponent=190))
    parsed = mavlink2.MAVLink(None).parse_char(wire)
    assert parsed.get_type() == "MISSION_ITEM_INT"
    assert parsed.x == deg_to_e7(lat) and parsed.y == deg_to_e7(lon)
    back = from_mission_item(parsed)
    assert back.frame is frame
    assert abs(back.lat_deg - lat) <= 0.5e-7 + 1e-12
    assert abs(back.lon_deg - lon) <= 0.5e-7 + 1e-12
    assert deg_to_e7(back.lat_deg) == deg_to_e7(lat)
    assert back.alt_m == float32(alt)
    for sent, got in zip(p, back.params[:4], strict=True):
        assert (sent is None and got is None) or (sent is not None and got == float32(sent))
    assert back.autocontinue is autocontinue


def test_int_frames_sent_plain_and_read_plain() -> None:
    item = MissionItem(
        command=MavCmd.NAV_WAYPOINT,
        frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
        param5=1.0,
        param6=2.0,
        param7=3.0,
    )
    message = to_mission_item_int(item, 1, 1, 1)
    assert message.frame == MavFrame.GLOBAL_RELATIVE_ALT
    message.frame = int(MavFrame.GLOBAL_TERRAIN_ALT_INT)
    assert from_mission_item(message).frame is MavFrame.GLOBAL_TERRAIN_ALT


def test_legacy_mission_item_and_mission_frame() -> None:
    legacy = mavlink2.MAVLink_mission_item_message(
        255, 190, 3, 3, 16, 0, 1, 2.0, 0.0, 0.0, math.nan, 41.5, -0.75, 55.5, 0
    )
    item = from_mission_item(legacy)
    assert (item.lat_deg, item.lon_deg, item.alt_m, item.param4) == (41.5, -0.75, 55.5, None)
    do = MissionItem.cam_trigger_distance(20.0)
    message = to_mission_item_int(do, 2, 1, 1)
    assert (message.frame, message.x, message.y) == (int(MavFrame.MISSION), 0, 0)
    assert from_mission_item(message) == do
    with pytest.raises(ValueError, match="not a mission item"):
        from_mission_item(mavlink2.MAVLink_mission_count_message(1, 1, 3, 0))


# --- verification rules ----------------------------------------------------------------------


def replace(item: MissionItem, **changes: Any) -> MissionItem:
    from dataclasses import replace as dc_replace

    return dc_replace(item, **changes)


def ardupilot_home() -> MissionItem:
    return MissionItem(command=16, frame=MavFrame.GLOBAL, param1=0.0, param7=0.0)


def test_verify_accepts_ardupilot_copter_storage() -> None:
    sent = [
        MissionItem(
            command=MavCmd.NAV_WAYPOINT,
            param1=2.7,  # hold: Copter keeps whole seconds
            param2=3.0,  # acceptance radius: dropped
            param3=5.0,  # pass radius: dropped
            param4=90.0,  # yaw: dropped
            param5=41.12345678,
            param6=-0.98765432,
            param7=45.678,  # kept in centimetres
        ),
        MissionItem.return_to_launch(),
    ]
    stored = [
        ardupilot_home(),
        replace(
            sent[0],
            frame=MavFrame.GLOBAL_RELATIVE_ALT,
            param1=2.0,
            param2=0.0,
            param3=0.0,
            param4=0.0,
            param7=float32(45.67),
        ),
        replace(sent[1], frame=MavFrame.GLOBAL),  # RTL reads back as frame 0
    ]
    assert verify_readback(sent, stored, Autopilot.ARDUPILOT, VehicleType.MULTIROTOR) == []
    # the same read-back from PX4 would be full of real differences
    found = verify_readback(sent, stored[1:], Autopilot.PX4, VehicleType.MULTIROTOR)
    assert {d.field for d in found} == {"param 1", "param 2", "param 4", "altitude (m)", "frame"}


def test_verify_accepts_ardupilot_plane_storage_and_catches_copter_rules() -> None:
    sent = [
        MissionItem(
            command=MavCmd.NAV_WAYPOINT,
            param1=4.0,
            param2=30.6,
            param3=400.0,
            param5=41.1,
            param6=-0.9,
        )
    ]
    plane_stored = [ardupilot_home(), replace(sent[0], param1=0.0, param2=30.0, param3=255.0)]
    assert verify_readback(sent, plane_stored, Autopilot.ARDUPILOT, VehicleType.FIXED_WING) == []
    # what Plane does is wrong for a Copter: hold time lost, radii kept where Copter drops them
    found = verify_readback(sent, plane_stored, Autopilot.ARDUPILOT, VehicleType.MULTIROTOR)
    assert [d.field for d in found] == ["param 1", "param 2", "param 3"]


@pytest.mark.parametrize(
    ("change", "field"),
    [
        ({"param5": 41.1 + 1e-7}, "latitude (degE7)"),  # one degE7 unit, 1.1 cm
        ({"param6": -0.9 - 1e-7}, "longitude (degE7)"),
        ({"param7": 45.7 + 0.02}, "altitude (m)"),  # beyond the centimetre storage
        ({"frame": MavFrame.GLOBAL}, "frame"),  # AMSL instead of above home
        ({"command": MavCmd.NAV_LOITER_UNLIM}, "command"),
        ({"param1": 5.0}, "param 1"),  # hold 5 s instead of 2
    ],
)
@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
def test_verify_catches_every_real_difference(
    change: dict[str, Any], field: str, autopilot: Autopilot
) -> None:
    sent = [MissionItem.waypoint(41.1, -0.9, 45.7, hold_s=2.0), MissionItem.return_to_launch()]
    received = [replace(sent[0], **change), sent[1]]
    if autopilot is Autopilot.ARDUPILOT:
        received = [ardupilot_home(), *received]
    found = verify_readback(sent, received, autopilot, VehicleType.MULTIROTOR)
    assert [d.field for d in found] == [field]
    assert found[0].index == 1
    assert found[0].seq == (1 if autopilot is Autopilot.ARDUPILOT else 0)
    assert "item 1 (NAV_WAYPOINT" in found[0].describe()


def test_verify_float32_precision_and_missing_items() -> None:
    sent = [MissionItem.cam_trigger_distance(23.456)]
    same32 = [replace(sent[0], param1=float32(23.456))]
    assert verify_readback(sent, same32, Autopilot.PX4, None) == []
    next32 = [replace(sent[0], param1=float(math.nextafter(float32(23.456), 100.0)) + 1e-6)]
    assert [d.field for d in verify_readback(sent, next32, Autopilot.PX4, None)] == ["param 1"]
    nan_sent = [MissionItem.gimbal_manager_pitch_yaw(-90.0, 0.0)]
    assert verify_readback(nan_sent, nan_sent, Autopilot.PX4, None) == []
    zero_for_nan = [replace(nan_sent[0], param3=0.0)]
    assert [d.field for d in verify_readback(nan_sent, zero_for_nan, Autopilot.PX4, None)] == ["param 3"]
    found = verify_readback(sent * 3, [ardupilot_home(), *sent], Autopilot.ARDUPILOT, None)
    assert found[0].field == "number of items" and (found[0].sent, found[0].received) == ("3", "1")
    assert verify_readback(sent, [], Autopilot.ARDUPILOT, None)[0].field == "home item"


def test_every_mission_result_is_a_sentence() -> None:
    sentences = {code: describe_mission_result(code) for code in range(16)}
    assert len(set(sentences.values())) == 16
    for code, sentence in sentences.items():
        assert sentence.startswith("the vehicle")
        name = [n for n in dir(mavlink2) if n.startswith("MAV_MISSION_") and getattr(mavlink2, n) == code]
        assert any(n in sentence for n in name), (code, sentence)
    assert "unknown" in describe_mission_result(99)


# --- against the simulated vehicle --------------------------------------------------------------


def run_round_trip(
    sim: SimulatedVehicle,
    items: list[MissionItem],
    *,
    full: bool = True,
    download: bool = True,
    **options: Any,
) -> list[MissionItem]:
    """Upload (verified) and check the vehicle's store; with ``full`` also clear (and with
    ``download`` download first). The link runs on the vehicle's clock.

    Returns what the vehicle stored after the upload."""
    progress: list[tuple[TransferPhase, int, int]] = []
    settings = {**FAST, **options}
    with connect(sim) as link:
        result = upload_mission(
            link,
            mission_of(items, sim.autopilot),
            progress=lambda *a: progress.append(a),
            **settings,
        )
        assert result.verified and result.state is MissionState.REPLACED_VERIFIED
        assert result.items == len(items)
        stored = sim.stored_mission()
        assert_stored_exactly(sim, items)
        uploads = [p for p in progress if p[0] is TransferPhase.UPLOAD]
        assert [p[1] for p in uploads] == list(range(1, result.items_sent + 1))
        assert progress[-1][0] is TransferPhase.VERIFY and progress[-1][1] == progress[-1][2]
        if not full:
            return stored
        timing = {k: v for k, v in settings.items() if k in ("timeout_s", "retries")}
        if download:  # (the verification above was a download already)
            assert download_mission(link, **timing) == stored
        assert clear_mission(link, **timing) is MissionState.CLEARED
        remaining = download_mission(link, **timing)
        assert len(remaining) == (1 if sim.autopilot is Autopilot.ARDUPILOT else 0)
    return stored


# Faulty links: short timers on both sides (the loopback answers in milliseconds), many retries.
LOSSY: dict[str, Any] = {"timeout_s": 0.03, "retries": 30}
LOSSY_VEHICLE: dict[str, Any] = {"request_timeout_s": 0.03}
FAULTS = {
    "loss10": FaultConfig(loss_pct=10.0, seed=1),
    "loss30": FaultConfig(loss_pct=30.0, seed=2),
    "dup30": FaultConfig(duplicate_pct=30.0, seed=3),
    "reorder30": FaultConfig(reorder_pct=30.0, seed=4),
    "mixed": FaultConfig(loss_pct=10.0, duplicate_pct=10.0, reorder_pct=10.0, latency_s=0.005, seed=5),
}


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
@pytest.mark.parametrize("count", [1, 50])
def test_clean_link(autopilot: Autopilot, count: int) -> None:
    with vehicle(autopilot) as sim:
        run_round_trip(sim, survey_items(count, nan_params=autopilot is Autopilot.PX4))


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
def test_clean_link_700_items(autopilot: Autopilot) -> None:
    with vehicle(autopilot) as sim:
        run_round_trip(sim, survey_items(700), full=False)


#: The faulty-link case that also runs on the wall clock (every other one runs on simulated
#: time, where the same timeouts fire without the wait): all the faults at once, latency included.
REAL_TIME_CASE = ("mixed", Autopilot.ARDUPILOT)


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
@pytest.mark.parametrize("fault", list(FAULTS))
def test_faulty_link_50_items(autopilot: Autopilot, fault: str) -> None:
    clock = WALL_CLOCK if (fault, autopilot) == REAL_TIME_CASE else VirtualClock()
    with vehicle(autopilot, FAULTS[fault], clock=clock, **LOSSY_VEHICLE) as sim:
        run_round_trip(sim, survey_items(50, seed=FAULTS[fault].seed), download=False, **LOSSY)


@pytest.mark.slow
@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
@pytest.mark.parametrize("fault", list(FAULTS))
def test_faulty_link_700_items(autopilot: Autopilot, fault: str) -> None:
    with vehicle(autopilot, FAULTS[fault], **LOSSY_VEHICLE) as sim:
        run_round_trip(sim, survey_items(700, seed=FAULTS[fault].seed), full=False, **LOSSY)


def test_fixed_wing_storage_is_verified() -> None:
    items = [
        MissionItem.takeoff(HOME.lat_deg, HOME.lon_deg, 40.0),
        MissionItem(
            command=MavCmd.NAV_WAYPOINT,
            param1=3.0,
            param2=25.5,
            param3=300.0,
            param5=41.65,
            param6=-0.88,
            param7=80.0,
        ),
        MissionItem.return_to_launch(),
    ]
    with vehicle(Autopilot.ARDUPILOT, vehicle_type=VehicleType.FIXED_WING) as sim:
        stored = run_round_trip(sim, items)
    assert (stored[2].param1, stored[2].param2, stored[2].param3) == (0.0, 25.0, 255.0)


def test_ardupilot_no_space_after_boot_is_retried() -> None:
    """On simulated time (the vehicle's VirtualClock), with the boot window opened when the
    link is up: however long the machine takes to get there, the first MISSION_COUNT falls
    0.6 simulated seconds before the window closes, and 5 retries 0.3 s apart outlast it
    (it failed under load when the 0.6 s ran on the wall clock, issue 24)."""
    with vehicle(Autopilot.ARDUPILOT, boot_delay_s=math.inf) as sim:
        with connect(sim) as link:
            with sim.lock:  # the window closes 0.6 simulated seconds from now
                sim.boot_delay_s = sim.flight.time_s + 0.6
            settings = {**FAST, "no_space_wait_s": 0.3, "no_space_retries": 5}
            result = upload_mission(link, mission_of(survey_items(10)), **settings)
        refusals = [note for note in result.notes if "NO_SPACE" in note]
        assert 1 <= len(refusals) <= 3  # 0.6 s of refusals, 0.3 s apart
        assert sim.received_counts["MISSION_COUNT"] == len(refusals) + 1
        assert_stored_exactly(sim, survey_items(10))


def _mission_items(sim: SimulatedVehicle) -> list[MissionItem]:
    """The vehicle's stored mission without ArduPilot's home (item 0): home is the vehicle's own,
    set at its GPS fix, which may come during an upload attempt (comparing it made the tests of a
    refused upload fail under load)."""
    stored = sim.stored_mission()
    return stored[1:] if sim.autopilot is Autopilot.ARDUPILOT else stored


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
def test_vehicle_without_room_refuses(autopilot: Autopilot) -> None:
    with vehicle(autopilot, FaultConfig(refuse="no_space")) as sim:
        sim.load_mission(survey_items(5))
        before = _mission_items(sim)
        with (
            connect(sim) as link,
            pytest.raises(MissionTransferError) as caught,
        ):
            upload_mission(link, mission_of(survey_items(20)), **{**FAST, "no_space_retries": 1})
        assert _mission_items(sim) == before
    error = caught.value
    assert error.mission_state is MissionState.UNCHANGED
    if autopilot is Autopilot.ARDUPILOT:  # "Only 724 items": room enough, so a boot refusal
        assert "no room" in str(error) and "NO_SPACE" in str(error)
    else:  # PX4 refuses only what it cannot hold
        assert isinstance(error, MissionTooLargeError) and "NO_SPACE" in str(error)
    assert "mission is unchanged" in str(error)


@pytest.mark.parametrize(
    ("autopilot", "state"),
    [(Autopilot.ARDUPILOT, MissionState.PARTIAL), (Autopilot.PX4, MissionState.UNCHANGED)],
)
def test_vehicle_refusing_an_item(autopilot: Autopilot, state: MissionState) -> None:
    old = survey_items(8, seed=3)
    new = survey_items(30)
    with vehicle(autopilot, FaultConfig(refuse="invalid")) as sim:
        sim.load_mission(old)
        with (
            connect(sim) as link,
            pytest.raises(MissionTransferError) as caught,
        ):
            upload_mission(link, mission_of(new), **FAST)
        stored = sim.stored_mission()
    assert caught.value.mission_state is state
    assert "invalid (MAV_MISSION_INVALID)" in str(caught.value)
    assert state.sentence in str(caught.value)
    if autopilot is Autopilot.PX4:
        assert verify_readback(old, stored, autopilot, VehicleType.MULTIROTOR) == []
    else:
        assert verify_readback(new, stored, autopilot, VehicleType.MULTIROTOR) != []
        assert verify_readback(old, stored, autopilot, VehicleType.MULTIROTOR) != []


def test_invalid_mission_is_not_sent() -> None:
    bad = [MissionItem.waypoint(95.0, 0.5, 50.0), MissionItem.waypoint(41.0, 0.5, 500.0)]
    with vehicle(Autopilot.PX4) as sim:
        with (
            connect(sim) as link,
            pytest.raises(MissionValidationError) as caught,
        ):
            upload_mission(link, mission_of(bad), max_alt_rel_home_m=120.0, **FAST)
        assert "MISSION_COUNT" not in sim.received_counts
    assert "item 1" in str(caught.value) and "item 2" in str(caught.value)
    assert "unchanged" in str(caught.value)


def test_nan_that_ardupilot_refuses_is_caught_before_sending() -> None:
    items = [
        MissionItem.takeoff(HOME.lat_deg, HOME.lon_deg, 30.0),
        MissionItem.gimbal_manager_pitch_yaw(-90, 0),
    ]
    with vehicle(Autopilot.ARDUPILOT) as sim:
        with (
            connect(sim) as link,
            pytest.raises(MissionValidationError, match="param 3 is empty"),
        ):
            upload_mission(link, mission_of(items), **FAST)
        assert "MISSION_COUNT" not in sim.received_counts


def test_corrupted_store_fails_verification() -> None:
    items = survey_items(12)
    with (
        vehicle(Autopilot.ARDUPILOT) as sim,
        connect(sim) as link,
    ):
        upload_mission(link, mission_of(items), **FAST)
        sim.corrupt_stored_item(5, param5=items[4].lat_deg + 1e-7)
        received = download_mission(link, timeout_s=0.2)
    found = verify_readback(items, received, Autopilot.ARDUPILOT, VehicleType.MULTIROTOR)
    assert [(d.index, d.field) for d in found] == [(5, "latitude (degE7)")]


# --- a relay between ground station and vehicle ------------------------------------------------


@contextmanager
def relay(
    upstream_url: str,
    *,
    alter: Callable[[Any], Any] | None = None,
    cut_after_items: int | None = None,
) -> Iterator[str]:
    """A TCP relay to the vehicle. ``alter`` may change (or drop: None) messages from the
    ground station;
    ``cut_after_items`` closes both connections after that many MISSION_ITEM_INT."""
    host, port = upstream_url.removeprefix("tcp://").split(":")
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    stop = threading.Event()

    def pump(src: socket.socket, dst: socket.socket, from_gcs: bool, state: dict[str, int]) -> None:
        parser = mavlink2.MAVLink(None)
        parser.robust_parsing = True
        packer = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
        try:
            while not stop.is_set():
                data = src.recv(4096)
                if not data:
                    break
                if not from_gcs:
                    dst.sendall(data)
                    continue
                for message in parser.parse_buffer(data) or []:
                    if message.get_type() == "MISSION_ITEM_INT":
                        state["items"] += 1
                        if cut_after_items is not None and state["items"] > cut_after_items:
                            stop.set()
                            break
                    if alter is not None:
                        changed = alter(message)
                        if changed is None:
                            continue
                        if changed is not message:
                            dst.sendall(changed.pack(packer))
                            continue
                    dst.sendall(bytes(message.get_msgbuf()))
        except OSError:
            pass
        finally:
            stop.set()
            for s in (src, dst):
                with suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)

    def serve() -> None:
        gcs, _ = server.accept()
        upstream = socket.create_connection((host, int(port)))
        state = {"items": 0}
        threads = [
            threading.Thread(target=pump, args=(gcs, upstream, True, state), daemon=True),
            threading.Thread(target=pump, args=(upstream, gcs, False, state), daemon=True),
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        gcs.close()
        upstream.close()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        server.close()


@pytest.mark.parametrize(
    ("autopilot", "state"),
    [(Autopilot.ARDUPILOT, MissionState.PARTIAL), (Autopilot.PX4, MissionState.UNCHANGED)],
)
def test_link_drops_mid_transfer(autopilot: Autopilot, state: MissionState) -> None:
    old = survey_items(6, seed=9)
    with vehicle(autopilot, clock=WALL_CLOCK) as sim:
        sim.load_mission(old)
        with (
            relay(sim.url_for_client, cut_after_items=20) as url,
            Link.open(url, heartbeat_timeout_s=5.0) as link,
            pytest.raises(MissionTransferError) as caught,
        ):
            upload_mission(link, mission_of(survey_items(60)), **FAST)
        stored = sim.stored_mission()
    message = str(caught.value)
    assert caught.value.mission_state is state
    assert "dropped" in message and url in message
    assert state.sentence in message
    if autopilot is Autopilot.PX4:
        assert verify_readback(old, stored, autopilot, VehicleType.MULTIROTOR) == []


def test_item_altered_in_flight_fails_verification() -> None:
    """A vehicle that stores something else than it was sent: the read-back must say so."""
    items = survey_items(20)

    def alter(message: Any) -> Any:
        if message.get_type() == "MISSION_ITEM_INT" and message.seq == 7:
            return mavlink2.MAVLink_mission_item_int_message(
                message.target_system,
                message.target_component,
                message.seq,
                message.frame,
                message.command,
                message.current,
                message.autocontinue,
                message.param1,
                message.param2,
                message.param3,
                message.param4,
                message.x + 3,
                message.y,
                message.z,
                message.mission_type,
            )
        return message

    with (
        vehicle(Autopilot.PX4, clock=WALL_CLOCK) as sim,
        relay(sim.url_for_client, alter=alter) as url,
        Link.open(url, heartbeat_timeout_s=5.0) as link,
        pytest.raises(MissionVerificationError) as caught,
    ):
        upload_mission(link, mission_of(items), **FAST)
    result = caught.value.result
    assert not result.verified and result.state is MissionState.REPLACED_DIFFERS
    assert [(d.index, d.field) for d in result.differences] == [(8, "latitude (degE7)")]
    assert "item 8 (NAV_WAYPOINT" in str(caught.value)
    assert "DIFFERS" in str(caught.value)


def test_fence_is_kept_apart_from_the_mission() -> None:
    fence = [
        MissionItem(command=5001, frame=MavFrame.GLOBAL, param1=3.0, param5=lat, param6=lon)
        for lat, lon in [(41.64, -0.89), (41.65, -0.89), (41.65, -0.88)]
    ]
    items = survey_items(10)
    with (
        vehicle(Autopilot.ARDUPILOT) as sim,
        connect(sim) as link,
    ):
        upload_mission(link, mission_of(items), **FAST)
        result = upload_mission(link, mission_of(fence), mission_type=MissionType.FENCE, **FAST)
        assert result.verified and result.items_sent == 3  # no home item in a fence
        got = download_mission(link, mission_type=MissionType.FENCE, timeout_s=0.2)
        assert [deg_to_e7(i.lat_deg) for i in got] == [deg_to_e7(i.lat_deg) for i in fence]
        assert len(download_mission(link, timeout_s=0.2)) == len(items) + 1


def test_downloaded_mission_takes_ardupilot_home() -> None:
    items = survey_items(5)
    with vehicle(Autopilot.ARDUPILOT, gps_fix_s=0.0) as sim:
        sim.load_mission(items)
        with connect(sim) as link:
            got = download_mission(link, timeout_s=0.2)
    mission = downloaded_mission(got, Autopilot.ARDUPILOT, VehicleType.MULTIROTOR)
    assert len(mission.items) == 5
    assert deg_to_e7(mission.home.lat_deg) == deg_to_e7(HOME.lat_deg)
    assert verify_readback(items, got, Autopilot.ARDUPILOT, VehicleType.MULTIROTOR) == []


def test_download_from_vehicle_that_never_answers() -> None:
    def swallow_requests(message: Any) -> Any:
        return None if message.get_type() == "MISSION_REQUEST_LIST" else message

    with (
        vehicle(Autopilot.PX4, clock=WALL_CLOCK) as sim,
        relay(sim.url_for_client, alter=swallow_requests) as url,
        Link.open(url, heartbeat_timeout_s=5.0) as link,
        pytest.raises(TransferError) as caught,
    ):
        download_mission(link, timeout_s=0.1, retries=3)
    assert "no MISSION_COUNT after 4 requests 0.1 s apart" in str(caught.value)
    assert url in str(caught.value)


def test_verify_accepts_px4_storage() -> None:
    # What PX4 reads back (format_mavlink_mission_item): pass radius and take-off pitch not
    # kept, yaw wrapped to -180..180 degrees, INT frames.
    sent = [
        MissionItem(command=MavCmd.NAV_TAKEOFF, param1=15.0, param4=270.0, param5=41.1, param6=-0.9),
        MissionItem(
            command=MavCmd.NAV_WAYPOINT,
            param1=2.0,
            param2=3.0,
            param3=9.0,
            param5=41.2,
            param6=-0.9,
        ),
    ]
    received = [
        replace(sent[0], param1=0.0, param4=-90.0),
        replace(sent[1], param3=0.0),
    ]
    assert verify_readback(sent, received, Autopilot.PX4, VehicleType.FIXED_WING) == []
    turned = [replace(sent[0], param1=0.0, param4=-89.0), sent[1]]
    assert [d.field for d in verify_readback(sent, turned, Autopilot.PX4, None)] == ["param 4"]
    kept_hold = [received[0], replace(sent[1], param1=0.0, param3=0.0)]
    assert [d.field for d in verify_readback(sent, kept_hold, Autopilot.PX4, None)] == ["param 1"]


def test_mission_larger_than_the_vehicle_is_refused_at_once_with_the_excess() -> None:
    items = survey_items(40)
    with vehicle(Autopilot.ARDUPILOT, max_items=30) as sim:
        sim.load_mission(survey_items(5))
        before = _mission_items(sim)
        with (
            connect(sim) as link,
            pytest.raises(MissionTooLargeError) as caught,
        ):
            upload_mission(link, mission_of(items), **{**FAST, "no_space_wait_s": 2.0})
        # no retry as after boot: one MISSION_COUNT, and no pause of no_space_wait_s
        assert sim.received_counts.get("MISSION_COUNT") == 1
        assert _mission_items(sim) == before
    error = caught.value
    count = len(items) + 1  # ArduPilot: home is item 0
    assert (error.items, error.capacity) == (count, 30)
    assert f"{count} items (home included)" in str(error) and "at most 30" in str(error)
    assert f"{count - 30} too many" in str(error) and "sorties" in str(error)
    assert error.mission_state is MissionState.UNCHANGED
    # issue 22: "unchanged.. The vehicle's mission is unchanged."; said once, one full stop
    assert ".." not in str(error) and str(error).lower().count("mission is unchanged") == 1


@pytest.mark.parametrize(
    ("planned", "actual"), [(Autopilot.PX4, Autopilot.ARDUPILOT), (Autopilot.ARDUPILOT, Autopilot.PX4)]
)
def test_plan_made_for_the_other_autopilot_is_named_not_sent(planned: Autopilot, actual: Autopilot) -> None:
    items = [
        MissionItem.takeoff(HOME.lat_deg, HOME.lon_deg, 30.0),
        MissionItem.gimbal_manager_pitch_yaw(-90, 0),
    ]
    mission = Mission(
        items=tuple(items), home=HOME, autopilot=planned, metadata={"autopilot_from_file": True}
    )
    name = {Autopilot.PX4: "PX4", Autopilot.ARDUPILOT: "ArduPilot"}
    with vehicle(actual) as sim:
        with (
            connect(sim) as link,
            pytest.raises(MissionValidationError) as caught,
        ):
            upload_mission(link, mission, **FAST)
        assert "MISSION_COUNT" not in sim.received_counts
    text = str(caught.value)
    assert f"planned for {name[planned]}" in text and f"is {name[actual]}" in text
    assert f'autopilot = "{actual.value}"' in text and "NaN" not in text


def test_trigger_distance_truncated_to_whole_metres_fails_verification() -> None:
    sent = [MissionItem.cam_trigger_distance(11.06)]
    # what float32 storage gives back passes ...
    stored32 = [ardupilot_home(), replace(sent[0], param1=float32(11.06))]
    assert verify_readback(sent, stored32, Autopilot.ARDUPILOT, None) == []
    # ... a distance truncated to whole metres (Mission Planner's habit) does not
    truncated = [replace(sent[0], param1=11.0)]
    found = verify_readback(sent, [ardupilot_home(), *truncated], Autopilot.ARDUPILOT, VehicleType.MULTIROTOR)
    assert [(d.index, d.field, d.received) for d in found] == [(1, "param 1", "11")]
    # and end to end: a vehicle that stored the truncated distance is caught by the read-back
    items = [*survey_items(6), MissionItem.cam_trigger_distance(11.06)]
    with vehicle(Autopilot.ARDUPILOT) as sim, connect(sim) as link:
        upload_mission(link, mission_of(items), **FAST)
        sim.corrupt_stored_item(len(items), param1=11.0)
        received = download_mission(link, timeout_s=0.2)
    found = verify_readback(items, received, Autopilot.ARDUPILOT, VehicleType.MULTIROTOR)
    assert [(d.index, d.field) for d in found] == [(len(items), "param 1")]


@pytest.mark.parametrize(
    ("autopilot", "phase", "state"),
    [
        (Autopilot.ARDUPILOT, TransferPhase.UPLOAD, MissionState.PARTIAL),
        (Autopilot.PX4, TransferPhase.UPLOAD, MissionState.UNCHANGED),
        (Autopilot.ARDUPILOT, TransferPhase.VERIFY, MissionState.REPLACED_UNVERIFIED),
    ],
)
def test_ctrl_c_says_what_the_vehicle_now_holds(
    autopilot: Autopilot, phase: TransferPhase, state: MissionState
) -> None:
    """Issue 24: an upload interrupted with Ctrl-C said only "interrupted"."""
    old, new = survey_items(8, seed=3), survey_items(30)

    def interrupt(at: TransferPhase, done: int, total: int) -> None:
        if at is phase and done == 10:
            raise KeyboardInterrupt

    with vehicle(autopilot) as sim:
        sim.load_mission(old)
        with connect(sim) as link, pytest.raises(MissionInterruptedError) as caught:
            upload_mission(link, mission_of(new, autopilot), progress=interrupt, **FAST)
        stored = sim.stored_mission()
    error = caught.value
    assert error.mission_state is state and error.exit_code == 130
    assert "interrupted (Ctrl-C)" in str(error) and state.sentence in str(error)
    if phase is TransferPhase.UPLOAD:
        assert "after 10 of" in str(error)
    holds_old = verify_readback(old, stored, autopilot, VehicleType.MULTIROTOR) == []
    holds_new = verify_readback(new, stored, autopilot, VehicleType.MULTIROTOR) == []
    # what the vehicle really holds is what the message says
    assert (holds_old, holds_new) == {
        MissionState.PARTIAL: (False, False),
        MissionState.UNCHANGED: (True, False),
        MissionState.REPLACED_UNVERIFIED: (False, True),
    }[state]
