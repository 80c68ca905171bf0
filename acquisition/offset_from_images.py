"""The camera clock offset from the frames' own motion against the track, when the log has no
camera events (``sfap geotag --offset-from-images``).

Without events a frame is placed at its capture time minus the camera clock offset, and every
second of error moves it a second of flight along the track. The frames themselves say where
the camera was relative to the other frames: a quick reconstruction of them (SIFT on downscaled
frames, matches between neighbours in time and in space, two-view verification and COLMAP's
incremental mapper, all through :mod:`processing.handoff.colmap_adapter`) gives each registered
frame's camera centre, in the model's own frame (its scale, rotation and origin unknown). For a
candidate offset ``d`` the track is interpolated at capture time minus ``d`` and each model is
aligned to those positions by a similarity (:func:`processing.similarity.fit_similarity`); the
misfit is the sum of the squared residuals over the models (:func:`misfit`). The offset that
minimises it is the estimate (:func:`estimate_offset`).

What pins it down: a shift in time slides every frame along the track. Along a straight line
flown at constant speed that slide is a translation, which the similarity absorbs: the misfit
curve is flat and nothing is claimed. Lines flown in opposite directions slide opposite ways,
turns bend the slide, speed changes stretch it: none is a similarity, so the misfit rises.

Uncertainty, from the misfit curve: with the residual variance ``s2 = S_min / dof`` (three
residuals a frame, less seven parameters a model and the offset), the offsets whose misfit is
within ``9 s2`` of the minimum (a rise of nine in chi-square) are the three-sigma interval, those
within ``s2`` the one-sigma interval; the sigma is the wider of a sixth of the first and half the
second (the same on a parabola; where the misfit has a flat bottom, the first is fooled by a
shallow dip that noise makes at its edge, the second by a box shape). It is widened by
``sqrt((1 + r) / (1 - r))`` for the lag-1 correlation ``r`` of the residuals along the flight
(GPS error and a reconstruction's slow drift are correlated in time; independent residuals would
overstate what the frames know), and replaced by the delete-a-run jackknife's standard error
when that is larger (the frames in ten runs of capture order, each left out in turn). No
estimate is claimed when the sigma exceeds :data:`MAX_SIGMA_S`, when the misfit does not rise on
both sides within the offsets searched (a flat curve), when leaving out a run of frames (or a
single frame) flattens the minimum or moves it by more than :data:`AMBIGUITY_SIGMA` sigma (a dip
the rest of the frames do not make), or when another, separate minimum lies within
:data:`AMBIGUITY_SIGMA` sigma of the best (a repeating pattern: one pair of lines of a lawnmower
looks like the next once the similarity has moved it).

The offsets searched are those that put every registered frame inside the track, so a camera
clock hours off (a time zone) is found as long as the log covers the photos.
"""

from __future__ import annotations

import logging
import math
import os
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .errors import GeotagError
from .local_plane import LocalPlane
from .telemetry.model import FlightLog, PositionTrack

if TYPE_CHECKING:
    from .geotag_frames import Frame
    from .geotag_placement import Clock

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]

#: Registered frames a model needs to take part: seven similarity parameters need redundancy.
MIN_MODEL_FRAMES = 5
#: The step of the first scan over every offset searched, and of the scan about its minimum, s.
COARSE_STEP_S = 0.25
FINE_STEP_S = 0.01
#: No estimate is claimed with a one-sigma uncertainty above this, s: an offset known only to
#: more than a second places frames no better than a crew's sync point (known to about 1 s,
#: :data:`acquisition.sync_points.SYNC_TIME_ACCURACY_S`) and is not worth the claim.
MAX_SIGMA_S = 1.0
#: The lowest local minima of the coarse scan refined by a fine scan (a noisy flat curve has one at
#: nearly every step; a real minimum is among the lowest even when narrower than the step).
REFINED_MINIMA = 25
#: Runs of frames the jackknife leaves out in turn (its standard error has this many less one
#: degrees of freedom).
JACKKNIFE_BLOCKS = 10
#: Another minimum of the misfit within this many sigma of the best makes the curve ambiguous.
AMBIGUITY_SIGMA = 3.0
#: The lag-1 correlation of the residuals used for the widening is capped here (a widening of
#: at most sqrt(19) = 4.4).
MAX_CORRELATION = 0.9


@dataclass(frozen=True, kw_only=True)
class ModelPath:
    """One reconstruction's registered frames: their names, capture times (camera clock, s) and
    camera centres in the model's own frame (N x 3), in capture order."""

    names: tuple[str, ...]
    capture_s: F64
    centres: F64

    def __len__(self) -> int:
        return len(self.names)


