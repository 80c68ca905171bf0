"""A simulated vehicle on a MAVLink URL: the mission protocol as ArduPilot or PX4 speak it.

:class:`SimulatedVehicle` listens on ``tcpin://HOST:PORT``, ``udpin://HOST:PORT`` (or sends to
``udpout://HOST:PORT``), runs in a background thread and stops cleanly when its ``with`` block
ends. It is a simulator and says so: a STATUSTEXT "sfap simulated vehicle" at start and a log
line. What it does, and which real behaviour each part copies:

- HEARTBEAT at 1 Hz of simulated time (autopilot ARDUPILOTMEGA or PX4, quadrotor or fixed
  wing, armed flag, custom mode AUTO when flying), and the telemetry of
  :class:`acquisition.simulator.flight.FlightSimulator`.
- The mission protocol (mavlink.io "Mission Protocol"; REFERENCES.md section 3), per flavour:

  * ArduPilot (copied from ArduPilot 4.5's MissionItemProtocol and AP_Mission): requests
    items with the legacy MISSION_REQUEST (id 40); accepts MISSION_ITEM_INT (and MISSION_ITEM,
    with a STATUSTEXT warning); answers an item with an unexpected seq with
    MAV_MISSION_INVALID_SEQUENCE and carries on; re-requests after 1 s without an item and
    cancels (MAV_MISSION_OPERATION_CANCELLED) after 8 s; writes items as they arrive, so a
    failed upload leaves a partial mission; stores home as item 0 (what is uploaded as item 0
    is ignored: home reads back as zeros until the GPS has a fix, then as the home position);
    refuses uploads with MAV_MISSION_NO_SPACE ("Only 0 items are supported") for
    ``boot_delay_s`` after boot; stores items compressed (see :func:`ardupilot_store`);
    rejects NaN in params 1-4 except where AP_Mission allows it; denies downloads during an
    upload; does not repeat the final ACK when the last item is sent again.
  * PX4: requests with MISSION_REQUEST_INT; no home item; ignores items with an unexpected
    seq; re-requests after 0.25 s and cancels after 5 s; commits the mission only when the
    upload completes (a failed upload leaves the old mission); repeats the final ACK when
    the last item arrives again.
  * Both: MISSION_REQUEST_LIST -> MISSION_COUNT; MISSION_REQUEST_INT -> MISSION_ITEM_INT; the
    legacy MISSION_REQUEST -> the legacy MISSION_ITEM (float degrees), as both real
    autopilots answer it; MISSION_CLEAR_ALL -> MISSION_ACK; mission_type mission, fence and
    rally kept apart.

  * A ground station may cancel its upload with an error MISSION_ACK (the spec's way).

- Fault injection (:class:`FaultConfig`) on every message sent and received: loss,
  duplication, reordering (a message swapped with the next one), latency; seeded RNG.
  ``link_baud`` adds a serial radio's speed (8N1, each way, shared with the telemetry).
- Commands: ARM_DISARM (400), DO_SET_MODE (176) and SET_MODE, MISSION_START (300),
  DO_SET_MISSION_CURRENT (224), NAV_RETURN_TO_LAUNCH (20), REQUEST_MESSAGE (512) for
  AUTOPILOT_VERSION (148) or HOME_POSITION (242), answered with COMMAND_ACK.
- Every ground station that connects gets a HEARTBEAT and the banner at once.
- Optionally a .tlog of what it sends (before link faults): per packet an 8-byte big-endian
  microsecond UTC time stamp (simulated time) then the raw packet, as MAVProxy and QGC write.

Timers of the protocol (re-requests, cancellation, latency) run on the wall clock; the flight,
the boot delay and the GPS fix run on simulated time (``speedup`` x the wall clock).
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import random
import select
import socket
import struct
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import IO, Any
from urllib.parse import urlsplit

import numpy as np
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from planner.errors import InputError, MissionValidationError
from planner.mission import Autopilot, HomePosition, MavCmd, MissionItem, VehicleType

from ..errors import LinkError
from ..mavlink_items import from_mission_item, to_mission_item_int
from .flight import FlightConfig, FlightSimulator

log = logging.getLogger(__name__)

SIMULATOR_BANNER = "sfap simulated vehicle"

#: Where the simulated vehicle stands when nobody says otherwise (a field near Zaragoza).
DEFAULT_HOME = HomePosition(lat_deg=41.6488, lon_deg=-0.8891, alt_amsl_m=210.0)

M = mavlink2  # the message set (ardupilotmega includes common)

MISSION_TYPE_MISSION = 0
MISSION_TYPE_FENCE = 1
MISSION_TYPE_RALLY = 2
_MISSION_TYPES = (MISSION_TYPE_MISSION, MISSION_TYPE_FENCE, MISSION_TYPE_RALLY)


class Refusal(StrEnum):
    """How a refusing vehicle answers an upload."""

    NO_SPACE = "no_space"  # every MISSION_COUNT > 0 -> MAV_MISSION_NO_SPACE
    INVALID = "invalid"  # the item at seq count // 2 -> MAV_MISSION_INVALID


@dataclass(frozen=True, kw_only=True)
class FaultConfig:
    """Faults injected on the link, applied to every message the vehicle sends and receives.

    - ``loss_pct``: chance (0-100) that a message is dropped.
    - ``duplicate_pct``: chance (0-100) that a message is delivered twice.
    - ``reorder_pct``: chance (0-100) that a message is held back and delivered after the
      next one (or after 0.2 s when no next one comes).
    - ``latency_s``: delay added to every message, seconds (wall clock).
    - ``refuse``: None, ``"no_space"`` or ``"invalid"`` (see :class:`Refusal`).
    - ``seed``: seed of the fault RNG (sending and receiving use two streams derived from it).
    """

    loss_pct: float = 0.0
    duplicate_pct: float = 0.0
    reorder_pct: float = 0.0
    latency_s: float = 0.0
    refuse: str | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("loss_pct", "duplicate_pct", "reorder_pct"):
            value = getattr(self, name)
            if not (0.0 <= value <= 100.0) or math.isnan(value):
                raise InputError(f"FaultConfig.{name} is {value}; give a percentage 0-100")
        if not (0.0 <= self.latency_s <= 60.0):
            raise InputError(f"FaultConfig.latency_s is {self.latency_s}; give 0-60 s")
        if self.refuse is not None and self.refuse not in {r.value for r in Refusal}:
            raise InputError(f"FaultConfig.refuse is {self.refuse!r}; use None, 'no_space' or 'invalid'")


@dataclass
class FaultStats:
    """What the fault injector did, per direction (for tests and logs)."""

    offered: int = 0
    dropped: int = 0
    duplicated: int = 0
    reordered: int = 0
    overflowed: int = 0  # dropped because the simulated serial link's buffer was full


class _FaultyPipe:
    """Applies a :class:`FaultConfig` to a stream of items; ``release(now)`` yields them.

    With ``baud``, the items also cross a serial link one after the other: each takes
    10 bits per byte (8N1) of link time, and what would wait more than ``buffer_s`` for the
    link is dropped, as a telemetry radio's full buffer drops it.
    """

    def __init__(
        self,
        faults: FaultConfig,
        rng: random.Random,
        *,
        baud: int | None = None,
        size_of: Callable[[Any], int] = len,
        buffer_s: float = 1.0,
    ) -> None:
        self.faults = faults
        self.rng = rng
        self.stats = FaultStats()
        self.baud = baud
        self.size_of = size_of
        self.buffer_s = buffer_s
        self._busy_until = 0.0
        self._queue: list[tuple[float, int, Any]] = []
        self._held: tuple[float, Any] | None = None
        self._order = 0

    def _schedule(self, when: float, item: Any) -> None:
        if self.baud:
            start = max(when, self._busy_until)
            self._busy_until = start + self.size_of(item) * 10.0 / self.baud
            when = self._busy_until
        self._order += 1
        self._queue.append((when, self._order, item))

    def offer(self, item: Any, now: float) -> None:
        self.stats.offered += 1
        f = self.faults
        if self.baud and self._busy_until - now > self.buffer_s:
            self.stats.overflowed += 1
            return
        if f.loss_pct and self.rng.random() * 100.0 < f.loss_pct:
            self.stats.dropped += 1
            return
        copies = 1
        if f.duplicate_pct and self.rng.random() * 100.0 < f.duplicate_pct:
            self.stats.duplicated += 1
            copies = 2
        when = now + f.latency_s
        if self._held is None and f.reorder_pct and self.rng.random() * 100.0 < f.reorder_pct:
            self.stats.reordered += 1
            self._held = (when, item)
            for _ in range(copies - 1):
                self._schedule(when, item)
            return
        for _ in range(copies):
            self._schedule(when, item)
        if self._held is not None:
            # The held message goes out right after this one: the two are swapped.
            self._schedule(when, self._held[1])
            self._held = None

    def release(self, now: float) -> list[Any]:
        if self._held is not None and now - self._held[0] > 0.2:
            self._schedule(self._held[0] + 0.2, self._held[1])
            self._held = None
        if not self._queue:
            return []
        ready = [entry for entry in self._queue if entry[0] <= now]
        if not ready:
            return []
        self._queue = [entry for entry in self._queue if entry[0] > now]
        ready.sort(key=lambda entry: (entry[0], entry[1]))
        return [entry[2] for entry in ready]


# --- URLs -------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ListenAddress:
    """Where the vehicle listens (``tcpin``, ``udpin``) or sends to (``udpout``)."""

    scheme: str
    host: str
    port: int


def parse_listen_url(url: str) -> ListenAddress:
    """``tcpin://HOST:PORT``, ``udpin://HOST:PORT`` or ``udpout://HOST:PORT`` (also the
    mavutil spelling ``tcpin:HOST:PORT``; ``tcp://`` means ``tcpin://`` for a vehicle)."""
    text = url.strip()
    if "://" not in text and text.count(":") == 2:
        text = text.replace(":", "://", 1)
    parts = urlsplit(text)
    scheme = parts.scheme.lower()
    if scheme == "tcp":
        scheme = "tcpin"
    if scheme not in ("tcpin", "udpin", "udpout"):
        raise LinkError(
            f"the simulator cannot listen on {url!r}; use tcpin://HOST:PORT, "
            f"udpin://HOST:PORT or udpout://HOST:PORT (e.g. tcpin://127.0.0.1:5760)"
        )
    try:
        port = parts.port
    except ValueError as error:
        raise LinkError(f"bad port in {url!r}: {error}; give a port 0-65535") from error
    if port is None or not parts.hostname:
        raise LinkError(f"{url!r} needs a host and a port, e.g. {scheme}://127.0.0.1:5760")
    if scheme == "udpout" and port == 0:
        raise LinkError(f"{url!r}: udpout needs the ground station's real port, not 0")
    return ListenAddress(scheme, parts.hostname, port)


