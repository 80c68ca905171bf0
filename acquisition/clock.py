"""The clock that the link, the mission protocol and the simulated vehicle wait on.

:data:`WALL_CLOCK` is the real one (``time.monotonic``, ``select``): what every program uses.
:class:`VirtualClock` is simulated time for tests, honest by construction: it stands still
while any party computes, and when every party waits (for bytes on its sockets, an event, or a
deadline) and no byte is in flight to any of them, it jumps to the earliest deadline and wakes
the parties whose deadline that is. A timeout therefore fires after exactly the simulated
seconds it names, with the same messages exchanged before it as on an idle wall clock, but
without the wait. A *party* is a thread that takes part in the exchange (the simulated
vehicle's loop, a ground station that holds a link, the link's heartbeat); it joins with
:meth:`VirtualClock.join` and leaves with :meth:`VirtualClock.leave`. Other threads may wait on
the clock too (a test waiting for a landing): they follow simulated time and never hold it.

Threads that hand each other messages use a :class:`ClockQueue`: an item not yet taken is a
byte not yet read, so simulated time does not move past it.

Sockets must be local (loopback): bytes sent are then readable at once by the peer, which is
what "no byte in flight" checks with a zero-timeout ``select``.
"""

from __future__ import annotations

import contextlib
import os
import queue
import select
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol


class Clock(Protocol):
    """What the link, the protocol engine and the simulated vehicle ask of a clock."""

    def monotonic(self) -> float:
        """Seconds, monotonic (only differences mean something)."""
        ...

    def time(self) -> float:
        """Now as POSIX seconds, UTC."""
        ...

    def sleep(self, seconds: float) -> None: ...

    def wait_readable(self, fds: Sequence[int], timeout_s: float) -> bool:
        """Wait until one of ``fds`` is readable (True) or ``timeout_s`` passed (False). May
        return False early (as ``select`` may): callers loop on their own deadline."""
        ...

    def wait_event(self, event: threading.Event, timeout_s: float) -> bool:
        """Wait until ``event`` is set (True) or ``timeout_s`` passed; whoever sets it calls
        :meth:`interrupt`."""
        ...

    def join(self, thread: threading.Thread | None = None) -> object:
        """Make ``thread`` (default: the calling thread; it may be not started yet) a party of
        the exchange; returns the token for :meth:`leave`."""
        ...

    def leave(self, token: object) -> None: ...

    def interrupt(self) -> None:
        """Wake every waiter so that it checks its condition again (after setting a flag)."""
        ...


class WallClock:
    """The real clock: ``time.monotonic``, ``time.time`` and ``select``."""

    def monotonic(self) -> float:
        return time.monotonic()

    def time(self) -> float:
        return time.time()

    def sleep(self, seconds: float) -> None:
        time.sleep(max(seconds, 0.0))

    def wait_readable(self, fds: Sequence[int], timeout_s: float) -> bool:
        try:
            readable, _, _ = select.select(list(fds), [], [], max(timeout_s, 0.0))
        except (OSError, ValueError):
            return False
        return bool(readable)

    def wait_event(self, event: threading.Event, timeout_s: float) -> bool:
        return event.wait(max(timeout_s, 0.0))

    def join(self, thread: threading.Thread | None = None) -> object:
        return None

    def leave(self, token: object) -> None:
        pass

    def interrupt(self) -> None:
        pass


WALL_CLOCK = WallClock()

#: Longest real wait of a virtual waiter before it looks again (a safety net: waking is by
#: pipe, so this only bounds the cost of a party that ends without leaving).
_RECHECK_S = 0.05


@dataclass
class _Waiter:
    deadline: float
    fds: list[int]
    wake_r: int
    wake_w: int
    woken: bool = False


