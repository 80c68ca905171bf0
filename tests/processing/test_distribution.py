"""Distribution against the standard library's statistics (an independent implementation of
the same linear-interpolation percentiles), on random sets with NaN and infinities mixed in."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from processing.distribution import Distribution

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)
not_finite = st.sampled_from([math.nan, math.inf, -math.inf])


@given(st.lists(finite, min_size=1, max_size=60), st.lists(not_finite, max_size=5), st.randoms())
def test_the_figures_are_the_finite_values_statistics(values: list[float], bad: list[float], rnd) -> None:  # type: ignore[no-untyped-def]
    mixed = values + bad
    rnd.shuffle(mixed)
    d = Distribution.of(np.array(mixed))
    assert d is not None
    deciles = statistics.quantiles(values, n=10, method="inclusive") if len(values) > 1 else [values[0]] * 9
    tol = 1e-9 * max(1.0, max(abs(v) for v in values))
    assert d.count == len(values)
    assert d.min == min(values) and d.max == max(values)
    assert d.median == pytest.approx(statistics.median(values), abs=tol)
    assert d.p10 == pytest.approx(deciles[0], abs=tol)
    assert d.p90 == pytest.approx(deciles[8], abs=tol)
    assert list(d.as_dict()) == ["count", "min", "p10", "median", "p90", "max"]


def test_no_finite_value_is_no_distribution() -> None:
    assert Distribution.of([]) is None
    assert Distribution.of([math.nan, math.inf]) is None
    one = Distribution.of([2.5])
    assert one is not None and (one.min, one.p10, one.median, one.p90, one.max) == (2.5,) * 5
