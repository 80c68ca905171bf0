"""The camera clock offset when frames are not matched to events, and the crew's sync points.

A sync point (:class:`SyncPoint`, ``--sync``/``--sync-position``) is a frame whose UTC time or
position the crew knows: it narrows the offsets the matcher may choose
(:func:`sync_windows_with_events`) or, without camera events, gives the offset itself
(:func:`sync_offset_by_track`), refused when the flight passes the position more than once or the
points disagree. :func:`offset_from_exif_gps` takes the offset from frames that carry their own GPS
time; :func:`offset_cost_warning` says what a wrong offset costs in metres along the track.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.errors import InputError
from planner.stats import median

from .errors import GeotagError
from .exif import ImageTags
from .geotag_results import OffsetSource
from .interpolation import interpolate_poses, iso_utc
from .local_plane import LocalPlane, segment_lengths_m
from .sync_points import SYNC_POSITION_MAX_M, SYNC_POSITION_RADIUS_M, SYNC_TIME_ACCURACY_S, SyncPoint
from .telemetry.model import CameraEvents, FlightLog, PositionTrack

F64 = NDArray[np.float64]


def offset_from_exif_gps(tags: Sequence[ImageTags]) -> float | None:
    """Camera clock minus UTC from frames that carry their own GPS time stamp (median)."""
    diffs = [
        t.capture_time_s - t.gps_time_utc_s
        for t in tags
        if t.capture_time_s is not None and t.gps_time_utc_s is not None
    ]
    return float(median(diffs)) if diffs else None


@dataclass(frozen=True)
class _Pass:
    time_utc_s: float
    distance_m: float
    speed_m_s: float


def _passes(times_s: F64, lat_deg: F64, lon_deg: F64, point: SyncPoint) -> list[_Pass]:
    """Where a track (or a sequence of event positions) comes closest to a sync position: one
    entry per pass (local minimum of the distance), nearest first."""
    assert point.lat_deg is not None and point.lon_deg is not None
    order = np.argsort(times_s, kind="stable")
    t, lat, lon = times_s[order], lat_deg[order], lon_deg[order]
    # Metres on the plane tangent at the sync position: exact at it, where distances matter.
    x, y = LocalPlane.at(point.lon_deg, point.lat_deg).to_xy(lon, lat)
    px = py = 0.0
    if t.size == 1:
        return [_Pass(float(t[0]), float(np.hypot(x[0] - px, y[0] - py)), 0.0)]
    dx, dy, dt = np.diff(x), np.diff(y), np.diff(t)
    length2 = dx * dx + dy * dy
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.clip(np.where(length2 > 0, ((px - x[:-1]) * dx + (py - y[:-1]) * dy) / length2, 0.0), 0.0, 1.0)
        speed = np.where(dt > 0, np.sqrt(length2) / dt, 0.0)
    d = np.hypot(x[:-1] + u * dx - px, y[:-1] + u * dy - py)
    tc = t[:-1] + u * dt
    minima = [
        k
        for k in range(d.size)
        if (k == 0 or d[k] <= d[k - 1]) and (k == d.size - 1 or d[k] < d[k + 1]) and np.isfinite(d[k])
    ]
    passes: list[_Pass] = []
    for k in sorted(minima, key=lambda k: float(d[k])):
        if all(abs(float(tc[k]) - p.time_utc_s) > 5.0 for p in passes):  # one pass, several minima
            passes.append(_Pass(float(tc[k]), float(d[k]), float(speed[k])))
    return passes


def _near_passes(passes: list[_Pass], point: SyncPoint) -> list[_Pass]:
    """The passes a sync position may belong to: within SYNC_POSITION_RADIUS_M of the nearest."""
    if not passes or passes[0].distance_m > SYNC_POSITION_MAX_M:
        nearest = f"{passes[0].distance_m:.0f} m" if passes else "nowhere"
        raise InputError(
            f"sync position {point.lat_deg}, {point.lon_deg} of {point.frame} is not on the flight "
            f"(the nearest pass is {nearest} away, more than {SYNC_POSITION_MAX_M:g} m): check the "
            f"position and the frame"
        )
    return [p for p in passes if p.distance_m <= passes[0].distance_m + SYNC_POSITION_RADIUS_M]


def track_speeds_m_s(positions: PositionTrack) -> list[float]:
    """Ground speed between consecutive samples of a track, m/s."""
    order = np.argsort(positions.time_utc_s, kind="stable")
    t, lat, lon = positions.time_utc_s[order], positions.lat_deg[order], positions.lon_deg[order]
    length = segment_lengths_m(lat, lon)
    dt = np.diff(t)
    ok = (dt > 0) & np.isfinite(length)
    return (length[ok] / dt[ok]).tolist()


def offset_cost_warning(offset: float, source: OffsetSource, speeds_m_s: Sequence[float]) -> str | None:
    """What a wrong camera clock offset costs when frames are placed by time: metres per second
    of error at the flight's ground speed."""
    moving = [s for s in speeds_m_s if s > 0.5]
    if not moving:
        return None
    speed = float(median(moving))
    how = {
        OffsetSource.GIVEN: "given (--offset-s)",
        OffsetSource.EXIF_GPS: "from the frames' own GPS time stamps",
        OffsetSource.SYNC: "from the sync points",
        OffsetSource.IMAGES: (
            "estimated from the frames' own motion against the track (its uncertainty is in the report)"
        ),
        OffsetSource.ASSUMED_ZERO: "ASSUMED to be 0 s (no camera events, no --offset-s, no sync point)",
    }.get(source, str(source))
    return (
        f"frames are placed by their capture time: the camera clock offset {offset:+.3f} s is "
        f"{how}; every second it is wrong moves each frame about {speed:.1f} m along the track "
        f"(median ground speed {speed:.1f} m/s), and a wrong time zone by hours puts them "
        f"outside the log. Give a sync point (--sync FRAME=TIME or --sync-position "
        f"FRAME=LAT,LON) to check it"
    )