# --- transport --------------------------------------------------------------------------------


class _Transport:
    """Sockets of one listening URL: several TCP clients, or UDP peers; bytes in and out."""

    def __init__(self, address: ListenAddress) -> None:
        self.address = address
        self._listen: socket.socket | None = None
        self._udp: socket.socket | None = None
        self._clients: dict[int, socket.socket] = {}
        self._udp_peers: list[tuple[str, int]] = []
        self._next_id = 1
        self.new_peers = 0  # ground stations that appeared since the vehicle last looked
        self._pending: dict[int, bytearray] = {}
        self.max_pending_bytes = 4 << 20
        try:
            if address.scheme == "tcpin":
                sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                sock.bind((address.host, address.port))
                sock.listen(8)
                sock.setblocking(False)
                self._listen = sock
                self.port = sock.getsockname()[1]
            else:
                sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                if address.scheme == "udpin":
                    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                    sock.bind((address.host, address.port))
                    self.port = sock.getsockname()[1]
                else:
                    self._udp_peers.append((address.host, address.port))
                    self.port = address.port
                sock.setblocking(False)
                self._udp = sock
        except OSError as error:
            raise LinkError(
                f"cannot listen on {address.scheme}://{address.host}:{address.port}: "
                f"{error.strerror or error}; choose a free port (or port 0 for any)"
            ) from error

    def sockets(self) -> list[socket.socket]:
        socks = list(self._clients.values())
        if self._listen is not None:
            socks.append(self._listen)
        if self._udp is not None:
            socks.append(self._udp)
        return socks

    def poll(self, timeout_s: float) -> list[tuple[object, bytes]]:
        """Wait up to ``timeout_s`` and return (peer key, bytes) received."""
        socks = self.sockets()
        out: list[tuple[object, bytes]] = []
        try:
            readable, _, _ = select.select(socks, [], [], timeout_s)
        except (OSError, ValueError):
            return out
        for sock in readable:
            if sock is self._listen:
                with contextlib.suppress(OSError):
                    conn, peer = sock.accept()
                    conn.setblocking(False)
                    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    self._clients[self._next_id] = conn
                    self.new_peers += 1
                    log.info("simulated vehicle: ground station connected from %s:%s", *peer)
                    self._next_id += 1
            elif sock is self._udp:
                while True:
                    try:
                        data, peer = sock.recvfrom(65535)
                    except (BlockingIOError, InterruptedError):
                        break
                    except OSError:
                        break
                    if peer not in self._udp_peers:
                        self._udp_peers.append(peer)
                        self.new_peers += 1
                    out.append((peer, data))
            else:
                key = next((k for k, s in self._clients.items() if s is sock), None)
                if key is None:
                    continue
                try:
                    data = sock.recv(65536)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError:
                    data = b""
                if not data:
                    log.info("simulated vehicle: ground station %s disconnected", key)
                    self._drop(key)
                    continue
                out.append((("tcp", key), data))
        return out

    def flush(self) -> None:
        """Send what TCP clients could not take before."""
        for key, pending in list(self._pending.items()):
            sock = self._clients.get(key)
            if sock is None or not pending:
                continue
            try:
                sent = sock.send(pending)
            except (BlockingIOError, InterruptedError):
                continue
            except OSError:
                self._drop(key)
                continue
            del pending[:sent]

    def _drop(self, key: int) -> None:
        self._pending.pop(key, None)
        sock = self._clients.pop(key, None)
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.close()

    def send(self, data: bytes) -> None:
        for key, sock in list(self._clients.items()):
            pending = self._pending.setdefault(key, bytearray())
            if len(pending) < self.max_pending_bytes:
                pending += data  # whole packets only: a client that does not read loses some
            try:
                sent = sock.send(pending)
            except (BlockingIOError, InterruptedError):
                continue
            except OSError:
                self._drop(key)
                continue
            del pending[:sent]
        if self._udp is not None:
            for peer in self._udp_peers:
                with contextlib.suppress(OSError):
                    self._udp.sendto(data, peer)

    def close(self) -> None:
        for key in list(self._clients):
            self._drop(key)
        for sock in (self._listen, self._udp):
            if sock is not None:
                with contextlib.suppress(OSError):
                    sock.close()


