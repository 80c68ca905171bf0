"""Which frames of a card are survey frames: the others (on the ground, climbing, landing, in
transit) are left out of coverage, GSD and scale statistics and listed with the reason.

A card holds what the camera shot from power-on to power-off: frames on the pad before take-off,
on the climb, on the way to the area and back. Counted as survey frames they stretch the block,
open false gaps, and put a GSD of 0.03 cm at the bottom of the report's range. The rules, on the
heights above the ground chosen for the check (:mod:`processing.ground_choice`) and the positions:

- at most :data:`ON_GROUND_M` above the ground: on the ground (take-off, landing, the pad);
- more than (1 - :data:`LOW_RATIO`) x the median height below the median altitude of the
  airborne frames: climbing, descending or in transit below the survey height (on flat ground:
  lower than :data:`LOW_RATIO` x the median height; a frame low over a hill at the survey
  altitude stays a survey frame, and so does a frame of a lower pass flown at a level of its
  own, :data:`LEVEL_BAND_M`);
- an altitude more than :data:`CRUISE_SHARE` x the median height (and at least
  :data:`ON_GROUND_M`) off the block's cruise altitude (the median altitude of the airborne
  frames), and a height above ground as far off the median height, on no level of its own:
  "climbing" or "descending" (by the altitude's change between the frames before and after it in
  time), on the climb, the descent or between lines. Over a hill at the cruise altitude the
  altitude stays; on a terrain-following block the height stays: both stay survey frames. With
  drifting GPS altitudes the caller gives the altitudes detrended (:func:`altitude_trend`);
- (images only, not a plan's stations) further from the nearest other frame than
  :data:`ISOLATED_RATIO` x the median nearest-frame distance and two frame lengths: in transit.

A plan's stations are all survey frames: only the ground check applies to them.

When more than a third of the frames would be left out by height, or a frame is more than
:data:`ON_GROUND_M` under the ground, the ground is wrong, not the frames (an elevation in the
wrong reference, ellipsoidal heights where mean sea level is expected, a DEM off by tens of
metres): the check refuses and says so.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray

#: A frame no higher than this above the ground is on it (a GPS altitude is good to a few metres).
ON_GROUND_M = 3.0
#: A frame lower than this share of the block's median height above ground is not a survey frame.
LOW_RATIO = 0.5
#: A low frame that shares its altitude (or its height above ground) within this band with at
#: least LEVEL_MIN_FRAMES others (and LEVEL_MIN_SHARE of the frames) is on a survey level: a
#: second, lower pass of a multi-scale block, not a climb (a climb changes altitude every frame).
LEVEL_BAND_M = 2.0
LEVEL_BAND_RATIO = 0.02
LEVEL_MIN_FRAMES = 5
LEVEL_MIN_SHARE = 0.05
#: An airborne frame whose altitude departs from the cruise altitude (and whose height departs
#: from the median height) by more than this share of the median height is climbing or descending:
#: its GSD differs by as much from the block's, beyond the 10 % scale difference the stereo step
#: flags between neighbours (processing.stereo.SCALE_TOLERANCE), and no survey line is flown there.
CRUISE_SHARE = 0.1
#: More than this share of the frames left out by height, or any frame more than ON_GROUND_M under
#: the ground, means the ground is wrong (a card holds a few take-off and landing frames, not a
#: third of its frames, and no camera flies under the ground).
SUSPECT_SHARE = 1.0 / 3.0
#: A frame further than this many median nearest-frame distances from any other is in transit.
ISOLATED_RATIO = 5.0


def _nearest_other_m(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distance from each point to the nearest other point (STRtree; inf when alone)."""
    geoms = shapely.points(points)
    tree = shapely.STRtree(geoms)
    # Equal geometries are skipped (exclusive): frames shot from one spot see the next spot.
    (src, _dst), dist = tree.query_nearest(geoms, exclusive=True, return_distance=True, all_matches=False)
    out = np.full(len(points), np.inf)
    out[src] = dist
    return out


def _within(values: NDArray[np.float64], band: float) -> NDArray[np.intp]:
    """How many other values lie within +-``band`` of each value (sorted search, n log n)."""
    ordered = np.sort(values)
    upper = np.searchsorted(ordered, values + band, side="right")
    lower = np.searchsorted(ordered, values - band, side="left")
    return np.asarray(upper - lower - 1, dtype=np.intp)


@dataclass(frozen=True, kw_only=True)
class SurveySelection:
    """``keep``: the survey frames (mask over the frames given); ``left_out``: (row, reason)."""

    keep: NDArray[np.bool_]
    left_out: tuple[tuple[int, str], ...]
    ground_suspect: bool
    median_height_m: float


