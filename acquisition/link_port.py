"""Link URLs and the ports they open, with the errors a crew meets in words.

:class:`LinkUrl` parses ``serial://``, ``udpin://``, ``udpout://``, ``tcp://`` and ``tcpin://``
URLs; :func:`open_port` opens the pymavlink ``mavutil`` connection of one (a refused ``tcp://``
connection is tried again for a moment, UDP receive buffers are enlarged) and turns every
failure into a :class:`~acquisition.errors.LinkError` that says what to check.
"""

from __future__ import annotations

import errno
import logging
import re
import socket
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pymavlink import mavutil

from planner.errors import InputError

from .clock import Clock
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

    def no_vehicle_hint(self) -> str:
        """What to check when no vehicle is heard on this URL."""
        scheme = self.scheme
        if scheme == "serial":
            hint = (
                "check that the vehicle is powered and the radio or USB cable connected, that "
                "the baud rate is right (SiK radios usually 57600, USB 115200), and that no "
                "other program (Mission Planner, QGroundControl, MAVProxy) holds the port"
            )
        elif scheme == "udpin":
            hint = (
                f"check that the vehicle or its Wi-Fi bridge sends to this computer on UDP port "
                f"{self.port}, and that a firewall does not block it"
            )
        elif scheme == "udpout":
            hint = (
                f"check that the vehicle listens on {self.host}:{self.port} "
                f"(UDP) and that this computer can reach that address"
            )
        else:
            hint = (
                "check that the vehicle or simulator on the other end is running and speaks "
                "MAVLink on that port"
            )
        return hint


def close_quietly(conn: Any) -> None:
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


def open_port(url: LinkUrl, source_system: int, source_component: int, timeout_s: float, clock: Clock) -> Any:
    """The mavutil connection for ``url`` (:func:`_open_transport`); a refused ``tcp://``
    connection is tried again every 0.2 s (on ``clock``) for up to
    min(:data:`CONNECT_PATIENCE_S`, ``timeout_s``) seconds."""
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


def watch_for_drops(conn: Any, scheme: str, on_drop: Callable[[str], None]) -> None:
    """Make an end-of-stream on TCP visible (mavutil only prints it): ``on_drop(why)``."""
    if scheme == "tcp":

        def on_eof() -> None:
            on_drop("the other end closed the TCP connection")

        def on_reset() -> None:
            on_drop("the TCP connection was reset")

        conn.handle_eof = on_eof
        conn.handle_disconnect = on_reset
    elif scheme == "tcpin":
        plain_recv = conn.recv

        def recv(n: int | None = None) -> Any:
            port = conn.port
            data = plain_recv(n)
            if not data and port is not None:
                if conn.port is None:
                    on_drop("the TCP connection was reset")
                else:
                    try:
                        if port.recv(1, socket.MSG_PEEK) == b"":
                            on_drop("the other end closed the TCP connection")
                    except (BlockingIOError, InterruptedError):
                        pass
                    except OSError as error:
                        on_drop(str(error))
            return data

        conn.recv = recv
