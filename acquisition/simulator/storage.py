"""How ArduPilot and PX4 store mission items, and the conversions to and from the wire.

A :class:`WireItem` is a mission item as MISSION_ITEM_INT carries it. :func:`ardupilot_store`
and :func:`px4_store` return what each autopilot keeps of an uploaded item (as it reads back)
or the MAV_MISSION_RESULT it refuses the item with; :func:`store_item` picks the rule for an
autopilot and a mission type.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from planner.mission import Autopilot, HomePosition, MavCmd, MissionItem, VehicleType

from ..mavlink_items import (
    ARDUPILOT_LOCATION_COMMANDS,
    MissionResult,
    MissionType,
    ardupilot_nan_allowed,
    deg_to_e7,
    e7_to_deg,
    from_mission_item,
    int_frame,
    is_global_frame,
    plain_wire_frame,
)

M = mavlink2  # the message set (ardupilotmega includes common)

MISSION_TYPES = tuple(int(t) for t in MissionType)


@dataclass(frozen=True)
class WireItem:
    """A mission item as MISSION_ITEM_INT carries it (float32 params, degE7 x/y)."""

    frame: int
    command: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float
    autocontinue: int = 1


_F32 = np.float32


def _f32(value: float) -> float:
    return float(_F32(value))


def _c_uint(value: float, bits: int) -> int:
    """A C float -> unsigned integer conversion (truncation, saturated as ARM does)."""
    if math.isnan(value):
        return 0
    return int(min(max(math.trunc(value), 0), (1 << bits) - 1))


def _c_int(value: float, bits: int) -> int:
    if math.isnan(value):
        return 0
    limit = 1 << (bits - 1)
    return int(min(max(math.trunc(value), -limit), limit - 1))


def _c_uint_clamped(value: float, bits: int, limit: int) -> int:
    """``MIN(limit, (uintN_t)value)``: the conversion, then the clamp (AP_Mission's radii)."""
    return min(_c_uint(value, bits), limit)


def _sign_of(value: float) -> float:
    return -1.0 if value < 0 else 1.0


def ardupilot_store(item: WireItem, vehicle_type: VehicleType) -> WireItem | int:
    """What ArduPilot (AP_Mission, 4.5) stores for ``item``, as it will read it back.

    Returns the stored item or a MAV_MISSION_RESULT error code. It copies, command by command,
    AP_Mission::mavlink_int_to_mission_cmd (the packing into Mission_Command: ``p1`` a
    uint16_t, the Content structs of AP_Mission.h) and mission_cmd_to_mavlink_int (the
    unpacking; every param not written there reads back 0, ``autocontinue`` 1):

    - location commands (AP_Mission::stored_in_location) keep degE7 latitude/longitude and
      the altitude in whole centimetres (``alt = packet.z * 100.0f``, an int32: truncated);
      the frame reads back plain (GLOBAL 0, GLOBAL_RELATIVE_ALT 3, GLOBAL_TERRAIN_ALT 10);
      other commands read back with frame 0 and x = y = z = 0 unless the command stores them;
    - NAV_WAYPOINT: ArduPlane (FIXED_WING here) keeps the acceptance and pass
      radii as bytes (``MIN(0xFF, (uint16_t)param)``) and drops the hold time; Copter keeps
      the hold time as ``p1`` (whole seconds) and drops the radii;
    - NAV_TAKEOFF, NAV_LAND: ``p1 = param1`` (pitch; abort altitude); NAV_LAND keeps only the
      sign of param 4 (``loiter_ccw = is_negative(param4)``) and reads it back as -1 or 1;
    - NAV_LOITER_TO_ALT: ``p1 = fabsf(param2)`` with its sign in ``loiter_ccw``, param 4 as
      ``loiter_xtrack = (param4 > 0)``; params 1 and 3 are not stored;
    - NAV_LOITER_UNLIM / _TIME / _TURNS: radius or time in ``p1``, the direction's sign, the
      exit flag;
    - DO_CHANGE_SPEED (uint8 type, float speed and throttle), DO_SET_CAM_TRIGG_DIST (float
      distance, uint8 trigger), DO_MOUNT_CONTROL (float pitch, roll, yaw: the mount mode in
      param 7 is not stored), DO_GIMBAL_MANAGER_PITCHYAW (int8 pitch, int16 yaw, int8 rates,
      uint8 flags in x, uint8 gimbal id in z), DO_DIGICAM_CONTROL (uint8, uint8, int8, uint8;
      uint8 x and y), DO_JUMP, the conditions, IMAGE_START_CAPTURE;
    - DO_LAND_START, NAV_VTOL_TAKEOFF, NAV_RETURN_TO_LAUNCH store nothing but (where they have
      one) the location.

    Commands this table does not know keep params 1-4 as float32 (a simplification: the real
    autopilot refuses a command it does not know with MAV_MISSION_UNSUPPORTED).
    """
    params = (item.param1, item.param2, item.param3, item.param4)
    allowed = ardupilot_nan_allowed(item.command)
    for n, value in enumerate(params, start=1):
        if math.isinf(value) or (math.isnan(value) and n not in allowed):
            return MissionResult.INVALID_PARAM1 + n - 1
    if item.command in (0, 1):
        return MissionResult.INVALID
    land_ccw = not math.isnan(item.param4) and item.param4 < 0  # NAV_LAND: isnan checked first
    p1, p2, p3, p4 = (0.0 if math.isnan(v) else v for v in params)
    cmd = item.command
    # The ArduPlane build. A real quadplane (VTOL) runs ArduPlane too, but this simulator's VTOL
    # flies and announces itself as a quadrotor (HEARTBEAT MAV_TYPE_QUADROTOR), so it stores
    # as ArduCopter, as the ground station that hears it expects.
    plane = vehicle_type is VehicleType.FIXED_WING
    out1 = out2 = out3 = out4 = 0.0
    x = y = 0
    z = 0.0
    frame = 0
    if cmd in ARDUPILOT_LOCATION_COMMANDS:
        plain = plain_wire_frame(item.frame)
        if plain not in (0, 2, 3, 10):
            return MissionResult.UNSUPPORTED_FRAME
        if not (-900_000_000 <= item.x <= 900_000_000):
            return MissionResult.INVALID_PARAM5_X
        if not (-1_800_000_000 <= item.y <= 1_800_000_000):
            return MissionResult.INVALID_PARAM6_Y
        if not math.isfinite(item.z) or abs(item.z) >= 83000:
            return MissionResult.INVALID_PARAM7
        frame = 0 if plain == 2 else plain
        x, y = item.x, item.y
        alt_cm = int(_F32(item.z) * _F32(100.0))  # int32 cast truncates toward zero
        z = float(_F32(alt_cm) / _F32(100.0))
    if cmd == MavCmd.NAV_WAYPOINT:
        if plane:
            out2 = float(_c_uint_clamped(p2, 16, 255))
            out3 = float(_c_uint_clamped(p3, 16, 255))
        else:
            out1 = float(_c_uint(p1, 16))
    elif cmd == MavCmd.NAV_SPLINE_WAYPOINT:
        if plane:
            return MissionResult.UNSUPPORTED
        out1 = float(_c_uint(p1, 16))
    elif cmd == MavCmd.NAV_TAKEOFF:
        out1 = float(_c_uint(p1, 16))
    elif cmd == MavCmd.NAV_LAND:
        out1 = float(_c_uint(p1, 16))
        out4 = -1.0 if land_ccw else 1.0
    elif cmd == MavCmd.NAV_LOITER_TO_ALT:
        out2 = float(_c_uint(abs(p2), 16)) * _sign_of(p2)
        out4 = 1.0 if p4 > 0 else 0.0
    elif cmd == MavCmd.NAV_LOITER_TIME:
        out1 = float(_c_uint(p1, 16))
        out3 = _sign_of(p3)
        out4 = 1.0 if p4 > 0 else 0.0
    elif cmd == MavCmd.NAV_LOITER_TURNS:
        turns = _c_uint(min(255.0, p1), 16)
        radius = abs(p3)
        scaled = radius > 255
        stored_radius = _c_uint(radius, 8) if not scaled else _c_uint(min(255.0, radius * 0.1), 8)
        out1 = float(turns & 0xFF)
        out3 = float(stored_radius) * _sign_of(p3) * (10.0 if scaled else 1.0)
        out4 = 1.0 if p4 > 0 else 0.0
    elif cmd == MavCmd.NAV_LOITER_UNLIM:
        out3 = float(_c_uint(abs(p3), 16)) * _sign_of(p3)
    elif cmd in (MavCmd.NAV_RETURN_TO_LAUNCH, MavCmd.DO_LAND_START, MavCmd.NAV_VTOL_TAKEOFF, 191):
        pass  # nothing but the location (RTL: not even that)
    elif cmd in (MavCmd.NAV_VTOL_LAND, 30, 92, MavCmd.DO_SET_HOME, 201):
        out1 = float(_c_uint(p1, 16))  # cmd.p1 = packet.param1
    elif cmd == 94:  # NAV_PAYLOAD_PLACE: p1 = param1 * 100 (m -> cm), read back / 100
        out1 = float(_F32(_c_uint(p1 * 100, 16)) / _F32(100.0))
    elif cmd == MavCmd.DO_CHANGE_SPEED:
        out1, out2, out3 = float(_c_uint(p1, 8)), _f32(p2), _f32(p3)
    elif cmd == MavCmd.DO_SET_CAM_TRIGG_DIST:
        out1, out3 = _f32(p1), float(_c_uint(p3, 8))
    elif cmd == MavCmd.DO_MOUNT_CONTROL:
        out1, out2, out3 = _f32(p1), _f32(p2), _f32(p3)
    elif cmd == MavCmd.DO_GIMBAL_MANAGER_PITCHYAW:
        out1, out2 = float(_c_int(p1, 8)), float(_c_int(p2, 16))
        out3, out4 = float(_c_int(p3, 8)), float(_c_int(p4, 8))
        x = int(item.x) & 0xFF  # uint8_t flags = packet.x (int32 -> uint8: modulo 256)
        z = float(_c_uint(item.z, 8))  # uint8_t gimbal_id = packet.z
    elif cmd == MavCmd.IMAGE_START_CAPTURE:
        out1 = float(_c_uint(p1, 8))
        out2 = _f32(p2)
        out3 = float(_c_uint(p3, 16))
        out4 = float(_c_uint(p4, 16))
    elif cmd == MavCmd.IMAGE_STOP_CAPTURE:
        out1 = float(_c_uint(p1, 8))
    elif cmd == MavCmd.DO_JUMP:
        out1, out2 = float(_c_uint(p1, 16)), float(_c_int(p2, 16))
    elif cmd in (MavCmd.CONDITION_DELAY, MavCmd.CONDITION_DISTANCE):
        out1 = _f32(p1)
    elif cmd == MavCmd.DO_DIGICAM_CONTROL:
        out1, out2 = float(_c_uint(p1, 8)), float(_c_uint(p2, 8))
        out3, out4 = float(_c_int(p3, 8)), float(_c_uint(p4, 8))
        # shooting command and command id live in x and y (uint8 each)
        x, y = _c_uint(float(item.x), 8), _c_uint(float(item.y), 8)
    elif cmd in ARDUPILOT_LOCATION_COMMANDS:
        out1 = float(_c_uint(p1, 16))
    else:
        out1, out2, out3, out4 = _f32(p1), _f32(p2), _f32(p3), _f32(p4)
        x, y, z = item.x, item.y, _f32(item.z)
        frame = plain_wire_frame(item.frame)
    return WireItem(frame, cmd, out1, out2, out3, out4, x, y, z, 1)


#: What PX4 (MavlinkMissionManager::parse_mavlink_mission_item and
#: format_mavlink_mission_item) does not keep of a positional item, as readback.py's PX4 rules
#: list it: these params read back 0, and param 4 (yaw) comes back wrapped to -180..180 deg
#: (kept in radians, ``_wrap_pi``).
_PX4_DROPPED: dict[int, tuple[int, ...]] = {
    MavCmd.NAV_WAYPOINT: (3,),
    MavCmd.NAV_TAKEOFF: (1, 2, 3),
    MavCmd.NAV_LAND: (1, 3),
    MavCmd.NAV_LOITER_UNLIM: (1, 2),
    MavCmd.NAV_LOITER_TO_ALT: (3,),
    MavCmd.NAV_VTOL_TAKEOFF: (1, 2, 3),
    MavCmd.NAV_VTOL_LAND: (1, 2, 3),
}
_PX4_YAW = frozenset(
    {
        MavCmd.NAV_WAYPOINT,
        MavCmd.NAV_TAKEOFF,
        MavCmd.NAV_LAND,
        MavCmd.NAV_LOITER_UNLIM,
        MavCmd.NAV_VTOL_TAKEOFF,
        MavCmd.NAV_VTOL_LAND,
    }
)


def _px4_yaw(value: float) -> float:
    """Degrees -> radians (float32), wrapped to -pi..pi, -> degrees: PX4's stored yaw."""
    if not math.isfinite(value):
        return _f32(value)
    rad = float(_F32(value) * _F32(math.pi / 180.0))
    rad = math.remainder(rad, 2.0 * math.pi)
    return _f32(math.degrees(_f32(rad)))


def px4_store(item: WireItem, mission_type: int = MissionType.MISSION) -> WireItem | int:
    """What PX4 keeps: params as float32, positions degE7; in a mission, the frame in its
    _INT form for positional items and MAV_FRAME_MISSION (2) for the other commands it knows;
    fence and rally items keep their frame. Of positional items it drops the params in
    :data:`_PX4_DROPPED` and keeps yaw wrapped to -180..180 degrees."""
    try:
        command: MavCmd | None = MavCmd(item.command)
    except ValueError:
        command = None
    frame = item.frame
    params = [_f32(item.param1), _f32(item.param2), _f32(item.param3), _f32(item.param4)]
    if mission_type != MissionType.MISSION or command is None:
        pass
    elif command.is_nav:
        plain = plain_wire_frame(item.frame)
        if plain not in (0, 3, 10):
            return MissionResult.UNSUPPORTED_FRAME
        frame = int(int_frame(plain))
        for n in _PX4_DROPPED.get(command, ()):
            params[n - 1] = 0.0
        if command in _PX4_YAW:
            params[3] = _px4_yaw(params[3])
    else:
        frame = 2
    return WireItem(
        frame,
        item.command,
        params[0],
        params[1],
        params[2],
        params[3],
        item.x,
        item.y,
        _f32(item.z),
        1 if item.autocontinue else 0,
    )


def wire_item_from_message(msg: Any) -> WireItem:
    """MISSION_ITEM_INT (or legacy MISSION_ITEM: float degrees) -> :class:`WireItem`."""
    if msg.get_type() == "MISSION_ITEM":
        if is_global_frame(msg.frame):
            x, y = deg_to_e7(msg.x), deg_to_e7(msg.y)
        else:
            x, y = math.trunc(msg.x), math.trunc(msg.y)
    else:
        x, y = int(msg.x), int(msg.y)
    return WireItem(
        int(msg.frame),
        int(msg.command),
        float(msg.param1),
        float(msg.param2),
        float(msg.param3),
        float(msg.param4),
        x,
        y,
        float(msg.z),
        int(msg.autocontinue),
    )


def wire_item_to_mission_item(item: WireItem) -> MissionItem:
    """The :class:`MissionItem` a ground station reads for this stored item."""
    return from_mission_item(item_int_message(item, 0, 0, 0, 0))


def item_int_message(item: WireItem, seq: int, sysid: int, compid: int, mission_type: int) -> Any:
    return M.MAVLink_mission_item_int_message(
        sysid,
        compid,
        seq,
        item.frame,
        item.command,
        0,
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
        item.x,
        item.y,
        item.z,
        mission_type,
    )


def item_float_message(item: WireItem, seq: int, sysid: int, compid: int, mission_type: int) -> Any:
    if is_global_frame(item.frame):
        x, y = _f32(e7_to_deg(item.x)), _f32(e7_to_deg(item.y))
    else:
        x, y = float(item.x), float(item.y)
    return M.MAVLink_mission_item_message(
        sysid,
        compid,
        seq,
        item.frame,
        item.command,
        0,
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
        x,
        y,
        item.z,
        mission_type,
    )


#: ArduPilot's item 0 before the GPS has a fix (and what it stores for an uploaded item 0).
NO_HOME = WireItem(0, 16, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0)


def home_wire_item(home: HomePosition | None) -> WireItem:
    """ArduPilot's item 0: the home position (altitude AMSL in whole centimetres, as
    AP_Mission keeps it), or zeros while there is none (``home`` None: no GPS fix yet)."""
    if home is None:
        return NO_HOME
    alt_cm = int(_F32(home.alt_amsl_m) * _F32(100.0))
    return WireItem(
        0,
        16,
        0.0,
        0.0,
        0.0,
        0.0,
        deg_to_e7(home.lat_deg),
        deg_to_e7(home.lon_deg),
        float(_F32(alt_cm) / _F32(100.0)),
    )


def store_item(
    item: WireItem, autopilot: Autopilot, vehicle_type: VehicleType, mission_type: int
) -> WireItem | int:
    """What ``autopilot`` keeps of ``item`` uploaded as ``mission_type``, or the
    MAV_MISSION_RESULT it refuses the item with. Fence and rally items: PX4's rule; ArduPilot
    keeps them as float32 without checking them."""
    if mission_type != MissionType.MISSION:
        if autopilot is Autopilot.PX4:
            return px4_store(item, mission_type)
        return dataclasses.replace(
            item,
            param1=_f32(item.param1),
            param2=_f32(item.param2),
            param3=_f32(item.param3),
            param4=_f32(item.param4),
            z=_f32(item.z),
        )
    if autopilot is Autopilot.ARDUPILOT:
        return ardupilot_store(item, vehicle_type)
    return px4_store(item)
