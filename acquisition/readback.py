"""Read-back verification: every real difference between the items sent and the items a vehicle
holds, with each autopilot's storage rules (what it changes on the way is not a difference).

ArduPilot (AP_Mission, REFERENCES.md section 3) stores items compressed: hold times in whole
seconds, radii dropped or clamped, altitudes in centimetres, no frame for items without a
location, no autocontinue. PX4 (MavlinkMissionManager) keeps only some fields of positional
items and wraps yaw. Latitude and longitude must match in degE7 exactly, float parameters to
float32; anything else is reported as an :class:`ItemDifference`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from planner.mission import Autopilot, MavCmd, MavFrame, MissionItem, VehicleType

from .mavlink_items import (
    ARDUPILOT_LOCATION_COMMANDS,
    PARAM_NAMES,
    MissionType,
    deg_to_e7,
    float32,
    has_home_item,
    is_global_frame,
    plain_frame,
)


@dataclass(frozen=True, kw_only=True)
class ItemDifference:
    """One way in which an item read back differs from the item sent.

    ``index`` is the item's 1-based position in the mission (None for the item count),
    ``seq`` its index on the vehicle (ArduPilot: home is seq 0, so seq = index).
    """

    index: int | None
    seq: int | None
    command: str
    field: str
    sent: str
    received: str

    def describe(self) -> str:
        if self.index is None:
            return f"{self.field}: sent {self.sent}, read back {self.received}"
        return (
            f"item {self.index} ({self.command}, vehicle seq {self.seq}): {self.field} sent "
            f"{self.sent}, read back {self.received}"
        )

    def to_dict(self) -> dict[str, object]:
        return {
            "index": self.index,
            "seq": self.seq,
            "command": self.command,
            "field": self.field,
            "sent": self.sent,
            "received": self.received,
        }


# How ArduPilot stores items: AP_Mission::mavlink_int_to_mission_cmd packs each command into a
# Mission_Command (``p1`` a uint16_t, the typed Content structs of AP_Mission.h) and
# mission_cmd_to_mavlink_int unpacks it; a param not unpacked there reads back 0. Each rule
# maps the value sent to the value read back (C's float -> integer conversion truncates; the
# ARM targets saturate at the type's range). A parameter passes when it reads back exactly
# (to float32) or as its rule makes it. REFERENCES.md section 3; tests/acquisition/
# test_storage_rules.py quotes the source line of every rule.
_Rule = Callable[[float], float]


def _uint(bits: int) -> _Rule:
    top = float((1 << bits) - 1)
    return lambda v: min(max(float(math.trunc(v)), 0.0), top)


def _int(bits: int) -> _Rule:
    half = float(1 << (bits - 1))
    return lambda v: min(max(float(math.trunc(v)), -half), half - 1.0)


def _zero(_v: float) -> float:
    return 0.0


def _byte_radius(v: float) -> float:  # MIN(0xFF, (uint16_t)param)
    return min(_uint(16)(v), 255.0)


def _signed_uint16(v: float) -> float:  # p1 = fabsf(param); loiter_ccw = param < 0
    return _uint(16)(abs(v)) * (-1.0 if v < 0 else 1.0)


def _direction(v: float) -> float:  # loiter_ccw ? -1 : 1
    return -1.0 if v < 0 else 1.0


def _exit_flag(v: float) -> float:  # loiter_xtrack = (param4 > 0)
    return 1.0 if v > 0 else 0.0


def _loiter_turns_radius(v: float) -> float:  # <= 255 m as a byte, above as a byte of tens
    radius = abs(v)
    stored = _uint(8)(radius) if radius <= 255 else _uint(8)(min(255.0, radius * 0.1)) * 10.0
    return stored * (-1.0 if v < 0 else 1.0)


_U8, _U16, _I8, _I16 = _uint(8), _uint(16), _int(8), _int(16)
_AP_COPTER_WAYPOINT: dict[int, _Rule] = {1: _U16, 2: _zero, 3: _zero, 4: _zero}
_AP_PLANE_WAYPOINT: dict[int, _Rule] = {1: _zero, 2: _byte_radius, 3: _byte_radius, 4: _zero}
_ALL_ZERO: dict[int, _Rule] = {1: _zero, 2: _zero, 3: _zero, 4: _zero}
_AP_RULES: dict[int, dict[int, _Rule]] = {
    MavCmd.NAV_TAKEOFF: {1: _U16, 2: _zero, 3: _zero, 4: _zero},
    MavCmd.NAV_LAND: {1: _U16, 2: _zero, 3: _zero, 4: _direction},
    MavCmd.NAV_LOITER_TO_ALT: {1: _zero, 2: _signed_uint16, 3: _zero, 4: _exit_flag},
    MavCmd.NAV_LOITER_UNLIM: {1: _zero, 2: _zero, 3: _signed_uint16, 4: _zero},
    MavCmd.NAV_LOITER_TURNS: {
        1: lambda v: float(int(_U16(min(255.0, v))) & 0xFF),
        2: _zero,
        3: _loiter_turns_radius,
        4: _exit_flag,
    },
    MavCmd.NAV_LOITER_TIME: {1: _U16, 2: _zero, 3: _direction, 4: _exit_flag},
    MavCmd.NAV_SPLINE_WAYPOINT: {1: _U16, 2: _zero, 3: _zero, 4: _zero},
    MavCmd.NAV_VTOL_TAKEOFF: _ALL_ZERO,
    MavCmd.NAV_VTOL_LAND: {1: _U16, 2: _zero, 3: _zero, 4: _zero},
    MavCmd.NAV_RETURN_TO_LAUNCH: {n: _zero for n in range(1, 8)},
    MavCmd.DO_LAND_START: _ALL_ZERO,
    MavCmd.DO_MOUNT_CONTROL: {4: _zero, 5: _zero, 6: _zero, 7: _zero},
    MavCmd.DO_GIMBAL_MANAGER_PITCHYAW: {
        1: _I8,
        2: _I16,
        3: _I8,
        4: _I8,
        6: _zero,
        # flags (x) and gimbal id (z) are kept as bytes: one that does not fit is a real
        # difference (another gimbal, other flags), not a storage rule
    },
    MavCmd.DO_SET_CAM_TRIGG_DIST: {2: _zero, 3: _U8, 4: _zero},
    MavCmd.DO_CHANGE_SPEED: {1: _U8, 4: _zero},
    MavCmd.IMAGE_START_CAPTURE: {1: _U8, 3: _U16, 4: _U16},
    MavCmd.DO_DIGICAM_CONTROL: {1: _U8, 2: _U8, 3: _I8, 4: _U8, 5: _U8, 6: _U8},
    MavCmd.DO_JUMP: {1: _U16, 2: _I16, 3: _zero, 4: _zero},
}
_AP_ALT_STEP_M = 0.01  # ArduPilot stores altitudes as integer centimetres


def _fmt(value: float | None, n: int, global_frame: bool) -> str:
    if value is None:
        return "none (NaN)"
    if global_frame and n in (5, 6):
        return f"{value:.7f}"
    return f"{value:.6g}"


def _same32(a: float | None, b: float | None) -> bool:
    """Equal as float32 storage makes them. A float parameter travels and is stored as a
    float32, so what comes back is exactly the float32 nearest to what was sent: the tolerance
    is that rounding (half a unit in the 24th significant bit, 2**-24 relative), and anything
    else is a difference. A trigger distance of 11.06 m read back as 11 m (truncated to whole
    metres) is 0.5 % off: different."""
    if a is None or b is None:
        return a is None and b is None
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return float32(a) == float32(b)


# How PX4 stores positional items (MavlinkMissionManager::parse_mavlink_mission_item and
# format_mavlink_mission_item): only the fields it keeps come back, the others read 0, and yaw
# is kept in radians wrapped to -pi..pi ("yaw": the same heading, to 1e-3 deg).
_PX4_RULES: dict[int, dict[int, str]] = {
    MavCmd.NAV_WAYPOINT: {3: "zero", 4: "yaw"},
    MavCmd.NAV_TAKEOFF: {1: "zero", 2: "zero", 3: "zero", 4: "yaw"},
    MavCmd.NAV_LAND: {1: "zero", 3: "zero", 4: "yaw"},
    MavCmd.NAV_LOITER_UNLIM: {1: "zero", 2: "zero", 4: "yaw"},
    MavCmd.NAV_LOITER_TO_ALT: {3: "zero"},
    MavCmd.NAV_VTOL_TAKEOFF: {1: "zero", 2: "zero", 3: "zero", 4: "yaw"},
    MavCmd.NAV_VTOL_LAND: {1: "zero", 2: "zero", 3: "zero", 4: "yaw"},
}


def _yaw_same(sent: float | None, received: float) -> bool:
    """PX4's "yaw": the same heading, wrapped to -180..180, to 1e-3 deg."""
    if sent is None or not math.isfinite(sent) or not math.isfinite(received):
        return False
    turn = (received - sent) % 360.0
    return min(turn, 360.0 - turn) <= 1e-3


