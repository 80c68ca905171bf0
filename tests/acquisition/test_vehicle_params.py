"""The vehicle parameters a mission needs (acquisition.vehicle_params) and the simulated
vehicle's side of them: PARAM_REQUEST_READ / PARAM_SET answered with PARAM_VALUE, and ArduPlane's
pre-arm refusal of a landing sequence while RTL_AUTOLAND is 0 (AP_Arming_Plane::mission_checks:
``if (plane.g.rtl_autoland == RtlAutoland::RTL_DISABLE) { if
(plane.mission.contains_item(MAV_CMD_DO_LAND_START)) { ... check_failed(..., "DO_LAND_START set
and RTL_AUTOLAND disabled"); } }``).

The simulated vehicle's protocol side is checked with pymavlink's own connection (mavutil), not
with the code under test; the defaults against the ArduPlane 4.5.6 SITL log in
../shared/data/ardupilot_sitl_plane (PARM RTL_AUTOLAND Value 0 Default 0, CAM1_TYPE Default 1).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import pytest
from pymavlink import mavutil, mavwp
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from shared_data import SHARED_DATA

from acquisition.clock import WALL_CLOCK, VirtualClock
from acquisition.link import Link
from acquisition.simulator.parameters import PREARM_LAND_START
from acquisition.simulator.server import SimulatedVehicle
from acquisition.vehicle_params import (
    CAM1_TYPE,
    RTL_AUTOLAND,
    VehicleParameterError,
    check_parameters,
    read_parameter,
    required_parameters,
)
from planner.mission import Autopilot, HomePosition, MavCmd, MavFrame, MissionItem, VehicleType
from planner.spec import load_spec
from planner.survey import plan_survey

HOME = HomePosition(lat_deg=42.1060, lon_deg=-0.4160, alt_amsl_m=400.0)
MISSIONS = Path(__file__).parents[2] / "missions"
PLANE, COPTER = VehicleType.FIXED_WING, VehicleType.MULTIROTOR


def landing_mission() -> list[MissionItem]:
    return [
        MissionItem.takeoff(42.107, -0.416, 40.0),
        MissionItem.cam_trigger_distance(30.0),
        MissionItem.waypoint(42.108, -0.414, 80.0),
        MissionItem.cam_trigger_distance(0.0, trigger_now=False),
        MissionItem(command=MavCmd.DO_LAND_START, frame=MavFrame.MISSION),
        MissionItem(
            command=MavCmd.NAV_LOITER_TO_ALT,
            param2=55.0,
            param4=1.0,
            param5=42.106,
            param6=-0.420,
            param7=40.0,
        ),
        MissionItem(command=MavCmd.NAV_LAND, param5=42.106, param6=-0.416, param7=0.0),
    ]


def plane(**options: Any) -> SimulatedVehicle:
    options.setdefault("clock", VirtualClock())
    options.update(boot_delay_s=0.0, gps_fix_s=0.0, home=HOME)
    return SimulatedVehicle(autopilot=Autopilot.ARDUPILOT, vehicle_type=PLANE, **options)


# --- which parameters -----------------------------------------------------------------------------


def test_a_plane_landing_sequence_needs_rtl_autoland_and_a_trigger_needs_a_camera() -> None:
    items = landing_mission()
    assert required_parameters(items, Autopilot.ARDUPILOT, PLANE) == (RTL_AUTOLAND, CAM1_TYPE)
    assert required_parameters(items, Autopilot.ARDUPILOT, VehicleType.VTOL) == (RTL_AUTOLAND, CAM1_TYPE)
    assert required_parameters(items, Autopilot.ARDUPILOT, COPTER) == (CAM1_TYPE,)  # Copter's arming
    assert required_parameters(items, Autopilot.PX4, PLANE) == ()
    no_photo = [i for i in items if i.command != MavCmd.DO_SET_CAM_TRIGG_DIST or i.param1 == 0.0]
    assert required_parameters(no_photo, Autopilot.ARDUPILOT, PLANE) == (RTL_AUTOLAND,)
    assert RTL_AUTOLAND.accepts(1) and RTL_AUTOLAND.accepts(2)
    assert not RTL_AUTOLAND.accepts(0) and not RTL_AUTOLAND.accepts(3)
    assert not CAM1_TYPE.accepts(0) and CAM1_TYPE.accepts(1) and CAM1_TYPE.accepts(5)


def test_the_planned_plane_block_names_rtl_autoland() -> None:
    plan = plan_survey(load_spec(MISSIONS / "huesca-plane-block.toml"))
    names = [r.name for r in required_parameters(plan.mission.items, plan.mission.autopilot, PLANE)]
    assert names == ["RTL_AUTOLAND", "CAM1_TYPE"]


SITL = SHARED_DATA / "ardupilot_sitl_plane"


def test_the_defaults_are_those_of_arduplane_sitl() -> None:
    if not (SITL / "flight.BIN").exists():
        where = f"{SITL} (../shared/data beside the repository, or $SFAP_SHARED_DATA)"
        if os.environ.get("CI") == "true":
            pytest.fail(f"the ArduPlane SITL log is missing: {where}")
        pytest.skip(f"needs the ArduPlane SITL log in {where}")
    log = mavutil.mavlink_connection(str(SITL / "flight.BIN"))
    defaults: dict[str, float] = {}
    while (msg := log.recv_match(type="PARM")) is not None:
        if msg.Name in ("RTL_AUTOLAND", "CAM1_TYPE"):
            defaults[msg.Name] = float(msg.Default)
    assert defaults["RTL_AUTOLAND"] == RTL_AUTOLAND.default == 0.0
    with plane() as sim:
        assert sim.params.get("RTL_AUTOLAND") == defaults["RTL_AUTOLAND"]
        assert sim.params.get("CAM1_TYPE") == defaults["CAM1_TYPE"]


# --- the simulated vehicle, through pymavlink ------------------------------------------------------


class Gcs:
    """A ground station made of pymavlink's mavutil alone."""

    def __init__(self, sim: SimulatedVehicle) -> None:
        url = sim.url_for_client.replace("tcp://", "tcp:")
        self.conn = mavutil.mavlink_connection(url, source_system=255)
        self.conn.wait_heartbeat(timeout=5)

    def recv(self, types: list[str], timeout_s: float = 2.0) -> Any:
        return self.conn.recv_match(type=types, blocking=True, timeout=timeout_s)

    def close(self) -> None:
        self.conn.close()


