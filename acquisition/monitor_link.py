"""What :func:`acquisition.monitor.monitor` does on the link besides recording.

- :class:`LinkReader`: reads the link in a thread of its own, so that the link is drained while
  the recorder writes files and computes progress (behind a ground station relaying about
  1,100 messages/s, a monitor that read between its own work paused up to 1.5 s and lost
  bursts). Every message parsed goes, with its receive time, into one queue, in arrival order;
  a drop puts a :class:`Dropped` behind the last message.
- :class:`StreamRequests`: asks the vehicle for the telemetry the recording needs
  (:data:`WANTED_STREAMS`). ArduPilot's stream rates (SRn_*) default to 0 on its serial ports,
  so a monitor that does not ask records no position at all. It asks with
  MAV_CMD_SET_MESSAGE_INTERVAL (COMMAND_LONG 511, param1 the message id, param2 the interval in
  microseconds) and, for every message whose request is not ACCEPTED by a COMMAND_ACK within
  :data:`ACK_TIMEOUT_S` (old firmware), with the legacy REQUEST_DATA_STREAM for the message's
  group (ArduPilot's groups: EXTENDED_STATUS 2 MISSION_CURRENT, POSITION 6
  GLOBAL_POSITION_INT, EXTRA1 10 ATTITUDE, EXTRA3 12 SYSTEM_TIME). It then checks that they
  arrive: :data:`STREAM_CHECK_S` after asking, the required ones that have not come are asked
  again the legacy way, and after as long again they are named in a warning and in
  ``MonitorState.missing_streams`` (cleared when they come). CAMERA_FEEDBACK and
  CAMERA_IMAGE_CAPTURED need no request: autopilots send them at every photo.
- :class:`MissionFollower`: reads the mission the vehicle holds (MISSION_REQUEST_LIST, the
  mission protocol) at the start and whenever MISSION_CURRENT says it changed (another total
  or mission_id, :meth:`acquisition.flight_recorder.FlightRecorder._watch_mission`), once it
  has been quiet for :data:`MISSION_QUIET_S`, in a worker thread fed by the main loop. When the
  mission read is the plan folder's own mission, the plan's stations stay; otherwise the
  stations become those of the vehicle's mission (:mod:`acquisition.mission_stations`).

Every timer and wait here runs on one :class:`acquisition.clock.Clock` (the wall clock, or a
:class:`~acquisition.clock.VirtualClock` in tests): the reader and the mission threads are
parties of it, and they hand messages on through :class:`acquisition.clock.ClockQueue`, so that
simulated time never moves while a message waits to be handled.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from planner.mission import Autopilot, MissionItem

from . import mavlink_messages as mm
from .clock import WALL_CLOCK, Clock, ClockQueue
from .errors import AcquisitionError, LinkError

log = logging.getLogger(__name__)

#: What the monitor asks for: message name -> (message id, rate Hz, required).
WANTED_STREAMS: dict[str, tuple[int, float, bool]] = {
    name: (mm.MESSAGE_ID[name], rate_hz, required)
    for name, rate_hz, required in (
        ("GLOBAL_POSITION_INT", 10.0, True),
        ("ATTITUDE", 10.0, True),
        ("SYSTEM_TIME", 1.0, True),
        ("MISSION_CURRENT", 1.0, True),
        ("EXTENDED_SYS_STATE", 1.0, False),
    )
}
#: REQUEST_DATA_STREAM groups (MAV_DATA_STREAM) of the wanted messages, as ArduPilot files them
#: (EXTENDED_SYS_STATE is in none).
LEGACY_GROUP = {
    name: mm.ARDUPILOT_STREAM_GROUP[name] for name in WANTED_STREAMS if name in mm.ARDUPILOT_STREAM_GROUP
}
#: Wall seconds to wait for the COMMAND_ACK of a SET_MESSAGE_INTERVAL.
ACK_TIMEOUT_S = 1.5
#: Wall seconds after asking before the streams are checked (and again before warning).
STREAM_CHECK_S = 4.0
#: Wall seconds the mission must stay unchanged before it is read (an upload in progress).
MISSION_QUIET_S = 2.0
#: Wall seconds between two attempts to read the mission after a failure; attempts at most.
MISSION_RETRY_S = 3.0
MISSION_ATTEMPTS = 5

_MISSION_TYPES = frozenset({"MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK", "STATUSTEXT"})


@dataclass(frozen=True)
class Dropped:
    """The link dropped (put in the queue after the last message read)."""

    detail: str


class LinkReader:
    """Reads ``link`` in a daemon thread until it drops or :meth:`stop` (module docstring).
    The messages reach the queue through the link's ``on_message`` observer. The thread is a
    party of ``clock`` (the link's) from before it starts until it ends."""

    def __init__(self, link: Any, out: ClockQueue, clock: Clock = WALL_CLOCK) -> None:
        self.link = link
        self.out = out
        self.clock = clock
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name="sfap-monitor-reader", daemon=True)
        self._party = clock.join(self.thread)
        self.thread.start()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                try:
                    self.link.recv(None, timeout_s=0.05, all_components=True)
                except LinkError as error:
                    if not self._stop.is_set():
                        self.out.put(Dropped(str(error)))
                    return
                except Exception as error:  # an observer's own failure: report it as a drop
                    self.out.put(Dropped(f"{type(error).__name__}: {error}"))
                    return
        finally:
            self.clock.leave(self._party)

    def stop(self) -> None:
        self._stop.set()
        self.clock.interrupt()
        if self.thread is not threading.current_thread():
            self.thread.join(timeout=2.0)