# --- how each autopilot stores mission items ----------------------------------------------------


@dataclass(frozen=True)
class WireItem:
    """A mission item as MISSION_ITEM_INT carries it (float32 params, degE7 x/y)."""

    frame: int
    command: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float
    autocontinue: int = 1


_F32 = np.float32
_GLOBAL_FRAMES = frozenset({0, 3, 5, 6, 10, 11})
_PLAIN = {5: 0, 6: 3, 11: 10}
_INT_OF = {0: 5, 3: 6, 10: 11}

# MAV_MISSION_RESULT values, from pymavlink's message definitions
MAV_MISSION_ACCEPTED = M.MAV_MISSION_ACCEPTED
MAV_MISSION_ERROR = M.MAV_MISSION_ERROR
MAV_MISSION_UNSUPPORTED_FRAME = M.MAV_MISSION_UNSUPPORTED_FRAME
MAV_MISSION_UNSUPPORTED = M.MAV_MISSION_UNSUPPORTED
MAV_MISSION_NO_SPACE = M.MAV_MISSION_NO_SPACE
MAV_MISSION_INVALID = M.MAV_MISSION_INVALID
MAV_MISSION_INVALID_PARAM1 = M.MAV_MISSION_INVALID_PARAM1
MAV_MISSION_INVALID_PARAM5_X = M.MAV_MISSION_INVALID_PARAM5_X
MAV_MISSION_INVALID_PARAM6_Y = M.MAV_MISSION_INVALID_PARAM6_Y
MAV_MISSION_INVALID_PARAM7 = M.MAV_MISSION_INVALID_PARAM7
MAV_MISSION_INVALID_SEQUENCE = M.MAV_MISSION_INVALID_SEQUENCE
MAV_MISSION_DENIED = M.MAV_MISSION_DENIED
MAV_MISSION_OPERATION_CANCELLED = M.MAV_MISSION_OPERATION_CANCELLED

#: Commands AP_Mission stores with a location (copy_location), which read back in a global frame.
_AP_LOCATION_CMDS = frozenset({16, 17, 18, 19, 21, 22, 30, 31, 82, 84, 85, 94, 179, 189, 195, 201})


def _f32(value: float) -> float:
    return float(_F32(value))


def _c_uint(value: float, bits: int) -> int:
    """A C float -> unsigned integer conversion (truncation, saturated as ARM does)."""
    if math.isnan(value):
        return 0
    return int(min(max(math.trunc(value), 0), (1 << bits) - 1))


def _c_int(value: float, bits: int) -> int:
    if math.isnan(value):
        return 0
    limit = 1 << (bits - 1)
    return int(min(max(math.trunc(value), -limit), limit - 1))


def _ap_nan_allowed(command: int) -> frozenset[int]:
    """Params (1-4) that AP_Mission::sanity_check_params lets be NaN."""
    if command in (16, 21, 22, 84):
        return frozenset({4})
    if command == 85:
        return frozenset({3, 4})
    return frozenset()


