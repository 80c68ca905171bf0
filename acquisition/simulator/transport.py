"""Where the simulated vehicle listens and the sockets it talks through.

:func:`parse_listen_url` reads ``tcpin://``, ``udpin://`` and ``udpout://`` URLs;
:class:`Transport` owns the sockets of one such URL (several TCP ground stations, or UDP
peers) and moves bytes in and out without blocking.
"""

from __future__ import annotations

import contextlib
import logging
import select
import socket
from dataclasses import dataclass
from urllib.parse import urlsplit

from ..clock import WALL_CLOCK, Clock, WallClock
from ..errors import LinkError
from ..link_port import LinkInputError

log = logging.getLogger(__name__)


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
        raise LinkInputError(
            f"the simulator cannot listen on {url!r}; use tcpin://HOST:PORT, "
            f"udpin://HOST:PORT or udpout://HOST:PORT (e.g. tcpin://127.0.0.1:5760)"
        )
    try:
        port = parts.port
    except ValueError as error:
        raise LinkInputError(f"bad port in {url!r}: {error}; give a port 0-65535") from error
    if port is None or not parts.hostname:
        raise LinkInputError(f"{url!r} needs a host and a port, e.g. {scheme}://127.0.0.1:5760")
    if scheme == "udpout" and port == 0:
        raise LinkInputError(f"{url!r}: udpout needs the ground station's real port, not 0")
    return ListenAddress(scheme, parts.hostname, port)


# --- transport --------------------------------------------------------------------------------


class Transport:
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

    def poll(self, timeout_s: float, clock: Clock = WALL_CLOCK) -> list[tuple[object, bytes]]:
        """Wait up to ``timeout_s`` (on ``clock``) and return (peer key, bytes) received."""
        socks = self.sockets()
        out: list[tuple[object, bytes]] = []
        try:
            if isinstance(clock, WallClock):
                readable, _, _ = select.select(socks, [], [], timeout_s)
            elif clock.wait_readable([sock.fileno() for sock in socks], timeout_s):
                readable, _, _ = select.select(socks, [], [], 0)
            else:
                readable = []
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
