"""Recording a flight as it happens: camera events and telemetry, progress against the plan.

Two layers:

- :class:`FlightRecorder` (no sockets) consumes pymavlink messages with their receive time
  and keeps three things up to date:

  * ``flight.tlog``: every message, as MAVProxy and QGroundControl write a telemetry log: an
    8-byte big-endian receive time (microseconds since the Unix epoch, UTC, the ground
    station's clock) then the packet's raw bytes (``msg.get_msgbuf()``, signature included).
    The file is flushed after every message, so a crash of this process loses nothing that
    was received; it is also fsync'ed after every camera event and at least once a second,
    so a power cut loses at most the last second.
  * ``triggers.csv``: one row per camera event (header :data:`CSV_COLUMNS`, units in the
    names), appended and flushed and fsync'ed row by row, never rewritten.
  * :class:`MonitorState`: mission progress, photos taken against planned stations, the
    stations missed so far, link quality.

- :func:`monitor` runs the loop on an :class:`acquisition.link.Link`, reconnects after a
  drop and stops on landing, on a stop event or on Ctrl-C; it writes ``monitor.json`` (the
  final state) when it ends. It records through the link's ``on_message`` observer, not
  what :meth:`Link.recv` returns, so the tlog holds the whole traffic as a ground station
  logs it: every system and component (a second vehicle, a companion computer, another
  ground station), messages addressed to another ground station, and those read while the
  link waits for the vehicle's heartbeat, at the first connection and at every reconnection.
  The vehicle the recorder follows is the one the link identified.

Camera events
    CAMERA_FEEDBACK (ArduPilot; ``img_idx`` is the sequence number since
    ``completed_captures`` stays 0 without a feedback pin, REFERENCES.md section 3) and
    CAMERA_IMAGE_CAPTURED (PX4, MAVLink cameras; failed captures, ``capture_result`` 0, are
    counted and left out). A message received again (same message type, camera and image
    index, same event time: a duplicate on the link, or the same event through two paths) is
    written once. The same index with another time is a new event (the counter restarted:
    a reboot) and is logged as such. CAMERA_TRIGGER (only a time and a sequence number) is
    used only when a vehicle sends no CAMERA_FEEDBACK or CAMERA_IMAGE_CAPTURED: it is held
    for :data:`TRIGGER_HOLD_S` waiting for its CAMERA_IMAGE_CAPTURED (PX4 sends both), then
    written with the last GLOBAL_POSITION_INT as its position (source
    ``CAMERA_TRIGGER+GLOBAL_POSITION_INT``).

Event times (``time_utc_s``, POSIX seconds, UTC) come from the vehicle: CAMERA_FEEDBACK and
CAMERA_TRIGGER ``time_usec`` is Unix-epoch microseconds when large (the MAVLink definition;
read as GPS-epoch microseconds instead when that lands nearer the vehicle's current UTC, as
some firmwares send) or microseconds since boot (feedback pin), mapped to UTC through the
last SYSTEM_TIME; CAMERA_IMAGE_CAPTURED ``time_utc``, else ``time_boot_ms`` the same way. An
event with no usable time has an empty ``time_utc_s``.

Missed stations (the definition :class:`StationTracker` implements)
    Stations are the plan's ``stations.geojson`` in flight order; consecutive stations of the
    same pass and line form a *leg*. A station's match radius is ``r = max(d / 2, 5 m)``
    with ``d`` the trigger distance of its pass (``summary.json``; 5 m when unknown): half
    the spacing, so that a photo can match only one station of a regularly spaced line.

    * A station is *taken* when a camera event lies within ``r`` of it (horizontal distance).
      Each event takes at most one station: of the untaken stations within ``r``, the first
      in flight order after the last station taken, else the nearest; an event that takes
      none is an *extra* photo.
    * The vehicle's *progress* ``P`` is the index of the furthest station it has reached:
      the station an event took, or a station whose ``r`` the vehicle's reported position
      (GLOBAL_POSITION_INT) entered while flying along the station's heading (course within
      :data:`COURSE_TOLERANCE_DEG`, ground speed at least :data:`MIN_ALONG_SPEED_M_S`).
      Progress moves only within the current leg or into the next one, so that a transit
      over later lines, or a crossing of another pass, cannot make it jump; an event taking a
      station in a leg further ahead moves it only when the next event confirms that leg.
    * A station is *passed* when its index is below ``P`` (the vehicle reached a later
      station: on a line, within ``r`` of the next station is at least ``d - r >= r`` past
      this one), or when the flight is over (the vehicle disarmed after having flown: armed
      and more than :data:`FLYING_ALT_REL_HOME_M` above home).
    * A station is *missed* when it is passed and not taken. A late event can still take a
      passed station; the missed list is recomputed, never latched.

Link quality
    Per sender (system, component), from MAVLink sequence numbers (8 bits, modular). With
    ``last`` the sequence number of the sender's newest message and ``k = (seq - last) mod
    256``: ``k == 0`` is a duplicate (not counted as received); a message whose number was
    counted lost within the last :data:`LATE_WINDOW` numbers arrives *late* (reordered): it
    is received and no longer lost; any other ``k`` (1-255) is a forward jump, ``k - 1``
    messages lost. So a burst of 200 lost messages counts 200, never "a late arrival" (an older
    rule read every jump of 128 or more as reordering, which hid long bursts). A duplicate of
    a message older than the newest is indistinguishable from a burst of ``k - 1`` losses and
    counts as one (relays deliver in order; duplicates come back to back). Quality is received
    / (received + lost), in percent. Every message received counts, from every system, whoever it is addressed
    to (a message left out would show as a gap: a false loss). The count restarts with
    the first message of each connection attempt after a drop (what was sent while the link
    was down cannot be told from sequence numbers modulo 256); drops are counted separately.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import math
import os
import queue
import struct
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import IO, Any

import numpy as np
from numpy.typing import NDArray

from planner.errors import InputError, OutputExistsError
from planner.geo import LocalFrame
from planner.outputs import atomic_write_text

from .errors import AcquisitionError, LinkError
from .telemetry.gpstime import gps_usec_to_utc_s
from .telemetry.tlog import BOOT_US_LIMIT, euler_deg_from_quaternion

log = logging.getLogger(__name__)

TLOG_NAME = "flight.tlog"
CSV_NAME = "triggers.csv"
SUMMARY_NAME = "monitor.json"
#: The trigger CSV's header, in order.
CSV_COLUMNS = (
    "time_utc_s",
    "seq",
    "lat_deg",
    "lon_deg",
    "alt_amsl_m",
    "alt_rel_home_m",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "source",
)
#: Smallest match radius of a station, metres (GNSS noise of a plain receiver).
MIN_MATCH_RADIUS_M = 5.0
#: How far the course may differ from a station's heading for the vehicle to "fly along" it.
COURSE_TOLERANCE_DEG = 45.0
#: Below this ground speed (m/s) the course is not trusted.
MIN_ALONG_SPEED_M_S = 1.0
#: How long (wall seconds) a CAMERA_TRIGGER waits for its CAMERA_IMAGE_CAPTURED.
TRIGGER_HOLD_S = 2.0
#: Armed and this high above home (m): the vehicle has flown; its next disarming ends the flight.
FLYING_ALT_REL_HOME_M = 2.0
#: fsync the tlog at least this often (wall seconds).
FSYNC_INTERVAL_S = 1.0

_MAV_TYPE_GCS = 6
_MAV_AUTOPILOT_INVALID = 8
_MAV_MODE_FLAG_SAFETY_ARMED = 128
_MISSION_STATE_COMPLETE = 5
_CAMERA_TYPES = frozenset({"CAMERA_FEEDBACK", "CAMERA_IMAGE_CAPTURED"})


# --- the plan's stations ------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class StationPlan:
    """The planned exposure stations, in flight order (columns are numpy arrays).

    ``lat_deg``/``lon_deg`` WGS84; ``pass_index``/``line_index`` the pass and line;
    ``heading_deg`` the true bearing of flight at the station; ``match_radius_m`` the radius
    within which a photo counts for the station; ``trigger_distance_m`` the plan's trigger
    distance (None when the plan does not say).
    """

    name: str
    lat_deg: NDArray[np.float64]
    lon_deg: NDArray[np.float64]
    pass_index: NDArray[np.int64]
    line_index: NDArray[np.int64]
    heading_deg: NDArray[np.float64]
    match_radius_m: NDArray[np.float64]
    trigger_distance_m: float | None = None

    def __post_init__(self) -> None:
        n = self.lat_deg.shape[0]
        for name in ("lon_deg", "pass_index", "line_index", "heading_deg", "match_radius_m"):
            if getattr(self, name).shape != (n,):
                raise InputError(
                    f"StationPlan.{name} has shape {getattr(self, name).shape}; every column "
                    f"needs one value per station ({n})"
                )
        if n and not np.all(self.match_radius_m > 0):
            raise InputError("StationPlan.match_radius_m must be > 0 for every station")

    def __len__(self) -> int:
        return int(self.lat_deg.shape[0])


def load_station_plan(plan_dir: str | os.PathLike[str]) -> StationPlan:
    """Read ``stations.geojson`` and ``summary.json`` of a plan folder (``sfap plan -o DIR``).

    Raises :class:`InputError` naming the file when either is missing or malformed.
    """
    folder = Path(plan_dir)
    stations_path = folder / "stations.geojson"
    summary_path = folder / "summary.json"
    if not folder.is_dir():
        raise InputError(f"plan folder {folder} does not exist; give the folder `sfap plan -o` wrote")
    summary: dict[str, Any] = {}
    if summary_path.exists():
        try:
            summary = json.loads(summary_path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as error:
            raise InputError(f"cannot read {summary_path}: {error}") from error
    try:
        data = json.loads(stations_path.read_text(encoding="utf-8"))
        features = data["features"]
    except FileNotFoundError as error:
        raise InputError(
            f"{stations_path} is missing; --plan must be a folder written by `sfap plan -o`"
        ) from error
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise InputError(f"cannot read {stations_path}: {error}") from error
    default_d = summary.get("trigger_distance_m")
    per_pass = {
        int(p["index"]): p.get("trigger_distance_m")
        for p in summary.get("passes", [])
        if isinstance(p, dict) and "index" in p
    }
    rows: list[tuple[float, float, int, int, float, float]] = []
    for k, feature in enumerate(features):
        try:
            props = feature["properties"]
            lat, lon = float(props["lat_deg"]), float(props["lon_deg"])
            pass_index = int(props.get("pass", 0))
            line_index = int(props.get("line", 0))
            heading = props.get("heading_deg")
        except (KeyError, TypeError, ValueError) as error:
            raise InputError(
                f"{stations_path}: feature {k} lacks lat_deg/lon_deg properties ({error}); "
                f"re-plan with `sfap plan`"
            ) from error
        d = per_pass.get(pass_index, default_d)
        radius = max(float(d) / 2.0, MIN_MATCH_RADIUS_M) if d else MIN_MATCH_RADIUS_M
        rows.append(
            (
                lat,
                lon,
                pass_index,
                line_index,
                math.nan if heading is None else float(heading),
                radius,
            )
        )
    a = np.array(rows, dtype=np.float64).reshape(-1, 6)
    return StationPlan(
        name=str(summary.get("name", folder.name)),
        lat_deg=a[:, 0].copy(),
        lon_deg=a[:, 1].copy(),
        pass_index=a[:, 2].astype(np.int64),
        line_index=a[:, 3].astype(np.int64),
        heading_deg=a[:, 4].copy(),
        match_radius_m=a[:, 5].copy(),
        trigger_distance_m=float(default_d) if default_d else None,
    )


def _angle_diff_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


class StationTracker:
    """Which planned stations were taken, passed and missed (definition: module docstring)."""

    def __init__(self, plan: StationPlan) -> None:
        self.plan = plan
        n = len(plan)
        self.taken_by = np.full(n, -1, dtype=np.int64)  # station -> event that took it, -1 none
        self.progress = -1  # P: index of the furthest station reached
        self.extra_photos = 0
        self.flight_over = False
        self._last_taken = -1
        self._pending_jump_leg: int | None = None
        #: With a late join (the monitor started after the first photos), the first station
        #: observed; the stations before it are neither taken nor missed: not seen.
        self.late_join = False
        self.first_observed = 0
        if n:
            self.frame: LocalFrame | None = LocalFrame.utm_for(
                float(np.mean(plan.lon_deg)), float(np.mean(plan.lat_deg))
            )
            self.x, self.y = self.frame.to_xy(plan.lon_deg, plan.lat_deg)
        else:
            self.frame = None
            self.x = self.y = np.zeros(0)
        change = np.ones(n, dtype=bool)
        if n > 1:
            change[1:] = (np.diff(plan.pass_index) != 0) | (np.diff(plan.line_index) != 0)
        self.leg = np.cumsum(change) - 1  # leg number of every station
        starts = np.flatnonzero(change)
        self._leg_start = np.append(starts, n)  # stations of leg k: [start[k], start[k+1])

    def __len__(self) -> int:
        return len(self.plan)

    def _xy(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        assert self.frame is not None
        x, y = self.frame.to_xy(lon_deg, lat_deg)
        return float(x), float(y)

    def _leg_of(self, index: int) -> int:
        return int(self.leg[index]) if index >= 0 else -1

    def _near_legs(self) -> tuple[int, int]:
        """Stations progress may move to: the current leg and the next (index range)."""
        leg = self._leg_of(self.progress)
        first = max(leg, 0)
        last = min(leg + 1, len(self._leg_start) - 2)
        return int(self._leg_start[first]), int(self._leg_start[last + 1])

    def add_event(self, event_number: int, lat_deg: float, lon_deg: float) -> int | None:
        """Match one camera event; returns the station it took (None: an extra photo)."""
        n = len(self)
        if n == 0 or not (math.isfinite(lat_deg) and math.isfinite(lon_deg)):
            self.extra_photos += 1
            return None
        x, y = self._xy(lat_deg, lon_deg)
        dist = np.hypot(self.x - x, self.y - y)
        free = self.taken_by < 0
        candidates = np.flatnonzero((dist <= self.plan.match_radius_m) & free)
        if candidates.size == 0:
            self.extra_photos += 1
            return None
        ahead = candidates[candidates > self._last_taken]
        if self.late_join and self._last_taken < 0:
            # joined late: the first photo seen says where the vehicle is in the plan (the
            # positions seen before it may have moved progress already: keep the furthest)
            station = int(candidates[np.argmin(dist[candidates])])
            self.first_observed = station
            self.taken_by[station] = event_number
            self._last_taken = station
            self.progress = max(self.progress, station)
            return station
        if ahead.size:
            lo, hi = self._near_legs()
            near = ahead[(ahead >= lo) & (ahead < hi)]
            station = int(near[0]) if near.size else int(ahead[0])
        else:
            station = int(candidates[np.argmin(dist[candidates])])
        self.taken_by[station] = event_number
        self._advance_by_event(station)
        return station

    def _advance_by_event(self, station: int) -> None:
        lo, hi = self._near_legs()
        if lo <= station < hi or station <= self.progress:
            self._pending_jump_leg = None
            if station > self.progress:
                self.progress = station
            self._last_taken = max(self._last_taken, station)
            return
        leg = self._leg_of(station)
        if self._pending_jump_leg == leg:  # a second event in the same leg ahead: believe it
            self._pending_jump_leg = None
            self.progress = station
            self._last_taken = station
        else:
            self._pending_jump_leg = leg

    def add_position(self, lat_deg: float, lon_deg: float, north_m_s: float, east_m_s: float) -> None:
        """Advance progress from one reported position and velocity (see the module docstring)."""
        if len(self) == 0 or self.flight_over:
            return
        speed = math.hypot(north_m_s, east_m_s)
        if speed < MIN_ALONG_SPEED_M_S:
            return
        course = math.degrees(math.atan2(east_m_s, north_m_s)) % 360.0
        if self.late_join and self.progress < 0:
            return  # where it is in the plan is first learned from a photo
        lo, hi = self._near_legs()
        lo = max(lo, self.progress + 1)
        if lo >= hi:
            return
        x, y = self._xy(lat_deg, lon_deg)
        dist = np.hypot(self.x[lo:hi] - x, self.y[lo:hi] - y)
        inside = np.flatnonzero(dist <= self.plan.match_radius_m[lo:hi])
        for k in inside[::-1]:
            heading = float(self.plan.heading_deg[lo + k])
            if math.isnan(heading) or _angle_diff_deg(course, heading) <= COURSE_TOLERANCE_DEG:
                self.progress = lo + int(k)
                return

    def end_flight(self) -> None:
        """The flight is over: every station counts as passed."""
        self.flight_over = True

    @property
    def taken_count(self) -> int:
        return int(np.count_nonzero(self.taken_by >= 0))

    @property
    def passed_count(self) -> int:
        return len(self) if self.flight_over else max(self.progress, 0)

    def missed(self) -> list[int]:
        """Indices of the stations passed with no photo within their radius, in flight order
        (after a late join, only from the first station observed)."""
        limit = self.passed_count
        start = self.first_observed if self.late_join else 0
        return [int(i) for i in np.flatnonzero(self.taken_by[:limit] < 0) if i >= start]


# --- link quality -------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class LinkQuality:
    """Messages of one MAVLink system since the last (re)connection, from sequence numbers.

    ``received``: distinct messages received; ``lost``: messages the sequence numbers say
    were sent and never arrived; ``duplicates``: the same sequence number twice in a row;
    ``late``: messages that arrived after a later one (reordered).
    """

    system_id: int
    received: int
    lost: int
    duplicates: int
    late: int

    @property
    def expected(self) -> int:
        return self.received + self.lost

    @property
    def quality_pct(self) -> float | None:
        return 100.0 * self.received / self.expected if self.expected else None


#: How far back (in sequence numbers) a message counted lost may still arrive late.
LATE_WINDOW = 16


@dataclass
class _SeqCounter:
    """Loss from one sender's 8-bit sequence numbers (the rule: module docstring)."""

    last: int | None = None
    received: int = 0
    lost: int = 0
    duplicates: int = 0
    late: int = 0
    # sequence numbers counted lost in the last LATE_WINDOW steps: seq -> steps ago is implicit
    missing: dict[int, int] = field(default_factory=dict)  # seq -> position when counted lost
    position: int = 0  # how many sequence numbers the sender has moved through

    def add(self, seq: int) -> None:
        if self.last is None:
            self.received += 1
            self.last = seq
            return
        step = (seq - self.last) % 256
        if step == 0:
            self.duplicates += 1
            return
        counted_at = self.missing.pop(seq, None)
        if counted_at is not None and self.position - counted_at < LATE_WINDOW:
            # counted lost a few messages ago and here it is: late (reordered), not lost
            self.received += 1
            self.late += 1
            self.lost -= 1
            return
        # a forward jump of `step` (1..255): step - 1 messages never arrived
        self.received += 1
        self.lost += step - 1
        for k in range(1, min(step, LATE_WINDOW + 1)):
            self.missing[(seq - k) % 256] = self.position + step - k
        self.position += step
        self.last = seq
        if len(self.missing) > 4 * LATE_WINDOW:
            horizon = self.position - LATE_WINDOW
            self.missing = {s_: p_ for s_, p_ in self.missing.items() if p_ >= horizon}


