"""The vehicle parameters a mission depends on (:func:`required_parameters`), from the mission's
items alone: a plan states them in its summary, and an upload checks them on the vehicle
(acquisition.vehicle_params reads and sets them over MAVLink).

Only requirements that ArduPilot's own source states are listed:

- RTL_AUTOLAND 1 or 2 on ArduPlane (FIXED_WING and VTOL) when the mission holds
  DO_LAND_START: AP_Arming_Plane::mission_checks fails the pre-arm check with "DO_LAND_START
  set and RTL_AUTOLAND disabled" while it is 0 (RtlAutoland::RTL_DISABLE, the default). 1 flies
  home first and then the landing sequence on RTL, 2 goes to the landing sequence at once;
  sfap sets 2, the landing the plan drew.
- CAM1_TYPE not 0 when the mission triggers the camera (DO_SET_CAM_TRIGG_DIST with a distance,
  IMAGE_START_CAPTURE, DO_DIGICAM_CONTROL): AP_Camera_Params' ``_TYPE`` defaults to 0 (None)
  and with no camera backend the trigger commands take no photo. Which type (1 servo, 2 relay,
  5 MAVLink, ...) depends on how the camera is wired: sfap names it and never sets it.

PX4's missions need no parameter that sfap can source: none is listed.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable
from dataclasses import dataclass

from .mission import Autopilot, MavCmd, MissionItem, VehicleType


def float32(value: float) -> float:
    """``value`` as PARAM_VALUE carries it (IEEE single precision)."""
    return float(struct.unpack("<f", struct.pack("<f", value))[0])


@dataclass(frozen=True, kw_only=True)
class ParamRequirement:
    """A vehicle parameter the mission depends on: the values that work (``allowed``), or
    those that do not (``refused``), what sfap sets when told to (None: the crew chooses),
    and why."""

    name: str
    allowed: frozenset[float] = frozenset()
    refused: frozenset[float] = frozenset()
    set_to: float | None = None
    default: float
    why: str
    source: str

    def accepts(self, value: float) -> bool:
        if self.allowed:
            return float32(value) in {float32(v) for v in self.allowed}
        return float32(value) not in {float32(v) for v in self.refused}

    @property
    def needed(self) -> str:
        """What the parameter must be, said to a person ("1 or 2", "anything but 0")."""
        if self.allowed:
            values = sorted(self.allowed)
            return " or ".join(f"{v:g}" for v in values)
        return "anything but " + " or ".join(f"{v:g}" for v in sorted(self.refused))

    def to_dict(self) -> dict[str, object]:
        return {
            "name": self.name,
            "needed": self.needed,
            "set_to": self.set_to,
            "default": self.default,
            "why": self.why,
            "source": self.source,
        }


RTL_AUTOLAND = ParamRequirement(
    name="RTL_AUTOLAND",
    allowed=frozenset({1.0, 2.0}),
    set_to=2.0,
    default=0.0,
    why=(
        "the mission holds DO_LAND_START and ArduPlane refuses to arm while RTL_AUTOLAND is 0 "
        "(PreArm: DO_LAND_START set and RTL_AUTOLAND disabled); 2 flies the landing sequence on RTL, "
        "1 flies home first"
    ),
    source="ArduPlane/AP_Arming_Plane.cpp, AP_Arming_Plane::mission_checks",
)

CAM1_TYPE = ParamRequirement(
    name="CAM1_TYPE",
    refused=frozenset({0.0}),
    default=0.0,
    why=(
        "the mission triggers the camera and with CAM1_TYPE 0 (None) ArduPilot has no camera to "
        "trigger: no photo is taken; set the type your camera is wired as (1 servo, 2 relay, "
        "5 MAVLink, ...)"
    ),
    source="libraries/AP_Camera/AP_Camera_Params.cpp, _TYPE (default 0)",
)

_CAMERA_COMMANDS = frozenset({MavCmd.IMAGE_START_CAPTURE, MavCmd.DO_DIGICAM_CONTROL})


def _triggers_camera(item: MissionItem) -> bool:
    command = int(item.command)
    if command == MavCmd.DO_SET_CAM_TRIGG_DIST:
        return item.param1 is not None and item.param1 > 0
    return command in _CAMERA_COMMANDS


def required_parameters(
    items: Iterable[MissionItem], autopilot: Autopilot, vehicle_type: VehicleType | None
) -> tuple[ParamRequirement, ...]:
    """The vehicle parameters a mission of ``items`` needs on ``autopilot`` (module
    docstring): what a plan's summary and an upload name."""
    if autopilot is not Autopilot.ARDUPILOT:
        return ()
    commands = list(items)
    found: list[ParamRequirement] = []
    plane = vehicle_type in (VehicleType.FIXED_WING, VehicleType.VTOL)
    if plane and any(int(i.command) == MavCmd.DO_LAND_START for i in commands):
        found.append(RTL_AUTOLAND)
    if any(_triggers_camera(i) for i in commands):
        found.append(CAM1_TYPE)
    return tuple(found)