def ardupilot_store(item: WireItem, vehicle_type: VehicleType) -> WireItem | int:
    """What ArduPilot (AP_Mission, 4.5) stores for ``item``, as it will read it back.

    Returns the stored item or a MAV_MISSION_RESULT error code. Rules (from AP_Mission's
    mavlink_int_to_mission_cmd / mission_cmd_to_mavlink_int; REFERENCES.md section 3):
    positional commands keep degE7 latitude/longitude and the altitude in whole centimetres
    (truncated), their frame reads back in its plain form (GLOBAL 0, GLOBAL_RELATIVE_ALT 3,
    GLOBAL_TERRAIN_ALT 10); other commands read back with frame 0 and x=y=z=0 unless the
    command stores them; Copter keeps a waypoint's hold time in whole seconds and drops
    acceptance radius, pass radius and yaw; Plane drops the hold time and keeps the radii as
    integers clamped to 0-255. Commands this table does not know keep params 1-4 as float32.
    """
    params = (item.param1, item.param2, item.param3, item.param4)
    allowed = _ap_nan_allowed(item.command)
    for n, value in enumerate(params, start=1):
        if math.isinf(value) or (math.isnan(value) and n not in allowed):
            return MAV_MISSION_INVALID_PARAM1 + n - 1
    if item.command == 0:
        return MAV_MISSION_INVALID
    p1, p2, p3, p4 = (0.0 if math.isnan(v) else v for v in params)
    cmd = item.command
    copter = vehicle_type is not VehicleType.FIXED_WING
    out1 = out2 = out3 = out4 = 0.0
    x = y = 0
    z = 0.0
    frame = 0
    if cmd in _AP_LOCATION_CMDS:
        plain = _PLAIN.get(item.frame, item.frame)
        if plain not in (0, 2, 3, 10):
            return MAV_MISSION_UNSUPPORTED_FRAME
        if not (-900_000_000 <= item.x <= 900_000_000):
            return MAV_MISSION_INVALID_PARAM5_X
        if not (-1_800_000_000 <= item.y <= 1_800_000_000):
            return MAV_MISSION_INVALID_PARAM6_Y
        if not math.isfinite(item.z) or abs(item.z) >= 83000:
            return MAV_MISSION_INVALID_PARAM7
        frame = 0 if plain == 2 else plain
        x, y = item.x, item.y
        alt_cm = int(_F32(item.z) * _F32(100.0))  # int32 cast truncates toward zero
        z = float(_F32(alt_cm) / _F32(100.0))
    if cmd == MavCmd.NAV_WAYPOINT:
        if copter:
            out1 = float(_c_uint(p1, 16))
        else:
            out2 = float(min(_c_uint(p2, 16), 255))
            out3 = float(min(_c_uint(p3, 16), 255))
    elif cmd == MavCmd.NAV_SPLINE_WAYPOINT:
        if not copter:
            return MAV_MISSION_UNSUPPORTED
        out1 = float(_c_uint(p1, 16))
    elif cmd in (MavCmd.NAV_TAKEOFF, MavCmd.NAV_LAND):
        out1 = float(_c_uint(p1, 16))
    elif cmd == MavCmd.NAV_LOITER_TIME:
        out1 = float(_c_uint(p1, 16))
        out3 = -1.0 if p3 < 0 else 1.0
        out4 = 1.0 if p4 > 0 else 0.0
    elif cmd == MavCmd.NAV_LOITER_UNLIM:
        out3 = float(_c_uint(abs(p3), 16)) * (-1.0 if p3 < 0 else 1.0)
    elif cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
        pass
    elif cmd == MavCmd.DO_CHANGE_SPEED:
        out1, out2, out3 = float(_c_uint(p1, 8)), _f32(p2), _f32(p3)
    elif cmd == MavCmd.DO_SET_CAM_TRIGG_DIST:
        out1, out3 = _f32(p1), float(_c_uint(p3, 8))
    elif cmd == MavCmd.DO_MOUNT_CONTROL:
        out1, out2, out3 = _f32(p1), _f32(p2), _f32(p3)
    elif cmd == MavCmd.DO_GIMBAL_MANAGER_PITCHYAW:
        out1, out2, out3, out4 = _f32(p1), _f32(p2), _f32(p3), _f32(p4)
        x = int(item.x) & 0xFFFFFFFF if item.x >= 0 else 0
        z = float(_c_uint(item.z, 8))
    elif cmd == MavCmd.IMAGE_START_CAPTURE:
        out1 = float(_c_uint(p1, 8))
        out2 = _f32(p2)
        out3 = float(_c_uint(p3, 16))
        out4 = float(_c_uint(p4, 16))
    elif cmd == MavCmd.IMAGE_STOP_CAPTURE:
        out1 = float(_c_uint(p1, 8))
    elif cmd == MavCmd.DO_JUMP:
        out1, out2 = float(_c_uint(p1, 16)), float(_c_int(p2, 16))
    elif cmd in (MavCmd.CONDITION_DELAY, MavCmd.CONDITION_DISTANCE):
        out1 = _f32(p1)
    elif cmd == MavCmd.DO_DIGICAM_CONTROL:
        out1, out2, out3, out4 = _f32(p1), _f32(p2), _f32(p3), _f32(p4)
        # shooting command and command id live in x and y (uint8 each)
        x, y = _c_uint(float(item.x), 8), _c_uint(float(item.y), 8)
    elif cmd in _AP_LOCATION_CMDS:
        out1 = float(_c_uint(p1, 16))
    else:
        out1, out2, out3, out4 = _f32(p1), _f32(p2), _f32(p3), _f32(p4)
        x, y, z = item.x, item.y, _f32(item.z)
        frame = _PLAIN.get(item.frame, item.frame)
    return WireItem(frame, cmd, out1, out2, out3, out4, x, y, z, 1 if item.autocontinue else 0)


def px4_store(item: WireItem, mission_type: int = MISSION_TYPE_MISSION) -> WireItem | int:
    """What PX4 keeps: params as float32, positions degE7; in a mission, the frame in its
    _INT form for positional items and MAV_FRAME_MISSION (2) for the other commands it knows;
    fence and rally items keep their frame."""
    try:
        command: MavCmd | None = MavCmd(item.command)
    except ValueError:
        command = None
    frame = item.frame
    if mission_type != MISSION_TYPE_MISSION or command is None:
        pass
    elif command.is_nav:
        plain = _PLAIN.get(item.frame, item.frame)
        if plain not in (0, 3, 10):
            return MAV_MISSION_UNSUPPORTED_FRAME
        frame = _INT_OF[plain]
    else:
        frame = 2
    return WireItem(
        frame,
        item.command,
        _f32(item.param1),
        _f32(item.param2),
        _f32(item.param3),
        _f32(item.param4),
        item.x,
        item.y,
        _f32(item.z),
        1 if item.autocontinue else 0,
    )


def wire_item_from_message(msg: Any) -> WireItem:
    """MISSION_ITEM_INT (or legacy MISSION_ITEM: float degrees) -> :class:`WireItem`."""
    if msg.get_type() == "MISSION_ITEM":
        if msg.frame in _GLOBAL_FRAMES:
            x, y = round(msg.x * 1e7), round(msg.y * 1e7)
        else:
            x, y = math.trunc(msg.x), math.trunc(msg.y)
    else:
        x, y = int(msg.x), int(msg.y)
    return WireItem(
        int(msg.frame),
        int(msg.command),
        float(msg.param1),
        float(msg.param2),
        float(msg.param3),
        float(msg.param4),
        x,
        y,
        float(msg.z),
        int(msg.autocontinue),
    )


def wire_item_to_mission_item(item: WireItem) -> MissionItem:
    """The :class:`MissionItem` a ground station reads for this stored item."""
    return from_mission_item(_item_int_message(item, 0, 0, 0, 0))


def _item_int_message(item: WireItem, seq: int, sysid: int, compid: int, mission_type: int) -> Any:
    return M.MAVLink_mission_item_int_message(
        sysid,
        compid,
        seq,
        item.frame,
        item.command,
        0,
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
        item.x,
        item.y,
        item.z,
        mission_type,
    )


def _item_float_message(item: WireItem, seq: int, sysid: int, compid: int, mission_type: int) -> Any:
    if item.frame in _GLOBAL_FRAMES:
        x, y = _f32(item.x * 1e-7), _f32(item.y * 1e-7)
    else:
        x, y = float(item.x), float(item.y)
    return M.MAVLink_mission_item_message(
        sysid,
        compid,
        seq,
        item.frame,
        item.command,
        0,
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
        x,
        y,
        item.z,
        mission_type,
    )


# --- the vehicle --------------------------------------------------------------------------------


@dataclass
class _Upload:
    mission_type: int
    count: int
    sysid: int
    compid: int
    expected: int = 0
    items: list[WireItem] = field(default_factory=list)
    last_request_s: float = 0.0
    last_receive_s: float = 0.0


@dataclass
class _Completed:
    mission_type: int
    count: int
    sysid: int
    compid: int
    result: int
    at_s: float