class VirtualClock:
    """Simulated time (see the module docstring). ``start_s``: the monotonic reading at start;
    ``utc_start_s``: the UTC time then (default: the wall clock's now)."""

    def __init__(self, start_s: float = 1000.0, utc_start_s: float | None = None) -> None:
        self._now = float(start_s)
        self._utc_offset = (time.time() if utc_start_s is None else utc_start_s) - self._now
        self._lock = threading.Lock()
        self._parties: dict[threading.Thread, int] = {}  # party -> times joined
        # parties seen running (they joined themselves or waited): only those can have ended;
        # one joined before it starts is not alive yet while it starts, and must not be lost
        self._running: set[threading.Thread] = set()
        self._waiting: dict[threading.Thread, _Waiter] = {}
        self._pipes: dict[threading.Thread, tuple[int, int]] = {}  # wake-up pipe of each waiter
        self.advances = 0  # how many times time jumped (for tests)

    # --- reading ------------------------------------------------------------------------------

    def monotonic(self) -> float:
        return self._now

    def time(self) -> float:
        return self._utc_offset + self._now

    # --- parties ------------------------------------------------------------------------------

    def join(self, thread: threading.Thread | None = None) -> object:
        party = threading.current_thread() if thread is None else thread
        with self._lock:
            self._parties[party] = self._parties.get(party, 0) + 1
            if thread is None:
                self._running.add(party)
        return party

    def leave(self, token: object) -> None:
        assert isinstance(token, threading.Thread)
        with self._lock:
            count = self._parties.get(token, 0) - 1
            if count <= 0:
                self._parties.pop(token, None)
                self._running.discard(token)
                self._release_pipe(token)
            else:
                self._parties[token] = count
            self._advance_if_idle()

    def interrupt(self) -> None:
        with self._lock:
            for waiter in self._waiting.values():
                self._wake(waiter)

    # --- waiting ------------------------------------------------------------------------------

    def sleep(self, seconds: float) -> None:
        self._wait([], seconds, None)

    def wait_readable(self, fds: Sequence[int], timeout_s: float) -> bool:
        return self._wait(list(fds), timeout_s, None)

    def wait_event(self, event: threading.Event, timeout_s: float) -> bool:
        if event.is_set():
            return True
        self._wait([], timeout_s, event)
        return event.is_set()

    def _wake_pipe(self, thread: threading.Thread) -> tuple[int, int]:
        """The calling thread's wake-up pipe (kept while it is a party; called with the lock)."""
        pipe = self._pipes.get(thread)
        if pipe is None:
            pipe = os.pipe()
            os.set_blocking(pipe[0], False)
            os.set_blocking(pipe[1], False)
            self._pipes[thread] = pipe
        return pipe

    def _release_pipe(self, thread: threading.Thread) -> None:
        """Close the pipe of a thread that neither waits nor is a party (called with the lock)."""
        if thread in self._waiting or thread in self._parties:
            return
        pipe = self._pipes.pop(thread, None)
        if pipe is not None:
            os.close(pipe[0])
            os.close(pipe[1])

    def _wait(self, fds: list[int], timeout_s: float, event: threading.Event | None) -> bool:
        ident = threading.current_thread()
        with self._lock:
            if ident in self._parties:
                self._running.add(ident)
            wake_r, wake_w = self._wake_pipe(ident)
            waiter = _Waiter(
                deadline=self._now + max(timeout_s, 0.0),
                fds=fds,
                wake_r=wake_r,
                wake_w=wake_w,
            )
            self._waiting[ident] = waiter
            self._advance_if_idle()
        readable = False
        try:
            while True:
                with self._lock:
                    if waiter.woken or self._now >= waiter.deadline:
                        break
                if event is not None and event.is_set():
                    break
                try:
                    ready, _, _ = select.select([*fds, wake_r], [], [], _RECHECK_S)
                except (OSError, ValueError):
                    break
                if any(fd != wake_r for fd in ready):
                    readable = True
                    break
                if wake_r not in ready:
                    with self._lock:  # nobody woke us within the safety interval: look again
                        self._advance_if_idle()
        finally:
            with self._lock:
                self._waiting.pop(ident, None)
                _drain(wake_r)
                self._release_pipe(ident)
        if not readable and fds:
            readable = _readable_now(fds)
        return readable

    # --- advancing (called with the lock held) -------------------------------------------------

    def _wake(self, waiter: _Waiter) -> None:
        if not waiter.woken:
            waiter.woken = True
            with contextlib.suppress(BlockingIOError):  # the pipe is full of wake-ups already
                os.write(waiter.wake_w, b"x")

    def _advance_if_idle(self) -> None:
        """When every party waits, nobody is woken but not yet running, and no byte is in
        flight to a waiter: jump to the earliest deadline and wake who waits for it."""
        for thread in list(self._running):
            if not thread.is_alive():  # a party that ended without leaving
                self._parties.pop(thread, None)
                self._running.discard(thread)
                self._release_pipe(thread)
        if not self._waiting:
            return
        if any(ident not in self._waiting for ident in self._parties):
            return
        if any(waiter.woken for waiter in self._waiting.values()):
            return
        fds = [fd for waiter in self._waiting.values() for fd in waiter.fds]
        if fds and _readable_now(fds):
            return
        target = min(waiter.deadline for waiter in self._waiting.values())
        if target > self._now:
            self._now = target
            self.advances += 1
        for waiter in self._waiting.values():
            if waiter.deadline <= self._now:
                self._wake(waiter)


class ClockQueue:
    """A queue between threads whose waits run on ``clock``: every item put writes a byte into
    a pipe that the taker watches, so a :class:`VirtualClock` sees an item not yet taken as a
    byte not yet read and does not move time on. :meth:`close` it when done."""

    def __init__(self, clock: Clock = WALL_CLOCK) -> None:
        self.clock = clock
        self._items: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._lock = threading.Lock()  # no byte written into a descriptor closed (and reused)
        self._closed = False
        self._read_fd, self._write_fd = os.pipe()
        os.set_blocking(self._read_fd, False)
        os.set_blocking(self._write_fd, False)

    def put(self, item: Any) -> None:
        self._items.put(item)
        with self._lock:
            if not self._closed:
                with contextlib.suppress(BlockingIOError):  # the pipe is full: readable already
                    os.write(self._write_fd, b"x")

    def get_nowait(self) -> Any | None:
        """The next item, or None when there is none."""
        try:
            return self._items.get_nowait()
        except queue.Empty:
            return None

    def get(self, timeout_s: float) -> Any | None:
        """The next item, waiting up to ``timeout_s`` on the clock; None when none came."""
        deadline = self.clock.monotonic() + timeout_s
        while True:
            item = self.get_nowait()
            if item is not None:
                return item
            # drain the wake-up bytes, then look again: an item put after this look leaves a
            # byte in the pipe, so the wait below returns at once
            with self._lock, contextlib.suppress(BlockingIOError, OSError):
                while not self._closed and os.read(self._read_fd, 4096):
                    pass
            item = self.get_nowait()
            if item is not None:
                return item
            remaining = deadline - self.clock.monotonic()
            if remaining <= 0:
                return None
            self.clock.wait_readable([self._read_fd], remaining)

    def close(self) -> None:
        with self._lock:
            if not self._closed:
                self._closed = True
                os.close(self._read_fd)
                os.close(self._write_fd)


def _readable_now(fds: list[int]) -> bool:
    try:
        readable, _, _ = select.select(fds, [], [], 0)
    except (OSError, ValueError):
        return True  # a closed descriptor: let its owner find out
    return bool(readable)


def _drain(fd: int) -> None:
    try:
        while os.read(fd, 4096):
            pass
    except (BlockingIOError, OSError):
        pass
