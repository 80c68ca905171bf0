"""Mission upload, download and clear by the MAVLink mission protocol, with read-back proof.

The protocol (mavlink.io "Mission Protocol"; REFERENCES.md section 3):

- Upload: the ground station sends MISSION_COUNT; the vehicle asks for every item with
  MISSION_REQUEST_INT (ArduPilot: the legacy MISSION_REQUEST), in any order and as often as it
  likes; we answer each with MISSION_ITEM_INT; the vehicle ends with MISSION_ACK. When the
  vehicle goes quiet for ``timeout_s`` we repeat our last message (MISSION_COUNT, or the last
  item) up to ``retries`` times.
- Download: MISSION_REQUEST_LIST -> MISSION_COUNT, then MISSION_REQUEST_INT per item ->
  MISSION_ITEM_INT, then our MISSION_ACK. Each request is repeated on timeout.
- Clear: MISSION_CLEAR_ALL -> MISSION_ACK, then the list is requested to prove it is empty.

ArduPilot keeps the home position as item 0 of the mission: we send the mission's home there and
skip it when verifying (the vehicle replaces it with its own home, or zeros before a GPS fix).
PX4 has no home item: item 0 is the first mission item. Just after boot ArduPilot refuses an
upload with MAV_MISSION_NO_SPACE ("Only 0 items are supported") and accepts it a moment later:
that refusal, before any item was requested, is retried after a pause.

Every upload is validated first (:func:`planner.mission.validate_mission`), then read back and
compared item by item (:func:`verify_readback`). The result, or the error, states what the
vehicle now holds (:class:`MissionState`).
"""

from __future__ import annotations

import logging
import math
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Protocol

from planner.errors import InputError, MissionValidationError
from planner.mission import (
    Autopilot,
    HomePosition,
    MavCmd,
    MavFrame,
    Mission,
    MissionItem,
    VehicleType,
    validate_mission,
)

from .errors import LinkError, TransferError, VerificationError
from .mavlink_items import (
    MissionType,
    deg_to_e7,
    float32,
    from_mission_item,
    home_from_message,
    is_global_frame,
    plain_frame,
    to_mission_item_int,
)

log = logging.getLogger(__name__)

DEFAULT_TIMEOUT_S = 1.5
DEFAULT_RETRIES = 5


class LinkLike(Protocol):
    """What the transfer needs of a link (:class:`acquisition.link.Link` is one)."""

    url: str
    autopilot: Autopilot
    vehicle_type: VehicleType | None
    target_system: int
    target_component: int

    def send(self, message: Any) -> None: ...

    def recv(self, types: Any = None, timeout_s: float = 0.0) -> Any | None: ...


class MissionState(StrEnum):
    """What the vehicle holds after a transfer."""

    UNCHANGED = "unchanged"
    PARTIAL = "partial"
    REPLACED_VERIFIED = "replaced and verified"
    REPLACED_DIFFERS = "replaced, but differs from what was sent"
    REPLACED_UNVERIFIED = "replaced, not verified"
    CLEARED = "cleared"

    @property
    def sentence(self) -> str:
        """The state said to a person, with what to do about it."""
        return _STATE_SENTENCES[self]


_STATE_SENTENCES = {
    MissionState.UNCHANGED: "The vehicle's mission is unchanged.",
    MissionState.PARTIAL: (
        "The vehicle's mission is now PARTIAL: it may hold a mix of old and new items. Do not "
        "fly it: upload again, or clear it with `sfap clear`."
    ),
    MissionState.REPLACED_VERIFIED: "The vehicle's mission was replaced and verified.",
    MissionState.REPLACED_DIFFERS: (
        "The vehicle's mission was replaced but DIFFERS from what was sent. Do not fly it: "
        "upload again, or clear it with `sfap clear`."
    ),
    MissionState.REPLACED_UNVERIFIED: (
        "The vehicle accepted the mission but it could not be read back to verify it: check it "
        "with `sfap download` or upload again before flying."
    ),
    MissionState.CLEARED: "The vehicle's mission is cleared.",
}


class TransferPhase(StrEnum):
    UPLOAD = "upload"
    VERIFY = "verify"
    DOWNLOAD = "download"
    CLEAR = "clear"


#: progress(phase, items done, items in total)
ProgressCallback = Callable[[TransferPhase, int, int], None]


# --- MAV_MISSION_RESULT in words ------------------------------------------------------------------

_RESULT_SENTENCES: dict[int, str] = {
    0: "the vehicle accepted it (MAV_MISSION_ACCEPTED)",
    1: ("the vehicle reported an unspecified error (MAV_MISSION_ERROR); its status messages may say why"),
    2: (
        "the vehicle does not support the coordinate frame of an item "
        "(MAV_MISSION_UNSUPPORTED_FRAME); use altitudes relative to home or AMSL"
    ),
    3: (
        "the vehicle does not support a command in the mission (MAV_MISSION_UNSUPPORTED); "
        "check the mission's commands against this autopilot and its firmware version"
    ),
    4: (
        "the vehicle has no room for this many items (MAV_MISSION_NO_SPACE); split the mission "
        "into sorties, or wait a few seconds after boot and try again"
    ),
    5: "the vehicle found an item invalid (MAV_MISSION_INVALID)",
    13: (
        "the vehicle received an item out of sequence (MAV_MISSION_INVALID_SEQUENCE); the link "
        "may be losing or reordering messages"
    ),
    14: (
        "the vehicle refuses to change its mission now (MAV_MISSION_DENIED); it may be armed "
        "and flying a mission, or another ground station is transferring one"
    ),
    15: "the vehicle cancelled the transfer (MAV_MISSION_OPERATION_CANCELLED)",
}
_PARAM_MEANING = {
    1: "param 1",
    2: "param 2",
    3: "param 3",
    4: "param 4",
    5: "param 5 (latitude)",
    6: "param 6 (longitude)",
    7: "param 7 (altitude)",
}
_ACCEPTED = 0
_NO_SPACE = 4
_INVALID_SEQUENCE = 13


