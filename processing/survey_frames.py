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
) -> SurveySelection:
    """Apply the module's rules. ``height_agl_m``: (N,) camera heights above the ground;
    ``xy_m``: (N, 2) camera positions in metres (None: no transit rule); ``frame_length_m``:
    a frame's longer ground side at the median height (the transit rule's least distance);
    ``alt_m``: (N,) camera altitudes in any one reference (None: the heights). The low-frame
    rule is on the altitude: a frame more than (1 - LOW_RATIO) x the median height below the
    block's median altitude is climbing or descending, while a frame low over a hill at the
    survey altitude is a survey frame (its finer GSD and lower overlap are real)."""
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
    for k in range(n):
        if not airborne[k]:
            keep[k] = False
            reasons.append((k, f"on the ground: {h[k]:.1f} m above it (take-off, landing or the pad)"))
        elif median_alt - alt[k] > (1.0 - LOW_RATIO) * median and not on_a_level[k]:
            keep[k] = False
            reasons.append(
                (
                    k,
                    f"below the survey height: {h[k]:.1f} m above the ground, {median_alt - alt[k]:.1f} m "
                    f"under the block's median altitude (median height {median:.1f} m): climbing, "
                    "descending or in transit",
                )
            )
    by_height = int((~keep).sum())
    suspect = n > 0 and (by_height > n * SUSPECT_SHARE or bool((h < -ON_GROUND_M).any()))
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
