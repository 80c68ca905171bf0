"""Geotagging frames from the flight's own telemetry: match, interpolate, write, report.

Matching frames to camera events (:func:`match_frames_to_events`)
------------------------------------------------------------------
Frames are sorted by their capture time ``f_i`` (camera clock); camera events by their time
``e_j`` (UTC, autopilot clock). The model is ``f_i = e_j + offset + drift * (e_j - t_ref)``.
Mission Planner pairs the i-th frame with the i-th event, so one dropped frame shifts every
later position; here the two sequences are *aligned*, so that each frame is paired with the
event whose time pattern it shares, and frames or events left over are named.

1. Candidate offsets. Every difference ``f_i - e_j`` is a possible offset; the true one is the
   value that many pairs agree on within the matching tolerance ``tol`` (default 35 % of the
   median event interval, 0.05-2 s). The densest windows of the sorted differences give up to
   six distinct candidates (a given ``--offset-s`` is the only candidate).
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
3. The candidate with the lowest cost wins. After step 4 the runner-up is refined the same way
   and both are priced as a chi-square (squared residuals in units of the winner's scatter, plus
   2 per unmatched item); a margin below 10 flags the result ambiguous with a warning: a regular
   sequence with no pause to anchor it, where "nothing dropped" is only the likelier reading
   (a shift by one frame loses one pair: 4); pass ``--offset-s`` to decide.
4. Robust refinement: the offset is the median of the matched pairs' time differences; with
   enough pairs over a long enough span (>= 10 pairs, >= 120 s) the drift is the Theil-Sen slope of
   those differences against event time, kept when it is significant (> 3 standard errors).
   The alignment is repeated with the refined model until the pairs no longer change.
   Then the tolerance is narrowed to eight times the residual scatter (plus half the clock's
   resolution) and the alignment repeated, so that a spurious frame close to an event cannot
   take the event from the real frame.
5. The result is rejected (:class:`GeotagError`) when fewer than half of the smaller sequence,
   or fewer than 75 % of the smaller count within the span both sequences cover, could be
   matched, or when the residuals scatter as much as chance would (robust sigma above 30 % of
   the first tolerance): the log is from another flight, or the counts cannot be reconciled.
   Cameras that write whole seconds only (no SubSecTimeOriginal) widen the tolerance by half
   a second.

Placing frames
--------------
A matched frame is placed at its *event* time (the autopilot's clock, not the camera's): the
position track is interpolated there in a local metric frame (UTM of the flight,
:class:`planner.geo.LocalFrame`), attitude by spherical linear interpolation of quaternions; the
camera attitude combines vehicle and gimbal when the log has gimbal attitude. Without camera
events every frame is placed at its capture time corrected by the offset (given, or from the
frames' own EXIF GPS time, else zero). A frame without an event is placed at its corrected capture
time when the track covers it, and listed. Frames that cannot be placed (no capture time,
unreadable, outside the log, a gap in the track longer than ``max_gap_s``, duplicate name) are
listed with the reason, never guessed, and nothing is written for them.

Camera attitude convention (written as Pix4D ``Camera:Yaw/Pitch/Roll``): the yaw, pitch and roll
of a virtual airframe whose downward-looking camera would point like the real one. A camera fixed
to the airframe looking down therefore carries the vehicle's own yaw (clockwise from north,
0-360), pitch (nose up positive) and roll (right wing down positive); a level, nadir camera has
pitch 0, roll 0.
"""

from __future__ import annotations

import json
import logging
import math
import os
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.errors import InputError, OutputExistsError
from planner.geo import LocalFrame
from planner.outputs import atomic_write_text, check_output_dir, staged_output_dir

from . import exif, sidecars
from .errors import GeotagError
from .telemetry.model import AttitudeTrack, CameraEvents, FlightLog, PositionTrack

logger = logging.getLogger(__name__)

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

JPEG_SUFFIXES = (".jpg", ".jpeg")
REPORT_NAME = "geotag_report.json"

#: progress(done, total): called as frames are read and written.
ProgressCallback = Callable[[int, int], None]


# ============================================================================================
# Matching


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
    - ``candidates``: (offset_s, cost) of every alignment tried, best first.
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
    return float(np.median(steps)) if steps.size else 1.0


def _candidate_offsets(f: F64, e: F64, tol: float, count: int = 6) -> list[float]:
    """Offsets that many (frame, event) pairs agree on within ``tol``, densest first."""
    frames = f
    if f.size * e.size > 4_000_000:  # enough pairs to find the peak; bounded memory
        step = math.ceil(f.size * e.size / 4_000_000)
        frames = f[::step]
    diffs = np.sort((frames[:, None] - e[None, :]).ravel())
    hi = np.searchsorted(diffs, diffs + tol, side="right")
    lo = np.searchsorted(diffs, diffs - tol, side="left")
    support = hi - lo
    order = np.argsort(-support, kind="stable")
    chosen: list[float] = []
    for k in order:
        if support[k] < 2 and chosen:
            break
        window = diffs[lo[k] : hi[k]]
        centre = float(np.median(window))
        if all(abs(centre - c) > tol for c in chosen):
            chosen.append(centre)
            if len(chosen) >= count:
                break
    return chosen


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
    slope = float(np.median(dy[mask] / dx[mask]))
    fitted = y - slope * x
    resid = fitted - np.median(fitted)
    sigma = 1.4826 * float(np.median(np.abs(resid)))
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
    as chance would leave them.
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

    candidates = [float(offset_s)] if offset_s is not None else _candidate_offsets(f, e, tol)
    tried: list[tuple[float, _Alignment]] = []
    for offset in candidates:
        tried.append((offset, align(e + offset, tol)))
    tried.sort(key=lambda item: item[1].cost)
    offset, best = tried[0]
    warnings: list[str] = []
    ambiguous = False

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
            new_offset = float(np.median(diffs - new_drift * (ej - t_ref)))
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
        return 1.4826 * float(np.median(np.abs(r - np.median(r))))

    wide_tol = tol
    pairs, offset, drift = refine(best.pairs, offset, 0.0, tol)
    if tolerance_s is None and pairs:
        # Second stage: the residual scatter sets the tolerance (8 sigma, as a scatter estimated
        # from few pairs runs low; plus half the clock's resolution), so that a spurious frame
        # near an event cannot steal the event.
        tol = float(np.clip(8.0 * scatter(pairs, offset, drift) + 0.5 * resolution_s, 0.05, tol))
        pairs, offset, drift = refine(pairs, offset, drift, tol)
    if pairs:
        # Every other candidate, refined at the final tolerance like the winner, and all priced
        # as a chi-square: squared residuals in units of the winner's scatter, plus 2 per item
        # left unmatched. A margin below 10 (one lost pair costs 4) is too weak to trust.
        sigma = max(scatter(pairs, offset, drift), 0.3 * resolution_s, 1e-3)

        def chi2(chosen: list[tuple[int, int]], o: float, d: float) -> float:
            r = np.array([f[a] - e[b] - o - d * (e[b] - t_ref) for a, b in chosen])
            return float(np.sum((r / sigma) ** 2)) + 2.0 * (n + m - 2 * len(chosen))

        own = chi2(pairs, offset, drift)
        for other_offset, other in tried[1:]:
            if not other.pairs:
                continue
            other_pairs, other_offset, other_drift = refine(other.pairs, other_offset, 0.0, tol)
            if not other_pairs or other_pairs == pairs:
                continue
            if chi2(other_pairs, other_offset, other_drift) - own < 10.0:
                ambiguous = True
                warnings.append(
                    f"the alignment is weakly determined: camera clock offsets {offset:+.3f} s "
                    f"and {other_offset:+.3f} s fit almost equally well (the intervals are too "
                    f"regular); check the first and last frames or pass --offset-s"
                )
                break
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
    mad = 1.4826 * float(np.median(np.abs(residuals - np.median(residuals))))
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
        warnings=tuple(warnings),
    )