class SimulatedVehicle:
    """A simulated ArduPilot or PX4 vehicle on a MAVLink URL (see the module docstring).

    Parameters: ``url`` where to listen (``tcpin://HOST:PORT``, ``udpin://HOST:PORT``, port 0
    picks a free port; or ``udpout://HOST:PORT`` to send to a ground station);
    ``autopilot`` and ``vehicle_type`` the flavour; ``faults`` link faults and refusals;
    ``speedup`` simulated seconds per wall second (> 0); ``tlog_path`` where to write the
    .tlog of what it sends (None: none); ``home`` the take-off position; ``boot_delay_s``
    simulated seconds after boot during which ArduPilot refuses uploads (NO_SPACE);
    ``gps_fix_s`` simulated seconds until the GPS has a fix (home is set then);
    ``request_timeout_s`` / ``upload_timeout_s`` override the flavour's re-request interval
    and the silence after which it cancels an upload (wall seconds); ``max_items`` the
    mission capacity (ArduPilot 724 including home, PX4 2000); ``flight`` the flight model's
    settings; ``link_baud`` makes the link a serial radio of that many baud (8N1, each way,
    shared with the telemetry; None: as fast as the socket); ``system_id`` /
    ``component_id`` its MAVLink identity.
    """

    def __init__(
        self,
        url: str = "tcpin://127.0.0.1:0",
        autopilot: Autopilot = Autopilot.ARDUPILOT,
        faults: FaultConfig | None = None,
        speedup: float = 1.0,
        vehicle_type: VehicleType = VehicleType.MULTIROTOR,
        tlog_path: str | Path | None = None,
        *,
        home: HomePosition = DEFAULT_HOME,
        boot_delay_s: float = 1.0,
        gps_fix_s: float = 1.0,
        request_timeout_s: float | None = None,
        upload_timeout_s: float | None = None,
        max_items: int | None = None,
        flight: FlightConfig | None = None,
        link_baud: int | None = None,
        system_id: int = 1,
        component_id: int = 1,
    ) -> None:
        if not (speedup > 0 and math.isfinite(speedup)):
            raise InputError(f"speedup is {speedup}; give a positive number (1 = real time)")
        self.autopilot = Autopilot(autopilot)
        self.vehicle_type = VehicleType(vehicle_type)
        self.faults = faults if faults is not None else FaultConfig()
        self.speedup = float(speedup)
        self.address = parse_listen_url(url)
        self.url = url
        self.tlog_path = Path(tlog_path) if tlog_path is not None else None
        self.home = home
        self.boot_delay_s = boot_delay_s
        self.gps_fix_s = gps_fix_s
        ardupilot = self.autopilot is Autopilot.ARDUPILOT
        self.request_timeout_s = (
            request_timeout_s if request_timeout_s is not None else (1.0 if ardupilot else 0.25)
        )
        self.upload_timeout_s = (
            upload_timeout_s if upload_timeout_s is not None else (8.0 if ardupilot else 5.0)
        )
        self.max_items = max_items if max_items is not None else (724 if ardupilot else 2000)
        self.system_id = system_id
        self.component_id = component_id

        self._lock = threading.RLock()
        self._stored: dict[int, list[WireItem]] = {t: [] for t in _MISSION_TYPES}
        self._upload: _Upload | None = None
        self._completed: _Completed | None = None
        self._warned: set[str] = set()
        self._mav = M.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self._parsers: dict[object, Any] = {}
        if link_baud is not None and link_baud <= 0:
            raise InputError(f"link_baud is {link_baud}; give a positive baud rate or None")
        self.link_baud = link_baud
        self._send_pipe = _FaultyPipe(self.faults, random.Random(self.faults.seed * 2 + 1), baud=link_baud)
        self._recv_pipe = _FaultyPipe(
            self.faults,
            random.Random(self.faults.seed * 2 + 2),
            baud=link_baud,
            size_of=lambda msg: len(msg.get_msgbuf()),
        )
        self.flight = FlightSimulator(
            autopilot=self.autopilot,
            vehicle_type=self.vehicle_type,
            home=home,
            config=flight or FlightConfig(seed=self.faults.seed),
            gps_fix_s=gps_fix_s,
            boot_utc_s=time.time(),
        )
        self._transport: _Transport | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._tlog: IO[bytes] | None = None
        self._last_tlog_us = 0
        self._error: BaseException | None = None
        self.received_counts: dict[str, int] = {}
        self.sent_counts: dict[str, int] = {}
        self._auto_start = False

    # --- lifecycle ---------------------------------------------------------------------------

    def __enter__(self) -> SimulatedVehicle:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def start(self) -> None:
        """Open the socket and start the background thread."""
        if self._thread is not None:
            return
        self._transport = _Transport(self.address)
        if self.tlog_path is not None:
            self.tlog_path.parent.mkdir(parents=True, exist_ok=True)
            self._tlog = open(self.tlog_path, "wb")  # noqa: SIM115 - closed in stop()
        log.info(
            "%s (%s %s) listening on %s; connect a ground station to %s",
            SIMULATOR_BANNER,
            self.autopilot.value,
            self.vehicle_type.value,
            self.url,
            self.url_for_client,
        )
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="sfap-sim-vehicle", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the thread and close the socket and the tlog."""
        self._stop.set()
        if self._thread is not None:
            # The loop checks the stop flag between steps; a step of a heavily loaded simulation
            # can take long, so wait for it rather than pull the socket from under it.
            self._thread.join(timeout=30.0)
            if self._thread.is_alive():
                log.error("simulated vehicle: the loop did not stop within 30 s; leaving it running")
                return
            self._thread = None
        if self._transport is not None:
            self._transport.close()
            self._transport = None
        if self._tlog is not None:
            self._tlog.close()
            self._tlog = None

    @property
    def url_for_client(self) -> str:
        """The URL a ground station connects to (port 0 resolved to the real port)."""
        port = self.address.port if self._transport is None else self._transport.port
        host = self.address.host
        if host in ("0.0.0.0", ""):
            host = "127.0.0.1"
        client_scheme = {"tcpin": "tcp", "udpin": "udpout", "udpout": "udpin"}[self.address.scheme]
        if client_scheme == "udpin" and host not in ("127.0.0.1", "localhost"):
            host = "0.0.0.0"
        return f"{client_scheme}://{host}:{port}"

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    # --- what tests and the CLI use ------------------------------------------------------------

    @property
    def sim_time_s(self) -> float:
        """Simulated seconds since boot."""
        with self._lock:
            return self.flight.time_s

    @property
    def send_stats(self) -> FaultStats:
        return self._send_pipe.stats

    @property
    def receive_stats(self) -> FaultStats:
        return self._recv_pipe.stats

    def stored_mission(self, mission_type: int = MISSION_TYPE_MISSION) -> list[MissionItem]:
        """A copy of the stored mission as a ground station would read it back
        (ArduPilot: home at index 0)."""
        with self._lock:
            return [wire_item_to_mission_item(w) for w in self._items_for_readback(mission_type)]

    def load_mission(self, items: Sequence[MissionItem], mission_type: int = 0) -> None:
        """Store ``items`` as if uploaded (ArduPilot: give the items without home)."""
        with self._lock:
            stored: list[WireItem] = []
            if self.autopilot is Autopilot.ARDUPILOT and mission_type == MISSION_TYPE_MISSION:
                stored.append(WireItem(0, 16, 0, 0, 0, 0, 0, 0, 0.0))
            for seq, item in enumerate(items):
                wire = wire_item_from_message(to_mission_item_int(item, seq, 1, 1, mission_type))
                result = self._store(wire, mission_type)
                if isinstance(result, int):
                    raise MissionValidationError(
                        f"the simulated {self.autopilot.value} vehicle refuses item {seq + 1} "
                        f"({item.command_name}): MAV_MISSION_RESULT {result}; fix the item"
                    )
                stored.append(result)
            self._stored[mission_type] = stored
            self._mission_changed(mission_type)

    def corrupt_stored_item(self, seq: int, **changes: Any) -> None:
        """Change stored item ``seq`` (index as read back) behind the protocol's back, so a
        test can prove that a verification notices. ``changes`` are MissionItem fields."""
        with self._lock:
            stored = self._stored[MISSION_TYPE_MISSION]
            if not 0 <= seq < len(stored):
                raise IndexError(f"seq {seq} is outside the stored mission (0-{len(stored) - 1})")
            item = dataclasses.replace(wire_item_to_mission_item(stored[seq]), **changes)
            stored[seq] = wire_item_from_message(to_mission_item_int(item, seq, 1, 1, 0))
            self._mission_changed(MISSION_TYPE_MISSION)

    def auto_start(self) -> None:
        """Arm and start the mission (AUTO) as soon as the GPS has a fix, once; as a ground
        station would with ARM_DISARM and MISSION_START."""
        with self._lock:
            self._auto_start = True

    def wait_landed(self, timeout_s: float) -> bool:
        """Wait (wall seconds) until the vehicle has flown and landed; True if it has."""
        deadline = time.monotonic() + timeout_s
        while True:
            with self._lock:
                if self.flight.has_landed_after_flight:
                    return True
            if self._error is not None:
                raise LinkError(f"the simulated vehicle stopped: {self._error}") from self._error
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)

    def wait_sim_time(self, sim_time_s: float, timeout_s: float = 30.0) -> bool:
        """Wait until the simulated clock has reached ``sim_time_s``."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.sim_time_s >= sim_time_s:
                return True
            time.sleep(0.01)
        return False

    # --- the loop ----------------------------------------------------------------------------

    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as error:
            self._error = error
            log.exception("simulated vehicle stopped with an error")

    def _loop(self) -> None:
        assert self._transport is not None
        self._send_text(6, SIMULATOR_BANNER)
        last = time.monotonic()
        while not self._stop.is_set():
            for peer, data in self._transport.poll(0.002):
                self._receive_bytes(peer, data)
            if self._transport.new_peers:
                # Say it to every ground station that connects, not only at boot, and let
                # it hear a heartbeat at once rather than up to a second later.
                self._transport.new_peers = 0
                with self._lock:
                    self._send(self.flight.heartbeat_message())
                self._send_text(6, SIMULATOR_BANNER)
            now = time.monotonic()
            dt_wall = now - last
            last = now
            for msg in self._recv_pipe.release(now):
                self._handle(msg)
            with self._lock:
                # --auto-start waits for a GPS fix and for a mission (preloaded or uploaded).
                if self._auto_start and self.flight.gps_has_fix and self.flight.has_mission:
                    self._auto_start = False
                    self._start_by_itself()
                for when_s, msg in self.flight.drain_events():
                    self._send(msg, when_s)
                for when_s, msg in self.flight.step_timed(dt_wall * self.speedup):
                    self._send(msg, when_s)
                self._protocol_timers(now)
            self._flush(now)

    def _start_by_itself(self) -> None:
        ok, why = self.flight.arm()
        if ok:
            ok, why = self.flight.start_mission()
        if ok:
            self._send_text(6, "Mission started (sfap sim --auto-start)")
            log.info("simulated vehicle: armed and started the mission by itself")
        else:
            self._send_text(3, why)
            log.warning("simulated vehicle: could not start the mission: %s", why)

    def _receive_bytes(self, peer: object, data: bytes) -> None:
        parser = self._parsers.get(peer)
        if parser is None:
            parser = M.MAVLink(None)
            parser.robust_parsing = True
            self._parsers[peer] = parser
        try:
            msgs = parser.parse_buffer(data) or []
        except Exception:
            log.debug("unparsable bytes from %s", peer, exc_info=True)
            return
        now = time.monotonic()
        for msg in msgs:
            if msg.get_type() == "BAD_DATA":
                continue
            self._recv_pipe.offer(msg, now)

    def _send(self, msg: Any, sim_time_s: float | None = None) -> None:
        """Pack ``msg`` now (sequence number, tlog stamped at ``sim_time_s``, default now)
        and hand it to the faulty link."""
        data = bytes(msg.pack(self._mav))
        self._mav.seq = (self._mav.seq + 1) % 256
        name = msg.get_type()
        self.sent_counts[name] = self.sent_counts.get(name, 0) + 1
        if self._tlog is not None:
            when_s = self.flight.time_s if sim_time_s is None else sim_time_s
            stamp_us = round((self.flight.boot_utc_s + when_s) * 1e6)
            stamp_us = max(stamp_us, self._last_tlog_us)
            self._last_tlog_us = stamp_us
            self._tlog.write(struct.pack(">Q", stamp_us) + data)
        self._send_pipe.offer(data, time.monotonic())

    def _flush(self, now: float) -> None:
        assert self._transport is not None
        for data in self._send_pipe.release(now):
            self._transport.send(data)
        self._transport.flush()

    def _send_text(self, severity: int, text: str) -> None:
        with self._lock:
            self._send(M.MAVLink_statustext_message(severity, text.encode()[:50]))

    def _warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self._send_text(4, text)

    # --- message handling --------------------------------------------------------------------

    def _for_us(self, msg: Any) -> bool:
        target = getattr(msg, "target_system", 0)
        return target in (0, self.system_id)

    def _handle(self, msg: Any) -> None:
        name = msg.get_type()
        self.received_counts[name] = self.received_counts.get(name, 0) + 1
        handler: Callable[[Any], None] | None = getattr(self, f"_on_{name.lower()}", None)
        if handler is None or not self._for_us(msg):
            return
        with self._lock:
            handler(msg)

    def _ack(self, msg: Any, result: int, mission_type: int) -> None:
        self._send(
            M.MAVLink_mission_ack_message(msg.get_srcSystem(), msg.get_srcComponent(), result, mission_type)
        )

    def _request(self, upload: _Upload) -> None:
        if self.autopilot is Autopilot.ARDUPILOT:
            req = M.MAVLink_mission_request_message(
                upload.sysid, upload.compid, upload.expected, upload.mission_type
            )
        else:
            req = M.MAVLink_mission_request_int_message(
                upload.sysid, upload.compid, upload.expected, upload.mission_type
            )
        upload.last_request_s = time.monotonic()
        self._send(req)

    def _items_for_readback(self, mission_type: int) -> list[WireItem]:
        items = list(self._stored[mission_type])
        if self.autopilot is Autopilot.ARDUPILOT and mission_type == MISSION_TYPE_MISSION:
            if not items:
                items = [WireItem(0, 16, 0, 0, 0, 0, 0, 0, 0.0)]
            items[0] = self._home_item()
        return items

    def _home_item(self) -> WireItem:
        if not self.flight.gps_has_fix:
            return WireItem(0, 16, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0)
        h = self.flight.home
        alt_cm = int(_F32(h.alt_amsl_m) * _F32(100.0))
        return WireItem(
            0,
            16,
            0.0,
            0.0,
            0.0,
            0.0,
            round(h.lat_deg * 1e7),
            round(h.lon_deg * 1e7),
            float(_F32(alt_cm) / _F32(100.0)),
        )

    def _store(self, item: WireItem, mission_type: int) -> WireItem | int:
        if mission_type != MISSION_TYPE_MISSION:
            return (
                px4_store(item, mission_type)
                if self.autopilot is Autopilot.PX4
                else dataclasses.replace(
                    item,
                    param1=_f32(item.param1),
                    param2=_f32(item.param2),
                    param3=_f32(item.param3),
                    param4=_f32(item.param4),
                    z=_f32(item.z),
                )
            )
        if self.autopilot is Autopilot.ARDUPILOT:
            return ardupilot_store(item, self.vehicle_type)
        return px4_store(item)

    def _mission_changed(self, mission_type: int) -> None:
        if mission_type == MISSION_TYPE_MISSION:
            items = [wire_item_to_mission_item(w) for w in self._items_for_readback(0)]
            self.flight.set_mission(items)

    def _on_mission_count(self, msg: Any) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in _MISSION_TYPES:
            self._ack(msg, MAV_MISSION_UNSUPPORTED, mission_type)
            return
        up = self._upload
        if up is not None:
            if (up.sysid, up.compid) != (msg.get_srcSystem(), msg.get_srcComponent()):
                self._ack(msg, MAV_MISSION_DENIED, mission_type)
                return
            self._upload = None  # the same ground station restarts its upload
        ardupilot = self.autopilot is Autopilot.ARDUPILOT
        if ardupilot and self.flight.time_s < self.boot_delay_s:
            self._ack(msg, MAV_MISSION_NO_SPACE, mission_type)
            self._send_text(4, "Only 0 items are supported")
            return
        if self.faults.refuse == Refusal.NO_SPACE and msg.count > 0:
            self._ack(msg, MAV_MISSION_NO_SPACE, mission_type)
            self._send_text(4, f"Only {self.max_items} items are supported")
            return
        if msg.count > self.max_items:
            self._ack(msg, MAV_MISSION_NO_SPACE, mission_type)
            self._send_text(4, f"Only {self.max_items} items are supported")
            return
        self._completed = None
        if ardupilot:
            # ArduPilot truncates at once and writes items as they arrive.
            stored = self._stored[mission_type]
            keep = max(msg.count, 1) if mission_type == MISSION_TYPE_MISSION else msg.count
            del stored[keep:]
            self._mission_changed(mission_type)
        if msg.count == 0:
            if not ardupilot:
                self._stored[mission_type] = []
                self._mission_changed(mission_type)
            self._ack(msg, MAV_MISSION_ACCEPTED, mission_type)
            return
        now = time.monotonic()
        self._upload = _Upload(
            mission_type=mission_type,
            count=int(msg.count),
            sysid=msg.get_srcSystem(),
            compid=msg.get_srcComponent(),
            last_receive_s=now,
        )
        self._request(self._upload)

    def _on_mission_item(self, msg: Any) -> None:
        if self.autopilot is Autopilot.ARDUPILOT and self._upload is not None:
            self._warn_once("item", "got MISSION_ITEM; GCS should send MISSION_ITEM_INT")
        self._on_mission_item_int(msg)

    def _on_mission_item_int(self, msg: Any) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        up = self._upload
        ardupilot = self.autopilot is Autopilot.ARDUPILOT
        if up is None or up.mission_type != mission_type:
            done = self._completed
            if (
                not ardupilot
                and done is not None
                and done.mission_type == mission_type
                and msg.seq == done.count - 1
            ):
                # PX4: the last item again means our ACK was lost; send it again.
                self._ack(msg, done.result, mission_type)
            return
        if msg.seq != up.expected:
            if ardupilot:
                self._ack(msg, MAV_MISSION_INVALID_SEQUENCE, mission_type)
            return
        if (msg.get_srcSystem(), msg.get_srcComponent()) != (up.sysid, up.compid):
            self._ack(msg, MAV_MISSION_DENIED, mission_type)
            return
        wire = wire_item_from_message(msg)
        if self.faults.refuse == Refusal.INVALID and msg.seq == up.count // 2:
            result: WireItem | int = MAV_MISSION_INVALID
        elif ardupilot and mission_type == MISSION_TYPE_MISSION and msg.seq == 0:
            result = WireItem(0, 16, 0, 0, 0, 0, 0, 0, 0.0)  # home: ArduPilot keeps its own
        else:
            result = self._store(wire, mission_type)
        if isinstance(result, int):
            self._upload = None
            self._finish(msg, up, result)
            return
        up.last_receive_s = time.monotonic()
        if ardupilot:
            stored = self._stored[mission_type]
            if msg.seq < len(stored):
                stored[msg.seq] = result
            else:
                stored.append(result)
            # the flight reads the mission when the upload ends (_finish), not per item
        else:
            up.items.append(result)
        up.expected += 1
        if up.expected >= up.count:
            self._upload = None
            if not ardupilot:
                self._stored[mission_type] = list(up.items)
            self._finish(msg, up, MAV_MISSION_ACCEPTED)
            return
        self._request(up)

    def _finish(self, msg: Any, up: _Upload, result: int) -> None:
        self._completed = _Completed(up.mission_type, up.count, up.sysid, up.compid, result, time.monotonic())
        self._mission_changed(up.mission_type)
        self._ack(msg, result, up.mission_type)
        log.info(
            "simulated vehicle: upload of %d items (type %d) ended with MAV_MISSION_RESULT %d",
            up.count,
            up.mission_type,
            result,
        )

    def _protocol_timers(self, now: float) -> None:
        up = self._upload
        if up is None:
            return
        if now - up.last_receive_s > self.upload_timeout_s:
            self._upload = None
            self._completed = None
            self._mission_changed(up.mission_type)
            self._send(
                M.MAVLink_mission_ack_message(
                    up.sysid, up.compid, MAV_MISSION_OPERATION_CANCELLED, up.mission_type
                )
            )
            log.info("simulated vehicle: upload timed out at item %d of %d", up.expected, up.count)
            return
        if now - up.last_request_s > self.request_timeout_s:
            self._request(up)

    def _on_mission_request_list(self, msg: Any) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in _MISSION_TYPES:
            self._ack(msg, MAV_MISSION_UNSUPPORTED, mission_type)
            return
        if self._upload is not None:
            self._ack(msg, MAV_MISSION_DENIED, mission_type)
            return
        count = len(self._items_for_readback(mission_type))
        self._send(
            M.MAVLink_mission_count_message(msg.get_srcSystem(), msg.get_srcComponent(), count, mission_type)
        )

    def _answer_request(self, msg: Any, as_int: bool) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in _MISSION_TYPES:
            self._ack(msg, MAV_MISSION_UNSUPPORTED, mission_type)
            return
        if self._upload is not None:
            if self.autopilot is Autopilot.ARDUPILOT or not as_int:
                self._ack(msg, MAV_MISSION_DENIED, mission_type)
            # PX4 ignores requests during its own upload
            return
        items = self._items_for_readback(mission_type)
        if not 0 <= msg.seq < len(items):
            if as_int:
                self._send(
                    M.MAVLink_mission_count_message(
                        msg.get_srcSystem(), msg.get_srcComponent(), len(items), mission_type
                    )
                )
            self._ack(msg, MAV_MISSION_INVALID_SEQUENCE, mission_type)
            return
        build = _item_int_message if as_int else _item_float_message
        if not as_int and self.autopilot is Autopilot.ARDUPILOT:
            self._warn_once("request", "got MISSION_REQUEST; use MISSION_REQUEST_INT!")
        self._send(
            build(
                items[msg.seq],
                msg.seq,
                msg.get_srcSystem(),
                msg.get_srcComponent(),
                mission_type,
            )
        )

    def _on_mission_request_int(self, msg: Any) -> None:
        self._answer_request(msg, as_int=True)

    def _on_mission_request(self, msg: Any) -> None:
        self._answer_request(msg, as_int=False)

    def _on_mission_ack(self, msg: Any) -> None:
        # The end of a download (nothing to free here), or a ground station cancelling its
        # upload with an error result: stop requesting items.
        up = self._upload
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        mission_type = int(getattr(msg, "mission_type", 0))
        ours = up is not None and (up.sysid, up.compid) == source
        if ours and up is not None and up.mission_type == mission_type and msg.type != 0:
            self._upload = None
            self._mission_changed(mission_type)
            log.info("simulated vehicle: the ground station cancelled its upload")

    def _on_mission_clear_all(self, msg: Any) -> None:
        mission_type = int(getattr(msg, "mission_type", 0))
        if mission_type not in _MISSION_TYPES:
            self._ack(msg, MAV_MISSION_UNSUPPORTED, mission_type)
            return
        up = self._upload
        if up is not None and (up.sysid, up.compid) != (
            msg.get_srcSystem(),
            msg.get_srcComponent(),
        ):
            self._ack(msg, MAV_MISSION_ERROR, mission_type)
            return
        self._upload = None
        self._stored[mission_type] = []
        self._mission_changed(mission_type)
        self._ack(msg, MAV_MISSION_ACCEPTED, mission_type)

    def _on_mission_set_current(self, msg: Any) -> None:
        self.flight.set_current(int(msg.seq))

    # --- commands ----------------------------------------------------------------------------

    def _command_ack(self, msg: Any, command: int, result: int) -> None:
        self._send(
            M.MAVLink_command_ack_message(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
        )

    def _on_command_long(self, msg: Any) -> None:
        command = int(msg.command)
        params = (
            msg.param1,
            msg.param2,
            msg.param3,
            msg.param4,
            msg.param5,
            msg.param6,
            msg.param7,
        )
        result = self._run_command(command, params)
        self._command_ack(msg, command, result)

    def _on_command_int(self, msg: Any) -> None:
        command = int(msg.command)
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z)
        result = self._run_command(command, params)
        self._command_ack(msg, command, result)

    def _run_command(self, command: int, params: Sequence[float]) -> int:
        accepted, denied = M.MAV_RESULT_ACCEPTED, M.MAV_RESULT_DENIED
        failed, unsupported = M.MAV_RESULT_FAILED, M.MAV_RESULT_UNSUPPORTED
        flight = self.flight
        if command == 400:  # MAV_CMD_COMPONENT_ARM_DISARM
            if params[0] >= 0.5:
                ok, why = flight.arm()
            else:
                ok, why = flight.disarm(force=abs(params[1] - 21196) < 0.5)
            if not ok:
                self._send_text(3, why)
            return accepted if ok else failed
        if command == 176:  # MAV_CMD_DO_SET_MODE
            ok = flight.set_mode(int(params[0]), int(params[1]), int(params[2]))
            return accepted if ok else denied
        if command == 300:  # MAV_CMD_MISSION_START
            ok, why = flight.start_mission()
            if not ok:
                self._send_text(3, why)
            return accepted if ok else failed
        if command == 224:  # MAV_CMD_DO_SET_MISSION_CURRENT
            seq = int(params[0])
            if not 0 <= seq < len(flight.mission.items):
                return denied
            flight.set_current(seq)
            return accepted
        if command == 20:  # MAV_CMD_NAV_RETURN_TO_LAUNCH
            return accepted if flight.return_to_launch() else failed
        if command in (512, 520):  # REQUEST_MESSAGE / REQUEST_AUTOPILOT_CAPABILITIES
            if command == 520 or int(params[0]) == 148:
                self._send(self._autopilot_version())
                return accepted
            if int(params[0]) == 242:  # HOME_POSITION
                home = flight.home_position_message()
                if home is None:
                    return failed
                self._send(home)
                return accepted
            return unsupported
        if command in (511, 2504):  # SET_MESSAGE_INTERVAL, REQUEST_CAMERA_INFORMATION
            return accepted
        return unsupported

    def _autopilot_version(self) -> Any:
        # MAV_PROTOCOL_CAPABILITY: MISSION_FLOAT 1, MISSION_INT 4, COMMAND_INT 8,
        # MAVLINK2 8192, MISSION_FENCE 16384, MISSION_RALLY 32768
        capabilities = 1 | 4 | 8 | 8192 | 16384 | 32768
        version = (
            (4 << 24) | (5 << 16) | (7 << 8)
            if self.autopilot is Autopilot.ARDUPILOT
            else ((1 << 24) | (15 << 16))
        )
        return M.MAVLink_autopilot_version_message(
            capabilities, version, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 0xF00D
        )

    def _on_set_mode(self, msg: Any) -> None:
        self.flight.set_mode(int(msg.base_mode), *self.flight.split_custom_mode(msg.custom_mode))

    def _on_request_data_stream(self, msg: Any) -> None:
        return


def serve(
    vehicle: SimulatedVehicle,
    *,
    duration_s: float | None = None,
    until_landed: bool = False,
    poll_s: float = 0.05,
) -> str:
    """Keep a started ``vehicle`` running; return why it stopped: ``"duration"`` after
    ``duration_s`` wall seconds, ``"landed"`` once it has flown and landed (``until_landed``).
    Without either it runs until KeyboardInterrupt (Ctrl-C), which propagates."""
    deadline = None if duration_s is None else time.monotonic() + duration_s
    while True:
        if vehicle._error is not None:
            raise LinkError(f"the simulated vehicle stopped: {vehicle._error}")
        if until_landed and vehicle.wait_landed(0.0):
            return "landed"
        if deadline is not None and time.monotonic() >= deadline:
            return "duration"
        time.sleep(poll_s)