@dataclass(frozen=True, kw_only=True)
class TrackXYZ:
    """A position track in metres (east, north, up on a local plane), its times sorted (UTC s)."""

    time_s: F64
    xyz_m: F64

    @classmethod
    def from_positions(cls, positions: PositionTrack) -> TrackXYZ:
        """The log's track on the plane tangent at its median; altitude AMSL (or above home; 0
        when the log has neither: the alignment is then horizontal in effect)."""
        order = np.argsort(positions.time_utc_s, kind="stable")
        t = np.asarray(positions.time_utc_s, float)[order]
        lat = np.asarray(positions.lat_deg, float)[order]
        lon = np.asarray(positions.lon_deg, float)[order]
        alt_source = positions.alt_amsl_m if positions.alt_amsl_m is not None else positions.alt_rel_home_m
        alt = np.zeros_like(t) if alt_source is None else np.asarray(alt_source, float)[order]
        ok = np.isfinite(t) & np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt)
        t, lat, lon, alt = t[ok], lat[ok], lon[ok], alt[ok]
        keep = np.concatenate([[True], np.diff(t) > 0]) if t.size else np.zeros(0, bool)
        t, lat, lon, alt = t[keep], lat[keep], lon[keep], alt[keep]
        if t.size < 2:
            raise GeotagError("the log's track has fewer than two positions: no offset can be estimated")
        east, north = LocalPlane.centred_on(lon, lat).to_xy(lon, lat)
        return cls(time_s=t, xyz_m=np.column_stack([east, north, alt]))

    def at(self, times_s: F64) -> F64:
        """Positions at ``times_s`` (linear interpolation; times must lie within the track)."""
        return np.column_stack([np.interp(times_s, self.time_s, self.xyz_m[:, k]) for k in range(3)])


def _aligned_residuals(centres: F64, target: F64) -> F64 | None:
    """Residuals (N x 3, metres) of the best similarity from model to track positions; None when
    the centres lie on a line (no rotation about it is fixed: such a model is left out)."""
    from processing.similarity import SimilarityError, fit_similarity

    try:
        similarity = fit_similarity(centres, target)
    except SimilarityError:
        return None
    return np.asarray(similarity.apply(centres) - target, dtype=np.float64)


def aligned_rss(centres: F64, targets: F64) -> F64:
    """Sum of squared residuals of the best similarity taking ``centres`` (N x 3) to each of
    ``targets`` (M x N x 3), in closed form (Umeyama 1991, eq. 33: the least mean squared error is
    ``var_y - trace(D S)^2 / var_x``, D the singular values of the cross-covariance and S the
    reflection guard), for M candidate offsets at once. A model whose centres are all one point
    fixes no scale: its misfit is the targets' own spread."""
    x = centres - centres.mean(axis=0)
    y = targets - targets.mean(axis=1, keepdims=True)
    n = centres.shape[0]
    var_x = float(np.sum(x * x)) / n
    var_y = np.sum(y * y, axis=(1, 2)) / n
    if var_x <= 0:
        return np.asarray(n * var_y, dtype=np.float64)
    cov = np.einsum("mni,nj->mij", y, x) / n
    singular = np.linalg.svd(cov, compute_uv=False)
    sign = np.where(np.linalg.det(cov) < 0, -1.0, 1.0)
    trace = singular[:, 0] + singular[:, 1] + sign * singular[:, 2]
    return np.asarray(np.maximum(n * (var_y - trace * trace / var_x), 0.0), dtype=np.float64)


def _metres_per_unit(model: ModelPath, track: TrackXYZ) -> float:
    """A model's scale, metres per model unit, from speeds: the track's median ground speed (moving
    samples) over the model's median speed between consecutive frames. It only weighs the models
    against each other and puts the misfit in metres; an error in it moves no minimum."""
    steps = np.diff(track.time_s)
    track_speed = np.hypot(*np.diff(track.xyz_m[:, :2], axis=0).T) / np.where(steps > 0, steps, np.inf)
    moving = track_speed[track_speed > 0.5]
    order = np.argsort(model.capture_s, kind="stable")
    gaps = np.diff(model.capture_s[order])
    moved = np.linalg.norm(np.diff(model.centres[order], axis=0), axis=1)
    ok = gaps > 0
    if not moving.size or not ok.any() or not np.median(moved[ok] / gaps[ok]) > 0:
        return 1.0
    return float(np.median(moving) / np.median(moved[ok] / gaps[ok]))


