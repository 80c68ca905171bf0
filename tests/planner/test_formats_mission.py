"""Mission files: QGC .plan and QGC WPL 110 .waypoints, written and read.

Oracles: pymavlink's own .waypoints loader and writer (mavwp), QGroundControl's load rules
(encoded below from its source), exact write -> read round trips over random missions
(hypothesis), and hand-written fixtures shaped like QGC and Mission Planner files
(tests/data/mission_files, provenance in tests/data/README.md).
"""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink import mavutil, mavwp

from planner.errors import MissionFileError, MissionValidationError, OutputExistsError
from planner.formats import (
    plan_document,
    read_mission,
    read_plan,
    read_waypoints,
    waypoints_text,
    write_plan,
    write_waypoints,
)
from planner.formats.qgc_plan import parse_plan, plan_text
from planner.formats.waypoints import format_number, parse_waypoints
from planner.mission import (
    Autopilot,
    HomePosition,
    MavCmd,
    MavFrame,
    Mission,
    MissionItem,
    VehicleType,
)

DATA = Path(__file__).resolve().parents[1] / "data" / "mission_files"
SURVEY_PLAN = DATA / "qgc_survey_ardupilot.plan"
CORRIDOR_PLAN = DATA / "qgc_corridor_px4_vtol.plan"
MP_WAYPOINTS = DATA / "mission_planner.waypoints"

