"""`sfap sim` through the real click group: it says it is a simulator, preloads a mission file,
flies it by itself and writes a .tlog that pymavlink reads; bad input is a clear error."""

from __future__ import annotations

import math
from pathlib import Path

from click.testing import CliRunner
from pymavlink import mavutil

from planner.geo import geodesic_distance_m
from sfap.cli import cli

# QGC WPL 110, written by hand: home, take-off 30 m, 10 m/s, one line east with distance
# triggering every 20 m (QGC's pattern: entry + TRIGG(20, 0, 1), exit + TRIGG(0)), RTL.
LINE = ((41.6497, -0.8891), (41.6497, -0.8870))
WAYPOINTS = f"""QGC WPL 110
0\t1\t0\t16\t0\t0\t0\t0\t41.6488\t-0.8891\t210.0\t1
1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t30\t1
2\t0\t3\t178\t1\t10\t-1\t0\t0\t0\t0\t1
3\t0\t3\t16\t0\t0\t0\t0\t{LINE[0][0]}\t{LINE[0][1]}\t30\t1
4\t0\t3\t206\t20\t0\t1\t0\t0\t0\t0\t1
5\t0\t3\t16\t0\t0\t0\t0\t{LINE[1][0]}\t{LINE[1][1]}\t30\t1
6\t0\t3\t206\t0\t0\t0\t0\t0\t0\t0\t1
7\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1
"""


def _run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(cli, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_sim_says_it_is_a_simulator_and_where_to_connect() -> None:
    code, out, err = _run("sim", "--listen", "tcpin://127.0.0.1:0", "--duration-s", "0.3")
    assert code == 0, err
    assert "sfap simulated vehicle" in err and "not an aircraft" in err
    url = next(line.split()[-1] for line in err.splitlines() if "connect a ground station" in line)
    assert url.startswith("tcp://127.0.0.1:") and not url.endswith(":0")
    assert out == ""


def test_sim_flies_a_preloaded_mission_and_writes_the_tlog(tmp_path: Path) -> None:
    mission = tmp_path / "line.waypoints"
    mission.write_text(WAYPOINTS)
    tlog = tmp_path / "flight.tlog"
    code, _, err = _run(
        "sim",
        "--listen",
        "udpin://127.0.0.1:0",
        "--mission",
        str(mission),
        "--auto-start",
        "--streams",
        "always",  # no ground station here asks for telemetry: stream it anyway
        "--until-landed",
        "--speedup",
        "200",
        "--tlog",
        str(tlog),
        "--duration-s",
        "30",
    )
    assert code == 0, err
    assert "stopped (landed)" in err
    length_m = geodesic_distance_m(*LINE[0], *LINE[1])
    expected = math.floor(length_m / 20.0) + 1  # one at the entry, then every 20 m
    assert f"{expected} photos taken" in err
    log = mavutil.mavlink_connection(str(tlog))
    feedback, stamps = [], []
    while (msg := log.recv_match()) is not None:
        stamps.append(msg._timestamp)
        if msg.get_type() == "CAMERA_FEEDBACK":
            feedback.append(msg)
    assert stamps == sorted(stamps)
    assert [m.img_idx for m in feedback] == list(range(1, expected + 1))
    first, last = feedback[0], feedback[-1]
    assert geodesic_distance_m(first.lat / 1e7, first.lng / 1e7, *LINE[0]) < 1.5
    spacing = geodesic_distance_m(first.lat / 1e7, first.lng / 1e7, last.lat / 1e7, last.lng / 1e7)
    assert abs(spacing - 20.0 * (expected - 1)) < 2.0


def test_sim_bad_input_is_a_clear_error(tmp_path: Path) -> None:
    code, _, err = _run("sim", "--listen", "serial:///dev/ttyUSB0", "--duration-s", "0")
    assert code == 2 and "tcpin://" in err and "Traceback" not in err  # not a URL it can listen on
    not_mission = tmp_path / "notes.txt"
    not_mission.write_text("hello\n")
    code, _, err = _run("sim", "--mission", str(not_mission), "--duration-s", "0")
    assert code == 2 and "not a mission file" in err
    code, out, _ = _run("sim", "--help")
    assert code == 0 and "Example: sfap sim" in out and "--loss-pct" in out


def test_sim_stands_at_the_plans_home_and_refuses_a_bad_home(tmp_path: Path) -> None:
    from planner.formats.qgc_plan import write_plan
    from planner.mission import HomePosition, Mission, MissionItem

    home = HomePosition(lat_deg=42.2012, lon_deg=-1.4866, alt_amsl_m=412.5)
    plan_dir = tmp_path / "plan"
    plan_dir.mkdir()
    items = (MissionItem.takeoff(home.lat_deg, home.lon_deg, 30.0), MissionItem.return_to_launch())
    write_plan(Mission(items=items, home=home), plan_dir / "mission.plan")
    code, _, err = _run(
        "sim", "--listen", "tcpin://127.0.0.1:0", "--plan", str(plan_dir), "--duration-s", "0.2"
    )
    assert code == 0, err
    assert "home 42.2012000, -1.4866000, ground at 412.5 m AMSL" in err
    for bad in ("91,0,0", "42.2,-1.5", "a,b,c"):
        code, _, err = _run("sim", "--home", bad, "--duration-s", "0")
        assert code == 2 and "LAT,LON,ALT" in err and "Traceback" not in err, err
    code, _, err = _run("sim", "--camera-offset-s", "5", "--duration-s", "0")
    assert code == 2 and "--frames" in err
    code, _, err = _run("sim", "--plan", str(tmp_path / "nowhere"), "--duration-s", "0")
    assert code == 2 and "sfap plan -o" in err
