"""Flight modes of the simulated vehicle and how each autopilot numbers them on the wire.

:class:`Mode` is what the vehicle does, whatever its autopilot calls it. ArduPilot sends its
mode as HEARTBEAT ``custom_mode`` from its mode tables (ArduCopter and ArduPlane differ); PX4
packs a main mode and an AUTO sub mode into it (px4_custom_mode.h). SET_MODE and DO_SET_MODE
carry the same numbers back.
"""

from __future__ import annotations

from enum import Enum

from planner.mission import Autopilot, VehicleType

from .. import mavlink_messages as mm

#: ArduCopter / ArduPlane custom mode numbers (ArduPilot's mode tables).
COPTER_MODES = {"STABILIZE": 0, "AUTO": 3, "GUIDED": 4, "LOITER": 5, "RTL": 6, "LAND": 9}
PLANE_MODES = {"MANUAL": 0, "AUTO": 10, "RTL": 11, "LOITER": 12, "GUIDED": 15}
#: PX4 main modes and AUTO sub-modes (px4_custom_mode.h).
PX4_MAIN_MANUAL, PX4_MAIN_ALTCTL, PX4_MAIN_POSCTL, PX4_MAIN_AUTO = 1, 2, 3, 4
PX4_SUB_AUTO = {"READY": 1, "TAKEOFF": 2, "LOITER": 3, "MISSION": 4, "RTL": 5, "LAND": 6}


class Mode(Enum):
    """What the vehicle is doing, whatever its autopilot calls it."""

    MANUAL = "manual"  # STABILIZE / MANUAL / POSCTL: holds still in this simulator
    AUTO = "auto"
    GUIDED = "guided"
    LOITER = "loiter"
    RTL = "rtl"
    LAND = "land"


#: The modes in which the vehicle flies its legs by itself.
FLYING_MODES = frozenset({Mode.AUTO, Mode.RTL, Mode.LAND})

_PX4_MODE = {
    Mode.MANUAL: (PX4_MAIN_POSCTL, 0),
    Mode.AUTO: (PX4_MAIN_AUTO, PX4_SUB_AUTO["MISSION"]),
    Mode.GUIDED: (PX4_MAIN_AUTO, PX4_SUB_AUTO["LOITER"]),
    Mode.LOITER: (PX4_MAIN_AUTO, PX4_SUB_AUTO["LOITER"]),
    Mode.RTL: (PX4_MAIN_AUTO, PX4_SUB_AUTO["RTL"]),
    Mode.LAND: (PX4_MAIN_AUTO, PX4_SUB_AUTO["LAND"]),
}
_PX4_SUB_MODE = {"MISSION": Mode.AUTO, "RTL": Mode.RTL, "LAND": Mode.LAND, "LOITER": Mode.LOITER}
_ARDUPILOT_MODE = {
    "AUTO": Mode.AUTO,
    "GUIDED": Mode.GUIDED,
    "LOITER": Mode.LOITER,
    "RTL": Mode.RTL,
    "LAND": Mode.LAND,
}


def heartbeat(autopilot: Autopilot, vehicle_type: VehicleType, mode: Mode, armed: bool) -> mm.Heartbeat:
    """The vehicle's HEARTBEAT: its type, autopilot, base mode flags and custom mode."""
    plane = vehicle_type is VehicleType.FIXED_WING
    base = mm.MODE_FLAG_CUSTOM_MODE_ENABLED | mm.MODE_FLAG_STABILIZE_ENABLED
    if armed:
        base |= mm.MODE_FLAG_SAFETY_ARMED
    if mode in (Mode.AUTO, Mode.RTL, Mode.LAND, Mode.LOITER, Mode.GUIDED):
        base |= mm.MODE_FLAG_GUIDED_ENABLED
    if mode in FLYING_MODES:
        base |= mm.MODE_FLAG_AUTO_ENABLED
    if autopilot is Autopilot.PX4:
        main, sub = _PX4_MODE[mode]
        custom = (main << 16) | (sub << 24)
    else:
        name = {
            Mode.MANUAL: "MANUAL" if plane else "STABILIZE",
            Mode.AUTO: "AUTO",
            Mode.GUIDED: "GUIDED",
            Mode.LOITER: "LOITER",
            Mode.RTL: "RTL",
            Mode.LAND: "RTL" if plane else "LAND",
        }[mode]
        custom = (PLANE_MODES if plane else COPTER_MODES)[name]
    ardupilot = autopilot is Autopilot.ARDUPILOT
    return mm.Heartbeat(
        mav_type=mm.MAV_TYPE_FIXED_WING if plane else mm.MAV_TYPE_QUADROTOR,
        autopilot=mm.MAV_AUTOPILOT_ARDUPILOTMEGA if ardupilot else mm.MAV_AUTOPILOT_PX4,
        base_mode=base,
        custom_mode=custom,
        system_status=mm.MAV_STATE_ACTIVE if armed else mm.MAV_STATE_STANDBY,
    )


def split_custom_mode(autopilot: Autopilot, custom_mode: int) -> tuple[int, int]:
    """SET_MODE's custom_mode as DO_SET_MODE's (param2, param3)."""
    if autopilot is Autopilot.PX4:
        return (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
    return int(custom_mode), 0


def mode_from_numbers(autopilot: Autopilot, vehicle_type: VehicleType, p2: int, p3: int) -> Mode | None:
    """The :class:`Mode` of DO_SET_MODE's param2 (custom or PX4 main mode) and param3 (PX4 sub
    mode); None for a mode this simulator does not know."""
    if autopilot is Autopilot.PX4:
        if p2 == PX4_MAIN_AUTO:
            for name, sub in PX4_SUB_AUTO.items():
                if sub == p3:
                    return _PX4_SUB_MODE.get(name, Mode.LOITER)
            return None
        if p2 in (PX4_MAIN_MANUAL, PX4_MAIN_ALTCTL, PX4_MAIN_POSCTL):
            return Mode.MANUAL
        return None
    table = PLANE_MODES if vehicle_type is VehicleType.FIXED_WING else COPTER_MODES
    for name, number in table.items():
        if number == p2:
            return _ARDUPILOT_MODE.get(name, Mode.MANUAL)
    return None


def is_custom_mode(base_mode: int) -> bool:
    """DO_SET_MODE's param1 says the custom mode (param2) is meant."""
    return bool(base_mode & mm.MODE_FLAG_CUSTOM_MODE_ENABLED)
