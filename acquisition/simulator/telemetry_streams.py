"""Telemetry emission of the simulated vehicle: which periodic messages it sends, how often, and what.

Streams and default periods: HEARTBEAT 1 Hz, SYSTEM_TIME 1 Hz, GLOBAL_POSITION_INT 10 Hz,
ATTITUDE 10 Hz, GPS_RAW_INT 5 Hz, MISSION_CURRENT 1 Hz, MOUNT_STATUS (ArduPilot) or
GIMBAL_DEVICE_ATTITUDE_STATUS (PX4) 1 Hz once a gimbal was commanded, EXTENDED_SYS_STATE 1 Hz
when asked.

Telemetry rates (``streams_on_request``): a real ArduPilot sends nothing but HEARTBEAT (and the
messages it sends on events: STATUSTEXT, MISSION_CURRENT on change, MISSION_ITEM_REACHED,
CAMERA_FEEDBACK) until a ground station asks, because its SRx_ stream rates default to 0 on its
serial ports. With ``streams_on_request`` the periodic streams start at 0 and follow
MAV_CMD_SET_MESSAGE_INTERVAL (:meth:`TelemetryStreams.set_message_interval`) and the legacy
REQUEST_DATA_STREAM (:meth:`TelemetryStreams.request_data_stream`, grouped as ArduCopter's
GCS_Mavlink.cpp groups them: :data:`DATA_STREAM_GROUPS`); without it they run at the rates
above from boot (as PX4 does). EXTENDED_SYS_STATE (landed state) is sent only when asked. The
rates are the vehicle's, not one per ground station (ArduPilot keeps them per port).

:func:`periodic_record` is what each stream sends, from the vehicle's state now.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from planner.mission import Autopilot

from .. import mavlink_messages as mm
from ..attitude import quat_from_euler_deg

if TYPE_CHECKING:
    from .flight import FlightSimulator

#: MAVLink message id -> the stream that sends it (what SET_MESSAGE_INTERVAL can change).
STREAM_OF_MESSAGE_ID = {
    **{
        mm.MESSAGE_ID[name]: name
        for name in (
            "HEARTBEAT",
            "SYSTEM_TIME",
            "GLOBAL_POSITION_INT",
            "ATTITUDE",
            "GPS_RAW_INT",
            "MISSION_CURRENT",
            "EXTENDED_SYS_STATE",
        )
    },
    mm.MESSAGE_ID["MOUNT_STATUS"]: "GIMBAL",  # ArduPilot
    mm.MESSAGE_ID["GIMBAL_DEVICE_ATTITUDE_STATUS"]: "GIMBAL",  # PX4
}


def _groups() -> dict[int, tuple[str, ...]]:
    out: dict[int, list[str]] = {}
    for name, group in mm.ARDUPILOT_STREAM_GROUP.items():
        stream = "GIMBAL" if name in ("MOUNT_STATUS", "GIMBAL_DEVICE_ATTITUDE_STATUS") else name
        if stream not in out.setdefault(group, []):
            out[group].append(stream)
    return {group: tuple(names) for group, names in sorted(out.items())}


#: REQUEST_DATA_STREAM's MAV_DATA_STREAM groups of the streams this simulator sends
#: (:data:`acquisition.mavlink_messages.ARDUPILOT_STREAM_GROUP`); MAV_DATA_STREAM_ALL is every group.
DATA_STREAM_GROUPS: dict[int, tuple[str, ...]] = _groups()


@dataclass
class _Stream:
    """One periodic message. ``period_s`` 0: not sent (ArduPilot's rate 0)."""

    name: str
    default_period_s: float
    period_s: float = 0.0
    next_s: float = 0.0


class TelemetryStreams:
    """The periodic streams and their rates (module docstring); times are simulated seconds."""

    def __init__(self, streams_on_request: bool) -> None:
        self._streams = [
            _Stream("HEARTBEAT", 1.0),
            _Stream("SYSTEM_TIME", 1.0),
            _Stream("GLOBAL_POSITION_INT", 0.1),
            _Stream("ATTITUDE", 0.1),
            _Stream("GPS_RAW_INT", 0.2),
            _Stream("MISSION_CURRENT", 1.0),
            _Stream("GIMBAL", 1.0),
            _Stream("EXTENDED_SYS_STATE", 1.0),
        ]
        # ArduPilot sends only HEARTBEAT until a ground station asks (its SRx_ rates are 0);
        # EXTENDED_SYS_STATE is in none of its stream groups: only SET_MESSAGE_INTERVAL starts it.
        for stream in self._streams:
            asked_only = streams_on_request or stream.name == "EXTENDED_SYS_STATE"
            stream.period_s = 0.0 if asked_only and stream.name != "HEARTBEAT" else stream.default_period_s
        #: True once a ground station asked for a telemetry stream.
        self.requested = False

    def _stream(self, name: str) -> _Stream:
        return next(s for s in self._streams if s.name == name)

    def _set_period(self, name: str, period_s: float, now_s: float) -> None:
        stream = self._stream(name)
        if period_s > 0 and stream.period_s <= 0:
            stream.next_s = now_s  # the first one at once
        elif period_s > 0:
            stream.next_s = min(stream.next_s, now_s + period_s)
        stream.period_s = max(period_s, 0.0)
        if period_s > 0 and name != "HEARTBEAT":
            self.requested = True

    def set_message_interval(self, message_id: int, interval_us: float, now_s: float) -> bool:
        """MAV_CMD_SET_MESSAGE_INTERVAL: ``interval_us`` > 0 that period (simulated
        microseconds), 0 the default rate, -1 stop. False for a message this vehicle cannot send."""
        name = STREAM_OF_MESSAGE_ID.get(int(message_id))
        if name is None or not math.isfinite(interval_us) or interval_us < -1:
            return False
        if interval_us == 0:
            period = self._stream(name).default_period_s
        elif interval_us < 0:
            period = 0.0
        else:
            period = max(interval_us / 1e6, 0.001)
        self._set_period(name, period, now_s)
        return True

    def request_data_stream(self, stream_id: int, rate_hz: float, start: bool, now_s: float) -> None:
        """REQUEST_DATA_STREAM (the legacy way): every message of the group at ``rate_hz``
        (ArduPilot stores it as its SRx_ rate), or off when ``start`` is 0 or the rate 0."""
        groups = (
            DATA_STREAM_GROUPS.values()
            if stream_id == mm.MAV_DATA_STREAM_ALL
            else [DATA_STREAM_GROUPS.get(stream_id, ())]
        )
        period = 1.0 / rate_hz if start and rate_hz > 0 else 0.0
        for group in groups:
            for name in group:
                self._set_period(name, period, now_s)

    def rates_hz(self) -> dict[str, float]:
        """Every stream's rate now (Hz of simulated time; 0 = not sent)."""
        return {s.name: (1.0 / s.period_s if s.period_s > 0 else 0.0) for s in self._streams}

    def next_due_s(self) -> float:
        """When the next periodic message is due (inf: none is sent)."""
        return min((s.next_s for s in self._streams if s.period_s > 0), default=math.inf)

    def take_due(self, now_s: float) -> list[str]:
        """The streams due at ``now_s``, in their order, each then scheduled one period later."""
        due = []
        for stream in self._streams:
            if stream.period_s > 0 and stream.next_s <= now_s + 1e-9:
                due.append(stream.name)
                stream.next_s += stream.period_s
        return due


def periodic_record(sim: FlightSimulator, name: str) -> mm.Record | None:
    """What stream ``name`` sends now (None: nothing, e.g. a gimbal never commanded)."""
    t = sim.time_s
    fix = sim.gps_has_fix
    if name == "HEARTBEAT":
        return sim.heartbeat()
    if name == "SYSTEM_TIME":
        return mm.SystemTime(time_boot_s=t, time_utc_s=sim.utc_s if fix else None)
    if name == "MISSION_CURRENT":
        return sim.mission_current()
    if name == "EXTENDED_SYS_STATE":
        return mm.ExtendedSysState(landed_state=sim.landed_state)
    if name == "GIMBAL":
        if not sim.gimbal_commanded:
            return None
        g = sim.gimbal
        pitch = g.pitch_deg or 0.0
        if sim.autopilot is Autopilot.ARDUPILOT:
            return mm.MountStatus(roll_deg=g.roll_deg, pitch_deg=pitch, yaw_rel_deg=g.yaw_deg)
        w, x, y, z = (float(v) for v in quat_from_euler_deg(g.yaw_deg, pitch, g.roll_deg)[0])
        return mm.GimbalAttitude(time_boot_s=t, flags=0, q=(w, x, y, z))
    lat, lon, alt_rel = sim.reported_position() if fix else (0.0, 0.0, 0.0)
    alt_amsl = alt_rel + sim.home.alt_amsl_m
    vx, vy, vz = sim.vel
    if name == "GLOBAL_POSITION_INT":
        return mm.GlobalPosition(
            time_boot_s=t,
            lat_deg=lat,
            lon_deg=lon,
            alt_amsl_m=alt_amsl if fix else 0.0,
            alt_rel_home_m=alt_rel,
            north_m_s=vy,
            east_m_s=vx,
            down_m_s=-vz,
            heading_deg=sim.heading_deg,
            has_position=fix,
        )
    if name == "ATTITUDE":
        roll, pitch, yaw = sim.attitude_deg()
        return mm.Attitude(time_boot_s=t, roll_deg=roll, pitch_deg=pitch, yaw_deg=yaw)
    if name == "GPS_RAW_INT":
        speed = math.hypot(vx, vy)
        return mm.GpsRaw(
            time_usec=round(t * 1e6),
            fix_type=3 if fix else 1,
            lat_deg=lat,
            lon_deg=lon,
            alt_amsl_m=alt_amsl if fix else 0.0,
            eph=70 if fix else 9999,
            epv=120 if fix else 9999,
            ground_speed_m_s=speed,
            course_deg=sim.heading_deg if speed > 0 else None,
            satellites=14 if fix else 0,
        )
    return None
