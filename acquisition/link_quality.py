"""Link quality from MAVLink sequence numbers, per sender, as the monitor counts it.

Per sender (system, component), from MAVLink sequence numbers (8 bits, modular). With
``last`` the sequence number of the sender's newest message and ``k = (seq - last) mod
256``: ``k == 0`` is a duplicate (not counted as received); a message whose number was
counted lost within the last :data:`LATE_WINDOW` numbers arrives *late* (reordered): it
is received and no longer lost; any other ``k`` (1-255) is a forward jump, ``k - 1``
messages lost. So a burst of 200 lost messages counts 200, never "a late arrival" (an older
rule read every jump of 128 or more as reordering, which hid long bursts). A duplicate of
a message older than the newest is indistinguishable from a burst of ``k - 1`` losses and
counts as one (relays deliver in order; duplicates come back to back). Quality is received /
(received + lost), in percent. Every message received counts, from every system, whoever it is
addressed to (a message left out would show as a gap: a false loss). The count restarts with
the first message of each connection attempt after a drop (what was sent while the link
was down cannot be told from sequence numbers modulo 256); drops are counted separately.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True, kw_only=True)
class LinkQuality:
    """Messages of one MAVLink system since the last (re)connection, from sequence numbers.

    ``received``: distinct messages received; ``lost``: messages the sequence numbers say
    were sent and never arrived; ``duplicates``: the same sequence number twice in a row;
    ``late``: messages that arrived after a later one (reordered).
    """

    system_id: int
    received: int
    lost: int
    duplicates: int
    late: int

    @property
    def expected(self) -> int:
        return self.received + self.lost

    @property
    def quality_pct(self) -> float | None:
        return 100.0 * self.received / self.expected if self.expected else None


#: How far back (in sequence numbers) a message counted lost may still arrive late.
LATE_WINDOW = 16


@dataclass
class SeqCounter:
    """Loss from one sender's 8-bit sequence numbers (the rule: module docstring)."""

    last: int | None = None
    received: int = 0
    lost: int = 0
    duplicates: int = 0
    late: int = 0
    # sequence numbers counted lost in the last LATE_WINDOW steps: seq -> steps ago is implicit
    missing: dict[int, int] = field(default_factory=dict)  # seq -> position when counted lost
    position: int = 0  # how many sequence numbers the sender has moved through

    def add(self, seq: int) -> None:
        if self.last is None:
            self.received += 1
            self.last = seq
            return
        step = (seq - self.last) % 256
        if step == 0:
            self.duplicates += 1
            return
        counted_at = self.missing.pop(seq, None)
        if counted_at is not None and self.position - counted_at <= LATE_WINDOW:
            # counted lost at most LATE_WINDOW numbers behind the newest (the numbers the jump
            # recorded, and the horizon the pruning below keeps) and here it is: late, not lost
            self.received += 1
            self.late += 1
            self.lost -= 1
            return
        # a forward jump of `step` (1..255): step - 1 messages never arrived
        self.received += 1
        self.lost += step - 1
        for k in range(1, min(step, LATE_WINDOW + 1)):
            self.missing[(seq - k) % 256] = self.position + step - k
        self.position += step
        self.last = seq
        if len(self.missing) > 4 * LATE_WINDOW:
            horizon = self.position - LATE_WINDOW
            self.missing = {s_: p_ for s_, p_ in self.missing.items() if p_ >= horizon}


class LinkCounts:
    """The :class:`SeqCounter` of every sender (system, component) since the last connection."""

    def __init__(self) -> None:
        self._counters: dict[tuple[int, int], SeqCounter] = {}
        self._restart = False

    def restart(self) -> None:
        """A new connection attempt: the counts restart with its first message."""
        self._restart = True

    def add(self, sender: tuple[int, int], seq: int) -> None:
        """One message of ``sender`` with sequence number ``seq``."""
        if self._restart:
            self._counters.clear()
            self._restart = False
        self._counters.setdefault(sender, SeqCounter()).add(seq)

    def per_system(self) -> tuple[LinkQuality, ...]:
        """The counts of every system (its components together), by system id."""
        totals: dict[int, SeqCounter] = {}
        for (system, _), counter in self._counters.items():
            total = totals.setdefault(system, SeqCounter())
            total.received += counter.received
            total.lost += counter.lost
            total.duplicates += counter.duplicates
            total.late += counter.late
        return tuple(
            LinkQuality(
                system_id=system, received=c.received, lost=c.lost, duplicates=c.duplicates, late=c.late
            )
            for system, c in sorted(totals.items())
        )
