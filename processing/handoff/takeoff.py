"""The ground under a block from its own take-off frames, when nobody gave it.

A card often starts with frames shot on the pad: the camera powered on, the drone not yet in the
air. Their GPS altitude (above mean sea level, as the block's) is the ground at the take-off
point to within the GPS's vertical error, which is the same error every frame's altitude has.
They are the frames at the start of the card, in capture order, that stay within
:data:`PAD_RADIUS_M` of the first one horizontally and :data:`PAD_BAND_M` of its altitude, while
the block's median altitude is at least :data:`MIN_SURVEY_HEIGHT_M` above them (a block flown
that low has no take-off frames to tell from its survey frames).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..survey_frames import ON_GROUND_M

F64 = NDArray[np.float64]

#: The pad frames lie within this horizontal distance of the first frame, metres.
PAD_RADIUS_M = 15.0
#: ... and within this band of its altitude, metres (a GPS altitude is good to a few metres).
PAD_BAND_M = ON_GROUND_M
#: The survey is flown at least this far above the pad, metres.
MIN_SURVEY_HEIGHT_M = 20.0


@dataclass(frozen=True, kw_only=True)
class TakeoffGround:
    elevation_m: float
    names: tuple[str, ...]

    @property
    def description(self) -> str:
        shown = ", ".join(self.names[:5]) + (" ..." if len(self.names) > 5 else "")
        return (
            f"{self.elevation_m:.1f} m: the median GPS altitude of the {len(self.names)} frame(s) taken on "
            f"the ground before take-off ({shown})"
        )


def takeoff_ground(names: Sequence[str], xy_m: F64, alt_m: F64) -> TakeoffGround | None:
    """The take-off frames among positioned frames given in capture order (``xy_m`` (N, 2) metres
    in any local frame, ``alt_m`` (N,) in one reference) and the ground they show, or None
    (module docstring)."""
    n = len(names)
    if n < 3:
        return None
    xy = np.asarray(xy_m, dtype=np.float64)
    alt = np.asarray(alt_m, dtype=np.float64)
    dist = np.hypot(xy[:, 0] - xy[0, 0], xy[:, 1] - xy[0, 1])
    on_pad = (dist <= PAD_RADIUS_M) & (np.abs(alt - alt[0]) <= PAD_BAND_M)
    count = n if on_pad.all() else int(np.argmin(on_pad))
    if count >= n / 2:
        return None
    elevation = float(np.median(alt[:count]))
    if float(np.median(alt[count:])) - elevation < MIN_SURVEY_HEIGHT_M:
        return None
    return TakeoffGround(elevation_m=elevation, names=tuple(names[:count]))
