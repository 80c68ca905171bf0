"""The simulated vehicle's commands: COMMAND_LONG and COMMAND_INT (arm, modes, mission start,
set current, return to launch, message requests and intervals), SET_MODE and
REQUEST_DATA_STREAM, answered as ArduPilot or PX4 do (COMMAND_ACK; no answer to
REQUEST_DATA_STREAM, as ArduPilot).

:class:`VehicleCommands` is a base of :class:`~acquisition.simulator.server.SimulatedVehicle`:
a test vehicle with other firmware behaviour overrides its ``_run_command`` or ``_on_*``
handlers."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from planner.mission import Autopilot

if TYPE_CHECKING:
    from .flight import FlightSimulator
    from .parameters import VehicleParameters

M = mavlink2


class VehicleCommands:
    """How the vehicle answers commands (its ``_on_*`` handlers run under its lock)."""

    autopilot: Autopilot
    flight: FlightSimulator
    params: VehicleParameters

    def prearm_failure(self) -> str | None:
        """Why the vehicle refuses to arm now (a PreArm text), or None."""
        raise NotImplementedError

    def send(self, msg: Any, sim_time_s: float | None = None) -> None:
        raise NotImplementedError

    def send_text(self, severity: int, text: str) -> None:
        raise NotImplementedError

    def _command_ack(self, msg: Any, command: int, result: int) -> None:
        self.send(
            M.MAVLink_command_ack_message(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
        )

    def _on_command_long(self, msg: Any) -> None:
        command = int(msg.command)
        params = (
            msg.param1,
            msg.param2,
            msg.param3,
            msg.param4,
            msg.param5,
            msg.param6,
            msg.param7,
        )
        result = self._run_command(command, params)
        self._command_ack(msg, command, result)

    def _on_command_int(self, msg: Any) -> None:
        command = int(msg.command)
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z)
        result = self._run_command(command, params)
        self._command_ack(msg, command, result)

    def _run_command(self, command: int, params: Sequence[float]) -> int:
        accepted, denied = M.MAV_RESULT_ACCEPTED, M.MAV_RESULT_DENIED
        failed, unsupported = M.MAV_RESULT_FAILED, M.MAV_RESULT_UNSUPPORTED
        flight = self.flight
        if command == 400:  # MAV_CMD_COMPONENT_ARM_DISARM
            if params[0] >= 0.5:
                refused = None if flight.armed else self.prearm_failure()
                ok, why = (False, refused) if refused else flight.arm()
            else:
                ok, why = flight.disarm(force=abs(params[1] - 21196) < 0.5)
            if not ok:
                self.send_text(2 if why.startswith("PreArm") else 3, why)  # CRITICAL, as check_failed
            return accepted if ok else failed
        if command == 176:  # MAV_CMD_DO_SET_MODE
            ok = flight.set_mode(int(params[0]), int(params[1]), int(params[2]))
            return accepted if ok else denied
        if command == 300:  # MAV_CMD_MISSION_START
            ok, why = flight.start_mission()
            if not ok:
                self.send_text(3, why)
            return accepted if ok else failed
        if command == 224:  # MAV_CMD_DO_SET_MISSION_CURRENT
            seq = int(params[0])
            if not 0 <= seq < len(flight.mission.items):
                return denied
            flight.set_current(seq)
            return accepted
        if command == 20:  # MAV_CMD_NAV_RETURN_TO_LAUNCH
            return accepted if flight.return_to_launch() else failed
        if command in (512, 520):  # REQUEST_MESSAGE / REQUEST_AUTOPILOT_CAPABILITIES
            if command == 520 or int(params[0]) == 148:
                self.send(self._autopilot_version())
                return accepted
            if int(params[0]) == 242:  # HOME_POSITION
                home = flight.home_position_message()
                if home is None:
                    return failed
                self.send(home)
                return accepted
            return unsupported
        if command == 511:  # MAV_CMD_SET_MESSAGE_INTERVAL (param1 message id, param2 interval us)
            ok = flight.set_message_interval(int(params[0]), float(params[1]))
            return accepted if ok else unsupported
        if command == 2504:  # REQUEST_CAMERA_INFORMATION
            return accepted
        return unsupported

    def _autopilot_version(self) -> Any:
        # MAV_PROTOCOL_CAPABILITY: MISSION_FLOAT 1, MISSION_INT 4, COMMAND_INT 8,
        # MAVLINK2 8192, MISSION_FENCE 16384, MISSION_RALLY 32768
        capabilities = 1 | 4 | 8 | 8192 | 16384 | 32768
        version = (
            (4 << 24) | (5 << 16) | (7 << 8)
            if self.autopilot is Autopilot.ARDUPILOT
            else ((1 << 24) | (15 << 16))
        )
        return M.MAVLink_autopilot_version_message(
            capabilities, version, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 0xF00D
        )

    def _on_set_mode(self, msg: Any) -> None:
        self.flight.set_mode(int(msg.base_mode), *self.flight.split_custom_mode(msg.custom_mode))

    def _on_param_request_read(self, msg: Any) -> None:
        answer = self.params.on_request_read(msg)
        if answer is not None:
            self.send(answer)

    def _on_param_set(self, msg: Any) -> None:
        answer = self.params.on_set(msg)
        if answer is not None:
            self.send(answer)

    def _on_param_request_list(self, msg: Any) -> None:
        for answer in self.params.all_messages():
            self.send(answer)

    def _on_request_data_stream(self, msg: Any) -> None:
        # No answer, as ArduPilot: the streams start (or stop), that is all.
        self.flight.request_data_stream(
            int(msg.req_stream_id), float(msg.req_message_rate), bool(msg.start_stop)
        )
