"""Shared helpers for the planner tests: specs from dicts, and an independent replay of the
trigger items that says where an autopilot fires the camera."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from planner.mission import MavCmd, Mission
from planner.spec import MissionSpec, parse_spec

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"


def make_spec(overrides: dict[str, Any] | None = None, camera: dict[str, Any] | None = None) -> MissionSpec:
    """A valid spec (area path unused: tests call plan_polygons) with survey overrides."""
    survey: dict[str, Any] = {
        "gsd_cm": 2.0,
        "front_overlap_pct": 80,
        "side_overlap_pct": 70,
        "speed_m_s": 5.0,
        "turnaround_m": 10.0,
    }
    survey.update(overrides or {})
    data = {
        "name": "test",
        "area": "area.geojson",
        "camera": camera or {"model": "dji-phantom-4-pro"},
        "survey": survey,
        "vehicle": {"type": "multirotor", "max_alt_agl_m": 400},
    }
    return parse_spec(data, REPO / "tests" / "spec.toml")


def replay_triggers(mission: Mission, to_xy: Any) -> np.ndarray:
    """Where an autopilot fires the camera, replaying the mission items the way ArduPilot's
    AP_Camera does: DO_SET_CAM_TRIGG_DIST(d, _, 1) fires once at the current position, then
    whenever the straight distance from the last photo reaches d along the flown legs; d = 0
    stops; IMAGE_START_CAPTURE fires once at the current position.

    This is written from the MAVLink command definitions, independently of the planner's
    station computation, so it can be the oracle for "the photo count the vehicle will take".
    ``to_xy(lon, lat) -> (x, y)`` projects waypoints into metres.
    """
    photos: list[tuple[float, float]] = []
    position: tuple[float, float] | None = None
    last_photo: tuple[float, float] | None = None
    distance = 0.0
    for item in mission.items:
        command = int(item.command)
        if command in (MavCmd.NAV_WAYPOINT, MavCmd.NAV_TAKEOFF):
            x, y = to_xy(item.lon_deg, item.lat_deg)
            target = (float(x), float(y))
            if position is not None and distance > 0 and last_photo is not None:
                photos_on_leg = _fire_along_leg(position, target, last_photo, distance)
                photos.extend(photos_on_leg)
                if photos_on_leg:
                    last_photo = photos_on_leg[-1]
            position = target
        elif command == MavCmd.DO_SET_CAM_TRIGG_DIST:
            assert item.param1 is not None
            distance = float(item.param1)
            if item.param3 == 1.0 and position is not None:
                photos.append(position)
                last_photo = position
        elif command == MavCmd.IMAGE_START_CAPTURE:
            assert position is not None
            photos.append(position)
            last_photo = position
    return np.asarray(photos, float).reshape(-1, 2)


def _fire_along_leg(
    a: tuple[float, float], b: tuple[float, float], last: tuple[float, float], d: float
) -> list[tuple[float, float]]:
    """Points on the leg a->b where the straight distance from the last photo first reaches d
    (solved exactly: the leg meets the circle of radius d around the last photo)."""
    out: list[tuple[float, float]] = []
    wx, wy = b[0] - a[0], b[1] - a[1]
    ww = wx * wx + wy * wy
    if ww == 0.0:
        return out
    t0 = 0.0
    while True:
        # |a + t w - last|^2 = d^2, smallest root t >= t0
        ox, oy = a[0] - last[0], a[1] - last[1]
        bq = 2.0 * (ox * wx + oy * wy)
        cq = ox * ox + oy * oy - d * d
        disc = bq * bq - 4.0 * ww * cq
        if disc < 0:
            return out
        roots = sorted(((-bq - math.sqrt(disc)) / (2 * ww), (-bq + math.sqrt(disc)) / (2 * ww)))
        t = next((r for r in roots if r >= t0 - 1e-12 and r > 1e-12), None)
        if t is None or t > 1.0 + 1e-12:
            return out
        last = (a[0] + t * wx, a[1] + t * wy)
        out.append(last)
        t0 = t