def select_survey_frames(
    height_agl_m: NDArray[np.float64],
    xy_m: NDArray[np.float64] | None = None,
    frame_length_m: float | None = None,
    alt_m: NDArray[np.float64] | None = None,
    time_s: NDArray[np.float64] | None = None,
) -> SurveySelection:
    """Apply the module's rules. ``height_agl_m``: (N,) camera heights above the ground;
    ``xy_m``: (N, 2) camera positions in metres (None: no transit rule); ``frame_length_m``:
    a frame's longer ground side at the median height (the transit rule's least distance);
    ``alt_m``: (N,) camera altitudes in any one reference (None: the heights). The low-frame
    rule is on the altitude: a frame more than (1 - LOW_RATIO) x the median height below the
    block's median altitude is climbing or descending, while a frame low over a hill at the
    survey altitude is a survey frame (its finer GSD and lower overlap are real). ``time_s``: (N,)
    capture times (None: the frames' order), for telling a climb from a descent."""
    h = np.asarray(height_agl_m, dtype=np.float64)
    alt = h if alt_m is None else np.asarray(alt_m, dtype=np.float64)
    n = h.size
    keep = np.ones(n, dtype=bool)
    reasons: list[tuple[int, str]] = []
    airborne = h > ON_GROUND_M
    median = float(np.median(h[airborne])) if airborne.any() else float(np.median(h)) if n else 0.0
    median_alt = float(np.median(alt[airborne])) if airborne.any() else float(np.median(alt)) if n else 0.0
    band = max(LEVEL_BAND_M, LEVEL_BAND_RATIO * median)
    peers = max(LEVEL_MIN_FRAMES, math.ceil(LEVEL_MIN_SHARE * n))
    on_a_level = (_within(alt, band) >= peers) | (_within(h, band) >= peers)
    # In time order: a frame whose altitude is higher after it than before it is climbing.
    when = np.arange(n, dtype=np.float64) if time_s is None else np.asarray(time_s, dtype=np.float64)
    order = np.argsort(when, kind="stable")
    rank = np.empty(n, dtype=np.intp)
    rank[order] = np.arange(n)
    timed_alt = alt[order]

    def way(j: int) -> str:
        place = int(rank[j])
        rising = timed_alt[min(place + 1, n - 1)] - timed_alt[max(place - 1, 0)] > 0
        return "climbing" if rising else "descending"

    for k in range(n):
        if not airborne[k]:
            keep[k] = False
            reasons.append((k, f"on the ground: {h[k]:.1f} m above it (take-off, landing or the pad)"))
        elif median_alt - alt[k] > (1.0 - LOW_RATIO) * median and not on_a_level[k]:
            keep[k] = False
            reasons.append(
                (
                    k,
                    f"{way(k)}: {h[k]:.1f} m above the ground, {median_alt - alt[k]:.1f} m under the "
                    f"block's median altitude (median height {median:.1f} m): below the survey height "
                    "(or in transit)",
                )
            )
    by_height = int((~keep).sum())
    suspect = n > 0 and (by_height > n * SUSPECT_SHARE or bool((h < -ON_GROUND_M).any()))
    # Climbing and descending: off the cruise altitude and off the median height (a wrong ground
    # shifts every height alike, so these do not make the ground suspect).
    off = max(CRUISE_SHARE * median, ON_GROUND_M)
    departs = keep & (np.abs(alt - median_alt) > off) & (np.abs(h - median) > off) & ~on_a_level
    for j in np.flatnonzero(departs).tolist():
        keep[j] = False
        reasons.append(
            (
                j,
                f"{way(j)}: {h[j]:.1f} m above the ground, {alt[j] - median_alt:+.1f} m off the block's "
                f"cruise altitude (median height {median:.1f} m)",
            )
        )
    if xy_m is not None and keep.sum() >= 3:
        rows = np.flatnonzero(keep)
        pts = np.asarray(xy_m, dtype=np.float64)[rows]
        nearest = _nearest_other_m(pts)
        limit = ISOLATED_RATIO * float(np.median(nearest))
        if frame_length_m is not None:
            limit = max(limit, 2.0 * frame_length_m)
        for r, dist in zip(rows, nearest, strict=True):
            if dist > limit:
                keep[r] = False
                reasons.append((int(r), f"in transit: {dist:.0f} m from the nearest other frame"))
    reasons.sort()
    return SurveySelection(keep=keep, left_out=tuple(reasons), ground_suspect=suspect, median_height_m=median)


#: A camera altitude that trends by more than this over a flight is reported, metres.
ALTITUDE_DRIFT_M = 10.0


@dataclass(frozen=True, kw_only=True)
class AltitudeTrend:
    """The least-squares line of altitude on time: ``slope_m_per_s`` over the ``span_s`` of the
    frames from ``start_s`` (the first frame's time); ``drift_m``: its change over the span. The
    ground choice carries the trend it removed to the check (``GroundChoice.detrended``,
    ``CheckInputs.detrended``): the typed sign that the heights drift."""

    slope_m_per_s: float
    start_s: float
    span_s: float

    @property
    def drift_m(self) -> float:
        return self.slope_m_per_s * self.span_s

    def detrended(self, alt_m: NDArray[np.float64], time_s: NDArray[np.float64]) -> NDArray[np.float64]:
        """The altitudes with the line removed about mid-flight: what they would be if the block
        was flown at one height, the GPS altitude of mid-flight (a drift moves the early frames one
        way and the late ones the other; mid-flight, the median height stays what the tags say)."""
        mid_s = self.start_s + self.span_s / 2.0
        return np.asarray(alt_m, dtype=np.float64) - self.slope_m_per_s * (np.asarray(time_s) - mid_s)