# --- state --------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class CameraEvent:
    """One recorded camera event (a row of the trigger CSV). None where unknown."""

    time_utc_s: float | None
    seq: int
    lat_deg: float | None
    lon_deg: float | None
    alt_amsl_m: float | None
    alt_rel_home_m: float | None
    roll_deg: float | None
    pitch_deg: float | None
    yaw_deg: float | None
    source: str
    station: int | None = None  # the planned station it took (None: an extra photo)


@dataclass(frozen=True, kw_only=True)
class MonitorState:
    """What the monitor knows now. Counts since the recording started.

    - ``mission_seq`` / ``mission_total``: MISSION_CURRENT (the vehicle's numbering;
      ArduPilot counts home as item 0); ``mission_state``: its MISSION_STATE (None: not sent).
    - ``photos_taken``: photos the vehicle took during the recording, from its own image
      index (CAMERA_FEEDBACK img_idx, CAMERA_IMAGE_CAPTURED image_index): the highest index
      seen minus the first of the flight, plus one; ``events_received``: distinct camera
      events recorded; ``photos_unseen``: indices never received (events lost on the link);
      ``photos_before_join`` / ``joined_late``: the monitor started after the first photos
      (the vehicle was already armed, or its first index seen was past the first), so those
      photos have no event in this recording; ``photos_planned``: planned stations;
      ``stations_taken`` / ``stations_passed`` / ``missed_stations`` (station indices, flight
      order) / ``extra_photos``: see the module docstring.
    - ``link``: quality per system; ``link_quality_pct``: all systems together (None before
      two messages); ``heartbeat_age_s``: wall seconds since the vehicle's last HEARTBEAT.
    - ``connected``, ``drops`` (times the link was lost), ``reconnects`` (times it came back),
      ``last_drop``: why it was last lost.
    - ``armed``, ``flight_over`` (disarmed after having flown: armed and more than
      :data:`FLYING_ALT_REL_HOME_M` above home, or EXTENDED_SYS_STATE in the air);
      ``landed_state``: the last EXTENDED_SYS_STATE landed state (1 on the ground, 2 in the
      air, 3 taking off, 4 landing; None: not sent).
    - ``missing_streams``: telemetry the monitor asked for and has not received (see
      :func:`monitor`); ``mission_changes``: times the vehicle's mission changed during the
      recording; ``stations_from``: what the stations come from ("plan": the plan folder;
      "vehicle": the mission the vehicle holds; None: no stations).
    """

    mission_seq: int | None = None
    mission_total: int | None = None
    mission_state: int | None = None
    photos_taken: int = 0
    events_received: int = 0
    photos_unseen: int = 0
    photos_before_join: int = 0
    joined_late: bool = False
    photos_planned: int = 0
    stations_taken: int = 0
    stations_passed: int = 0
    missed_stations: tuple[int, ...] = ()
    extra_photos: int = 0
    duplicate_events: int = 0
    failed_captures: int = 0
    messages: int = 0
    link: tuple[LinkQuality, ...] = ()
    link_quality_pct: float | None = None
    heartbeat_age_s: float | None = None
    connected: bool = False
    drops: int = 0
    reconnects: int = 0
    last_drop: str | None = None
    armed: bool = False
    flight_over: bool = False
    landed_state: int | None = None
    missing_streams: tuple[str, ...] = ()
    mission_changes: int = 0
    stations_from: str | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key in self.__dataclass_fields__:
            value = getattr(self, key)
            if key == "link":
                value = [
                    {
                        "system_id": q.system_id,
                        "received": q.received,
                        "lost": q.lost,
                        "duplicates": q.duplicates,
                        "late": q.late,
                        "quality_pct": q.quality_pct,
                    }
                    for q in value
                ]
            elif isinstance(value, tuple):
                value = list(value)
            out[key] = value
        return out


