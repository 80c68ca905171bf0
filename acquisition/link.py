"""A MAVLink connection to one vehicle, opened from a URL, with a lifecycle.

::

    with Link.open("serial:///dev/ttyUSB0:57600") as link:
        link.autopilot, link.target_system, link.vehicle_type
        link.send(message)
        link.recv({"MISSION_REQUEST", "MISSION_REQUEST_INT"}, timeout_s=1.5)

URLs (the scheme says who opens the connection):

==========================================  ================================================
``serial:///dev/ttyUSB0:57600``             serial device and baud rate (default 57600);
                                            ``serial://COM3:57600`` on Windows
``udpin://0.0.0.0:14550``                   listen for UDP datagrams on that address and port
``udpout://HOST:PORT``                      send UDP datagrams to HOST:PORT (we speak first)
``tcp://HOST:PORT``                         connect to a TCP server (SITL: tcp://127.0.0.1:5760)
``tcpin://HOST:PORT``                       accept one TCP connection on that address and port
==========================================  ================================================

The transport is a pymavlink ``mavutil`` connection (pyserial for serial ports), always
speaking MAVLink 2 whatever the process-wide pymavlink setting is.

Heartbeat: :meth:`Link.open` sends our own GCS heartbeat from a background thread, once per
second from the moment the port is open (a ``udpout`` peer learns our address from it) until
:meth:`Link.close`; it then waits for a heartbeat from an autopilot component (GCS, gimbal,
camera and other non-autopilot heartbeats are ignored) and identifies the autopilot, the
vehicle type and the target system and component. Sends from the thread and from the caller are
serialised by one lock, which also covers parsing (the signing timestamp is shared state).

Observing the whole traffic: :meth:`Link.recv` hands back only what concerns this ground
station and its vehicle. A program that must see everything (a telemetry log, as MAVProxy and
QGroundControl write one; link quality from the sequence numbers of every sender) passes
``on_message`` to :meth:`Link.open`: it is called with ``(message, rx_time_utc_s)`` for every
valid message the link parses, before any filtering, from every system and component and
whoever it is addressed to, including those read while :meth:`Link.open` waits for the
vehicle's heartbeat. It runs in the thread that reads (the caller of :meth:`Link.open` and
:meth:`Link.recv`), in arrival order; what it raises propagates to that caller. Bytes that do
not parse (BAD_DATA, including messages refused by signing) are not handed to it. The link
reads only inside :meth:`Link.open` and :meth:`Link.recv`: a program that only observes keeps
calling ``recv`` and may ignore what it returns (the observer has seen it already).

Signing (MAVLink 2): with a 32-byte key every message we send is signed; with
``require_signing`` every unsigned or wrongly signed incoming message is refused, except
RADIO_STATUS, which SiK telemetry radios inject unsigned (as the MAVLink signing guide allows).
:func:`acquisition.signing.load_signing_key` reads a key from a file or the environment variable
``SFAP_SIGNING_KEY``; see it for the accepted forms.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Collection
from types import TracebackType
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from planner.mission import Autopilot, VehicleType

from .clock import WALL_CLOCK, Clock, WallClock
from .errors import LinkError
from .link_port import LinkInputError, LinkUrl, close_quietly, open_port, watch_for_drops
from .signing import SIGNING_KEY_ENV

log = logging.getLogger(__name__)


HEARTBEAT_INTERVAL_S = 1.0

_MAV_TYPE_GCS = 6
_MAV_AUTOPILOT = {
    mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA: Autopilot.ARDUPILOT,
    mavlink2.MAV_AUTOPILOT_PX4: Autopilot.PX4,
}
_MULTIROTOR_TYPES = frozenset({2, 3, 4, 13, 14, 15, 29, 35})
_VTOL_TYPES = frozenset({19, 20, 21, 22, 23, 24, 25})
_RADIO_STATUS_ID = mavlink2.MAVLINK_MSG_ID_RADIO_STATUS

#: ``on_message(message, rx_time_utc_s)``: sees every valid message the link parses (module
#: docstring). ``rx_time_utc_s``: when it was read, POSIX seconds, UTC, this computer's clock.
MessageObserver = Callable[[Any, float], None]


def vehicle_type_from_mav_type(mav_type: int) -> VehicleType | None:
    """MAV_TYPE -> :class:`VehicleType`; None for vehicles that are none of the three."""
    if mav_type == 1:
        return VehicleType.FIXED_WING
    if mav_type in _MULTIROTOR_TYPES:
        return VehicleType.MULTIROTOR
    if mav_type in _VTOL_TYPES:
        return VehicleType.VTOL
    return None


# --- the link -----------------------------------------------------------------------------------


class Link:
    """An open MAVLink connection to one vehicle. Create it with :meth:`Link.open`.

    Attributes set when the vehicle's heartbeat is heard: ``autopilot``, ``vehicle_type``
    (None for a vehicle that is not a multirotor, fixed wing or VTOL), ``mav_type`` (MAV_TYPE),
    ``target_system``, ``target_component``.
    """

    autopilot: Autopilot
    vehicle_type: VehicleType | None
    mav_type: int
    target_system: int
    target_component: int

    def __init__(
        self,
        url: LinkUrl,
        conn: Any,
        *,
        source_system: int,
        source_component: int,
        signing_key: bytes | None,
        require_signing: bool,
        on_message: MessageObserver | None = None,
        clock: Clock = WALL_CLOCK,
    ) -> None:
        self.url = url.text
        self.clock = clock
        self._party: object = None
        self._on_message = on_message
        self._parsed = url
        self._conn = conn
        self.source_system = source_system
        self.source_component = source_component
        self.signing = signing_key is not None
        self.require_signing = require_signing
        self.refused_unsigned = 0
        self.bad_data = 0
        self.last_heartbeat_s: float | None = None  # clock.monotonic() of the vehicle's last
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._dropped: str | None = None
        self._closed = False
        self._heartbeat_thread: threading.Thread | None = None
        self.target_system = 0
        self.target_component = 0
        # Always MAVLink 2 (signing needs it), whatever dialect module mavutil loaded globally.
        conn.mav = mavlink2.MAVLink(
            conn, srcSystem=source_system, srcComponent=source_component, use_native=False
        )
        conn.mav.robust_parsing = True
        conn.WIRE_PROTOCOL_VERSION = "2.0"
        conn.first_byte = False
        if signing_key is not None:
            conn.setup_signing(
                signing_key,
                sign_outgoing=True,
                allow_unsigned_callback=self._allow_unsigned,
                link_id=0,
            )
        watch_for_drops(conn, url.scheme, self._on_drop)

    # --- opening ---------------------------------------------------------------------------------

    @classmethod
    def open(
        cls,
        url: str,
        *,
        heartbeat_timeout_s: float = 10.0,
        signing_key: bytes | None = None,
        require_signing: bool = False,
        source_system: int = 255,
        source_component: int = 190,
        on_message: MessageObserver | None = None,
        clock: Clock = WALL_CLOCK,
    ) -> Link:
        """Open ``url``, start our heartbeat, and wait for the vehicle's heartbeat.

        ``heartbeat_timeout_s``: how long to wait for an autopilot heartbeat (s).
        ``source_system``/``source_component``: our MAVLink ids (255/190 = a ground station).
        ``on_message(message, rx_time_utc_s)``: called for every valid message parsed, before
        the filtering of :meth:`recv`, from the first one read while waiting for the
        heartbeat (see the module docstring).
        ``clock``: what the link's waits are measured on (:mod:`acquisition.clock`; tests pass a
        :class:`~acquisition.clock.VirtualClock`, and the thread that opens the link is then
        one of its parties until :meth:`close`).
        Raises :class:`LinkError` with what to check when the port cannot be opened or no
        autopilot is heard. ``require_signing`` needs a ``signing_key``.
        """
        parsed = LinkUrl.parse(url)
        if require_signing and signing_key is None:
            raise LinkInputError(
                f"--require-signing needs a key: give --signing-key FILE or set {SIGNING_KEY_ENV}"
            )
        if signing_key is not None and len(signing_key) != 32:
            raise LinkInputError(
                f"a MAVLink signing key is 32 bytes, this one has {len(signing_key)}; "
                f"see load_signing_key for the key file forms"
            )
        conn = open_port(parsed, source_system, source_component, heartbeat_timeout_s, clock)
        link: Link | None = None
        try:
            link = cls(
                parsed,
                conn,
                source_system=source_system,
                source_component=source_component,
                signing_key=signing_key,
                require_signing=require_signing,
                on_message=on_message,
                clock=clock,
            )
            link._party = clock.join()
            link._start_heartbeat()
            link._wait_for_vehicle(heartbeat_timeout_s)
        except BaseException:
            if link is not None:
                link.close()
            else:
                close_quietly(conn)
            raise
        return link

    def __enter__(self) -> Link:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def close(self) -> None:
        """Stop the heartbeat and close the port. Safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        self.clock.interrupt()
        if self._heartbeat_thread is not None:
            self._heartbeat_thread.join(timeout=2.0)
        with self._lock:
            close_quietly(self._conn)
        if self._party is not None:
            self.clock.leave(self._party)
            self._party = None
        log.debug("closed %s", self.url)

    @property
    def closed(self) -> bool:
        return self._closed

    # --- traffic ---------------------------------------------------------------------------------

    @property
    def bytes_sent(self) -> int:
        return int(self._conn.mav.total_bytes_sent)

    @property
    def bytes_received(self) -> int:
        return int(self._conn.mav.total_bytes_received)

    def send(self, message: Any) -> None:
        """Send one pymavlink message (signed when a key is set)."""
        self._check_open()
        with self._lock:
            try:
                self._conn.mav.send(message)
            except OSError as error:
                raise self._drop_error(f"sending failed: {error}") from error

    def recv(
        self,
        types: Collection[str] | None = None,
        timeout_s: float = 0.0,
        *,
        all_components: bool = False,
    ) -> Any | None:
        """The next message from the vehicle whose type is in ``types`` (any when None).

        Waits up to ``timeout_s`` seconds; returns None when nothing matching came. Messages
        from other systems, addressed to another ground station, or (unless
        ``all_components``) from another component of the vehicle are skipped (the
        ``on_message`` observer of :meth:`open` still sees them). Raises :class:`LinkError`
        when the link dropped.
        """
        deadline = self.clock.monotonic() + timeout_s
        while True:
            message = self._recv_one()
            if message is not None:
                if self._wanted(message, types, all_components):
                    return message
                continue
            remaining = deadline - self.clock.monotonic()
            if remaining <= 0:
                return None
            self._wait_for_bytes(min(remaining, 0.1))

    # --- internals -------------------------------------------------------------------------------

    def _wait_for_bytes(self, timeout_s: float) -> None:
        if isinstance(self.clock, WallClock):
            self._conn.select(timeout_s)  # mavutil's own wait (it knows ports without a descriptor)
            return
        fd = getattr(self._conn, "fd", None)
        if fd is None:
            self.clock.sleep(timeout_s)
        else:
            self.clock.wait_readable([fd], timeout_s)

    def _on_drop(self, detail: str) -> None:
        self._dropped = detail

    def _check_open(self) -> None:
        if self._closed:
            raise LinkError(f"the link {self.url} is closed")
        if self._dropped is not None:
            raise self._drop_error(self._dropped)

    def _drop_error(self, detail: str) -> LinkError:
        return LinkError(
            f"the link {self.url} dropped ({detail}); check the cable or radio and that the "
            f"vehicle is still powered, then connect again"
        )

    def _recv_one(self) -> Any | None:
        self._check_open()
        with self._lock:
            try:
                message = self._conn.recv_msg()
            except OSError as error:  # includes serial.SerialException
                self._dropped = str(error) or type(error).__name__
                raise self._drop_error(self._dropped) from error
        if message is None:
            if self._dropped is not None:
                raise self._drop_error(self._dropped)
            return None
        # outside the lock: the observer may be slow (a disk write) and must not hold up our
        # heartbeat; a failure of its own is not a link drop and reaches the caller as it is
        if self._on_message is not None and message.get_type() != "BAD_DATA":
            if isinstance(self.clock, WallClock):
                # mavutil stamps every message it parses with time.time() (its receive time)
                rx_time_utc_s = float(getattr(message, "_timestamp", 0.0) or time.time())
            else:
                rx_time_utc_s = self.clock.time()
            self._on_message(message, rx_time_utc_s)
        return message

    def _wanted(self, message: Any, types: Collection[str] | None, all_components: bool) -> bool:
        kind = message.get_type()
        if kind == "BAD_DATA":
            self.bad_data += 1
            return False
        if self.target_system:
            if message.get_srcSystem() != self.target_system:
                return False
            if kind == "HEARTBEAT" and message.get_srcComponent() == self.target_component:
                self.last_heartbeat_s = self.clock.monotonic()
            if not all_components and message.get_srcComponent() != self.target_component:
                return False
        addressee = getattr(message, "target_system", 0)
        if addressee not in (0, self.source_system):
            return False
        return types is None or kind in types

    def _allow_unsigned(self, mav: Any, message_id: int) -> bool:
        if not self.require_signing:
            return True
        if message_id == _RADIO_STATUS_ID:
            return True
        self.refused_unsigned += 1
        return False

    def _heartbeat_message(self) -> Any:
        return mavlink2.MAVLink_heartbeat_message(
            type=_MAV_TYPE_GCS,
            autopilot=mavlink2.MAV_AUTOPILOT_INVALID,
            base_mode=0,
            custom_mode=0,
            system_status=mavlink2.MAV_STATE_ACTIVE,
            mavlink_version=3,
        )

    def _start_heartbeat(self) -> None:
        def beat() -> None:
            try:
                while not self._stop.is_set():
                    try:
                        with self._lock:
                            if self._closed:
                                return
                            self._conn.mav.send(self._heartbeat_message())
                    except OSError as error:
                        log.debug("heartbeat not sent on %s: %s", self.url, error)
                    self.clock.wait_event(self._stop, HEARTBEAT_INTERVAL_S)
            finally:
                self.clock.leave(party)

        thread = threading.Thread(target=beat, name=f"sfap-heartbeat {self.url}", daemon=True)
        party = self.clock.join(thread)  # a party from before it starts: time waits for it
        self._heartbeat_thread = thread
        try:
            thread.start()
        except BaseException:
            self.clock.leave(party)
            raise

    def _wait_for_vehicle(self, timeout_s: float) -> None:
        deadline = self.clock.monotonic() + timeout_s
        others: set[str] = set()
        while True:
            remaining = deadline - self.clock.monotonic()
            if remaining <= 0:
                raise LinkError(self._no_heartbeat_message(timeout_s, others))
            message = self.recv({"HEARTBEAT"}, timeout_s=remaining)
            if message is None:
                continue
            autopilot = _MAV_AUTOPILOT.get(int(message.autopilot))
            if int(message.type) == _MAV_TYPE_GCS or autopilot is None:
                if int(message.type) != _MAV_TYPE_GCS and int(message.autopilot) != 8:
                    others.add(
                        f"system {message.get_srcSystem()} component "
                        f"{message.get_srcComponent()} (MAV_AUTOPILOT {message.autopilot})"
                    )
                continue
            self.autopilot = autopilot
            self.mav_type = int(message.type)
            self.vehicle_type = vehicle_type_from_mav_type(self.mav_type)
            self.target_system = message.get_srcSystem()
            self.target_component = message.get_srcComponent()
            self.last_heartbeat_s = self.clock.monotonic()
            log.info(
                "%s: %s (MAV_TYPE %d), system %d component %d%s",
                self.url,
                self.autopilot.value,
                self.mav_type,
                self.target_system,
                self.target_component,
                ", signed" if self.signing else "",
            )
            return

    def _no_heartbeat_message(self, timeout_s: float, others: set[str]) -> str:
        received = self.bytes_received
        parts = [f"no heartbeat from an autopilot on {self.url} within {timeout_s:g} s"]
        if others:
            parts.append(
                "; heard only autopilots sfap does not support (ArduPilot and PX4 are): "
                + ", ".join(sorted(others))
            )
        elif received == 0:
            parts.append(" (nothing at all was received)")
        else:
            parts.append(f" ({received} bytes received")
            if self.bad_data and received > 0:
                parts.append(", none of them valid MAVLink")
            parts.append(")")
        if self.refused_unsigned:
            parts.append(
                f"; {self.refused_unsigned} unsigned or wrongly signed messages were refused "
                f"because signing is required: check that the vehicle signs with the same key"
            )
        return "".join(parts) + "; " + self._parsed.no_vehicle_hint()
