"""How an autopilot fires a distance-triggered camera, and the margins a plan keeps for it.

ArduPilot (AP_Camera_Backend::update, "should be called at 50hz") checks, once per loop, whether
the vehicle is at least the trigger distance from where the last photo was taken, measuring with
``Location::get_distance``: latitude and longitude as integers of 1e-7 degree, the longitude
difference scaled by the cosine of the mean latitude, times LOCATION_SCALING_FACTOR (a sphere of
radius 6,378,100 m). Two things follow, both handled here:

1. Its metre is not the plan's: the sphere and the UTM grid differ by a few parts per thousand,
   depending on the latitude, the line's bearing and the distance from the central meridian.
   Each run's commanded distance is the station spacing converted into the autopilot's own
   measure (:func:`distance_ratio`), so the photos fall where the plan put them.
2. A photo fires at the first loop after the distance is reached, up to one loop step
   (speed / loop rate) late, and the next distance is measured from there: the lag grows along a
   run. The commanded distance is shortened by half a loop step (the spacing flown is then the
   planned one +- half a step), the planned spacing is at most the air base minus half a step
   (:func:`station_step_m`, so the overlaps hold even with the step), and a run holds at most
   :func:`max_run_stations` stations, so that the worst accumulated drift stays below
   :data:`DRIFT_SHARE` of the half spacing between the last station and the camera-off point:
   the last photo always fires and no extra one does. Longer lines are cut into runs that
   follow each other without a turn; each run re-arms the trigger, firing at its first station.

PX4 (camera_trigger in distance mode) measures in its local frame, an azimuthal projection on a
sphere of radius 6,371,000 m; the same margins are kept, with that sphere's distance.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .lines import Segment, split_run
from .mission import Autopilot

#: The rate at which the trigger distance is checked (AP_Camera_Backend::update), Hz.
LOOP_RATE_HZ = 50.0
#: ArduPilot's LOCATION_SCALING_FACTOR: metres per 1e-7 degree of latitude (sphere of 6,378,100 m).
ARDUPILOT_SCALING_M = 0.011131884502145034
#: PX4's CONSTANTS_RADIUS_OF_EARTH, metres.
PX4_RADIUS_M = 6_371_000.0
#: Share of the half spacing (last station to camera-off) that the worst drift may use.
DRIFT_SHARE = 0.8


def autopilot_distance_m(
    lat0_deg: ArrayLike,
    lon0_deg: ArrayLike,
    lat1_deg: ArrayLike,
    lon1_deg: ArrayLike,
    autopilot: Autopilot,
    *,
    integer_positions: bool = True,
) -> NDArray[np.float64]:
    """Horizontal distance between two positions as the autopilot measures it, metres.

    ArduPilot holds positions as integers of 1e-7 degree (``integer_positions``; False gives the
    formula's value between the exact positions, for scale ratios over short baselines)."""
    lat0, lon0, lat1, lon1 = (np.asarray(a, float) for a in (lat0_deg, lon0_deg, lat1_deg, lon1_deg))
    if autopilot is Autopilot.ARDUPILOT:
        rnd = np.round if integer_positions else np.asarray
        ilat0, ilon0 = rnd(lat0 * 1e7), rnd(lon0 * 1e7)
        ilat1, ilon1 = rnd(lat1 * 1e7), rnd(lon1 * 1e7)
        dlng = ilon1 - ilon0
        dlng = np.where(dlng > 1.8e9, dlng - 3.6e9, np.where(dlng < -1.8e9, dlng + 3.6e9, dlng))
        scale = np.maximum(np.cos(np.radians((ilat0 + ilat1) / 2.0 * 1e-7)), 0.01)
        return np.asarray(np.hypot(ilat1 - ilat0, dlng * scale) * ARDUPILOT_SCALING_M, float)
    p0, p1 = np.radians(lat0), np.radians(lat1)
    dp, dl = p1 - p0, np.radians(lon1 - lon0)
    h = np.sin(dp / 2.0) ** 2 + np.cos(p0) * np.cos(p1) * np.sin(dl / 2.0) ** 2
    return np.asarray(2.0 * PX4_RADIUS_M * np.arcsin(np.sqrt(np.minimum(h, 1.0))), float)


def loop_step_m(speed_m_s: float) -> float:
    """How far the vehicle flies between two trigger checks."""
    return speed_m_s / LOOP_RATE_HZ


def station_step_m(air_base_m: float, speed_m_s: float) -> float:
    """The largest planned station spacing: a photo may fire half a loop step late."""
    return air_base_m - 0.5 * loop_step_m(speed_m_s)


def max_run_stations(spacing_m: float, speed_m_s: float) -> int:
    """Most stations in one armed run: the first photo fires up to one step late and each
    later one +- half a step, which must stay within DRIFT_SHARE of the half spacing."""
    step = loop_step_m(speed_m_s)
    room = DRIFT_SHARE * 0.5 * spacing_m - step
    return max(1, math.floor(room / (0.5 * step)) + 1) if room > 0 else 1


def split_for_trigger(segments: Iterable[Segment], speed_m_s: float) -> tuple[Segment, ...]:
    """Each run cut into consecutive runs of at most :func:`max_run_stations` stations."""
    return tuple(
        part for seg in segments for part in split_run(seg, max_run_stations(seg.spacing_m, speed_m_s))
    )


def commanded_distance_m(spacing_m: float, ratio: float, speed_m_s: float) -> float:
    """DO_SET_CAM_TRIGG_DIST distance for a run: the spacing less half a loop step, in the
    autopilot's measure (``ratio`` = its distance / the plan's)."""
    return (spacing_m - 0.5 * loop_step_m(speed_m_s)) * ratio


def distance_ratio(
    lat_deg: tuple[float, float], lon_deg: tuple[float, float], plan_distance_m: float, autopilot: Autopilot
) -> float:
    """The autopilot's distance over the plan's between two points of a run."""
    if plan_distance_m <= 0.0:
        return 1.0
    measured = float(
        autopilot_distance_m(
            lat_deg[0], lon_deg[0], lat_deg[1], lon_deg[1], autopilot, integer_positions=False
        )
    )
    return measured / plan_distance_m
