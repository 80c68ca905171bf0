"""``sfap monitor``'s loop: record a flight as it happens, over a link that may drop.

:func:`monitor` runs on an :class:`acquisition.link.Link`, reconnects after a drop and stops on
landing, on a stop event or on Ctrl-C; it writes ``monitor.json`` (the final state) when it
ends. It records through the link's ``on_message`` observer, not what :meth:`Link.recv`
returns, so the tlog holds the whole traffic as a ground station logs it: every system and
component (a second vehicle, a companion computer, another ground station), messages addressed
to another ground station, and those read while the link waits for the vehicle's heartbeat, at
the first connection and at every reconnection. The vehicle the recorder follows is the one the
link identified.

The parts, each a module of its own:

- :mod:`acquisition.flight_recorder`: the tlog, the trigger CSV and the state (no sockets);
- :mod:`acquisition.camera_feed`: which messages make a camera event, and its UTC time;
- :mod:`acquisition.station_tracker`: the plan's stations, taken, passed and missed;
- :mod:`acquisition.link_quality`: messages received and lost, from sequence numbers;
- :mod:`acquisition.monitor_link`: the reader thread, the stream requests, the mission followed;
- :mod:`acquisition.mavlink_messages`: the messages decoded into typed records.

Every wait and timer runs on one clock (``clock``, :mod:`acquisition.clock`): the wall clock
for users; in tests a :class:`~acquisition.clock.VirtualClock`, of which the monitor's thread,
the link's reader and heartbeat threads and the mission reader are parties, so that simulated
time moves only while all of them wait with nothing left to read. The receive times written to
the tlog and the trigger CSV are the link's (:meth:`Link.open`'s ``on_message``): this
computer's UTC on the wall clock, the virtual clock's UTC in tests.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any

from .clock import WALL_CLOCK, Clock, ClockQueue
from .errors import LinkError
from .flight_recorder import FlightRecorder
from .monitor_state import CameraEvent, MonitorState
from .recording_files import CSV_NAME, TLOG_NAME, check_recording_target
from .station_tracker import StationPlan, load_station_plan

log = logging.getLogger(__name__)


class StopReason(StrEnum):
    """Why :func:`monitor` ended (every one leaves the files complete)."""

    LANDED = "landed"  # the vehicle disarmed after the flight
    STOPPED = "stopped"  # the stop event was set
    INTERRUPTED = "interrupted"  # Ctrl-C


@dataclass(frozen=True, kw_only=True)
class MonitorResult:
    """The end of a recording: why, the final state, and where the files are."""

    reason: StopReason
    state: MonitorState
    tlog_path: Path
    csv_path: Path
    summary_path: Path
    events: tuple[CameraEvent, ...] = field(default=())


def monitor(
    url: str,
    plan_dir: str | os.PathLike[str] | None,
    out_dir: str | os.PathLike[str],
    *,
    on_update: Callable[[MonitorState], None] | None = None,
    stop_event: threading.Event | None = None,
    reconnect_timeout_s: float = 60.0,
    heartbeat_timeout_s: float = 10.0,
    overwrite: bool = False,
    update_interval_s: float = 0.5,
    stop_when_landed: bool = True,
    linger_s: float = 1.0,
    signing_key: bytes | None = None,
    require_signing: bool = False,
    clock: Clock = WALL_CLOCK,
) -> MonitorResult:
    """Record the flight on ``url`` into ``out_dir`` until it ends (module docstring).

    ``plan_dir``: the plan folder (stations.geojson, summary.json), None for no plan.
    ``on_update(state)``: called at most every ``update_interval_s`` wall seconds, and at
    every drop and reconnection. ``stop_event``: set it to end the recording.
    ``reconnect_timeout_s``: after a drop, how long (wall s) to keep trying to reopen the
    link before giving up. ``heartbeat_timeout_s``: wait for the vehicle at the first
    connection (s). ``stop_when_landed``: end ``linger_s`` after the vehicle disarms following
    a flight. ``signing_key`` / ``require_signing``: as :meth:`Link.open`. ``clock``: what
    every wait and timer runs on (the seconds above are its seconds; module docstring).

    Ends on landing, the stop event or Ctrl-C with the files complete and returns a
    :class:`MonitorResult`. Raises :class:`LinkError` when the first connection fails (no
    file is written then) or when the link does not come back within ``reconnect_timeout_s``
    (the recording up to the drop is kept, and the message says where).
    """
    plan = load_station_plan(plan_dir) if plan_dir is not None else None
    check_recording_target(out_dir, overwrite=overwrite)
    if plan is not None:
        log.info("plan %s: %d stations", plan.name, len(plan))
    party = clock.join()  # this thread takes part from the first connection to the end
    try:
        return _monitor(
            url, plan, plan_dir, out_dir, on_update, stop_event, reconnect_timeout_s, heartbeat_timeout_s,
            overwrite, update_interval_s, stop_when_landed, linger_s, signing_key, require_signing, clock,
        )  # fmt: skip
    finally:
        clock.leave(party)


def _monitor(
    url: str,
    plan: StationPlan | None,
    plan_dir: str | os.PathLike[str] | None,
    out_dir: str | os.PathLike[str],
    on_update: Callable[[MonitorState], None] | None,
    stop_event: threading.Event | None,
    reconnect_timeout_s: float,
    heartbeat_timeout_s: float,
    overwrite: bool,
    update_interval_s: float,
    stop_when_landed: bool,
    linger_s: float,
    signing_key: bytes | None,
    require_signing: bool,
    clock: Clock,
) -> MonitorResult:
    from .link import Link
    from .mission_stations import mission_station_plan
    from .monitor_link import Dropped, LinkReader, MissionFollower, StreamRequests

    # Every message any read parses goes into this queue (from the reader thread, or from
    # Link.open while it waits for the heartbeat); the main loop records them in order.
    inbox = ClockQueue(clock)

    def observe(msg: Any, rx_time_utc_s: float) -> None:
        inbox.put((msg, rx_time_utc_s))

    def open_link(timeout_s: float) -> Link:
        return Link.open(
            url,
            heartbeat_timeout_s=timeout_s,
            signing_key=signing_key,
            require_signing=require_signing,
            on_message=observe,
            clock=clock,
        )

    try:
        first = open_link(heartbeat_timeout_s)
    except BaseException:
        inbox.close()
        raise
    link: Link | None = first
    stop = stop_event if stop_event is not None else threading.Event()
    try:
        recorder = FlightRecorder(out_dir, plan, overwrite=overwrite, clock=clock)
    except BaseException:
        first.close()
        inbox.close()
        raise
    recorder.set_vehicle(first.target_system, first.target_component)
    requests = StreamRequests(clock)
    follower = MissionFollower(Path(plan_dir) if plan_dir is not None else None, clock)
    reader: LinkReader | None = None
    reason = StopReason.STOPPED
    last_update = 0.0
    landed_at: float | None = None

    def update(force: bool = False) -> None:
        nonlocal last_update
        now = clock.monotonic()
        if on_update is not None and (force or now - last_update >= update_interval_s):
            last_update = now
            on_update(recorder.state())

    def start(active: Link) -> LinkReader:
        try:
            requests.ask(active)
        except LinkError as error:  # the reader will see the drop too
            log.debug("asking for streams failed: %s", error)
        return LinkReader(active, inbox, clock)

    def apply_mission(items: list[Any], same_as_plan: bool) -> None:
        if same_as_plan:
            if recorder.stations_from != "plan" and plan is not None:
                recorder.replace_plan(plan, source="plan")
            log.info("the vehicle holds the plan's mission (%d items)", len(items))
            return
        stations = mission_station_plan(items)
        if plan is not None or recorder.mission_changes:
            log.warning(
                "the vehicle holds %s (%d items, %d photo stations): photos are now counted "
                "against its stations",
                "another mission than the plan's" if plan is not None else "a new mission",
                len(items),
                len(stations) if stations is not None else 0,
            )
        recorder.replace_plan(stations, source="vehicle")

    try:
        try:
            recording = True
            reader = start(first)
            while recording:
                if stop.is_set():
                    reason = StopReason.STOPPED
                    break
                if link is None:
                    link = _reconnect(
                        open_link, recorder, stop, reconnect_timeout_s, heartbeat_timeout_s, update, clock
                    )
                    if link is None:  # stopped while reconnecting
                        reason = StopReason.STOPPED
                        break
                    reader = start(link)
                    continue
                item = inbox.get(0.1)
                handled = 0
                while item is not None:
                    if isinstance(item, Dropped):
                        log.warning("link lost: %s; reconnecting (the recording goes on)", item.detail)
                        recorder.note_drop(item.detail)
                        if reader is not None:
                            reader.stop()
                            reader = None
                        link.close()
                        link = None
                        update(force=True)
                        break
                    msg, rx_time_utc_s = item
                    recorder.record(msg, rx_time_utc_s)
                    kind = msg.get_type()
                    if kind == "COMMAND_ACK" and recorder.vehicle is not None:
                        if msg.get_srcSystem() == recorder.vehicle[0] and getattr(
                            msg, "target_system", 0
                        ) in (0, link.source_system):
                            requests.on_command_ack(msg)
                    else:
                        follower.feed(msg)
                    handled += 1
                    if handled >= 500:  # look at the clock now and then under a flood
                        break
                    item = inbox.get_nowait()
                if link is None:
                    continue
                missing = requests.check(recorder.last_seen_s)
                if missing is not None:
                    recorder.missing_streams = missing
                follower.tick(link, recorder.mission_changed_at_s)
                result = follower.poll()
                if result is not None:
                    apply_mission(*result)
                if stop_when_landed and recorder.flight_over:
                    if landed_at is None:
                        landed_at = clock.monotonic()
                        log.info("the vehicle has landed and disarmed; ending the recording")
                    elif clock.monotonic() - landed_at >= linger_s:
                        reason = StopReason.LANDED
                        break
                else:
                    landed_at = None
                update()
        except KeyboardInterrupt:
            reason = StopReason.INTERRUPTED
            log.warning("interrupted: closing the recording")
    finally:
        if reader is not None:
            reader.stop()
        if link is not None:
            link.close()
        # what was read but not yet recorded still goes into the files
        while (item := inbox.get_nowait()) is not None:
            if not isinstance(item, Dropped) and not recorder.closed:
                recorder.record(*item)
        state = recorder.close()
        inbox.close()
    if on_update is not None:
        on_update(state)
    return MonitorResult(
        reason=reason,
        state=state,
        tlog_path=recorder.tlog_path,
        csv_path=recorder.csv_path,
        summary_path=recorder.summary_path,
        events=tuple(recorder.events),
    )


def _reconnect(
    open_link: Callable[[float], Any],
    recorder: FlightRecorder,
    stop: threading.Event,
    timeout_s: float,
    heartbeat_timeout_s: float,
    update: Callable[[bool], None],
    clock: Clock,
) -> Any | None:
    """Reopen the link until it works, ``stop`` is set (None) or ``timeout_s`` passes
    (:class:`LinkError` that says the recording is kept)."""
    started = clock.monotonic()
    attempts = 0
    while not stop.is_set():
        remaining = timeout_s - (clock.monotonic() - started)
        if remaining <= 0:
            break
        attempts += 1
        recorder.note_connecting()
        try:
            link = open_link(max(min(heartbeat_timeout_s, remaining), 0.5))
        except LinkError as error:
            log.debug("reconnection attempt %d failed: %s", attempts, error)
            update(True)
            clock.wait_event(stop, min(0.5, max(remaining, 0.0)))
            continue
        recorder.set_vehicle(link.target_system, link.target_component)
        recorder.note_reconnect()
        log.warning(
            "reconnected after %.1f s (%d attempts); recording goes on in %s",
            clock.monotonic() - started,
            attempts,
            recorder.out_dir,
        )
        update(True)
        return link
    if stop.is_set():
        return None
    raise LinkError(
        f"the link did not come back within {timeout_s:g} s after it dropped "
        f"({recorder.last_drop}); the recording up to the drop is complete in "
        f"{recorder.out_dir} ({TLOG_NAME}, {CSV_NAME}, {len(recorder.events)} photos)"
    )
