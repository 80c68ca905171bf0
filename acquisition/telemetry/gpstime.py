"""GPS time <-> UTC, and the mapping of an autopilot's boot clock onto UTC.

GPS time started at 1980-01-06T00:00:00 UTC and has no leap seconds, so it runs ahead of UTC
by the leap seconds inserted since then: 18 s since 2017-01-01 (Mission Planner hard-codes
17, a known bug; REFERENCES.md section 3). All UTC values here are POSIX seconds (float64),
which have no representation for an inserted leap second (23:59:60): the GPS second that
falls on it maps onto the first second of the next UTC day (see :func:`gps_to_utc_s`).

Boot clocks: autopilots stamp most messages with the time since boot (``time_boot_ms``,
``TimeUS``, ULog ``timestamp``). :func:`fit_boot_clock` fits UTC against boot time from the
pairs a log carries (SYSTEM_TIME, the GPS messages), robustly, with a rate term for the
crystal drift of the flight controller.

:func:`time_order` sorts the rows of a table by time and drops exact duplicates; every
reader uses it so that the tables of :mod:`acquisition.telemetry.model` are in time order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.stats import median

from ..errors import TelemetryError

#: POSIX time of the GPS epoch, 1980-01-06T00:00:00 UTC.
GPS_EPOCH_POSIX_S = 315_964_800
SECONDS_PER_WEEK = 604_800

# (POSIX second at which the offset starts, GPS - UTC in seconds from then on). The leap
# seconds of IERS Bulletin C, inserted at the end of 30 June or 31 December; GPS - UTC was
# 0 at the GPS epoch (TAI - UTC was then 19 s). None has been inserted since 2017; add a row
# when Bulletin C announces one (GPS receivers broadcast the offset too: u-blox NAV-TIMELS).
_LEAP_SECONDS: tuple[tuple[int, int], ...] = (
    (362_793_600, 1),  # 1981-07-01
    (394_329_600, 2),  # 1982-07-01
    (425_865_600, 3),  # 1983-07-01
    (489_024_000, 4),  # 1985-07-01
    (567_993_600, 5),  # 1988-01-01
    (631_152_000, 6),  # 1990-01-01
    (662_688_000, 7),  # 1991-01-01
    (709_948_800, 8),  # 1992-07-01
    (741_484_800, 9),  # 1993-07-01
    (773_020_800, 10),  # 1994-07-01
    (820_454_400, 11),  # 1996-01-01
    (867_715_200, 12),  # 1997-07-01
    (915_148_800, 13),  # 1999-01-01
    (1_136_073_600, 14),  # 2006-01-01
    (1_230_768_000, 15),  # 2009-01-01
    (1_341_100_800, 16),  # 2012-07-01
    (1_435_708_800, 17),  # 2015-07-01
    (1_483_228_800, 18),  # 2017-01-01
)

_UTC_CHANGE_S = np.array([0] + [utc for utc, _ in _LEAP_SECONDS], dtype=np.float64)
_OFFSET_S = np.array([0] + [off for _, off in _LEAP_SECONDS], dtype=np.float64)
# The same instants on the GPS time scale (seconds since the GPS epoch).
_GPS_CHANGE_S = _UTC_CHANGE_S - GPS_EPOCH_POSIX_S + _OFFSET_S
_GPS_CHANGE_S[0] = -np.inf
_UTC_CHANGE_S[0] = -np.inf

F64 = NDArray[np.float64]


def gps_minus_utc_s(utc_s: ArrayLike) -> F64:
    """GPS - UTC in seconds (0 to 18) in force at the UTC POSIX time(s) ``utc_s``."""
    utc = np.asarray(utc_s, dtype=np.float64)
    return _OFFSET_S[np.searchsorted(_UTC_CHANGE_S, utc, side="right") - 1]


def gps_to_utc_s(gps_s: ArrayLike) -> F64:
    """UTC POSIX seconds of ``gps_s`` seconds since the GPS epoch (float64, any shape).

    The inserted leap second itself has no POSIX representation: GPS instants inside it map
    onto the first second of the next UTC day, which therefore has two GPS preimages.
    """
    gps = np.asarray(gps_s, dtype=np.float64)
    offset = _OFFSET_S[np.searchsorted(_GPS_CHANGE_S, gps, side="right") - 1]
    return gps + GPS_EPOCH_POSIX_S - offset


def utc_to_gps_s(utc_s: ArrayLike) -> F64:
    """Seconds since the GPS epoch of the UTC POSIX time(s) ``utc_s`` (inverse of
    :func:`gps_to_utc_s` everywhere but inside an inserted leap second)."""
    utc = np.asarray(utc_s, dtype=np.float64)
    return utc - GPS_EPOCH_POSIX_S + gps_minus_utc_s(utc)


def gps_week_tow_to_utc_s(week: ArrayLike, tow_s: ArrayLike) -> F64:
    """UTC POSIX seconds of GPS week number (full, not modulo 1024) and time of week (s)."""
    w = np.asarray(week, dtype=np.float64)
    return gps_to_utc_s(w * SECONDS_PER_WEEK + np.asarray(tow_s, dtype=np.float64))


def gps_week_ms_to_utc_s(week: ArrayLike, tow_ms: ArrayLike) -> F64:
    """UTC POSIX seconds of GPS week number and time of week in milliseconds (GWk, GMS)."""
    return gps_week_tow_to_utc_s(week, np.asarray(tow_ms, dtype=np.float64) / 1000.0)


def gps_usec_to_utc_s(gps_epoch_us: ArrayLike) -> F64:
    """UTC POSIX seconds of microseconds since the GPS epoch."""
    us = np.asarray(gps_epoch_us)
    # Split whole seconds from the fraction in integers so that large values keep their
    # microseconds (float64 has 16 digits; GPS-epoch microseconds have 16).
    if np.issubdtype(us.dtype, np.integer):
        whole = (us // 1_000_000).astype(np.float64)
        frac = (us % 1_000_000).astype(np.float64) / 1e6
        return gps_to_utc_s(whole) + frac
    return gps_to_utc_s(us.astype(np.float64) / 1e6)


def utc_to_gps_week_tow_s(utc_s: ArrayLike) -> tuple[NDArray[np.int64], F64]:
    """(GPS week, time of week in seconds) of the UTC POSIX time(s) ``utc_s``."""
    gps = utc_to_gps_s(utc_s)
    week = np.floor(gps / SECONDS_PER_WEEK)
    return week.astype(np.int64), gps - week * SECONDS_PER_WEEK


@dataclass(frozen=True, kw_only=True)
class BootClock:
    """``utc_s = utc_at_ref_s + rate * (boot_s - ref_boot_s)``: a flight controller's boot clock
    mapped onto UTC.

    - ``ref_boot_s``: a boot time inside the fitted span (seconds since boot).
    - ``utc_at_ref_s``: UTC POSIX seconds at ``ref_boot_s``.
    - ``rate``: UTC seconds per boot-clock second (1 +- crystal drift, typically 1e-5).
    - ``residual_rms_s``: RMS of the inliers' residuals; ``n_used`` of ``n_pairs`` pairs kept.
    - ``first_boot_s``, ``last_boot_s``: the span of the pairs used.
    """

    ref_boot_s: float
    utc_at_ref_s: float
    rate: float
    residual_rms_s: float
    n_used: int
    n_pairs: int
    first_boot_s: float
    last_boot_s: float

    def __post_init__(self) -> None:
        if not 0.99 < self.rate < 1.01:
            raise TelemetryError(f"boot clock rate {self.rate} is not within 1 % of 1")
        if not 0 < self.n_used <= self.n_pairs:
            raise TelemetryError(f"boot clock fit used {self.n_used} of {self.n_pairs} pairs")

    def utc_s(self, boot_s: ArrayLike) -> F64:
        """UTC POSIX seconds of boot time(s) ``boot_s`` (seconds since boot)."""
        b = np.asarray(boot_s, dtype=np.float64)
        return self.utc_at_ref_s + self.rate * (b - self.ref_boot_s)

    def boot_s(self, utc_s: ArrayLike) -> F64:
        """Inverse of :meth:`utc_s`."""
        u = np.asarray(utc_s, dtype=np.float64)
        return self.ref_boot_s + (u - self.utc_at_ref_s) / self.rate


def fit_boot_clock(boot_s: ArrayLike, utc_s: ArrayLike, *, min_span_for_rate_s: float = 10.0) -> BootClock:
    """Fit UTC against boot time, robust to outliers (a clock jump when the autopilot's RTC is
    first set, a stale pair).

    ``boot_s``: seconds since boot; ``utc_s``: UTC POSIX seconds of the same instants. The
    offset is the median of ``utc - boot``; pairs farther than max(5 MAD, 5 ms) from it are
    outliers. A rate (drift) term is fitted by least squares on the inliers only when they
    span ``min_span_for_rate_s`` or more and it stays within 1e-3 of 1 (a real crystal is
    within 1e-4); otherwise the rate is 1.

    Raises :class:`TelemetryError` when there is no pair.
    """
    b = np.asarray(boot_s, dtype=np.float64).ravel()
    u = np.asarray(utc_s, dtype=np.float64).ravel()
    if b.shape != u.shape:
        raise TelemetryError(f"boot and UTC times differ in length: {b.shape} vs {u.shape}")
    ok = np.isfinite(b) & np.isfinite(u)
    b, u = b[ok], u[ok]
    n = int(b.shape[0])
    if n == 0:
        raise TelemetryError("no (boot time, UTC) pair to map the boot clock onto UTC")
    ref = float(median(b))
    # Work on offsets relative to a reference so that float64 keeps the microseconds.
    utc0 = float(np.floor(median(u)))
    d = (u - utc0) - (b - ref)
    med = float(median(d))
    mad = float(median(np.abs(d - med)))
    keep = np.abs(d - med) <= max(5.0 * 1.4826 * mad, 0.005)
    bk, dk = b[keep] - ref, d[keep]
    rate = 1.0
    intercept = float(np.mean(dk))
    if bk.size >= 3 and float(np.ptp(bk)) >= min_span_for_rate_s:
        # d = intercept + (rate - 1) * (b - ref)
        slope, icpt = np.polyfit(bk, dk, 1)
        if abs(slope) <= 1e-3:
            rate = 1.0 + float(slope)
            intercept = float(icpt)
    resid = dk - (intercept + (rate - 1.0) * bk)
    return BootClock(
        ref_boot_s=ref,
        utc_at_ref_s=utc0 + intercept,
        rate=rate,
        residual_rms_s=float(np.sqrt(np.mean(resid**2))),
        n_used=int(keep.sum()),
        n_pairs=n,
        first_boot_s=float(b[keep].min()),
        last_boot_s=float(b[keep].max()),
    )


def time_order(time_s: ArrayLike, *keys: ArrayLike) -> NDArray[np.intp]:
    """Indices that put rows in time order, dropping rows with a non-finite time and exact
    duplicates (same time and same value in every one of ``keys``, e.g. the image index of a
    message received twice). The first of duplicated rows is kept."""
    t = np.asarray(time_s, dtype=np.float64)
    idx = np.flatnonzero(np.isfinite(t))
    if idx.size == 0:
        return idx
    cols = [np.asarray(k)[idx] for k in reversed(keys)] + [t[idx]]
    # lexsort sorts by the last key first: time, then the keys; stable, so the first of a
    # group of duplicates stays first.
    order = idx[np.lexsort(cols)]
    if order.size < 2:
        return order
    same = t[order][1:] == t[order][:-1]
    for k in keys:
        ka = np.asarray(k)
        same &= ka[order][1:] == ka[order][:-1]
    return np.concatenate([order[:1], order[1:][~same]])