def describe_mission_result(code: int) -> str:
    """A MAV_MISSION_RESULT code as a sentence a person understands."""
    if code in _RESULT_SENTENCES:
        return _RESULT_SENTENCES[code]
    if 6 <= code <= 12:
        n = code - 5
        suffix = {5: "_X", 6: "_Y"}.get(n, "")
        return (
            f"the vehicle found {_PARAM_MEANING[n]} of an item out of its range "
            f"(MAV_MISSION_INVALID_PARAM{n}{suffix})"
        )
    return f"the vehicle answered with an unknown mission result code {code}"


# --- results and errors ------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class ItemDifference:
    """One way in which an item read back differs from the item sent.

    ``index`` is the item's 1-based position in the mission (None for the item count),
    ``seq`` its index on the vehicle (ArduPilot: home is seq 0, so seq = index).
    """

    index: int | None
    seq: int | None
    command: str
    field: str
    sent: str
    received: str

    def describe(self) -> str:
        if self.index is None:
            return f"{self.field}: sent {self.sent}, read back {self.received}"
        return (
            f"item {self.index} ({self.command}, vehicle seq {self.seq}): {self.field} sent "
            f"{self.sent}, read back {self.received}"
        )

    def to_dict(self) -> dict[str, object]:
        return {
            "index": self.index,
            "seq": self.seq,
            "command": self.command,
            "field": self.field,
            "sent": self.sent,
            "received": self.received,
        }


@dataclass(frozen=True, kw_only=True)
class UploadResult:
    """What an upload did. ``upload_s``/``verify_s`` are wall-clock seconds."""

    url: str
    autopilot: Autopilot
    vehicle_type: VehicleType | None
    mission_type: MissionType
    state: MissionState
    items: int  # mission items, home not counted
    items_sent: int  # MISSION_COUNT: with ArduPilot's home item
    differences: tuple[ItemDifference, ...] = ()
    upload_s: float = 0.0
    verify_s: float = 0.0
    items_resent: int = 0  # item messages sent more than once (loss, repeated requests)
    notes: tuple[str, ...] = ()

    @property
    def verified(self) -> bool:
        return self.state is MissionState.REPLACED_VERIFIED

    def summary(self) -> str:
        head = (
            f"{self.items} items to {self.autopilot.value} on {self.url} in "
            f"{self.upload_s:.1f} s, read back in {self.verify_s:.1f} s: {self.state.sentence}"
        )
        if not self.differences:
            return head
        lines = [d.describe() for d in self.differences[:30]]
        more = len(self.differences) - len(lines)
        if more > 0:
            lines.append(f"... and {more} more differences")
        return head + "\nDifferences:\n  " + "\n  ".join(lines)

    def to_dict(self) -> dict[str, object]:
        return {
            "url": self.url,
            "autopilot": self.autopilot.value,
            "vehicle_type": None if self.vehicle_type is None else self.vehicle_type.value,
            "mission_type": self.mission_type.name.lower(),
            "state": self.state.value,
            "verified": self.verified,
            "items": self.items,
            "items_sent": self.items_sent,
            "upload_s": round(self.upload_s, 3),
            "verify_s": round(self.verify_s, 3),
            "items_resent": self.items_resent,
            "differences": [d.to_dict() for d in self.differences],
            "notes": list(self.notes),
        }


class MissionTransferError(TransferError):
    """A transfer failed; ``mission_state`` says what the vehicle now holds."""

    def __init__(self, message: str, *, mission_state: MissionState) -> None:
        super().__init__(f"{message}. {mission_state.sentence}")
        self.mission_state = mission_state


class MissionTooLargeError(MissionTransferError):
    """The vehicle holds fewer items than the mission has (MAV_MISSION_NO_SPACE with its
    capacity, "Only N items are supported"); nothing changed on the vehicle."""

    def __init__(self, message: str, *, items: int, capacity: int | None) -> None:
        super().__init__(message, mission_state=MissionState.UNCHANGED)
        self.items = items
        self.capacity = capacity


class MissionInputError(InputError, MissionValidationError):
    """The mission cannot be sent as it is (it fails validation, or it was planned for the
    other autopilot): bad input, exit code 2; nothing was sent."""


class MissionVerificationError(VerificationError):
    """The read-back differs from what was sent; ``result`` lists the differences."""

    def __init__(self, result: UploadResult) -> None:
        super().__init__(
            f"the mission read back from {result.url} differs from the one sent in "
            f"{len(result.differences)} places. {result.summary()}"
        )
        self.result = result
        self.mission_state = result.state


# --- the protocol engine -----------------------------------------------------------------------


@dataclass
class _Session:
    """One transfer's bookkeeping: the link, the timing, and what the vehicle said."""

    link: LinkLike
    mission_type: MissionType
    timeout_s: float
    retries: int
    status_texts: list[str] = field(default_factory=list)

    def recv(self, types: set[str], deadline: float) -> Any | None:
        """The next message of ``types`` for our mission type, or None at ``deadline``."""
        wanted = types | {"STATUSTEXT"}
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return None
            message = self.link.recv(wanted, timeout_s=remaining)
            if message is None:
                return None
            if message.get_type() == "STATUSTEXT":
                text = str(message.text).strip()
                log.info("vehicle says: %s", text)
                # warnings and worse (MAV_SEVERITY <= 4) explain refusals; the rest is chatter
                if int(message.severity) <= 4:
                    self.status_texts.append(text)
                    del self.status_texts[:-5]
                continue
            if int(getattr(message, "mission_type", 0)) != int(self.mission_type):
                continue
            return message

    def deadline(self) -> float:
        return time.monotonic() + self.timeout_s

    def vehicle_said(self) -> str:
        if not self.status_texts:
            return ""
        recent = list(dict.fromkeys(reversed(self.status_texts)))[:3][::-1]
        return " (the vehicle said: " + "; ".join(f"'{t}'" for t in recent) + ")"

    def msg(self, name: str, **fields: Any) -> Any:
        from pymavlink.dialects.v20 import ardupilotmega as mavlink2

        cls = getattr(mavlink2, f"MAVLink_{name}_message")
        return cls(
            target_system=self.link.target_system,
            target_component=self.link.target_component,
            mission_type=int(self.mission_type),
            **fields,
        )


