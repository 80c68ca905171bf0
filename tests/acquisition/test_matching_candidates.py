"""The clock-offset candidates of frame-to-event matching (acquisition.matching): every
distinct offset that at least half as many (frame, event) pairs support as the densest one is
a candidate (issue 24's surviving mutant: the threshold 0.5 raised to 0.9 went unnoticed).

The oracle counts the support of every offset by brute force over all pairs, without the
module's sorted-window search."""

from __future__ import annotations

import math

import numpy as np
import pytest

from acquisition.matching import _candidate_offsets


def brute_support(f: np.ndarray, e: np.ndarray, offset: float, tol: float) -> int:
    return int(np.count_nonzero(np.abs((f[:, None] - e[None, :]) - offset) <= tol))


@pytest.mark.parametrize(("events", "frames"), [(60, 30), (45, 20), (80, 50)])
def test_every_offset_with_half_the_densest_support_is_a_candidate(events: int, frames: int) -> None:
    """A card of ``frames`` photos taken at a steady 2 s rhythm, part of a flight of ``events``
    camera events: every shift of the card along the flight fits some of its frames, the
    densest all of them. Each shift with at least half the densest support is a candidate,
    and none with less is (more than the 12 densest exist, so the floor adds none)."""
    rng = np.random.default_rng(events)
    e = 1000.0 + np.arange(events) * 2.0 + rng.uniform(-0.02, 0.02, events)
    f = e[:frames] + 7.3
    tol = 0.1
    shifts = 7.3 + 2.0 * np.arange(-(events - 1), frames)
    support = {round(float(s), 1): brute_support(f, e, float(s), tol) for s in shifts}
    densest = max(support.values())
    expected = {s for s, n in support.items() if n >= math.ceil(0.5 * densest)}
    assert len(expected) > 12  # the floor of 12 densest candidates does not decide
    assert any(n < 0.9 * densest for s, n in support.items() if s in expected)
    found = {round(centre, 1) for centre, _ in _candidate_offsets(f, e, tol)}
    assert found == expected


def test_each_candidate_carries_its_support() -> None:
    e = 1000.0 + np.arange(40) * 2.0
    f = e[:25] + 3.1
    for centre, bound in _candidate_offsets(f, e, 0.1):
        assert bound == brute_support(f, e, centre, 0.1)