DETERMINISTIC = settings(
    derandomize=True,
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


# --- strategies ---------------------------------------------------------------------------------

finite = st.floats(allow_nan=False, allow_infinity=False)
optional_param = st.one_of(st.none(), finite)


@st.composite
def mission_items(draw: st.DrawFn) -> MissionItem:
    return MissionItem(
        command=draw(st.sampled_from(list(MavCmd))),
        frame=draw(st.sampled_from(list(MavFrame))),
        param1=draw(optional_param),
        param2=draw(optional_param),
        param3=draw(optional_param),
        param4=draw(optional_param),
        param5=draw(st.floats(min_value=-90.0, max_value=90.0)),
        param6=draw(st.floats(min_value=-180.0, max_value=180.0)),
        param7=draw(finite),
        autocontinue=draw(st.booleans()),
    )


@st.composite
def missions(draw: st.DrawFn) -> Mission:
    items = draw(st.lists(mission_items(), max_size=25))
    # A DO_JUMP names the 1-based position of an item of the same mission.
    fixed = [
        _with_param1(item, float(draw(st.integers(1, len(items)))))
        if item.command == MavCmd.DO_JUMP
        else item
        for item in items
    ]
    return Mission(
        items=tuple(fixed),
        home=HomePosition(
            lat_deg=draw(st.floats(min_value=-90.0, max_value=90.0)),
            lon_deg=draw(st.floats(min_value=-180.0, max_value=180.0)),
            alt_amsl_m=draw(st.floats(min_value=-500.0, max_value=9000.0)),
        ),
        autopilot=draw(st.sampled_from(list(Autopilot))),
        vehicle_type=draw(st.sampled_from(list(VehicleType))),
        cruise_speed_m_s=draw(st.floats(min_value=0.1, max_value=100.0)),
        hover_speed_m_s=draw(st.floats(min_value=0.1, max_value=100.0)),
    )


def _with_param1(item: MissionItem, value: float | None) -> MissionItem:
    params = dict(vars(item))
    params["param1"] = value
    return MissionItem(**params)


def _survey_mission() -> Mission:
    """A small ArduPilot survey as the planner builds it."""
    items = (
        MissionItem.takeoff(42.1963214, -1.4821598, 30.0),
        MissionItem.change_speed(8.0),
        MissionItem.gimbal_pitch_yaw(-90.0, 0.0),
        MissionItem.gimbal_manager_pitch_yaw(-90.0, 0.0),
        MissionItem.waypoint(42.197120312345678, -1.483884109876543, 75.6),
        MissionItem.cam_trigger_distance(14.23),
        MissionItem.waypoint(42.1971203, -1.4799040, 75.6),
        MissionItem.cam_trigger_distance(0.0, trigger_now=False),
        MissionItem.waypoint(42.1974802, -1.4799040, 75.6, hold_s=4.0),
        MissionItem.image_start_capture(),
        MissionItem(command=MavCmd.DO_JUMP, frame=MavFrame.MISSION, param1=5.0, param2=1.0),
        MissionItem.return_to_launch(),
    )
    return Mission(
        items=items,
        home=HomePosition(lat_deg=42.1963214, lon_deg=-1.4821598, alt_amsl_m=281.3),
        autopilot=Autopilot.ARDUPILOT,
        vehicle_type=VehicleType.MULTIROTOR,
        cruise_speed_m_s=12.0,
        hover_speed_m_s=8.0,
    )


def _nan_to_none(value: float) -> float | None:
    return None if math.isnan(value) else value


# --- .waypoints: pymavlink is the oracle --------------------------------------------------------


def _load_with_mavwp(path: Path) -> mavwp.MAVWPLoader:
    loader = mavwp.MAVWPLoader()
    loader.load(str(path))
    return loader


def _assert_mavwp_matches(path: Path, mission: Mission) -> None:
    loader = _load_with_mavwp(path)
    assert loader.count() == len(mission.items) + 1  # row 0 is home
    home = loader.wp(0)
    assert (home.seq, home.frame, home.command) == (0, 0, 16)
    assert (home.x, home.y, home.z) == (
        mission.home.lat_deg,
        mission.home.lon_deg,
        mission.home.alt_amsl_m,
    )
    for seq, item in enumerate(mission.items, start=1):
        wp = loader.wp(seq)
        assert wp.seq == seq
        assert wp.command == int(item.command)
        assert wp.frame == int(item.frame)
        assert wp.current == 0
        assert wp.autocontinue == int(item.autocontinue)
        got = (wp.param1, wp.param2, wp.param3, wp.param4, wp.x, wp.y, wp.z)
        assert tuple(_nan_to_none(v) for v in got[:4]) == item.params[:4]
        assert got[4:] == item.params[4:]


def test_mavwp_loads_the_waypoints_we_write(tmp_path: Path) -> None:
    mission = _survey_mission()
    path = write_waypoints(mission, tmp_path / "mission.waypoints")
    _assert_mavwp_matches(path, mission)


@DETERMINISTIC
@given(mission=missions())
def test_mavwp_loads_random_missions(tmp_path: Path, mission: Mission) -> None:
    path = write_waypoints(mission, tmp_path / "random.waypoints")
    _assert_mavwp_matches(path, mission)


def test_waypoints_rows_are_what_qgc_and_mission_planner_expect() -> None:
    mission = _survey_mission()
    text = waypoints_text(mission)
    lines = text.split("\n")
    assert lines[0] == "QGC WPL 110"
    assert lines[-1] == ""  # the file ends with a newline
    rows = [line.split("\t") for line in lines[1:-1]]
    # QGroundControl splits rows on tabs only (MissionItem::load), and wants exactly 12 fields.
    assert all(len(row) == 12 for row in rows)
    assert [int(row[0]) for row in rows] == list(range(len(rows)))
    assert rows[0][1:4] == ["1", "0", "16"]  # home: current, frame GLOBAL, NAV_WAYPOINT
    assert all(row[1] == "0" for row in rows[1:])
    # Full precision: lat/lon with at least 8 decimals, digits for the whole double.
    assert rows[5][8] == repr(mission.items[4].lat_deg)  # 17 significant digits
    assert rows[5][9] == repr(mission.items[4].lon_deg)
    assert len(rows[5][8]) == 18
    assert rows[1][8] == "42.19632140"
    # The gimbal-manager item's "leave unchanged" rates are NaN, spelled as Mission Planner does.
    assert rows[4][6:8] == ["NaN", "NaN"]
    assert "e" not in text.replace("QGC WPL 110", "").lower().replace("nan", "")


def test_we_read_what_pymavlink_writes(tmp_path: Path) -> None:
    """MAVProxy's writer (mavwp.save, "%f" numbers, "nan") read by ours."""
    loader = mavwp.MAVWPLoader()
    mission = _survey_mission()
    home_row = MissionItem(
        command=MavCmd.NAV_WAYPOINT,
        frame=MavFrame.GLOBAL,
        param5=mission.home.lat_deg,
        param6=mission.home.lon_deg,
        param7=mission.home.alt_amsl_m,
    )
    for seq, item in enumerate([home_row, *mission.items]):
        p = [math.nan if v is None else v for v in item.params]
        loader.add(
            mavutil.mavlink.MAVLink_mission_item_message(
                1, 1, seq, int(item.frame), int(item.command), 0, int(item.autocontinue), *p
            )
        )
    path = tmp_path / "mavproxy.waypoints"
    loader.save(str(path))
    read = read_waypoints(path)
    assert read.home.lat_deg == pytest.approx(mission.home.lat_deg, abs=5e-7)
    assert read.home.alt_amsl_m == pytest.approx(281.3, abs=5e-7)
    assert len(read.items) == len(mission.items)
    for got, want in zip(read.items, mission.items, strict=True):
        assert got.command == want.command
        assert got.frame == want.frame
        assert got.autocontinue == want.autocontinue
        for g, w in zip(got.params, want.params, strict=True):
            if w is None:
                assert g is None  # pymavlink wrote "nan"
            else:
                assert g == pytest.approx(w, abs=5e-7)  # "%f": six decimals


@DETERMINISTIC
@given(mission=missions())
def test_waypoints_round_trip_is_exact(mission: Mission) -> None:
    read = parse_waypoints(waypoints_text(mission))
    assert read.items == mission.items
    assert read.home == mission.home


def test_waypoints_file_round_trip_and_overwrite(tmp_path: Path) -> None:
    mission = _survey_mission()
    path = tmp_path / "out" / "mission.waypoints"
    write_waypoints(mission, path)
    assert read_waypoints(path).items == mission.items
    with pytest.raises(OutputExistsError, match="--overwrite"):
        write_waypoints(mission, path, overwrite=False)
    assert sorted(p.name for p in path.parent.iterdir()) == ["mission.waypoints"]


@DETERMINISTIC
@given(value=finite)
def test_format_number_is_exact_and_plain(value: float) -> None:
    text = format_number(value)
    assert float(text) == value
    assert "e" not in text.lower()
    assert len(text.partition(".")[2]) >= 8


def test_format_number_nan_and_none() -> None:
    assert format_number(None) == "NaN"
    assert format_number(math.nan) == "NaN"
    with pytest.raises(MissionValidationError):
        format_number(math.inf)


def test_reads_a_mission_planner_file_with_crlf_nan_and_blank_lines() -> None:
    raw = MP_WAYPOINTS.read_bytes()
    assert b"\r\n" in raw and raw.endswith(b"\r\n\r\n")  # the fixture is what it claims
    mission = read_waypoints(MP_WAYPOINTS)
    assert mission.home == HomePosition(lat_deg=-35.363261, lon_deg=149.16523, alt_amsl_m=584.09)
    assert [int(i.command) for i in mission.items] == [22, 178, 16, 206, 16, 206, 177, 20]
    assert all(i.frame is MavFrame.GLOBAL_RELATIVE_ALT for i in mission.items)
    assert mission.items[2].param4 is None  # "NaN"
    assert mission.items[2].params[4:] == (-35.3621144, 149.1637866, 45.0)
    assert mission.items[1].params[:3] == (1.0, 6.5, -1.0)
    # DO_JUMP keeps its row number: 3 is the first survey waypoint, row 3 of the file.
    assert mission.items[6].param1 == 3.0 and mission.items[6].param2 == 2.0
    assert mission.autopilot is Autopilot.ARDUPILOT
    assert mission.metadata["autopilot_from_file"] is False


def test_reads_pymavlink_comments_and_spaces(tmp_path: Path) -> None:
    text = (
        "QGC WPL 110\n# a comment\n0 0 0 16 0 0 0 0 47.6 -122.3 10.0 1\n\n"
        "# another\n1  0  3  16  0  0  0  nan  47.61 -122.31 -5.0  1\n"
    )
    mission = parse_waypoints(text)
    assert mission.items[0].param4 is None
    assert mission.items[0].alt_m == -5.0


_HOME_ROW = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t1\t2\t3\t1\n"


def _with_home(row: str) -> str:
    """A file with a good home row and then ``row`` (fields given space-separated)."""
    return _HOME_ROW + row.replace(" ", "\t") + "\n"


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("QGC WPL 100\n", r"line 1: .*QGC WPL 100.*Mission Planner"),
        ("QGC WPL 120\n", r"line 1: .*no home row"),
        ("hello\n0\t1\n", r"line 1: header is 'hello'"),
        ("QGC WPL 110\n", r"no rows"),
        ("", r"empty"),
        (
            _with_home("1 0 3 16 0 0 0 1 2 3 1"),
            r"line 3: 11 fields, expected 12",
        ),
        (
            _with_home("1 0 3 16 0 0 0 0 x 2 3 1"),
            r"line 3: LAT is 'x', expected a number",
        ),
        (
            _with_home("1 0 3 WP 0 0 0 0 1 2 3 1"),
            r"line 3: COMMAND is 'WP', expected an integer",
        ),
        (
            "QGC WPL 110\r\n0\t1\t0\t16\t0\t0\t0\t0\t1\t2\t3\t1\r\n\r\n"
            "2\t0\t3\t16\t0\t0\t0\t0\t1\t2\t3\t1\r\n",
            r"line 4: INDEX is 2, expected 1",
        ),
        (
            _with_home("1 0 1 16 0 0 0 0 1 2 3 1"),
            r"line 3: FRAME 1 is not a mission frame",
        ),
        (
            _with_home("1 0 3 16 0 0 0 0 1 2 inf 1"),
            r"line 3: ALT is 'inf', expected a finite number",
        ),
        (
            _with_home("1 0 3 16 0 0 0 0 1 2 3 7"),
            r"line 3: AUTOCONTINUE is 7",
        ),
        ("QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\tNaN\t2\t3\t1\n", r"line 2: the home row's LAT"),
    ],
)
def test_bad_waypoints_files_are_named_by_line_and_field(text: str, match: str) -> None:
    with pytest.raises(MissionFileError, match=match) as info:
        parse_waypoints(text, source="bad.waypoints")
    assert str(info.value).startswith("bad.waypoints")


