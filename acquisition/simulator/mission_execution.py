"""Mission execution of the simulated vehicle, as ArduPilot's AP_Mission runs a mission.

The DO commands that follow a NAV command run when that NAV command completes (those before
the first NAV command run at the start): :func:`run_do_commands_from`. A NAV command becomes
legs to fly (:func:`start_nav`; :mod:`.kinematics`); the camera's DO commands are
:mod:`.triggering`'s, DO_CHANGE_SPEED, the gimbal's and DO_JUMP are here. RTL climbs to
``rtl_alt_m`` if lower, flies home, descends and disarms, as ArduCopter does. PX4 does the same
for these commands. A multirotor holds a waypoint's param1 seconds; a plane ignores it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from planner.mission import MavCmd, MavFrame, MissionItem, VehicleType

from .. import mavlink_messages as mm
from . import plane
from .kinematics import Leg
from .modes import Mode
from .triggering import Gimbal

if TYPE_CHECKING:
    from .flight import FlightSimulator

_CAMERA_COMMANDS = frozenset(
    {
        MavCmd.DO_SET_CAM_TRIGG_DIST,
        MavCmd.IMAGE_START_CAPTURE,
        MavCmd.IMAGE_STOP_CAPTURE,
        MavCmd.DO_SET_CAM_TRIGG_INTERVAL,
        MavCmd.DO_DIGICAM_CONTROL,
    }
)


def is_nav(command: int) -> bool:
    """A NAV command (one the vehicle flies), RTL included."""
    try:
        cmd = MavCmd(int(command))
    except ValueError:
        return False
    return cmd.is_nav or cmd is MavCmd.NAV_RETURN_TO_LAUNCH


def begin_mission(sim: FlightSimulator, restart: bool) -> None:
    m = sim.mission
    if restart:
        m.current = sim.first_index
        m.complete = False
        m.jumps_left = {}
    m.started = True
    run_do_commands_from(sim, m.current)


# --- mission execution --------------------------------------------------------------------


def item_xyz(sim: FlightSimulator, item: MissionItem) -> tuple[float, float, float]:
    frame = MavFrame(int(item.frame))
    # relative to home unless absolute; terrain frames are flat at home level in this simulator
    absolute = frame in (MavFrame.GLOBAL, MavFrame.GLOBAL_INT)
    z = item.alt_m - sim.home.alt_amsl_m if absolute else item.alt_m
    if item.lat_deg == 0.0 and item.lon_deg == 0.0:
        return sim.pos[0], sim.pos[1], z
    x, y = sim.frame.to_xy(item.lon_deg, item.lat_deg)
    return float(x), float(y), z


def run_do_commands_from(sim: FlightSimulator, index: int) -> None:
    """Run DO commands from ``index`` up to the next NAV command, then start that one."""
    items = sim.mission.items
    i = index
    guard = 0
    while i < len(items):
        guard += 1
        if guard > 10_000:
            break
        item = items[i]
        if is_nav(item.command):
            start_nav(sim, i)
            return
        jump = do_command(sim, i, item)
        i = jump if jump is not None else i + 1
    sim.mission.current = max(len(items) - 1, 0)
    mission_complete(sim)


def mission_complete(sim: FlightSimulator) -> None:
    sim.mission.complete = True
    sim.legs = [Leg(None, forever=True)] if sim.airborne else []
    sim.after_legs = None


def start_nav(sim: FlightSimulator, index: int) -> None:
    m = sim.mission
    m.current = index
    item = m.items[index]
    cmd = int(item.command)
    sim.legs = []
    sim.after_legs = "nav_done"
    copter = sim.vehicle_type is not VehicleType.FIXED_WING
    if cmd == MavCmd.NAV_TAKEOFF and not copter:
        sim.legs = [_plane_climb_out(sim, item)]
        sim.plane_last_wp = None  # the first waypoint is flown from where the climb ends
        sim.has_flown = True
    elif cmd == MavCmd.NAV_TAKEOFF:
        _, _, z = item_xyz(sim, item)
        sim.legs = [Leg((sim.pos[0], sim.pos[1], max(z, sim.pos[2])))]
        sim.has_flown = True
    elif cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
        plan_rtl(sim, from_mission=True)
    elif cmd in (MavCmd.NAV_LAND, MavCmd.NAV_VTOL_LAND):
        x, y, _ = item_xyz(sim, item)
        if copter:
            sim.legs = [Leg((x, y, sim.pos[2])), Leg((x, y, 0.0))]
        else:  # a plane flies its approach to the land point, then (simplified) sinks there
            sim.legs = [Leg((x, y, sim.pos[2]), plane=True, track_from=sim.plane_last_wp), Leg((x, y, 0.0))]
        sim.after_legs = "landed"
    else:
        target = item_xyz(sim, item)
        if not sim.airborne and target[2] > 0:
            sim.has_flown = True
        if copter:
            sim.legs = [Leg(target)]
        else:
            sim.legs = [_plane_leg(sim, index, target)]
        hold = 0.0
        waypoint = cmd in (MavCmd.NAV_WAYPOINT, MavCmd.NAV_SPLINE_WAYPOINT)
        if (waypoint and copter) or cmd == MavCmd.NAV_LOITER_TIME:
            hold = float(item.param1 or 0.0)  # Plane ignores a waypoint's hold time
        if cmd == MavCmd.NAV_LOITER_UNLIM:
            sim.legs.append(Leg(None, forever=True))
        elif hold > 0:
            sim.legs.append(Leg(None, wait_s=hold))
    sim.queue_mission_current()


def _plane_climb_out(sim: FlightSimulator, item: MissionItem) -> Leg:
    """ArduPlane's take-off: straight ahead at the minimum pitch (param 1; 15 degrees if 0)
    until the altitude, along the heading the plane is launched on (toward the item's position
    when it has one, as the crew points the plane down the planned take-off course)."""
    x, y, z = item_xyz(sim, item)
    if math.hypot(x - sim.pos[0], y - sim.pos[1]) > 1.0:
        sim.heading_deg = math.degrees(math.atan2(x - sim.pos[0], y - sim.pos[1])) % 360.0
    pitch = math.radians(float(item.param1 or 0.0) or 15.0)
    climb = max(z - sim.pos[2], 0.0)
    run = climb / math.tan(pitch)
    h = math.radians(sim.heading_deg)
    target = (sim.pos[0] + run * math.sin(h), sim.pos[1] + run * math.cos(h), max(z, sim.pos[2]))
    return Leg(target, climb_rate_m_s=sim.speed_m_s * math.tan(pitch))


def _next_position(sim: FlightSimulator, index: int) -> tuple[float, float] | None:
    """Where the NAV command after ``index`` goes (None: no next position), following DO_JUMP
    as AP_Mission::get_next_nav_cmd does."""
    items = sim.mission.items
    i, seen = index + 1, 0
    while 0 <= i < len(items) and seen < len(items):
        seen += 1
        item = items[i]
        if item.command == MavCmd.DO_JUMP:
            i = int(item.param1 or 0)
            continue
        if is_nav(item.command):
            if item.command == MavCmd.NAV_RETURN_TO_LAUNCH:
                return (0.0, 0.0)
            if item.lat_deg == 0.0 and item.lon_deg == 0.0:
                return None
            x, y, _ = item_xyz(sim, item)
            return x, y
        i += 1
    return None


def _plane_leg(sim: FlightSimulator, index: int, target: tuple[float, float, float]) -> Leg:
    """A plane's leg to ``target``: tracked from the last waypoint reached, counted reached
    within the turn distance of the coming turn (Plane::verify_nav_wp)."""
    start = sim.plane_last_wp or (sim.pos[0], sim.pos[1])
    accept = 0.0
    nxt = _next_position(sim, index)
    here = (target[0], target[1])
    if nxt is not None and math.dist(here, nxt) > 1e-3 and math.dist(start, here) > 1e-3:
        angle = plane.turn_angle_deg(start, here, nxt)
        accept = sim.plane_tuning.turn_distance_m(sim.speed_m_s, angle)
    return Leg(target, plane=True, track_from=sim.plane_last_wp, accept_m=accept)


def nav_done(sim: FlightSimulator) -> None:
    m = sim.mission
    seq = m.current
    sim.reached.append((sim.time_s, seq))
    sim.queue_message(mm.mission_item_reached_message(seq))
    run_do_commands_from(sim, seq + 1)


def do_command(sim: FlightSimulator, index: int, item: MissionItem) -> int | None:
    """Run one DO command; returns the index to continue at for DO_JUMP."""
    cmd = int(item.command)
    p = [0.0 if v is None else float(v) for v in item.params]
    sim.mission.current = index
    if cmd == MavCmd.DO_CHANGE_SPEED:
        if p[1] > 0:
            sim.speed_m_s = p[1]
    elif cmd in _CAMERA_COMMANDS:
        if sim.camera.command(cmd, p, sim.time_s):
            sim.take_photo()
    elif cmd == MavCmd.DO_MOUNT_CONTROL:
        sim.gimbal = Gimbal(pitch_deg=p[0], roll_deg=p[1], yaw_deg=p[2])
        sim.gimbal_commanded = True
    elif cmd == MavCmd.DO_GIMBAL_MANAGER_PITCHYAW:
        sim.gimbal = Gimbal(pitch_deg=p[0], yaw_deg=p[1])
        sim.gimbal_commanded = True
    elif cmd == MavCmd.DO_JUMP:
        target, repeat = int(p[0]), int(p[1])
        left = sim.mission.jumps_left.setdefault(index, repeat)
        if 0 <= target < len(sim.mission.items) and (left > 0 or repeat < 0):
            if repeat >= 0:
                sim.mission.jumps_left[index] = left - 1
            return target
    return None


def plan_rtl(sim: FlightSimulator, from_mission: bool = False) -> None:
    climb_to = max(sim.pos[2], sim.config.rtl_alt_m)
    sim.legs = []
    if sim.airborne or from_mission:
        sim.legs.append(Leg((sim.pos[0], sim.pos[1], climb_to)))
        sim.legs.append(Leg((0.0, 0.0, climb_to)))
        sim.legs.append(Leg((0.0, 0.0, 0.0)))
        sim.after_legs = "landed"
        if from_mission:
            sim.queue_mission_current()


def plan_land_here(sim: FlightSimulator) -> None:
    sim.legs = [Leg((sim.pos[0], sim.pos[1], 0.0))] if sim.airborne else []
    sim.after_legs = "landed" if sim.legs else None


def landed(sim: FlightSimulator) -> None:
    sim.pos[2] = 0.0
    sim.vel = (0.0, 0.0, 0.0)
    sim.armed = False
    sim.has_landed_after_flight = True
    sim.mission.complete = True
    sim.legs = []
    sim.after_legs = None


def finish_legs(sim: FlightSimulator) -> None:
    """The legs are flown: what was to follow them (the NAV command done, or the landing)."""
    after = sim.after_legs
    sim.after_legs = None
    if after == "landed":
        landed(sim)
    elif after == "nav_done" and sim.mode is Mode.AUTO:
        nav_done(sim)
