"""The simulated vehicle's parameters: PARAM_REQUEST_READ, PARAM_SET and PARAM_REQUEST_LIST
answered with PARAM_VALUE, as ArduPilot's GCS_MAVLINK does, and the pre-arm check that reads
them.

Only the parameters that sfap's missions depend on are modelled, with ArduPilot's defaults:

- RTL_AUTOLAND 0 (ArduPlane: ``RtlAutoland::RTL_DISABLE``; the ArduPlane 4.5.6 SITL log in
  ../shared/data/ardupilot_sitl_plane has PARM RTL_AUTOLAND Value 0, Default 0). ArduPlane
  refuses to arm with DO_LAND_START in the mission while it is 0
  (AP_Arming_Plane::mission_checks: ``check_failed(..., "DO_LAND_START set and RTL_AUTOLAND
  disabled")``, which AP_Arming prefixes "PreArm: ").
- CAM1_TYPE 1 (servo): the firmware's default is 0 (AP_Camera_Params.cpp ``_TYPE ... 0``), and
  ArduPilot's SITL sets 1 (the same log: PARM CAM1_TYPE Default 1): the simulator stands in
  for SITL, whose camera fires.

A name the vehicle does not have is not answered, as ArduPilot ignores it. PX4's vehicle here
has none of these (no answer). Values are kept as float32, as PARAM_VALUE carries them.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from planner.mission import Autopilot, MavCmd, VehicleType

M = mavlink2

#: ArduPilot's PreArm text for a landing sequence without RTL_AUTOLAND (AP_Arming_Plane).
PREARM_LAND_START = "PreArm: DO_LAND_START set and RTL_AUTOLAND disabled"


@dataclass
class _Param:
    value: float
    kind: int  # MAV_PARAM_TYPE


def _defaults(autopilot: Autopilot, vehicle_type: VehicleType) -> dict[str, _Param]:
    if autopilot is not Autopilot.ARDUPILOT:
        return {}
    params = {"CAM1_TYPE": _Param(1.0, M.MAV_PARAM_TYPE_INT8)}
    if vehicle_type is VehicleType.FIXED_WING:  # ArduPlane (this simulator's VTOL is a quadrotor)
        params["RTL_AUTOLAND"] = _Param(0.0, M.MAV_PARAM_TYPE_INT8)
    return params


def _f32(value: float) -> float:
    return float(np.float32(value))


class VehicleParameters:
    """The parameter table of one simulated vehicle (its handlers run under its lock)."""

    def __init__(self, autopilot: Autopilot, vehicle_type: VehicleType) -> None:
        self.autopilot = autopilot
        self.vehicle_type = vehicle_type
        self._params = _defaults(autopilot, vehicle_type)
        self.sets: list[tuple[str, float]] = []  # every PARAM_SET applied, in order

    def get(self, name: str) -> float | None:
        param = self._params.get(name)
        return None if param is None else param.value

    def set(self, name: str, value: float) -> bool:
        """Set ``name`` (as PARAM_SET does); False for a name the vehicle does not have."""
        param = self._params.get(name)
        if param is None:
            return False
        param.value = _f32(float(int(value))) if param.kind != M.MAV_PARAM_TYPE_REAL32 else _f32(value)
        self.sets.append((name, param.value))
        return True

    def value_message(self, name: str) -> Any | None:
        param = self._params.get(name)
        if param is None:
            return None
        names = sorted(self._params)
        return M.MAVLink_param_value_message(
            name.encode(), param.value, param.kind, len(names), names.index(name)
        )

    def on_request_read(self, msg: Any) -> Any | None:
        """PARAM_REQUEST_READ -> the PARAM_VALUE to send (None: not answered)."""
        name = _param_name(msg.param_id)
        index = int(msg.param_index)
        if index >= 0:
            names = sorted(self._params)
            if index >= len(names):
                return None
            name = names[index]
        return self.value_message(name)

    def on_set(self, msg: Any) -> Any | None:
        """PARAM_SET -> the PARAM_VALUE of the value now held (None: unknown name)."""
        name = _param_name(msg.param_id)
        value = float(msg.param_value)
        if not np.isfinite(value) or not self.set(name, value):
            return None
        return self.value_message(name)

    def all_messages(self) -> list[Any]:
        """PARAM_REQUEST_LIST: every parameter's PARAM_VALUE."""
        return [m for name in sorted(self._params) if (m := self.value_message(name)) is not None]

    def prearm_failure(self, commands: Iterable[int]) -> str | None:
        """ArduPlane's mission pre-arm check (AP_Arming_Plane::mission_checks) on the stored
        mission's ``commands``, or None."""
        if self.get("RTL_AUTOLAND") != 0.0:
            return None  # not ArduPlane, or a landing sequence is allowed
        if any(int(command) == MavCmd.DO_LAND_START for command in commands):
            return PREARM_LAND_START
        return None


def _param_name(raw: Any) -> str:
    if isinstance(raw, bytes):
        raw = raw.decode("ascii", "replace")
    return str(raw).split("\x00", 1)[0]