# --- .plan: QGroundControl's loader rules are the oracle ----------------------------------------

# The keys and JSON types QGroundControl requires when it opens a .plan, from its source:
# - PlanMasterController.cc loadFromFile: JsonHelper::validateExternalQGCJsonFile (groundStation
#   string, fileType "Plan", version 1 number) and mission/geoFence/rallyPoints objects.
# - MissionController.cc _loadJsonMissionFileV2 (mission version 2): plannedHomePosition array of 3,
#   items array, firmwareType number required; vehicleType, cruiseSpeed, hoverSpeed,
#   globalPlanAltitudeMode numbers optional.
# - MissionItem.cc load: type "SimpleItem", frame, command numbers, params array of 7 (params 1-4
#   number or null), autoContinue bool; doJumpId number optional.
# - SimpleMissionItem.cc load: AltitudeMode, Altitude, AMSLAltAboveTerrain all three or none,
#   numbers (JsonHelper::validateKeyTypes lets null stand for a NaN double).
# - GeoFenceController.cc load: version 2, circles and polygons arrays.
# - RallyPointController.cc load: version 2, points array.
_NUMBER = (int, float)


def _is_double(value: object, *, null_ok: bool = False) -> bool:
    if value is None:
        return null_ok
    return isinstance(value, _NUMBER) and not isinstance(value, bool)


