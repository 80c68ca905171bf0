"""The MAVLink adapter for mission items: the only module that knows MISSION_ITEM_INT, and degE7 (its
constants in :mod:`acquisition.mavlink_units`, which needs no pymavlink).

It also holds the mission protocol's constants that the ground station and the simulated
vehicle share: :class:`MissionType`, :class:`MissionResult` (MAV_MISSION_RESULT), ArduPilot's
home item (:func:`has_home_item`), the commands ArduPilot stores with a location
(:data:`ARDUPILOT_LOCATION_COMMANDS`) and the parameters it lets be NaN
(:func:`ardupilot_nan_allowed`).

Everything above it (:mod:`acquisition.transfer`, the CLI) speaks
:class:`planner.mission.MissionItem`: WGS84 degrees, metres, None for "no value". This module
turns such an item into the MISSION_ITEM_INT message that goes on the wire, and the
MISSION_ITEM_INT (or the legacy MISSION_ITEM) a vehicle sends back into an item.

Conventions on the wire (MAVLink common.xml, "Mission Protocol" on mavlink.io):

- Global frames: ``x``/``y`` are latitude/longitude in degE7 (int32, rounded to nearest),
  ``z`` the altitude in metres (float32) in the frame's reference (AMSL, above home, above
  terrain). ``MAV_FRAME_MISSION`` items carry params 5/6 as plain integers in ``x``/``y``
  (the INT message has no room for a fraction there, as QGroundControl also does).
- Frames are sent in their plain form (GLOBAL, GLOBAL_RELATIVE_ALT, GLOBAL_TERRAIN_ALT): the
  ``_INT`` variants mean the same (MAVLink deprecated them in 2024) and every autopilot accepts
  both. Items read back are normalized the same way, so an ``_INT`` frame from a vehicle
  compares equal to its plain twin.
- Params 1-4: None is sent as NaN ("leave unchanged") and NaN reads back as None.
"""

from __future__ import annotations

import math
import struct
from enum import IntEnum
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from planner.mission import Autopilot, HomePosition, MavCmd, MavFrame, MissionItem

from .mavlink_units import E7_PER_DEG


class MissionType(IntEnum):
    """MAV_MISSION_TYPE: which of the vehicle's lists a transfer addresses."""

    MISSION = 0
    FENCE = 1
    RALLY = 2


class MissionResult(IntEnum):
    """MAV_MISSION_RESULT: how a vehicle answers a mission transfer (MISSION_ACK.type)."""

    ACCEPTED = 0
    ERROR = 1
    UNSUPPORTED_FRAME = 2
    UNSUPPORTED = 3
    NO_SPACE = 4
    INVALID = 5
    INVALID_PARAM1 = 6
    INVALID_PARAM2 = 7
    INVALID_PARAM3 = 8
    INVALID_PARAM4 = 9
    INVALID_PARAM5_X = 10
    INVALID_PARAM6_Y = 11
    INVALID_PARAM7 = 12
    INVALID_SEQUENCE = 13
    DENIED = 14
    OPERATION_CANCELLED = 15


#: What params 1-7 of a mission item are called in messages to a person.
PARAM_NAMES = {
    1: "param 1",
    2: "param 2",
    3: "param 3",
    4: "param 4",
    5: "param 5 (latitude)",
    6: "param 6 (longitude)",
    7: "param 7 (altitude)",
}


def has_home_item(autopilot: Autopilot, mission_type: MissionType | int) -> bool:
    """True when the vehicle keeps its home as item 0 of the list (ArduPilot's mission; PX4
    has no home item, and fences and rally points have none)."""
    return autopilot is Autopilot.ARDUPILOT and int(mission_type) == MissionType.MISSION


#: Commands ArduPilot stores with a location (AP_Mission::stored_in_location): params 5-7 are
#: latitude, longitude and altitude in a global frame, and read back so. The navigation
#: commands with a position (:attr:`planner.mission.MavCmd.is_nav`: WAYPOINT, LOITER_UNLIM,
#: LOITER_TURNS, LOITER_TIME, LAND, TAKEOFF, LOITER_TO_ALT, SPLINE_WAYPOINT, VTOL_TAKEOFF,
#: VTOL_LAND), NAV_CONTINUE_AND_CHANGE_ALT (30), NAV_GUIDED_ENABLE (92), NAV_PAYLOAD_PLACE (94),
#: DO_SET_HOME, DO_LAND_START, DO_GO_AROUND (191) and DO_SET_ROI (201).
ARDUPILOT_LOCATION_COMMANDS: frozenset[int] = frozenset(
    {int(command) for command in MavCmd if command.is_nav}
    | {30, 92, 94, MavCmd.DO_SET_HOME, MavCmd.DO_LAND_START, 191, 201}
)

#: AP_Mission::sanity_check_params: the params (1-4) that may be NaN, per command; any other
#: NaN is refused with MAV_MISSION_INVALID_PARAMn.
_ARDUPILOT_NAN_ALLOWED: dict[int, frozenset[int]] = {
    MavCmd.NAV_WAYPOINT: frozenset({4}),
    MavCmd.NAV_LAND: frozenset({4}),
    MavCmd.NAV_TAKEOFF: frozenset({4}),
    MavCmd.NAV_VTOL_TAKEOFF: frozenset({4}),
    MavCmd.NAV_VTOL_LAND: frozenset({3, 4}),
}


def ardupilot_nan_allowed(command: int) -> frozenset[int]:
    """The params (1-4) of ``command`` that ArduPilot accepts as NaN ("leave unchanged")."""
    return _ARDUPILOT_NAN_ALLOWED.get(int(command), frozenset())