def test_the_simulated_arduplane_answers_param_read_and_set() -> None:
    with plane(clock=WALL_CLOCK) as sim:
        gcs = Gcs(sim)
        gcs.conn.mav.param_request_read_send(1, 1, b"RTL_AUTOLAND", -1)
        value = gcs.recv(["PARAM_VALUE"])
        assert value is not None and value.param_id == "RTL_AUTOLAND"
        assert value.param_value == 0.0 and value.param_type == mavlink2.MAV_PARAM_TYPE_INT8
        gcs.conn.mav.param_set_send(1, 1, b"RTL_AUTOLAND", 2.0, mavlink2.MAV_PARAM_TYPE_INT8)
        value = gcs.recv(["PARAM_VALUE"])
        assert value is not None and (value.param_id, value.param_value) == ("RTL_AUTOLAND", 2.0)
        gcs.conn.mav.param_request_read_send(1, 1, b"NO_SUCH_PARAM", -1)
        assert gcs.recv(["PARAM_VALUE"], 0.5) is None  # ArduPilot ignores a name it lacks
        gcs.close()
        assert sim.params.get("RTL_AUTOLAND") == 2.0


def test_the_simulated_arduplane_refuses_to_arm_a_landing_sequence_until_rtl_autoland_is_set() -> None:
    with plane(clock=WALL_CLOCK) as sim:
        sim.load_mission(landing_mission())
        gcs = Gcs(sim)
        gcs.conn.mav.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)
        texts: list[str] = []
        ack = None
        while ack is None:
            msg = gcs.recv(["COMMAND_ACK", "STATUSTEXT"])
            assert msg is not None
            if msg.get_type() == "STATUSTEXT":
                texts.append(msg.text)
            elif msg.command == 400:
                ack = msg
        assert ack.result == mavlink2.MAV_RESULT_FAILED
        assert PREARM_LAND_START[:50] in texts  # STATUSTEXT carries 50 characters
        assert not sim.flight.armed
        gcs.conn.mav.param_set_send(1, 1, b"RTL_AUTOLAND", 1.0, mavlink2.MAV_PARAM_TYPE_INT8)
        assert gcs.recv(["PARAM_VALUE"]) is not None
        gcs.conn.mav.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)
        ack = gcs.recv(["COMMAND_ACK"])
        assert ack is not None and ack.result == mavlink2.MAV_RESULT_ACCEPTED
        assert sim.flight.armed
        gcs.close()


def test_a_copter_or_a_plane_without_landing_sequence_arms() -> None:
    items = [i for i in landing_mission() if i.command != MavCmd.DO_LAND_START]
    with plane() as sim:
        sim.load_mission(items)
        assert sim.prearm_failure() is None
    copter = SimulatedVehicle(boot_delay_s=0.0, gps_fix_s=0.0, clock=VirtualClock())
    with copter as sim:
        sim.load_mission(landing_mission())
        assert sim.prearm_failure() is None  # ArduCopter has no RTL_AUTOLAND check


# --- check_parameters over the project's link --------------------------------------------------------


