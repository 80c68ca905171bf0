"""Camera triggering of the simulated vehicle, as AP_Camera and PX4 do it, and the events it sends.

DO_SET_CAM_TRIGG_DIST sets the distance and, with param3 = 1, takes one photo at once; distance
triggering takes a photo whenever the horizontal straight-line distance from the last photo's
position reaches the distance (AP_Camera), with the crossing solved exactly
(:func:`acquisition.mission_stations.distance_trigger_fractions`; ArduPilot checks at 50 Hz,
which adds up to speed / 50 m); distance 0 stops it. IMAGE_START_CAPTURE takes ``total`` photos
every ``interval`` seconds (1 and 0: one photo now); DO_SET_CAM_TRIGG_INTERVAL photographs every
``param1`` milliseconds; DO_DIGICAM_CONTROL with shoot = 1 takes one photo.

At every photo ArduPilot sends CAMERA_FEEDBACK, PX4 CAMERA_TRIGGER then CAMERA_IMAGE_CAPTURED
(:func:`photo_records`). CAMERA_FEEDBACK.time_usec is the photo's UTC time in microseconds since
the Unix epoch, as ArduPilot derives it from GPS time (AP_GPS::time_epoch_usec) when no feedback
pin is set.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from planner.mission import Autopilot, MavCmd

from .. import mavlink_messages as mm
from ..attitude import quat_from_euler_deg
from ..mission_stations import distance_trigger_fractions


@dataclass(frozen=True, kw_only=True)
class Shot:
    """One photo: truth and what the vehicle reported.

    ``time_s`` simulated seconds since boot; ``utc_s`` POSIX seconds; ``index`` the image
    index reported (ArduPilot img_idx from 1, PX4 image_index from 0); ``x_m``/``y_m`` east and
    north of home (true); ``lat_deg``/``lon_deg``/``alt_rel_home_m`` true position;
    ``reported_*`` the noisy position in the message; ``gimbal_pitch_deg`` the gimbal pitch
    commanded then (None: no gimbal command yet); ``mission_seq`` the current mission item.
    """

    time_s: float
    utc_s: float
    index: int
    x_m: float
    y_m: float
    lat_deg: float
    lon_deg: float
    alt_rel_home_m: float
    reported_lat_deg: float
    reported_lon_deg: float
    reported_alt_rel_home_m: float
    gimbal_pitch_deg: float | None
    mission_seq: int


@dataclass
class Gimbal:
    """The gimbal's commanded angles, degrees (pitch None: never commanded)."""

    pitch_deg: float | None = None
    yaw_deg: float = 0.0
    roll_deg: float = 0.0


@dataclass
class Camera:
    """The camera's triggering state. ``remaining`` photos of a timed capture (-1: until
    stopped); ``next_capture_s`` the simulated time of the next timed photo (inf: none)."""

    trigger_distance_m: float = 0.0
    last_xy: tuple[float, float] | None = None
    interval_s: float = 0.0
    remaining: int = 0
    next_capture_s: float = math.inf
    count: int = 0

    def schedule(self, now_s: float) -> None:
        """Set the time of the next timed photo after one taken at ``now_s``."""
        if self.remaining != 0 and self.interval_s > 0:
            self.next_capture_s = now_s + self.interval_s
        else:
            self.next_capture_s = math.inf

    def _stop_timed(self) -> None:
        self.remaining = 0
        self.next_capture_s = math.inf

    def command(self, command: int, p: list[float], now_s: float) -> bool:
        """Apply a camera DO command (params ``p``, None as 0) at ``now_s``; True when it takes
        a photo at once."""
        if command == MavCmd.DO_SET_CAM_TRIGG_DIST:
            self.trigger_distance_m = max(p[0], 0.0)
            return p[2] == 1
        if command == MavCmd.IMAGE_START_CAPTURE:
            interval, total = p[1], int(p[2])
            if interval <= 0 or total == 1:
                return True
            self.interval_s = interval
            self.remaining = total if total > 0 else -1
            if self.remaining > 0:
                self.remaining -= 1  # the first one is taken now
            self.schedule(now_s)
            return True
        if command == MavCmd.IMAGE_STOP_CAPTURE:
            self._stop_timed()
        elif command == MavCmd.DO_SET_CAM_TRIGG_INTERVAL:
            if p[0] > 0:
                self.interval_s = p[0] / 1000.0
                self.remaining = -1
                self.schedule(now_s)
            else:
                self._stop_timed()
        elif command == MavCmd.DO_DIGICAM_CONTROL:
            return p[4] == 1
        return False

    def timed_photo_taken(self, now_s: float) -> None:
        """A timed photo was taken at ``now_s``: count it and schedule the next."""
        if self.remaining > 0:
            self.remaining -= 1
        self.schedule(now_s)

    def distance_crossings(self, start: tuple[float, float], end: tuple[float, float]) -> list[float]:
        """Fractions of the straight piece start->end at which distance triggering fires."""
        d = self.trigger_distance_m
        if d <= 0 or start == end:
            return []
        if self.last_xy is None:
            # AP_Camera: the first update only remembers where the vehicle is.
            self.last_xy = start
        return [min(s, 1.0) for s in distance_trigger_fractions(start, end, self.last_xy, d, tolerance=1e-12)]


def photo_records(
    autopilot: Autopilot,
    shot: Shot,
    attitude_deg: tuple[float, float, float],
    home_alt_amsl_m: float,
) -> list[mm.Record]:
    """What the vehicle sends for ``shot`` (attitude (roll, pitch, yaw) degrees then)."""
    roll, pitch, yaw = attitude_deg
    alt_amsl_m = shot.reported_alt_rel_home_m + home_alt_amsl_m
    time_usec = round(shot.utc_s * 1e6)
    where = {"lat_deg": shot.reported_lat_deg, "lon_deg": shot.reported_lon_deg, "alt_amsl_m": alt_amsl_m}
    where["alt_rel_home_m"] = shot.reported_alt_rel_home_m
    if autopilot is Autopilot.ARDUPILOT:
        where |= {"roll_deg": roll, "pitch_deg": pitch, "yaw_deg": yaw}
        return [mm.CameraFeedback(time_usec=time_usec, camera_index=0, image_index=shot.index, **where)]
    w, x, y, z = (float(v) for v in quat_from_euler_deg(yaw, pitch, roll)[0])
    return [
        mm.CameraTrigger(time_usec=time_usec, seq=shot.index),
        mm.CameraImageCaptured(
            time_boot_s=shot.time_s,
            time_utc_s=time_usec / 1e6,
            image_index=shot.index,
            captured=True,
            q=(w, x, y, z),
            **where,
        ),
    ]
