"""The MAVLink mission protocol engine: one transfer's state machine, its timeouts and retries.

The protocol (mavlink.io "Mission Protocol"; REFERENCES.md section 3):

- Upload (:func:`send_items`): the ground station sends MISSION_COUNT; the vehicle asks for
  every item with MISSION_REQUEST_INT (ArduPilot: the legacy MISSION_REQUEST), in any order and
  as often as it likes; we answer each with MISSION_ITEM_INT; the vehicle ends with
  MISSION_ACK. When the vehicle goes quiet for ``timeout_s`` we repeat our last message
  (MISSION_COUNT, or the last item) up to ``retries`` times. Just after boot ArduPilot refuses
  an upload with MAV_MISSION_NO_SPACE ("Only 0 items are supported") and accepts it a moment
  later: that refusal, before any item was requested, is retried after a pause.
- Download (:func:`receive_items`): MISSION_REQUEST_LIST -> MISSION_COUNT
  (:func:`request_count`), then MISSION_REQUEST_INT per item -> MISSION_ITEM_INT, then our
  MISSION_ACK. Each request is repeated on timeout.

Every wait is measured on the link's clock (:attr:`LinkLike.clock`): the wall clock on a real
link, simulated time in tests (:mod:`acquisition.clock`).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Protocol

from planner.mission import Autopilot, MissionItem, VehicleType

from .clock import WALL_CLOCK, Clock
from .errors import TransferError
from .mavlink_items import MissionResult, MissionType, from_mission_item, to_mission_item_int
from .transfer_outcome import (
    MissionState,
    MissionTooLargeError,
    MissionTransferError,
    describe_mission_result,
)

log = logging.getLogger(__name__)

DEFAULT_TIMEOUT_S = 1.5
DEFAULT_RETRIES = 5


class LinkLike(Protocol):
    """What the transfer needs of a link (:class:`acquisition.link.Link` is one).

    A link may also have a ``clock`` (:class:`acquisition.clock.Clock`) that its ``recv``
    waits on; the transfer then measures its timeouts on it (:func:`link_clock`)."""

    url: str
    autopilot: Autopilot
    vehicle_type: VehicleType | None
    target_system: int
    target_component: int

    def send(self, message: Any) -> None: ...

    def recv(self, types: Any = None, timeout_s: float = 0.0) -> Any | None: ...


def link_clock(link: LinkLike) -> Clock:
    """The clock ``link`` waits on: its ``clock`` attribute, else the wall clock."""
    clock: Clock = getattr(link, "clock", WALL_CLOCK)
    return clock


class TransferPhase(StrEnum):
    UPLOAD = "upload"
    VERIFY = "verify"
    DOWNLOAD = "download"
    CLEAR = "clear"


#: progress(phase, items done, items in total)
ProgressCallback = Callable[[TransferPhase, int, int], None]


@dataclass
class Session:
    """One transfer's bookkeeping: the link, the timing, and what the vehicle said."""

    link: LinkLike
    mission_type: MissionType
    timeout_s: float
    retries: int
    status_texts: list[str] = field(default_factory=list)

    @property
    def clock(self) -> Clock:
        return link_clock(self.link)

    def recv(self, types: set[str], deadline: float) -> Any | None:
        """The next message of ``types`` for our mission type, or None at ``deadline``."""
        wanted = types | {"STATUSTEXT"}
        while True:
            remaining = deadline - self.clock.monotonic()
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
        return self.clock.monotonic() + self.timeout_s

    def vehicle_said(self, result: int | None = None) -> str:
        """The vehicle's recent warnings, quoted; for a refusal with MAV_MISSION_RESULT
        ``result``, not those that explain another refusal (ArduPilot's "Only N items are
        supported" belongs to NO_SPACE alone)."""
        texts = [t for t in self.status_texts if result is None or _explains(t) in (None, result)]
        if not texts:
            return ""
        recent = list(dict.fromkeys(reversed(texts)))[:3][::-1]
        return " (the vehicle said: " + "; ".join(f"'{t}'" for t in recent) + ")"

    def forget_texts(self) -> None:
        """The refusal these warnings explained was dealt with: they explain nothing after."""
        self.status_texts.clear()

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
class SendOutcome:
    items_resent: int
    notes: list[str]