class StreamRequests:
    """Asks for :data:`WANTED_STREAMS` and checks that they come (module docstring)."""

    def __init__(self, clock: Clock = WALL_CLOCK) -> None:
        self.clock = clock
        self.link: Any = None
        self.asked_at = 0.0
        self._pending: list[tuple[str, float]] = []  # SET_MESSAGE_INTERVAL awaiting an ACK
        self._legacy_sent: set[str] = set()
        self._stage = 0  # 0 asked, 1 re-asked the legacy way, 2 warned
        self.warnings: list[str] = []

    def ask(self, link: Any) -> None:
        """Ask ``link``'s vehicle for every wanted stream (at every (re)connection)."""
        self.link = link
        now = self.clock.monotonic()
        self.asked_at = now
        self._pending = []
        self._legacy_sent = set()
        self._stage = 0
        for name, (message_id, rate_hz, _) in WANTED_STREAMS.items():
            link.send(
                mm.set_message_interval_message(
                    link.target_system, link.target_component, message_id, rate_hz
                )
            )
            self._pending.append((name, now))
        log.info("asked the vehicle for %s (SET_MESSAGE_INTERVAL)", ", ".join(WANTED_STREAMS))

    def _legacy(self, names: list[str]) -> None:
        groups = sorted({LEGACY_GROUP[n] for n in names if n in LEGACY_GROUP})
        for group in groups:
            rate = max(int(WANTED_STREAMS[n][1]) for n, g in LEGACY_GROUP.items() if g == group)
            self.link.send(
                mm.request_data_stream_message(
                    self.link.target_system, self.link.target_component, group, rate
                )
            )
        self._legacy_sent.update(names)
        if groups:
            log.info("asked again with REQUEST_DATA_STREAM (groups %s) for %s", groups, ", ".join(names))

    def on_command_ack(self, msg: Any) -> None:
        """A COMMAND_ACK from the vehicle: the answers come in the order of the requests."""
        if int(msg.command) != mm.MAV_CMD_SET_MESSAGE_INTERVAL or not self._pending:
            return
        name, _ = self._pending.pop(0)
        if int(msg.result) != mm.MAV_RESULT_ACCEPTED:
            log.info("the vehicle refused SET_MESSAGE_INTERVAL for %s (MAV_RESULT %d)", name, int(msg.result))
            if self.link is not None:
                self._legacy([name])

    def check(self, last_seen_s: dict[str, float]) -> tuple[str, ...] | None:
        """Run the timers; returns the required streams still missing once checked (None
        before the first check)."""
        if self.link is None:
            return None
        now = self.clock.monotonic()
        late = [name for name, sent in self._pending if now - sent > ACK_TIMEOUT_S]
        if late:
            self._pending = [(n, t) for n, t in self._pending if n not in late]
            self._legacy([n for n in late if n not in self._legacy_sent])
        if now - self.asked_at < STREAM_CHECK_S:
            return None
        missing = tuple(
            name
            for name, (_, _, required) in WANTED_STREAMS.items()
            if required and last_seen_s.get(name, 0.0) < self.asked_at
        )
        if self._stage == 0 and missing:
            self._stage = 1
            self.asked_at_again = now
            self._legacy([n for n in missing if n not in self._legacy_sent] or list(missing))
            return None
        if self._stage == 1:
            if now - getattr(self, "asked_at_again", now) < STREAM_CHECK_S:
                return None
            self._stage = 2
            if missing:
                text = (
                    f"the vehicle does not send {', '.join(missing)} although the monitor asked for "
                    f"{'it' if len(missing) == 1 else 'them'} twice (SET_MESSAGE_INTERVAL, then "
                    f"REQUEST_DATA_STREAM): without them the recording has "
                    + _consequences(missing)
                    + "; set the stream rates on the vehicle (ArduPilot: SRn_POSITION, SRn_EXTRA1, "
                    "SRn_EXTRA3, SRn_EXT_STAT of this port) or check that the link carries them"
                )
                log.warning(text)
                self.warnings.append(text)
        return missing


def _consequences(missing: tuple[str, ...]) -> str:
    what = []
    if "GLOBAL_POSITION_INT" in missing:
        what.append("no track (no progress, no landing seen by altitude)")
    if "ATTITUDE" in missing:
        what.append("no attitude for geotagging")
    if "SYSTEM_TIME" in missing:
        what.append("no vehicle clock (events from boot time cannot be placed in UTC)")
    if "MISSION_CURRENT" in missing:
        what.append("no mission progress (item -) and no mission change seen")
    return ", ".join(what)