def _rule_allows(rule: _Rule | str | None, sent: float | None, received: float | None) -> bool:
    if rule is None or received is None:
        return False
    if rule == "yaw":
        return _yaw_same(sent, received)
    if rule == "zero":
        return received == 0.0
    if isinstance(rule, str):
        return False
    # NaN is stored as 0 where AP_Mission lets it through (sanity_check_params)
    source = 0.0 if sent is None or not math.isfinite(sent) else sent
    return float32(rule(source)) == float32(received)


def _ap_rules(command: int, vehicle_type: VehicleType | None) -> dict[int, _Rule]:
    """The rules of ``command`` (NAV_WAYPOINT: ArduPlane's, for FIXED_WING and VTOL, or
    Copter's); none for a command whose params are stored as float32."""
    if command == MavCmd.NAV_WAYPOINT:
        plane = vehicle_type in (VehicleType.FIXED_WING, VehicleType.VTOL)
        return _AP_PLANE_WAYPOINT if plane else _AP_COPTER_WAYPOINT
    return _AP_RULES.get(command, {})


def _compare_item(
    index: int,
    seq: int,
    sent: MissionItem,
    got: MissionItem,
    autopilot: Autopilot,
    vehicle_type: VehicleType | None,
    mission_type: MissionType,
) -> list[ItemDifference]:
    name = sent.command_name

    def diff(what: str, a: str, b: str) -> ItemDifference:
        return ItemDifference(index=index, seq=seq, command=name, field=what, sent=a, received=b)

    if int(sent.command) != int(got.command):
        return [diff("command", name, got.command_name)]
    ardupilot = autopilot is Autopilot.ARDUPILOT
    fence = mission_type is not MissionType.MISSION
    located = is_global_frame(sent.frame) and (
        not ardupilot or fence or int(sent.command) in ARDUPILOT_LOCATION_COMMANDS
    )
    out: list[ItemDifference] = []
    # Frame: the INT and plain forms mean the same. ArduPilot drops the frame of items that
    # store no location (it reads back 0); fence vertices have no altitude, so no frame.
    frame_matters = not fence and (located or not ardupilot)
    if frame_matters:
        try:
            same = plain_frame(sent.frame) == plain_frame(got.frame)
        except ValueError:
            same = False
        if not same:
            out.append(diff("frame", MavFrame(sent.frame).name, str(got.frame.name)))
    if not ardupilot and sent.autocontinue != got.autocontinue:
        # ArduPilot does not store autocontinue (it always continues) and reads back 1.
        out.append(diff("autocontinue", str(sent.autocontinue), str(got.autocontinue)))
    rules: dict[int, _Rule] | dict[int, str]
    if fence:
        rules = {}
    elif ardupilot:
        rules = _ap_rules(int(sent.command), vehicle_type)
    else:
        rules = _PX4_RULES.get(int(sent.command), {})
    for n in range(1, 8):
        a = sent.params[n - 1]
        b = got.params[n - 1]
        if located and n in (5, 6):
            assert a is not None and b is not None
            if deg_to_e7(a) != deg_to_e7(b):
                label = "latitude" if n == 5 else "longitude"
                out.append(diff(f"{label} (degE7)", _fmt(a, n, True), _fmt(b, n, True)))
            continue
        if located and n == 7:
            assert a is not None and b is not None
            if fence:
                continue
            tolerance = _AP_ALT_STEP_M + 1e-6 * abs(a) if ardupilot else 0.0
            if not (_same32(a, b) or abs(a - b) <= tolerance):
                out.append(diff("altitude (m)", _fmt(a, 7, True), _fmt(b, 7, True)))
            continue
        if n in (5, 6) and not located and b is not None and is_global_frame(got.frame):
            # ArduPilot reads an item without a location back with frame 0 (GLOBAL), so its
            # x and y (DO_GIMBAL_MANAGER_PITCHYAW's flags) arrive as if they were degE7
            b = float(deg_to_e7(b))
        if _same32(a, b) or _rule_allows(rules.get(n), a, b):
            continue
        out.append(diff(PARAM_NAMES[n].split(" (")[0], _fmt(a, n, False), _fmt(b, n, False)))
    return out