@dataclass
class _SendOutcome:
    items_resent: int
    notes: list[str]


def _send_items(
    session: _Session,
    wire_items: Sequence[MissionItem],
    *,
    progress: ProgressCallback | None,
    no_space_wait_s: float,
    no_space_retries: int,
    failed_state: Callable[[bool], MissionState],
) -> _SendOutcome:
    """Run the upload half of the protocol. ``failed_state(any_item_sent)`` names the state."""
    link = session.link
    count = len(wire_items)
    notes: list[str] = []
    sent: set[int] = set()
    sends = 0
    last_seq: int | None = None  # the last item requested
    resent_final = False
    attempts = 0
    no_space_tries = 0

    def fail(reason: str) -> MissionTransferError:
        return MissionTransferError(
            f"upload to {link.url} failed: {reason}{session.vehicle_said()}",
            mission_state=failed_state(bool(sent)),
        )

    link.send(session.msg("mission_count", count=count))
    deadline = session.deadline()
    while True:
        message = session.recv({"MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"}, deadline)
        final_sent = (count - 1) in sent
        if message is None:
            attempts += 1
            if attempts > session.retries:
                if final_sent:
                    # Every item went out; only the ACK is missing. The read-back decides.
                    notes.append("the vehicle did not acknowledge the last item; read-back decides")
                    return _SendOutcome(sends - len(sent), notes)
                if not sent:
                    raise fail(
                        f"the vehicle did not ask for any item after {attempts} MISSION_COUNT "
                        f"messages {session.timeout_s:g} s apart; it may not support missions "
                        f"or the link loses everything we send"
                    )
                raise fail(
                    f"the vehicle stopped asking for items after item {max(sent) + 1} of {count} "
                    f"(no request in {attempts} x {session.timeout_s:g} s)"
                )
            if not sent:
                log.debug("no request yet: MISSION_COUNT again (%d)", attempts)
                link.send(session.msg("mission_count", count=count))
            elif final_sent:
                # The vehicle drives an upload and re-requests what it lacks; only a lost final
                # ACK needs us: the last item again makes the vehicle repeat its ACK.
                log.debug("no MISSION_ACK: last item again (%d)", attempts)
                final = count - 1
                link.send(to_mission_item_int(wire_items[final], final, *_target(session)))
                sends += 1
                resent_final = True
            deadline = session.deadline()
            continue
        kind = message.get_type()
        if kind == "MISSION_ACK":
            code = int(message.type)
            if code == _ACCEPTED:
                if final_sent:
                    return _SendOutcome(sends - len(sent), notes)
                log.debug("MISSION_ACK accepted before the last item: stale, ignored")
                continue
            if code == _INVALID_SEQUENCE:
                # ArduPilot and PX4 say this about a duplicate item and carry on.
                log.debug("MISSION_ACK invalid sequence: a duplicate crossed; carrying on")
                continue
            if code == _NO_SPACE and not sent:
                capacity = _capacity_said(session, deadline_s=0.5)
                if (capacity is not None and 0 < capacity < count) or (
                    capacity is None and link.autopilot is Autopilot.PX4
                ):
                    raise _too_large(link.url, count, capacity, session)
            if code == _NO_SPACE and not sent and no_space_tries < no_space_retries:
                no_space_tries += 1
                note = (
                    f"the vehicle refused with NO_SPACE (as ArduPilot does just after boot); "
                    f"asked again after {no_space_wait_s:g} s"
                )
                log.info(note)
                notes.append(note)
                time.sleep(no_space_wait_s)
                link.send(session.msg("mission_count", count=count))
                attempts = 0
                deadline = session.deadline()
                continue
            if final_sent and resent_final:
                notes.append(
                    f"after the last item was repeated the vehicle answered: "
                    f"{describe_mission_result(code)}; read-back decides"
                )
                return _SendOutcome(sends - len(sent), notes)
            where = (
                f" (the vehicle had last asked for seq {last_seq} of 0-{count - 1})"
                if last_seq is not None
                else ""
            )
            if code == _NO_SPACE and not sent:
                where = f" ({count} items, refused {no_space_tries + 1} times)"
            raise fail(describe_mission_result(code) + where)
        seq = int(message.seq)
        if not 0 <= seq < count:
            log.debug("request for seq %d outside 0-%d ignored", seq, count - 1)
            continue
        link.send(to_mission_item_int(wire_items[seq], seq, *_target(session)))
        sends += 1
        if seq not in sent:
            sent.add(seq)
            if progress is not None:
                progress(TransferPhase.UPLOAD, len(sent), count)
        last_seq = seq
        attempts = 0
        deadline = session.deadline()


_CAPACITY_RE = re.compile(r"Only (\d+) items are supported", re.I)