def sync_windows_with_events(
    sync_capture: Sequence[tuple[SyncPoint, float]], events: CameraEvents, log: FlightLog
) -> list[list[tuple[float, float]]]:
    """Per sync point, the camera clock offsets it allows, as (centre, half width) windows: a
    known time allows offsets within SYNC_TIME_ACCURACY_S of capture minus that time; a known
    position allows the offsets that put the frame on one of the events taken there."""
    windows: list[list[tuple[float, float]]] = []
    steps = np.diff(np.sort(events.time_utc_s))
    half_step = 0.5 * float(median(steps)) if steps.size else 1.0
    for point, capture_s in sync_capture:
        if point.time_utc_s is not None:
            windows.append([(capture_s - point.time_utc_s, SYNC_TIME_ACCURACY_S)])
            continue
        if events.lat_deg is not None and events.lon_deg is not None:
            lat, lon = events.lat_deg, events.lon_deg
        elif log.positions is not None and len(log.positions) > 0:
            lat, lon = _track_at(log, events.time_utc_s)
        else:
            raise InputError(f"sync position for {point.frame}: the log has no positions to compare it with")
        near = _near_passes(_event_points(events.time_utc_s, lat, lon, point), point)
        windows.append([(capture_s - p.time_utc_s, half_step) for p in near])
    return windows


def _event_points(times_s: F64, lat_deg: F64, lon_deg: F64, point: SyncPoint) -> list[_Pass]:
    """Each event as a 'pass' at its own distance from the point, nearest first."""
    assert point.lat_deg is not None and point.lon_deg is not None
    x, y = LocalPlane.at(point.lon_deg, point.lat_deg).to_xy(lon_deg, lat_deg)
    d = np.hypot(x, y)
    return [_Pass(float(times_s[k]), float(d[k]), 0.0) for k in np.argsort(d) if np.isfinite(d[k])]


def _track_at(log: FlightLog, times_s: F64) -> tuple[F64, F64]:
    assert log.positions is not None
    interpolation = interpolate_poses(times_s, positions=log.positions, max_gap_s=1e9)
    lat = np.array([np.nan if p is None else p.lat_deg for p in interpolation.poses])
    lon = np.array([np.nan if p is None else p.lon_deg for p in interpolation.poses])
    return lat, lon


def sync_offset_by_track(sync_capture: Sequence[tuple[SyncPoint, float]], log: FlightLog) -> float | None:
    """The camera clock offset from sync points alone (no camera events): the median of the
    offsets they give, after checking that they agree within their accuracies. A sync position
    gives the time the track passes it; a track that passes it more than once is ambiguous."""
    if not sync_capture:
        return None
    estimates: list[tuple[float, float, str]] = []  # (offset, accuracy s, what)
    for point, capture_s in sync_capture:
        if point.time_utc_s is not None:
            estimates.append((capture_s - point.time_utc_s, SYNC_TIME_ACCURACY_S, f"{point.frame} time"))
            continue
        if log.positions is None or len(log.positions) < 2:
            raise InputError(f"sync position for {point.frame}: the log has no track to compare it with")
        near = _near_passes(
            _passes(log.positions.time_utc_s, log.positions.lat_deg, log.positions.lon_deg, point), point
        )
        if len(near) > 1:
            listed = ", ".join(f"{iso_utc(p.time_utc_s)} ({p.distance_m:.0f} m)" for p in near[:5])
            raise GeotagError(
                f"nothing written: the flight passes the sync position of {point.frame} "
                f"{len(near)} times ({listed}); the position does not say which pass took the "
                f"frame: give a sync time (--sync) or a position on a single pass"
            )
        speed = max(near[0].speed_m_s, 1.0)
        accuracy = (near[0].distance_m + SYNC_POSITION_RADIUS_M) / speed
        estimates.append((capture_s - near[0].time_utc_s, accuracy, f"{point.frame} position"))
    for a in estimates:
        for b in estimates:
            if abs(a[0] - b[0]) > a[1] + b[1]:
                raise InputError(
                    f"the sync points disagree: {a[2]} gives a camera clock offset of {a[0]:+.1f} s, "
                    f"{b[2]} {b[0]:+.1f} s; check them"
                )
    return float(median([e[0] for e in estimates]))