def test_check_names_what_to_set_and_sets_it_only_when_told() -> None:
    with plane() as sim:
        sim.load_mission(landing_mission())
        with Link.open(sim.url_for_client, heartbeat_timeout_s=5.0, clock=sim.clock) as link:
            needed = required_parameters(landing_mission(), Autopilot.ARDUPILOT, link.vehicle_type)
            looked = check_parameters(link, needed, timeout_s=0.2)
            assert [(s.requirement.name, s.value, s.ok) for s in looked] == [
                ("RTL_AUTOLAND", 0.0, False),
                ("CAM1_TYPE", 1.0, True),
            ]
            text = looked[0].describe()
            assert "RTL_AUTOLAND is 0, needs 1 or 2" in text and "--set-params" in text
            assert sim.params.sets == []  # nothing set without being told
            assert sim.prearm_failure() == PREARM_LAND_START
            fixed = check_parameters(link, needed, apply=True, timeout_s=0.2)
            assert [(s.requirement.name, s.value, s.was, s.ok) for s in fixed] == [
                ("RTL_AUTOLAND", 2.0, 0.0, True),
                ("CAM1_TYPE", 1.0, None, True),
            ]
            assert read_parameter(link, "RTL_AUTOLAND", timeout_s=0.2) == (2.0, mavlink2.MAV_PARAM_TYPE_INT8)
        assert sim.params.sets == [("RTL_AUTOLAND", 2.0)]
        assert sim.prearm_failure() is None


class _DeafToParamSet(SimulatedVehicle):
    """A vehicle that answers PARAM_SET with its old value (a read-only or locked parameter)."""

    def _on_param_set(self, msg: Any) -> None:
        name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
        answer = self.params.value_message(name.rstrip("\x00"))
        if answer is not None:
            self.send(answer)


def test_a_value_the_vehicle_does_not_keep_is_an_error() -> None:
    vehicle = _DeafToParamSet(
        vehicle_type=PLANE, boot_delay_s=0.0, gps_fix_s=0.0, home=HOME, clock=VirtualClock()
    )
    with (
        vehicle as sim,
        Link.open(sim.url_for_client, heartbeat_timeout_s=5.0, clock=sim.clock) as link,
        pytest.raises(VehicleParameterError) as caught,
    ):
        check_parameters(link, [RTL_AUTOLAND], apply=True, timeout_s=0.2)
    assert "RTL_AUTOLAND could not be set to 2" in str(caught.value)
    assert "reads back 0" in str(caught.value)


def test_a_vehicle_that_does_not_answer_is_said_so() -> None:
    px4 = SimulatedVehicle(autopilot=Autopilot.PX4, boot_delay_s=0.0, clock=VirtualClock())
    with px4 as sim, Link.open(sim.url_for_client, heartbeat_timeout_s=5.0, clock=sim.clock) as link:
        (status,) = check_parameters(link, [RTL_AUTOLAND], apply=True, timeout_s=0.2, retries=1)
    assert status.value is None and not status.ok
    assert "could not be read" in status.describe()


def test_the_requirements_load_no_mavlink() -> None:
    """A plan's summary asks for them: importing them must not pull pymavlink in."""
    import subprocess
    import sys

    code = (
        "import sys; from acquisition.vehicle_params import required_parameters; "
        "print(any(m.startswith('pymavlink') for m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
    # the planner's own module imports nothing of acquisition (nor pymavlink), and acquisition
    # uses the very same requirements
    code = (
        "import sys, planner.vehicle_params as p; "
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'acquisition', 'pymavlink', 'sfap'}))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    import planner.vehicle_params as planned

    assert required_parameters is planned.required_parameters and RTL_AUTOLAND is planned.RTL_AUTOLAND


@pytest.mark.parametrize(
    ("mission", "expected"),
    [
        ("huesca-plane-block", ["RTL_AUTOLAND", "CAM1_TYPE"]),
        ("quarry-block", ["CAM1_TYPE"]),
        ("field-concave", []),
    ],
)
def test_a_plan_states_the_parameters_it_needs(tmp_path: Path, mission: str, expected: list[str]) -> None:
    """summary.json and `sfap plan`'s table name them. The expectation follows ArduPilot's
    rules read off the written mission file with pymavlink: ArduPlane with DO_LAND_START needs
    RTL_AUTOLAND, an ArduPilot mission with a trigger distance needs CAM1_TYPE, PX4 nothing."""
    from click.testing import CliRunner

    from sfap.cli import cli

    out = tmp_path / "out"
    result = CliRunner().invoke(cli, ["plan", str(MISSIONS / f"{mission}.toml"), "-o", str(out)])
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    names = [p["name"] for p in summary["vehicle_parameters"]]
    assert names == expected
    if (out / "mission.waypoints").exists() and expected:
        loader = mavwp.MAVWPLoader()
        loader.load(str(out / "mission.waypoints"))
        commands = {loader.wp(i).command for i in range(loader.count())}
        assert ("RTL_AUTOLAND" in names) == (mavutil.mavlink.MAV_CMD_DO_LAND_START in commands)
        assert ("CAM1_TYPE" in names) == (mavutil.mavlink.MAV_CMD_DO_SET_CAM_TRIGG_DIST in commands)
    for p in summary["vehicle_parameters"]:
        assert f"vehicle parameter {p['name']}" in result.output and p["needed"] in result.output
    if not expected:
        assert "vehicle parameter" not in result.output