def misfit_curve(models: Sequence[ModelPath], track: TrackXYZ, offsets_s: F64) -> F64:
    """Sum over the models of the squared residuals (m^2) of the similarity aligning the track, at
    the frames' capture time minus each of ``offsets_s``, to the model's camera centres, measured in
    the model (whose shape does not change with the offset) and put in metres by
    :func:`_metres_per_unit`. Measured the other way, on the track, a similarity could shrink a
    model onto the few metres the vehicle moves while it stands before take-off, and an offset that
    puts the frames there would fit best; in the model the misfit is the share of the model's spread
    the track leaves unexplained (``1 - R^2``, the same both ways), so that offset fits worst."""
    offsets = np.asarray(offsets_s, dtype=np.float64).reshape(-1)
    total = np.zeros(offsets.size)
    for model in models:
        times = model.capture_s[None, :] - offsets[:, None]
        targets = track.at(times.ravel()).reshape(offsets.size, len(model), 3)
        spread_y = np.sum((targets - targets.mean(axis=1, keepdims=True)) ** 2, axis=(1, 2))
        unexplained = np.where(
            spread_y > 0, aligned_rss(model.centres, targets) / np.where(spread_y > 0, spread_y, 1.0), 1.0
        )
        spread_x = float(np.sum((model.centres - model.centres.mean(axis=0)) ** 2))
        total += unexplained * spread_x * _metres_per_unit(model, track) ** 2
    return total


def misfit(models: Sequence[ModelPath], track: TrackXYZ, offset_s: float) -> tuple[float, int]:
    """:func:`misfit_curve` at one offset, and the number of frames that entered it."""
    return float(misfit_curve(models, track, np.array([offset_s]))[0]), sum(len(m) for m in models)


def search_range_s(models: Sequence[ModelPath], track: TrackXYZ) -> tuple[float, float] | None:
    """The offsets that put every frame of ``models`` inside the track (None: none does)."""
    first = min(float(m.capture_s.min()) for m in models)
    last = max(float(m.capture_s.max()) for m in models)
    low, high = last - float(track.time_s[-1]), first - float(track.time_s[0])
    return (low, high) if low <= high else None


def _lag1_correlation(models: Sequence[ModelPath], track: TrackXYZ, offset_s: float) -> float:
    """Lag-1 correlation of the residuals along each model's frames (in capture order), pooled
    over the three axes and the models; clipped to [0, MAX_CORRELATION]."""
    products, squares = 0.0, 0.0
    for model in models:
        order = np.argsort(model.capture_s, kind="stable")
        residuals = _aligned_residuals(model.centres[order], track.at(model.capture_s[order] - offset_s))
        if residuals is None or len(residuals) < 3:
            continue
        r = residuals - residuals.mean(axis=0)
        products += float(np.sum(r[1:] * r[:-1]))
        squares += float(np.sum(r * r))
    if squares <= 0:
        return 0.0
    return float(np.clip(products / squares, 0.0, MAX_CORRELATION))


@dataclass(frozen=True, kw_only=True)
class OffsetEstimate:
    """What the images say about the camera clock offset (camera clock minus UTC, s).

    ``offset_s``/``sigma_s``: the estimate and its one-sigma uncertainty, None when the images do
    not pin it down (``reason`` says why); ``best_offset_s``: the misfit's minimum even then
    (None when no misfit could be computed); ``rms_m``: the residual RMS there, per frame (3D);
    ``prior_offset_s``/``rms_at_prior_m``: the offset geotag would otherwise use and the misfit
    there; ``search_s``: the offsets searched; ``competing_s``: other minima within
    :data:`AMBIGUITY_SIGMA` sigma; ``widening``: the factor applied for correlated residuals.
    """

    offset_s: float | None
    sigma_s: float | None
    best_offset_s: float | None
    rms_m: float | None
    prior_offset_s: float
    rms_at_prior_m: float | None
    search_s: tuple[float, float] | None
    frames_used: int
    models: int
    competing_s: tuple[float, ...] = ()
    widening: float = 1.0
    jackknife_sigma_s: float | None = None
    reason: str | None = None
    frames_registered: int = 0
    frames_given: int = 0
    seconds: float = 0.0

    @property
    def claimed(self) -> bool:
        return self.offset_s is not None

    def as_dict(self) -> dict[str, Any]:
        return {
            "source": "images (reconstruction of the frames aligned to the track)",
            "offset_s": self.offset_s,
            "sigma_s": self.sigma_s,
            "best_offset_s": self.best_offset_s,
            "rms_m": self.rms_m,
            "prior_offset_s": self.prior_offset_s,
            "rms_at_prior_m": self.rms_at_prior_m,
            "search_s": list(self.search_s) if self.search_s is not None else None,
            "frames_given": self.frames_given,
            "frames_registered": self.frames_registered,
            "frames_used": self.frames_used,
            "models": self.models,
            "competing_offsets_s": list(self.competing_s),
            "correlation_widening": self.widening,
            "jackknife_sigma_s": self.jackknife_sigma_s,
            "reason": self.reason,
            "seconds": self.seconds,
        }


