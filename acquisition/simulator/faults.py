"""Faults injected on the simulated vehicle's link: loss, duplication, reordering, latency,
a serial radio's speed; and the refusals a vehicle may answer an upload with.

:class:`FaultConfig` says what to inject, :class:`FaultyPipe` applies it to a stream of
messages (one pipe each way), :class:`FaultStats` counts what it did. The RNG is seeded, so a
run is repeatable.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from planner.errors import InputError


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


class FaultyPipe:
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

    def next_due_s(self) -> float | None:
        """When (monotonic s) the next queued or held item is due; None when nothing waits."""
        due = min((entry[0] for entry in self._queue), default=None)
        if self._held is not None:
            held_due = self._held[0] + 0.2
            due = held_due if due is None else min(due, held_due)
        return due

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
