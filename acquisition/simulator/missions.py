"""The simulated vehicle's side of the mission protocol: what it stores, per mission type, and
how it answers uploads, downloads and clears, as ArduPilot or PX4 do (see
:mod:`acquisition.simulator.server` for which real behaviour each part copies).

:class:`VehicleMissions` belongs to one :class:`~acquisition.simulator.server.SimulatedVehicle`:
the vehicle hands it every mission message (``on_mission_*``) under its lock, runs its timers
(re-requests, cancellation) each loop step, and sends what it answers.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from planner.errors import MissionValidationError
from planner.mission import Autopilot, HomePosition, MavFrame, MissionItem

from ..mavlink_items import (
    MissionResult,
    MissionType,
    e7_to_deg,
    is_global_frame,
    plain_wire_frame,
    to_mission_item_int,
)
from .faults import Refusal
from .storage import (
    MISSION_TYPES,
    NO_HOME,
    WireItem,
    home_wire_item,
    item_float_message,
    item_int_message,
    store_item,
    wire_item_from_message,
    wire_item_to_mission_item,
)

if TYPE_CHECKING:
    from .server import SimulatedVehicle

log = logging.getLogger(__name__)

M = mavlink2


@dataclass
class _Upload:
    mission_type: int
    count: int
    sysid: int
    compid: int
    expected: int = 0
    items: list[WireItem] = field(default_factory=list)
    last_request_s: float = 0.0
    last_receive_s: float = 0.0


@dataclass
class _Completed:
    mission_type: int
    count: int
    sysid: int
    compid: int
    result: int
    at_s: float


class VehicleMissions:
    """The mission, fence and rally lists of ``vehicle`` and the state of an upload."""

    def __init__(self, vehicle: SimulatedVehicle) -> None:
        self.vehicle = vehicle
        self.stored: dict[int, list[WireItem]] = {t: [] for t in MISSION_TYPES}
        self.upload: _Upload | None = None
        self.completed: _Completed | None = None
        self.uploaded_home: HomePosition | None = None

    def stored_mission(self, mission_type: int = MissionType.MISSION) -> list[MissionItem]:
        """A copy of the stored mission as a ground station would read it back
        (ArduPilot: home at index 0)."""
        with self.vehicle.lock:
            return [wire_item_to_mission_item(w) for w in self.items_for_readback(mission_type)]

    def load_mission(self, items: Sequence[MissionItem], mission_type: int = 0) -> None:
        """Store ``items`` as if uploaded (ArduPilot: give the items without home)."""
        with self.vehicle.lock:
            stored: list[WireItem] = []
            if self.vehicle.autopilot is Autopilot.ARDUPILOT and mission_type == MissionType.MISSION:
                stored.append(NO_HOME)
            for seq, item in enumerate(items):
                wire = wire_item_from_message(to_mission_item_int(item, seq, 1, 1, mission_type))
                result = self.store(wire, mission_type)
                if isinstance(result, int):
                    raise MissionValidationError(
                        f"the simulated {self.vehicle.autopilot.value} vehicle refuses item {seq + 1} "
                        f"({item.command_name}): MAV_MISSION_RESULT {result}; fix the item"
                    )
                stored.append(result)
            self.stored[mission_type] = stored
            self.changed(mission_type)

    def corrupt_stored_item(self, seq: int, **changes: Any) -> None:
        """Change stored item ``seq`` (index as read back) behind the protocol's back, so a
        test can prove that a verification notices. ``changes`` are MissionItem fields."""
        with self.vehicle.lock:
            stored = self.stored[MissionType.MISSION]
            if not 0 <= seq < len(stored):
                raise IndexError(f"seq {seq} is outside the stored mission (0-{len(stored) - 1})")
            item = dataclasses.replace(wire_item_to_mission_item(stored[seq]), **changes)
            stored[seq] = wire_item_from_message(to_mission_item_int(item, seq, 1, 1, 0))
            self.changed(MissionType.MISSION)

    def _ack(self, msg: Any, result: int, mission_type: int) -> None:
        self.vehicle.send(
            M.MAVLink_mission_ack_message(msg.get_srcSystem(), msg.get_srcComponent(), result, mission_type)
        )

    def _request(self, upload: _Upload) -> None:
        if self.vehicle.autopilot is Autopilot.ARDUPILOT:
            req = M.MAVLink_mission_request_message(
                upload.sysid, upload.compid, upload.expected, upload.mission_type
            )
        else:
            req = M.MAVLink_mission_request_int_message(
                upload.sysid, upload.compid, upload.expected, upload.mission_type
            )
        upload.last_request_s = self.vehicle.clock.monotonic()
        self.vehicle.send(req)

    def items_for_readback(self, mission_type: int) -> list[WireItem]:
        items = list(self.stored[mission_type])
        if self.vehicle.autopilot is Autopilot.ARDUPILOT and mission_type == MissionType.MISSION:
            if not items:
                items = [NO_HOME]
            items[0] = self._home_item()
        return items

    def _home_item(self) -> WireItem:
        return home_wire_item(self.vehicle.flight.home if self.vehicle.flight.gps_has_fix else None)

    def store(self, item: WireItem, mission_type: int) -> WireItem | int:
        return store_item(item, self.vehicle.autopilot, self.vehicle.vehicle_type, mission_type)

    def changed(self, mission_type: int) -> None:
        if mission_type == MissionType.MISSION:
            items = [wire_item_to_mission_item(w) for w in self.items_for_readback(0)]
            self.vehicle.flight.set_mission(items)

    def on_mission_count(self, msg: Any) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in MISSION_TYPES:
            self._ack(msg, MissionResult.UNSUPPORTED, mission_type)
            return
        up = self.upload
        if up is not None:
            if (up.sysid, up.compid) != (msg.get_srcSystem(), msg.get_srcComponent()):
                self._ack(msg, MissionResult.DENIED, mission_type)
                return
            self.upload = None  # the same ground station restarts its upload
        ardupilot = self.vehicle.autopilot is Autopilot.ARDUPILOT
        if ardupilot and self.vehicle.flight.time_s < self.vehicle.boot_delay_s:
            self._ack(msg, MissionResult.NO_SPACE, mission_type)
            self.vehicle.send_text(4, "Only 0 items are supported")
            return
        if (
            self.vehicle.faults.refuse == Refusal.NO_SPACE and msg.count > 0
        ) or msg.count > self.vehicle.max_items:
            self._ack(msg, MissionResult.NO_SPACE, mission_type)
            if ardupilot:  # PX4 says nothing more than its NO_SPACE
                self.vehicle.send_text(4, f"Only {self.vehicle.max_items} items are supported")
            return
        self.completed = None
        if ardupilot:
            # ArduPilot truncates at once and writes items as they arrive.
            stored = self.stored[mission_type]
            keep = max(msg.count, 1) if mission_type == MissionType.MISSION else msg.count
            del stored[keep:]
            self.changed(mission_type)
        if msg.count == 0:
            if not ardupilot:
                self.stored[mission_type] = []
                self.changed(mission_type)
            self._ack(msg, MissionResult.ACCEPTED, mission_type)
            return
        now = self.vehicle.clock.monotonic()
        self.upload = _Upload(
            mission_type=mission_type,
            count=int(msg.count),
            sysid=msg.get_srcSystem(),
            compid=msg.get_srcComponent(),
            last_receive_s=now,
        )
        self._request(self.upload)

    def on_mission_item(self, msg: Any) -> None:
        if self.vehicle.autopilot is Autopilot.ARDUPILOT and self.upload is not None:
            self.vehicle.warn_once("item", "got MISSION_ITEM; GCS should send MISSION_ITEM_INT")
        self.on_mission_item_int(msg)

    def on_mission_item_int(self, msg: Any) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        up = self.upload
        ardupilot = self.vehicle.autopilot is Autopilot.ARDUPILOT
        if up is None or up.mission_type != mission_type:
            done = self.completed
            if (
                not ardupilot
                and done is not None
                and done.mission_type == mission_type
                and msg.seq == done.count - 1
            ):
                # PX4: the last item again means our ACK was lost; send it again.
                self._ack(msg, done.result, mission_type)
            return
        if msg.seq != up.expected:
            if ardupilot:
                self._ack(msg, MissionResult.INVALID_SEQUENCE, mission_type)
            return
        if (msg.get_srcSystem(), msg.get_srcComponent()) != (up.sysid, up.compid):
            self._ack(msg, MissionResult.DENIED, mission_type)
            return
        wire = wire_item_from_message(msg)
        if self.vehicle.faults.refuse == Refusal.INVALID and msg.seq == up.count // 2:
            result: WireItem | int = MissionResult.INVALID
        elif ardupilot and mission_type == MissionType.MISSION and msg.seq == 0:
            result = NO_HOME  # home: ArduPilot keeps its own
            if plain_wire_frame(wire.frame) == MavFrame.GLOBAL and (wire.x != 0 or wire.y != 0):
                self.uploaded_home = HomePosition(
                    lat_deg=e7_to_deg(wire.x), lon_deg=e7_to_deg(wire.y), alt_amsl_m=float(wire.z)
                )
        else:
            result = self.store(wire, mission_type)
        if isinstance(result, int):
            self.upload = None
            self._finish(msg, up, result)
            return
        up.last_receive_s = self.vehicle.clock.monotonic()
        if ardupilot:
            stored = self.stored[mission_type]
            if msg.seq < len(stored):
                stored[msg.seq] = result
            else:
                stored.append(result)
            # the flight reads the mission when the upload ends (_finish), not per item
        else:
            up.items.append(result)
        up.expected += 1
        if up.expected >= up.count:
            self.upload = None
            if not ardupilot:
                self.stored[mission_type] = list(up.items)
            self._finish(msg, up, MissionResult.ACCEPTED)
            return
        self._request(up)

    def _follow_home(self, up: _Upload) -> None:
        """``follow_mission_home``: move to the uploaded mission's home before the first flight."""
        if not self.vehicle.follow_mission_home or up.mission_type != MissionType.MISSION:
            return
        flight = self.vehicle.flight
        if flight.has_flown or flight.armed:
            return
        home = self.uploaded_home
        if home is None and self.vehicle.autopilot is Autopilot.PX4:
            for wire in up.items:
                if is_global_frame(wire.frame) and (wire.x != 0 or wire.y != 0):
                    home = HomePosition(
                        lat_deg=e7_to_deg(wire.x),
                        lon_deg=e7_to_deg(wire.y),
                        alt_amsl_m=flight.home.alt_amsl_m,
                    )
                    break
        self.uploaded_home = None
        if home is None or (home.lat_deg, home.lon_deg) == (flight.home.lat_deg, flight.home.lon_deg):
            return
        flight.move_home(home)
        self.vehicle.home = home
        self.vehicle.send_text(6, "sim: moved to the mission's home")
        log.info(
            "simulated vehicle: moved to the uploaded mission's home %.7f, %.7f, %.1f m AMSL",
            home.lat_deg,
            home.lon_deg,
            home.alt_amsl_m,
        )

    def _finish(self, msg: Any, up: _Upload, result: int) -> None:
        if result == MissionResult.ACCEPTED:
            self._follow_home(up)
        self.completed = _Completed(
            up.mission_type, up.count, up.sysid, up.compid, result, self.vehicle.clock.monotonic()
        )
        self.changed(up.mission_type)
        self._ack(msg, result, up.mission_type)
        log.info(
            "simulated vehicle: upload of %d items (type %d) ended with MAV_MISSION_RESULT %d",
            up.count,
            up.mission_type,
            result,
        )

    def timers(self, now: float) -> None:
        up = self.upload
        if up is None:
            return
        if now - up.last_receive_s > self.vehicle.upload_timeout_s:
            self.upload = None
            self.completed = None
            self.changed(up.mission_type)
            self.vehicle.send(
                M.MAVLink_mission_ack_message(
                    up.sysid, up.compid, MissionResult.OPERATION_CANCELLED, up.mission_type
                )
            )
            log.info("simulated vehicle: upload timed out at item %d of %d", up.expected, up.count)
            return
        if now - up.last_request_s > self.vehicle.request_timeout_s:
            self._request(up)

    def on_mission_request_list(self, msg: Any) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in MISSION_TYPES:
            self._ack(msg, MissionResult.UNSUPPORTED, mission_type)
            return
        if self.upload is not None:
            self._ack(msg, MissionResult.DENIED, mission_type)
            return
        count = len(self.items_for_readback(mission_type))
        self.vehicle.send(
            M.MAVLink_mission_count_message(msg.get_srcSystem(), msg.get_srcComponent(), count, mission_type)
        )

    def _answer_request(self, msg: Any, as_int: bool) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in MISSION_TYPES:
            self._ack(msg, MissionResult.UNSUPPORTED, mission_type)
            return
        if self.upload is not None:
            if self.vehicle.autopilot is Autopilot.ARDUPILOT or not as_int:
                self._ack(msg, MissionResult.DENIED, mission_type)
            # PX4 ignores requests during its own upload
            return
        items = self.items_for_readback(mission_type)
        if not 0 <= msg.seq < len(items):
            if as_int:
                self.vehicle.send(
                    M.MAVLink_mission_count_message(
                        msg.get_srcSystem(), msg.get_srcComponent(), len(items), mission_type
                    )
                )
            self._ack(msg, MissionResult.INVALID_SEQUENCE, mission_type)
            return
        build = item_int_message if as_int else item_float_message
        if not as_int and self.vehicle.autopilot is Autopilot.ARDUPILOT:
            self.vehicle.warn_once("request", "got MISSION_REQUEST; use MISSION_REQUEST_INT!")
        self.vehicle.send(
            build(
                items[msg.seq],
                msg.seq,
                msg.get_srcSystem(),
                msg.get_srcComponent(),
                mission_type,
            )
        )

    def on_mission_request_int(self, msg: Any) -> None:
        self._answer_request(msg, as_int=True)

    def on_mission_request(self, msg: Any) -> None:
        self._answer_request(msg, as_int=False)

    def on_mission_ack(self, msg: Any) -> None:
        # The end of a download (nothing to free here), or a ground station cancelling its
        # upload with an error result: stop requesting items.
        up = self.upload
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        mission_type = int(getattr(msg, "mission_type", 0))
        ours = up is not None and (up.sysid, up.compid) == source
        if ours and up is not None and up.mission_type == mission_type and msg.type != 0:
            self.upload = None
            self.changed(mission_type)
            log.info("simulated vehicle: the ground station cancelled its upload")

    def on_mission_clear_all(self, msg: Any) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in MISSION_TYPES:
            self._ack(msg, MissionResult.UNSUPPORTED, mission_type)
            return
        up = self.upload
        if up is not None and (up.sysid, up.compid) != (
            msg.get_srcSystem(),
            msg.get_srcComponent(),
        ):
            self._ack(msg, MissionResult.ERROR, mission_type)
            return
        self.upload = None
        self.stored[mission_type] = []
        self.changed(mission_type)
        self._ack(msg, MissionResult.ACCEPTED, mission_type)

    def on_mission_set_current(self, msg: Any) -> None:
        self.vehicle.flight.set_current(int(msg.seq))