def _crossing(offsets: F64, values: F64, start: int, level: float, step: int) -> float | None:
    """Where ``values`` first rises to ``level`` walking from index ``start`` by ``step`` (linear
    between samples); None when it never does inside the samples."""
    k = start
    while 0 <= k + step < len(values):
        a, b = values[k], values[k + step]
        if b >= level:
            frac = (level - a) / (b - a) if b != a else 0.0
            return float(offsets[k] + frac * (offsets[k + step] - offsets[k]))
        k += step
    return None


def _scan(
    models: Sequence[ModelPath], track: TrackXYZ, low: float, high: float
) -> tuple[F64, F64, list[tuple[float, float]]]:
    """The misfit over ``low``-``high``: a coarse scan, and a fine scan about each of its lowest
    local minima (a minimum narrower than the coarse step, fast flight and exact centres, is then
    compared at its true depth). The offsets and values sorted, and the refined minima."""
    coarse = np.unique(np.concatenate([np.arange(low, high, COARSE_STEP_S), [high]]))
    coarse_s = misfit_curve(models, track, coarse)
    inner = (np.r_[True, coarse_s[1:] <= coarse_s[:-1]]) & (np.r_[coarse_s[:-1] <= coarse_s[1:], True])
    minima: list[tuple[float, float]] = []
    fine_parts: list[F64] = []
    fine_values: list[F64] = []
    candidates = np.flatnonzero(inner)
    for j in candidates[np.argsort(coarse_s[candidates], kind="stable")][:REFINED_MINIMA]:
        fine = np.arange(
            max(low, coarse[j] - 2 * COARSE_STEP_S), min(high, coarse[j] + 2 * COARSE_STEP_S), FINE_STEP_S
        )
        fine = np.unique(np.concatenate([fine, [coarse[j]]]))
        fine_s = misfit_curve(models, track, fine)
        fine_parts.append(fine)
        fine_values.append(fine_s)
        m = int(np.argmin(fine_s))
        minima.append((float(fine_s[m]), float(fine[m])))
    offsets = np.concatenate([coarse, *fine_parts])
    values = np.concatenate([coarse_s, *fine_values])
    order = np.argsort(offsets, kind="stable")
    return offsets[order], values[order], minima


def _without(models: Sequence[ModelPath], out_of: Sequence[NDArray[np.bool_]]) -> list[ModelPath]:
    """The models without the frames marked in ``out_of`` (one mask a model); models left with fewer
    than :data:`MIN_MODEL_FRAMES` frames dropped."""
    kept: list[ModelPath] = []
    for m, out in zip(models, out_of, strict=True):
        if int((~out).sum()) >= MIN_MODEL_FRAMES:
            kept.append(
                ModelPath(
                    names=tuple(n for n, o in zip(m.names, out, strict=True) if not o),
                    capture_s=m.capture_s[~out],
                    centres=m.centres[~out],
                )
            )
    return kept


def _best_within(
    models: Sequence[ModelPath], track: TrackXYZ, low: float, high: float, variance: float
) -> float | None:
    """The misfit's minimum within ``low``-``high``; None when the curve does not rise from it by
    ``variance`` (a chi-square of one) on both sides inside the window, or no model is left."""
    if not models:
        return None
    offsets, values, _ = _scan(models, track, low, high)
    best = int(np.argmin(values))
    level = float(values[best]) + variance
    if (
        _crossing(offsets, values, best, level, -1) is None
        or _crossing(offsets, values, best, level, +1) is None
    ):
        return None
    return float(offsets[best])


def _jackknife_sigma(
    models: Sequence[ModelPath], track: TrackXYZ, best_s: float, half_window_s: float, variance: float
) -> float | None:
    """The delete-a-block jackknife's standard error of the best offset: the frames in capture
    order cut into :data:`JACKKNIFE_BLOCKS` runs, each left out in turn and the minimum found
    again within ``half_window_s`` of ``best_s`` (runs, not single frames, so that errors
    correlated along the flight count). None when a minimum without a run is at the window's edge."""
    times = np.sort(np.concatenate([m.capture_s for m in models]))
    edges = times[np.linspace(0, len(times) - 1, JACKKNIFE_BLOCKS + 1).round().astype(int)]
    edges[-1] = np.inf
    estimates: list[float] = []
    for b in range(JACKKNIFE_BLOCKS):
        masks = [(m.capture_s >= edges[b]) & (m.capture_s < edges[b + 1]) for m in models]
        where = _best_within(
            _without(models, masks), track, best_s - half_window_s, best_s + half_window_s, variance
        )
        if where is None:
            return None
        estimates.append(where)
    g = len(estimates)
    mean = sum(estimates) / g
    return math.sqrt((g - 1) / g * sum((e - mean) ** 2 for e in estimates))