def _qgc_would_load(doc: dict[str, Any]) -> list[str]:
    """Every violation of QGC's load rules (an empty list: QGC loads the document)."""
    problems: list[str] = []

    def need(obj: dict[str, Any], key: str, check: Any, where: str) -> None:
        if key not in obj:
            problems.append(f"{where}: missing {key}")
        elif not check(obj[key]):
            problems.append(f"{where}: {key} has the wrong type: {obj[key]!r}")

    need(doc, "groundStation", lambda v: isinstance(v, str), "root")
    need(doc, "fileType", lambda v: v == "Plan", "root")
    need(doc, "version", lambda v: v == 1, "root")
    for key in ("mission", "geoFence", "rallyPoints"):
        need(doc, key, lambda v: isinstance(v, dict), "root")
    mission = doc.get("mission", {})
    need(mission, "version", lambda v: v == 2, "mission")
    need(
        mission,
        "plannedHomePosition",
        lambda v: isinstance(v, list) and len(v) == 3 and all(_is_double(x, null_ok=True) for x in v),
        "mission",
    )
    need(mission, "items", lambda v: isinstance(v, list), "mission")
    need(mission, "firmwareType", _is_double, "mission")
    for key in ("vehicleType", "cruiseSpeed", "hoverSpeed", "globalPlanAltitudeMode"):
        if key in mission and not _is_double(mission[key], null_ok=True):
            problems.append(f"mission: {key} is not a number")
    for n, item in enumerate(mission.get("items", []), start=1):
        where = f"item {n}"
        need(item, "type", lambda v: v == "SimpleItem", where)
        need(item, "frame", _is_double, where)
        need(item, "command", _is_double, where)
        need(item, "autoContinue", lambda v: isinstance(v, bool), where)
        need(
            item,
            "params",
            lambda v: isinstance(v, list) and len(v) == 7 and all(_is_double(x, null_ok=True) for x in v),
            where,
        )
        if "doJumpId" in item and not _is_double(item["doJumpId"]):
            problems.append(f"{where}: doJumpId is not a number")
        altitude_keys = {"AltitudeMode", "Altitude", "AMSLAltAboveTerrain"}
        present = altitude_keys & item.keys()
        if present and present != altitude_keys:
            problems.append(f"{where}: altitude keys {sorted(present)} without the others")
        for key in present:
            if not _is_double(item[key], null_ok=True):
                problems.append(f"{where}: {key} is not a number or null")
    fence = doc.get("geoFence", {})
    need(fence, "version", lambda v: v == 2, "geoFence")
    need(fence, "circles", lambda v: isinstance(v, list), "geoFence")
    need(fence, "polygons", lambda v: isinstance(v, list), "geoFence")
    rally = doc.get("rallyPoints", {})
    need(rally, "version", lambda v: v == 2, "rallyPoints")
    need(rally, "points", lambda v: isinstance(v, list), "rallyPoints")
    return problems