def verify_readback(
    sent: Sequence[MissionItem],
    received: Sequence[MissionItem],
    autopilot: Autopilot,
    vehicle_type: VehicleType | None,
    *,
    mission_type: MissionType = MissionType.MISSION,
) -> list[ItemDifference]:
    """Every real difference between the items sent and the items read back.

    ``sent``: the mission's items (no home item). ``received``: as :func:`download_mission`
    returns them (ArduPilot: home first; it is skipped, since the vehicle keeps its own home).
    Latitude and longitude must match in degE7 exactly, float parameters to float32, frames in
    meaning (INT or not). With ArduPilot, what its storage changes is not a difference
    (AP_Mission's packing, command by command, in :data:`_AP_RULES`): frames of items without
    a location, autocontinue, a Copter waypoint's hold time in whole seconds and its dropped
    radii and yaw, a Plane waypoint's dropped hold time and radii clamped to 0-255, a
    take-off's pitch and a landing's abort altitude in whole units, NAV_LAND's param 4 read
    back as -1 or 1, NAV_LOITER_TO_ALT's dropped param 1 (heading required) and param 4 read
    back as 0 or 1, integer gimbal angles, altitudes rounded to centimetres, and the
    parameters it does not store for the DO commands. With PX4, what it does not store for
    positional items (a waypoint's pass radius, a take-off's pitch) and yaw wrapped to
    -180..180 degrees. Anything else is reported.
    """
    skip = 1 if has_home_item(autopilot, mission_type) else 0
    body = list(received[skip:])
    differences: list[ItemDifference] = []
    if skip and not received:
        differences.append(
            ItemDifference(
                index=None,
                seq=None,
                command="",
                field="home item",
                sent="present",
                received="missing (the vehicle reported no items at all)",
            )
        )
    if len(body) != len(sent):
        differences.append(
            ItemDifference(
                index=None,
                seq=None,
                command="",
                field="number of items",
                sent=str(len(sent)),
                received=str(len(body)),
            )
        )
    for i, (a, b) in enumerate(zip(sent, body, strict=False)):
        differences.extend(_compare_item(i + 1, i + skip, a, b, autopilot, vehicle_type, mission_type))
    return differences