def _resting_on_one_frame(
    models: Sequence[ModelPath],
    track: TrackXYZ,
    best_s: float,
    sigma_s: float,
    half_window_s: float,
    variance: float,
) -> str | None:
    """The frame without which the minimum moves by more than :data:`AMBIGUITY_SIGMA` sigma or
    vanishes (the noise of one frame at the edge of a flat bottom, where a shift pushes it off the
    track's motion, can make a dip that the rest of the frames do not), or None."""
    for k, model in enumerate(models):
        for i in range(len(model)):
            masks = [np.zeros(len(m), dtype=bool) for m in models]
            masks[k][i] = True
            where = _best_within(
                _without(models, masks), track, best_s - half_window_s, best_s + half_window_s, variance
            )
            if where is None or abs(where - best_s) > AMBIGUITY_SIGMA * sigma_s + FINE_STEP_S:
                return model.names[i]
    return None


def estimate_offset(
    models: Sequence[ModelPath],
    track: TrackXYZ,
    *,
    prior_offset_s: float = 0.0,
    max_sigma_s: float = MAX_SIGMA_S,
) -> OffsetEstimate:
    """The offset minimising :func:`misfit` over every offset that keeps the frames inside the
    track, with its uncertainty, or None with the reason (module docstring)."""
    usable = [m for m in models if len(m) >= MIN_MODEL_FRAMES]
    frames = sum(len(m) for m in usable)
    base: dict[str, Any] = {"prior_offset_s": prior_offset_s, "frames_used": frames, "models": len(usable)}

    def not_compared(reason: str) -> OffsetEstimate:  # no misfit computed at all
        return OffsetEstimate(
            offset_s=None,
            sigma_s=None,
            best_offset_s=None,
            rms_m=None,
            rms_at_prior_m=None,
            search_s=None,
            reason=reason,
            **base,
        )

    if not usable:
        return not_compared(
            f"no reconstruction of {MIN_MODEL_FRAMES} frames or more to compare with the track"
        )
    span = search_range_s(usable, track)
    if span is None:
        return not_compared(
            "the registered frames span longer than the log's track: no offset puts them all on it"
        )
    low, high = span
    offsets, values, minima = _scan(usable, track, low, high)
    best = int(np.argmin(values))
    best_offset, s_min = float(offsets[best]), float(values[best])
    residual_count = 3 * frames
    dof = residual_count - 7 * len(usable) - 1
    rms = math.sqrt(s_min / frames)
    prior_inside = low <= prior_offset_s <= high
    rms_prior = math.sqrt(misfit(usable, track, prior_offset_s)[0] / frames) if prior_inside else None
    base.update(best_offset_s=best_offset, rms_m=rms, rms_at_prior_m=rms_prior, search_s=(low, high))
    if dof <= 0:
        return OffsetEstimate(
            offset_s=None, sigma_s=None, reason=f"{frames} frames leave no redundancy", **base
        )
    variance = max(s_min / dof, 1e-12)
    rho = _lag1_correlation(usable, track, best_offset)
    widening = math.sqrt((1.0 + rho) / (1.0 - rho))
    base["widening"] = widening
    # The one-sigma interval (a rise of one in chi-square) and the three-sigma one (nine) over
    # three: the same on a parabola; the wider of the two when the curve is not one: the first on
    # a box-shaped curve (a flat bottom whose noise barely tilts it), the second when the noise
    # makes a shallow dip at the edge of a flat bottom (a line whose end a shift pushes off the
    # track's motion).
    left = _crossing(offsets, values, best, s_min + 9.0 * variance, -1)
    right = _crossing(offsets, values, best, s_min + 9.0 * variance, +1)
    left1 = _crossing(offsets, values, best, s_min + variance, -1)
    right1 = _crossing(offsets, values, best, s_min + variance, +1)
    if left is None or right is None or left1 is None or right1 is None:
        return OffsetEstimate(
            offset_s=None,
            sigma_s=None,
            reason=(
                f"the misfit curve is flat: the frames' motion fits offsets to the end of those searched "
                f"({low:+.1f} to {high:+.1f} s) nearly as well as the best ({best_offset:+.2f} s); "
                f"straight lines flown one way at constant speed do not constrain it, lines in "
                f"opposite directions and turns do"
            ),
            **base,
        )
    sigma = max((right - left) / 6.0, (right1 - left1) / 2.0) * widening
    if sigma <= max_sigma_s:
        window = max(6.0 * sigma, 3.0 * max_sigma_s)
        jackknife = _jackknife_sigma(usable, track, best_offset, window, variance)
        base["jackknife_sigma_s"] = jackknife
        if jackknife is None:
            return OffsetEstimate(
                offset_s=None,
                sigma_s=None,
                reason=(
                    f"the misfit's minimum at {best_offset:+.2f} s rests on a few frames: without some "
                    f"of them the curve is flat (straight lines flown one way at constant speed do not "
                    f"constrain the offset, lines in opposite directions and turns do)"
                ),
                **base,
            )
        sigma = max(sigma, jackknife)
        lone = _resting_on_one_frame(usable, track, best_offset, sigma, window, variance)
        if lone is not None:
            return OffsetEstimate(
                offset_s=None,
                sigma_s=None,
                reason=(
                    f"the misfit's minimum at {best_offset:+.2f} s rests on one frame ({lone}): without "
                    f"it the best offset moves by more than {AMBIGUITY_SIGMA:g} sigma"
                ),
                **base,
            )
    if sigma > max_sigma_s:
        return OffsetEstimate(
            offset_s=None,
            sigma_s=sigma,
            reason=(
                f"the misfit curve is too flat: the best offset {best_offset:+.2f} s is uncertain by "
                f"+/-{sigma:.2f} s (one sigma), more than {max_sigma_s:g} s; straight lines flown one "
                f"way at constant speed do not constrain it, lines in opposite directions and turns do"
            ),
            **base,
        )
    # Other minima, separated from the best by a rise, nearly as good (a pattern that repeats:
    # one line pair of a lawnmower looks like the next once the similarity has moved it).
    level = s_min + (AMBIGUITY_SIGMA * widening) ** 2 * variance
    competing: list[float] = []
    for value, where in sorted(minima):
        if abs(where - best_offset) <= 2 * COARSE_STEP_S or value > level:
            continue
        between = (offsets > min(where, best_offset)) & (offsets < max(where, best_offset))
        separated = between.any() and float(values[between].max()) > value + widening**2 * variance
        if separated and all(abs(where - c) > 2 * COARSE_STEP_S for c in competing):
            competing.append(where)
    base["competing_s"] = tuple(competing)
    if competing:
        listed = ", ".join(f"{d:+.2f} s" for d in competing[:5])
        return OffsetEstimate(
            offset_s=None,
            sigma_s=sigma,
            reason=(
                f"the misfit curve is ambiguous: besides {best_offset:+.2f} s, offsets {listed} fit within "
                f"{AMBIGUITY_SIGMA:g} sigma"
            ),
            **base,
        )
    return OffsetEstimate(offset_s=best_offset, sigma_s=sigma, **base)


