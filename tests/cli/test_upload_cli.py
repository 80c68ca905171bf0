"""`sfap upload`, `sfap download` and `sfap clear` through the real CLI group, against the
simulated vehicle: exit codes, what the user reads, and the files written."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import socket
import threading
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from acquisition.readback import verify_readback
from acquisition.simulator.faults import FaultConfig
from acquisition.simulator.server import SimulatedVehicle
from planner.formats import read_mission
from planner.formats.qgc_plan import write_plan
from planner.formats.waypoints import write_waypoints
from planner.mission import Autopilot, HomePosition, MavCmd, MavFrame, Mission, MissionItem, VehicleType
from sfap.cli import cli

HOME = HomePosition(lat_deg=41.6488, lon_deg=-0.8891, alt_amsl_m=210.0)
FAST = ["--timeout-s", "0.2", "--retries", "10", "--heartbeat-timeout-s", "5"]


def mission(count: int = 12, autopilot: Autopilot = Autopilot.ARDUPILOT) -> Mission:
    items = [
        MissionItem.takeoff(HOME.lat_deg, HOME.lon_deg, 30.0),
        MissionItem.cam_trigger_distance(21.5),
    ]
    for i in range(count - 3):
        items.append(
            MissionItem.waypoint(
                HOME.lat_deg + 0.00012345678 * i, HOME.lon_deg + 0.0001 * (i % 4), 60.25, hold_s=1.0
            )
        )
    items.append(MissionItem.return_to_launch())
    return Mission(items=tuple(items), home=HOME, autopilot=autopilot)


def sim(autopilot: Autopilot = Autopilot.ARDUPILOT, **options: object) -> SimulatedVehicle:
    options.setdefault("boot_delay_s", 0.0)
    options.setdefault("request_timeout_s", 0.1)
    return SimulatedVehicle(autopilot=autopilot, **options)  # type: ignore[arg-type]


def run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return result.exit_code, result.stdout, result.stderr


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
@pytest.mark.parametrize("suffix", [".plan", ".waypoints"])
def test_upload_verified_exits_0(tmp_path: Path, autopilot: Autopilot, suffix: str) -> None:
    path = tmp_path / f"mission{suffix}"
    planned = mission(autopilot=autopilot)
    (write_plan if suffix == ".plan" else write_waypoints)(planned, path)
    with sim(autopilot) as vehicle:
        code, out, err = run("upload", str(path), "--connect", vehicle.url_for_client, *FAST)
        stored = vehicle.stored_mission()
    assert code == 0, err
    assert "Mission uploaded and verified" in out
    assert "replaced and verified" in out
    body = stored[1:] if autopilot is Autopilot.ARDUPILOT else stored
    assert [i.command for i in body] == [i.command for i in planned.items]


def test_upload_json(tmp_path: Path) -> None:
    path = write_plan(mission(30, autopilot=Autopilot.PX4), tmp_path / "m.plan")
    with sim(Autopilot.PX4, faults=FaultConfig(loss_pct=10.0, seed=3), request_timeout_s=0.03) as vehicle:
        code, out, err = run(
            "upload",
            str(path),
            "--connect",
            vehicle.url_for_client,
            "--json",
            *FAST,
            "--timeout-s",
            "0.05",
            "--retries",
            "30",
        )
    assert code == 0, err
    data = json.loads(out)
    assert data["verified"] is True
    assert data["state"] == "replaced and verified"
    assert data["items"] == 30 and data["items_sent"] == 30
    assert data["autopilot"] == "px4" and data["differences"] == []


def test_readback_difference_exits_1_and_lists_items(tmp_path: Path) -> None:
    # ArduPilot keeps a gimbal id as one byte: 300 reads back 255. A real difference.
    items = [
        *mission(6).items[:-1],
        MissionItem(
            command=MavCmd.DO_GIMBAL_MANAGER_PITCHYAW,
            frame=MavFrame.MISSION,
            param1=-90.0,
            param2=0.0,
            param3=0.0,
            param4=0.0,
            param7=300.0,
        ),
        MissionItem.return_to_launch(),
    ]
    path = write_plan(Mission(items=tuple(items), home=HOME), tmp_path / "m.plan")
    with sim(Autopilot.ARDUPILOT) as vehicle:
        code, out, err = run("upload", str(path), "--connect", vehicle.url_for_client, "--json", *FAST)
    assert code == 1
    assert "Traceback" not in err
    assert "item 6 (DO_GIMBAL_MANAGER_PITCHYAW, vehicle seq 6): param 7 sent 300, read back 255" in err
    assert "DIFFERS" in err
    data = json.loads(out)
    assert data["verified"] is False
    assert [(d["index"], d["field"]) for d in data["differences"]] == [(6, "param 7")]


def test_refusing_vehicle_exits_1_with_state(tmp_path: Path) -> None:
    path = write_plan(mission(autopilot=Autopilot.PX4), tmp_path / "m.plan")
    with sim(Autopilot.PX4, faults=FaultConfig(refuse="invalid")) as vehicle:
        code, _, err = run("upload", str(path), "--connect", vehicle.url_for_client, *FAST)
    assert code == 1
    assert "MAV_MISSION_INVALID" in err
    assert "The vehicle's mission is unchanged." in err
    assert "Traceback" not in err


def test_not_a_mission_file(tmp_path: Path) -> None:
    path = tmp_path / "notes.plan"
    path.write_text("shopping list\n")
    code, _, err = run("upload", str(path), "--connect", "tcp://127.0.0.1:9")
    assert code == 2  # bad input file: usage (sfap.cli maps InputError to 2)
    assert "not a mission file" in err
    assert "mission is unchanged" in err


def test_mission_over_the_altitude_limit_is_not_sent(tmp_path: Path) -> None:
    path = write_plan(mission(), tmp_path / "m.plan")
    code, _, err = run("upload", str(path), "--connect", "tcp://127.0.0.1:9", "--max-alt-rel-home-m", "50")
    assert code == 2  # a mission that fails validation is bad input
    assert "exceeds the vehicle limit 50.0 m" in err
    assert "Nothing was sent" in err


@pytest.mark.parametrize(
    ("url", "words"),
    [
        ("http://127.0.0.1:5760", "valid schemes are serial, udpin, udpout, tcp, tcpin"),
        ("serial:///dev/sfap-no-radio:57600", "does not exist"),
    ],
)
def test_bad_connection_exits_1(tmp_path: Path, url: str, words: str) -> None:
    path = write_plan(mission(), tmp_path / "m.plan")
    code, _, err = run("upload", str(path), "--connect", url)
    assert code == (2 if url.startswith("http") else 1)  # a URL that is not one is bad usage
    assert words in err
    assert "Nothing was sent: the vehicle's mission is unchanged." in err
    assert "Traceback" not in err


def test_no_heartbeat_exits_1(tmp_path: Path) -> None:
    path = write_plan(mission(), tmp_path / "m.plan")
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(1)
        url = f"tcp://127.0.0.1:{server.getsockname()[1]}"
        code, _, err = run("upload", str(path), "--connect", url, "--heartbeat-timeout-s", "0.3")
    assert code == 1
    assert f"no heartbeat from an autopilot on {url} within 0.3 s" in err


@pytest.mark.parametrize(
    ("suffix", "autopilot"),
    [(".plan", Autopilot.ARDUPILOT), (".waypoints", Autopilot.ARDUPILOT), (".plan", Autopilot.PX4)],
)
def test_download_writes_a_file_that_reads_back(tmp_path: Path, suffix: str, autopilot: Autopilot) -> None:
    planned = mission(9)
    out_file = tmp_path / f"onboard{suffix}"
    with sim(autopilot, gps_fix_s=0.0) as vehicle:
        vehicle.load_mission(planned.items)
        code, out, err = run("download", "--connect", vehicle.url_for_client, "-o", str(out_file), *FAST)
        assert code == 0, err
        again = run("download", "--connect", vehicle.url_for_client, "-o", str(out_file), *FAST)
    assert again[0] == 2 and "--overwrite" in again[2]
    assert "Mission downloaded" in out
    got = read_mission(out_file)
    assert [i.command for i in got.items] == [i.command for i in planned.items]
    assert round(got.home.lat_deg, 7) == HOME.lat_deg  # PX4: from HOME_POSITION
    assert got.home.alt_amsl_m == pytest.approx(HOME.alt_amsl_m, abs=0.01)
    assert got.items[3].lat_deg == pytest.approx(planned.items[3].lat_deg, abs=1e-7)


def test_download_needs_a_known_extension(tmp_path: Path) -> None:
    code, _, err = run("download", "--connect", "tcp://127.0.0.1:9", "-o", str(tmp_path / "x.txt"))
    assert code == 2
    assert ".plan or .waypoints" in err


@pytest.mark.parametrize("autopilot", [Autopilot.ARDUPILOT, Autopilot.PX4])
def test_clear(autopilot: Autopilot) -> None:
    with sim(autopilot) as vehicle:
        vehicle.load_mission(mission().items)
        code, out, err = run("clear", "--connect", vehicle.url_for_client, "--json", *FAST)
        remaining = vehicle.stored_mission()
    assert code == 0, err
    assert json.loads(out)["state"] == "cleared"
    assert len(remaining) == (1 if autopilot is Autopilot.ARDUPILOT else 0)


def test_require_signing_without_a_key(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("SFAP_SIGNING_KEY", raising=False)
    code, _, err = run("clear", "--connect", "tcp://127.0.0.1:9", "--require-signing")
    assert code == 2  # an option missing its key: bad usage
    assert "--require-signing needs a key" in err
    assert "mission is unchanged" in err


def test_first_waypoint_far_from_home_warns(tmp_path: Path) -> None:
    path = write_plan(mission(), tmp_path / "m.plan")
    far_home = HomePosition(lat_deg=HOME.lat_deg + 0.5, lon_deg=HOME.lon_deg, alt_amsl_m=300.0)
    with sim(home=far_home, gps_fix_s=0.0) as vehicle:
        code, _, err = run("upload", str(path), "--connect", vehicle.url_for_client, *FAST)
    assert code == 0, err
    assert "warning: the first waypoint is 55.5 km from the vehicle's home" in err  # 0.5 deg of latitude
    with sim(home=HOME, gps_fix_s=0.0) as vehicle:
        code, _, err = run("upload", str(path), "--connect", vehicle.url_for_client, *FAST)
    assert code == 0 and "first waypoint" not in err, err
    # the limit is the crew's: 60 km accepts the far one
    with sim(home=far_home, gps_fix_s=0.0) as vehicle:
        code, _, err = run(
            "upload", str(path), "--connect", vehicle.url_for_client, *FAST, "--max-home-distance-m", "60000"
        )
    assert code == 0 and "first waypoint" not in err, err


def test_mission_too_large_exits_1_at_once_and_plan_for_px4_exits_2(tmp_path: Path) -> None:
    big = write_plan(mission(count=40), tmp_path / "big.plan")
    with sim(max_items=30) as vehicle:
        code, _, err = run("upload", str(big), "--connect", vehicle.url_for_client, *FAST)
        assert vehicle.received_counts.get("MISSION_COUNT") == 1
    assert code == 1
    assert "41 items (home included)" in err and "at most 30" in err and "11 too many" in err
    px4 = write_plan(mission(autopilot=Autopilot.PX4), tmp_path / "px4.plan")
    with sim() as vehicle:
        code, _, err = run("upload", str(px4), "--connect", vehicle.url_for_client, *FAST)
        assert "MISSION_COUNT" not in vehicle.received_counts
    assert code == 2
    assert "planned for PX4" in err and "is ArduPilot" in err and "Traceback" not in err


def test_missing_signing_key_file_is_bad_usage(tmp_path: Path) -> None:
    path = write_plan(mission(), tmp_path / "m.plan")
    code, _, err = run(
        "upload", str(path), "--connect", "tcp://127.0.0.1:9", "--signing-key", str(tmp_path / "nokey")
    )
    assert code == 2 and "cannot read the signing key file" in err


def plane_landing_mission() -> Mission:
    items = [
        MissionItem.takeoff(HOME.lat_deg + 0.001, HOME.lon_deg, 40.0),
        MissionItem.cam_trigger_distance(30.0),
        MissionItem.waypoint(HOME.lat_deg + 0.002, HOME.lon_deg + 0.002, 80.0),
        MissionItem.cam_trigger_distance(0.0, trigger_now=False),
        MissionItem(command=MavCmd.DO_LAND_START, frame=MavFrame.MISSION),
        MissionItem(
            command=MavCmd.NAV_LOITER_TO_ALT,
            param1=1.0,
            param2=55.0,
            param4=1.0,
            param5=HOME.lat_deg - 0.003,
            param6=HOME.lon_deg,
            param7=40.0,
        ),
        MissionItem(command=MavCmd.NAV_LAND, param5=HOME.lat_deg, param6=HOME.lon_deg, param7=0.0),
    ]
    return Mission(items=tuple(items), home=HOME, vehicle_type=VehicleType.FIXED_WING)


def test_plane_landing_names_rtl_autoland_and_sets_it_only_with_set_params(tmp_path: Path) -> None:
    path = write_plan(plane_landing_mission(), tmp_path / "plane.plan")
    with sim(vehicle_type=VehicleType.FIXED_WING) as vehicle:
        code, out, err = run("upload", str(path), "--connect", vehicle.url_for_client, *FAST)
        untouched = list(vehicle.params.sets)
        refused = vehicle.prearm_failure()
        code_set, out_set, err_set = run(
            "upload", str(path), "--connect", vehicle.url_for_client, "--set-params", "--json", *FAST
        )
        allowed = vehicle.prearm_failure()
    # the upload itself verifies (NAV_LOITER_TO_ALT's param 1, NAV_LAND's param 4)
    assert code == 1 and "replaced and verified" in out, err
    assert "RTL_AUTOLAND is 0, needs 1 or 2" in err and "--set-params" in err
    assert "uploaded and verified, but the vehicle will not fly it" in err and "Traceback" not in err
    assert untouched == [] and refused is not None and refused.startswith("PreArm: DO_LAND_START")
    assert code_set == 0, err_set
    data = json.loads(out_set)
    assert data["verified"] is True
    assert [(p["name"], p["was"], p["value"], p["ok"]) for p in data["parameters"]] == [
        ("RTL_AUTOLAND", 0.0, 2.0, True),
        ("CAM1_TYPE", None, 1.0, True),
    ]
    assert allowed is None


def test_upload_refused_as_invalid_after_a_boot_refusal_quotes_no_boot_message(tmp_path: Path) -> None:
    """Issue 24: the INVALID refusal quoted "Only 0 items are supported", which answered the
    NO_SPACE refusal just after boot."""
    path = write_plan(mission(20), tmp_path / "m.plan")
    with sim(boot_delay_s=0.3, faults=FaultConfig(refuse="invalid")) as vehicle:
        code, _, err = run("upload", str(path), "--connect", vehicle.url_for_client, *FAST)
    assert code == 1
    assert "invalid (MAV_MISSION_INVALID)" in err
    assert "Only 0 items" not in err and "NO_SPACE" not in err.split("failed:")[1]
    assert "PARTIAL" in err


def test_ctrl_c_mid_upload_says_what_the_vehicle_holds(tmp_path: Path) -> None:
    """Issue 24: Ctrl-C printed only "interrupted". A real SIGINT, mid-way through an upload
    over a slow radio (4800 baud)."""
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        pytest.skip("SIGINT is not Python's KeyboardInterrupt here")
    path = write_plan(mission(120), tmp_path / "m.plan")
    old = [dataclasses.replace(item, param7=item.param7 + 5.0) for item in mission(12).items]
    with sim(link_baud=4800) as vehicle:
        vehicle.load_mission(old)

        def interrupt_mid_upload() -> None:
            deadline = time.monotonic() + 20
            while vehicle.received_counts.get("MISSION_ITEM_INT", 0) < 10 and time.monotonic() < deadline:
                time.sleep(0.01)
            os.kill(os.getpid(), signal.SIGINT)

        thread = threading.Thread(target=interrupt_mid_upload, daemon=True)
        thread.start()
        code, _, err = run("upload", str(path), "--connect", vehicle.url_for_client, *FAST)
        thread.join(timeout=5)
        stored = vehicle.stored_mission()
    assert code == 130
    assert "interrupted (Ctrl-C) after" in err and "of 121 items were sent" in err
    assert "PARTIAL" in err and "sfap clear" in err and "Traceback" not in err
    # ArduPilot wrote the new items as they came: the vehicle holds neither mission whole
    assert verify_readback(old, stored, Autopilot.ARDUPILOT, None) != []
    assert verify_readback(mission(120).items, stored, Autopilot.ARDUPILOT, None) != []


def test_ctrl_c_while_connecting_says_nothing_was_sent(tmp_path: Path) -> None:
    if signal.getsignal(signal.SIGINT) is not signal.default_int_handler:
        pytest.skip("SIGINT is not Python's KeyboardInterrupt here")
    path = write_plan(mission(), tmp_path / "m.plan")
    with socket.socket() as silent:  # a TCP peer that never says a word
        silent.bind(("127.0.0.1", 0))
        silent.listen(1)
        port = silent.getsockname()[1]
        timer = threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT))
        timer.start()
        code, _, err = run("upload", str(path), "--connect", f"tcp://127.0.0.1:{port}", *FAST)
        timer.join()
    assert code == 130
    assert f"interrupted (Ctrl-C) while connecting to tcp://127.0.0.1:{port}" in err
    assert err.count("mission is unchanged") == 1 and ".." not in err and "Traceback" not in err
