"""Frame-to-event matching (acquisition.matching), with truth built independently: event times
are generated here (lines of distance triggers, turns, wind), frames derived from them with a
known clock offset, drift, jitter, dropped frames, double fires and stray frames; every pair the
matcher makes is checked against the event each frame really came from."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from acquisition import matching
from acquisition.errors import GeotagError

START_S = 1_780_000_000.0


def survey_events(
    line_counts: list[int], *, seed: int, interval_s: float = 2.0, wind: float = 0.1, turn_s: float = 25.0
) -> np.ndarray:
    """Event times of a lawnmower survey: lines of distance triggers (``line_counts`` events
    each), flown alternately with and against a wind that changes the ground speed by
    ``wind`` (so the trigger interval too), 20 ms of trigger timing noise, and turns whose
    duration depends on how far the next line starts (line lengths differ in a polygon)."""
    rng = np.random.default_rng(seed)
    t = START_S
    out: list[float] = []
    for k, count in enumerate(line_counts):
        step = interval_s * (1.0 + wind if k % 2 else 1.0 - wind)
        for _ in range(count):
            out.append(t + rng.normal(0.0, 0.02))
            t += step * (1.0 + rng.normal(0.0, 0.005))
        if k + 1 < len(line_counts):
            t += turn_s + 0.5 * interval_s * abs(count - line_counts[k + 1])
    return np.array(out)


def camera_frames(
    events: np.ndarray,
    *,
    seed: int,
    offset_s: float,
    jitter_s: float = 0.02,
    drift_ppm: float = 0.0,
    dropped: frozenset[int] = frozenset(),
) -> tuple[np.ndarray, list[int]]:
    """Capture times on the camera's clock and, per frame, the index of its event."""
    rng = np.random.default_rng(seed)
    t_mid = float(np.mean(events))
    frames = [
        (float(e + offset_s + drift_ppm * 1e-6 * (e - t_mid) + rng.normal(0.0, jitter_s)), j)
        for j, e in enumerate(events)
        if j not in dropped
    ]
    frames.sort()
    return np.array([t for t, _ in frames]), [j for _, j in frames]


def assert_pairs_right(m: matching.Matching, truth: list[int]) -> None:
    """Every pair is a frame with its own event; no event is taken twice. ``truth`` holds the
    event of each frame, -1 for a stray frame, and -(j + 2) for the second shot of a double fire
    at event j (either shot of a double may take the event: they are 30-80 ms apart)."""
    events_taken = m.pairs[:, 1].tolist()
    assert len(events_taken) == len(set(events_taken)), "two frames took one event"

    def own(event: int, label: int) -> bool:
        return label == event or label == -(event + 2)

    wrong = [(int(a), int(b), truth[a]) for a, b in m.pairs if not own(int(b), truth[a])]
    assert not wrong, f"frames paired with another event: (frame, event, true event) {wrong[:5]}"


# ------------------------------------------------------------------------------- double fire


@pytest.mark.parametrize(
    ("gap_range_s", "tolerance_s"),
    [
        ((0.03, 0.08), None),  # a double pulse: the default tolerance narrows to ~0.16 s
        ((0.10, 0.30), 0.4),  # a slow second shot, with the crew's --tolerance-s 0.4
    ],
)
def test_a_double_fired_frame_takes_no_event(
    gap_range_s: tuple[float, float], tolerance_s: float | None
) -> None:
    """The camera fired twice for some events (a bouncing trigger line): the second frame of
    each double is an extra frame. It must not share its event with the first, nor take the
    neighbouring event, also when that neighbour's own frame was dropped."""
    events = survey_events([14, 11, 16, 9], seed=4)
    dropped = frozenset({6, 21, 33})  # 6, 21: the event after a double fire lost its frame
    times, truth = camera_frames(events, seed=5, offset_s=-812.4, dropped=dropped)
    rng = np.random.default_rng(6)
    doubles = [5, 12, 20, 28, 40]
    frames = [(t, j) for t, j in zip(times, truth, strict=True)]
    for j in doubles:
        first = next(t for t, k in frames if k == j)
        frames.append((first + rng.uniform(*gap_range_s), -(j + 2)))
    frames.sort()
    f = np.array([t for t, _ in frames])
    owner = [j for _, j in frames]
    m = matching.match_frames_to_events(f, events, tolerance_s=tolerance_s)
    assert not m.ambiguous
    assert_pairs_right(m, owner)
    # One shot of each double has the event, the other is left over as extra.
    left = sorted(max(owner[k], -owner[k] - 2) for k in m.unmatched_frames)
    assert left == doubles
    assert sorted(m.unmatched_events.tolist()) == sorted(dropped)
    assert m.offset_s == pytest.approx(-812.4, abs=0.02)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31), n_doubles=st.integers(1, 6))
def test_one_frame_per_event_whatever_the_doubles(seed: int, n_doubles: int) -> None:
    rng = np.random.default_rng(seed)
    counts = [int(c) for c in rng.integers(6, 18, size=int(rng.integers(3, 6)))]
    events = survey_events(counts, seed=seed)
    times, truth = camera_frames(events, seed=seed + 1, offset_s=float(rng.uniform(-4000, 4000)))
    frames = list(zip(times.tolist(), truth, strict=True))
    doubles = sorted(int(j) for j in rng.choice(len(events), size=n_doubles, replace=False))
    for j in doubles:
        first = next(t for t, k in frames if k == j)
        frames.append((first + float(rng.uniform(0.03, 0.08)), -(j + 2)))
    frames.sort()
    owner = [j for _, j in frames]
    m = matching.match_frames_to_events(np.array([t for t, _ in frames]), events)
    assert_pairs_right(m, owner)
    assert sorted(max(owner[k], -owner[k] - 2) for k in m.unmatched_frames) == doubles
    assert m.unmatched_events.size == 0


