"""The mission model: a list of items equal in meaning to MAVLink MISSION_ITEM_INT.

Coordinates are WGS84 degrees and altitudes metres here; the MAVLink adapter alone turns them
into degE7 integers. Parameters 1-4 are floats or None (MAVLink NaN, "leave unchanged");
parameters 5-7 are latitude (deg), longitude (deg) and altitude (m) for items in a global frame,
and plain numbers for items in ``MavFrame.MISSION``.

The home position is not an item: it travels beside the items as :class:`HomePosition`.
Writers and uploaders that need it as item 0 (ArduPilot, QGC WPL 110) put it there.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum, StrEnum

from .errors import MissionValidationError


class MavCmd(IntEnum):
    """The MAV_CMD values sfap writes and reads (MAVLink common.xml)."""

    NAV_WAYPOINT = 16
    NAV_LOITER_UNLIM = 17
    NAV_LOITER_TURNS = 18
    NAV_LOITER_TIME = 19
    NAV_RETURN_TO_LAUNCH = 20
    NAV_LAND = 21
    NAV_TAKEOFF = 22
    NAV_LOITER_TO_ALT = 31
    NAV_SPLINE_WAYPOINT = 82
    NAV_VTOL_TAKEOFF = 84
    NAV_VTOL_LAND = 85
    NAV_DELAY = 93
    CONDITION_DELAY = 112
    CONDITION_DISTANCE = 114
    CONDITION_YAW = 115
    DO_JUMP = 177
    DO_CHANGE_SPEED = 178
    DO_SET_HOME = 179
    DO_LAND_START = 189
    DO_SET_SERVO = 183
    DO_SET_ROI_LOCATION = 195
    DO_DIGICAM_CONFIGURE = 202
    DO_DIGICAM_CONTROL = 203
    DO_MOUNT_CONFIGURE = 204
    DO_MOUNT_CONTROL = 205
    DO_SET_CAM_TRIGG_DIST = 206
    DO_SET_ROI_NONE = 197
    DO_GIMBAL_MANAGER_PITCHYAW = 1000
    IMAGE_START_CAPTURE = 2000
    IMAGE_STOP_CAPTURE = 2001
    VIDEO_START_CAPTURE = 2500
    VIDEO_STOP_CAPTURE = 2501
    OBLIQUE_SURVEY = 260
    DO_SET_CAM_TRIGG_INTERVAL = 214

    @property
    def is_nav(self) -> bool:
        """True for commands that move the vehicle to a position (they need coordinates)."""
        return self in _NAV_WITH_POSITION


_NAV_WITH_POSITION = frozenset(
    {
        MavCmd.NAV_WAYPOINT,
        MavCmd.NAV_LOITER_UNLIM,
        MavCmd.NAV_LOITER_TURNS,
        MavCmd.NAV_LOITER_TIME,
        MavCmd.NAV_LAND,
        MavCmd.NAV_TAKEOFF,
        MavCmd.NAV_LOITER_TO_ALT,
        MavCmd.NAV_SPLINE_WAYPOINT,
        MavCmd.NAV_VTOL_TAKEOFF,
        MavCmd.NAV_VTOL_LAND,
    }
)


class MavFrame(IntEnum):
    """MAV_FRAME values used by missions."""

    GLOBAL = 0  # altitude AMSL
    MISSION = 2  # not a coordinate frame: params 5-7 are plain numbers
    GLOBAL_RELATIVE_ALT = 3  # altitude above home
    GLOBAL_INT = 5
    GLOBAL_RELATIVE_ALT_INT = 6
    GLOBAL_TERRAIN_ALT = 10  # altitude above terrain
    GLOBAL_TERRAIN_ALT_INT = 11

    @property
    def is_global(self) -> bool:
        return self is not MavFrame.MISSION


class Autopilot(StrEnum):
    ARDUPILOT = "ardupilot"
    PX4 = "px4"


class VehicleType(StrEnum):
    MULTIROTOR = "multirotor"
    FIXED_WING = "fixed_wing"
    VTOL = "vtol"


@dataclass(frozen=True, kw_only=True)
class HomePosition:
    """Take-off position, WGS84 degrees, altitude above mean sea level."""

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float = 0.0


#: GIMBAL_MANAGER_FLAGS of MAVLink common.xml (the same values as GIMBAL_DEVICE_FLAGS).
GIMBAL_MANAGER_FLAGS_ROLL_LOCK = 4
GIMBAL_MANAGER_FLAGS_PITCH_LOCK = 8
GIMBAL_MANAGER_FLAGS_YAW_LOCK = 16


@dataclass(frozen=True, kw_only=True)
class MissionItem:
    """One mission item, as in MISSION_ITEM_INT but in degrees and metres.

    ``param5``/``param6``/``param7`` are latitude deg / longitude deg / altitude m when ``frame``
    is global; use :attr:`lat_deg`, :attr:`lon_deg`, :attr:`alt_m` to read them by meaning.
    """

    command: int
    frame: MavFrame = MavFrame.GLOBAL_RELATIVE_ALT
    param1: float | None = 0.0
    param2: float | None = 0.0
    param3: float | None = 0.0
    param4: float | None = 0.0
    param5: float = 0.0
    param6: float = 0.0
    param7: float = 0.0
    autocontinue: bool = True

    @property
    def lat_deg(self) -> float:
        return self.param5

    @property
    def lon_deg(self) -> float:
        return self.param6

    @property
    def alt_m(self) -> float:
        return self.param7

    @property
    def params(self) -> tuple[float | None, ...]:
        """The seven parameters in MAVLink order."""
        return (
            self.param1,
            self.param2,
            self.param3,
            self.param4,
            self.param5,
            self.param6,
            self.param7,
        )

    @property
    def command_name(self) -> str:
        try:
            return MavCmd(self.command).name
        except ValueError:
            return f"MAV_CMD {self.command}"

    # --- constructors for the items sfap writes ----------------------------------------------

    @classmethod
    def waypoint(
        cls, lat_deg: float, lon_deg: float, alt_rel_home_m: float, hold_s: float = 0.0
    ) -> MissionItem:
        return cls(
            command=MavCmd.NAV_WAYPOINT,
            param1=hold_s,
            param5=lat_deg,
            param6=lon_deg,
            param7=alt_rel_home_m,
        )

    @classmethod
    def takeoff(cls, lat_deg: float, lon_deg: float, alt_rel_home_m: float) -> MissionItem:
        return cls(
            command=MavCmd.NAV_TAKEOFF,
            param5=lat_deg,
            param6=lon_deg,
            param7=alt_rel_home_m,
        )

    @classmethod
    def return_to_launch(cls) -> MissionItem:
        return cls(command=MavCmd.NAV_RETURN_TO_LAUNCH, frame=MavFrame.MISSION)

    @classmethod
    def change_speed(cls, speed_m_s: float) -> MissionItem:
        # param1 1 = ground speed; param3 -1 = no throttle change
        return cls(
            command=MavCmd.DO_CHANGE_SPEED,
            frame=MavFrame.MISSION,
            param1=1.0,
            param2=speed_m_s,
            param3=-1.0,
        )

    @classmethod
    def cam_trigger_distance(cls, distance_m: float, trigger_now: bool = True) -> MissionItem:
        # param3 = 1: trigger once immediately (REFERENCES.md section 2)
        return cls(
            command=MavCmd.DO_SET_CAM_TRIGG_DIST,
            frame=MavFrame.MISSION,
            param1=distance_m,
            param2=0.0,
            param3=1.0 if trigger_now else 0.0,
        )

    @classmethod
    def image_start_capture(cls) -> MissionItem:
        # param2 interval 0, param3 total 1: one photo now
        return cls(
            command=MavCmd.IMAGE_START_CAPTURE,
            frame=MavFrame.MISSION,
            param1=0.0,
            param2=0.0,
            param3=1.0,
        )

    @classmethod
    def gimbal_pitch_yaw(cls, pitch_deg: float, yaw_deg: float) -> MissionItem:
        """Point the gimbal: pitch (negative is down) and yaw relative to the vehicle."""
        return cls(
            command=MavCmd.DO_MOUNT_CONTROL,
            frame=MavFrame.MISSION,
            param1=pitch_deg,
            param2=0.0,  # roll
            param3=yaw_deg,
            param4=0.0,
            param7=2.0,  # MAV_MOUNT_MODE_MAVLINK_TARGETING
        )

    @classmethod
    def gimbal_manager_pitch_yaw(
        cls, pitch_deg: float, yaw_deg: float, *, yaw_earth_frame: bool = False
    ) -> MissionItem:
        """Point the gimbal with the gimbal-manager protocol (PX4, newer ArduPilot).

        param5 holds GIMBAL_MANAGER_FLAGS (MAVLink common.xml). PX4's gimbal module
        (src/modules/gimbal/input_mavlink.cpp, _set_control_data_from_set_attitude) takes each
        axis in the earth frame when its LOCK flag is set and relative to the airframe when it is
        not: roll and pitch are always locked here, so the camera stays level (nadir stays nadir
        however the drone tilts); yaw is locked (``yaw_earth_frame``, ``yaw_deg`` then a bearing
        from north) for obliques, which must look toward a fixed bearing even when the vehicle
        crabs, and follows the vehicle otherwise (``yaw_deg`` relative to its heading).
        """
        flags = GIMBAL_MANAGER_FLAGS_ROLL_LOCK | GIMBAL_MANAGER_FLAGS_PITCH_LOCK
        if yaw_earth_frame:
            flags |= GIMBAL_MANAGER_FLAGS_YAW_LOCK
        return cls(
            command=MavCmd.DO_GIMBAL_MANAGER_PITCHYAW,
            frame=MavFrame.MISSION,
            param1=pitch_deg,
            param2=yaw_deg,
            param3=None,  # pitch rate: leave unchanged
            param4=None,  # yaw rate: leave unchanged
            param5=float(flags),
            param6=0.0,
            param7=0.0,  # gimbal device id 0: primary gimbal
        )


@dataclass(frozen=True, kw_only=True)
class Mission:
    """A mission ready to be written or uploaded."""

    items: tuple[MissionItem, ...]
    home: HomePosition
    autopilot: Autopilot = Autopilot.ARDUPILOT
    vehicle_type: VehicleType = VehicleType.MULTIROTOR
    cruise_speed_m_s: float = 15.0
    hover_speed_m_s: float = 5.0
    metadata: dict[str, object] = field(default_factory=dict, compare=False)

    def __len__(self) -> int:
        return len(self.items)


def validate_mission(
    mission: Mission | Sequence[MissionItem],
    *,
    max_alt_rel_home_m: float | None = None,
) -> None:
    """Check a mission before it goes anywhere near a vehicle.

    Raises :class:`MissionValidationError` naming every bad item: unknown commands, NaN or
    out-of-range coordinates, positional items at 0,0, altitudes above the limit or below ground.
    """
    items = mission.items if isinstance(mission, Mission) else tuple(mission)
    problems: list[str] = []
    if not items:
        problems.append("the mission has no items")
    known = {int(c) for c in MavCmd}
    for index, item in enumerate(items):
        label = f"item {index + 1} ({item.command_name})"
        if int(item.command) not in known:
            problems.append(f"{label}: unknown command {item.command}")
            continue
        try:
            MavFrame(int(item.frame))
        except ValueError:
            problems.append(f"{label}: unknown frame {item.frame}")
            continue
        for n, value in enumerate(item.params, start=1):
            if n >= 5 and value is not None and not math.isfinite(value):
                problems.append(f"{label}: param{n} is {value}, not a number")
        cmd = MavCmd(int(item.command))
        if cmd.is_nav and item.frame.is_global:
            if not (-90.0 <= item.lat_deg <= 90.0) or not (-180.0 <= item.lon_deg <= 180.0):
                problems.append(f"{label}: latitude {item.lat_deg} / longitude {item.lon_deg} out of range")
            elif item.lat_deg == 0.0 and item.lon_deg == 0.0 and cmd is not MavCmd.NAV_TAKEOFF:
                problems.append(f"{label}: position is 0, 0 (null island); give a real position")
            if item.frame in (MavFrame.GLOBAL_RELATIVE_ALT, MavFrame.GLOBAL_RELATIVE_ALT_INT):
                if max_alt_rel_home_m is not None and item.alt_m > max_alt_rel_home_m + 1e-6:
                    problems.append(
                        f"{label}: altitude {item.alt_m:.1f} m above home exceeds the vehicle "
                        f"limit {max_alt_rel_home_m:.1f} m"
                    )
                if item.alt_m < 0 and cmd not in (MavCmd.NAV_LAND, MavCmd.NAV_VTOL_LAND):
                    problems.append(f"{label}: altitude {item.alt_m:.1f} m is below home")
    if problems:
        shown = problems[:20]
        more = f"\n  ... and {len(problems) - 20} more" if len(problems) > 20 else ""
        raise MissionValidationError(
            "the mission failed validation and will not be sent:\n  " + "\n  ".join(shown) + more
        )
