"""The exposure stations a mission will photograph, replayed from its items as the vehicle flies them.

``sfap monitor`` counts photos against planned stations. The plan folder has them; but when
the vehicle holds another mission (a re-fly of the gaps uploaded in the field, or no plan folder
at all), the stations are those of the mission the vehicle holds, read back from it. This
module replays the items in order as AP_Camera and PX4 trigger the camera (REFERENCES.md
sections 2, 3 and 6):

- DO_SET_CAM_TRIGG_DIST(d, _, p3): distance triggering at ``d`` metres (0: off); ``p3 = 1``
  takes one photo at once. While it is on, a photo is taken whenever the straight-line
  horizontal distance from the last photo reaches ``d`` along the path between the waypoints.
- IMAGE_START_CAPTURE with one image (or no interval), DO_DIGICAM_CONTROL(shoot = 1): one photo
  where the vehicle is (a hover station).

Each camera-on stretch is a *line* (``line_index``); a station's heading is the bearing of the
leg it lies on (NaN for a photo at a waypoint where the path turns: any course then matches).
The match radius is half the trigger distance, at least
:data:`acquisition.station_tracker.MIN_MATCH_RADIUS_M`.
Distances are measured in the UTM zone of the mission's first waypoint (within 0.1 % of the
sphere ArduPilot uses; the count may differ by one photo at the end of a line where the plan
itself has no margin).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from planner.geo import LocalFrame
from planner.mission import MavCmd, MissionItem

from .mavlink_items import is_global_frame
from .station_tracker import MIN_MATCH_RADIUS_M, StationPlan


def distance_trigger_fractions(
    start: tuple[float, float],
    end: tuple[float, float],
    last_photo: tuple[float, float],
    distance_m: float,
    *,
    tolerance: float,
) -> list[float]:
    """Fractions ``s`` (0..1 + ``tolerance``) of the straight piece start->end at which distance
    triggering fires: each the smallest ``s`` at or after the previous one where the horizontal
    straight-line distance from the last photo (``last_photo``, then each new one) reaches
    ``distance_m``, as AP_Camera decides, solved exactly (a quadratic in ``s``). Coordinates in
    metres of one plane frame."""
    bx, by = end[0] - start[0], end[1] - start[1]
    a = bx * bx + by * by
    if a == 0.0 or distance_m <= 0:
        return []
    out: list[float] = []
    last = last_photo
    s0 = 0.0
    while True:
        # smallest s >= s0 where |start + s b - last| = d
        ax, ay = start[0] + s0 * bx - last[0], start[1] + s0 * by - last[1]
        b = 2 * (ax * bx + ay * by)
        c = ax * ax + ay * ay - distance_m * distance_m
        u = 0.0 if c >= 0 else (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)
        s = s0 + u
        if s > 1.0 + tolerance:
            return out
        out.append(s)
        last = (start[0] + s * bx, start[1] + s * by)
        s0 = s


def replay_stations(
    items: Sequence[MissionItem],
) -> tuple[list[tuple[float, float, int, float, float]], LocalFrame | None]:
    """Stations of ``items`` (no home item) in flight order: (lat_deg, lon_deg, line_index,
    heading_deg, trigger_distance_m or NaN), and the frame used (None: no waypoint)."""
    positional = [
        it for it in items if is_global_frame(it.frame) and (it.lat_deg != 0.0 or it.lon_deg != 0.0)
    ]
    if not positional:
        return [], None
    frame = LocalFrame.utm_for(positional[0].lon_deg, positional[0].lat_deg)
    out: list[tuple[float, float, int, float, float]] = []
    pos: tuple[float, float] | None = None
    last_photo: tuple[float, float] | None = None
    distance_m = 0.0
    line = -1

    def photo(x: float, y: float, heading_deg: float) -> None:
        nonlocal last_photo
        lon, lat = frame.to_lonlat(x, y)
        out.append((float(lat), float(lon), max(line, 0), heading_deg, distance_m or math.nan))
        last_photo = (x, y)

    for item in items:
        command = int(item.command)
        if command == MavCmd.DO_SET_CAM_TRIGG_DIST:
            distance_m = max(float(item.param1 or 0.0), 0.0)
            if distance_m > 0:
                line += 1
            if (item.param3 or 0.0) == 1 and pos is not None:
                photo(pos[0], pos[1], math.nan)
            elif distance_m > 0 and pos is not None:
                last_photo = pos  # AP_Camera: the first update only remembers the position
            continue
        if command == MavCmd.IMAGE_START_CAPTURE:
            if pos is not None and ((item.param3 or 0.0) == 1 or (item.param2 or 0.0) <= 0):
                line += 1
                photo(pos[0], pos[1], math.nan)
            continue
        if command == MavCmd.DO_DIGICAM_CONTROL:
            if pos is not None and (item.param5 or 0.0) == 1:
                line += 1
                photo(pos[0], pos[1], math.nan)
            continue
        if not (is_global_frame(item.frame) and (item.lat_deg != 0.0 or item.lon_deg != 0.0)):
            continue
        tx, ty = (float(v) for v in frame.to_xy(item.lon_deg, item.lat_deg))
        if pos is not None and distance_m > 0:
            bx, by = tx - pos[0], ty - pos[1]
            length = math.hypot(bx, by)
            if length > 0:
                grid = math.degrees(math.atan2(bx, by)) % 360.0
                heading = (grid - frame.true_north_grid_bearing_deg(item.lon_deg, item.lat_deg)) % 360.0
                if last_photo is None:
                    last_photo = pos
                for s in distance_trigger_fractions(pos, (tx, ty), last_photo, distance_m, tolerance=1e-9):
                    photo(pos[0] + s * bx, pos[1] + s * by, heading)
        pos = (tx, ty)
    return out, frame


def mission_station_plan(items: Sequence[MissionItem]) -> StationPlan | None:
    """The :class:`StationPlan` of the stations of ``items`` (None: the mission takes no photo)."""
    rows, _ = replay_stations(items)
    if not rows:
        return None
    a = np.array(rows, dtype=np.float64).reshape(-1, 5)
    d = a[:, 4]
    return StationPlan(
        name="the vehicle's mission",
        lat_deg=a[:, 0].copy(),
        lon_deg=a[:, 1].copy(),
        pass_index=np.zeros(len(a), dtype=np.int64),
        line_index=a[:, 2].astype(np.int64),
        heading_deg=a[:, 3].copy(),
        match_radius_m=np.where(np.isfinite(d), np.maximum(d / 2.0, MIN_MATCH_RADIUS_M), MIN_MATCH_RADIUS_M),
        trigger_distance_m=None,
    )