#: INT frame -> the plain frame with the same meaning.
_PLAIN_FRAME = {
    MavFrame.GLOBAL_INT: MavFrame.GLOBAL,
    MavFrame.GLOBAL_RELATIVE_ALT_INT: MavFrame.GLOBAL_RELATIVE_ALT,
    MavFrame.GLOBAL_TERRAIN_ALT_INT: MavFrame.GLOBAL_TERRAIN_ALT,
}
_INT_FRAME = {plain: int_frame for int_frame, plain in _PLAIN_FRAME.items()}

#: Frame numbers that are not in :class:`MavFrame` but that some vehicles send for
#: non-positional items (MAV_FRAME_LOCAL_NED 1 is what a few firmwares put on DO commands).
_NON_GLOBAL_WIRE_FRAMES = frozenset({1, 4, 7, 8, 9})


def deg_to_e7(value_deg: float) -> int:
    """Degrees -> degE7 integer, rounded to the nearest unit (0.011 m of latitude)."""
    return math.floor(value_deg * E7_PER_DEG + 0.5)


def e7_to_deg(value_e7: int) -> float:
    """degE7 integer -> degrees."""
    return value_e7 / E7_PER_DEG


def plain_frame(frame: MavFrame | int) -> MavFrame:
    """The plain (non-INT) frame that means the same as ``frame``."""
    value = MavFrame(int(frame))
    return _PLAIN_FRAME.get(value, value)


def plain_wire_frame(frame: int) -> int:
    """Like :func:`plain_frame` for a frame number off the wire: numbers that are not a
    :class:`MavFrame` (local frames) pass through unchanged."""
    try:
        return int(plain_frame(frame))
    except ValueError:
        return int(frame)


def int_frame(frame: MavFrame | int) -> MavFrame:
    """The ``_INT`` variant of a global frame (MAV_FRAME_MISSION has none and is returned)."""
    value = plain_frame(frame)
    return _INT_FRAME.get(value, value)


def is_global_frame(frame: MavFrame | int) -> bool:
    """True when params 5/6 are latitude/longitude (any GLOBAL* frame, INT or not)."""
    try:
        return MavFrame(int(frame)).is_global
    except ValueError:
        return False


def float32(value: float) -> float:
    """``value`` as MAVLink carries it in a float field (IEEE single precision)."""
    return float(struct.unpack("<f", struct.pack("<f", value))[0])


def _param_out(value: float | None) -> float:
    return math.nan if value is None else float(value)


def _param_in(value: float) -> float | None:
    return None if math.isnan(value) else float(value)


def to_mission_item_int(
    item: MissionItem,
    seq: int,
    target_system: int,
    target_component: int,
    mission_type: MissionType | int = MissionType.MISSION,
) -> Any:
    """The MISSION_ITEM_INT message (pymavlink, MAVLink 2) that carries ``item`` as ``seq``.

    ``seq`` is the item's index on the vehicle (ArduPilot: 1 for the first item after home).
    """
    frame = plain_frame(item.frame)
    if frame.is_global:
        x = deg_to_e7(item.param5)
        y = deg_to_e7(item.param6)
    else:
        x = round(item.param5)
        y = round(item.param6)
    return mavlink2.MAVLink_mission_item_int_message(
        target_system=target_system,
        target_component=target_component,
        seq=seq,
        frame=int(frame),
        command=int(item.command),
        current=0,
        autocontinue=1 if item.autocontinue else 0,
        param1=_param_out(item.param1),
        param2=_param_out(item.param2),
        param3=_param_out(item.param3),
        param4=_param_out(item.param4),
        x=x,
        y=y,
        z=float(item.param7),
        mission_type=int(mission_type),
    )


def from_mission_item(msg: Any) -> MissionItem:
    """A MISSION_ITEM_INT or legacy MISSION_ITEM message -> :class:`MissionItem`.

    The frame is normalized to its plain form. Frames that are not global and not in
    :class:`MavFrame` (a local frame on a DO command) become ``MavFrame.MISSION``: their
    params 5-7 are plain numbers either way. Raises ValueError for another message type.
    """
    kind = msg.get_type()
    if kind not in ("MISSION_ITEM_INT", "MISSION_ITEM"):
        raise ValueError(f"not a mission item message: {kind}")
    raw_frame = int(msg.frame)
    frame = MavFrame.MISSION if raw_frame in _NON_GLOBAL_WIRE_FRAMES else plain_frame(raw_frame)
    if kind == "MISSION_ITEM_INT":
        if frame.is_global:
            param5 = e7_to_deg(int(msg.x))
            param6 = e7_to_deg(int(msg.y))
        else:
            param5 = float(msg.x)
            param6 = float(msg.y)
    else:
        # Legacy MISSION_ITEM carries degrees as float32: no better than ~1 m of precision.
        param5 = float(msg.x)
        param6 = float(msg.y)
    return MissionItem(
        command=int(msg.command),
        frame=frame,
        param1=_param_in(msg.param1),
        param2=_param_in(msg.param2),
        param3=_param_in(msg.param3),
        param4=_param_in(msg.param4),
        param5=param5,
        param6=param6,
        param7=float(msg.z),
        autocontinue=bool(msg.autocontinue),
    )


def home_from_message(msg: Any) -> HomePosition:
    """HOME_POSITION (latitude/longitude degE7, altitude mm AMSL) -> :class:`HomePosition`."""
    if msg.get_type() != "HOME_POSITION":
        raise ValueError(f"not a HOME_POSITION message: {msg.get_type()}")
    return HomePosition(
        lat_deg=e7_to_deg(int(msg.latitude)),
        lon_deg=e7_to_deg(int(msg.longitude)),
        alt_amsl_m=int(msg.altitude) / 1000.0,
    )
