"""How ArduPilot stores each command sfap writes, from ArduPilot's own source, against the
simulated vehicle's store (acquisition/simulator/storage.py) and the read-back rules
(acquisition/readback.py).

The oracle is the source: libraries/AP_Mission/AP_Mission.cpp, AP_Mission::
mavlink_int_to_mission_cmd (the packing into a Mission_Command, ``uint16_t p1`` and the typed
Content structs of AP_Mission.h) and AP_Mission::mission_cmd_to_mavlink_int (the unpacking,
after ``packet.param1 = 0; ... packet.param4 = 0; packet.frame = 0; packet.autocontinue = 1;``).
Each case quotes the lines it derives its expected read-back from, by hand: the expected values
are written out, not computed by either implementation. The lines quoted for the commands sfap
writes read the same in the ArduPilot/ardupilot versions of AP_Mission.cpp read for this (one
from 2019, commit 473d131; one from the 4.4-4.5 era, with sanity_check_params and
DO_GIMBAL_MANAGER_PITCHYAW), except that the older one lacks NAV_LAND's ``isnan`` guard and the
camera trigger's ``trigger`` field. ArduPlane 4.5.4 itself read NAV_LOITER_TO_ALT's param 1 back
as 0 and NAV_LAND's param 4 as 1 (issue 22), as these rules say.

Every command the planner writes for ArduPilot (a plane block and a copter block are planned
here) must have a case: a new command without one fails this module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from acquisition.clock import VirtualClock
from acquisition.link import Link
from acquisition.mavlink_items import MissionResult, to_mission_item_int
from acquisition.readback import verify_readback
from acquisition.simulator.server import SimulatedVehicle
from acquisition.simulator.storage import (
    WireItem,
    ardupilot_store,
    wire_item_from_message,
    wire_item_to_mission_item,
)
from acquisition.transfer import upload_mission
from acquisition.transfer_outcome import MissionState
from planner.mission import Autopilot, MavCmd, MavFrame, MissionItem, VehicleType
from planner.spec import load_spec
from planner.survey import plan_survey

MISSIONS = Path(__file__).parents[2] / "missions"
LAT, LON = 42.1060123, -0.4160456
PLANE, COPTER = VehicleType.FIXED_WING, VehicleType.MULTIROTOR


@dataclass(frozen=True)
class Case:
    """An item sent, the vehicle, the source lines, and params 1-4 (and x/z where stored
    outside a location) as ArduPilot reads them back."""

    name: str
    sent: MissionItem
    vehicle: VehicleType
    source: str
    expected: tuple[float, float, float, float]
    x: float = 0.0  # param 5 of an item without a location
    z: float = 0.0  # param 7 of an item without a location


def located(command: MavCmd, p: tuple[float | None, ...], alt: float = 80.0) -> MissionItem:
    params = dict(zip(("param1", "param2", "param3", "param4"), p, strict=True))
    return MissionItem(command=command, param5=LAT, param6=LON, param7=alt, **params)


CASES = [
    Case(
        "takeoff pitch (plane)",
        located(MavCmd.NAV_TAKEOFF, (12.7, 0.0, 0.0, 0.0), 40.0),
        PLANE,
        "cmd.p1 = packet.param1;  // minimum pitch (plane only)  ->  packet.param1 = cmd.p1;",
        (12.0, 0.0, 0.0, 0.0),
    ),
    Case(
        "takeoff (copter)",
        MissionItem.takeoff(LAT, LON, 30.0),
        COPTER,
        "cmd.p1 = packet.param1;  ->  packet.param1 = cmd.p1;",
        (0.0, 0.0, 0.0, 0.0),
    ),
    Case(
        "waypoint hold (copter)",
        located(MavCmd.NAV_WAYPOINT, (1.5, 2.0, 3.0, 45.0)),
        COPTER,
        "#else  cmd.p1 = packet.param1;  // delay at waypoint in seconds  ->  packet.param1 = cmd.p1;",
        (1.0, 0.0, 0.0, 0.0),
    ),
    Case(
        "waypoint radii (plane)",
        located(MavCmd.NAV_WAYPOINT, (3.0, 25.5, 300.0, 45.0)),
        PLANE,
        "uint16_t acp = packet.param2; uint16_t passby = packet.param3; passby = MIN(0xFF,passby); "
        "acp = MIN(0xFF,acp); cmd.p1 = (passby << 8) | (acp & 0x00FF);  ->  "
        "packet.param2 = LOWBYTE(cmd.p1); packet.param3 = HIGHBYTE(cmd.p1);",
        (0.0, 25.0, 255.0, 0.0),
    ),
    Case(
        "return to launch",
        MissionItem.return_to_launch(),
        COPTER,
        "case MAV_CMD_NAV_RETURN_TO_LAUNCH: break;  (and not stored_in_location)",
        (0.0, 0.0, 0.0, 0.0),
    ),
    Case(
        "change speed",
        MissionItem.change_speed(7.25),
        COPTER,
        "cmd.content.speed.speed_type = packet.param1; cmd.content.speed.target_ms = packet.param2; "
        "cmd.content.speed.throttle_pct = packet.param3;  (uint8_t speed_type; float target_ms; "
        "float throttle_pct)",
        (1.0, 7.25, -1.0, 0.0),
    ),
    Case(
        "camera trigger distance",
        MissionItem.cam_trigger_distance(23.456),
        PLANE,
        "cmd.content.cam_trigg_dist.meters = packet.param1; cmd.content.cam_trigg_dist.trigger = "
        "packet.param3;  (float meters; uint8_t trigger)",
        (23.456, 0.0, 1.0, 0.0),
    ),
    Case(
        "one photo (hover mode)",
        MissionItem.image_start_capture(),
        COPTER,
        "image_start_capture: uint8_t instance = param1; float interval_s = param2; uint16_t "
        "total_num_images = param3; uint16_t start_seq_number = param4",
        (0.0, 0.0, 1.0, 0.0),
    ),
    Case(
        "mount control",
        MissionItem.gimbal_pitch_yaw(-90.0, 12.5),
        PLANE,
        "cmd.content.mount_control.pitch = packet.param1; .roll = packet.param2; .yaw = packet.param3;"
        "  (float pitch, roll, yaw; the mount mode in param 7 is not stored)",
        (-90.0, 0.0, 12.5, 0.0),
    ),
    Case(
        "gimbal manager pitch/yaw",
        replace(MissionItem.gimbal_manager_pitch_yaw(-45.5, 170.9), param3=0.0, param4=0.0),
        COPTER,
        "cmd.content.gimbal_manager_pitchyaw.pitch_angle_deg = packet.param1; .yaw_angle_deg = "
        "packet.param2; ... .flags = packet.x; .gimbal_id = packet.z;  (int8_t pitch_angle_deg; "
        "int16_t yaw_angle_deg; int8_t rates; uint8_t flags, gimbal_id)",
        (-45.0, 170.0, 0.0, 0.0),
        x=12.0,
    ),
    Case(
        "landing sequence start",
        MissionItem(command=MavCmd.DO_LAND_START, frame=MavFrame.MISSION),
        PLANE,
        "case MAV_CMD_DO_LAND_START: break;  (stored_in_location: the location only)",
        (0.0, 0.0, 0.0, 0.0),
    ),
    Case(
        "loiter down to the approach altitude",
        located(MavCmd.NAV_LOITER_TO_ALT, (1.0, 55.7, 0.0, 1.0), 40.0),
        PLANE,
        "cmd.p1 = fabsf(packet.param2); cmd.content.location.loiter_ccw = (packet.param2 < 0); "
        "cmd.content.location.loiter_xtrack = (packet.param4 > 0);  ->  packet.param2 = cmd.p1; "
        "if (loiter_ccw) packet.param2 = -packet.param2; packet.param4 = loiter_xtrack;  "
        "(param 1, heading required, is not stored)",
        (0.0, 55.0, 0.0, 1.0),
    ),
    Case(
        "loiter down, counter-clockwise, centre exit",
        located(MavCmd.NAV_LOITER_TO_ALT, (0.0, -80.2, 0.0, 0.0), 40.0),
        PLANE,
        "loiter_ccw = (packet.param2 < 0)  ->  packet.param2 = -packet.param2",
        (0.0, -80.0, 0.0, 0.0),
    ),
    Case(
        "land",
        located(MavCmd.NAV_LAND, (0.0, 0.0, 0.0, 0.0), 0.0),
        PLANE,
        "cmd.p1 = packet.param1; if (!isnan(packet.param4)) { loiter_ccw = is_negative(packet.param4); }"
        "  ->  packet.param1 = cmd.p1; packet.param4 = cmd.content.location.loiter_ccw ? -1 : 1;",
        (0.0, 0.0, 0.0, 1.0),
    ),
    Case(
        "land, abort altitude, negative yaw direction",
        located(MavCmd.NAV_LAND, (25.9, 0.0, 0.0, -7.0), 0.0),
        PLANE,
        "is_negative(packet.param4)  ->  loiter_ccw ? -1 : 1",
        (25.0, 0.0, 0.0, -1.0),
    ),
    Case(
        "land, yaw empty (NaN is allowed for param 4)",
        located(MavCmd.NAV_LAND, (0.0, 0.0, 0.0, None), 0.0),
        COPTER,
        "case MAV_CMD_NAV_LAND: nan_mask = ~(1 << 3);  if (!isnan(packet.param4)) ...  ->  "
        "loiter_ccw stays 0: param 4 reads back 1",
        (0.0, 0.0, 0.0, 1.0),
    ),
]
IDS = [case.name for case in CASES]


def wire(item: MissionItem) -> WireItem:
    return wire_item_from_message(to_mission_item_int(item, 1, 1, 1, 0))


def home() -> MissionItem:
    return MissionItem(command=MavCmd.NAV_WAYPOINT, frame=MavFrame.GLOBAL, param5=LAT, param6=LON)


def read_back(case: Case, params: tuple[float, float, float, float]) -> MissionItem:
    """The item as the vehicle would send it back with ``params`` (frame and location as
    AP_Mission reads them back)."""
    stored = ardupilot_store(wire(case.sent), case.vehicle)
    assert isinstance(stored, WireItem)
    return replace(
        wire_item_to_mission_item(stored),
        param1=params[0],
        param2=params[1],
        param3=params[2],
        param4=params[3],
    )


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_the_simulator_stores_each_command_as_ardupilots_source_says(case: Case) -> None:
    stored = ardupilot_store(wire(case.sent), case.vehicle)
    assert isinstance(stored, WireItem), f"refused with {stored}"
    got = (stored.param1, stored.param2, stored.param3, stored.param4)
    assert got == pytest.approx(case.expected, abs=1e-5), case.source
    assert stored.autocontinue == 1  # packet.autocontinue = 1
    if case.sent.frame is MavFrame.MISSION:
        assert stored.frame == 0  # packet.frame = 0
        assert (stored.x, stored.z) == (case.x, case.z), case.source
    else:  # a location: degE7 kept, frame read back plain
        assert stored.frame == 3
        assert stored.z == pytest.approx(case.sent.param7, abs=0.01)


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_the_verification_accepts_what_ardupilot_stores(case: Case) -> None:
    received = [home(), read_back(case, case.expected)]
    assert verify_readback([case.sent], received, Autopilot.ARDUPILOT, case.vehicle) == []


@pytest.mark.parametrize("case", CASES, ids=IDS)
def test_the_verification_reports_anything_the_rules_do_not_make(case: Case) -> None:
    """Each param read back other than the source makes it (one more, or 2.5 less) is
    a difference that names the param (unless it is the value sent: a vehicle that keeps a
    param whole is not wrong)."""
    for n in range(4):
        for wrong in (case.expected[n] + 1.0, case.expected[n] - 2.5):
            if wrong == case.sent.params[n]:
                continue
            params = list(case.expected)
            params[n] = wrong
            received = [home(), read_back(case, (params[0], params[1], params[2], params[3]))]
            found = verify_readback([case.sent], received, Autopilot.ARDUPILOT, case.vehicle)
            assert [d.field for d in found] == [f"param {n + 1}"], (case.name, n, wrong)


def test_a_dropped_location_on_land_is_a_difference() -> None:
    case = CASES[IDS.index("land")]
    moved = replace(read_back(case, case.expected), param5=LAT + 1e-5)
    found = verify_readback([case.sent], [home(), moved], Autopilot.ARDUPILOT, PLANE)
    assert [d.field for d in found] == ["latitude (degE7)"]


def test_ardupilot_refuses_nan_where_its_sanity_check_does() -> None:
    """``default: nan_mask = 0xff`` (every param of other commands must be a number)."""
    loiter = located(MavCmd.NAV_LOITER_TO_ALT, (None, 50.0, 0.0, 1.0))
    assert ardupilot_store(wire(loiter), PLANE) == MissionResult.INVALID_PARAM1
    assert ardupilot_store(wire(MissionItem.gimbal_manager_pitch_yaw(-90, 0)), COPTER) == (
        MissionResult.INVALID_PARAM3
    )


commands_params = st.tuples(
    st.floats(min_value=-300, max_value=300, allow_nan=False, width=32),
    st.floats(min_value=-300, max_value=300, allow_nan=False, width=32),
    st.floats(min_value=-300, max_value=300, allow_nan=False, width=32),
    st.floats(min_value=-300, max_value=300, allow_nan=False, width=32),
)


@settings(max_examples=300, deadline=None)
@given(case=st.sampled_from(CASES), p=commands_params, vehicle=st.sampled_from([PLANE, COPTER]))
def test_store_and_verification_agree_on_any_values(
    case: Case, p: tuple[float, float, float, float], vehicle: VehicleType
) -> None:
    """The simulator's packing (C types, conversion by conversion) and the read-back rules
    (a declarative table) are two writings of the same source: whatever values a command
    carries, what one stores the other accepts, and one unit more in any param is caught."""
    sent = replace(case.sent, param1=p[0], param2=p[1], param3=p[2], param4=p[3])
    stored = ardupilot_store(wire(sent), vehicle)
    if not isinstance(stored, WireItem):
        assert sent.command == MavCmd.NAV_SPLINE_WAYPOINT
        return
    back = wire_item_to_mission_item(stored)
    assert verify_readback([sent], [home(), back], Autopilot.ARDUPILOT, vehicle) == []
    for n in range(1, 5):
        value = back.params[n - 1]
        assert value is not None
        if float(p[n - 1]) in (value, value + 1.0):
            continue  # stored exactly, or one more is what was sent: no rule is involved
        off = replace(back, **{f"param{n}": value + 1.0})
        assert verify_readback([sent], [home(), off], Autopilot.ARDUPILOT, vehicle) != []


# --- every command the planner writes, and a plane block through the simulated ArduPlane ----------


@pytest.fixture(scope="module")
def plane_block() -> list[MissionItem]:
    return list(plan_survey(load_spec(MISSIONS / "huesca-plane-block.toml")).mission.items)


def test_every_command_the_planner_writes_for_ardupilot_has_its_rule(plane_block: list[MissionItem]) -> None:
    spec = load_spec(MISSIONS / "field-concave.toml")
    copter = plan_survey(replace(spec, vehicle=replace(spec.vehicle, autopilot=Autopilot.ARDUPILOT)))
    written = {int(i.command) for i in plane_block} | {int(i.command) for i in copter.mission.items}
    covered = {int(case.sent.command) for case in CASES}
    missing = {MavCmd(c).name for c in written - covered}
    assert not missing, f"commands written without a storage case here: {sorted(missing)}"
    assert {MavCmd.NAV_LOITER_TO_ALT, MavCmd.NAV_LAND, MavCmd.DO_LAND_START} <= written


def test_a_plane_block_uploads_and_verifies_on_the_simulated_arduplane() -> None:
    mission = plan_survey(load_spec(MISSIONS / "huesca-plane-block.toml")).mission
    with SimulatedVehicle(
        autopilot=Autopilot.ARDUPILOT,
        vehicle_type=PLANE,
        boot_delay_s=0.0,
        request_timeout_s=0.1,
        clock=VirtualClock(),
    ) as sim:
        with Link.open(sim.url_for_client, heartbeat_timeout_s=5.0, clock=sim.clock) as link:
            result = upload_mission(link, mission, timeout_s=0.2, retries=10)
        stored = sim.stored_mission()
    assert result.state is MissionState.REPLACED_VERIFIED and result.items == len(mission.items)
    loiter = next(i for i in stored if i.command == MavCmd.NAV_LOITER_TO_ALT)
    land = next(i for i in stored if i.command == MavCmd.NAV_LAND)
    assert loiter.param1 == 0.0 and land.param4 == 1.0  # as ArduPlane 4.5.4 read them back
    assert math.isclose(loiter.param2 or 0.0, math.trunc(mission.items[-2].param2 or 0.0))
