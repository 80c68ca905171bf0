"""Pose interpolation: where the camera was, and how it was pointed, at given UTC times.

:func:`interpolate_poses` places each time on the flight's position track (and attitude and
gimbal tracks when the log has them); :class:`PoseInterpolation` holds one
:class:`InterpolatedPose` per time, or the reason there is none.

Positions are interpolated linearly in a plane tangent at the track's median
(:class:`acquisition.local_plane.LocalPlane`: linearly in latitude and longitude, within 2 mm of
the geodesic between samples 100 m apart), altitudes linearly, attitude by spherical linear
interpolation of quaternions (:mod:`acquisition.attitude`); the camera attitude combines vehicle
and gimbal when the log has gimbal attitude. A time outside the track, or in a gap of the track
longer than ``max_gap_s``, is not guessed: it gets None and a reason, except within
:data:`EDGE_S` of a sample, where the neighbouring interval is extrapolated.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .attitude import GimbalMode, camera_quat, euler_deg_from_quat, quat_from_euler_deg, slerp
from .local_plane import LocalPlane, distances_m
from .telemetry.model import AttitudeTrack, PositionTrack

logger = logging.getLogger(__name__)

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


@dataclass(frozen=True, kw_only=True)
class InterpolatedPose:
    """Where the camera was at ``time_utc_s``.

    ``position_gap_s``: length of the track interval the position was interpolated over (0 when a
    sample falls on the time); ``attitude_gap_s`` likewise for attitude (None: no attitude).
    ``speed_m_s``: horizontal ground speed over that interval.
    """

    time_utc_s: float
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float | None
    alt_rel_home_m: float | None
    yaw_deg: float | None
    pitch_deg: float | None
    roll_deg: float | None
    position_gap_s: float
    attitude_gap_s: float | None
    speed_m_s: float


@dataclass(frozen=True, kw_only=True)
class PoseInterpolation:
    """One entry per requested time: the pose, or None with the reason in ``reasons``."""

    poses: tuple[InterpolatedPose | None, ...]
    reasons: tuple[str | None, ...]


def iso_utc(time_utc_s: float) -> str:
    """A UTC time (POSIX s) as ISO 8601 to the millisecond, ``Z`` suffix (for messages, reports)."""
    stamp = datetime.fromtimestamp(time_utc_s, tz=UTC).isoformat(timespec="milliseconds")
    return stamp.replace("+00:00", "Z")


#: How far beyond the ends of a track a time may be and still be placed (extrapolated), s.
EDGE_S = 0.2

#: A track sample this far from the track's median position is no position of this flight.
FAR_FROM_TRACK_M = 1_000_000.0


def _bracket(track_t: F64, t: F64, max_gap_s: float) -> tuple[I64, I64, F64, F64, list[str | None]]:
    """Per time: sample indices (a, b), weight of b (position = a + w (b - a)), the length of
    the interval used (0 on a sample) and a reason (None when usable).

    A time within 1 ms of a sample takes that sample's position (the interval reported is 0), with
    the usable interval after it (else before it) for the speed: a track sampled at the frames
    themselves still has speeds. A time beyond an end of the track, or in a
    gap longer than ``max_gap_s``, but within :data:`EDGE_S` of a sample is extrapolated from the
    interval on the sample's other side (a log starts a moment after the first trigger it
    records; a sparse track is sampled at the frames themselves). Anything else is refused.
    """
    n = track_t.size
    idx = np.searchsorted(track_t, t, side="right")
    lo = np.zeros(t.size, dtype=np.int64)
    hi = np.zeros(t.size, dtype=np.int64)
    weight = np.zeros(t.size)
    gap = np.zeros(t.size)
    reasons: list[str | None] = []
    start, end = float(track_t[0]), float(track_t[-1])

    def usable(a: int, b: int) -> bool:
        return 0 <= a < b < n and 0.0 < track_t[b] - track_t[a] <= max_gap_s

    for k, tk in enumerate(t):
        i = int(idx[k])  # track_t[i - 1] <= tk < track_t[i]
        pair: tuple[int, int] | None = None
        on = (
            i - 1
            if i >= 1 and tk - track_t[i - 1] <= 1e-3
            else i
            if i < n and track_t[i] - tk <= 1e-3
            else -1
        )
        if on >= 0:
            # On a sample: its position, and the interval after it (else before it) for the speed.
            lo[k] = hi[k] = on
            for a, b in ((on, on + 1), (on - 1, on)):
                if usable(a, b):
                    lo[k], hi[k] = a, b
                    weight[k] = (tk - track_t[a]) / (track_t[b] - track_t[a])
                    break
        elif usable(i - 1, i):
            pair = (i - 1, i)
        elif i >= 2 and tk - track_t[i - 1] <= EDGE_S and usable(i - 2, i - 1):
            pair = (i - 2, i - 1)
        elif track_t[min(i, n - 1)] - tk <= EDGE_S and usable(i, i + 1):
            pair = (i, i + 1)
        else:
            if tk < start or tk > end:
                side = "before" if tk < start else "after"
                distance = start - tk if tk < start else tk - end
                reasons.append(
                    f"time {iso_utc(float(tk))} is {distance:.1f} s {side} the log ({iso_utc(start)} "
                    f"to {iso_utc(end)}): is the log from this flight and this day, is the camera "
                    f"clock offset right (--offset-s)?"
                )
            else:
                span = float(track_t[i] - track_t[i - 1])
                reasons.append(
                    f"the log has a gap of {span:.1f} s around {iso_utc(float(tk))} (longer than "
                    f"{max_gap_s:g} s): not interpolated"
                )
            continue
        if pair is not None:
            a, b = pair
            lo[k], hi[k] = a, b
            gap[k] = track_t[b] - track_t[a]
            weight[k] = (tk - track_t[a]) / gap[k]
        reasons.append(None)
    return lo, hi, weight, gap, reasons


def interpolate_poses(
    times_utc_s: ArrayLike,
    *,
    positions: PositionTrack,
    attitudes: AttitudeTrack | None = None,
    gimbal: AttitudeTrack | None = None,
    gimbal_mode: GimbalMode = GimbalMode.EARTH,
    max_gap_s: float = 5.0,
) -> PoseInterpolation:
    """Position and camera attitude at each time (UTC, POSIX s).

    Position is interpolated linearly in the plane tangent at the track's median position
    between the two track samples around the time, altitudes linearly; attitude by slerp. The
    ground speed is the interval's length (at its own latitude) over its duration. A time outside
    the track, or inside a track gap longer than ``max_gap_s``, gets None and a reason. A missing
    or too sparse attitude (or gimbal, when the log has one) leaves the attitude None.
    """
    t = np.atleast_1d(np.asarray(times_utc_s, float))
    if len(positions) == 0:
        return PoseInterpolation(poses=(None,) * t.size, reasons=("the log has no positions",) * t.size)
    order = np.argsort(positions.time_utc_s, kind="stable")
    pt = positions.time_utc_s[order]
    lat = positions.lat_deg[order]
    lon = positions.lon_deg[order]
    # Samples that are no positions of this flight (not finite, a pole, or a "0, 0" position
    # before the GPS fix, half a world away from the rest) are left out.
    usable = np.isfinite(lat) & np.isfinite(lon) & (np.abs(lat) < 90.0)
    if not usable.any():
        return PoseInterpolation(
            poses=(None,) * t.size, reasons=("the log has no usable positions",) * t.size
        )
    plane = LocalPlane.centred_on(lon[usable], lat[usable])
    x, y = plane.to_xy(lon, lat)
    usable &= np.hypot(x, y) <= FAR_FROM_TRACK_M
    if not usable.all():
        logger.info("%d track samples are no positions of this flight: ignored", int(np.sum(~usable)))
        order = order[usable]
        pt, lat, lon, x, y = (a[usable] for a in (pt, lat, lon, x, y))
        if pt.size == 0:
            return PoseInterpolation(
                poses=(None,) * t.size, reasons=("the log has no usable positions",) * t.size
            )
    lo, hi, w, gap, reasons = _bracket(pt, t, max_gap_s)
    xi = x[lo] + w * (x[hi] - x[lo])
    yi = y[lo] + w * (y[hi] - y[lo])
    lon_i, lat_i = plane.to_lonlat(xi, yi)
    span = pt[hi] - pt[lo]
    length = distances_m(lat[lo], lon[lo], lat[hi], lon[hi])
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(span > 0, length / np.where(span > 0, span, 1.0), 0.0)

    def alt(column: F64 | None) -> F64 | None:
        if column is None:
            return None
        c = column[order]
        return np.asarray(c[lo] + w * (c[hi] - c[lo]), float)

    alt_amsl = alt(positions.alt_amsl_m)
    alt_rel = alt(positions.alt_rel_home_m)

    def attitude_at(track: AttitudeTrack | None) -> tuple[F64, F64, list[str | None]] | None:
        """Slerped quaternions at the times, the interval lengths, the reasons."""
        if track is None or len(track) == 0:
            return None
        a_order = np.argsort(track.time_utc_s, kind="stable")
        at = track.time_utc_s[a_order]
        q = quat_from_euler_deg(track.yaw_deg[a_order], track.pitch_deg[a_order], track.roll_deg[a_order])
        a_lo, a_hi, a_w, a_gap, a_reasons = _bracket(at, t, max_gap_s)
        return slerp(q[a_lo], q[a_hi], a_w), a_gap, a_reasons

    # Vehicle and gimbal stay quaternions until the camera's angles are taken: Euler angles of
    # a gimbal looking straight down are in gimbal lock, where yaw and roll are one turn.
    vehicle = attitude_at(attitudes)
    gimbal_at = attitude_at(gimbal)
    cam_yaw = cam_pitch = cam_roll = None
    if vehicle is not None:
        cam_yaw, cam_pitch, cam_roll = euler_deg_from_quat(
            camera_quat(vehicle[0], None if gimbal_at is None else gimbal_at[0], gimbal_mode)
        )

    poses: list[InterpolatedPose | None] = []
    for k in range(t.size):
        if reasons[k] is not None:
            poses.append(None)
            continue
        has_attitude = (
            cam_yaw is not None
            and vehicle is not None
            and vehicle[2][k] is None
            and (gimbal_at is None or gimbal_at[2][k] is None)
        )
        attitude_gap = None
        if has_attitude and vehicle is not None:
            attitude_gap = float(vehicle[1][k])
            if gimbal_at is not None:
                attitude_gap = max(attitude_gap, float(gimbal_at[1][k]))
        poses.append(
            InterpolatedPose(
                time_utc_s=float(t[k]),
                lat_deg=float(lat_i[k]),
                lon_deg=float(lon_i[k]),
                alt_amsl_m=None if alt_amsl is None else float(alt_amsl[k]),
                alt_rel_home_m=None if alt_rel is None else float(alt_rel[k]),
                yaw_deg=float(cam_yaw[k]) if has_attitude and cam_yaw is not None else None,
                pitch_deg=float(cam_pitch[k]) if has_attitude and cam_pitch is not None else None,
                roll_deg=float(cam_roll[k]) if has_attitude and cam_roll is not None else None,
                position_gap_s=float(gap[k]),
                attitude_gap_s=attitude_gap,
                speed_m_s=float(speed[k]),
            )
        )
    return PoseInterpolation(poses=tuple(poses), reasons=tuple(reasons))