class MissionChannel:
    """A link for :func:`acquisition.transfer.download_mission` inside the monitor: it sends
    on the real link and receives what the main loop hands it (:meth:`feed`); the transfer
    measures its timeouts on ``clock``."""

    def __init__(self, link: Any, clock: Clock = WALL_CLOCK) -> None:
        self.link = link
        self.clock = clock
        self.url = link.url
        self.autopilot: Autopilot = link.autopilot
        self.vehicle_type = link.vehicle_type
        self.target_system = link.target_system
        self.target_component = link.target_component
        self.source_system = getattr(link, "source_system", 255)
        self._inbox = ClockQueue(clock)

    def wants(self, msg: Any) -> bool:
        if msg.get_type() not in _MISSION_TYPES or msg.get_srcSystem() != self.target_system:
            return False
        return getattr(msg, "target_system", 0) in (0, self.source_system)

    def feed(self, msg: Any) -> None:
        self._inbox.put(msg)

    def close(self) -> None:
        self._inbox.close()

    def send(self, message: Any) -> None:
        self.link.send(message)

    def recv(self, types: Any = None, timeout_s: float = 0.0) -> Any | None:
        deadline = self.clock.monotonic() + timeout_s
        while True:
            msg = self._inbox.get(deadline - self.clock.monotonic())
            if msg is None:
                return None
            if types is None or msg.get_type() in types:
                return msg


class MissionFollower:
    """Reads the vehicle's mission at the start and after each change (module docstring).

    ``plan_mission``: the plan folder's own mission (its ``mission.plan``), None when there is
    none. :meth:`poll` returns, once per read, ``(items, same_as_plan)``. ``clock``: what its
    timers run on; its reading thread is a party of it.
    """

    def __init__(self, plan_dir: Path | None, clock: Clock = WALL_CLOCK) -> None:
        self.clock = clock
        self._parties: dict[threading.Thread, object] = {}  # reading thread -> its clock party
        self.plan_items: list[MissionItem] | None = None
        if plan_dir is not None and (Path(plan_dir) / "mission.plan").is_file():
            try:
                from planner.formats import read_mission

                self.plan_items = list(read_mission(Path(plan_dir) / "mission.plan").items)
            except Exception as error:  # the stations still come from stations.geojson
                log.warning(
                    "cannot read %s/mission.plan (%s): the vehicle's mission is not compared", plan_dir, error
                )
        self.channel: MissionChannel | None = None
        self._thread: threading.Thread | None = None
        self._result: tuple[list[MissionItem], bool] | None = None
        self._wanted_since: float | None = self.clock.monotonic()  # read once at the start
        self._attempts = 0
        self._next_try_s = 0.0
        self.handled_change_at: float | None = None
        self.reads = 0

    def feed(self, msg: Any) -> None:
        channel = self.channel
        if channel is not None and channel.wants(msg):
            channel.feed(msg)

    def mission_changed(self, at_s: float | None) -> None:
        if at_s is not None and at_s != self.handled_change_at:
            self.handled_change_at = at_s
            self._wanted_since = at_s
            self._attempts = 0

    def tick(self, link: Any, changed_at_s: float | None) -> None:
        """Start a read when one is due and none runs (``link`` None: not connected)."""
        self.mission_changed(changed_at_s)
        if link is None or self._wanted_since is None or self._thread is not None:
            return
        now = self.clock.monotonic()
        if now - self._wanted_since < (MISSION_QUIET_S if self.reads or self._attempts else 0.0):
            return
        if now < self._next_try_s:
            return
        if self._attempts >= MISSION_ATTEMPTS:
            self._wanted_since = None
            log.warning(
                "could not read the vehicle's mission after %d attempts: counting against the stations "
                "known so far",
                self._attempts,
            )
            return
        self._attempts += 1
        self.channel = MissionChannel(link, self.clock)
        self._thread = threading.Thread(
            target=self._read, args=(self.channel,), daemon=True, name="sfap-monitor-mission"
        )
        self._parties[self._thread] = self.clock.join(self._thread)  # a party from before it starts
        self._thread.start()

    def _read(self, channel: MissionChannel) -> None:
        from .readback import verify_readback
        from .transfer import download_mission

        wanted_since = self._wanted_since
        try:
            items = download_mission(channel, timeout_s=1.5, retries=2)
            body = items[1:] if channel.autopilot is Autopilot.ARDUPILOT else items
            same = self.plan_items is not None and not verify_readback(
                self.plan_items, items, channel.autopilot, channel.vehicle_type
            )
            if self._wanted_since == wanted_since:  # else it changed again meanwhile: read again
                self._wanted_since = None
            self.reads += 1
            self._result = (list(body), same)
        except (AcquisitionError, LinkError) as error:
            log.info("reading the vehicle's mission failed (%s); trying again", error)
            self._next_try_s = self.clock.monotonic() + MISSION_RETRY_S
        finally:
            self.channel = None
            channel.close()
            self._thread = None
            self.clock.leave(self._parties.pop(threading.current_thread()))

    def poll(self) -> tuple[list[MissionItem], bool] | None:
        result, self._result = self._result, None
        return result