# ============================================================================================
# Attitude: quaternions and spherical interpolation (scipy is not a dependency)


def quat_from_euler_deg(yaw_deg: ArrayLike, pitch_deg: ArrayLike, roll_deg: ArrayLike) -> F64:
    """Unit quaternions (w, x, y, z), shape (N, 4), of the rotation ned_from_body for
    aerospace Z-Y-X angles (yaw about down, then pitch, then roll)."""
    y = np.radians(np.asarray(yaw_deg, float)) / 2.0
    p = np.radians(np.asarray(pitch_deg, float)) / 2.0
    r = np.radians(np.asarray(roll_deg, float)) / 2.0
    cy, sy, cp, sp, cr, sr = np.cos(y), np.sin(y), np.cos(p), np.sin(p), np.cos(r), np.sin(r)
    q = np.stack(
        [
            cy * cp * cr + sy * sp * sr,
            cy * cp * sr - sy * sp * cr,
            cy * sp * cr + sy * cp * sr,
            sy * cp * cr - cy * sp * sr,
        ],
        axis=-1,
    )
    return np.asarray(np.atleast_2d(q), float)


def euler_deg_from_quat(q: ArrayLike) -> tuple[F64, F64, F64]:
    """(yaw 0-360, pitch -90..90, roll -180..180) degrees of quaternions (w, x, y, z)."""
    qa = np.atleast_2d(np.asarray(q, float))
    qa = qa / np.linalg.norm(qa, axis=1, keepdims=True)
    w, x, y, z = qa[:, 0], qa[:, 1], qa[:, 2], qa[:, 3]
    yaw = np.degrees(np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))) % 360.0
    pitch = np.degrees(np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0)))
    roll = np.degrees(np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y)))
    return np.asarray(yaw, float), np.asarray(pitch, float), np.asarray(roll, float)


def quat_multiply(a: ArrayLike, b: ArrayLike) -> F64:
    """Hamilton product a * b of (N, 4) quaternion arrays (rotation b first, then a)."""
    qa = np.atleast_2d(np.asarray(a, float))
    qb = np.atleast_2d(np.asarray(b, float))
    w1, x1, y1, z1 = qa[:, 0], qa[:, 1], qa[:, 2], qa[:, 3]
    w2, x2, y2, z2 = qb[:, 0], qb[:, 1], qb[:, 2], qb[:, 3]
    return np.stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ],
        axis=-1,
    )


