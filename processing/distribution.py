"""How a set of measured values is summarized in every report: :class:`Distribution`."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True, kw_only=True)
class Distribution:
    """Count, minimum, 10th / 50th / 90th percentiles and maximum of the finite values of a set,
    in the unit the owning field names (``forward_overlap_pct``: percent)."""

    count: int
    min: float
    p10: float
    median: float
    p90: float
    max: float

    @classmethod
    def of(cls, values: NDArray[np.float64] | Sequence[float]) -> Distribution | None:
        """None when no value is finite (nothing to summarize); NaN and infinities are left out."""
        v = np.asarray(values, dtype=np.float64)
        v = v[np.isfinite(v)]
        if v.size == 0:
            return None
        p10, median, p90 = np.percentile(v, [10, 50, 90])
        return cls(
            count=int(v.size),
            min=float(v.min()),
            p10=float(p10),
            median=float(median),
            p90=float(p90),
            max=float(v.max()),
        )

    def as_dict(self) -> dict[str, float | int]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}
