"""The vehicle parameters a mission depends on, as the vehicle holds them
(:func:`check_parameters`: PARAM_REQUEST_READ -> PARAM_VALUE over the link, and PARAM_SET
verified by the PARAM_VALUE it answers with, only when asked). Which parameters a mission needs
(:func:`required_parameters`, from its items alone) is planner.vehicle_params', re-exported
here; its docstring says which and why.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from planner.vehicle_params import CAM1_TYPE as CAM1_TYPE
from planner.vehicle_params import RTL_AUTOLAND as RTL_AUTOLAND
from planner.vehicle_params import ParamRequirement as ParamRequirement
from planner.vehicle_params import float32 as float32
from planner.vehicle_params import required_parameters as required_parameters

from .errors import AcquisitionError

if TYPE_CHECKING:  # no MAVLink at import: the link functions load pymavlink when called
    from .mission_protocol import LinkLike

log = logging.getLogger(__name__)

DEFAULT_PARAM_TIMEOUT_S = 1.0
DEFAULT_PARAM_RETRIES = 2


class VehicleParameterError(AcquisitionError):
    """The vehicle's parameters do not let it fly the mission (exit code 1)."""


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