def send_items(
    session: Session,
    wire_items: Sequence[MissionItem],
    *,
    progress: ProgressCallback | None,
    no_space_wait_s: float,
    no_space_retries: int,
    failed_state: Callable[[bool], MissionState],
) -> SendOutcome:
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

    def fail(reason: str, result: int | None = None) -> MissionTransferError:
        return MissionTransferError(
            f"upload to {link.url} failed: {reason}{session.vehicle_said(result)}",
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
                    return SendOutcome(sends - len(sent), notes)
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
            if code == MissionResult.ACCEPTED:
                if final_sent:
                    return SendOutcome(sends - len(sent), notes)
                log.debug("MISSION_ACK accepted before the last item: stale, ignored")
                continue
            if code == MissionResult.INVALID_SEQUENCE:
                # ArduPilot and PX4 say this about a duplicate item and carry on.
                log.debug("MISSION_ACK invalid sequence: a duplicate crossed; carrying on")
                continue
            if code == MissionResult.NO_SPACE and not sent:
                capacity = _capacity_said(session, deadline_s=0.5)
                if (capacity is not None and 0 < capacity < count) or (
                    capacity is None and link.autopilot is Autopilot.PX4
                ):
                    raise _too_large(link.url, count, capacity, session)
            if code == MissionResult.NO_SPACE and not sent and no_space_tries < no_space_retries:
                no_space_tries += 1
                note = (
                    f"the vehicle refused with NO_SPACE (as ArduPilot does just after boot); "
                    f"asked again after {no_space_wait_s:g} s"
                )
                log.info(note)
                notes.append(note)
                session.forget_texts()  # "Only 0 items are supported" answered this refusal only
                session.clock.sleep(no_space_wait_s)
                link.send(session.msg("mission_count", count=count))
                attempts = 0
                deadline = session.deadline()
                continue
            if final_sent and resent_final:
                notes.append(
                    f"after the last item was repeated the vehicle answered: "
                    f"{describe_mission_result(code)}; read-back decides"
                )
                return SendOutcome(sends - len(sent), notes)
            where = (
                f" (the vehicle had last asked for seq {last_seq} of 0-{count - 1})"
                if last_seq is not None
                else ""
            )
            if code == MissionResult.NO_SPACE and not sent:
                where = f" ({count} items, refused {no_space_tries + 1} times)"
            raise fail(describe_mission_result(code) + where, code)
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


def _explains(text: str) -> int | None:
    """The MAV_MISSION_RESULT a vehicle's warning is known to explain, or None."""
    if _CAPACITY_RE.search(text):
        return int(MissionResult.NO_SPACE)
    return None


def _capacity_said(session: Session, *, deadline_s: float) -> int | None:
    """The capacity in the vehicle's "Only N items are supported" (ArduPilot), waiting up to
    ``deadline_s`` for it when it has not come yet; None when it does not say."""

    def said() -> int | None:
        for text in reversed(session.status_texts):
            found = _CAPACITY_RE.search(text)
            if found:
                return int(found.group(1))
        return None

    clock = session.clock
    deadline = clock.monotonic() + deadline_s
    while (value := said()) is None and clock.monotonic() < deadline:
        # collects STATUSTEXT on the way; stops as soon as the capacity is said
        session.recv(set(), min(deadline, clock.monotonic() + 0.05))
    return value


def _too_large(url: str, count: int, capacity: int | None, session: Session) -> MissionTooLargeError:
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


def _target(session: Session) -> tuple[int, int, int]:
    link = session.link
    return link.target_system, link.target_component, int(session.mission_type)


def request_count(session: Session, what: str) -> int:
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
            if int(message.type) != MissionResult.ACCEPTED:
                last_error = int(message.type)  # wait out the timeout before asking again
    reason = (
        describe_mission_result(last_error)
        if last_error is not None
        else f"no MISSION_COUNT after {session.retries + 1} requests {session.timeout_s:g} s apart"
    )
    raise TransferError(f"{what} from {link.url} failed: {reason}{session.vehicle_said()}")


def receive_items(
    session: Session, *, phase: TransferPhase, progress: ProgressCallback | None
) -> list[MissionItem]:
    """The download half of the protocol: every item of the list, in order."""
    link = session.link
    what = "verification read-back" if phase is TransferPhase.VERIFY else "download"
    count = request_count(session, what)
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
                if int(message.type) != MissionResult.ACCEPTED:
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
    link.send(session.msg("mission_ack", type=MissionResult.ACCEPTED))
    return [items[seq] for seq in range(count)]
