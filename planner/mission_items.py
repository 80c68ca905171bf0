"""The mission items of a flight path (planner.flight_path), emitted once, at the end of planning.

Items per line, distance triggering (as QGroundControl with "images in turnarounds" off,
REFERENCES.md section 2): [transit waypoints around no-fly zones], [gimbal command when the pose
changes], WP(entry), WP(camera on) + DO_SET_CAM_TRIGG_DIST(d, 0, 1), WP(camera off) +
DO_SET_CAM_TRIGG_DIST(0, 0, 0), WP(exit). The trigger fires once on reaching the camera-on point
(param 3 = 1), then every d metres. Hover triggering: WP(station, hold) + IMAGE_START_CAPTURE(0, 0,
1) at every station. With a transit speed, DO_CHANGE_SPEED after the entry and after the exit.

What differs between autopilots and vehicles sits in small helpers chosen by what the vehicle
can do: the gimbal command (:class:`MountControl` for ArduPilot's DO_MOUNT_CONTROL, yaw relative
to the vehicle; :class:`GimbalManager` for PX4's DO_GIMBAL_MANAGER_PITCHYAW, earth-frame locks),
the take-off (a multirotor climbs over home, a plane climbs out at its pitch toward a point), and
the end (return to launch, or a plane's landing sequence at its approach point).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from .fixed_wing import FixedWing
from .flight_path import CameraPose, FlightPath, PathPoint, Role
from .geo import LocalFrame
from .mission import Autopilot, HomePosition, Mission, MissionItem
from .spec import MissionSpec


class GimbalCommands(Protocol):
    """How one autopilot is told the camera's pose."""

    def state(self, pose: CameraPose) -> tuple[float, float]:
        """What the autopilot holds after the command (a repeat is not sent)."""
        ...

    def item(self, pose: CameraPose) -> MissionItem: ...


class MountControl:
    """DO_MOUNT_CONTROL (MAVLINK_TARGETING, stabilised): pitch, yaw relative to the vehicle."""

    def state(self, pose: CameraPose) -> tuple[float, float]:
        return (pose.pitch_deg, pose.yaw_deg)

    def item(self, pose: CameraPose) -> MissionItem:
        return MissionItem.gimbal_pitch_yaw(pose.pitch_deg, pose.yaw_deg)


class GimbalManager:
    """DO_GIMBAL_MANAGER_PITCHYAW with pitch and roll locked to the earth; an oblique's yaw is
    its true look bearing, locked too, so it looks there even when the vehicle crabs."""

    def state(self, pose: CameraPose) -> tuple[float, float]:
        look = pose.look_true_deg
        return (pose.pitch_deg, wrap180(look) if look is not None else pose.yaw_deg)

    def item(self, pose: CameraPose) -> MissionItem:
        if pose.look_true_deg is not None:
            return MissionItem.gimbal_manager_pitch_yaw(
                pose.pitch_deg, wrap180(pose.look_true_deg), yaw_earth_frame=True
            )
        return MissionItem.gimbal_manager_pitch_yaw(pose.pitch_deg, pose.yaw_deg)


#: The gimbal protocol each autopilot speaks (any other: MountControl, MAVLink's common one).
GIMBAL_COMMANDS: dict[Autopilot, GimbalCommands] = {Autopilot.PX4: GimbalManager()}


def gimbal_commands(autopilot: Autopilot) -> GimbalCommands:
    return GIMBAL_COMMANDS.get(autopilot, MountControl())


@dataclass(frozen=True, kw_only=True)
class MissionEmitter:
    """What the items of a survey's path are emitted with (a path reshaped over the terrain is
    emitted again, whole, by the same emitter)."""

    spec: MissionSpec
    frame: LocalFrame
    speed_m_s: float
    fixed_wing: FixedWing | None

    def __call__(self, path: FlightPath, home: HomePosition) -> Mission:
        return emit_mission(
            path, spec=self.spec, frame=self.frame, home=home, speed_m_s=self.speed_m_s,
            fixed_wing=self.fixed_wing,
        )  # fmt: skip


