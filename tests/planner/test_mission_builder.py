"""The mission items as an autopilot reads them: frames and altitudes of every positional item,
the trigger distances in the autopilot's own measure, long lines cut into runs, and the gimbal
command decoded the way PX4's gimbal module decodes it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from survey_oracles import MISSIONS, ardupilot_distance_m, make_spec, replay_at_loop_rate
from test_survey import to_lonlat_polygon

from planner.mission import Autopilot, MavCmd, MavFrame
from planner.plan_folder import write_outputs
from planner.spec import load_spec
from planner.survey import plan_polygons, plan_survey

#: MAV_FRAME_GLOBAL_RELATIVE_ALT, from MAVLink common.xml (3), and its _INT twin (6).
RELATIVE_TO_HOME = {3, 6}
POSITIONAL = {int(MavCmd.NAV_WAYPOINT), int(MavCmd.NAV_TAKEOFF)}


@pytest.mark.parametrize(
    "name", ["bardenas-gully", "field-concave", "plateau-high-home", "bardenas-gully-terrain", "quarry-block"]
)
def test_every_positional_item_is_relative_to_home(name: str) -> None:
    plan = plan_survey(load_spec(MISSIONS / f"{name}.toml"))
    positional = [it for it in plan.mission.items if int(it.command) in POSITIONAL]
    assert positional
    assert all(int(it.frame) in RELATIVE_TO_HOME for it in positional)
    # every other item carries no position at all
    others = [it for it in plan.mission.items if int(it.command) not in POSITIONAL]
    assert all(
        it.frame == MavFrame.MISSION for it in others if int(it.command) != MavCmd.NAV_RETURN_TO_LAUNCH
    )


def test_a_home_high_above_sea_level_writes_heights_above_home(tmp_path: Path) -> None:
    spec = load_spec(MISSIONS / "plateau-high-home.toml")
    assert spec.vehicle.home_alt_amsl_m == 412.0
    plan = plan_survey(spec)
    write_outputs(plan, tmp_path / "out")
    # QGC WPL 110, read as text: columns index, current, frame, command, p1-p4, lat, lon, alt
    rows = [
        line.split("\t") for line in (tmp_path / "out" / "mission.waypoints").read_text().splitlines()[1:]
    ]
    home, body = rows[0], rows[1:]
    assert float(home[10]) == pytest.approx(412.0)
    survey_alts = []
    for row in body:
        if int(row[3]) in POSITIONAL:
            assert int(row[2]) == 3, f"item {row[0]} in frame {row[2]}: not relative to home"
            survey_alts.append(float(row[10]))
    assert survey_alts[0] == pytest.approx(spec.vehicle.takeoff_alt_m)
    assert all(a == pytest.approx(60.0) for a in survey_alts[1:])
    # the QGroundControl plan says the same
    plan_json = json.loads((tmp_path / "out" / "mission.plan").read_text())
    items = plan_json["mission"]["items"]
    assert plan_json["mission"]["plannedHomePosition"][2] == pytest.approx(412.0)
    for item in items:
        if item["command"] in POSITIONAL:
            assert item["frame"] == 3
            assert item["params"][6] <= 60.0 + 1e-9


def test_trigger_distances_are_the_spacing_in_ardupilots_measure() -> None:
    # A block at 42.5 N flown north-south and east-west: ArduPilot's metre differs from the
    # UTM grid's by different amounts along the two axes.
    square = [(0, 0), (600, 0), (600, 400), (0, 400)]
    for direction in (0.0, 90.0):
        spec = make_spec({"gsd_cm": 2.0, "direction_deg": direction, "speed_m_s": 6.0})
        plan = plan_polygons(spec, [to_lonlat_polygon(square)], [])
        items = plan.mission.items
        arms = [k for k, it in enumerate(items) if it.command == MavCmd.DO_SET_CAM_TRIGG_DIST and it.param1]
        st = plan.stations
        # stations of each run, in flight order: the runs' first stations are the arming points
        starts = []
        for k in arms:
            wp = next(it for it in reversed(items[:k]) if it.command == MavCmd.NAV_WAYPOINT)
            starts.append((wp.lat_deg, wp.lon_deg))
            assert items[k].param3 == 1.0  # fires at once, at the run's first station
        first = np.array(starts)
        idx = [int(np.argmin(np.hypot(st.lat_deg - la, st.lon_deg - lo))) for la, lo in first]
        loop_step = 6.0 / 50.0
        for k, i in zip(arms, idx, strict=True):
            lat0, lon0, lat1, lon1 = st.lat_deg[i], st.lon_deg[i], st.lat_deg[i + 1], st.lon_deg[i + 1]
            ap = float(ardupilot_distance_m(np.array([lat0]), np.array([lon0]), lat1, lon1)[0])
            grid = math.hypot(st.x_m[i + 1] - st.x_m[i], st.y_m[i + 1] - st.y_m[i])
            expected = (grid - loop_step / 2) * ap / grid
            # not the grid distance, not whole metres: the spacing in ArduPilot's measure
            assert items[k].param1 == pytest.approx(expected, abs=0.01)
            assert abs(items[k].param1 - (grid - loop_step / 2)) > 0.01


def test_long_lines_are_cut_into_runs_flown_straight_on() -> None:
    # 2.4 km lines at 10 m/s: the loop-rate drift allows fewer stations than a line holds.
    strip = [(0, 0), (2400, 0), (2400, 150), (0, 150)]
    spec = make_spec({"gsd_cm": 3.0, "direction_deg": 90.0, "speed_m_s": 10.0, "front_overlap_pct": 80})
    plan = plan_polygons(spec, [to_lonlat_polygon(strip)], [])
    runs = plan.passes[0].lines
    assert len(runs) > len({ln.line_index for ln in runs})  # some line holds several runs
    # the vehicle never turns back between the runs of a line: along the line, the path is monotonic
    by_line: dict[int, list[object]] = {}
    for ln in runs:
        by_line.setdefault(ln.line_index, []).append(ln)
    for members in by_line.values():
        heading = math.radians(members[0].heading_deg)  # type: ignore[attr-defined]
        pos = [
            p
            for ln in members
            for p in (ln.entry_xy_m, ln.start_xy_m, ln.end_xy_m, ln.exit_xy_m)  # type: ignore[attr-defined]
        ]
        along = [x * math.sin(heading) + y * math.cos(heading) for x, y in pos]
        assert np.all(np.diff(along) >= -1e-6)
    fired = replay_at_loop_rate(plan.mission)
    assert len(fired) == len(plan.stations)


# --- PX4: DO_GIMBAL_MANAGER_PITCHYAW as PX4's gimbal module reads it -----------------------------
# src/modules/gimbal/input_mavlink.cpp: param1 pitch, param2 yaw (deg), param5 the flags as
# uint32; _set_control_data_from_set_attitude: an axis whose GIMBAL_MANAGER_FLAGS_*_LOCK bit is set
# (ROLL_LOCK 4, PITCH_LOCK 8, YAW_LOCK 16 in MAVLink common.xml) is held in the earth frame
# (AngleAbsoluteFrame), otherwise it is relative to the airframe (AngleBodyFrame).
_LOCK_BITS = {"roll": 4, "pitch": 8, "yaw": 16}


def _camera_axis_px4(item: object, vehicle_deg: dict[str, float]) -> np.ndarray:
    """The optical axis (east, north, up) a PX4 gimbal points for the item, on a vehicle with
    attitude ``vehicle_deg`` (roll, pitch, yaw)."""
    flags = int(item.param5)  # type: ignore[attr-defined]
    setpoint = {"roll": 0.0, "pitch": float(item.param1), "yaw": float(item.param2)}  # type: ignore[attr-defined]
    earth = {
        axis: setpoint[axis] if flags & bit else setpoint[axis] + vehicle_deg[axis]
        for axis, bit in _LOCK_BITS.items()
    }
    pitch, yaw = math.radians(earth["pitch"]), math.radians(earth["yaw"])
    # forward-looking axis turned by yaw (clockwise from north) and pitched (negative: down)
    return np.array([math.cos(pitch) * math.sin(yaw), math.cos(pitch) * math.cos(yaw), math.sin(pitch)])


def _px4_plan(oblique: bool) -> object:
    square = [(0, 0), (300, 0), (300, 200), (0, 200)]
    overrides: dict[str, object] = {"gsd_cm": 2.0, "direction_deg": 0.0}
    if oblique:
        overrides["oblique"] = [{"tilt_deg": 30.0, "headings_deg": [90]}]
    spec = make_spec(overrides)
    spec = type(spec)(
        **{
            **spec.__dict__,
            "vehicle": type(spec.vehicle)(**{**spec.vehicle.__dict__, "autopilot": Autopilot.PX4}),
        }
    )
    return plan_polygons(spec, [to_lonlat_polygon(square)], [])


@pytest.mark.parametrize("attitude", [(8.0, -6.0, 0.0), (-10.0, 4.0, 180.0), (0.0, 12.0, 93.0)])
def test_px4_nadir_stays_nadir_however_the_drone_tilts(attitude: tuple[float, float, float]) -> None:
    plan = _px4_plan(oblique=False)
    gimbal = [it for it in plan.mission.items if it.command == MavCmd.DO_GIMBAL_MANAGER_PITCHYAW]  # type: ignore[attr-defined]
    assert gimbal
    roll, pitch, yaw = attitude
    for item in gimbal:
        axis = _camera_axis_px4(item, {"roll": roll, "pitch": pitch, "yaw": yaw})
        assert axis[2] == pytest.approx(-1.0, abs=1e-9), "the camera tilts with the airframe"
    # the oracle can fail: with flags 0 (the old item) the axis follows the airframe's pitch
    unlocked = type(gimbal[0])(**{**gimbal[0].__dict__, "param5": 0.0})
    assert _camera_axis_px4(unlocked, {"roll": roll, "pitch": 10.0, "yaw": yaw})[2] > -0.999


def test_px4_obliques_look_at_their_bearing_even_when_the_drone_crabs() -> None:
    plan = _px4_plan(oblique=True)
    items = [it for it in plan.mission.items if it.command == MavCmd.DO_GIMBAL_MANAGER_PITCHYAW]  # type: ignore[attr-defined]
    obliques = [it for it in items if it.param1 == pytest.approx(-60.0)]
    assert obliques
    oblique_pass = plan.passes[-1]  # type: ignore[attr-defined]
    look = oblique_pass.look_heading_deg
    for item in obliques:
        for vehicle_yaw in (0.0, 10.0, 180.0, 250.0):  # a crab in wind, or either way along the line
            axis = _camera_axis_px4(item, {"roll": 5.0, "pitch": -3.0, "yaw": vehicle_yaw})
            bearing = math.degrees(math.atan2(axis[0], axis[1])) % 360.0
            assert abs((bearing - look + 180.0) % 360.0 - 180.0) < 1e-6
            assert math.degrees(math.asin(-axis[2])) == pytest.approx(60.0)
