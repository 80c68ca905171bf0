"""The flight recorder: the tlog, the trigger CSV and the :class:`MonitorState`, from received messages.

:class:`FlightRecorder` (no sockets) consumes pymavlink messages with their receive time and
keeps the recording up to date:

* ``flight.tlog`` (every message) and ``triggers.csv`` (one row per camera event), written
  as :mod:`acquisition.recording_files` says; which messages make an event, and their
  times: :mod:`acquisition.camera_feed`.
* :class:`~acquisition.monitor_state.MonitorState`: mission progress, photos taken against
  planned stations (:mod:`acquisition.station_tracker`), the stations missed so far, link
  quality (:mod:`acquisition.link_quality`).

It follows one vehicle (the autopilot the link identified, :meth:`FlightRecorder.set_vehicle`,
else the first autopilot heartbeat); every other system's messages are logged only. The flight
is over when the vehicle disarms after having flown: armed and more than
:data:`FLYING_ALT_REL_HOME_M` above home, or EXTENDED_SYS_STATE in the air.
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import replace
from typing import Any

from planner.outputs import atomic_write_text

from . import mavlink_messages as mm
from .camera_feed import CameraFeed
from .clock import WALL_CLOCK, Clock
from .errors import AcquisitionError
from .link_quality import LinkCounts
from .monitor_state import CameraEvent, MonitorState
from .recording_files import RecordingFiles, recording_paths
from .station_tracker import StationPlan, StationTracker

log = logging.getLogger(__name__)

#: Armed and this high above home (m): the vehicle has flown; its next disarming ends the flight.
FLYING_ALT_REL_HOME_M = 2.0
#: A mission that changes again within this many wall seconds is the same change (an upload).
MISSION_SETTLE_S = 5.0


#: What :class:`MonitorState` takes from the recorder's attributes of the same names.
_STATE_ATTRIBUTES = (
    "joined_late",
    "messages",
    "connected",
    "drops",
    "reconnects",
    "last_drop",
    "missing_streams",
    "mission_changes",
    "stations_from",
)


class FlightRecorder:
    """Writes the tlog and the trigger CSV and keeps the :class:`MonitorState`.

    ``out_dir``: the recording folder (created); ``plan``: the planned stations (None: no
    progress against a plan); ``overwrite``: replace an existing recording (else
    :class:`OutputExistsError`); ``clock``: what its timers (stream freshness, heartbeat age,
    fsync) run on. Use it as a context manager, or call :meth:`close`.
    Not thread-safe: one thread records.
    """

    def __init__(
        self,
        out_dir: str | os.PathLike[str],
        plan: StationPlan | None = None,
        *,
        overwrite: bool = False,
        clock: Clock = WALL_CLOCK,
    ) -> None:
        self.clock = clock
        self.files = RecordingFiles(out_dir, overwrite=overwrite, clock=clock)
        self.out_dir = self.files.folder
        self.tlog_path, self.csv_path, self.summary_path = recording_paths(self.out_dir)
        self.plan = plan
        self.tracker = StationTracker(plan) if plan is not None else None
        self.events: list[CameraEvent] = []
        self.camera = CameraFeed(on_late_join=self._set_late_join, clock=clock)
        self._link = LinkCounts()
        self.vehicle: tuple[int, int] | None = None
        self._last_heartbeat_wall_s: float | None = None
        self._armed = False
        self._flew = False  # armed and above FLYING_ALT_REL_HOME_M since the last arming
        self._flight_over = False
        self._mission: tuple[int | None, int | None, int | None] = (None, None, None)
        self._mission_key: tuple[int, int] | None = None  # (total, mission_id) last seen
        self.mission_changes = 0
        self.mission_changed_at_s: float | None = None  # monotonic s of the last change seen
        self._events_at_change = 0
        self.stations_from: str | None = "plan" if plan is not None else None
        self.last_seen_s: dict[str, float] = {}  # vehicle message type -> monotonic s
        self.missing_streams: tuple[str, ...] = ()
        self._landed_state: int | None = None
        self.joined_late = False
        self.messages = 0
        self.connected = True
        self.drops = 0
        self.reconnects = 0
        self.last_drop: str | None = None
        self.closed = False

    # --- lifecycle ---------------------------------------------------------------------------

    def __enter__(self) -> FlightRecorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> MonitorState:
        """Write held triggers, close both files (fsync'ed) and write ``monitor.json``."""
        if self.closed:
            return self.state()
        for photo in self.camera.release(force=True):
            self._add_event(photo)
        self.files.close()
        self.closed = True
        state = self.state()
        summary = {
            "tlog": str(self.tlog_path),
            "trigger_csv": str(self.csv_path),
            "plan": self.plan.name if self.plan is not None else None,
            **state.as_dict(),
        }
        atomic_write_text(self.summary_path, json.dumps(summary, indent=2, allow_nan=False) + "\n")
        return state

    # --- recording ---------------------------------------------------------------------------

    def record(self, msg: Any, rx_time_utc_s: float | None = None) -> CameraEvent | None:
        """Record one pymavlink message received at ``rx_time_utc_s`` (POSIX s, UTC, the
        ground station's clock; default ``msg._timestamp`` or now). Returns the camera event
        it completed, if any. BAD_DATA is skipped."""
        if self.closed:
            raise AcquisitionError(f"the recording in {self.out_dir} is closed")
        kind = msg.get_type()
        if kind == "BAD_DATA":
            return None
        if rx_time_utc_s is None:
            rx_time_utc_s = float(getattr(msg, "_timestamp", 0.0) or self.clock.time())
        self.files.write_message(msg, rx_time_utc_s)
        self.messages += 1
        src = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
        self._link.add(src, int(msg.get_seq()))
        m = mm.decode(msg)
        if isinstance(m, mm.Heartbeat):
            self._on_heartbeat(m, src)
        if self.vehicle is not None and src[0] != self.vehicle[0]:
            return None  # another system (a second vehicle, another GCS): logged only
        from_autopilot = self.vehicle is None or src == self.vehicle
        if from_autopilot:
            self.last_seen_s[kind] = self.clock.monotonic()
        photo: CameraEvent | None = None
        if isinstance(m, mm.CameraImageCaptured):
            on_autopilot_clock = self.vehicle is None or src[1] == self.vehicle[1]
            photo = self.camera.on_image_captured(m, component=src[1], on_autopilot_clock=on_autopilot_clock)
        elif from_autopilot:
            photo = self._from_autopilot(m)
        event = self._add_event(photo) if photo is not None else None
        for held in self.camera.release(force=False):
            self._add_event(held)
        return event

    def _from_autopilot(self, m: mm.Record | None) -> CameraEvent | None:
        if isinstance(m, mm.SystemTime):
            self.camera.on_system_time(m)
        elif isinstance(m, mm.GlobalPosition):
            self.camera.on_position(m)
            if self._armed and m.alt_rel_home_m > FLYING_ALT_REL_HOME_M:
                self._flew = True
            if m.has_position and self.tracker is not None:
                self.tracker.add_position(m.lat_deg, m.lon_deg, m.north_m_s, m.east_m_s)
        elif isinstance(m, mm.MissionCurrent):
            self._mission = (m.seq, m.items_total, m.mission_state or None)
            self._watch_mission(m)
        elif isinstance(m, mm.ExtendedSysState):
            self._landed_state = m.landed_state
            if self._armed and self._landed_state in mm.LANDED_STATES_AIRBORNE:
                self._flew = True
        elif isinstance(m, mm.CameraFeedback):
            return self.camera.on_feedback(m)
        elif isinstance(m, mm.CameraTrigger):
            self.camera.on_trigger(m)
        return None

    def _on_heartbeat(self, m: mm.Heartbeat, src: tuple[int, int]) -> None:
        if self.vehicle is None and m.is_autopilot and not m.is_ground_station:
            self.vehicle = src
            log.info("recording vehicle system %d component %d", *src)
        if src != self.vehicle:
            return
        self._last_heartbeat_wall_s = self.clock.monotonic()
        armed = m.armed
        if not armed:
            self.camera.seen_disarmed = True
        if armed and not self._armed and self._flight_over:
            log.info("the vehicle armed again: a new flight in the same recording")
            self._flight_over = False
            self._flew = False
            if self.tracker is not None:
                self.tracker.flight_over = False
        elif (
            not armed
            and self._flew
            and not self._flight_over
            and self._landed_state not in mm.LANDED_STATES_NOT_DOWN
        ):
            # an arming and disarming on the ground (checks before take-off) is not a flight
            self._flight_over = True
            log.info("the vehicle landed and disarmed: the flight is over")
            if self.tracker is not None:
                self.tracker.end_flight()
        self._armed = armed

    def _set_late_join(self, why: str) -> None:
        if self.joined_late:
            return
        self.joined_late = True
        if self.tracker is not None and self.tracker.taken_count == 0:
            self.tracker.late_join = True
        log.warning(
            "joined late: %s; photos taken before now have no camera event in this recording "
            "(they are counted from the vehicle's image index, not as missed)",
            why,
        )

    def _watch_mission(self, m: mm.MissionCurrent) -> None:
        """MISSION_CURRENT's total and mission_id (opaque id, 0 when not sent) name the
        mission the vehicle holds; a change is a new mission (a re-fly uploaded)."""
        if m.total is None:
            return
        key = (m.total, m.mission_id or 0)
        if self._mission_key is not None and key != self._mission_key:
            now = self.clock.monotonic()
            # an upload changes the total more than once (truncated, then complete): one change
            settled = self.mission_changed_at_s is None or now - self.mission_changed_at_s > MISSION_SETTLE_S
            self.mission_changes += 1 if settled else 0
            self.mission_changed_at_s = now
            if settled:
                self._events_at_change = len(self.events)
            log.warning(
                "the vehicle's mission changed (%d items%s, was %d): it will be read to follow it",
                key[0],
                f", id {key[1]}" if key[1] else "",
                self._mission_key[0],
            )
        self._mission_key = key

    def replace_plan(self, plan: StationPlan | None, *, source: str) -> None:
        """Count from now on against ``plan`` (the stations of the mission the vehicle holds);
        the camera events recorded since the mission changed are matched to it again."""
        self.plan = plan
        self.stations_from = source if plan is not None else None
        self.tracker = StationTracker(plan) if plan is not None else None
        if self.tracker is None:
            return
        self.tracker.late_join = self.joined_late and self._events_at_change == 0
        for number, event in enumerate(self.events[self._events_at_change :], start=self._events_at_change):
            if event.lat_deg is not None and event.lon_deg is not None:
                self.tracker.add_event(number, event.lat_deg, event.lon_deg)
            else:
                self.tracker.extra_photos += 1
        if self._flight_over:
            self.tracker.end_flight()

    def _add_event(self, photo: CameraEvent) -> CameraEvent:
        station = None
        if self.tracker is not None and photo.lat_deg is not None and photo.lon_deg is not None:
            station = self.tracker.add_event(len(self.events), photo.lat_deg, photo.lon_deg)
        elif self.tracker is not None:
            self.tracker.extra_photos += 1
        event = replace(photo, station=station)
        self.events.append(event)
        self.files.write_event(event)
        return event

    # --- link events -------------------------------------------------------------------------

    def set_vehicle(self, system_id: int, component_id: int) -> None:
        """Follow this autopilot (the one the link identified) rather than the first autopilot
        heartbeat recorded; messages of other systems are then logged only."""
        vehicle = (int(system_id), int(component_id))
        if self.vehicle is not None and self.vehicle != vehicle:
            log.warning(
                "now recording vehicle system %d component %d (was system %d component %d)",
                *vehicle,
                *self.vehicle,
            )
        self.vehicle = vehicle

    def note_drop(self, detail: str) -> None:
        """The link was lost (files stay open; the recording goes on after a reconnect).
        Sequence counts restart with the next message recorded."""
        if self.connected:
            self.drops += 1
        self.connected = False
        self.last_drop = detail
        self._link.restart()
        self.files.sync_tlog()

    def note_connecting(self) -> None:
        """A new attempt to open the link starts: sequence counts restart with its first
        message, so that a gap between two attempts is not counted as losses."""
        self._link.restart()

    def note_reconnect(self) -> None:
        """The link is back. Its sequence counts started with its first message (recorded
        while the link waited for the heartbeat), see :mod:`acquisition.link_quality`."""
        self.connected = True
        self.reconnects += 1

    # --- state -------------------------------------------------------------------------------

    @property
    def flight_over(self) -> bool:
        return self._flight_over

    def state(self) -> MonitorState:
        """The current :class:`MonitorState`."""
        link = self._link.per_system()
        received = sum(q.received for q in link)
        expected = sum(q.expected for q in link)
        tracker = self.tracker
        last = self._last_heartbeat_wall_s
        age = None if last is None else self.clock.monotonic() - last
        events = len(self.events)
        photos, unseen, before = self.camera.photo_counts(events, self.joined_late)
        own = {name: getattr(self, name) for name in _STATE_ATTRIBUTES}
        return MonitorState(
            **own,
            mission_seq=self._mission[0],
            mission_total=self._mission[1],
            mission_state=self._mission[2],
            photos_taken=photos,
            events_received=events,
            photos_unseen=unseen,
            photos_before_join=before,
            photos_planned=len(tracker) if tracker is not None else 0,
            stations_taken=tracker.taken_count if tracker is not None else 0,
            stations_passed=tracker.passed_count if tracker is not None else 0,
            missed_stations=tuple(tracker.missed()) if tracker is not None else (),
            extra_photos=tracker.extra_photos if tracker is not None else 0,
            duplicate_events=self.camera.duplicate_events,
            failed_captures=self.camera.failed_captures,
            link=link,
            link_quality_pct=100.0 * received / expected if expected > 1 else None,
            heartbeat_age_s=age,
            armed=self._armed,
            flight_over=self._flight_over,
            landed_state=self._landed_state,
        )