def emit_mission(
    path: FlightPath,
    *,
    spec: MissionSpec,
    frame: LocalFrame,
    home: HomePosition,
    speed_m_s: float,
    fixed_wing: FixedWing | None,
) -> Mission:
    """The mission of ``path``: its items in one pass (module docstring)."""
    vehicle = spec.vehicle
    survey = spec.survey
    gimbal = gimbal_commands(vehicle.autopilot)
    held: tuple[float, float] | None = None
    items: list[MissionItem] = []

    def lat_lon(xy: tuple[float, float]) -> tuple[float, float]:
        lon, lat = frame.to_lonlat(xy[0], xy[1])
        return float(lat), float(lon)

    def set_camera(pose: CameraPose | None) -> None:
        nonlocal held
        if pose is None:
            return
        state = gimbal.state(pose)
        if state != held:
            held = state
            items.append(gimbal.item(pose))

    def waypoint(p: PathPoint) -> None:
        lat, lon = lat_lon(p.xy)
        assert p.alt_m is not None
        items.append(MissionItem.waypoint(lat, lon, p.alt_m, hold_s=p.hold_s))

    points = path.points
    k = 0
    while k < len(points):
        # A leg: the points terrain following added on it, then the point that ends it; what
        # sets up the leg (the camera's pose for the line) is given at its start.
        j = k
        while points[j].role is Role.TERRAIN:
            j += 1
        p = points[j]
        if p.role is Role.TAKE_OFF:
            items.append(_takeoff(path, vehicle.takeoff_alt_m, home, lat_lon))
            if p.speed_m_s is not None:
                items.append(MissionItem.change_speed(p.speed_m_s))
            set_camera(p.camera)
            k = j + 1
            continue
        set_camera(p.camera)
        for t in points[k:j]:
            waypoint(t)
        if p.role is Role.APPROACH:
            assert fixed_wing is not None
            items.extend(fixed_wing.landing_items(lat_lon(p.xy), (home.lat_deg, home.lon_deg)))
        elif p.role is Role.LANDING:
            if fixed_wing is None:
                items.append(MissionItem.return_to_launch())
        elif p.is_waypoint:
            waypoint(p)
        if p.trigger_command_m is not None:
            items.append(MissionItem.cam_trigger_distance(p.trigger_command_m, trigger_now=True))
        elif p.role is Role.TRIGGER_STOP:
            items.append(MissionItem.cam_trigger_distance(0.0, trigger_now=False))
        elif p.role is Role.STATION:
            items.append(MissionItem.image_start_capture())
        if p.speed_m_s is not None:
            items.append(MissionItem.change_speed(p.speed_m_s))
        k = j + 1
    return Mission(
        items=tuple(items),
        home=home,
        autopilot=vehicle.autopilot,
        vehicle_type=vehicle.type,
        cruise_speed_m_s=survey.transit_speed_m_s or speed_m_s,
        hover_speed_m_s=speed_m_s,
        metadata={"name": spec.name, "generator": "sfap"},
    )


def _takeoff(
    path: FlightPath,
    alt_m: float,
    home: HomePosition,
    lat_lon: Callable[[tuple[float, float]], tuple[float, float]],
) -> MissionItem:
    """NAV_TAKEOFF: over home, or for a plane at its climb-out pitch toward its take-off point."""
    item = MissionItem.takeoff(home.lat_deg, home.lon_deg, alt_m)
    if path.takeoff_pitch_deg is None:
        return item
    lat, lon = home.lat_deg, home.lon_deg
    if path.takeoff_target_xy is not None:
        lat, lon = lat_lon(path.takeoff_target_xy)
    pitch = path.takeoff_pitch_deg
    return MissionItem(command=item.command, param1=pitch, param5=lat, param6=lon, param7=alt_m)


def wrap180(angle_deg: float) -> float:
    a = (angle_deg + 180.0) % 360.0 - 180.0
    return 180.0 if a == -180.0 else a