# --- the frames' reconstruction --------------------------------------------------------------------


@dataclass(frozen=True, kw_only=True)
class ReconstructionOptions:
    """How the frames are reconstructed: their size as matched (px, longer side), SIFT features
    per frame, neighbours in capture order and in space each frame is matched with (every pair up
    to ``exhaustive_max_frames`` frames: neighbours in space are found at the offset otherwise
    used, and when it is far off, the lines are left unconnected), and the file COLMAP's own log
    goes to (None: discarded)."""

    max_image_size_px: int = 640
    max_features: int = 2000
    time_neighbours: int = 3
    space_neighbours: int = 6
    exhaustive_max_frames: int = 60
    log_path: Path | None = None


def frame_pairs(
    capture_s: F64, positions_xy_m: F64 | None, *, time_neighbours: int, space_neighbours: int
) -> list[tuple[int, int]]:
    """Pairs of frame indices to match: each frame with the next ``time_neighbours`` in capture
    order, and (when approximate positions are known) with its ``space_neighbours`` nearest frames,
    which ties neighbouring lines together."""
    order = np.argsort(capture_s, kind="stable")
    pairs: set[tuple[int, int]] = set()
    for k in range(len(order)):
        for step in range(1, time_neighbours + 1):
            if k + step < len(order):
                i, j = int(order[k]), int(order[k + step])
                pairs.add((min(i, j), max(i, j)))
    if positions_xy_m is not None and len(positions_xy_m) > 1 and space_neighbours > 0:
        xy = np.asarray(positions_xy_m, float)
        d = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
        np.fill_diagonal(d, np.inf)
        for i in range(len(xy)):
            for j in np.argsort(d[i])[:space_neighbours]:
                if np.isfinite(d[i, j]):
                    pairs.add((min(i, int(j)), max(i, int(j))))
    return sorted(pairs)


