"""Camera events as they arrive on a live link: which are new, when and where each photo was taken.

:class:`CameraFeed` takes the decoded records (:mod:`acquisition.mavlink_messages`) of the
vehicle :class:`acquisition.flight_recorder.FlightRecorder` follows and gives back one
:class:`~acquisition.monitor_state.CameraEvent` per photo (its ``station`` left None):

- CAMERA_FEEDBACK (ArduPilot; ``img_idx`` is the sequence number since ``completed_captures``
  stays 0 without a feedback pin, REFERENCES.md section 3) and CAMERA_IMAGE_CAPTURED (PX4,
  MAVLink cameras; failed captures, ``capture_result`` 0, are counted and left out). A message
  received again (same message type, camera and image index, same event time: a duplicate on
  the link, or the same event through two paths) gives no event. The same index with another
  time is a new event (the counter restarted: a reboot) and is logged as such.
- CAMERA_TRIGGER (only a time and a sequence number) is used only when a vehicle sends no
  CAMERA_FEEDBACK or CAMERA_IMAGE_CAPTURED: it is held for :data:`TRIGGER_HOLD_S` waiting for
  its CAMERA_IMAGE_CAPTURED (PX4 sends both), then given the last GLOBAL_POSITION_INT as its
  position (source ``CAMERA_TRIGGER+GLOBAL_POSITION_INT``).

Event times (``time_utc_s``, POSIX seconds, UTC) come from the vehicle: CAMERA_FEEDBACK and
CAMERA_TRIGGER ``time_usec`` as :func:`acquisition.mavlink_messages.event_time_utc_s` reads it,
boot times mapped to UTC through the last SYSTEM_TIME; CAMERA_IMAGE_CAPTURED ``time_utc``, else
``time_boot_ms`` the same way. An event with no usable time has ``time_utc_s`` None.

The vehicle's own image index counts the photos taken, those whose event was lost on the link
included (:meth:`CameraFeed.photo_counts`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

from . import mavlink_messages as mm
from .attitude import roll_pitch_yaw_deg_from_quaternion
from .clock import WALL_CLOCK, Clock
from .monitor_state import CameraEvent

log = logging.getLogger(__name__)

#: How long (wall seconds) a CAMERA_TRIGGER waits for its CAMERA_IMAGE_CAPTURED.
TRIGGER_HOLD_S = 2.0


_Where = tuple[float | None, float | None, float | None, float | None]
_NOWHERE: _Where = (None, None, None, None)


def _event(time_utc_s: float | None, seq: int, where: _Where, rpy: _Where, source: str) -> CameraEvent:
    """A camera event at ``where`` (lat_deg, lon_deg, alt_amsl_m, alt_rel_home_m) with the
    attitude ``rpy`` (roll_deg, pitch_deg, yaw_deg; the fourth value unused)."""
    lat, lon, amsl, rel = where
    roll, pitch, yaw, _ = rpy
    return CameraEvent(
        time_utc_s=time_utc_s,
        seq=seq,
        lat_deg=lat,
        lon_deg=lon,
        alt_amsl_m=amsl,
        alt_rel_home_m=rel,
        roll_deg=roll,
        pitch_deg=pitch,
        yaw_deg=yaw,
        source=source,
    )


def _where(m: mm.CameraFeedback | mm.CameraImageCaptured | mm.GlobalPosition) -> _Where:
    return m.lat_deg, m.lon_deg, m.alt_amsl_m, m.alt_rel_home_m


class CameraFeed:
    """New camera events from the vehicle's records (module docstring). Not thread-safe.

    ``on_late_join(why)`` is called once the image indices show that photos were taken before
    the recording started."""

    def __init__(self, on_late_join: Callable[[str], None], clock: Clock = WALL_CLOCK) -> None:
        self.clock = clock
        self._on_late_join = on_late_join
        self._seen: dict[tuple[str, int, int], float] = {}  # (type, camera, index) -> event time
        self._pending: dict[int, tuple[float, mm.CameraTrigger]] = {}  # seq -> (wall s, trigger)
        self._positional = False  # the vehicle sends events with a position
        self._boot_offset_s: float | None = None  # vehicle UTC minus boot time, s
        self._last_boot_s: float | None = None
        self.last_position: mm.GlobalPosition | None = None
        self._index_first: int | None = None
        self._index_max: int | None = None
        self._index_origin = 1
        self._indices: set[int] = set()
        self.indexed_events = 0
        self.duplicate_events = 0
        self.failed_captures = 0
        #: False until the vehicle was seen disarmed (a first index past the first photo is
        #: then a late join only while it has never been seen on the ground).
        self.seen_disarmed = False

    # --- the vehicle's clock and position ------------------------------------------------------

    def on_system_time(self, m: mm.SystemTime) -> None:
        self._last_boot_s = m.time_boot_s
        if m.time_utc_s is not None:
            self._boot_offset_s = m.time_utc_s - m.time_boot_s

    def on_position(self, m: mm.GlobalPosition) -> None:
        self._last_boot_s = m.time_boot_s
        if m.has_position:
            self.last_position = m

    def _vehicle_utc_s(self, boot_s: float) -> float | None:
        return None if self._boot_offset_s is None else boot_s + self._boot_offset_s

    def _now_utc_s(self) -> float | None:
        """The vehicle's UTC at its last message that carried its boot time."""
        return None if self._last_boot_s is None else self._vehicle_utc_s(self._last_boot_s)

    def _event_utc_s(self, time_usec: int) -> float | None:
        now = self._now_utc_s()
        boot = self._vehicle_utc_s(time_usec / 1e6)
        t = float(
            mm.event_time_utc_s(
                time_usec, math.nan if boot is None else boot, math.nan if now is None else now
            ).utc_s
        )
        return None if math.isnan(t) else t

    # --- events --------------------------------------------------------------------------------

    def _is_duplicate(self, key: tuple[str, int, int], stamp: float) -> bool:
        seen = self._seen.get(key)
        if seen is not None and seen == stamp:
            self.duplicate_events += 1
            return True
        if seen is not None:
            log.warning(
                "%s index %d came again with another time: the camera counter restarted "
                "(a reboot?); recorded as a new photo",
                key[0],
                key[2],
            )
        self._seen[key] = stamp
        return False

    def on_feedback(self, m: mm.CameraFeedback) -> CameraEvent | None:
        self._positional = True
        self._pending.clear()
        if self._is_duplicate(("CAMERA_FEEDBACK", m.camera_index, m.image_index), m.time_usec):
            return None
        self._note_index(m.image_index, 1)
        rpy = (m.roll_deg, m.pitch_deg, m.yaw_deg, None)
        return _event(self._event_utc_s(m.time_usec), m.image_index, _where(m), rpy, "CAMERA_FEEDBACK")

    def on_image_captured(
        self, m: mm.CameraImageCaptured, *, component: int, on_autopilot_clock: bool
    ) -> CameraEvent | None:
        """``component``: the sender's component id (a camera's own); ``on_autopilot_clock``:
        its time_boot_ms is the autopilot's (sent by the autopilot)."""
        self._positional = True
        self._pending.clear()
        if not m.captured:
            self.failed_captures += 1
            log.warning("the camera reports capture %d failed", m.image_index)
            return None
        stamp = m.time_utc_s if m.time_utc_s is not None else m.time_boot_s
        if self._is_duplicate(("CAMERA_IMAGE_CAPTURED", component, m.image_index), stamp):
            return None
        if m.time_utc_s is not None:
            t: float | None = m.time_utc_s
        elif on_autopilot_clock:
            t = self._vehicle_utc_s(m.time_boot_s)
        else:  # a camera's own boot clock: the vehicle's time now is the best there is
            t = self._now_utc_s()
        roll, pitch, yaw = roll_pitch_yaw_deg_from_quaternion(*m.q)
        self._note_index(m.image_index, 0)
        rpy = (float(roll), float(pitch), float(yaw), None)
        return _event(t, m.image_index, _where(m), rpy, "CAMERA_IMAGE_CAPTURED")

    def on_trigger(self, m: mm.CameraTrigger) -> None:
        if not self._positional:
            self._pending.setdefault(m.seq, (self.clock.monotonic(), m))

    def release(self, *, force: bool) -> list[CameraEvent]:
        """The CAMERA_TRIGGERs held for :data:`TRIGGER_HOLD_S` (all of them with ``force``)."""
        out: list[CameraEvent] = []
        if not self._pending:
            return out
        now = self.clock.monotonic()
        for seq in sorted(self._pending):
            held_since, m = self._pending[seq]
            if not force and now - held_since < TRIGGER_HOLD_S:
                continue
            del self._pending[seq]
            if self._is_duplicate(("CAMERA_TRIGGER", 0, seq), m.time_usec):
                continue
            pos = self.last_position
            where = _NOWHERE if pos is None else _where(pos)
            source = "CAMERA_TRIGGER" if pos is None else "CAMERA_TRIGGER+GLOBAL_POSITION_INT"
            out.append(_event(self._event_utc_s(m.time_usec), seq, where, _NOWHERE, source))
        return out

    # --- the vehicle's image index -------------------------------------------------------------

    def _note_index(self, index: int, origin: int) -> None:
        """A camera event with the vehicle's image index ``index`` (first photo: ``origin``)."""
        if self._index_first is None or index < self._index_first:
            if self._index_first is None:
                self._index_origin = origin
                if index > origin and not self.seen_disarmed:
                    self._on_late_join(
                        f"the first camera event has image index {index} (the first photo is {origin})"
                    )
            self._index_first = index
        self._index_max = index if self._index_max is None else max(self._index_max, index)
        self._indices.add(index)
        self.indexed_events += 1

    def photo_counts(self, events: int, joined_late: bool) -> tuple[int, int, int]:
        """(photos taken, indices never received, photos before the recording) after ``events``
        distinct events, from the vehicle's image index."""
        photos, unseen, before = events, 0, 0
        if self._index_first is not None and self._index_max is not None:
            span = self._index_max - self._index_first + 1
            unseen = max(span - len(self._indices), 0)
            before = self._index_first - self._index_origin if joined_late else 0
            # events without an index (CAMERA_TRIGGER alone) add to what the indices say
            photos = span + before + (events - self.indexed_events)
        return max(photos, events), unseen, max(before, 0)