# --- the recorder -------------------------------------------------------------------------------


def recording_paths(out_dir: str | os.PathLike[str]) -> tuple[Path, Path, Path]:
    """(tlog, trigger CSV, summary JSON) paths of a recording folder."""
    folder = Path(out_dir)
    return folder / TLOG_NAME, folder / CSV_NAME, folder / SUMMARY_NAME


def check_recording_target(out_dir: str | os.PathLike[str], *, overwrite: bool) -> Path:
    """Refuse (:class:`OutputExistsError`) when ``out_dir`` already holds a recording and
    ``overwrite`` is False; a file in place of the folder is always refused."""
    folder = Path(out_dir)
    if folder.exists() and not folder.is_dir():
        raise OutputExistsError(f"{folder} exists and is not a folder; choose another -o folder")
    existing = [p for p in recording_paths(folder) if p.exists()]
    if existing and not overwrite:
        raise OutputExistsError(
            f"{folder} already holds a recording ({', '.join(p.name for p in existing)}); "
            f"pass --overwrite to replace it or choose another -o folder"
        )
    return folder


def _fmt(value: float | None, decimals: int) -> str:
    if value is None or not math.isfinite(value):
        return ""
    return f"{value:.{decimals}f}"


class FlightRecorder:
    """Writes the tlog and the trigger CSV and keeps the :class:`MonitorState`.

    ``out_dir``: the recording folder (created); ``plan``: the planned stations (None: no
    progress against a plan); ``overwrite``: replace an existing recording (else
    :class:`OutputExistsError`). Use it as a context manager, or call :meth:`close`.
    Not thread-safe: one thread records.
    """

    def __init__(
        self,
        out_dir: str | os.PathLike[str],
        plan: StationPlan | None = None,
        *,
        overwrite: bool = False,
    ) -> None:
        folder = check_recording_target(out_dir, overwrite=overwrite)
        folder.mkdir(parents=True, exist_ok=True)
        self.out_dir = folder
        self.tlog_path, self.csv_path, self.summary_path = recording_paths(folder)
        for stale in (self.summary_path,):
            if stale.exists():
                stale.unlink()
        self.plan = plan
        self.tracker = StationTracker(plan) if plan is not None else None
        self._tlog: IO[bytes] | None = open(self.tlog_path, "wb")  # noqa: SIM115 - close()
        self._csv: IO[str] | None = open(self.csv_path, "w", encoding="utf-8", newline="")  # noqa: SIM115
        self._write_csv_row(CSV_COLUMNS)
        self._last_fsync_s = time.monotonic()
        self.events: list[CameraEvent] = []
        self._seen: dict[tuple[str, int, int], int] = {}  # (type, camera, index) -> time_usec
        self._pending_triggers: dict[int, tuple[float, Any]] = {}  # seq -> (wall s, msg)
        self._positional_camera = False
        self._seq: dict[tuple[int, int], _SeqCounter] = {}
        self._restart_seq = False  # the next message starts new sequence counts (a new connection)
        self.vehicle: tuple[int, int] | None = None
        self._boot_offset_s: float | None = None  # vehicle UTC minus boot time, s
        self._last_boot_ms: float | None = None
        self._last_position: Any | None = None
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
        self._first_heartbeat_armed: bool | None = None
        self._seen_disarmed = False
        self._index_first: int | None = None
        self._index_max: int | None = None
        self._index_origin = 1
        self._indices: set[int] = set()
        self._indexed_events = 0
        self.joined_late = False
        self.messages = 0
        self.duplicate_events = 0
        self.failed_captures = 0
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
        self._release_triggers(force=True)
        for handle in (self._tlog, self._csv):
            if handle is not None:
                handle.flush()
                os.fsync(handle.fileno())
                handle.close()
        self._tlog = self._csv = None
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
            rx_time_utc_s = float(getattr(msg, "_timestamp", 0.0) or time.time())
        self._write_tlog(msg, rx_time_utc_s)
        self.messages += 1
        if self._restart_seq:
            self._seq.clear()
            self._restart_seq = False
        src = (int(msg.get_srcSystem()), int(msg.get_srcComponent()))
        self._seq.setdefault(src, _SeqCounter()).add(int(msg.get_seq()))
        if kind == "HEARTBEAT":
            self._on_heartbeat(msg, src)
        if self.vehicle is not None and src[0] != self.vehicle[0]:
            return None  # another system (a second vehicle, another GCS): logged only
        from_autopilot = self.vehicle is None or src == self.vehicle
        if from_autopilot:
            self.last_seen_s[kind] = time.monotonic()
        event: CameraEvent | None = None
        if kind == "SYSTEM_TIME" and from_autopilot:
            self._last_boot_ms = float(msg.time_boot_ms)
            if msg.time_unix_usec > 0:
                self._boot_offset_s = msg.time_unix_usec / 1e6 - msg.time_boot_ms / 1e3
        elif kind == "GLOBAL_POSITION_INT" and from_autopilot:
            self._last_boot_ms = float(msg.time_boot_ms)
            if self._armed and msg.relative_alt > FLYING_ALT_REL_HOME_M * 1000:
                self._flew = True
            if msg.lat != 0 or msg.lon != 0:
                self._last_position = msg
                if self.tracker is not None:
                    self.tracker.add_position(msg.lat * 1e-7, msg.lon * 1e-7, msg.vx / 100.0, msg.vy / 100.0)
        elif kind == "MISSION_CURRENT" and from_autopilot:
            total = getattr(msg, "total", None)
            state = getattr(msg, "mission_state", None)
            self._mission = (
                int(msg.seq),
                int(total) if total not in (None, 0, 65535) else None,
                int(state) if state not in (None, 0) else None,
            )
            self._watch_mission(total, getattr(msg, "mission_id", None))
        elif kind == "EXTENDED_SYS_STATE" and from_autopilot:
            self._landed_state = int(msg.landed_state) or None
            if self._armed and self._landed_state in (2, 3, 4):
                self._flew = True
        elif kind == "CAMERA_FEEDBACK" and from_autopilot:
            event = self._on_camera_feedback(msg)
        elif kind == "CAMERA_IMAGE_CAPTURED":
            event = self._on_image_captured(msg)
        elif kind == "CAMERA_TRIGGER" and from_autopilot and not self._positional_camera:
            self._pending_triggers.setdefault(int(msg.seq), (time.monotonic(), msg))
        self._release_triggers(force=False)
        return event

    def _write_tlog(self, msg: Any, rx_time_utc_s: float) -> None:
        assert self._tlog is not None
        data = msg.get_msgbuf()
        stamp = struct.pack(">Q", max(round(rx_time_utc_s * 1e6), 0))
        self._tlog.write(stamp + bytes(data))  # one write: a record is whole or absent
        self._tlog.flush()
        now = time.monotonic()
        if now - self._last_fsync_s >= FSYNC_INTERVAL_S:
            os.fsync(self._tlog.fileno())
            self._last_fsync_s = now

    def _on_heartbeat(self, msg: Any, src: tuple[int, int]) -> None:
        autopilot = int(msg.autopilot) != _MAV_AUTOPILOT_INVALID and int(msg.type) != _MAV_TYPE_GCS
        if self.vehicle is None and autopilot:
            self.vehicle = src
            log.info("recording vehicle system %d component %d", *src)
        if src != self.vehicle:
            return
        self._last_heartbeat_wall_s = time.monotonic()
        armed = bool(int(msg.base_mode) & _MAV_MODE_FLAG_SAFETY_ARMED)
        if self._first_heartbeat_armed is None:
            self._first_heartbeat_armed = armed
        if not armed:
            self._seen_disarmed = True
        if armed and not self._armed and self._flight_over:
            log.info("the vehicle armed again: a new flight in the same recording")
            self._flight_over = False
            self._flew = False
            if self.tracker is not None:
                self.tracker.flight_over = False
        elif not armed and self._flew and not self._flight_over and self._landed_state not in (2, 4):
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

    def _watch_mission(self, total: Any, mission_id: Any) -> None:
        """MISSION_CURRENT's total and mission_id (opaque id, 0 when not sent) name the
        mission the vehicle holds; a change is a new mission (a re-fly uploaded)."""
        if total is None:
            return
        key = (int(total), int(mission_id or 0))
        if self._mission_key is not None and key != self._mission_key:
            now = time.monotonic()
            # an upload changes the total more than once (truncated, then complete): one change
            settled = self.mission_changed_at_s is None or now - self.mission_changed_at_s > 5.0
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

    def _note_index(self, index: int, origin: int) -> None:
        """A camera event with the vehicle's image index ``index`` (first photo: ``origin``)."""
        if self._index_first is None or index < self._index_first:
            if self._index_first is None:
                self._index_origin = origin
                if index > origin and not self._seen_disarmed:
                    self._set_late_join(
                        f"the first camera event has image index {index} (the first photo is {origin})"
                    )
            self._index_first = index
        self._index_max = index if self._index_max is None else max(self._index_max, index)
        self._indices.add(index)
        self._indexed_events += 1

    def _vehicle_utc_s(self, boot_s: float) -> float | None:
        return None if self._boot_offset_s is None else boot_s + self._boot_offset_s

    def _time_usec_to_utc(self, time_usec: int) -> float | None:
        if time_usec <= 0:
            return None if self._last_boot_ms is None else self._vehicle_utc_s(self._last_boot_ms / 1e3)
        if time_usec < BOOT_US_LIMIT:
            return self._vehicle_utc_s(time_usec / 1e6)
        as_unix = (time_usec // 1_000_000) + (time_usec % 1_000_000) / 1e6
        now = None if self._last_boot_ms is None else self._vehicle_utc_s(self._last_boot_ms / 1e3)
        if now is not None:
            as_gps = float(gps_usec_to_utc_s(np.int64(time_usec)))
            if abs(as_gps - now) < abs(as_unix - now):
                return as_gps
        return float(as_unix)

    def _is_duplicate(self, key: tuple[str, int, int], time_usec: int) -> bool:
        seen = self._seen.get(key)
        if seen is not None and seen == time_usec:
            self.duplicate_events += 1
            return True
        if seen is not None:
            log.warning(
                "%s index %d came again with another time: the camera counter restarted "
                "(a reboot?); recorded as a new photo",
                key[0],
                key[2],
            )
        self._seen[key] = time_usec
        return False

    def _on_camera_feedback(self, msg: Any) -> CameraEvent | None:
        self._positional_camera = True
        self._pending_triggers.clear()
        key = ("CAMERA_FEEDBACK", int(msg.cam_idx), int(msg.img_idx))
        if self._is_duplicate(key, int(msg.time_usec)):
            return None
        return self._add_event(
            time_utc_s=self._time_usec_to_utc(int(msg.time_usec)),
            seq=int(msg.img_idx),
            lat_deg=msg.lat * 1e-7,
            lon_deg=msg.lng * 1e-7,
            alt_amsl_m=float(msg.alt_msl),
            alt_rel_home_m=float(msg.alt_rel),
            roll_deg=float(msg.roll),
            pitch_deg=float(msg.pitch),
            yaw_deg=float(msg.yaw) % 360.0,
            source="CAMERA_FEEDBACK",
        )

    def _on_image_captured(self, msg: Any) -> CameraEvent | None:
        self._positional_camera = True
        self._pending_triggers.clear()
        if int(msg.capture_result) != 1:
            self.failed_captures += 1
            log.warning("the camera reports capture %d failed", int(msg.image_index))
            return None
        component = int(msg.get_srcComponent())
        stamp = int(msg.time_utc) or int(msg.time_boot_ms)
        if self._is_duplicate(("CAMERA_IMAGE_CAPTURED", component, int(msg.image_index)), stamp):
            return None
        if msg.time_utc > 0:
            t: float | None = msg.time_utc / 1e6
        elif self.vehicle is None or msg.get_srcComponent() == self.vehicle[1]:
            t = self._vehicle_utc_s(msg.time_boot_ms / 1e3)
        else:  # a camera's own boot clock: the vehicle's time now is the best there is
            t = self._time_usec_to_utc(0)
        roll, pitch, yaw = euler_deg_from_quaternion(*(float(v) for v in msg.q))
        return self._add_event(
            time_utc_s=t,
            seq=int(msg.image_index),
            lat_deg=msg.lat * 1e-7,
            lon_deg=msg.lon * 1e-7,
            alt_amsl_m=msg.alt * 1e-3,
            alt_rel_home_m=msg.relative_alt * 1e-3,
            roll_deg=float(roll),
            pitch_deg=float(pitch),
            yaw_deg=float(yaw),
            source="CAMERA_IMAGE_CAPTURED",
        )

    def _release_triggers(self, *, force: bool) -> None:
        if not self._pending_triggers:
            return
        now = time.monotonic()
        for seq in sorted(self._pending_triggers):
            held_since, msg = self._pending_triggers[seq]
            if not force and now - held_since < TRIGGER_HOLD_S:
                continue
            del self._pending_triggers[seq]
            if self._is_duplicate(("CAMERA_TRIGGER", 0, seq), int(msg.time_usec)):
                continue
            pos = self._last_position
            self._add_event(
                time_utc_s=self._time_usec_to_utc(int(msg.time_usec)),
                seq=seq,
                lat_deg=pos.lat * 1e-7 if pos is not None else None,
                lon_deg=pos.lon * 1e-7 if pos is not None else None,
                alt_amsl_m=pos.alt * 1e-3 if pos is not None else None,
                alt_rel_home_m=pos.relative_alt * 1e-3 if pos is not None else None,
                roll_deg=None,
                pitch_deg=None,
                yaw_deg=None,
                source="CAMERA_TRIGGER+GLOBAL_POSITION_INT" if pos is not None else "CAMERA_TRIGGER",
            )

    def _add_event(self, **values: Any) -> CameraEvent:
        if values["source"] == "CAMERA_FEEDBACK":
            self._note_index(int(values["seq"]), 1)
        elif values["source"] == "CAMERA_IMAGE_CAPTURED":
            self._note_index(int(values["seq"]), 0)
        station = None
        if self.tracker is not None and values["lat_deg"] is not None:
            station = self.tracker.add_event(len(self.events), values["lat_deg"], values["lon_deg"])
        elif self.tracker is not None:
            self.tracker.extra_photos += 1
        event = CameraEvent(station=station, **values)
        self.events.append(event)
        self._write_csv_row(
            (
                _fmt(event.time_utc_s, 6),
                str(event.seq),
                _fmt(event.lat_deg, 7),
                _fmt(event.lon_deg, 7),
                _fmt(event.alt_amsl_m, 3),
                _fmt(event.alt_rel_home_m, 3),
                _fmt(event.roll_deg, 3),
                _fmt(event.pitch_deg, 3),
                _fmt(event.yaw_deg, 3),
                event.source,
            )
        )
        # an event is what the crew cannot get back: make it durable now
        assert self._tlog is not None
        os.fsync(self._tlog.fileno())
        self._last_fsync_s = time.monotonic()
        return event

    def _write_csv_row(self, row: Sequence[str]) -> None:
        assert self._csv is not None
        buffer = io.StringIO()
        csv.writer(buffer, lineterminator="\n").writerow(row)
        self._csv.write(buffer.getvalue())  # one write per row: a row is whole or absent
        self._csv.flush()
        os.fsync(self._csv.fileno())

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
        self._restart_seq = True
        if self._tlog is not None:
            self._tlog.flush()
            os.fsync(self._tlog.fileno())

    def note_connecting(self) -> None:
        """A new attempt to open the link starts: sequence counts restart with its first
        message, so that a gap between two attempts is not counted as losses."""
        self._restart_seq = True

    def note_reconnect(self) -> None:
        """The link is back. Its sequence counts started with its first message (recorded
        while the link waited for the heartbeat), see the module docstring."""
        self.connected = True
        self.reconnects += 1

    # --- state -------------------------------------------------------------------------------

    @property
    def flight_over(self) -> bool:
        return self._flight_over

    def state(self) -> MonitorState:
        """The current :class:`MonitorState`."""
        per_system: dict[int, _SeqCounter] = {}
        for (system, _), counter in self._seq.items():
            total = per_system.setdefault(system, _SeqCounter())
            total.received += counter.received
            total.lost += counter.lost
            total.duplicates += counter.duplicates
            total.late += counter.late
        link = tuple(
            LinkQuality(
                system_id=system,
                received=c.received,
                lost=c.lost,
                duplicates=c.duplicates,
                late=c.late,
            )
            for system, c in sorted(per_system.items())
        )
        received = sum(q.received for q in link)
        expected = sum(q.expected for q in link)
        tracker = self.tracker
        age = None if self._last_heartbeat_wall_s is None else time.monotonic() - self._last_heartbeat_wall_s
        events = len(self.events)
        photos, unseen, before = events, 0, 0
        if self._index_first is not None and self._index_max is not None:
            span = self._index_max - self._index_first + 1
            unseen = max(span - len(self._indices), 0)
            before = self._index_first - self._index_origin if self.joined_late else 0
            # events without an index (CAMERA_TRIGGER alone) add to what the indices say
            photos = span + before + (events - self._indexed_events)
        return MonitorState(
            mission_seq=self._mission[0],
            mission_total=self._mission[1],
            mission_state=self._mission[2],
            photos_taken=max(photos, events),
            events_received=events,
            photos_unseen=unseen,
            photos_before_join=max(before, 0),
            joined_late=self.joined_late,
            photos_planned=len(tracker) if tracker is not None else 0,
            stations_taken=tracker.taken_count if tracker is not None else 0,
            stations_passed=tracker.passed_count if tracker is not None else 0,
            missed_stations=tuple(tracker.missed()) if tracker is not None else (),
            extra_photos=tracker.extra_photos if tracker is not None else 0,
            duplicate_events=self.duplicate_events,
            failed_captures=self.failed_captures,
            messages=self.messages,
            link=link,
            link_quality_pct=100.0 * received / expected if expected > 1 else None,
            heartbeat_age_s=age,
            connected=self.connected,
            drops=self.drops,
            reconnects=self.reconnects,
            last_drop=self.last_drop,
            armed=self._armed,
            flight_over=self._flight_over,
            landed_state=self._landed_state,
            missing_streams=self.missing_streams,
            mission_changes=self.mission_changes,
            stations_from=self.stations_from,
        )


# --- the loop -----------------------------------------------------------------------------------


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
) -> MonitorResult:
    """Record the flight on ``url`` into ``out_dir`` until it ends (module docstring).

    ``plan_dir``: the plan folder (stations.geojson, summary.json), None for no plan.
    ``on_update(state)``: called at most every ``update_interval_s`` wall seconds, and at
    every drop and reconnection. ``stop_event``: set it to end the recording.
    ``reconnect_timeout_s``: after a drop, how long (wall s) to keep trying to reopen the
    link before giving up. ``heartbeat_timeout_s``: wait for the vehicle at the first
    connection (s). ``stop_when_landed``: end ``linger_s`` after the vehicle disarms following
    a flight. ``signing_key`` / ``require_signing``: as :meth:`Link.open`.

    Ends on landing, the stop event or Ctrl-C with the files complete and returns a
    :class:`MonitorResult`. Raises :class:`LinkError` when the first connection fails (no
    file is written then) or when the link does not come back within ``reconnect_timeout_s``
    (the recording up to the drop is kept, and the message says where).
    """
    from .link import Link
    from .mission_stations import station_columns
    from .monitor_link import Dropped, LinkReader, MissionFollower, StreamRequests

    plan = load_station_plan(plan_dir) if plan_dir is not None else None
    check_recording_target(out_dir, overwrite=overwrite)
    if plan is not None:
        log.info("plan %s: %d stations", plan.name, len(plan))

    # Every message any read parses goes into this queue (from the reader thread, or from
    # Link.open while it waits for the heartbeat); the main loop records them in order.
    inbox: queue.Queue[Any] = queue.Queue()

    def observe(msg: Any, rx_time_utc_s: float) -> None:
        inbox.put((msg, rx_time_utc_s))

    def open_link(timeout_s: float) -> Link:
        return Link.open(
            url,
            heartbeat_timeout_s=timeout_s,
            signing_key=signing_key,
            require_signing=require_signing,
            on_message=observe,
        )

    first = open_link(heartbeat_timeout_s)
    link: Link | None = first
    stop = stop_event if stop_event is not None else threading.Event()
    try:
        recorder = FlightRecorder(out_dir, plan, overwrite=overwrite)
    except BaseException:
        first.close()
        raise
    recorder.set_vehicle(first.target_system, first.target_component)
    requests = StreamRequests()
    follower = MissionFollower(Path(plan_dir) if plan_dir is not None else None)
    reader: LinkReader | None = None
    reason = StopReason.STOPPED
    last_update = 0.0
    landed_at: float | None = None

    def update(force: bool = False) -> None:
        nonlocal last_update
        now = time.monotonic()
        if on_update is not None and (force or now - last_update >= update_interval_s):
            last_update = now
            on_update(recorder.state())

    def start(active: Link) -> LinkReader:
        try:
            requests.ask(active)
        except LinkError as error:  # the reader will see the drop too
            log.debug("asking for streams failed: %s", error)
        return LinkReader(active, inbox)

    def apply_mission(items: list[Any], same_as_plan: bool) -> None:
        if same_as_plan:
            if recorder.stations_from != "plan" and plan is not None:
                recorder.replace_plan(plan, source="plan")
            log.info("the vehicle holds the plan's mission (%d items)", len(items))
            return
        columns = station_columns(items)
        stations = (
            StationPlan(name="the vehicle's mission", trigger_distance_m=None, **columns)
            if len(columns["lat_deg"])
            else None
        )
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
                        open_link, recorder, stop, reconnect_timeout_s, heartbeat_timeout_s, update
                    )
                    if link is None:  # stopped while reconnecting
                        reason = StopReason.STOPPED
                        break
                    reader = start(link)
                    continue
                try:
                    item = inbox.get(timeout=0.1)
                except queue.Empty:
                    item = None
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
                    try:
                        item = inbox.get_nowait()
                    except queue.Empty:
                        item = None
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
                        landed_at = time.monotonic()
                        log.info("the vehicle has landed and disarmed; ending the recording")
                    elif time.monotonic() - landed_at >= linger_s:
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
        while True:
            try:
                item = inbox.get_nowait()
            except queue.Empty:
                break
            if not isinstance(item, Dropped) and not recorder.closed:
                recorder.record(*item)
        state = recorder.close()
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
) -> Any | None:
    """Reopen the link until it works, ``stop`` is set (None) or ``timeout_s`` passes
    (:class:`LinkError` that says the recording is kept)."""
    started = time.monotonic()
    attempts = 0
    while not stop.is_set():
        remaining = timeout_s - (time.monotonic() - started)
        if remaining <= 0:
            break
        attempts += 1
        recorder.note_connecting()
        try:
            link = open_link(max(min(heartbeat_timeout_s, remaining), 0.5))
        except LinkError as error:
            log.debug("reconnection attempt %d failed: %s", attempts, error)
            update(True)
            stop.wait(min(0.5, max(remaining, 0.0)))
            continue
        recorder.set_vehicle(link.target_system, link.target_component)
        recorder.note_reconnect()
        log.warning(
            "reconnected after %.1f s (%d attempts); recording goes on in %s",
            time.monotonic() - started,
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
