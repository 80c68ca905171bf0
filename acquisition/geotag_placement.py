"""Placing geotagged frames: each timed frame at its event's time (matched) or its corrected
capture time, position and attitude interpolated on the track or taken from the event (RTK event
files), with its accuracy; and the reasons the others cannot be placed."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .attitude import CameraMount, camera_attitude_deg, heading_only_deg
from .geotag_frames import Frame
from .geotag_offset import offset_cost_warning, track_speeds_m_s
from .geotag_results import FrameResult, FrameStatus, GeotagOptions, OffsetSource, PositionSource
from .interpolation import InterpolatedPose, PoseInterpolation, interpolate_poses
from .matching import Matching
from .telemetry.model import AttitudeTrack, CameraEvents, FlightLog, VehicleType

F64 = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class Clock:
    """The camera clock against UTC: the offset (camera minus UTC), where it comes from, and the
    alignment with the camera events when there was one."""

    offset_s: float
    source: OffsetSource
    matching: Matching | None = None
    drift_ppm: float = 0.0
    residual_mad_s: float | None = None
    tolerance_s: float | None = None
    unmatched_events: tuple[tuple[int, int], ...] = ()

    def to_utc(self, t: F64) -> F64:
        if self.matching is not None:
            return self.matching.frame_time_to_utc(t)
        return np.asarray(t - self.offset_s, float)


def _accuracy(options: GeotagOptions, speed_m_s: float, timing_s: float) -> tuple[float, float]:
    xy = math.hypot(options.xy_accuracy_m, speed_m_s * timing_s)
    return xy, options.z_accuracy_m


def resolve_mount(mount: CameraMount, vehicle_type: VehicleType | None) -> tuple[CameraMount, str]:
    """The camera's mount (``auto`` resolved by what the log says the vehicle is: see
    :class:`CameraMount`) and where that choice came from, for the attitude sentence."""
    if mount is not CameraMount.AUTO:
        return mount, f"--camera-mount {mount}"
    if vehicle_type is None:
        return CameraMount.GIMBAL, "the log does not say what the vehicle is: a gimbal assumed"
    fixed = vehicle_type in (VehicleType.FIXED_WING, VehicleType.VTOL)
    return CameraMount.FIXED if fixed else CameraMount.GIMBAL, f"the log says a {vehicle_type}"


def camera_attitude_track(
    log: FlightLog, mount: CameraMount
) -> tuple[AttitudeTrack | None, CameraMount, str | None]:
    """The attitude track the camera's attitude is taken from, the mount used (``auto``
    resolved), and a sentence saying which attitude and why when the log has no gimbal angles:
    the vehicle's (a camera fixed to the airframe), or the vehicle's heading alone (a camera on a
    stabilised gimbal looks straight down whatever the vehicle's pitch and roll: writing those as
    the camera's would tilt a nadir block)."""
    mount, why = resolve_mount(mount, log.vehicle_type)
    vehicle = log.attitudes
    if vehicle is None or len(vehicle) == 0:
        return vehicle, mount, None
    if log.gimbal is not None and len(log.gimbal) > 0:
        return vehicle, mount, None
    if mount is CameraMount.FIXED:
        return (
            vehicle,
            mount,
            (
                f"attitude: the vehicle's, the camera fixed to the airframe (the log has no gimbal angles; "
                f"{why}); give --camera-mount gimbal for a camera on a stabilised gimbal"
            ),
        )
    yaw, pitch, roll = heading_only_deg(vehicle.yaw_deg)
    heading = AttitudeTrack(
        time_utc_s=vehicle.time_utc_s, roll_deg=roll, pitch_deg=pitch, yaw_deg=yaw, source=vehicle.source
    )
    return (
        heading,
        mount,
        (
            "attitude: the camera looking straight down on a stabilised gimbal, heading the vehicle's "
            f"(the log has no gimbal angles; {why}); give --camera-mount fixed for a camera fixed to "
            "the airframe"
        ),
    )


def _event_pose(events: CameraEvents, j: int, mount: CameraMount) -> InterpolatedPose | None:
    if events.lat_deg is None or events.lon_deg is None:
        return None

    def col(c: F64 | None) -> float | None:
        return None if c is None else float(c[j])

    yaw, pitch, roll = col(events.yaw_deg), col(events.pitch_deg), col(events.roll_deg)
    if yaw is not None and pitch is not None and roll is not None:
        # The event's attitude is the vehicle's (DataFlash CAM R, P, Y; MRK has none).
        vehicle = ([yaw], [pitch], [roll]) if mount is CameraMount.FIXED else heading_only_deg([yaw])
        cy, cp, cr = camera_attitude_deg(vehicle)
        yaw, pitch, roll = float(cy[0]), float(cp[0]), float(cr[0])
    else:
        yaw = pitch = roll = None
    return InterpolatedPose(
        time_utc_s=float(events.time_utc_s[j]),
        lat_deg=float(events.lat_deg[j]),
        lon_deg=float(events.lon_deg[j]),
        alt_amsl_m=col(events.alt_amsl_m),
        alt_rel_home_m=col(events.alt_rel_home_m),
        yaw_deg=yaw,
        pitch_deg=pitch,
        roll_deg=roll,
        position_gap_s=0.0,
        attitude_gap_s=None if yaw is None else 0.0,
        speed_m_s=0.0,
    )


def place_frames(
    timed: Sequence[Frame],
    times: F64,
    names: dict[Path, str],
    clock: Clock,
    events: CameraEvents | None,
    log: FlightLog,
    options: GeotagOptions,
    warnings: list[str],
) -> tuple[dict[Path, FrameResult], PoseInterpolation | None]:
    """Each timed frame placed at its event's time (matched) or its corrected capture time:
    position and attitude interpolated on the track, or the event's own (RTK event files), with
    its accuracy; or the reason it cannot be placed."""
    matching = clock.matching
    event_of = matching.event_of_frame() if matching is not None else {}
    residual_of = (
        {int(fi): float(r) for (fi, _), r in zip(matching.pairs, matching.residuals_s, strict=True)}
        if matching is not None
        else {}
    )
    utc_of_frame = clock.to_utc(times) if times.size else np.zeros(0)
    place_times: list[float] = []
    for k in range(len(timed)):
        if k in event_of and events is not None:
            place_times.append(float(events.time_utc_s[event_of[k]]))
        else:
            place_times.append(float(utc_of_frame[k]))

    attitudes, mount, attitude_note = camera_attitude_track(log, options.camera_mount)
    if attitude_note is not None and timed:
        warnings.append(attitude_note)
    interpolation: PoseInterpolation | None = None
    if log.positions is not None and len(log.positions) > 0 and place_times:
        interpolation = interpolate_poses(
            place_times,
            positions=log.positions,
            attitudes=attitudes,
            gimbal=log.gimbal,
            gimbal_mode=options.gimbal_mode,
            max_gap_s=options.max_gap_s,
        )
    prefer_event = options.position_source is PositionSource.EVENT or (
        options.position_source is PositionSource.AUTO and log.format == "mrk"
    )
    timing_scatter = clock.residual_mad_s if clock.residual_mad_s is not None else 0.0

    if events is None and log.positions is not None and len(log.positions) > 1:
        speeds = [] if interpolation is None else [p.speed_m_s for p in interpolation.poses if p is not None]
        if not speeds:  # no frame inside the log: the flight's own ground speed
            speeds = track_speeds_m_s(log.positions)
        cost = offset_cost_warning(clock.offset_s, clock.source, speeds)
        if cost is not None:
            warnings.append(cost)

    results: dict[Path, FrameResult] = {}
    for k, fr in enumerate(timed):
        assert fr.tags is not None and fr.tags.capture_time_s is not None
        base: dict[str, Any] = {
            "name": names[fr.path],
            "source_path": str(fr.path),
            "capture_time_s": fr.tags.capture_time_s,
            "time_utc_s": place_times[k],
        }
        pose: InterpolatedPose | None = None
        reason: str | None = None
        source = "track"
        j = event_of.get(k)
        if j is not None and events is not None:
            status = FrameStatus.MATCHED
            base["event_index"] = j
            base["event_seq"] = int(events.seq[j])
            base["time_residual_s"] = residual_of.get(k)
            if options.position_source is not PositionSource.TRACK:
                event_pose = _event_pose(events, j, mount)
            else:
                event_pose = None
            if prefer_event and event_pose is not None:
                pose, source = event_pose, "event"
            elif interpolation is not None and interpolation.poses[k] is not None:
                pose = interpolation.poses[k]
            elif event_pose is not None:
                pose, source = event_pose, "event"
            else:
                reason = interpolation.reasons[k] if interpolation is not None else "the log has no positions"
            if pose is None:
                status = FrameStatus.NO_POSITION
        else:
            extra = events is not None
            status = FrameStatus.EXTRA_BY_TIME if extra else FrameStatus.BY_TIME
            if extra and not options.place_extra_by_time:
                pose, reason = None, "no camera event matches this frame"
            elif interpolation is not None:
                pose, reason = interpolation.poses[k], interpolation.reasons[k]
            else:
                reason = "the log has no positions to place a frame by time"
            if pose is None:
                status = FrameStatus.EXTRA if extra else FrameStatus.NO_POSITION
                if extra:
                    reason = f"no camera event matches this frame; {reason}" if reason else "no camera event"
        if pose is not None:
            timing = 0.0 if status is FrameStatus.MATCHED else timing_scatter
            xy_acc, z_acc = _accuracy(options, pose.speed_m_s, timing)
            if status is FrameStatus.EXTRA_BY_TIME:
                reason = (
                    "no camera event matches this frame: placed at its capture time corrected by the offset"
                )
            results[fr.path] = FrameResult(
                **base,
                status=status,
                message=reason,
                lat_deg=pose.lat_deg,
                lon_deg=pose.lon_deg,
                alt_amsl_m=pose.alt_amsl_m,
                alt_rel_home_m=pose.alt_rel_home_m,
                yaw_deg=pose.yaw_deg,
                pitch_deg=pose.pitch_deg,
                roll_deg=pose.roll_deg,
                xy_accuracy_m=xy_acc,
                z_accuracy_m=z_acc,
                interpolation_gap_s=pose.position_gap_s,
                position_source=source,
            )
        else:
            results[fr.path] = FrameResult(**base, status=status, message=reason)
    return results, interpolation


def not_placed(
    frames: Sequence[Frame], timed: Sequence[Frame], names: dict[Path, str], results: dict[Path, FrameResult]
) -> list[FrameResult]:
    """Every frame's result, timed frames first: the unreadable, those without a capture time,
    and names that still collide in the outputs, with the reason."""
    name_count: dict[str, int] = {}
    for fr in frames:
        name_count[names[fr.path].lower()] = name_count.get(names[fr.path].lower(), 0) + 1
    for fr in frames:
        if fr.tags is None:
            results[fr.path] = FrameResult(
                name=names[fr.path],
                source_path=str(fr.path),
                status=FrameStatus.UNREADABLE,
                message=fr.error,
            )
        elif fr.tags.capture_time_s is None:
            results[fr.path] = FrameResult(
                name=names[fr.path],
                source_path=str(fr.path),
                status=FrameStatus.NO_CAPTURE_TIME,
                message="no capture time (DateTimeOriginal) in the file: it cannot be matched or placed",
            )
        elif name_count[names[fr.path].lower()] > 1:
            old = results[fr.path]
            results[fr.path] = FrameResult(
                **{
                    **old.__dict__,
                    "status": FrameStatus.DUPLICATE_NAME,
                    "message": f"another image also comes out as {names[fr.path]} (names must be "
                    f"unique in the outputs); rename one of them",
                    "lat_deg": None,
                    "lon_deg": None,
                    "alt_amsl_m": None,
                    "alt_rel_home_m": None,
                    "yaw_deg": None,
                    "pitch_deg": None,
                    "roll_deg": None,
                }
            )
    timed_paths = {fr.path for fr in timed}
    return [results[fr.path] for fr in timed] + [
        results[fr.path] for fr in frames if fr.path not in timed_paths
    ]