def _capacity_said(session: _Session, *, deadline_s: float) -> int | None:
    """The capacity in the vehicle's "Only N items are supported" (ArduPilot), waiting up to
    ``deadline_s`` for it when it has not come yet; None when it does not say."""

    def said() -> int | None:
        for text in reversed(session.status_texts):
            found = _CAPACITY_RE.search(text)
            if found:
                return int(found.group(1))
        return None

    value = said()
    if value is not None:
        return value
    session.recv(set(), time.monotonic() + deadline_s)  # collects STATUSTEXT on the way
    return said()


def _too_large(url: str, count: int, capacity: int | None, session: _Session) -> MissionTooLargeError:
    if capacity is None:
        size = f"the mission's {count} items do not fit this vehicle (MAV_MISSION_NO_SPACE)"
    else:
        size = (
            f"the mission has {count} items (home included) and this vehicle holds at most {capacity}: "
            f"{count - capacity} too many"
        )
    return MissionTooLargeError(
        f"upload to {url} refused: {size}{session.vehicle_said()}. Split the survey into sorties that fit "
        f"(plan part of the area per sortie, or fewer passes per mission) and upload them one after "
        f"another. Nothing was sent: the vehicle's mission is unchanged.",
        items=count,
        capacity=capacity,
    )


def _target(session: _Session) -> tuple[int, int, int]:
    link = session.link
    return link.target_system, link.target_component, int(session.mission_type)


def _request_count(session: _Session, what: str) -> int:
    """MISSION_REQUEST_LIST until MISSION_COUNT comes back (with retries)."""
    link = session.link
    last_error: int | None = None
    for attempt in range(session.retries + 1):
        if attempt:
            log.debug("no MISSION_COUNT: asking again (%d)", attempt)
        link.send(session.msg("mission_request_list"))
        deadline = session.deadline()
        while True:
            message = session.recv({"MISSION_COUNT", "MISSION_ACK"}, deadline)
            if message is None:
                break
            if message.get_type() == "MISSION_COUNT":
                return int(message.count)
            if int(message.type) != _ACCEPTED:
                last_error = int(message.type)  # wait out the timeout before asking again
    reason = (
        describe_mission_result(last_error)
        if last_error is not None
        else f"no MISSION_COUNT after {session.retries + 1} requests {session.timeout_s:g} s apart"
    )
    raise TransferError(f"{what} from {link.url} failed: {reason}{session.vehicle_said()}")


def _receive_items(
    session: _Session, *, phase: TransferPhase, progress: ProgressCallback | None
) -> list[MissionItem]:
    """The download half of the protocol: every item of the list, in order."""
    link = session.link
    what = "verification read-back" if phase is TransferPhase.VERIFY else "download"
    count = _request_count(session, what)
    if progress is not None:
        progress(phase, 0, count)
    items: dict[int, MissionItem] = {}
    for seq in range(count):
        if seq in items:
            continue
        attempts = 0
        last_error: int | None = None
        link.send(session.msg("mission_request_int", seq=seq))
        deadline = session.deadline()
        while seq not in items:
            message = session.recv({"MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK"}, deadline)
            if message is not None and message.get_type() != "MISSION_ACK":
                got = int(message.seq)
                if 0 <= got < count and got not in items:
                    try:
                        items[got] = from_mission_item(message)
                    except ValueError as error:
                        raise TransferError(
                            f"{what} from {link.url} failed: item {got} is not readable ({error})"
                        ) from error
                    if progress is not None:
                        progress(phase, len(items), count)
                continue
            if message is not None:
                # A refusal (or a stale answer to an earlier transfer): note it and wait out
                # the timeout, so that a vehicle busy for a moment gets its time; give up only
                # when it keeps refusing.
                if int(message.type) != _ACCEPTED:
                    last_error = int(message.type)
                continue
            attempts += 1
            if attempts > session.retries:
                reason = (
                    describe_mission_result(last_error)
                    if last_error is not None
                    else f"no answer after {attempts} requests {session.timeout_s:g} s apart"
                )
                raise TransferError(
                    f"{what} from {link.url} failed at item {seq} of {count}: {reason}"
                    f"{session.vehicle_said()}"
                )
            link.send(session.msg("mission_request_int", seq=seq))
            deadline = session.deadline()
    link.send(session.msg("mission_ack", type=_ACCEPTED))
    return [items[seq] for seq in range(count)]


# --- public API ---------------------------------------------------------------------------------


def _has_home_item(autopilot: Autopilot, mission_type: MissionType) -> bool:
    return autopilot is Autopilot.ARDUPILOT and mission_type is MissionType.MISSION


def home_item(home: HomePosition) -> MissionItem:
    """ArduPilot's item 0: the home position as a waypoint in AMSL."""
    return MissionItem(
        command=MavCmd.NAV_WAYPOINT,
        frame=MavFrame.GLOBAL,
        param1=0.0,
        param5=home.lat_deg,
        param6=home.lon_deg,
        param7=home.alt_amsl_m,
    )


_FENCE_COMMANDS = frozenset({5001, 5002, 5003, 5004})
_AUTOPILOT_NAME = {Autopilot.ARDUPILOT: "ArduPilot", Autopilot.PX4: "PX4"}


def _validate(mission: Mission, mission_type: MissionType, max_alt_rel_home_m: float | None) -> None:
    try:
        if mission_type is MissionType.MISSION:
            validate_mission(mission, max_alt_rel_home_m=max_alt_rel_home_m)
            return
        problems = []
        if not mission.items:
            problems.append("the fence has no items")
        for index, item in enumerate(mission.items, start=1):
            if mission_type is MissionType.FENCE and int(item.command) not in _FENCE_COMMANDS:
                problems.append(f"item {index}: command {item.command} is not a fence command (5001-5004)")
            if not (-90 <= item.lat_deg <= 90 and -180 <= item.lon_deg <= 180):
                problems.append(f"item {index}: latitude/longitude out of range")
        if problems:
            raise MissionInputError(
                "the fence failed validation and will not be sent:\n  " + "\n  ".join(problems)
            )
    except MissionValidationError as error:
        raise MissionInputError(f"{error}\nNothing was sent: the vehicle's mission is unchanged.") from error


