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
:func:`load_signing_key` reads a key from a file or the environment variable
``SFAP_SIGNING_KEY``; see it for the accepted forms.
"""

from __future__ import annotations

import errno
import hashlib
import logging
import os
import re
import socket
import threading
import time
from collections.abc import Callable, Collection
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from planner.errors import InputError
from planner.mission import Autopilot, VehicleType

from .clock import WALL_CLOCK, Clock, WallClock
from .errors import LinkError

log = logging.getLogger(__name__)


class LinkInputError(InputError, LinkError):
    """A link option is wrong (a URL that is not one, a signing key file that cannot be read
    or is not a key): bad usage, exit code 2, not a failed connection."""


#: The URL schemes :meth:`Link.open` accepts, with an example each (used in error messages).
URL_EXAMPLES: dict[str, str] = {
    "serial": "serial:///dev/ttyUSB0:57600",
    "udpin": "udpin://0.0.0.0:14550",
    "udpout": "udpout://192.168.4.1:14550",
    "tcp": "tcp://127.0.0.1:5760",
    "tcpin": "tcpin://0.0.0.0:5760",
}
DEFAULT_BAUD = 57600
SIGNING_KEY_ENV = "SFAP_SIGNING_KEY"
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


# --- URLs ---------------------------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class LinkUrl:
    """A parsed link URL. ``device``/``baud`` for serial, ``host``/``port`` for the others."""

    text: str
    scheme: str
    host: str | None = None
    port: int | None = None
    device: str | None = None
    baud: int | None = None

    @classmethod
    def parse(cls, url: str) -> LinkUrl:
        """Parse ``url``; raises :class:`LinkError` naming the valid forms when it is wrong."""
        valid = ", ".join(URL_EXAMPLES.values())
        match = re.fullmatch(r"([A-Za-z][A-Za-z0-9+.-]*)://(.*)", url.strip())
        if match is None:
            raise LinkInputError(f"{url!r} is not a link URL; use one of: {valid}")
        scheme, rest = match.group(1).lower(), match.group(2)
        if scheme not in URL_EXAMPLES:
            raise LinkInputError(
                f"unknown link scheme {scheme!r} in {url!r}; valid schemes are "
                f"{', '.join(URL_EXAMPLES)} (for example {valid})"
            )
        if scheme == "serial":
            device, baud = rest, DEFAULT_BAUD
            head, sep, tail = rest.rpartition(":")
            if sep and tail.isdigit():
                device, baud = head, int(tail)
            elif sep and tail:
                raise LinkInputError(
                    f"baud rate {tail!r} in {url!r} is not a number; for example {URL_EXAMPLES['serial']}"
                )
            if not device:
                raise LinkInputError(f"no serial device in {url!r}; for example {URL_EXAMPLES['serial']}")
            if baud <= 0:
                raise LinkInputError(f"baud rate {baud} in {url!r} must be positive (57600, 115200...)")
            return cls(text=url, scheme=scheme, device=device, baud=baud)
        host, sep, port_text = rest.rpartition(":")
        host = host.strip("[]")
        if not sep or not host or not port_text.isdigit():
            raise LinkInputError(f"{url!r} needs a host and a port, for example {URL_EXAMPLES[scheme]}")
        port = int(port_text)
        if not 0 <= port <= 65535:
            raise LinkInputError(f"port {port} in {url!r} is out of range 0-65535")
        return cls(text=url, scheme=scheme, host=host, port=port)

    @property
    def mavutil_device(self) -> str:
        if self.scheme == "serial":
            assert self.device is not None
            return self.device
        return f"{self.scheme}:{self.host}:{self.port}"


# --- signing keys -------------------------------------------------------------------------------


def signing_key_from_text(text: str) -> bytes:
    """A key from text: 64 hex digits are the key itself; anything else is a passphrase.

    A passphrase becomes SHA-256(passphrase, UTF-8), as MAVProxy's ``signing setup`` does, so
    the same passphrase given to MAVProxy or Mission Planner gives the same key.
    """
    stripped = text.strip()
    if not stripped:
        raise LinkInputError("the signing key is empty; give 64 hex digits or a passphrase")
    if re.fullmatch(r"[0-9A-Fa-f]{64}", stripped):
        return bytes.fromhex(stripped)
    return hashlib.sha256(stripped.encode("utf-8")).digest()


def load_signing_key(
    path: str | os.PathLike[str] | None = None, *, environ: dict[str, str] | None = None
) -> bytes | None:
    """The 32-byte MAVLink 2 signing key from ``path``, else from ``$SFAP_SIGNING_KEY``, else None.

    A key file holds either exactly 32 raw bytes, or 64 hex digits, or a passphrase (one line,
    hashed with SHA-256 as MAVProxy does). The environment variable holds 64 hex digits or a
    passphrase.
    """
    if path is not None:
        file = Path(path)
        try:
            data = file.read_bytes()
        except OSError as error:
            raise LinkInputError(
                f"cannot read the signing key file {file}: {error.strerror or error}"
            ) from error
        # 32 bytes that are all printable ASCII are far likelier a passphrase than a random key
        if len(data) == 32 and not re.fullmatch(rb"[ -~]{32}", data):
            return data
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as error:
            raise LinkInputError(
                f"signing key file {file} holds {len(data)} bytes that are not text; a raw key "
                f"must be exactly 32 bytes (or write 64 hex digits or a passphrase)"
            ) from error
        return signing_key_from_text(text)
    env = os.environ if environ is None else environ
    value = env.get(SIGNING_KEY_ENV)
    if value:
        return signing_key_from_text(value)
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
        self._watch_for_drops()

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
        conn = _open_with_patience(parsed, source_system, source_component, heartbeat_timeout_s, clock)
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
                _close_quietly(conn)
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
            _close_quietly(self._conn)
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
        scheme = self._parsed.scheme
        if scheme == "serial":
            hint = (
                "check that the vehicle is powered and the radio or USB cable connected, that "
                "the baud rate is right (SiK radios usually 57600, USB 115200), and that no "
                "other program (Mission Planner, QGroundControl, MAVProxy) holds the port"
            )
        elif scheme == "udpin":
            hint = (
                f"check that the vehicle or its Wi-Fi bridge sends to this computer on UDP port "
                f"{self._parsed.port}, and that a firewall does not block it"
            )
        elif scheme == "udpout":
            hint = (
                f"check that the vehicle listens on {self._parsed.host}:{self._parsed.port} "
                f"(UDP) and that this computer can reach that address"
            )
        else:
            hint = (
                "check that the vehicle or simulator on the other end is running and speaks "
                "MAVLink on that port"
            )
        return "".join(parts) + "; " + hint

    def _watch_for_drops(self) -> None:
        """Make an end-of-stream on TCP visible (mavutil only prints it) as a drop."""
        conn = self._conn
        if self._parsed.scheme == "tcp":

            def on_eof() -> None:
                self._dropped = "the other end closed the TCP connection"

            def on_reset() -> None:
                self._dropped = "the TCP connection was reset"

            conn.handle_eof = on_eof
            conn.handle_disconnect = on_reset
        elif self._parsed.scheme == "tcpin":
            plain_recv = conn.recv

            def recv(n: int | None = None) -> Any:
                port = conn.port
                data = plain_recv(n)
                if not data and port is not None:
                    if conn.port is None:
                        self._dropped = "the TCP connection was reset"
                    else:
                        try:
                            if port.recv(1, socket.MSG_PEEK) == b"":
                                self._dropped = "the other end closed the TCP connection"
                        except (BlockingIOError, InterruptedError):
                            pass
                        except OSError as error:
                            self._dropped = str(error)
                return data

            conn.recv = recv


def _close_quietly(conn: Any) -> None:
    try:
        conn.close()
    except Exception as error:  # a port that is already gone: nothing left to release
        log.debug("close: %s", error)


#: Receive buffer asked of the operating system for network links (bytes; Linux caps it at
#: net.core.rmem_max). A relaying ground station sends in bursts of thousands of messages a
#: second; the default UDP buffer (about 200 kB, some 200 datagrams) overflows in a tenth of a
#: second when the reading thread is not scheduled, and the kernel drops what does not fit.
RECEIVE_BUFFER_BYTES = 4 << 20


def _enlarge_receive_buffer(conn: Any) -> None:
    port = getattr(conn, "port", None)
    if isinstance(port, socket.socket):
        try:
            port.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)
        except OSError as error:  # a smaller buffer still works
            log.debug("receive buffer not enlarged: %s", error)


#: How long (s, at most; never more than the heartbeat timeout) a ``tcp://`` connection that
#: is refused is tried again: a simulator or SITL started a moment ago is not listening yet.
CONNECT_PATIENCE_S = 5.0


def _open_with_patience(
    url: LinkUrl, source_system: int, source_component: int, timeout_s: float, clock: Clock
) -> Any:
    """:func:`_open_transport`; a refused ``tcp://`` connection is tried again every 0.2 s for
    up to min(:data:`CONNECT_PATIENCE_S`, ``timeout_s``) seconds."""
    deadline = clock.monotonic() + min(CONNECT_PATIENCE_S, timeout_s)
    while True:
        try:
            conn = _open_transport(url, source_system, source_component)
            if url.scheme != "serial":
                _enlarge_receive_buffer(conn)
            return conn
        except LinkError as error:
            refused = isinstance(error.__cause__, ConnectionRefusedError)
            if not refused or url.scheme != "tcp" or clock.monotonic() + 0.2 > deadline:
                raise
        clock.sleep(0.2)


def _open_transport(url: LinkUrl, source_system: int, source_component: int) -> Any:
    """The mavutil connection for ``url``; every failure becomes a :class:`LinkError`."""
    device = url.mavutil_device
    if url.scheme in ("udpin", "tcpin"):
        _check_port_free(url)
    try:
        if url.scheme == "serial":
            return mavutil.mavlink_connection(
                device,
                baud=url.baud,
                source_system=source_system,
                source_component=source_component,
                autoreconnect=False,
            )
        return mavutil.mavlink_connection(
            device,
            source_system=source_system,
            source_component=source_component,
            autoreconnect=False,
            retries=0,  # one connection attempt; mavutil's retries print and sleep
        )
    except LinkError:
        raise
    except socket.gaierror as error:
        raise LinkError(
            f"cannot resolve host {url.host!r} in {url.text}: {error.strerror}; check the name "
            f"or use an IP address"
        ) from error
    except ConnectionRefusedError as error:
        raise LinkError(
            f"nothing accepts connections at {url.text} (connection refused): check that the "
            f"vehicle, SITL or `sfap sim` is running and listening on port {url.port}"
        ) from error
    except OSError as error:
        raise LinkError(_os_error_message(url, error)) from error


def _os_error_message(url: LinkUrl, error: OSError) -> str:
    code = error.errno
    text = str(error)
    if url.scheme == "serial":
        if code == errno.ENOENT or "No such file" in text:
            return (
                f"serial device {url.device} does not exist ({url.text}); is the radio or USB "
                f"cable plugged in? {_serial_ports_hint()}"
            )
        if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
            return (
                f"no permission to open {url.device} ({url.text}); on Linux add yourself to the "
                f"'dialout' group (sudo usermod -aG dialout $USER) and log in again"
            )
        if code == errno.EBUSY or "busy" in text.lower():
            return (
                f"serial device {url.device} is busy ({url.text}); close the other program "
                f"(Mission Planner, QGroundControl, MAVProxy) that holds it"
            )
        return f"cannot open serial device {url.device} ({url.text}): {text}"
    if code == errno.EADDRINUSE:
        return _port_busy_message(url)
    if code == errno.EADDRNOTAVAIL:
        return (
            f"address {url.host} in {url.text} is not an address of this computer; use 0.0.0.0 "
            f"to listen on every interface"
        )
    if code in (errno.EACCES, errno.EPERM):
        return f"no permission to use port {url.port} ({url.text}); use a port above 1023"
    if code in (errno.ETIMEDOUT, errno.EHOSTUNREACH, errno.ENETUNREACH):
        return f"cannot reach {url.host} ({url.text}): {text}; check the network and the address"
    return f"cannot open {url.text}: {text}"


def _port_busy_message(url: LinkUrl) -> str:
    return (
        f"port {url.port} is busy ({url.text}): another program (Mission Planner, "
        f"QGroundControl, MAVProxy, another sfap) is listening on it; close it or choose "
        f"another port"
    )


def _check_port_free(url: LinkUrl) -> None:
    """mavutil binds with SO_REUSEADDR, which on UDP hides a port already in use: probe first."""
    kind = socket.SOCK_DGRAM if url.scheme == "udpin" else socket.SOCK_STREAM
    probe = socket.socket(socket.AF_INET, kind)
    try:
        if kind == socket.SOCK_STREAM:
            # as mavutil does: only a live listener blocks the port, not TIME_WAIT leftovers
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        probe.bind((url.host or "0.0.0.0", url.port or 0))
    except socket.gaierror as error:
        raise LinkError(f"cannot resolve host {url.host!r} in {url.text}: {error.strerror}") from error
    except OSError as error:
        raise LinkError(_os_error_message(url, error)) from error
    finally:
        probe.close()


def _serial_ports_hint() -> str:
    try:
        from serial.tools import list_ports

        ports = sorted(port.device for port in list_ports.comports())
    except Exception:  # listing ports is only a hint
        return ""
    if not ports:
        return "No serial ports are present on this computer."
    return "Serial ports present: " + ", ".join(ports) + "."