def _strict_json(text: str) -> Any:
    def refuse(constant: str) -> None:
        raise AssertionError(f"{constant} is not JSON")

    return json.loads(text, parse_constant=refuse)


def test_the_loader_rules_catch_a_broken_document() -> None:
    """The oracle itself must be able to fail."""
    doc = plan_document(_survey_mission())
    del doc["geoFence"]
    doc["mission"]["items"][0]["params"] = [0, 0, 0]
    doc["mission"]["items"][0].pop("Altitude")
    problems = _qgc_would_load(doc)
    assert any("geoFence" in p for p in problems)
    assert any("item 1: params" in p for p in problems)
    assert any("altitude keys" in p for p in problems)


def test_plan_has_every_key_qgc_requires(tmp_path: Path) -> None:
    path = write_plan(_survey_mission(), tmp_path / "mission.plan")
    text = path.read_text()
    doc = _strict_json(text)
    assert _qgc_would_load(doc) == []
    assert "NaN" not in text and "Infinity" not in text


@DETERMINISTIC
@given(mission=missions())
def test_random_plans_follow_qgc_rules_and_round_trip_exactly(mission: Mission) -> None:
    text = plan_text(mission)
    assert _qgc_would_load(_strict_json(text)) == []
    assert parse_plan(text) == mission