# AP_Mission::sanity_check_params: the params (1-4) that may be NaN; any other NaN is refused
# with MAV_MISSION_INVALID_PARAMn, so it is refused here before anything is sent.
_AP_NAN_ALLOWED: dict[int, frozenset[int]] = {
    MavCmd.NAV_WAYPOINT: frozenset({4}),
    MavCmd.NAV_LAND: frozenset({4}),
    MavCmd.NAV_TAKEOFF: frozenset({4}),
    MavCmd.NAV_VTOL_TAKEOFF: frozenset({4}),
    MavCmd.NAV_VTOL_LAND: frozenset({3, 4}),
}


def _check_ardupilot_nan(items: Sequence[MissionItem]) -> None:
    problems = []
    for index, item in enumerate(items, start=1):
        allowed = _AP_NAN_ALLOWED.get(int(item.command), frozenset())
        for n, value in enumerate(item.params[:4], start=1):
            if value is None and n not in allowed:
                problems.append(
                    f"item {index} ({item.command_name}): param {n} is empty (NaN), which "
                    f"ArduPilot refuses for this command; give a number"
                )
    if problems:
        raise MissionInputError(
            "the mission cannot go to ArduPilot as it is:\n  "
            + "\n  ".join(problems[:20])
            + "\nNothing was sent: the vehicle's mission is unchanged."
        )


def upload_mission(
    link: LinkLike,
    mission: Mission,
    *,
    progress: ProgressCallback | None = None,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    retries: int = DEFAULT_RETRIES,
    max_alt_rel_home_m: float | None = None,
    mission_type: MissionType = MissionType.MISSION,
    no_space_wait_s: float = 2.0,
    no_space_retries: int = 3,
    allow_other_autopilot: bool = False,
) -> UploadResult:
    """Validate ``mission``, upload it, read it back and verify it item by item.

    ``timeout_s``: how long to wait for the vehicle before repeating our last message (s);
    ``retries``: how many times to repeat it before giving up. ``max_alt_rel_home_m``: the
    vehicle's altitude limit above home (m), checked before anything is sent.
    ``no_space_wait_s``/``no_space_retries``: the pause and the number of new attempts after a
    MAV_MISSION_NO_SPACE refusal received before any item was requested (ArduPilot just after
    boot: "Only 0 items are supported"); a refusal that names a capacity smaller than the
    mission ("Only 650 items are supported"), or PX4's NO_SPACE, raises
    :class:`MissionTooLargeError` at once, with the excess. A mission file that says it was
    planned for the other autopilot is refused (:class:`MissionValidationError`) unless
    ``allow_other_autopilot``. With ``mission_type`` FENCE, ``mission.items`` are the fence items.

    Returns the :class:`UploadResult` of a verified upload. Raises
    :class:`MissionValidationError` (nothing sent), :class:`MissionTransferError` (the transfer
    failed; its ``mission_state`` says what the vehicle holds) or
    :class:`MissionVerificationError` (the read-back differs; its ``result`` lists how).
    """
    _validate(mission, mission_type, max_alt_rel_home_m)
    autopilot = link.autopilot
    if mission_type is MissionType.MISSION and mission.autopilot is not autopilot:
        if mission.metadata.get("autopilot_from_file") and not allow_other_autopilot:
            raise MissionInputError(
                f"the mission was planned for {_AUTOPILOT_NAME[mission.autopilot]} but the vehicle on "
                f"{link.url} is {_AUTOPILOT_NAME[autopilot]}: their mission commands differ (gimbal, "
                f"camera, empty parameters), so it would not fly as planned. Plan it again with "
                f'[vehicle] autopilot = "{autopilot.value}" in the mission spec (or pass '
                f"--allow-other-autopilot to send it as it is). Nothing was sent: the vehicle's mission "
                f"is unchanged."
            )
        log.warning(
            "the mission was planned for %s but the vehicle is %s: uploading it as %s expects",
            mission.autopilot.value,
            autopilot.value,
            autopilot.value,
        )
    if autopilot is Autopilot.ARDUPILOT and mission_type is MissionType.MISSION:
        _check_ardupilot_nan(mission.items)
    with_home = _has_home_item(autopilot, mission_type)
    wire_items = ([home_item(mission.home)] if with_home else []) + list(mission.items)
    if len(wire_items) > 65535:
        raise MissionInputError(
            f"{len(wire_items)} items do not fit the mission protocol (at most 65535); split "
            f"the mission into sorties. Nothing was sent: the vehicle's mission is unchanged."
        )
    session = _Session(link=link, mission_type=mission_type, timeout_s=timeout_s, retries=retries)

    def failed_state(any_item_sent: bool) -> MissionState:
        # PX4 writes an upload to a spare buffer and switches only when it completes; ArduPilot
        # replaces its stored items one by one as they arrive.
        if not any_item_sent or autopilot is Autopilot.PX4:
            return MissionState.UNCHANGED
        return MissionState.PARTIAL

    started = time.monotonic()
    sent_any = False

    def tracking(phase: TransferPhase, done: int, total: int) -> None:
        nonlocal sent_any
        sent_any = sent_any or done > 0
        if progress is not None:
            progress(phase, done, total)

    try:
        outcome = _send_items(
            session,
            wire_items,
            progress=tracking,
            no_space_wait_s=no_space_wait_s,
            no_space_retries=no_space_retries,
            failed_state=failed_state,
        )
    except LinkError as error:
        raise MissionTransferError(f"upload failed: {error}", mission_state=failed_state(sent_any)) from error
    upload_s = time.monotonic() - started
    log.info("upload of %d items took %.2f s", len(wire_items), upload_s)

    verify_started = time.monotonic()
    try:
        received = _receive_items(session, phase=TransferPhase.VERIFY, progress=progress)
    except (TransferError, LinkError) as error:
        raise MissionTransferError(
            f"the upload completed but reading it back failed: {error}",
            mission_state=MissionState.REPLACED_UNVERIFIED,
        ) from error
    verify_s = time.monotonic() - verify_started
    differences = verify_readback(
        mission.items, received, autopilot, link.vehicle_type, mission_type=mission_type
    )
    result = UploadResult(
        url=link.url,
        autopilot=autopilot,
        vehicle_type=link.vehicle_type,
        mission_type=mission_type,
        state=MissionState.REPLACED_DIFFERS if differences else MissionState.REPLACED_VERIFIED,
        items=len(mission.items),
        items_sent=len(wire_items),
        differences=tuple(differences),
        upload_s=upload_s,
        verify_s=verify_s,
        items_resent=outcome.items_resent,
        notes=tuple(outcome.notes),
    )
    if differences:
        raise MissionVerificationError(result)
    return result


