"""A TCP relay between a ground station and the simulator that a test cuts and restores."""

from __future__ import annotations

import contextlib
import select
import socket
import threading
import time


class Relay:
    """A TCP relay between the monitor and the simulator that a test can cut and restore:
    cut closes both connections and stops listening (reconnections are refused)."""

    def __init__(self, upstream_url: str) -> None:
        host, port = upstream_url.removeprefix("tcp://").rsplit(":", 1)
        self.upstream = (host, int(port))
        self.port = 0
        self._listen: socket.socket | None = None
        self._pairs: list[tuple[socket.socket, socket.socket]] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def open(self) -> Relay:
        """Listen and start relaying."""
        self.restore()
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)
        self.cut()

    def __enter__(self) -> Relay:
        return self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def restore(self) -> None:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(("127.0.0.1", self.port))
        sock.listen(4)
        self.port = sock.getsockname()[1]
        with self._lock:
            self._listen = sock

    @property
    def url(self) -> str:
        """Where the ground station connects (the relay's own port)."""
        return f"tcp://127.0.0.1:{self.port}"

    def cut(self) -> None:
        with self._lock:
            socks = [s for pair in self._pairs for s in pair]
            if self._listen is not None:
                socks.append(self._listen)
            self._pairs, self._listen = [], None
        for s in socks:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            s.close()

    def _run(self) -> None:
        while not self._stop.is_set():
            with self._lock:
                listen = self._listen
                pairs = list(self._pairs)
            socks = [s for pair in pairs for s in pair] + ([listen] if listen else [])
            try:
                readable, _, _ = select.select(socks, [], [], 0.02) if socks else ([], [], [])
            except (OSError, ValueError):
                continue
            if not socks:
                time.sleep(0.02)
            for s in readable:
                try:
                    if s is listen:
                        client, _ = s.accept()
                        server = socket.create_connection(self.upstream)
                        with self._lock:
                            self._pairs.append((client, server))
                        continue
                    pair = next(p for p in pairs if s in p)
                    data = s.recv(65536)
                    if not data:
                        raise OSError("closed")
                    (pair[1] if s is pair[0] else pair[0]).sendall(data)
                except (OSError, StopIteration):
                    continue
