"""Matching frames to camera events: which frame each trigger took, and the camera clock.

:func:`match_frames_to_events` pairs frame capture times (camera clock) with camera event times
(UTC, autopilot clock) and fits the camera clock's offset and drift; :class:`Matching` holds
the pairs, the frames and events left over, and the clock model.

The algorithm
-------------
Frames are sorted by their capture time ``f_i`` (camera clock); camera events by their time
``e_j`` (UTC, autopilot clock). The model is ``f_i = e_j + offset + drift * (e_j - t_ref)``.
Mission Planner pairs the i-th frame with the i-th event, so one dropped frame shifts every
later position; here the two sequences are *aligned*, so that each frame is paired with the
event whose time pattern it shares, and frames or events left over are named.

1. Candidate offsets. Every difference ``f_i - e_j`` is a possible offset; the true one is the
   value that many pairs agree on within the matching tolerance ``tol`` (default 35 % of the
   median event interval, 0.05-2 s). Every distinct window of the sorted differences holding at
   least half as many pairs as the densest is a candidate (and at least the twelve densest): a
   subset of a card fits every stretch of the flight with its rhythm, and all of them must be
   weighed. A given ``--offset-s`` is the only candidate; sync points keep only the candidates
   inside their windows.
2. Alignment by dynamic programming, per candidate. Nodes are the pairs (i, j) whose residual
   ``r_ij = f_i - predicted(e_j)`` is within ``tol``. A path is a chain of nodes increasing in
   both i and j (order is kept: a camera does not reorder its frames). Its cost is
   ``g`` per frame left without an event (extra frame) and per event left without a frame
   (dropped frame), plus per node ``(r_ij / tol)^2``, plus between consecutive nodes
   ``((f_i - f_i') - (e_j - e_j'))^2 / tol^2``: the mismatch of the *intervals* between
   consecutive frames and consecutive events, which is what identifies a sequence whose clock is
   offset (turns, pauses and irregular triggering give it a fingerprint). ``g = 1``, so a pair
   is matched whenever its costs are below the two gaps it saves. Predecessors are searched
   within ``max_skip`` frames and events; longer gaps (the camera stopped for a while) restart
   the chain from the best earlier node at the gap price. Cost O(N * band * max_skip^2).
3. Choosing, and saying when the data cannot choose. The alignments within five lost pairs of
   the cheapest are refined (step 4) and priced in units of the timing noise ``sigma`` (the
   residual scatter of the cheapest): ``sum (r / sigma)^2 + sum (dr)^2 / (2 sigma^2) + 6 per
   unmatched item`` (dr: the interval mismatch of consecutive pairs; 6 = -2 ln 0.05, about one
   frame in twenty dropped or extra; each squared term counts at most 9, three sigma: one late
   frame must not outweigh the line ends that anchor an alignment), the lowest wins. After the
   tolerance is narrowed, every other alignment at a clearly different offset (more than the
   final tolerance away) is priced the same way, each pair of alignments with the larger of
   their two scatters (a low estimate of the noise inflates every difference); when the best of
   them is worse by less than ``10 + 2 ln N`` (N of them: odds of e^5 against each), the result
   is flagged ambiguous and the warning names the competing
   offsets. A regular sequence with no pause or turn to anchor it, or a subset of a card whose
   rhythm repeats along the flight, is ambiguous; geotag then writes nothing until the crew
   confirms the offset or gives a sync point.
4. Robust refinement: the offset is the median of the matched pairs' time differences; with
   enough pairs over a long enough span (>= 10 pairs, >= 120 s) the drift is the Theil-Sen slope of
   those differences against event time, kept when it is significant (> 3 standard errors).
   The alignment is repeated with the refined model until the pairs no longer change.
   Then the tolerance is narrowed to ten times the residual scatter (plus half the clock's
   resolution) and the alignment repeated, so that a spurious frame close to an event cannot
   take the event from the real frame.
5. The result is rejected (:class:`GeotagError`) when fewer than half of the smaller sequence,
   or fewer than 75 % of the smaller count within the span both sequences cover, could be
   matched, or when the residuals scatter as much as chance would (robust sigma above 30 % of
   the first tolerance): the log is from another flight, or the counts cannot be reconciled.
   Cameras that write whole seconds only (no SubSecTimeOriginal) widen the tolerance by half
   a second.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.stats import median

from .errors import GeotagError

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


#: Alignments that lose at most this many pairs against the cheapest are refined and compared.
CONTENDER_PAIRS = 5
#: Chi-square margin (in units of the timing noise) the best alignment needs over one other.
AMBIGUITY_MARGIN = 10.0
#: Price of a frame or an event left unmatched, in the same units: -2 ln 0.05, a camera that
#: drops or adds about one frame in twenty. A shift by one frame that loses one pair pays 12.
UNMATCHED_COST = 6.0
#: The most one residual or interval term adds to an alignment's price (3 sigma squared): the
#: timing noise has heavier tails than a Gaussian (a camera's write delay now and then), and one
#: such frame must not outweigh the line ends that anchor an alignment.
OUTLIER_COST = 9.0


@dataclass(frozen=True, kw_only=True)
class Matching:
    """The alignment of frames (camera clock) with camera events (UTC).

    Indices refer to the arrays as passed to :func:`match_frames_to_events` (not sorted ones).

    - ``pairs``: (K, 2) int64, rows (frame index, event index), in time order.
    - ``residuals_s``: (K,) frame time minus the frame time predicted from its event.
    - ``unmatched_frames``, ``unmatched_events``: int64 indices left over.
    - ``offset_s``: camera clock minus UTC at ``reference_time_s`` (UTC, POSIX s);
      ``drift_ppm``: how fast that offset grows, microseconds per second (0 when not fitted).
    - ``residual_mad_s``: robust scatter of the residuals (1.4826 x median absolute deviation).
    - ``candidates``: (offset_s, cost) of every alignment tried, cheapest first.
    - ``competitors``: (offset_s, chi-square margin, pairs) of the alignments at clearly different
      offsets, closest first; ``margin`` the smallest (inf: none); ``ambiguous`` when it is too
      small to trust the winner.
    """

    pairs: I64
    residuals_s: F64
    unmatched_frames: I64
    unmatched_events: I64
    offset_s: float
    drift_ppm: float
    reference_time_s: float
    residual_mad_s: float
    tolerance_s: float
    ambiguous: bool = False
    candidates: tuple[tuple[float, float], ...] = ()
    competitors: tuple[tuple[float, float, int], ...] = ()
    margin: float = math.inf
    warnings: tuple[str, ...] = ()

    def event_of_frame(self) -> dict[int, int]:
        return {int(f): int(e) for f, e in self.pairs}

    def frame_time_to_utc(self, frame_time_s: ArrayLike) -> F64:
        """Camera-clock times to UTC with this model."""
        t = np.asarray(frame_time_s, dtype=float)
        rate = self.drift_ppm * 1e-6
        return np.asarray((t - self.offset_s + rate * self.reference_time_s) / (1.0 + rate), float)

    def predicted_frame_time(self, event_time_s: ArrayLike) -> F64:
        e = np.asarray(event_time_s, dtype=float)
        return np.asarray(e + self.offset_s + self.drift_ppm * 1e-6 * (e - self.reference_time_s), float)


def _median_interval_s(times: F64) -> float:
    steps = np.diff(np.sort(times))
    steps = steps[steps > 0]
    return float(median(steps)) if steps.size else 1.0


def _candidate_offsets(
    f: F64, e: F64, tol: float, *, floor: int = 12, cap: int = 2000
) -> list[tuple[float, int | None]]:
    """Offsets that many (frame, event) pairs agree on within ``tol``, densest first: every
    distinct offset (more than ``tol`` apart) supported by at least half as many pairs as the
    densest, and at least the ``floor`` densest whatever their support (at most ``cap``).

    A subset of a card (one DCIM folder of a long flight) fits every stretch of the flight with
    the same rhythm about equally well: all of them are candidates, so that the alignment can
    tell whether one of them stands out. Each comes with the number of (frame, event) pairs
    within ``tol`` of it, an upper bound of the pairs its alignment can make (None when the
    frames were subsampled)."""
    frames = f
    step = 1
    if f.size * e.size > 4_000_000:  # enough pairs to find the peaks; bounded memory
        step = math.ceil(f.size * e.size / 4_000_000)
        frames = f[::step]
    diffs = np.sort((frames[:, None] - e[None, :]).ravel())
    hi = np.searchsorted(diffs, diffs + tol, side="right")
    lo = np.searchsorted(diffs, diffs - tol, side="left")
    support = hi - lo
    order = np.argsort(-support, kind="stable")
    needed = max(2, math.ceil(0.5 * int(support[order[0]])))
    chosen: list[float] = []
    ordered: list[float] = []  # the same, sorted, to find the nearest quickly
    bounds: list[int | None] = []
    taken = np.zeros(diffs.size, dtype=bool)  # differences already inside a chosen window
    for k in order:
        if (support[k] < needed and len(chosen) >= floor) or len(chosen) >= cap:
            break
        if taken[k]:
            continue
        window = diffs[lo[k] : hi[k]]
        centre = float(median(window))
        taken[lo[k] : hi[k]] = True  # this window is a candidate, or too close to one
        at = bisect.bisect_left(ordered, centre)
        if (at > 0 and centre - ordered[at - 1] <= tol) or (
            at < len(ordered) and ordered[at] - centre <= tol
        ):
            continue
        ordered.insert(at, centre)
        chosen.append(centre)
        inside = int(
            np.searchsorted(diffs, centre + tol, side="right") - np.searchsorted(diffs, centre - tol)
        )
        bounds.append(inside if step == 1 else None)
    return list(zip(chosen, bounds, strict=True))


@dataclass(frozen=True)
class _Alignment:
    cost: float
    pairs: list[tuple[int, int]]


def _align(
    f: F64,
    p: F64,
    tol: float,
    *,
    interval_tol: float | None = None,
    gap_cost: float = 1.0,
    max_skip: int = 8,
) -> _Alignment:
    """Align sorted frame times ``f`` with sorted predicted frame times ``p`` (see module doc).

    ``tol`` gates and prices the residuals; ``interval_tol`` (default ``tol``) prices the
    interval mismatches (wider for frame times quantized to whole seconds)."""
    n, m = f.size, p.size
    node_i: list[int] = []
    node_j: list[int] = []
    node_r: list[float] = []
    for i in range(n):
        lo = int(np.searchsorted(p, f[i] - tol, side="left"))
        hi = int(np.searchsorted(p, f[i] + tol, side="right"))
        for j in range(lo, hi):
            node_i.append(i)
            node_j.append(j)
            node_r.append(float(f[i] - p[j]))
    if not node_i:
        return _Alignment(gap_cost * (n + m), [])
    count = len(node_i)
    cost = [0.0] * count
    parent = [-1] * count
    first_of_frame: dict[int, int] = {}
    last_of_frame: dict[int, int] = {}
    for k, i in enumerate(node_i):
        first_of_frame.setdefault(i, k)
        last_of_frame[i] = k
    inv_tol2 = 1.0 / (tol * tol)
    inv_interval2 = 1.0 / (interval_tol * interval_tol) if interval_tol else inv_tol2
    # Best node among frames older than i - max_skip, for restarts after long gaps:
    # value = cost - g*(i' + j'), so that adding g*(i + j - 2) prices the skipped items.
    restart_best = math.inf
    restart_node = -1
    restart_frontier = 0  # frames below this index are folded into restart_best
    for k in range(count):
        i, j, r = node_i[k], node_j[k], node_r[k]
        while restart_frontier < i - max_skip:
            if restart_frontier in first_of_frame:
                for q in range(first_of_frame[restart_frontier], last_of_frame[restart_frontier] + 1):
                    value = cost[q] - gap_cost * (node_i[q] + node_j[q])
                    if value < restart_best:
                        restart_best, restart_node = value, q
            restart_frontier += 1
        best = gap_cost * (i + j)  # start here: every earlier frame and event unmatched
        best_parent = -1
        if restart_node >= 0 and node_j[restart_node] < j:
            value = restart_best + gap_cost * (i + j - 2)
            if value < best:
                best, best_parent = value, restart_node
        for i_prev in range(max(0, i - 1 - max_skip), i):
            if i_prev not in first_of_frame:
                continue
            for q in range(first_of_frame[i_prev], last_of_frame[i_prev] + 1):
                j_prev = node_j[q]
                if j_prev >= j or j - j_prev - 1 > max_skip:
                    continue
                d = r - node_r[q]
                skipped = i - i_prev - 1 + j - j_prev - 1
                value = cost[q] + gap_cost * skipped + d * d * inv_interval2
                if value < best:
                    best, best_parent = value, q
        cost[k] = best + r * r * inv_tol2
        parent[k] = best_parent
    total_best = gap_cost * (n + m)
    end = -1
    for k in range(count):
        value = cost[k] + gap_cost * (n - 1 - node_i[k] + m - 1 - node_j[k])
        if value < total_best:
            total_best, end = value, k
    pairs: list[tuple[int, int]] = []
    while end >= 0:
        pairs.append((node_i[end], node_j[end]))
        end = parent[end]
    pairs.reverse()
    return _Alignment(total_best, pairs)


def _theil_sen(x: F64, y: F64) -> tuple[float, float]:
    """Slope (median of pairwise slopes) and its approximate standard error."""
    if x.size > 400:  # bounded work: an even subsample keeps the estimator's robustness
        idx = np.linspace(0, x.size - 1, 400).astype(int)
        x, y = x[idx], y[idx]
    dx = x[:, None] - x[None, :]
    dy = y[:, None] - y[None, :]
    mask = dx > 0
    slope = float(median(dy[mask] / dx[mask]))
    fitted = y - slope * x
    resid = fitted - median(fitted)
    sigma = 1.4826 * float(median(np.abs(resid)))
    spread = float(np.std(x))
    se = sigma / (spread * math.sqrt(x.size)) if spread > 0 else math.inf
    return slope, se


def match_frames_to_events(
    frame_times_s: ArrayLike,
    event_times_s: ArrayLike,
    *,
    offset_s: float | None = None,
    tolerance_s: float | None = None,
    max_skip: int = 8,
    min_match_fraction: float = 0.5,
    min_overlap_fraction: float = 0.75,
    resolution_s: float = 0.0,
    offset_windows_s: Sequence[Sequence[tuple[float, float]]] = (),
) -> Matching:
    """Align frame capture times (camera clock, s) with camera event times (UTC, s).

    ``offset_s``: the camera clock minus UTC if known (then only that alignment is tried, and
    refined). ``tolerance_s``: the largest residual for a pair (default 35 % of the median event
    interval, clipped to 0.05-2 s). ``max_skip``: the most consecutive frames or events a chain
    skips before it restarts. ``resolution_s``: the resolution of the frame times (1 s for a
    camera that writes no sub-seconds), widening the tolerance accordingly. Raises
    :class:`GeotagError` when the sequences cannot be reconciled: fewer than
    ``min_match_fraction`` of the smaller sequence matched, fewer than ``min_overlap_fraction``
    of the smaller count within the time span both sequences cover, or residuals as scattered
    as chance would leave them. ``offset_windows_s``: the offsets to
    consider, when ``offset_s`` is not given: one sequence of (centre, half width) per sync point;
    an offset must fall in one window of each (within ``tol``).

    ``ambiguous`` is set (and a warning names the competing offsets) when an alignment at a
    clearly different offset fits nearly as well; callers must not place frames from it
    without confirmation.
    """
    f_in = np.asarray(frame_times_s, dtype=float).ravel()
    e_in = np.asarray(event_times_s, dtype=float).ravel()
    if not (np.all(np.isfinite(f_in)) and np.all(np.isfinite(e_in))):
        raise GeotagError("frame and event times must be finite numbers (seconds)")
    n, m = f_in.size, e_in.size
    if n == 0 or m == 0:
        raise GeotagError(f"nothing to match: {n} frames with a capture time, {m} camera events")
    if offset_s is None and min(n, m) < 3:
        raise GeotagError(
            f"{n} frames and {m} camera events are too few to find the camera clock offset; "
            f"pass --offset-s (camera clock minus UTC, seconds)"
        )
    f_order = np.argsort(f_in, kind="stable")
    e_order = np.argsort(e_in, kind="stable")
    f = f_in[f_order]
    e = e_in[e_order]
    tol = tolerance_s if tolerance_s is not None else float(np.clip(0.35 * _median_interval_s(e), 0.05, 2.0))
    if not tol > 0:
        raise GeotagError(f"matching tolerance {tol} s must be > 0")
    if tolerance_s is None:
        tol = max(tol, 0.5 * resolution_s + 0.2 if resolution_s > 0 else tol)
    t_ref = float(np.mean(e))

    def align(predicted: F64, tol: float) -> _Alignment:
        return _align(f, predicted, tol, interval_tol=tol + resolution_s, max_skip=max_skip)

    candidates: list[tuple[float, int | None]] = (
        [(float(offset_s), None)] if offset_s is not None else _candidate_offsets(f, e, tol)
    )

    def allowed(c: float) -> bool:
        """Inside the sync points' windows (a candidate's centre is good to a few residuals)."""
        slack = min(tol, 0.1)
        return all(any(abs(c - centre) <= half + slack for centre, half in w) for w in offset_windows_s)

    if offset_windows_s and offset_s is None:
        candidates = [c for c in candidates if allowed(c[0])]
        if not candidates:
            spans = "; ".join(
                " or ".join(f"{centre - half:+.1f} to {centre + half:+.1f} s" for centre, half in w)
                for w in offset_windows_s
            )
            raise GeotagError(
                f"no alignment of the frames with the camera events puts the camera clock offset "
                f"where the sync points say ({spans}): are the sync points right, and is the log "
                f"from this flight?"
            )
    tried: list[tuple[float, _Alignment]] = []
    cheapest = math.inf
    for offset, most_pairs in candidates:
        # An alignment cannot pair more than the pairs within tol of its offset: skip those
        # that cannot come within CONTENDER_PAIRS of the cheapest so far (the cost is exact).
        if most_pairs is not None and n + m - 2 * most_pairs > cheapest + 2.0 * CONTENDER_PAIRS:
            continue
        alignment = align(e + offset, tol)
        cheapest = min(cheapest, alignment.cost)
        tried.append((offset, alignment))
    tried.sort(key=lambda item: item[1].cost)

    def refine(
        pairs: list[tuple[int, int]], offset: float, drift: float, tol: float
    ) -> tuple[list[tuple[int, int]], float, float]:
        for _ in range(4):
            if not pairs:
                break
            fi = np.array([f[a] for a, _ in pairs])
            ej = np.array([e[b] for _, b in pairs])
            diffs = fi - ej
            new_drift = 0.0
            span = float(ej.max() - ej.min())
            if len(pairs) >= 10 and span >= 120.0:
                slope, se = _theil_sen(ej - t_ref, diffs)
                if abs(slope) > 3.0 * se:
                    new_drift = slope
            new_offset = float(median(diffs - new_drift * (ej - t_ref)))
            predicted = e + new_offset + new_drift * (e - t_ref)
            realigned = align(predicted, tol)
            offset, drift = new_offset, new_drift
            if realigned.pairs == pairs:
                break
            pairs = realigned.pairs
        return pairs, offset, drift

    def scatter(pairs: list[tuple[int, int]], offset: float, drift: float) -> float:
        if not pairs:
            return math.inf
        r = np.array([f[a] - e[b] - offset - drift * (e[b] - t_ref) for a, b in pairs])
        return 1.4826 * float(median(np.abs(r - median(r))))

    def chi2(chosen: list[tuple[int, int]], o: float, d: float, sigma: float) -> float:
        """The alignment cost of the module docstring in units of the timing noise ``sigma``:
        squared residuals, squared interval mismatches of consecutive pairs (the difference of
        two residuals: variance 2 sigma^2), and UNMATCHED_COST per frame or event left over."""
        r = np.array([f[a] - e[b] - o - d * (e[b] - t_ref) for a, b in chosen])
        intervals = np.diff(r) if r.size > 1 else np.zeros(0)
        terms = np.concatenate([(r / sigma) ** 2, intervals**2 / (2.0 * sigma * sigma)])
        return float(np.sum(np.minimum(terms, OUTLIER_COST))) + UNMATCHED_COST * (n + m - 2 * len(chosen))

    # Contenders: every alignment within CONTENDER_PAIRS lost pairs of the cheapest (each costs
    # 2 gaps), refined. The winner is the best fit in units of the timing noise, not the
    # cheapest at the first, wide tolerance (which cannot see a scatter of tens of ms).
    best_raw = tried[0][1].cost
    contenders: list[tuple[list[tuple[int, int]], float, float]] = []
    for cand_offset, alignment in tried:
        if alignment.cost > best_raw + 2.0 * CONTENDER_PAIRS or not alignment.pairs:
            continue
        refined = refine(alignment.pairs, cand_offset, 0.0, tol)
        if refined[0] and all(refined[0] != c[0] for c in contenders):
            contenders.append(refined)
    if not contenders:
        contenders.append(([], tried[0][0], 0.0))
    # The timing noise: the scatter of the cheapest alignment (not the smallest scatter, which a
    # chance alignment of a few pairs can have).
    noise = max(scatter(*contenders[0]), 0.3 * resolution_s, 1e-3)
    contenders.sort(key=lambda c: chi2(c[0], c[1], c[2], noise))
    pairs, offset, drift = contenders[0]
    warnings: list[str] = []
    ambiguous = False
    competitors: list[tuple[float, float, int]] = []
    margin = math.inf

    wide_tol = tol
    if tolerance_s is None and pairs:
        # Second stage: the residual scatter sets the tolerance (10 sigma, as a scatter estimated
        # from few pairs runs low; plus half the clock's resolution), so that a spurious frame
        # near an event cannot steal the event.
        tol = float(np.clip(10.0 * scatter(pairs, offset, drift) + 0.5 * resolution_s, 0.05, tol))
        pairs, offset, drift = refine(pairs, offset, drift, tol)
    if pairs and offset_s is None:
        # Every other contender at a clearly different offset (more than the final tolerance
        # away: it pairs other events), refined at the final tolerance like the winner and
        # priced in units of the winner's timing noise. The data pin the offset down only when
        # the best of them is worse by a margin that also pays for the number of alternatives
        # (10 + 2 ln N: odds of e^5 against each of N equally likely offsets).
        sigma = max(scatter(pairs, offset, drift), 0.3 * resolution_s, 1e-3)
        own = chi2(pairs, offset, drift, sigma)
        for other_pairs0, other_offset0, other_drift0 in contenders[1:]:
            other_pairs, other_offset, other_drift = refine(other_pairs0, other_offset0, other_drift0, tol)
            if not other_pairs or other_pairs == pairs or abs(other_offset - offset) <= tol:
                continue
            if offset_windows_s and not allowed(other_offset):
                continue
            # The timing noise is estimated, and a low estimate inflates every difference:
            # each pair of alignments is priced with the larger of their two scatters.
            both = max(sigma, scatter(other_pairs, other_offset, other_drift))
            own_here = own if both == sigma else chi2(pairs, offset, drift, both)
            delta = chi2(other_pairs, other_offset, other_drift, both) - own_here
            competitors.append((other_offset, delta, len(other_pairs)))
        competitors.sort(key=lambda c: c[1])
        if competitors:
            margin = competitors[0][1]
            needed_margin = AMBIGUITY_MARGIN + 2.0 * math.log(len(competitors))
            if margin < needed_margin:
                ambiguous = True
                close = [c for c in competitors if c[1] < needed_margin]
                listed = ", ".join(f"{o:+.3f} s ({k} pairs, worse by {d:.1f})" for o, d, k in close[:5])
                more = f" and {len(close) - 5} more" if len(close) > 5 else ""
                warnings.append(
                    f"the alignment is ambiguous: the camera clock offset {offset:+.3f} s "
                    f"({len(pairs)} pairs) fits best, but {len(close)} other offset(s) fit "
                    f"nearly as well: {listed}{more} (chi-square in units of the "
                    f"{sigma * 1e3:.0f} ms timing noise; {needed_margin:.1f} needed). The frames' "
                    f"rhythm repeats along the flight (a subset of a card, regular lines): confirm "
                    f"the offset with --offset-s, or give a sync point (--sync, --sync-position)"
                )
    spread = scatter(pairs, offset, drift)
    if pairs and spread > 0.3 * wide_tol + 0.4 * resolution_s:
        raise GeotagError(
            f"frames and camera events cannot be reconciled: {n} frames, {m} events, the best "
            f"alignment (camera clock offset {offset:+.3f} s, {len(pairs)} pairs) leaves "
            f"residuals scattered by {spread:.3f} s, as much as chance gives with a tolerance "
            f"of {wide_tol:.3f} s: the frames' rhythm does not follow the events'. Is the log "
            f"from this flight? If the camera's delay truly varies that much, pass a larger "
            f"--tolerance-s"
        )

    matched = len(pairs)
    # Where both sequences exist under the model, nearly everything must pair up: a chance
    # alignment of two regular sequences pairs many items overall but leaves holes inside.
    predicted_all = e + offset + drift * (e - t_ref)
    start = max(f[0], predicted_all[0]) - tol
    end = min(f[-1], predicted_all[-1]) + tol
    in_both = min(
        int(np.count_nonzero((f >= start) & (f <= end))),
        int(np.count_nonzero((predicted_all >= start) & (predicted_all <= end))),
    )
    needed = max(
        3 if offset_s is None else 1,
        math.ceil(min_match_fraction * min(n, m)),
        math.ceil(min_overlap_fraction * in_both),
    )
    if matched < needed:
        raise GeotagError(
            f"frames and camera events cannot be reconciled: {n} frames, {m} events, the best "
            f"alignment (camera clock offset {offset:+.3f} s) pairs only {matched} (need "
            f"{needed}). Is the log from this flight (and this day)? If it is, pass --offset-s "
            f"(camera clock minus UTC, seconds) or --tolerance-s"
        )
    pair_f = np.array([f_order[a] for a, _ in pairs], dtype=np.int64)
    pair_e = np.array([e_order[b] for _, b in pairs], dtype=np.int64)
    predicted_pairs = e_in[pair_e] + offset + drift * (e_in[pair_e] - t_ref)
    residuals = f_in[pair_f] - predicted_pairs
    mad = 1.4826 * float(median(np.abs(residuals - median(residuals))))
    if abs(offset) > 86_400.0:
        warnings.append(
            f"the camera clock is {offset / 86_400.0:+.2f} days off the log; check that the log is "
            f"from the same flight"
        )
    return Matching(
        pairs=np.column_stack([pair_f, pair_e]).astype(np.int64).reshape(-1, 2),
        residuals_s=np.asarray(residuals, float),
        unmatched_frames=np.setdiff1d(np.arange(n), pair_f).astype(np.int64),
        unmatched_events=np.setdiff1d(np.arange(m), pair_e).astype(np.int64),
        offset_s=float(offset),
        drift_ppm=float(drift * 1e6),
        reference_time_s=t_ref,
        residual_mad_s=mad,
        tolerance_s=float(tol),
        ambiguous=ambiguous,
        candidates=tuple((float(o), float(a.cost)) for o, a in tried),
        competitors=tuple(competitors),
        margin=float(margin),
        warnings=tuple(warnings),
    )