def download_mission(
    link: LinkLike,
    *,
    mission_type: MissionType = MissionType.MISSION,
    progress: ProgressCallback | None = None,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    retries: int = DEFAULT_RETRIES,
) -> list[MissionItem]:
    """Every item the vehicle stores, in vehicle order (ArduPilot: home first, as item 0).

    Raises :class:`TransferError` when the vehicle does not answer or refuses; nothing on the
    vehicle changes either way.
    """
    session = _Session(link=link, mission_type=mission_type, timeout_s=timeout_s, retries=retries)
    return _receive_items(session, phase=TransferPhase.DOWNLOAD, progress=progress)


def clear_mission(
    link: LinkLike,
    *,
    mission_type: MissionType = MissionType.MISSION,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    retries: int = DEFAULT_RETRIES,
) -> MissionState:
    """Clear the vehicle's mission (or fence) and prove it by reading the count back.

    Returns :attr:`MissionState.CLEARED`; raises :class:`MissionTransferError` otherwise.
    """
    session = _Session(link=link, mission_type=mission_type, timeout_s=timeout_s, retries=retries)
    refused: int | None = None
    acknowledged = False
    try:
        for attempt in range(retries + 1):
            if attempt:
                log.debug("no MISSION_ACK to MISSION_CLEAR_ALL: asking again (%d)", attempt)
            link.send(session.msg("mission_clear_all"))
            deadline = session.deadline()
            while not acknowledged and refused is None:
                message = session.recv({"MISSION_ACK"}, deadline)
                if message is None:
                    break
                code = int(message.type)
                if code == _ACCEPTED:
                    acknowledged = True
                elif code != _INVALID_SEQUENCE:  # that one answers a stale duplicate item
                    refused = code
            if acknowledged or refused is not None:
                break
        if refused is not None:
            raise MissionTransferError(
                f"clear on {link.url} refused: {describe_mission_result(refused)}{session.vehicle_said()}",
                mission_state=MissionState.UNCHANGED,
            )
        empty = 1 if _has_home_item(link.autopilot, mission_type) else 0
        count = _request_count(session, "checking the clear")
    except (LinkError, TransferError) as error:
        if isinstance(error, MissionTransferError):
            raise
        raise MissionTransferError(
            f"clear on {link.url} could not be confirmed: {error}",
            mission_state=MissionState.UNCHANGED if not acknowledged else MissionState.CLEARED,
        ) from error
    if count > empty:
        raise MissionTransferError(
            f"clear on {link.url} failed: the vehicle still reports {count - empty} items"
            + ("" if acknowledged else " and never acknowledged the clear"),
            mission_state=MissionState.UNCHANGED,
        )
    return MissionState.CLEARED


def request_home_position(
    link: LinkLike, *, timeout_s: float = DEFAULT_TIMEOUT_S, retries: int = 2
) -> HomePosition | None:
    """The vehicle's home (HOME_POSITION, asked for with MAV_CMD_REQUEST_MESSAGE), or None
    when it has none yet (no GPS fix) or does not answer."""
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    for attempt in range(retries + 1):
        link.send(
            mavlink2.MAVLink_command_long_message(
                link.target_system,
                link.target_component,
                mavlink2.MAV_CMD_REQUEST_MESSAGE,
                attempt,  # confirmation
                float(mavlink2.MAVLINK_MSG_ID_HOME_POSITION),
                0,
                0,
                0,
                0,
                0,
                0,
            )
        )
        deadline = time.monotonic() + timeout_s
        while (remaining := deadline - time.monotonic()) > 0:
            message = link.recv({"HOME_POSITION", "COMMAND_ACK"}, timeout_s=remaining)
            if message is None:
                break
            if message.get_type() == "HOME_POSITION":
                return home_from_message(message)
            if (
                int(message.command) == mavlink2.MAV_CMD_REQUEST_MESSAGE
                and int(message.result) != mavlink2.MAV_RESULT_ACCEPTED
            ):
                return None  # refused: no home yet, or the message is not supported
    return None


def first_waypoint_distance_m(items: Sequence[MissionItem], home: HomePosition) -> float | None:
    """Geodesic distance (m, WGS84) from ``home`` to the first item with a position (a global
    frame and a latitude or longitude that is not 0); None when no item has one."""
    from planner.geo import geodesic_distance_m

    for item in items:
        if is_global_frame(item.frame) and (item.lat_deg != 0.0 or item.lon_deg != 0.0):
            return geodesic_distance_m(home.lat_deg, home.lon_deg, item.lat_deg, item.lon_deg)
    return None


