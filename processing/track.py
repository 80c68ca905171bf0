"""Frames from positions alone (camera events of a flight log, a simulated flight): nadir, the
image top along the track."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pyproj import Geod

from planner.camera import Camera, Orientation

from .frames import AltitudeReference, AttitudeSource, Frames

_GEOD = Geod(ellps="WGS84")

#: A frame whose incoming and outgoing steps turn by more than this is at a turn (a line's end).
TURN_DEG = 30.0


def track_heading_deg(lon_deg: np.ndarray, lat_deg: np.ndarray) -> np.ndarray:
    """True bearing of the track at each point, degrees 0-360 (clockwise from north).

    Central difference (previous to next point) on the WGS84 ellipsoid, one-sided at the
    track's ends. At a turn (the steps in and out differ by more than :data:`TURN_DEG`: the
    first or last frame of a line) the shorter step's bearing: the neighbour on the frame's
    own line is the one a trigger distance away, the other is across the turn. A point that
    has not moved from either neighbour gets 0.
    """
    n = lon_deg.shape[0]
    if n < 2:
        return np.zeros(n)
    prev = np.r_[0, np.arange(n - 1)]
    nxt = np.r_[np.arange(1, n), n - 1]
    azimuth, _, distance = _GEOD.inv(lon_deg[prev], lat_deg[prev], lon_deg[nxt], lat_deg[nxt])
    heading = np.where(np.asarray(distance) > 0.0, np.asarray(azimuth, float) % 360.0, 0.0)
    if n >= 3:
        step_az, _, step_len = _GEOD.inv(lon_deg[:-1], lat_deg[:-1], lon_deg[1:], lat_deg[1:])
        step_az = np.asarray(step_az, float) % 360.0
        step_len = np.asarray(step_len, float)
        az_in, az_out = step_az[:-1], step_az[1:]  # for points 1..n-2
        len_in, len_out = step_len[:-1], step_len[1:]
        turn = np.abs((az_out - az_in + 180.0) % 360.0 - 180.0)
        at_turn = (turn > TURN_DEG) & (len_in > 0) & (len_out > 0)
        shorter = np.where(len_in <= len_out, az_in, az_out)
        heading[1:-1] = np.where(at_turn, shorter, heading[1:-1])
    return np.asarray(heading, dtype=np.float64)


def frames_from_track(
    *,
    name: Sequence[str],
    lon_deg: np.ndarray,
    lat_deg: np.ndarray,
    alt_m: np.ndarray,
    alt_reference: AltitudeReference,
    camera: Camera,
    time_utc_s: np.ndarray | None = None,
    exposure_s: np.ndarray | None = None,
    orientation: Orientation = Orientation.LANDSCAPE,
) -> Frames:
    """Frames from positions alone (camera events of a flight log, a simulated flight): nadir,
    the image top along the track (:func:`track_heading_deg`; landscape: forward, portrait:
    90 deg to the left), :attr:`AttitudeSource.ASSUMED_NADIR`. Rows are taken in the order
    given, which must be the capture order."""
    lon = np.asarray(lon_deg, dtype=np.float64)
    lat = np.asarray(lat_deg, dtype=np.float64)
    heading = track_heading_deg(lon, lat)
    yaw = heading if orientation is Orientation.LANDSCAPE else (heading - 90.0) % 360.0
    return Frames(
        name=tuple(name),
        lon_deg=lon,
        lat_deg=lat,
        alt_m=np.asarray(alt_m, dtype=np.float64),
        alt_reference=alt_reference,
        yaw_deg=yaw,
        pitch_deg=np.zeros_like(yaw),
        roll_deg=np.zeros_like(yaw),
        attitude_source=AttitudeSource.ASSUMED_NADIR,
        camera=camera,
        time_utc_s=None if time_utc_s is None else np.asarray(time_utc_s, dtype=np.float64),
        exposure_s=None if exposure_s is None else np.asarray(exposure_s, dtype=np.float64),
    )