def altitude_trend(alt_m: NDArray[np.float64], time_s: NDArray[np.float64] | None) -> AltitudeTrend | None:
    """The trend of altitude on time over a card's frames, robust to its take-off, climb and
    descent: first the median of the slopes between each frame of the first half of the flight (in
    time) and its partner half a card later (a take-off or a climb pairs with cruise frames, a
    minority of the slopes); then a least-squares line through the frames within 3 robust
    deviations (at least :data:`ON_GROUND_M`) of that line. None without times or with fewer
    than 3 frames."""
    if time_s is None or alt_m.size < 3:
        return None
    t = np.asarray(time_s, dtype=np.float64)
    a = np.asarray(alt_m, dtype=np.float64)
    good = np.isfinite(t) & np.isfinite(a)
    if good.sum() < 3:
        return None
    order = np.argsort(t[good], kind="stable")
    t, a = t[good][order], a[good][order]
    start = float(t[0])
    span_s = float(t[-1] - start)
    if not span_s > 0:
        return None
    half = t.size // 2
    dt = t[half : 2 * half] - t[:half]
    apart = dt > 0
    if not apart.any():
        return None
    slope = float(np.median((a[half : 2 * half] - a[:half])[apart] / dt[apart]))
    resid = a - slope * (t - start)
    centre = float(np.median(resid))
    spread = max(3.0 * 1.4826 * float(np.median(np.abs(resid - centre))), ON_GROUND_M)
    near = np.abs(resid - centre) <= spread
    if near.sum() >= 3 and float(np.ptp(t[near])) > 0:
        slope = float(np.polyfit(t[near] - start, a[near], 1)[0])
    return AltitudeTrend(slope_m_per_s=float(slope), start_s=start, span_s=span_s)


def altitude_drift_warning(
    alt_m: NDArray[np.float64], time_s: NDArray[np.float64] | None, height_agl_m: float, reference: str
) -> str | None:
    """A warning when the camera altitudes of the survey frames trend by more than
    :data:`ALTITUDE_DRIFT_M` over the flight (least-squares line of altitude on time): a survey
    is flown at one height, and GPS altitude (unlike barometric, relative altitude) can drift by
    tens of metres. ``height_agl_m``: the block's median height, to say what it does to GSD."""
    if time_s is None or alt_m.size < 3 or reference not in ("amsl", "ellipsoid"):
        return None
    t = np.asarray(time_s, dtype=np.float64)
    span_s = float(t.max() - t.min())
    if not span_s > 0:
        return None
    slope, _ = np.polyfit(t - t.min(), np.asarray(alt_m, dtype=np.float64), 1)
    drift = float(slope * span_s)
    if abs(drift) <= ALTITUDE_DRIFT_M:
        return None
    share = 100.0 * abs(drift) / 2.0 / height_agl_m if height_agl_m > 0 else float("nan")
    return (
        f"the GPS altitudes trend by {drift:+.1f} m over the {span_s / 60:.0f} min of survey frames "
        f"({slope * 600:+.1f} m per 10 min): if the block was flown at one height (most are), the GPS "
        f"altitude drifted, and heights above ground and GSD carry about +-{abs(drift) / 2:.0f} m "
        f"(+-{share:.0f} %); a relative (barometric) altitude or a surveyed take-off elevation settles it"
    )


def left_out_summary(left_out: Sequence[tuple[str, str]], shown: int = 4) -> str:
    """The frames left out, in one line of a few hundred characters however many there are: each
    kind of reason (its words before the first colon or parenthesis: "climbing", "on the ground",
    "no position") with its count, up to three names and one reason in full, the most frequent
    kinds first; the full list is in report.json."""
    groups: dict[str, list[tuple[str, str]]] = {}
    for name, why in left_out:
        kind = why.split(":", 1)[0].split(" (", 1)[0].strip() or why
        groups.setdefault(kind, []).append((name, why))
    ordered = sorted(groups.items(), key=lambda item: -len(item[1]))
    parts = []
    for kind, items in ordered[:shown]:
        names = ", ".join(name for name, _ in items[:3]) + (" ..." if len(items) > 3 else "")
        example = items[0][1]
        example = example if len(example) <= 120 else example[:117] + "..."
        parts.append(f"{len(items)} {kind} ({names}; e.g. {example})")
    if len(ordered) > shown:
        parts.append(f"{sum(len(items) for _, items in ordered[shown:])} for other reasons")
    return "; ".join(parts) + (" (all in report.json)" if len(left_out) > 3 else "")
