"""The vehicle parameters a mission depends on: which (:func:`required_parameters`, from the
mission's items alone, for a plan's summary too), and what the vehicle holds
(:func:`check_parameters`: PARAM_REQUEST_READ -> PARAM_VALUE over the link, and PARAM_SET
verified by the PARAM_VALUE it answers with, only when asked).

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

import logging
import math
import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from planner.mission import Autopilot, MavCmd, MissionItem, VehicleType

from .errors import AcquisitionError

if TYPE_CHECKING:  # the requirements need no MAVLink: a plan's summary imports them cheaply
    from .mission_protocol import LinkLike

log = logging.getLogger(__name__)

DEFAULT_PARAM_TIMEOUT_S = 1.0
DEFAULT_PARAM_RETRIES = 2


def float32(value: float) -> float:
    """``value`` as PARAM_VALUE carries it (IEEE single precision)."""
    return float(struct.unpack("<f", struct.pack("<f", value))[0])


class VehicleParameterError(AcquisitionError):
    """The vehicle's parameters do not let it fly the mission (exit code 1)."""


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


@dataclass(frozen=True, kw_only=True)
class ParamStatus:
    """A required parameter as the vehicle holds it: ``value`` None when it did not answer;
    ``was`` the value before sfap set it (``value`` is then the value read back)."""

    requirement: ParamRequirement
    value: float | None
    was: float | None = None

    @property
    def ok(self) -> bool:
        return self.value is not None and self.requirement.accepts(self.value)

    @property
    def changed(self) -> bool:
        return self.was is not None

    def describe(self) -> str:
        r = self.requirement
        if self.value is None:
            return f"{r.name} could not be read (no answer): it must be {r.needed}; check it yourself"
        if self.changed and self.ok:
            return f"{r.name} set from {self.was:g} to {self.value:g} and read back"
        if self.ok:
            return f"{r.name} is {self.value:g} (needs {r.needed})"
        fix = (
            f"Set it to {r.set_to:g} (sfap upload --set-params does)"
            if r.set_to is not None
            else "Set it in your ground station"
        )
        return f"{r.name} is {self.value:g}, needs {r.needed}: {r.why}. {fix}"

    def to_dict(self) -> dict[str, object]:
        return {**self.requirement.to_dict(), "value": self.value, "was": self.was, "ok": self.ok}


def _name(raw: object) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return str(raw).split("\x00", 1)[0]


def _exchange(
    link: LinkLike, message: object, name: str, *, timeout_s: float, retries: int
) -> tuple[float, int] | None:
    """Send ``message`` until a PARAM_VALUE for ``name`` comes back: (value, MAV_PARAM_TYPE),
    or None after ``retries`` repeats without one."""
    from .mission_protocol import link_clock

    clock = link_clock(link)
    for attempt in range(retries + 1):
        if attempt:
            log.debug("no PARAM_VALUE for %s: asking again (%d)", name, attempt)
        link.send(message)
        deadline = clock.monotonic() + timeout_s
        while (remaining := deadline - clock.monotonic()) > 0:
            answer = link.recv({"PARAM_VALUE"}, timeout_s=remaining)
            if answer is None:
                break
            if _name(answer.param_id) == name:
                return float(answer.param_value), int(answer.param_type)
    return None


def read_parameter(
    link: LinkLike,
    name: str,
    *,
    timeout_s: float = DEFAULT_PARAM_TIMEOUT_S,
    retries: int = DEFAULT_PARAM_RETRIES,
) -> tuple[float, int] | None:
    """PARAM_REQUEST_READ by name -> (value, MAV_PARAM_TYPE), or None when the vehicle does
    not answer (it does not have the parameter, or the link loses everything)."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    request = mavlink2.MAVLink_param_request_read_message(
        link.target_system, link.target_component, name.encode(), -1
    )
    return _exchange(link, request, name, timeout_s=timeout_s, retries=retries)


def set_parameter(
    link: LinkLike,
    name: str,
    value: float,
    param_type: int,
    *,
    timeout_s: float = DEFAULT_PARAM_TIMEOUT_S,
    retries: int = DEFAULT_PARAM_RETRIES,
) -> float | None:
    """PARAM_SET; the value the vehicle answers with in PARAM_VALUE (None: no answer)."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    message = mavlink2.MAVLink_param_set_message(
        link.target_system, link.target_component, name.encode(), float(value), param_type
    )
    answer = _exchange(link, message, name, timeout_s=timeout_s, retries=retries)
    return None if answer is None else answer[0]


def check_parameters(
    link: LinkLike,
    requirements: Sequence[ParamRequirement],
    *,
    apply: bool = False,
    timeout_s: float = DEFAULT_PARAM_TIMEOUT_S,
    retries: int = DEFAULT_PARAM_RETRIES,
) -> tuple[ParamStatus, ...]:
    """Read each required parameter from the vehicle; with ``apply``, set the ones that are
    wrong and have a value to set (:attr:`ParamRequirement.set_to`), and read them back.
    Raises :class:`VehicleParameterError` when the vehicle does not keep a value set."""
    statuses: list[ParamStatus] = []
    for requirement in requirements:
        read = read_parameter(link, requirement.name, timeout_s=timeout_s, retries=retries)
        if read is None:
            statuses.append(ParamStatus(requirement=requirement, value=None))
            continue
        value, param_type = read
        if requirement.accepts(value) or not apply or requirement.set_to is None:
            statuses.append(ParamStatus(requirement=requirement, value=value))
            continue
        target = requirement.set_to
        answered = set_parameter(
            link, requirement.name, target, param_type, timeout_s=timeout_s, retries=retries
        )
        back = read_parameter(link, requirement.name, timeout_s=timeout_s, retries=retries)
        now = None if back is None else back[0]
        if answered is None or now is None or not (math.isclose(now, target) and requirement.accepts(now)):
            said = "did not answer" if answered is None else f"answered {answered:g}"
            holds = "no value" if now is None else f"{now:g}"
            raise VehicleParameterError(
                f"{requirement.name} could not be set to {target:g} on {link.url}: the vehicle "
                f"{said} and reads back {holds}; set it in your ground station"
            )
        log.info("%s set from %g to %g on %s", requirement.name, value, now, link.url)
        statuses.append(ParamStatus(requirement=requirement, value=now, was=value))
    return tuple(statuses)