def test_plan_items_are_written_as_qgc_writes_them() -> None:
    mission = _survey_mission()
    doc = plan_document(mission)
    assert doc["groundStation"] == "sfap"
    m = doc["mission"]
    assert (m["firmwareType"], m["vehicleType"], m["version"]) == (3, 2, 2)
    assert (m["cruiseSpeed"], m["hoverSpeed"]) == (12.0, 8.0)
    assert m["plannedHomePosition"] == [42.1963214, -1.4821598, 281.3]
    assert m["globalPlanAltitudeMode"] == 1  # every positional item is relative to home
    items = m["items"]
    assert [i["doJumpId"] for i in items] == list(range(1, len(items) + 1))
    takeoff = items[0]
    assert takeoff["AltitudeMode"] == 1 and takeoff["Altitude"] == 30.0
    assert takeoff["AMSLAltAboveTerrain"] is None
    assert "Altitude" not in items[1]  # DO_CHANGE_SPEED flies nowhere
    assert items[3]["params"][2:4] == [None, None]  # gimbal manager rates: NaN -> null
    assert items[4]["params"][4:] == [42.197120312345678, -1.483884109876543, 75.6]
    assert items[10]["command"] == 177 and items[10]["params"][0] == 5.0
    assert doc["geoFence"] == {"circles": [], "polygons": [], "version": 2}
    assert doc["rallyPoints"] == {"points": [], "version": 2}


@pytest.mark.parametrize(
    ("autopilot", "vehicle", "firmware_type", "vehicle_type"),
    [
        (Autopilot.ARDUPILOT, VehicleType.MULTIROTOR, 3, 2),
        (Autopilot.PX4, VehicleType.MULTIROTOR, 12, 2),
        (Autopilot.PX4, VehicleType.FIXED_WING, 12, 1),
        (Autopilot.ARDUPILOT, VehicleType.VTOL, 3, 20),
    ],
)
def test_firmware_and_vehicle_type_numbers(
    autopilot: Autopilot, vehicle: VehicleType, firmware_type: int, vehicle_type: int
) -> None:
    base = _survey_mission()
    mission = Mission(items=base.items, home=base.home, autopilot=autopilot, vehicle_type=vehicle)
    doc = plan_document(mission)
    assert doc["mission"]["firmwareType"] == firmware_type  # MAV_AUTOPILOT
    assert doc["mission"]["vehicleType"] == vehicle_type  # MAV_TYPE
    back = parse_plan(json.dumps(doc))
    assert (back.autopilot, back.vehicle_type) == (autopilot, vehicle)


def test_plan_file_round_trip_and_overwrite(tmp_path: Path) -> None:
    mission = _survey_mission()
    path = tmp_path / "mission.plan"
    write_plan(mission, path)
    assert read_plan(path) == mission
    with pytest.raises(OutputExistsError):
        write_plan(mission, path, overwrite=False)
    assert [p.name for p in tmp_path.iterdir()] == ["mission.plan"]


def test_writer_refuses_what_it_could_not_read_back() -> None:
    base = _survey_mission()
    bad_jump = MissionItem(command=MavCmd.DO_JUMP, frame=MavFrame.MISSION, param1=99.0)
    with pytest.raises(MissionValidationError, match=r"item 1 \(DO_JUMP\): param1 99"):
        plan_document(Mission(items=(bad_jump,), home=base.home))
    infinite = MissionItem.waypoint(42.0, -1.0, math.inf)
    with pytest.raises(MissionValidationError, match="param7"):
        plan_document(Mission(items=(infinite,), home=base.home))
    with pytest.raises(MissionValidationError):
        waypoints_text(Mission(items=(infinite,), home=base.home))