def slerp(q0: ArrayLike, q1: ArrayLike, fraction: ArrayLike) -> F64:
    """Spherical linear interpolation between unit quaternions, row by row, shortest arc."""
    a = np.atleast_2d(np.asarray(q0, float))
    b = np.atleast_2d(np.asarray(q1, float)).copy()
    t = np.asarray(fraction, float).reshape(-1, 1)
    dot = np.sum(a * b, axis=1, keepdims=True)
    b = np.where(dot < 0.0, -b, b)  # q and -q are the same rotation: take the short way
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin_theta = np.sin(theta)
    near = sin_theta < 1e-9
    safe = np.where(near, 1.0, sin_theta)
    w0 = np.where(near, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(near, t, np.sin(t * theta) / safe)
    out = w0 * a + w1 * b
    return np.asarray(out / np.linalg.norm(out, axis=1, keepdims=True), float)


class GimbalMode(StrEnum):
    """How the log's gimbal angles relate to the world and the vehicle. In every mode the angles
    are those of the camera's optical axis (forward looking at pitch 0; -90 pitch looks down).

    - ``earth``: yaw clockwise from north, pitch and roll relative to the horizon: what the
      telemetry readers produce (they turn a vehicle-relative gimbal yaw into an earth yaw).
    - ``stabilized``: pitch and roll relative to the horizon, yaw relative to the vehicle's nose
      (ArduPilot MOUNT_STATUS as sent, most 3-axis gimbals).
    - ``body``: all three angles relative to the airframe (a gimbal that only rotates the camera
      on the body).
    """

    EARTH = "earth"
    STABILIZED = "stabilized"
    BODY = "body"


# ned_from_camera of a gimbal times this = a virtual airframe whose down axis is the boresight.
_NADIR_FROM_FORWARD = quat_from_euler_deg(0.0, 90.0, 0.0)


def camera_attitude_deg(
    vehicle_ypr_deg: tuple[ArrayLike, ArrayLike, ArrayLike],
    gimbal_ypr_deg: tuple[ArrayLike, ArrayLike, ArrayLike] | None = None,
    mode: GimbalMode = GimbalMode.EARTH,
) -> tuple[F64, F64, F64]:
    """Camera (yaw, pitch, roll) in the convention of the module docstring.

    Without gimbal angles the camera is taken as fixed to the airframe, looking down.
    """
    vehicle_q = quat_from_euler_deg(*vehicle_ypr_deg)
    if gimbal_ypr_deg is None:
        return euler_deg_from_quat(vehicle_q)
    g_yaw, g_pitch, g_roll = (np.asarray(a, float) for a in gimbal_ypr_deg)
    if mode is GimbalMode.EARTH:
        ned_from_camera = quat_from_euler_deg(g_yaw, g_pitch, g_roll)
    elif mode is GimbalMode.STABILIZED:
        v_yaw = np.asarray(vehicle_ypr_deg[0], float)
        ned_from_camera = quat_from_euler_deg(v_yaw + g_yaw, g_pitch, g_roll)
    else:
        ned_from_camera = quat_multiply(vehicle_q, quat_from_euler_deg(g_yaw, g_pitch, g_roll))
    return euler_deg_from_quat(quat_multiply(ned_from_camera, _NADIR_FROM_FORWARD))


# ============================================================================================
# Interpolation


@dataclass(frozen=True, kw_only=True)
class InterpolatedPose:
    """Where the camera was at ``time_utc_s``.

    ``position_gap_s``: length of the track interval the position was interpolated over (0 when a
    sample falls on the time); ``attitude_gap_s`` likewise for attitude (None: no attitude).
    ``speed_m_s``: horizontal ground speed over that interval.
    """

    time_utc_s: float
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float | None
    alt_rel_home_m: float | None
    yaw_deg: float | None
    pitch_deg: float | None
    roll_deg: float | None
    position_gap_s: float
    attitude_gap_s: float | None
    speed_m_s: float


@dataclass(frozen=True, kw_only=True)
class PoseInterpolation:
    """One entry per requested time: the pose, or None with the reason in ``reasons``."""

    poses: tuple[InterpolatedPose | None, ...]
    reasons: tuple[str | None, ...]


def _iso(t: float) -> str:
    return datetime.fromtimestamp(t, tz=UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


#: How far beyond the ends of a track a time may be and still be placed (extrapolated), s.
EDGE_S = 0.2


def _bracket(track_t: F64, t: F64, max_gap_s: float) -> tuple[I64, I64, F64, F64, list[str | None]]:
    """Per time: sample indices (a, b), weight of b (position = a + w (b - a)), the length of
    the interval used (0 on a sample) and a reason (None when usable).

    A time within 1 ms of a sample takes that sample. A time beyond an end of the track, or in a
    gap longer than ``max_gap_s``, but within :data:`EDGE_S` of a sample is extrapolated from the
    interval on the sample's other side (a log starts a moment after the first trigger it
    records; a sparse track is sampled at the frames themselves). Anything else is refused.
    """
    n = track_t.size
    idx = np.searchsorted(track_t, t, side="right")
    lo = np.zeros(t.size, dtype=np.int64)
    hi = np.zeros(t.size, dtype=np.int64)
    weight = np.zeros(t.size)
    gap = np.zeros(t.size)
    reasons: list[str | None] = []
    start, end = float(track_t[0]), float(track_t[-1])

    def usable(a: int, b: int) -> bool:
        return 0 <= a < b < n and 0.0 < track_t[b] - track_t[a] <= max_gap_s

    for k, tk in enumerate(t):
        i = int(idx[k])  # track_t[i - 1] <= tk < track_t[i]
        pair: tuple[int, int] | None = None
        if i >= 1 and tk - track_t[i - 1] <= 1e-3:
            lo[k] = hi[k] = i - 1
        elif i < n and track_t[i] - tk <= 1e-3:
            lo[k] = hi[k] = i
        elif usable(i - 1, i):
            pair = (i - 1, i)
        elif i >= 2 and tk - track_t[i - 1] <= EDGE_S and usable(i - 2, i - 1):
            pair = (i - 2, i - 1)
        elif track_t[min(i, n - 1)] - tk <= EDGE_S and usable(i, i + 1):
            pair = (i, i + 1)
        else:
            if tk < start or tk > end:
                side = "before" if tk < start else "after"
                distance = start - tk if tk < start else tk - end
                reasons.append(
                    f"time {_iso(float(tk))} is {distance:.1f} s {side} the log ({_iso(start)} "
                    f"to {_iso(end)}): is the log from this flight and this day, is the camera "
                    f"clock offset right (--offset-s)?"
                )
            else:
                span = float(track_t[i] - track_t[i - 1])
                reasons.append(
                    f"the log has a gap of {span:.1f} s around {_iso(float(tk))} (longer than "
                    f"{max_gap_s:g} s): not interpolated"
                )
            continue
        if pair is not None:
            a, b = pair
            lo[k], hi[k] = a, b
            gap[k] = track_t[b] - track_t[a]
            weight[k] = (tk - track_t[a]) / gap[k]
        reasons.append(None)
    return lo, hi, weight, gap, reasons


def interpolate_poses(
    times_utc_s: ArrayLike,
    *,
    positions: PositionTrack,
    attitudes: AttitudeTrack | None = None,
    gimbal: AttitudeTrack | None = None,
    gimbal_mode: GimbalMode = GimbalMode.EARTH,
    frame: LocalFrame | None = None,
    max_gap_s: float = 5.0,
) -> PoseInterpolation:
    """Position and camera attitude at each time (UTC, POSIX s).

    Position is interpolated linearly in ``frame`` (default: the UTM zone of the track) between
    the two track samples around the time, altitudes linearly; attitude by slerp. A time outside
    the track, or inside a track gap longer than ``max_gap_s``, gets None and a reason. A missing
    or too sparse attitude (or gimbal, when the log has one) leaves the attitude None.
    """
    t = np.atleast_1d(np.asarray(times_utc_s, float))
    if len(positions) == 0:
        return PoseInterpolation(poses=(None,) * t.size, reasons=("the log has no positions",) * t.size)
    order = np.argsort(positions.time_utc_s, kind="stable")
    pt = positions.time_utc_s[order]
    lat = positions.lat_deg[order]
    lon = positions.lon_deg[order]
    if frame is None:
        frame = LocalFrame.utm_for(float(np.median(lon)), float(np.median(lat)))
    x, y = frame.to_xy(lon, lat)
    # Samples the frame cannot hold (a "0, 0" position before the GPS fix, half a world away)
    # are not positions of this flight.
    finite = np.isfinite(x) & np.isfinite(y)
    if not finite.all():
        logger.info("%d track samples outside the local frame ignored", int(np.sum(~finite)))
        order, pt, x, y = order[finite], pt[finite], x[finite], y[finite]
        if pt.size == 0:
            return PoseInterpolation(
                poses=(None,) * t.size, reasons=("the log has no usable positions",) * t.size
            )
    lo, hi, w, gap, reasons = _bracket(pt, t, max_gap_s)
    xi = x[lo] + w * (x[hi] - x[lo])
    yi = y[lo] + w * (y[hi] - y[lo])
    lon_i, lat_i = frame.to_lonlat(xi, yi)
    span = pt[hi] - pt[lo]
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(
            span > 0, np.hypot(x[hi] - x[lo], y[hi] - y[lo]) / np.where(span > 0, span, 1.0), 0.0
        )

    def alt(column: F64 | None) -> F64 | None:
        if column is None:
            return None
        c = column[order]
        return np.asarray(c[lo] + w * (c[hi] - c[lo]), float)

    alt_amsl = alt(positions.alt_amsl_m)
    alt_rel = alt(positions.alt_rel_home_m)

    def attitude_at(
        track: AttitudeTrack | None,
    ) -> tuple[F64, F64, F64, F64, list[str | None]] | None:
        if track is None or len(track) == 0:
            return None
        a_order = np.argsort(track.time_utc_s, kind="stable")
        at = track.time_utc_s[a_order]
        q = quat_from_euler_deg(track.yaw_deg[a_order], track.pitch_deg[a_order], track.roll_deg[a_order])
        a_lo, a_hi, a_w, a_gap, a_reasons = _bracket(at, t, max_gap_s)
        yaw_a, pitch_a, roll_a = euler_deg_from_quat(slerp(q[a_lo], q[a_hi], a_w))
        return yaw_a, pitch_a, roll_a, a_gap, a_reasons

    vehicle = attitude_at(attitudes)
    gimbal_at = attitude_at(gimbal)
    cam_yaw = cam_pitch = cam_roll = None
    if vehicle is not None:
        g = None if gimbal_at is None else (gimbal_at[0], gimbal_at[1], gimbal_at[2])
        cam_yaw, cam_pitch, cam_roll = camera_attitude_deg(
            (vehicle[0], vehicle[1], vehicle[2]), g, gimbal_mode
        )

    poses: list[InterpolatedPose | None] = []
    for k in range(t.size):
        if reasons[k] is not None:
            poses.append(None)
            continue
        has_attitude = (
            cam_yaw is not None
            and vehicle is not None
            and vehicle[4][k] is None
            and (gimbal is None or (gimbal_at is not None and gimbal_at[4][k] is None))
        )
        attitude_gap = None
        if has_attitude and vehicle is not None:
            attitude_gap = float(vehicle[3][k])
            if gimbal_at is not None:
                attitude_gap = max(attitude_gap, float(gimbal_at[3][k]))
        poses.append(
            InterpolatedPose(
                time_utc_s=float(t[k]),
                lat_deg=float(lat_i[k]),
                lon_deg=float(lon_i[k]),
                alt_amsl_m=None if alt_amsl is None else float(alt_amsl[k]),
                alt_rel_home_m=None if alt_rel is None else float(alt_rel[k]),
                yaw_deg=float(cam_yaw[k]) if has_attitude and cam_yaw is not None else None,
                pitch_deg=float(cam_pitch[k]) if has_attitude and cam_pitch is not None else None,
                roll_deg=float(cam_roll[k]) if has_attitude and cam_roll is not None else None,
                position_gap_s=float(gap[k]),
                attitude_gap_s=attitude_gap,
                speed_m_s=float(speed[k]),
            )
        )
    return PoseInterpolation(poses=tuple(poses), reasons=tuple(reasons))


# ============================================================================================
# The whole job


class FrameStatus(StrEnum):
    """What happened to one frame. The first three are placed; the others are not."""

    MATCHED = "matched"  # paired with a camera event, placed at the event time
    BY_TIME = "by_time"  # the log has no camera events: placed at the corrected capture time
    EXTRA_BY_TIME = "extra_by_time"  # no event for this frame; placed at its corrected capture time
    EXTRA = "extra"  # no event for this frame, and the track does not cover its time
    NO_POSITION = "no_position"  # the time is outside the log or in a gap of the track
    NO_CAPTURE_TIME = "no_capture_time"
    UNREADABLE = "unreadable"
    DUPLICATE_NAME = "duplicate_name"
    WRITE_FAILED = "write_failed"

    @property
    def placed(self) -> bool:
        return self in (FrameStatus.MATCHED, FrameStatus.BY_TIME, FrameStatus.EXTRA_BY_TIME)


class PositionSource(StrEnum):
    """Where a matched frame's position comes from: ``auto`` = the event's own position for
    RTK event files (MRK), the interpolated track otherwise (the event's position when the
    track does not cover the event)."""

    AUTO = "auto"
    TRACK = "track"
    EVENT = "event"


class OffsetSource(StrEnum):
    GIVEN = "given"  # --offset-s, used as is (time only) or as the alignment to refine
    MATCHED = "matched"  # from the alignment with camera events
    EXIF_GPS = "exif_gps"  # frames' own GPS time stamps versus capture time
    ASSUMED_ZERO = "assumed_zero"


@dataclass(frozen=True, kw_only=True)
class GeotagOptions:
    """Tuning of :func:`geotag_images`.

    - ``tolerance_s``: largest frame/event residual (None: 35 % of the event interval).
    - ``max_gap_s``: longest track interval to interpolate over.
    - ``xy_accuracy_m``, ``z_accuracy_m``: one-sigma accuracy of the log's positions (uncorrected
      GNSS by default); frames placed by time add speed x timing scatter.
    - ``place_extra_by_time``: place frames that have no event at their corrected capture time.
    - ``gimbal_mode``: see :class:`GimbalMode`.
    """

    tolerance_s: float | None = None
    max_gap_s: float = 5.0
    xy_accuracy_m: float = 2.0
    z_accuracy_m: float = 3.0
    place_extra_by_time: bool = True
    position_source: PositionSource = PositionSource.AUTO
    gimbal_mode: GimbalMode = GimbalMode.EARTH

    def __post_init__(self) -> None:
        if self.tolerance_s is not None and not (0.0 < self.tolerance_s <= 60.0):
            raise InputError(f"tolerance {self.tolerance_s} s is outside 0-60 s")
        if not (0.0 < self.max_gap_s <= 3600.0):
            raise InputError(f"max gap {self.max_gap_s} s is outside 0-3600 s")
        if self.xy_accuracy_m < 0 or self.z_accuracy_m < 0:
            raise InputError("position accuracies must be >= 0 m")


@dataclass(frozen=True, kw_only=True)
class FrameResult:
    """One frame's outcome. Position and attitude are None when the frame was not placed.

    ``capture_time_s``: the camera's time stamp (camera clock); ``time_utc_s``: the UTC time the
    frame was placed at (its event's time, or the corrected capture time); ``time_residual_s``:
    capture time minus the time predicted from the matched event (matched frames only).
    """

    name: str
    source_path: str
    status: FrameStatus
    message: str | None = None
    capture_time_s: float | None = None
    time_utc_s: float | None = None
    event_index: int | None = None
    event_seq: int | None = None
    time_residual_s: float | None = None
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_amsl_m: float | None = None
    alt_rel_home_m: float | None = None
    yaw_deg: float | None = None
    pitch_deg: float | None = None
    roll_deg: float | None = None
    xy_accuracy_m: float | None = None
    z_accuracy_m: float | None = None
    interpolation_gap_s: float | None = None
    position_source: str | None = None
    output_path: str | None = None

    @property
    def placed(self) -> bool:
        return self.status.placed

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "source_path": self.source_path,
            "status": str(self.status),
            "message": self.message,
            "capture_time": None if self.capture_time_s is None else _iso(self.capture_time_s),
            "capture_time_s": self.capture_time_s,
            "time_utc": None if self.time_utc_s is None else _iso(self.time_utc_s),
            "time_utc_s": self.time_utc_s,
            "event_index": self.event_index,
            "event_seq": self.event_seq,
            "time_residual_s": self.time_residual_s,
            "lat_deg": self.lat_deg,
            "lon_deg": self.lon_deg,
            "alt_amsl_m": self.alt_amsl_m,
            "alt_rel_home_m": self.alt_rel_home_m,
            "yaw_deg": self.yaw_deg,
            "pitch_deg": self.pitch_deg,
            "roll_deg": self.roll_deg,
            "xy_accuracy_m": self.xy_accuracy_m,
            "z_accuracy_m": self.z_accuracy_m,
            "interpolation_gap_s": self.interpolation_gap_s,
            "position_source": self.position_source,
            "output_path": self.output_path,
        }


@dataclass(frozen=True, kw_only=True)
class GeotagResult:
    """Everything :func:`geotag_images` did: per frame, and the summary.

    ``unmatched_events``: (index, seq) of camera events no frame was found for (dropped frames).
    ``untagged``: frames nothing was written for, with the reason. ``offset_s``: camera clock
    minus UTC; ``drift_ppm``: its rate of change.
    """

    frames: tuple[FrameResult, ...]
    n_events: int
    unmatched_events: tuple[tuple[int, int], ...]
    offset_s: float
    offset_source: OffsetSource
    drift_ppm: float
    residual_mad_s: float | None
    tolerance_s: float | None
    dry_run: bool
    out_dir: str
    outputs: tuple[str, ...] = ()
    warnings: tuple[str, ...] = field(default=())

    @property
    def extra_frames(self) -> tuple[str, ...]:
        """Frames without a camera event (whether or not they could be placed by time)."""
        return tuple(
            f.name for f in self.frames if f.status in (FrameStatus.EXTRA, FrameStatus.EXTRA_BY_TIME)
        )

    @property
    def untagged(self) -> tuple[FrameResult, ...]:
        return tuple(f for f in self.frames if not f.placed or f.status is FrameStatus.WRITE_FAILED)

    @property
    def tagged(self) -> tuple[FrameResult, ...]:
        return tuple(f for f in self.frames if f.placed)

    def to_dict(self) -> dict[str, Any]:
        return {
            "summary": {
                "frames": len(self.frames),
                "tagged": len(self.tagged),
                "untagged": [
                    {"name": f.name, "status": str(f.status), "message": f.message} for f in self.untagged
                ],
                "camera_events": self.n_events,
                "matched": sum(1 for f in self.frames if f.status is FrameStatus.MATCHED),
                "extra_frames": list(self.extra_frames),
                "unmatched_events": [{"index": i, "seq": s} for i, s in self.unmatched_events],
                "offset_s": self.offset_s,
                "offset_source": str(self.offset_source),
                "drift_ppm": self.drift_ppm,
                "residual_mad_s": self.residual_mad_s,
                "tolerance_s": self.tolerance_s,
                "dry_run": self.dry_run,
                "out_dir": self.out_dir,
                "outputs": list(self.outputs),
                "warnings": list(self.warnings),
            },
            "frames": [f.to_dict() for f in self.frames],
        }


def list_images(image_dir: str | os.PathLike[str]) -> list[Path]:
    """JPEG files under ``image_dir`` (recursively, cards split frames into subfolders), by path."""
    root = Path(image_dir)
    if not root.is_dir():
        raise InputError(f"{root} is not a folder of images; give the folder that holds the JPEGs")
    return sorted(
        p
        for p in root.rglob("*")
        if p.is_file() and p.suffix.lower() in JPEG_SUFFIXES and not p.name.startswith(".")
    )


@dataclass
class _Frame:
    path: Path
    tags: exif.ImageTags | None = None
    error: str | None = None


def _offset_from_exif_gps(frames: Sequence[_Frame]) -> float | None:
    """Camera clock minus UTC from frames that carry their own GPS time stamp (median)."""
    diffs = [
        fr.tags.capture_time_s - fr.tags.gps_time_utc_s
        for fr in frames
        if fr.tags is not None and fr.tags.capture_time_s is not None and fr.tags.gps_time_utc_s is not None
    ]
    return float(np.median(diffs)) if diffs else None


def _accuracy(options: GeotagOptions, speed_m_s: float, timing_s: float) -> tuple[float, float]:
    xy = math.hypot(options.xy_accuracy_m, speed_m_s * timing_s)
    return xy, options.z_accuracy_m


def _event_pose(events: CameraEvents, j: int) -> InterpolatedPose | None:
    if events.lat_deg is None or events.lon_deg is None:
        return None

    def col(c: F64 | None) -> float | None:
        return None if c is None else float(c[j])

    yaw, pitch, roll = col(events.yaw_deg), col(events.pitch_deg), col(events.roll_deg)
    if yaw is not None and pitch is not None and roll is not None:
        cy, cp, cr = camera_attitude_deg(([yaw], [pitch], [roll]))
        yaw, pitch, roll = float(cy[0]), float(cp[0]), float(cr[0])
    else:
        yaw = pitch = roll = None
    return InterpolatedPose(
        time_utc_s=float(events.time_utc_s[j]),
        lat_deg=float(events.lat_deg[j]),
        lon_deg=float(events.lon_deg[j]),
        alt_amsl_m=col(events.alt_amsl_m),
        alt_rel_home_m=col(events.alt_rel_home_m),
        yaw_deg=yaw,
        pitch_deg=pitch,
        roll_deg=roll,
        position_gap_s=0.0,
        attitude_gap_s=None if yaw is None else 0.0,
        speed_m_s=0.0,
    )


def geotag_images(
    image_dir: str | os.PathLike[str],
    log: FlightLog,
    out_dir: str | os.PathLike[str],
    *,
    offset_s: float | None = None,
    dry_run: bool = False,
    in_place: bool = False,
    backup_dir: str | os.PathLike[str] | None = None,
    overwrite: bool = False,
    progress: ProgressCallback | None = None,
    options: GeotagOptions | None = None,
) -> GeotagResult:
    """Geotag every JPEG under ``image_dir`` from ``log``; results in ``out_dir``.

    ``out_dir`` receives the tagged copies (unless ``in_place``), the sidecars (``geo.txt``,
    ``pix4d_geolocation.csv``, ``cameras.geojson``) and ``geotag_report.json``; it is built in a
    staging folder and moved into place whole. ``offset_s``: camera clock minus UTC, seconds, if
    known. ``in_place`` rewrites the originals, after copying each to ``backup_dir`` (required).
    ``dry_run`` writes nothing. Frames that cannot be placed are reported, never written.
    """
    options = options or GeotagOptions()
    report = progress or (lambda done, total: None)
    paths = list_images(image_dir)
    if not paths:
        raise InputError(f"no JPEG images (.jpg, .jpeg) under {image_dir}")
    if in_place and backup_dir is None:
        raise InputError("--in-place needs --backup-dir: the originals are copied there first")
    if not dry_run:
        check_output_dir(out_dir, overwrite=overwrite)
        if not in_place and Path(out_dir).resolve() == Path(image_dir).resolve():
            raise InputError("the output folder is the image folder; choose another -o or use --in-place")
    total = 2 * len(paths)

    frames: list[_Frame] = []
    for done, path in enumerate(paths, start=1):
        try:
            frames.append(_Frame(path, tags=exif.read_tags(path)))
        except (GeotagError, OSError) as error:
            frames.append(_Frame(path, error=str(error)))
        report(done, total)

    name_count: dict[str, int] = {}
    for fr in frames:
        name_count[fr.path.name.lower()] = name_count.get(fr.path.name.lower(), 0) + 1
    timed = [fr for fr in frames if fr.tags is not None and fr.tags.capture_time_s is not None]
    timed.sort(key=lambda fr: (fr.tags.capture_time_s if fr.tags else 0.0, str(fr.path)))
    times = np.array([fr.tags.capture_time_s for fr in timed if fr.tags is not None], dtype=float)

    warnings: list[str] = list(log.warnings)
    events = log.events if log.events is not None and len(log.events) > 0 else None
    matching: Matching | None = None
    results: dict[Path, FrameResult] = {}
    unmatched_events: tuple[tuple[int, int], ...] = ()
    residual_mad: float | None = None
    tolerance: float | None = None
    drift_ppm = 0.0

    def model_to_utc(t: F64) -> F64:
        if matching is not None:
            return matching.frame_time_to_utc(t)
        return np.asarray(t - offset, float)

    # A camera that writes no sub-seconds truncates its times to the second: take the middle.
    whole_seconds = bool(times.size > 1 and np.all(np.abs(times - np.round(times)) < 1e-6))
    if whole_seconds:
        times = times + 0.5
        warnings.append(
            "the capture times have whole seconds only (no SubSecTimeOriginal): matched with a "
            "wider tolerance; frames placed by time can be off by up to half a second of flight"
        )
    if events is not None and times.size:
        matching = match_frames_to_events(
            times,
            events.time_utc_s,
            offset_s=offset_s,
            tolerance_s=options.tolerance_s,
            resolution_s=1.0 if whole_seconds else 0.0,
        )
        offset = matching.offset_s
        offset_source = OffsetSource.MATCHED if offset_s is None else OffsetSource.GIVEN
        drift_ppm = matching.drift_ppm
        residual_mad = matching.residual_mad_s
        tolerance = matching.tolerance_s
        warnings.extend(matching.warnings)
        unmatched_events = tuple((int(j), int(events.seq[j])) for j in matching.unmatched_events)
    else:
        if events is None and log.events is not None:
            warnings.append("the log has no camera events: frames are placed by capture time")
        if offset_s is not None:
            offset, offset_source = float(offset_s), OffsetSource.GIVEN
        else:
            from_gps = _offset_from_exif_gps(timed)
            if from_gps is not None:
                offset, offset_source = from_gps, OffsetSource.EXIF_GPS
            else:
                offset, offset_source = 0.0, OffsetSource.ASSUMED_ZERO
                if timed and not all(fr.tags is not None and fr.tags.capture_time_zone_known for fr in timed):
                    warnings.append(
                        "no camera events and no --offset-s: the camera clock is assumed to be "
                        "UTC; a wrong clock or time zone places every frame wrongly"
                    )

    # What time and which event each timed frame is placed at.
    event_of = matching.event_of_frame() if matching is not None else {}
    residual_of = (
        {int(fi): float(r) for (fi, _), r in zip(matching.pairs, matching.residuals_s, strict=True)}
        if matching is not None
        else {}
    )
    utc_of_frame = model_to_utc(times) if times.size else np.zeros(0)
    place_times: list[float] = []
    for k in range(len(timed)):
        if k in event_of and events is not None:
            place_times.append(float(events.time_utc_s[event_of[k]]))
        else:
            place_times.append(float(utc_of_frame[k]))

    interpolation: PoseInterpolation | None = None
    if log.positions is not None and len(log.positions) > 0 and place_times:
        interpolation = interpolate_poses(
            place_times,
            positions=log.positions,
            attitudes=log.attitudes,
            gimbal=log.gimbal,
            gimbal_mode=options.gimbal_mode,
            max_gap_s=options.max_gap_s,
        )
    prefer_event = options.position_source is PositionSource.EVENT or (
        options.position_source is PositionSource.AUTO and log.format == "mrk"
    )
    timing_scatter = residual_mad if residual_mad is not None else 0.0

    for k, fr in enumerate(timed):
        assert fr.tags is not None and fr.tags.capture_time_s is not None
        base: dict[str, Any] = {
            "name": fr.path.name,
            "source_path": str(fr.path),
            "capture_time_s": fr.tags.capture_time_s,
            "time_utc_s": place_times[k],
        }
        pose: InterpolatedPose | None = None
        reason: str | None = None
        source = "track"
        j = event_of.get(k)
        if j is not None and events is not None:
            status = FrameStatus.MATCHED
            base["event_index"] = j
            base["event_seq"] = int(events.seq[j])
            base["time_residual_s"] = residual_of.get(k)
            if options.position_source is not PositionSource.TRACK:
                event_pose = _event_pose(events, j)
            else:
                event_pose = None
            if prefer_event and event_pose is not None:
                pose, source = event_pose, "event"
            elif interpolation is not None and interpolation.poses[k] is not None:
                pose = interpolation.poses[k]
            elif event_pose is not None:
                pose, source = event_pose, "event"
            else:
                reason = interpolation.reasons[k] if interpolation is not None else "the log has no positions"
            if pose is None:
                status = FrameStatus.NO_POSITION
        else:
            extra = events is not None
            status = FrameStatus.EXTRA_BY_TIME if extra else FrameStatus.BY_TIME
            if extra and not options.place_extra_by_time:
                pose, reason = None, "no camera event matches this frame"
            elif interpolation is not None:
                pose, reason = interpolation.poses[k], interpolation.reasons[k]
            else:
                reason = "the log has no positions to place a frame by time"
            if pose is None:
                status = FrameStatus.EXTRA if extra else FrameStatus.NO_POSITION
                if extra:
                    reason = f"no camera event matches this frame; {reason}" if reason else "no camera event"
        if pose is not None:
            timing = 0.0 if status is FrameStatus.MATCHED else timing_scatter
            xy_acc, z_acc = _accuracy(options, pose.speed_m_s, timing)
            if status is FrameStatus.EXTRA_BY_TIME:
                reason = (
                    "no camera event matches this frame: placed at its capture time corrected by the offset"
                )
            results[fr.path] = FrameResult(
                **base,
                status=status,
                message=reason,
                lat_deg=pose.lat_deg,
                lon_deg=pose.lon_deg,
                alt_amsl_m=pose.alt_amsl_m,
                alt_rel_home_m=pose.alt_rel_home_m,
                yaw_deg=pose.yaw_deg,
                pitch_deg=pose.pitch_deg,
                roll_deg=pose.roll_deg,
                xy_accuracy_m=xy_acc,
                z_accuracy_m=z_acc,
                interpolation_gap_s=pose.position_gap_s,
                position_source=source,
            )
        else:
            results[fr.path] = FrameResult(**base, status=status, message=reason)

    for fr in frames:
        if fr.tags is None:
            results[fr.path] = FrameResult(
                name=fr.path.name,
                source_path=str(fr.path),
                status=FrameStatus.UNREADABLE,
                message=fr.error,
            )
        elif fr.tags.capture_time_s is None:
            results[fr.path] = FrameResult(
                name=fr.path.name,
                source_path=str(fr.path),
                status=FrameStatus.NO_CAPTURE_TIME,
                message="no capture time (DateTimeOriginal) in the file: it cannot be matched or placed",
            )
        elif name_count[fr.path.name.lower()] > 1:
            old = results[fr.path]
            results[fr.path] = FrameResult(
                **{
                    **old.__dict__,
                    "status": FrameStatus.DUPLICATE_NAME,
                    "message": f"another image is also named {fr.path.name} (names must be unique "
                    f"for the sidecars); geotag the folders separately or rename",
                    "lat_deg": None,
                    "lon_deg": None,
                    "alt_amsl_m": None,
                    "alt_rel_home_m": None,
                    "yaw_deg": None,
                    "pitch_deg": None,
                    "roll_deg": None,
                }
            )
    timed_paths = {fr.path for fr in timed}
    ordered = [results[fr.path] for fr in timed] + [
        results[fr.path] for fr in frames if fr.path not in timed_paths
    ]

    if interpolation is not None and timed and not any(r.placed for r in ordered):
        outside = [r for r in interpolation.reasons if r is not None and " the log (" in r]
        if len(outside) == len(timed):
            warnings.append(
                "no frame falls inside the log: it is from another flight or day, or the camera "
                "clock is off; pass --offset-s (camera clock minus UTC, seconds)"
            )
    for message in warnings:
        logger.warning("%s", message)

    final: list[FrameResult] = ordered
    outputs: list[str] = []
    if not dry_run:
        final, outputs = _write_outputs(
            ordered,
            out_dir=Path(out_dir),
            in_place=in_place,
            backup_dir=None if backup_dir is None else Path(backup_dir),
            overwrite=overwrite,
            report=lambda n: report(len(paths) + n, total),
            summary=lambda frames_now, outs: GeotagResult(
                frames=tuple(frames_now),
                n_events=0 if events is None else len(events),
                unmatched_events=unmatched_events,
                offset_s=offset,
                offset_source=offset_source,
                drift_ppm=drift_ppm,
                residual_mad_s=residual_mad,
                tolerance_s=tolerance,
                dry_run=dry_run,
                out_dir=str(out_dir),
                outputs=tuple(outs),
                warnings=tuple(warnings),
            ),
        )
    report(total, total)
    return GeotagResult(
        frames=tuple(final),
        n_events=0 if events is None else len(events),
        unmatched_events=unmatched_events,
        offset_s=offset,
        offset_source=offset_source,
        drift_ppm=drift_ppm,
        residual_mad_s=residual_mad,
        tolerance_s=tolerance,
        dry_run=dry_run,
        out_dir=str(out_dir),
        outputs=tuple(outputs),
        warnings=tuple(warnings),
    )


def _json_clean(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_clean(v) for v in value]
    return value


def report_json(result: GeotagResult) -> str:
    """The result as JSON text (what ``geotag_report.json`` holds and ``--json`` prints): the
    summary indented, then one line per frame (json's fast encoder; 1000 frames stay quick)."""
    doc = _json_clean(result.to_dict())
    summary = json.dumps(doc["summary"], indent=2, allow_nan=False).replace("\n", "\n  ")
    frames = ",\n    ".join(json.dumps(f, allow_nan=False) for f in doc["frames"])
    return f'{{\n  "summary": {summary},\n  "frames": [\n    {frames}\n  ]\n}}\n'


def _geotag_of(frame: FrameResult) -> exif.GeoTag:
    assert frame.lat_deg is not None and frame.lon_deg is not None
    return exif.GeoTag(
        lat_deg=frame.lat_deg,
        lon_deg=frame.lon_deg,
        alt_amsl_m=frame.alt_amsl_m,
        time_utc_s=frame.time_utc_s,
        yaw_deg=frame.yaw_deg,
        pitch_deg=frame.pitch_deg,
        roll_deg=frame.roll_deg,
        xy_accuracy_m=frame.xy_accuracy_m,
        z_accuracy_m=frame.z_accuracy_m,
        alt_rel_home_m=frame.alt_rel_home_m,
    )


def _with(frame: FrameResult, **changes: Any) -> FrameResult:
    return FrameResult(**{**frame.__dict__, **changes})


def _write_outputs(
    frames: list[FrameResult],
    *,
    out_dir: Path,
    in_place: bool,
    backup_dir: Path | None,
    overwrite: bool,
    report: Callable[[int], None],
    summary: Callable[[list[FrameResult], list[str]], GeotagResult],
) -> tuple[list[FrameResult], list[str]]:
    """Write tagged frames, sidecars and the report; returns the frames with their output paths."""
    to_write = [f for f in frames if f.placed]
    written: list[FrameResult] = []
    if in_place:
        assert backup_dir is not None
        backup_dir.mkdir(parents=True, exist_ok=True)
        for frame in to_write:  # every backup before the first original is touched
            target = backup_dir / frame.name
            if target.exists() and not overwrite:
                raise OutputExistsError(
                    f"backup {target} exists; pass --overwrite or choose another --backup-dir"
                )
            shutil.copy2(frame.source_path, target)
    with staged_output_dir(out_dir, overwrite=overwrite) as staging:
        by_path: dict[str, FrameResult] = {}
        for n, frame in enumerate(to_write, start=1):
            dst = Path(frame.source_path) if in_place else staging / frame.name
            final_path = Path(frame.source_path) if in_place else out_dir / frame.name
            try:
                # In place: each original is replaced atomically (synced). Copies go plainly into
                # the staging folder, which is moved into place whole at the end.
                exif.write_geotag(
                    frame.source_path,
                    dst,
                    _geotag_of(frame),
                    overwrite=in_place,
                    atomic=in_place,
                )
                by_path[frame.source_path] = _with(frame, output_path=str(final_path))
            except (GeotagError, OSError) as error:
                by_path[frame.source_path] = _with(
                    frame, status=FrameStatus.WRITE_FAILED, message=f"tags not written: {error}"
                )
            report(n)
        written = [by_path.get(f.source_path, f) for f in frames]
        placed = [f for f in written if f.placed]
        rows = [
            sidecars.CameraPosition(
                name=f.name,
                lat_deg=f.lat_deg,
                lon_deg=f.lon_deg,
                alt_amsl_m=f.alt_amsl_m,
                yaw_deg=f.yaw_deg,
                pitch_deg=f.pitch_deg,
                roll_deg=f.roll_deg,
                xy_accuracy_m=f.xy_accuracy_m,
                z_accuracy_m=f.z_accuracy_m,
                time_utc_s=f.time_utc_s,
                status=str(f.status),
            )
            for f in placed
            if f.lat_deg is not None and f.lon_deg is not None
        ]
        sidecar_paths = sidecars.write_all(staging, rows)
        outputs = [str(out_dir / p.name) for p in sidecar_paths] + [str(out_dir / REPORT_NAME)]
        result = summary(written, outputs)
        atomic_write_text(staging / REPORT_NAME, report_json(result))
    return written, outputs
