"""Late (reordered) messages at the edge of the window (acquisition.link_quality): a message
counted lost when a later one arrived may still arrive up to LATE_WINDOW sequence numbers
behind the newest, and is then received, not lost (issue 24's surviving mutant: ``<
LATE_WINDOW`` against ``<= LATE_WINDOW`` went unnoticed). The oracle is the construction of
the stream: every message is sent once, so nothing is lost."""

from __future__ import annotations

from hypothesis import example, given, settings
from hypothesis import strategies as st

from acquisition.link_quality import LATE_WINDOW, SeqCounter


def count(seqs: list[int]) -> SeqCounter:
    counter = SeqCounter()
    for seq in seqs:
        counter.add(seq % 256)
    return counter


def test_a_message_exactly_the_window_behind_the_newest_arrives_late() -> None:
    # 0, then LATE_WINDOW + 1: LATE_WINDOW numbers counted lost; then 1, LATE_WINDOW behind
    edge = count([0, LATE_WINDOW + 1, 1])
    assert (edge.received, edge.lost, edge.late) == (3, LATE_WINDOW - 1, 1)
    inside = count([0, LATE_WINDOW + 1, 2])
    assert (inside.received, inside.lost, inside.late) == (3, LATE_WINDOW - 1, 1)


def test_a_message_beyond_the_window_is_a_forward_jump() -> None:
    # 0, then LATE_WINDOW + 2 (LATE_WINDOW + 1 lost); 1 is LATE_WINDOW + 1 behind: too far to
    # tell from a burst of losses (the documented rule), so it is a jump of 256 - LATE_WINDOW - 1
    beyond = count([0, LATE_WINDOW + 2, 1])
    assert beyond.late == 0
    assert beyond.lost == LATE_WINDOW + 1 + (256 - LATE_WINDOW - 1 - 1)


@settings(max_examples=300, deadline=None)
@example(delays=[0, LATE_WINDOW] + [0] * (LATE_WINDOW + 4))  # message 1 arrives the window behind
@given(
    delays=st.lists(st.integers(min_value=0, max_value=LATE_WINDOW), min_size=2, max_size=600),
)
def test_every_message_sent_once_and_delayed_within_the_window_is_received(delays: list[int]) -> None:
    """Message i leaves at i and arrives at i + delays[i]: none arrives more than LATE_WINDOW
    numbers behind the newest one received before it, so none is lost, whatever the order
    (and across the 8-bit wrap). The count starts with the first message heard, so message
    0 comes first."""
    delays = [0, *delays[1:]]
    order = sorted(range(len(delays)), key=lambda i: (i + delays[i], -i))  # ties: the later first
    counter = count(order)
    assert (counter.received, counter.lost, counter.duplicates) == (len(delays), 0, 0)
    late = sum(1 for k, i in enumerate(order) if any(j > i for j in order[:k]))
    assert counter.late == late