def downloaded_mission(
    items: Sequence[MissionItem],
    autopilot: Autopilot,
    vehicle_type: VehicleType | None,
    *,
    home: HomePosition | None = None,
) -> Mission:
    """A :class:`Mission` from :func:`download_mission`'s list, ready for a file writer.

    Home is ``home`` when given (from :func:`request_home_position`), else ArduPilot's item 0
    when the vehicle has one (it reads back as zeros before a GPS fix), else the first
    positional item's latitude and longitude at 0 m AMSL.
    """
    body = list(items)
    if autopilot is Autopilot.ARDUPILOT and body:
        first = body.pop(0)
        if home is None and (first.lat_deg != 0.0 or first.lon_deg != 0.0):
            home = HomePosition(lat_deg=first.lat_deg, lon_deg=first.lon_deg, alt_amsl_m=first.alt_m)
    if home is None:
        for item in body:
            if is_global_frame(item.frame) and (item.lat_deg != 0.0 or item.lon_deg != 0.0):
                home = HomePosition(lat_deg=item.lat_deg, lon_deg=item.lon_deg)
                log.warning(
                    "the vehicle reported no home position: the file's home is the first "
                    "waypoint's position at 0 m AMSL"
                )
                break
    if home is None:
        home = HomePosition(lat_deg=0.0, lon_deg=0.0)
    return Mission(
        items=tuple(body),
        home=home,
        autopilot=autopilot,
        vehicle_type=vehicle_type or VehicleType.MULTIROTOR,
        metadata={"source": "downloaded from the vehicle"},
    )


# --- verification ------------------------------------------------------------------------------

# How ArduPilot stores items (AP_Mission, REFERENCES.md section 3). A parameter passes when it
# reads back exactly (to float32) or as the storage rule makes it:
#   "whole": an unsigned integer (hold seconds, flags); "byte": clamped to 0-255 (Plane radii);
#   "zero": not stored, reads back 0.
_Rule = str
_AP_COPTER_WAYPOINT: dict[int, _Rule] = {1: "whole", 2: "zero", 3: "zero", 4: "zero"}
_AP_PLANE_WAYPOINT: dict[int, _Rule] = {1: "zero", 2: "byte", 3: "byte", 4: "zero"}
_AP_RULES: dict[int, dict[int, _Rule]] = {
    MavCmd.NAV_TAKEOFF: {1: "whole", 2: "zero", 3: "zero", 4: "zero"},
    MavCmd.NAV_LAND: {1: "whole", 2: "zero", 3: "zero", 4: "zero"},
    MavCmd.NAV_LOITER_UNLIM: {1: "zero", 2: "zero", 3: "whole", 4: "zero"},
    MavCmd.NAV_LOITER_TURNS: {1: "whole", 2: "zero", 3: "whole", 4: "zero"},
    MavCmd.NAV_LOITER_TIME: {1: "whole", 2: "zero", 3: "whole", 4: "zero"},
    MavCmd.NAV_RETURN_TO_LAUNCH: {n: "zero" for n in range(1, 8)},
    MavCmd.DO_MOUNT_CONTROL: {4: "zero", 5: "zero", 6: "zero", 7: "zero"},
    MavCmd.DO_SET_CAM_TRIGG_DIST: {2: "zero", 3: "whole"},
    MavCmd.DO_CHANGE_SPEED: {1: "whole", 4: "zero"},
    MavCmd.IMAGE_START_CAPTURE: {1: "whole", 3: "whole", 4: "whole"},
    MavCmd.DO_DIGICAM_CONTROL: {n: "whole" for n in range(1, 7)},
}
# Commands for which ArduPilot stores a location (params 5-7 are lat, lon, alt with a frame).
_AP_LOCATION_COMMANDS = frozenset(
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
        MavCmd.DO_SET_HOME,
        MavCmd.DO_SET_ROI_LOCATION,
        201,  # DO_SET_ROI
    }
)
_AP_ALT_STEP_M = 0.01  # ArduPilot stores altitudes as integer centimetres


def _fmt(value: float | None, n: int, global_frame: bool) -> str:
    if value is None:
        return "none (NaN)"
    if global_frame and n in (5, 6):
        return f"{value:.7f}"
    return f"{value:.6g}"


def _same32(a: float | None, b: float | None) -> bool:
    """Equal as float32 storage makes them. A float parameter travels and is stored as a
    float32, so what comes back is exactly the float32 nearest to what was sent: the tolerance
    is that rounding (half a unit in the 24th significant bit, 2**-24 relative), and anything
    else is a difference. A trigger distance of 11.06 m read back as 11 m (truncated to whole
    metres) is 0.5 % off: different."""
    if a is None or b is None:
        return a is None and b is None
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return float32(a) == float32(b)


# How PX4 stores positional items (MavlinkMissionManager::parse_mavlink_mission_item and
# format_mavlink_mission_item): only the fields it keeps come back, the others read 0, and yaw
# is kept in radians wrapped to -pi..pi ("yaw": the same heading, to 1e-3 deg).
_PX4_RULES: dict[int, dict[int, _Rule]] = {
    MavCmd.NAV_WAYPOINT: {3: "zero", 4: "yaw"},
    MavCmd.NAV_TAKEOFF: {1: "zero", 2: "zero", 3: "zero", 4: "yaw"},
    MavCmd.NAV_LAND: {1: "zero", 3: "zero", 4: "yaw"},
    MavCmd.NAV_LOITER_UNLIM: {1: "zero", 2: "zero", 4: "yaw"},
    MavCmd.NAV_LOITER_TO_ALT: {3: "zero"},
    MavCmd.NAV_VTOL_TAKEOFF: {1: "zero", 2: "zero", 3: "zero", 4: "yaw"},
    MavCmd.NAV_VTOL_LAND: {1: "zero", 2: "zero", 3: "zero", 4: "yaw"},
}


