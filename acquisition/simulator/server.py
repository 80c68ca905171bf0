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
    MissionResult.INVALID_SEQUENCE and carries on; re-requests after 1 s without an item and
    cancels (MissionResult.OPERATION_CANCELLED) after 8 s; writes items as they arrive, so a
    failed upload leaves a partial mission; stores home as item 0 (what is uploaded as item 0
    is ignored: home reads back as zeros until the GPS has a fix, then as the home position);
    refuses uploads with MissionResult.NO_SPACE ("Only 0 items are supported") for
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
  AUTOPILOT_VERSION (148) or HOME_POSITION (242), SET_MESSAGE_INTERVAL (511; UNSUPPORTED for
  a message it cannot send), answered with COMMAND_ACK; REQUEST_DATA_STREAM (no answer, as
  ArduPilot).
- Parameters (:mod:`.parameters`): PARAM_REQUEST_READ, PARAM_SET and PARAM_REQUEST_LIST
  answered with PARAM_VALUE, with ArduPilot SITL's defaults for the parameters sfap's
  missions depend on (RTL_AUTOLAND 0 on a plane, CAM1_TYPE 1); as ArduPlane, it refuses to
  arm (COMMAND_ACK FAILED, STATUSTEXT "PreArm: DO_LAND_START set and RTL_AUTOLAND disabled",
  repeated every 30 s while disarmed) a mission with DO_LAND_START while RTL_AUTOLAND is 0;
  ``auto_start`` tries again once a second.
