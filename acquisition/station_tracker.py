"""The planned exposure stations and which of them a flight took, passed and missed.

:class:`StationPlan` holds the stations in flight order (from the plan folder,
:func:`load_station_plan`, or from the mission the vehicle holds,
:mod:`acquisition.mission_stations`); :class:`StationTracker` matches camera events and reported
positions to them as they come (used by :class:`acquisition.flight_recorder.FlightRecorder`).

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
      and more than :data:`acquisition.flight_recorder.FLYING_ALT_REL_HOME_M` above home).
    * A station is *missed* when it is passed and not taken. A late event can still take a
      passed station; the missed list is recomputed, never latched.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.errors import InputError
from planner.geo import LocalFrame
from planner.plan_folder import PlanFolder, read_plan_folder

#: Smallest match radius of a station, metres (GNSS noise of a plain receiver).
MIN_MATCH_RADIUS_M = 5.0
#: How far the course may differ from a station's heading for the vehicle to "fly along" it.
COURSE_TOLERANCE_DEG = 45.0
#: Below this ground speed (m/s) the course is not trusted.
MIN_ALONG_SPEED_M_S = 1.0


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
    """The stations of a plan folder (``sfap plan -o DIR``, read by
    :func:`planner.plan_folder.read_plan_folder`), each with the match radius of its pass.

    Raises :class:`~planner.errors.PlanFolderError` naming the folder or the file when the
    folder is not a plan folder or a file is missing or malformed.
    """
    return station_plan(read_plan_folder(plan_dir))


def station_plan(folder: PlanFolder) -> StationPlan:
    """The :class:`StationPlan` of a plan folder as read: the match radius of a station is half
    its pass's trigger distance (the plan's when the pass does not say), at least
    :data:`MIN_MATCH_RADIUS_M`."""
    stations = folder.stations
    default_d = folder.summary.trigger_distance_m
    per_pass = {p.index: p.trigger_distance_m for p in folder.passes}
    d = np.array([per_pass.get(int(k), default_d) or 0.0 for k in stations.pass_index], dtype=np.float64)
    radius = np.where(d > 0, np.maximum(d / 2.0, MIN_MATCH_RADIUS_M), MIN_MATCH_RADIUS_M)
    return StationPlan(
        name=folder.summary.name,
        lat_deg=stations.lat_deg.copy(),
        lon_deg=stations.lon_deg.copy(),
        pass_index=stations.pass_index.copy(),
        line_index=stations.line_index.copy(),
        heading_deg=stations.heading_deg.copy(),
        match_radius_m=radius.reshape(len(stations.lat_deg)),
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