def test_qgc_survey_complex_item_is_expanded() -> None:
    doc = json.loads(SURVEY_PLAN.read_text())
    assert _qgc_would_load({**doc, "mission": {**doc["mission"], "items": []}}) == []
    survey = doc["mission"]["items"][3]
    assert (survey["type"], survey["complexItemType"]) == ("ComplexItem", "survey")
    generated = survey["TransectStyleComplexItem"]["Items"]

    mission = read_plan(SURVEY_PLAN)
    assert mission.autopilot is Autopilot.ARDUPILOT
    assert mission.vehicle_type is VehicleType.MULTIROTOR
    assert (mission.cruise_speed_m_s, mission.hover_speed_m_s) == (15.0, 8.0)
    assert mission.home == HomePosition(lat_deg=42.1963214, lon_deg=-1.4821598, alt_amsl_m=281.3)
    assert len(mission.items) == 3 + len(generated) + 1
    expanded = mission.items[3 : 3 + len(generated)]
    for item, raw in zip(expanded, generated, strict=True):
        assert int(item.command) == raw["command"]
        assert int(item.frame) == raw["frame"]
        assert [None if p is None else p for p in item.params] == raw["params"]
    assert [int(i.command) for i in mission.items[:3]] == [22, 178, 205]
    assert mission.items[4].command == MavCmd.DO_SET_CAM_TRIGG_DIST
    assert mission.items[4].param1 == 14.2
    assert mission.items[3].param4 is None  # QGC's transect yaw NaN
    assert mission.items[-1].command == MavCmd.NAV_RETURN_TO_LAUNCH


def test_qgc_px4_vtol_plan_with_corridor_scan_and_jump() -> None:
    mission = read_plan(CORRIDOR_PLAN)
    assert mission.autopilot is Autopilot.PX4
    assert mission.vehicle_type is VehicleType.VTOL  # MAV_TYPE 22, VTOL fixed rotor
    assert mission.metadata["qgc_vehicle_type"] == 22
    assert [int(i.command) for i in mission.items] == [84, 16, 16, 206, 16, 16, 206, 177, 16, 85]
    jump = mission.items[7]
    assert jump.param1 == 2.0 and jump.param2 == 1.0  # doJumpId 2 is the second item
    assert mission.items[8].frame is MavFrame.GLOBAL and mission.items[8].alt_m == 570.5


def test_fixtures_round_trip_through_our_writers(tmp_path: Path) -> None:
    for source in (SURVEY_PLAN, CORRIDOR_PLAN, MP_WAYPOINTS):
        mission = read_mission(source)
        again = read_plan(write_plan(mission, tmp_path / f"{source.stem}.plan"))
        assert again == mission
        wpl = read_waypoints(write_waypoints(mission, tmp_path / f"{source.stem}.waypoints"))
        assert (wpl.items, wpl.home) == (mission.items, mission.home)


def test_do_jump_ids_that_are_not_positions_are_mapped() -> None:
    doc = plan_document(_survey_mission())
    items = doc["mission"]["items"]
    for item in items:
        item["doJumpId"] += 100
    items[10]["params"][0] = 105.0  # DO_JUMP to doJumpId 105, the fifth item
    mission = parse_plan(json.dumps(doc))
    assert mission.items[10].param1 == 5.0
    items[10]["params"][0] = 42.0
    with pytest.raises(MissionFileError, match=r"mission item 11 \(DO_JUMP\).*doJumpId 42"):
        parse_plan(json.dumps(doc), source="jump.plan")


def test_legacy_coordinate_items_are_read() -> None:
    doc = plan_document(_survey_mission())
    first = doc["mission"]["items"][0]
    first["coordinate"] = first["params"][4:]
    first["params"] = first["params"][:4]
    assert parse_plan(json.dumps(doc)).items[0] == _survey_mission().items[0]


def _survey_doc() -> dict[str, Any]:
    doc: dict[str, Any] = json.loads(SURVEY_PLAN.read_text())
    return doc


@pytest.mark.parametrize(
    ("complex_type", "match"),
    [
        ("StructureScan", r"mission item 4 \(StructureScan\).*saves only its settings"),
        ("fwLandingPattern", r"fixed-wing landing pattern"),
        ("spraying", r"complexItemType 'spraying'.*'survey', 'CorridorScan'"),
    ],
)
def test_complex_items_sfap_cannot_expand_are_refused(complex_type: str, match: str) -> None:
    doc = _survey_doc()
    doc["mission"]["items"][3]["complexItemType"] = complex_type
    with pytest.raises(MissionFileError, match=match):
        parse_plan(json.dumps(doc), source="x.plan")