- Telemetry: as ArduPilot on a serial port, only HEARTBEAT and event messages until a ground
  station asks for streams (``streams_on_request``, the ArduPilot flavour's default).
- Optionally the camera's card (:class:`.camera.FrameCard`): a small JPEG per photo, stamped
  by a camera clock that is off by a set offset, with frames dropped or added on request.
- Every ground station that connects gets a HEARTBEAT and the banner at once.
- Optionally a .tlog of what it sends (before link faults): per packet an 8-byte big-endian
  microsecond UTC time stamp (simulated time) then the raw packet, as MAVProxy and QGC write.

Every timer (re-requests, cancellation, latency, the flight's steps) runs on the vehicle's clock
(``clock``: the wall clock, or a :class:`acquisition.clock.VirtualClock` in tests); the flight,
the boot delay and the GPS fix run on flight time, ``speedup`` x that clock.

A message is answered in the loop iteration that receives it, and what the link holds back
(latency, baud rate) leaves when it falls due, not at the next step of the flight.

The parts live in modules of their own: :mod:`.faults` (fault injection), :mod:`.storage` (how
each autopilot stores items), :mod:`.transport` (URLs and sockets), :mod:`.flight` (the flight
and its telemetry); this module is the vehicle and its protocol.
"""

from __future__ import annotations

import logging
import math
import random
import struct
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO, Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from planner.errors import InputError
from planner.mission import Autopilot, HomePosition, MissionItem, VehicleType

from ..clock import WALL_CLOCK, Clock
from ..errors import LinkError
from ..mavlink_items import (
    MissionType,
)
from .camera import FrameCard
from .commands import VehicleCommands
from .faults import FaultConfig, FaultStats, FaultyPipe
from .flight import FlightConfig, FlightSimulator
from .missions import VehicleMissions
from .parameters import VehicleParameters
from .transport import Transport, parse_listen_url

log = logging.getLogger(__name__)

SIMULATOR_BANNER = "sfap simulated vehicle"

#: Where the simulated vehicle stands when nobody says otherwise (a field near Zaragoza).
DEFAULT_HOME = HomePosition(lat_deg=41.6488, lon_deg=-0.8891, alt_amsl_m=210.0)

M = mavlink2  # the message set (ardupilotmega includes common)

#: Longest wait for bytes between two steps of the flight (wall s). Replies do not wait for it:
#: a message is answered in the loop iteration that received it.
_POLL_S = 0.002


# --- the vehicle --------------------------------------------------------------------------------


class SimulatedVehicle(VehicleCommands):
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
    ``component_id`` its MAVLink identity; ``clock`` what its loop and timers run on (its
    thread is a party of a :class:`~acquisition.clock.VirtualClock`); ``streams_on_request``:
    periodic telemetry only once a ground station asks for it
    (SET_MESSAGE_INTERVAL or REQUEST_DATA_STREAM), as
    ArduPilot on a serial port (default: True for ArduPilot, False for PX4; see
    :mod:`.flight`); ``follow_mission_home``: before its first flight the vehicle moves to
    the home of the mission it is given (ArduPilot: the uploaded item 0; PX4: the first
    positional item, on the ground at the current elevation), so that a simulated flight does
    not start kilometres away; ``frames``: the camera card the photos are written to.
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
        streams_on_request: bool | None = None,
        follow_mission_home: bool = False,
        frames: FrameCard | None = None,
        clock: Clock = WALL_CLOCK,
    ) -> None:
        if not (speedup > 0 and math.isfinite(speedup)):
            raise InputError(f"speedup is {speedup}; give a positive number (1 = real time)")
        self.autopilot = Autopilot(autopilot)
        self.vehicle_type = VehicleType(vehicle_type)
        self.faults = faults if faults is not None else FaultConfig()
        self.speedup = float(speedup)
        self.clock = clock
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

        self.lock = threading.RLock()
        self._warned: set[str] = set()
        self._mav = M.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self._parsers: dict[object, Any] = {}
        if link_baud is not None and link_baud <= 0:
            raise InputError(f"link_baud is {link_baud}; give a positive baud rate or None")
        self.link_baud = link_baud
        self._send_pipe = FaultyPipe(self.faults, random.Random(self.faults.seed * 2 + 1), baud=link_baud)
        self._recv_pipe = FaultyPipe(
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
            boot_utc_s=self.clock.time(),
            streams_on_request=ardupilot if streams_on_request is None else streams_on_request,
        )
        self.streams_on_request = ardupilot if streams_on_request is None else streams_on_request
        self.follow_mission_home = follow_mission_home
        self.frames = frames
        self.missions = VehicleMissions(self)
        self.params = VehicleParameters(self.autopilot, self.vehicle_type)
        self._prearm_said_s: float | None = None  # flight time of the last PreArm text
        self._next_start_try_s = 0.0
        self._transport: Transport | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._tlog: IO[bytes] | None = None
        self._last_tlog_us = 0
        self._error: BaseException | None = None
        self.received_counts: dict[str, int] = {}
        self.sent_counts: dict[str, int] = {}
        self._auto_start = False
        self._auto_start_waits = False
        self._said_waiting = False
        self._party: object = None
        self._caller_parties: list[object] = []

    # --- lifecycle ---------------------------------------------------------------------------

    def __enter__(self) -> SimulatedVehicle:
        """Start; the thread that enters is a party of the vehicle's clock until the block
        ends: on a :class:`~acquisition.clock.VirtualClock`, simulated time then stands still
        while the block computes (its checks see the vehicle as it was when it last waited)."""
        self.start()
        self._caller_parties.append(self.clock.join())
        return self

    def __exit__(self, *exc: object) -> None:
        try:
            self.stop()
        finally:
            if self._caller_parties:
                self.clock.leave(self._caller_parties.pop())

    def start(self) -> None:
        """Open the socket and start the background thread."""
        if self._thread is not None:
            return
        self._transport = Transport(self.address)
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
        self._party = self.clock.join(self._thread)  # a party from before it starts
        try:
            self._thread.start()
        except BaseException:
            self.clock.leave(self._party)
            raise

    def stop(self) -> None:
        """Stop the thread and close the socket and the tlog."""
        self._stop.set()
        self.clock.interrupt()
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
        with self.lock:
            return self.flight.time_s

    @property
    def send_stats(self) -> FaultStats:
        return self._send_pipe.stats

    @property
    def receive_stats(self) -> FaultStats:
        return self._recv_pipe.stats

    def stored_mission(self, mission_type: int = MissionType.MISSION) -> list[MissionItem]:
        """A copy of the stored mission as a ground station would read it back
        (ArduPilot: home at index 0)."""
        return self.missions.stored_mission(mission_type)

    def load_mission(self, items: Sequence[MissionItem], mission_type: int = 0) -> None:
        """Store ``items`` as if uploaded (ArduPilot: give the items without home)."""
        self.missions.load_mission(items, mission_type)

    def corrupt_stored_item(self, seq: int, **changes: Any) -> None:
        """Change stored item ``seq`` (index as read back) behind the protocol's back, so a
        test can prove that a verification notices. ``changes`` are MissionItem fields."""
        self.missions.corrupt_stored_item(seq, **changes)

    def auto_start(self, *, wait_for_telemetry: bool = False) -> None:
        """Arm and start the mission (AUTO) as soon as the GPS has a fix and a mission is
        stored, once; as a ground station would with ARM_DISARM and MISSION_START. With
        ``wait_for_telemetry`` it also waits until a ground station has asked for telemetry
        (a monitor does at once): a crew starts the flight once the flight is being watched."""
        with self.lock:
            self._auto_start = True
            self._auto_start_waits = wait_for_telemetry

    def wait_landed(self, timeout_s: float) -> bool:
        """Wait (wall seconds) until the vehicle has flown and landed; True if it has."""
        deadline = time.monotonic() + timeout_s
        while True:
            with self.lock:
                if self.flight.has_landed_after_flight:
                    return True
            if self._error is not None:
                raise LinkError(f"the simulated vehicle stopped: {self._error}") from self._error
            if time.monotonic() >= deadline:
                return False
            self.clock.sleep(0.02)

    def wait_sim_time(self, sim_time_s: float, timeout_s: float = 30.0) -> bool:
        """Wait until the simulated clock has reached ``sim_time_s``."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.sim_time_s >= sim_time_s:
                return True
            self.clock.sleep(0.01)
        return False

    # --- the loop ----------------------------------------------------------------------------

    def _run(self) -> None:
        try:
            self._loop()
        except BaseException as error:
            self._error = error
            log.exception("simulated vehicle stopped with an error")
        finally:
            self.clock.leave(self._party)

    def _loop(self) -> None:
        assert self._transport is not None
        self.send_text(6, SIMULATOR_BANNER)
        last = self.clock.monotonic()
        while not self._stop.is_set():
            for peer, data in self._transport.poll(self._poll_timeout_s(self.clock.monotonic()), self.clock):
                self._receive_bytes(peer, data)
            if self._transport.new_peers:
                # Say it to every ground station that connects, not only at boot, and let
                # it hear a heartbeat at once rather than up to a second later.
                self._transport.new_peers = 0
                with self.lock:
                    self.send(self.flight.heartbeat_message())
                self.send_text(6, SIMULATOR_BANNER)
            now = self.clock.monotonic()
            dt_wall = now - last
            last = now
            for msg in self._recv_pipe.release(now):
                self._handle(msg)
            # Answers go out as soon as they are made, before the flight steps: the clock is
            # read again because what was just sent is stamped later than ``now``.
            self._flush(self.clock.monotonic())
            with self.lock:
                # --auto-start waits for a GPS fix and for a mission (preloaded or uploaded).
                if self._auto_start and self.flight.gps_has_fix and self.flight.has_mission:
                    if self._auto_start_waits and not self.flight.telemetry_requested:
                        if not self._said_waiting:
                            self._said_waiting = True
                            self.send_text(6, "Auto-start: waiting for a GCS to ask telemetry")
                            log.info(
                                "simulated vehicle: mission stored; waiting for a ground station to "
                                "ask for telemetry (sfap monitor) before starting"
                            )
                    elif self.flight.time_s >= self._next_start_try_s:
                        # a crew tries again (once a second) while a pre-arm check refuses
                        self._next_start_try_s = self.flight.time_s + 1.0
                        self._auto_start = not self._start_by_itself()
                if self.flight.gps_has_fix:
                    self._repeat_prearm()
                for when_s, msg in self.flight.drain_events():
                    self.send(msg, when_s)
                for when_s, msg in self.flight.step_timed(dt_wall * self.speedup):
                    self.send(msg, when_s)
                self._write_frames()
                self.missions.timers(now)
            self._flush(self.clock.monotonic())

    def _write_frames(self) -> None:
        card = self.frames
        if card is None:
            return
        shots = self.flight.shots
        while card.photos < len(shots):
            card.photo(shots[card.photos].utc_s)

    def _poll_timeout_s(self, now: float) -> float:
        """How long the loop may wait for bytes: at most :data:`_POLL_S` (the flight's step),
        less when a message held back by the link (latency, baud rate) falls due sooner, so it
        leaves exactly when the link lets it and not up to a step later."""
        timeout = _POLL_S
        for pipe in (self._send_pipe, self._recv_pipe):
            due = pipe.next_due_s()
            if due is not None:
                timeout = min(timeout, max(due - now, 0.0))
        return timeout

    def prearm_failure(self) -> str | None:
        """Why the vehicle refuses to arm now (ArduPilot's PreArm text), or None."""
        if self.autopilot is not Autopilot.ARDUPILOT:
            return None
        return self.params.prearm_failure(w.command for w in self.missions.stored[MissionType.MISSION])

    def _repeat_prearm(self) -> None:
        """While disarmed and failing a pre-arm check, say why every 30 s of flight time, as
        ArduPilot's AP_Arming::update does (PREARM_DISPLAY_PERIOD 30)."""
        if self.flight.armed or self.autopilot is not Autopilot.ARDUPILOT:
            return
        now = self.flight.time_s
        if self._prearm_said_s is not None and now - self._prearm_said_s < 30.0:
            return
        why = self.prearm_failure()
        if why is not None:
            self._prearm_said_s = now
            self.send_text(2, why)

    def _start_by_itself(self) -> bool:
        """Arm and start the mission; False when the vehicle refuses (it is tried again)."""
        refused = self.prearm_failure()
        if refused is not None:
            if self._prearm_said_s is None or self.flight.time_s - self._prearm_said_s >= 30.0:
                self._prearm_said_s = self.flight.time_s
                self.send_text(2, refused)
                log.warning("simulated vehicle: refuses to arm: %s", refused)
            return False
        ok, why = self.flight.arm()
        if ok:
            ok, why = self.flight.start_mission()
        if ok:
            self.send_text(6, "Mission started (sfap sim --auto-start)")
            log.info("simulated vehicle: armed and started the mission by itself")
        else:
            self.send_text(3, why)
            log.warning("simulated vehicle: could not start the mission: %s", why)
        return True

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
        now = self.clock.monotonic()
        for msg in msgs:
            if msg.get_type() == "BAD_DATA":
                continue
            self._recv_pipe.offer(msg, now)

    def send(self, msg: Any, sim_time_s: float | None = None) -> None:
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
        self._send_pipe.offer(data, self.clock.monotonic())

    def _flush(self, now: float) -> None:
        assert self._transport is not None
        for data in self._send_pipe.release(now):
            self._transport.send(data)
        self._transport.flush()

    def send_text(self, severity: int, text: str) -> None:
        with self.lock:
            self.send(M.MAVLink_statustext_message(severity, text.encode()[:50]))

    def warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.send_text(4, text)

    # --- message handling --------------------------------------------------------------------

    def _for_us(self, msg: Any) -> bool:
        target = getattr(msg, "target_system", 0)
        return target in (0, self.system_id)

    def _handle(self, msg: Any) -> None:
        name = msg.get_type()
        self.received_counts[name] = self.received_counts.get(name, 0) + 1
        handler: Callable[[Any], None] | None = getattr(self.missions, f"on_{name.lower()}", None) or getattr(
            self, f"_on_{name.lower()}", None
        )
        if handler is None or not self._for_us(msg):
            return
        with self.lock:
            handler(msg)


def serve(
    vehicle: SimulatedVehicle,
    *,
    duration_s: float | None = None,
    until_landed: bool = False,
    poll_s: float = 0.05,
    linger_s: float = 0.0,
) -> str:
    """Keep a started ``vehicle`` running; return why it stopped: ``"duration"`` after
    ``duration_s`` wall seconds, ``"landed"`` once it has flown and landed (``until_landed``;
    ``linger_s`` wall seconds later when a ground station asked for telemetry, so that it sees
    the landing and the disarm and can still talk to the vehicle).
    Without either it runs until KeyboardInterrupt (Ctrl-C), which propagates."""
    deadline = None if duration_s is None else time.monotonic() + duration_s
    landed_at: float | None = None
    while True:
        if vehicle._error is not None:
            raise LinkError(f"the simulated vehicle stopped: {vehicle._error}")
        if until_landed and landed_at is None and vehicle.wait_landed(0.0):
            landed_at = time.monotonic()
        if landed_at is not None:
            watched = vehicle.flight.telemetry_requested  # a ground station may still be reading
            if not watched or time.monotonic() - landed_at >= linger_s:
                return "landed"
        if deadline is not None and time.monotonic() >= deadline:
            return "duration"
        time.sleep(poll_s)
