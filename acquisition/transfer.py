"""Mission upload, download and clear by the MAVLink mission protocol, with read-back proof.

The public functions of a transfer: :func:`upload_mission` validates a mission, sends it with
the protocol engine (:mod:`acquisition.mission_protocol`), reads it back and compares it item by
item (:func:`acquisition.readback.verify_readback`); :func:`download_mission` and
:func:`clear_mission` (MISSION_CLEAR_ALL -> MISSION_ACK, then the list is requested to prove it
is empty); the vehicle's home (:func:`request_home_position`) and a downloaded list as a
:class:`Mission` (:func:`downloaded_mission`).

ArduPilot keeps the home position as item 0 of the mission: we send the mission's home there and
skip it when verifying (the vehicle replaces it with its own home, or zeros before a GPS fix).
PX4 has no home item: item 0 is the first mission item.

The result, or the error, states what the vehicle now holds
(:class:`acquisition.transfer_outcome.MissionState`).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

from planner.errors import MissionValidationError
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

from .errors import LinkError, TransferError
from .mavlink_items import (
    MissionResult,
    MissionType,
    ardupilot_nan_allowed,
    has_home_item,
    home_from_message,
    is_global_frame,
)
from .mission_protocol import (
    DEFAULT_RETRIES,
    DEFAULT_TIMEOUT_S,
    LinkLike,
    ProgressCallback,
    Session,
    TransferPhase,
    link_clock,
    receive_items,
    request_count,
    send_items,
)
from .readback import verify_readback
from .transfer_outcome import (
    MissionInputError,
    MissionInterruptedError,
    MissionState,
    MissionTransferError,
    MissionVerificationError,
    UploadResult,
    describe_mission_result,
)

log = logging.getLogger(__name__)


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


def _check_ardupilot_nan(items: Sequence[MissionItem]) -> None:
    problems = []
    for index, item in enumerate(items, start=1):
        allowed = ardupilot_nan_allowed(item.command)
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
    with_home = has_home_item(autopilot, mission_type)
    wire_items = ([home_item(mission.home)] if with_home else []) + list(mission.items)
    if len(wire_items) > 65535:
        raise MissionInputError(
            f"{len(wire_items)} items do not fit the mission protocol (at most 65535); split "
            f"the mission into sorties. Nothing was sent: the vehicle's mission is unchanged."
        )
    session = Session(link=link, mission_type=mission_type, timeout_s=timeout_s, retries=retries)

    def failed_state(any_item_sent: bool) -> MissionState:
        # PX4 writes an upload to a spare buffer and switches only when it completes; ArduPilot
        # replaces its stored items one by one as they arrive.
        if not any_item_sent or autopilot is Autopilot.PX4:
            return MissionState.UNCHANGED
        return MissionState.PARTIAL

    clock = link_clock(link)
    started = clock.monotonic()
    sent_any = False
    sent_count = 0

    def tracking(phase: TransferPhase, done: int, total: int) -> None:
        nonlocal sent_any, sent_count
        sent_any = sent_any or done > 0
        sent_count = max(sent_count, done)
        if progress is not None:
            progress(phase, done, total)

    try:
        outcome = send_items(
            session,
            wire_items,
            progress=tracking,
            no_space_wait_s=no_space_wait_s,
            no_space_retries=no_space_retries,
            failed_state=failed_state,
        )
    except LinkError as error:
        raise MissionTransferError(f"upload failed: {error}", mission_state=failed_state(sent_any)) from error
    except KeyboardInterrupt as stop:
        raise MissionInterruptedError(
            f"upload to {link.url} interrupted (Ctrl-C) after {sent_count} of {len(wire_items)} items "
            f"were sent",
            mission_state=failed_state(sent_any),
        ) from stop
    upload_s = clock.monotonic() - started
    log.info("upload of %d items took %.2f s", len(wire_items), upload_s)

    verify_started = clock.monotonic()
    try:
        received = receive_items(session, phase=TransferPhase.VERIFY, progress=progress)
    except (TransferError, LinkError) as error:
        raise MissionTransferError(
            f"the upload completed but reading it back failed: {error}",
            mission_state=MissionState.REPLACED_UNVERIFIED,
        ) from error
    except KeyboardInterrupt as stop:
        raise MissionInterruptedError(
            f"upload to {link.url} interrupted (Ctrl-C) while reading the mission back to verify it",
            mission_state=MissionState.REPLACED_UNVERIFIED,
        ) from stop
    verify_s = clock.monotonic() - verify_started
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
    session = Session(link=link, mission_type=mission_type, timeout_s=timeout_s, retries=retries)
    return receive_items(session, phase=TransferPhase.DOWNLOAD, progress=progress)


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
    session = Session(link=link, mission_type=mission_type, timeout_s=timeout_s, retries=retries)
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
                if code == MissionResult.ACCEPTED:
                    acknowledged = True
                elif code != MissionResult.INVALID_SEQUENCE:  # that one answers a stale duplicate item
                    refused = code
            if acknowledged or refused is not None:
                break
        if refused is not None:
            raise MissionTransferError(
                f"clear on {link.url} refused: {describe_mission_result(refused)}"
                f"{session.vehicle_said(refused)}",
                mission_state=MissionState.UNCHANGED,
            )
        empty = 1 if has_home_item(link.autopilot, mission_type) else 0
        count = request_count(session, "checking the clear")
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

    clock = link_clock(link)
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
        deadline = clock.monotonic() + timeout_s
        while (remaining := deadline - clock.monotonic()) > 0:
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