def reconstruct_paths(
    image_dir: Path,
    names: Sequence[str],
    capture_s: F64,
    sizes_px: Sequence[tuple[int, int]],
    positions_xy_m: F64 | None,
    options: ReconstructionOptions,
) -> tuple[list[ModelPath], int]:
    """A quick reconstruction of the frames ``names`` (paths relative to ``image_dir``; one
    camera per frame size, its focal length COLMAP's default guess, refined by the mapper): each
    model's registered frames as a :class:`ModelPath`, largest first, and the number of frames
    registered. ``positions_xy_m``: approximate positions to choose the pairs by (None: capture
    order only)."""
    from processing.handoff import colmap_adapter as colmap
    from processing.handoff.errors import HandoffError

    by_size: dict[tuple[int, int], list[str]] = {}
    for name, size in zip(names, sizes_px, strict=True):
        by_size.setdefault(size, []).append(name)
    cameras = [
        colmap.CameraSpec(
            width_px=w, height_px=h, focal_px=1.2 * max(w, h), principal_xy_px=(w / 2.0, h / 2.0)
        )
        for w, h in by_size
    ]
    pairs = frame_pairs(
        capture_s,
        positions_xy_m,
        time_neighbours=options.time_neighbours,
        space_neighbours=options.space_neighbours,
    )
    with tempfile.TemporaryDirectory(prefix="sfap-offset-") as tmp:
        work = Path(tmp)
        log_path = options.log_path or work / "colmap.log"
        database = work / "frames.db"
        pairs_file = work / "pairs.txt"
        pairs_file.write_text("".join(f"{names[i]} {names[j]}\n" for i, j in pairs), encoding="utf-8")
        try:
            with colmap.stderr_to(log_path):
                colmap.write_database(database, image_dir, cameras, list(by_size.values()), [])
                colmap.extract_features(
                    database,
                    image_dir,
                    list(names),
                    max_image_size_px=options.max_image_size_px,
                    max_features=options.max_features,
                )
                if len(names) <= options.exhaustive_max_frames:
                    colmap.match_exhaustive(database)
                else:
                    colmap.match_pairs_file(database, pairs_file)
                reconstructions = colmap.incremental_mapping(
                    database, image_dir, work / "sparse", min_model_size=MIN_MODEL_FRAMES
                )
        except (HandoffError, RuntimeError, ValueError) as error:
            raise GeotagError(
                f"the frames could not be reconstructed to estimate the clock offset: {error}"
            ) from error
    time_of = dict(zip(names, capture_s.tolist(), strict=True))
    models: list[ModelPath] = []
    taken: set[str] = set()
    for model in reconstructions:  # largest first; a frame COLMAP registered twice counts once
        registered = sorted(set(model.registered) - taken, key=lambda n: time_of[n])
        taken.update(registered)
        if not registered:
            continue
        models.append(
            ModelPath(
                names=tuple(registered),
                capture_s=np.array([time_of[n] for n in registered], dtype=np.float64),
                centres=np.array([model.views[n].centre for n in registered], dtype=np.float64).reshape(
                    -1, 3
                ),
            )
        )
    registered_count = len({n for m in models for n in m.names})
    return models, registered_count


def offset_from_images(
    image_dir: Path,
    names: Sequence[str],
    capture_s: F64,
    sizes_px: Sequence[tuple[int, int]],
    positions: PositionTrack,
    *,
    prior_offset_s: float,
    options: ReconstructionOptions | None = None,
) -> OffsetEstimate:
    """Reconstruct the frames and estimate the camera clock offset from their motion against the
    log's track (module docstring). ``capture_s``: the frames' capture times (camera clock);
    ``prior_offset_s``: the offset geotag would use otherwise (it chooses the pairs to match by
    the frames' positions there, and the report compares the two)."""
    options = options or ReconstructionOptions()
    start = time.monotonic()
    track = TrackXYZ.from_positions(positions)
    utc = capture_s - prior_offset_s
    inside = (utc >= track.time_s[0]) & (utc <= track.time_s[-1])
    positions_xy = track.at(utc)[:, :2] if inside.mean() > 0.5 else None
    models, registered = reconstruct_paths(image_dir, names, capture_s, sizes_px, positions_xy, options)
    estimate = estimate_offset(models, track, prior_offset_s=prior_offset_s)
    seconds = time.monotonic() - start
    log.info(
        "clock offset from %d frames (%d registered): %s in %.0f s",
        len(names),
        registered,
        estimate.offset_s,
        seconds,
    )
    return replace(estimate, frames_registered=registered, frames_given=len(names), seconds=seconds)