def test_old_survey_without_generated_items_is_refused() -> None:
    doc = _survey_doc()
    survey = doc["mission"]["items"][3]
    survey["version"] = 3
    del survey["TransectStyleComplexItem"]
    with pytest.raises(MissionFileError, match=r"no TransectStyleComplexItem.Items"):
        parse_plan(json.dumps(doc))


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda d: d.update(fileType="Mission"), r"fileType is 'Mission', expected 'Plan'"),
        (lambda d: d.update(version=2), r"plan version is 2, expected 1"),
        (lambda d: d.pop("mission"), r"no 'mission' object"),
        (lambda d: d["mission"].pop("firmwareType"), r"no 'firmwareType' key"),
        (lambda d: d["mission"].update(plannedHomePosition=[1, 2]), r"plannedHomePosition"),
        (lambda d: d["mission"]["items"][0].update(type="Waypoint"), r"item 1 has type 'Waypoint'"),
        (lambda d: d["mission"]["items"][1].update(params=[1, 2]), r"item 2 has 2 params"),
        (lambda d: d["mission"]["items"][1].update(frame=1), r"item 2 frame 1 is not"),
        (lambda d: d["mission"]["items"][1].update(command="WP"), r"item 2 command is 'WP'"),
        (lambda d: d["mission"]["items"][1].update(autoContinue=1), r"autoContinue is 1"),
        (
            lambda d: d["mission"]["items"][1]["params"].__setitem__(1, "fast"),
            r"item 2 param2 is 'fast'",
        ),
        (lambda d: d["mission"].update(cruiseSpeed=-3), r"cruiseSpeed is -3"),
    ],
)
def test_bad_plans_name_what_is_wrong(mutate: Any, match: str) -> None:
    doc = _survey_doc()
    mutate(doc)
    with pytest.raises(MissionFileError, match=match) as info:
        parse_plan(json.dumps(doc), source="bad.plan")
    assert str(info.value).startswith("bad.plan")


def test_broken_json_names_file_and_position(tmp_path: Path) -> None:
    path = tmp_path / "broken.plan"
    path.write_text(SURVEY_PLAN.read_text()[:500])
    for reader in (read_plan, read_mission):
        with pytest.raises(MissionFileError, match=r"broken.plan is not valid JSON \(line \d+"):
            reader(path)


# --- read_mission: detection by content ---------------------------------------------------------


def test_read_mission_detects_the_format_by_content(tmp_path: Path) -> None:
    plan_as_txt = tmp_path / "mission.txt"
    shutil.copy(SURVEY_PLAN, plan_as_txt)
    assert read_mission(plan_as_txt) == read_plan(SURVEY_PLAN)
    wpl_as_plan = tmp_path / "odd.plan"
    shutil.copy(MP_WAYPOINTS, wpl_as_plan)
    assert read_mission(wpl_as_plan).items == read_waypoints(MP_WAYPOINTS).items
    bom = tmp_path / "bom.waypoints"
    bom.write_bytes(b"\xef\xbb\xbf" + MP_WAYPOINTS.read_bytes())
    assert read_mission(bom).items == read_waypoints(MP_WAYPOINTS).items


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"lat,lon,alt\n42.1,-1.5,30\n", r"not a mission file: expected a QGroundControl \.plan"),
        (b"", r"it is empty"),
        (b'{"type": "FeatureCollection"}', r"fileType is None, expected 'Plan'"),
        (b"QGC WPL 100\n", r"QGC WPL 100"),
    ],
)
def test_read_mission_refuses_other_files(tmp_path: Path, content: bytes, match: str) -> None:
    path = tmp_path / "area.csv"
    path.write_bytes(content)
    with pytest.raises(MissionFileError, match=match) as info:
        read_mission(path)
    assert str(path) in str(info.value)


def test_read_mission_missing_file_and_folder(tmp_path: Path) -> None:
    with pytest.raises(MissionFileError, match=r"cannot read .*nope.plan"):
        read_mission(tmp_path / "nope.plan")
    with pytest.raises(MissionFileError, match="is a folder"):
        read_mission(tmp_path)