# -------------------------------------------------------------------- the interval term decides


def test_a_stray_frame_near_a_dropped_frames_event_is_left_extra() -> None:
    """Only the interval term can solve this: event 9's frame was dropped and a stray frame
    (a manual shutter press) fell 0.45 s after event 9, inside the crew's tolerance of 0.5 s.
    Its residual alone, (0.45 / 0.5)^2 = 0.81, is cheaper than the two gaps (2) it would save;
    but the intervals to its neighbours disagree with the events' by 0.45 s on both sides,
    (2 x 0.81 more), which the other 40 frames never do: it is an extra frame, and event 9
    a dropped one. Without the interval term the stray frame takes event 9."""
    events = survey_events([12, 12, 12, 12], seed=11)
    times, truth = camera_frames(events, seed=12, offset_s=55.0, dropped=frozenset({9, 30}))
    stray = float(events[9] + 55.0 + 0.45)
    f = np.sort(np.append(times, stray))
    owner = [truth[int(np.argmin(np.abs(times - t)))] if t != stray else -1 for t in f]
    m = matching.match_frames_to_events(f, events, tolerance_s=0.5)
    assert_pairs_right(m, owner)
    assert [owner[k] for k in m.unmatched_frames] == [-1]
    assert sorted(m.unmatched_events.tolist()) == [9, 30]


def test_a_short_subset_across_a_turn_is_placed() -> None:
    """20 frames around a turn between lines of different lengths (intervals 1.8 s, a pause,
    then 2.2 s): that rhythm appears once in the flight, so the offset is pinned down."""
    events = survey_events([30, 18, 25, 12, 22], seed=21)
    times, truth = camera_frames(events, seed=22, offset_s=3604.3)
    start = 40  # 8 frames before the turn after line 2 ends (index 48), 12 after
    f, owner = times[start : start + 20], truth[start : start + 20]
    m = matching.match_frames_to_events(f, events)
    assert not m.ambiguous
    assert_pairs_right(m, owner)
    assert m.offset_s == pytest.approx(3604.3, abs=0.02)


# -------------------------------------------------------------------------- subsets of a card


def test_subsets_are_placed_right_or_called_ambiguous() -> None:
    """Subsets of a 565-event flight (one DCIM folder of a card), of several sizes and from
    several places: a subset is either matched right, or the matcher says the alignment is
    ambiguous and names the competing offsets. Never a confident wrong offset."""
    counts = [45, 38, 52, 47, 41, 55, 36, 50, 44, 53, 44, 60]  # 565 events over a polygon
    events = survey_events(counts, seed=31)
    assert events.size == 565
    times, truth = camera_frames(
        events, seed=32, offset_s=3604.3, jitter_s=0.03, dropped=frozenset({77, 300})
    )
    rng = np.random.default_rng(33)
    outcomes = {"right": 0, "ambiguous": 0}
    for size in (8, 20, 40, 60, 120):
        for start in rng.integers(0, times.size - size, size=6):
            f, owner = times[start : start + size], truth[start : start + size]
            m = matching.match_frames_to_events(f, events)
            if m.ambiguous:
                outcomes["ambiguous"] += 1
                assert m.competitors and m.competitors[0][1] < m.margin + 1e-9
                assert "--offset-s" in m.warnings[0] and "--sync" in m.warnings[0]
                continue
            assert_pairs_right(m, owner)
            assert m.offset_s == pytest.approx(3604.3, abs=0.03)
            outcomes["right"] += 1
    # Both outcomes occur: short subsets inside a line repeat along the flight, long ones do not.
    assert outcomes["right"] >= 6 and outcomes["ambiguous"] >= 3, outcomes


@pytest.mark.parametrize(("start", "size"), [(0, 565), (160, 60), (300, 120), (520, 40)])
def test_unambiguous_subsets_still_pass(start: int, size: int) -> None:
    """The whole card, and subsets that hold a turn between lines of different lengths."""
    counts = [45, 38, 52, 47, 41, 55, 36, 50, 44, 53, 44, 60]
    events = survey_events(counts, seed=31)
    times, truth = camera_frames(events, seed=34, offset_s=3604.3, jitter_s=0.03)
    f, owner = times[start : start + size], truth[start : start + size]
    m = matching.match_frames_to_events(f, events)
    assert not m.ambiguous, m.warnings
    assert_pairs_right(m, owner)
    assert len(m.pairs) == size


def test_a_subset_inside_one_regular_line_is_ambiguous() -> None:
    """40 frames from the middle of one line of a flight flown without wind, all lines alike:
    the same rhythm occurs on every line, so several offsets fit equally well."""
    events = survey_events([60] * 10, seed=41, wind=0.0)
    times, truth = camera_frames(events, seed=42, offset_s=3604.3, jitter_s=0.03)
    f = times[310:350]
    m = matching.match_frames_to_events(f, events)
    assert m.ambiguous
    assert len(m.competitors) >= 2
    assert "ambiguous" in m.warnings[0]
    # A sync time within a second picks the right one among them.
    synced = matching.match_frames_to_events(f, events, offset_windows_s=[[(f[0] - events[310], 1.0)]])
    assert not synced.ambiguous
    assert_pairs_right(synced, truth[310:350])


def test_sync_windows_that_match_nothing_are_refused() -> None:
    events = survey_events([20, 20], seed=51)
    times, _ = camera_frames(events, seed=52, offset_s=10.0)
    with pytest.raises(GeotagError, match="sync points"):
        matching.match_frames_to_events(times, events, offset_windows_s=[[(500.0, 1.0)]])