def estimate_words(estimate: OffsetEstimate, speed_m_s: float | None) -> str:
    """One line on what the images said: the offset and its uncertainty in seconds and metres, or
    that they do not pin it down, why, and what that costs."""
    per_s = f" (about {speed_m_s:.1f} m along the track per second)" if speed_m_s else ""
    used = (
        f"{estimate.frames_used} of {estimate.frames_given} frames in {estimate.models} model(s)"
        if estimate.frames_given
        else f"{estimate.frames_used} frames in {estimate.models} model(s)"
    )
    if estimate.offset_s is not None and estimate.sigma_s is not None:
        metres = f", +/-{estimate.sigma_s * speed_m_s:.1f} m" if speed_m_s else ""
        prior = (
            f"; at the offset otherwise used ({estimate.prior_offset_s:+.2f} s) it is "
            f"{estimate.rms_at_prior_m:.2f} m"
            if estimate.rms_at_prior_m is not None
            else ""
        )
        return (
            f"camera clock offset from the images: {estimate.offset_s:+.2f} +/- {estimate.sigma_s:.2f} s "
            f"(one sigma{metres}; {used}; their camera centres fit the track to {estimate.rms_m:.2f} m "
            f"RMS{prior})"
        )
    return (
        f"the images do not pin the camera clock offset down ({used}): {estimate.reason}; the offset "
        f"stays {estimate.prior_offset_s:+.2f} s, and every second it is wrong moves each frame along "
        f"the track{per_s}"
    )


#: Sources whose offset the images' estimate is compared with (a disagreement is said).
_PRIOR_WORDS = {
    "sync": "the sync points",
    "exif_gps": "the frames' own GPS time stamps",
    "assumed_zero": "assumed: no camera events, no --offset-s, no sync point",
}


def clock_from_images(
    clock: Clock,
    image_dir: Path,
    timed: Sequence[Frame],
    times: F64,
    log_: FlightLog,
    options: ReconstructionOptions,
    warnings: list[str],
) -> tuple[Clock, OffsetEstimate | None]:
    """Geotag's step for ``--offset-from-images`` (no camera events, no given offset): the
    estimate replaces ``clock`` (whose offset came from sync points, the frames' GPS time, or was
    assumed 0) when the images pin it down; either way one line in ``warnings`` says what the
    images said, and what a wrong offset costs when they said nothing."""
    from .geotag_offset import track_speeds_m_s
    from .geotag_placement import Clock
    from .geotag_results import OffsetSource

    if log_.positions is None or len(log_.positions) < 2:
        warnings.append("--offset-from-images: the log has no position track to compare the frames with")
        return clock, None
    keep = [
        k
        for k, fr in enumerate(timed)
        if fr.tags is not None and fr.tags.width_px and fr.tags.height_px and math.isfinite(times[k])
    ]
    if len(keep) < MIN_MODEL_FRAMES:
        warnings.append(
            f"--offset-from-images: {len(keep)} frame(s) with a capture time and a size, fewer than "
            f"{MIN_MODEL_FRAMES}: no offset estimated from the images"
        )
        return clock, None
    names = [os.path.relpath(timed[k].path, image_dir) for k in keep]
    sizes: list[tuple[int, int]] = []
    for k in keep:
        tags = timed[k].tags
        assert tags is not None and tags.width_px and tags.height_px
        sizes.append((int(tags.width_px), int(tags.height_px)))
    estimate = offset_from_images(
        image_dir, names, times[keep], sizes, log_.positions, prior_offset_s=clock.offset_s, options=options
    )
    moving = [s for s in track_speeds_m_s(log_.positions) if s > 0.5]
    speed = float(np.median(moving)) if moving else None
    prior_words = _PRIOR_WORDS.get(str(clock.source), str(clock.source))
    if estimate.offset_s is None or estimate.sigma_s is None:
        warnings.append(f"{estimate_words(estimate, speed)} ({prior_words})")
        return clock, estimate
    warnings.append(estimate_words(estimate, speed))
    if clock.source in (OffsetSource.SYNC, OffsetSource.EXIF_GPS):
        allowed = AMBIGUITY_SIGMA * estimate.sigma_s + 1.0  # a sync time or GPS stamp is good to ~1 s
        if abs(estimate.offset_s - clock.offset_s) > allowed:
            warnings.append(
                f"the images' camera clock offset {estimate.offset_s:+.2f} s disagrees with the "
                f"{clock.offset_s:+.2f} s from {prior_words} by more than {allowed:.1f} s: the images' "
                f"is used; check the sync points or the camera's GPS time"
            )
    return Clock(offset_s=estimate.offset_s, source=OffsetSource.IMAGES), estimate