def _rule_allows(rule: _Rule | None, sent: float | None, received: float | None) -> bool:
    if rule is None or received is None:
        return False
    if rule == "yaw":
        if sent is None or not math.isfinite(sent) or not math.isfinite(received):
            return False
        turn = (received - sent) % 360.0
        return min(turn, 360.0 - turn) <= 1e-3
    if rule == "zero":
        return received == 0.0
    source = 0.0 if sent is None or not math.isfinite(sent) else sent
    if rule == "whole":
        options = {min(max(math.trunc(source), 0), 65535), min(max(round(source), 0), 65535)}
        return received in options
    if rule == "byte":
        options = {min(max(math.trunc(source), 0), 255), min(max(round(source), 0), 255)}
        return received in options
    return False


def _ap_rules(command: int, vehicle_type: VehicleType | None) -> dict[int, _Rule]:
    if command == MavCmd.NAV_WAYPOINT:
        plane = vehicle_type in (VehicleType.FIXED_WING, VehicleType.VTOL)
        return _AP_PLANE_WAYPOINT if plane else _AP_COPTER_WAYPOINT
    return _AP_RULES.get(command, {})


def _compare_item(
    index: int,
    seq: int,
    sent: MissionItem,
    got: MissionItem,
    autopilot: Autopilot,
    vehicle_type: VehicleType | None,
    mission_type: MissionType,
) -> list[ItemDifference]:
    name = sent.command_name

    def diff(what: str, a: str, b: str) -> ItemDifference:
        return ItemDifference(index=index, seq=seq, command=name, field=what, sent=a, received=b)

    if int(sent.command) != int(got.command):
        return [diff("command", name, got.command_name)]
    ardupilot = autopilot is Autopilot.ARDUPILOT
    fence = mission_type is not MissionType.MISSION
    located = is_global_frame(sent.frame) and (
        not ardupilot or fence or int(sent.command) in _AP_LOCATION_COMMANDS
    )
    out: list[ItemDifference] = []
    # Frame: the INT and plain forms mean the same. ArduPilot drops the frame of items that
    # store no location (it reads back 0); fence vertices have no altitude, so no frame.
    frame_matters = not fence and (located or not ardupilot)
    if frame_matters:
        try:
            same = plain_frame(sent.frame) == plain_frame(got.frame)
        except ValueError:
            same = False
        if not same:
            out.append(diff("frame", MavFrame(sent.frame).name, str(got.frame.name)))
    if not ardupilot and sent.autocontinue != got.autocontinue:
        # ArduPilot does not store autocontinue (it always continues) and reads back 1.
        out.append(diff("autocontinue", str(sent.autocontinue), str(got.autocontinue)))
    if fence:
        rules: dict[int, _Rule] = {}
    elif ardupilot:
        rules = _ap_rules(int(sent.command), vehicle_type)
    else:
        rules = _PX4_RULES.get(int(sent.command), {})
    for n in range(1, 8):
        a = sent.params[n - 1]
        b = got.params[n - 1]
        if located and n in (5, 6):
            assert a is not None and b is not None
            if deg_to_e7(a) != deg_to_e7(b):
                label = "latitude" if n == 5 else "longitude"
                out.append(diff(f"{label} (degE7)", _fmt(a, n, True), _fmt(b, n, True)))
            continue
        if located and n == 7:
            assert a is not None and b is not None
            if fence:
                continue
            tolerance = _AP_ALT_STEP_M + 1e-6 * abs(a) if ardupilot else 0.0
            if not (_same32(a, b) or abs(a - b) <= tolerance):
                out.append(diff("altitude (m)", _fmt(a, 7, True), _fmt(b, 7, True)))
            continue
        if _same32(a, b) or _rule_allows(rules.get(n), a, b):
            continue
        out.append(diff(_PARAM_MEANING[n].split(" (")[0], _fmt(a, n, False), _fmt(b, n, False)))
    return out


def verify_readback(
    sent: Sequence[MissionItem],
    received: Sequence[MissionItem],
    autopilot: Autopilot,
    vehicle_type: VehicleType | None,
    *,
    mission_type: MissionType = MissionType.MISSION,
) -> list[ItemDifference]:
    """Every real difference between the items sent and the items read back.

    ``sent``: the mission's items (no home item). ``received``: as :func:`download_mission`
    returns them (ArduPilot: home first; it is skipped, since the vehicle keeps its own home).
    Latitude and longitude must match in degE7 exactly, float parameters to float32, frames in
    meaning (INT or not). With ArduPilot, what its storage changes is not a difference
    (REFERENCES.md section 3): frames of items without a location, autocontinue, a Copter
    waypoint's hold time in whole seconds and its dropped radii and yaw, a Plane waypoint's
    dropped hold time and radii clamped to 0-255, altitudes rounded to centimetres, and the
    parameters it does not store for a few DO commands. With PX4, what it does not store for
    positional items (a waypoint's pass radius, a take-off's pitch) and yaw wrapped to
    -180..180 degrees. Anything else is reported.
    """
    skip = 1 if _has_home_item(autopilot, mission_type) else 0
    body = list(received[skip:])
    differences: list[ItemDifference] = []
    if skip and not received:
        differences.append(
            ItemDifference(
                index=None,
                seq=None,
                command="",
                field="home item",
                sent="present",
                received="missing (the vehicle reported no items at all)",
            )
        )
    if len(body) != len(sent):
        differences.append(
            ItemDifference(
                index=None,
                seq=None,
                command="",
                field="number of items",
                sent=str(len(sent)),
                received=str(len(body)),
            )
        )
    for i, (a, b) in enumerate(zip(sent, body, strict=False)):
        differences.extend(_compare_item(i + 1, i + skip, a, b, autopilot, vehicle_type, mission_type))
    return differences
