"""What the monitor knows while it records: the camera events and the :class:`MonitorState`."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .link_quality import LinkQuality


@dataclass(frozen=True, kw_only=True)
class CameraEvent:
    """One recorded camera event (a row of the trigger CSV). None where unknown."""

    time_utc_s: float | None
    seq: int
    lat_deg: float | None
    lon_deg: float | None
    alt_amsl_m: float | None
    alt_rel_home_m: float | None
    roll_deg: float | None
    pitch_deg: float | None
    yaw_deg: float | None
    source: str
    station: int | None = None  # the planned station it took (None: an extra photo)


@dataclass(frozen=True, kw_only=True)
class MonitorState:
    """What the monitor knows now. Counts since the recording started.

    - ``mission_seq`` / ``mission_total``: MISSION_CURRENT (the vehicle's numbering;
      ArduPilot counts home as item 0); ``mission_state``: its MISSION_STATE (None: not sent).
    - ``photos_taken``: photos the vehicle took during the recording, from its own image
      index (CAMERA_FEEDBACK img_idx, CAMERA_IMAGE_CAPTURED image_index): the highest index
      seen minus the first of the flight, plus one; ``events_received``: distinct camera
      events recorded; ``photos_unseen``: indices never received (events lost on the link);
      ``photos_before_join`` / ``joined_late``: the monitor started after the first photos
      (the vehicle was already armed, or its first index seen was past the first), so those
      photos have no event in this recording; ``photos_planned``: planned stations;
      ``stations_taken`` / ``stations_passed`` / ``missed_stations`` (station indices, flight
      order) / ``extra_photos``: see :mod:`acquisition.station_tracker`.
    - ``link``: quality per system; ``link_quality_pct``: all systems together (None before
      two messages); ``heartbeat_age_s``: wall seconds since the vehicle's last HEARTBEAT.
    - ``connected``, ``drops`` (times the link was lost), ``reconnects`` (times it came back),
      ``last_drop``: why it was last lost.
    - ``armed``, ``flight_over`` (disarmed after having flown: armed and more than
      :data:`acquisition.flight_recorder.FLYING_ALT_REL_HOME_M` above home, or EXTENDED_SYS_STATE in the air);
      ``landed_state``: the last EXTENDED_SYS_STATE landed state (1 on the ground, 2 in the
      air, 3 taking off, 4 landing; None: not sent).
    - ``missing_streams``: telemetry the monitor asked for and has not received (see
      :mod:`acquisition.monitor_link`); ``mission_changes``: times the vehicle's mission changed during the
      recording; ``stations_from``: what the stations come from ("plan": the plan folder;
      "vehicle": the mission the vehicle holds; None: no stations).
    """

    mission_seq: int | None = None
    mission_total: int | None = None
    mission_state: int | None = None
    photos_taken: int = 0
    events_received: int = 0
    photos_unseen: int = 0
    photos_before_join: int = 0
    joined_late: bool = False
    photos_planned: int = 0
    stations_taken: int = 0
    stations_passed: int = 0
    missed_stations: tuple[int, ...] = ()
    extra_photos: int = 0
    duplicate_events: int = 0
    failed_captures: int = 0
    messages: int = 0
    link: tuple[LinkQuality, ...] = ()
    link_quality_pct: float | None = None
    heartbeat_age_s: float | None = None
    connected: bool = False
    drops: int = 0
    reconnects: int = 0
    last_drop: str | None = None
    armed: bool = False
    flight_over: bool = False
    landed_state: int | None = None
    missing_streams: tuple[str, ...] = ()
    mission_changes: int = 0
    stations_from: str | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for key in self.__dataclass_fields__:
            value = getattr(self, key)
            if key == "link":
                value = [
                    {
                        "system_id": q.system_id,
                        "received": q.received,
                        "lost": q.lost,
                        "duplicates": q.duplicates,
                        "late": q.late,
                        "quality_pct": q.quality_pct,
                    }
                    for q in value
                ]
            elif isinstance(value, tuple):
                value = list(value)
            out[key] = value
        return out
