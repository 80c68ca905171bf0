"""The ground a coverage check projects frames onto: flat at one elevation, or a DEM.

Height above ground is the critical unknown of a coverage check: every footprint, GSD and
base-height ratio scales with it. A ground model therefore never guesses: it is built from an
explicit elevation or a DEM file, states the vertical reference its elevations are in (which must
be the frames' altitude reference), and carries a ``description`` the report prints, saying where
its numbers come from.

Horizontal coordinates are metres in a :class:`planner.geo.LocalFrame` (x east, y north).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Protocol, Self, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.errors import SfapError
from planner.geo import LocalFrame
from planner.terrain import Dem

from .errors import GroundError
from .frames import AltitudeReference

logger = logging.getLogger(__name__)

F64 = NDArray[np.float64]


@runtime_checkable
class Ground(Protocol):
    """What :func:`processing.footprints.project_footprints` needs from a ground model."""

    @property
    def reference(self) -> AltitudeReference: ...

    @property
    def description(self) -> str: ...

    def elevation_at(self, x_m: ArrayLike, y_m: ArrayLike, frame: LocalFrame) -> F64:
        """Ground elevation (metres, in ``reference``) at local-frame points; GroundError if unknown."""
        ...


@dataclass(frozen=True, kw_only=True)
class FlatGround:
    """Horizontal ground at ``elevation_m`` above ``reference``.

    ``reference`` must be the frames' altitude reference: ``rel_home`` with ``elevation_m = 0``
    is "the ground is where the drone took off"; ``amsl`` with a surveyed or map elevation is the
    usual choice for EXIF altitudes. ``agl`` with ``elevation_m = 0`` accepts frames whose
    altitudes are already above the ground below them.
    """

    elevation_m: float
    reference: AltitudeReference
    source: str = ""

    def __post_init__(self) -> None:
        if not (isinstance(self.elevation_m, int | float) and math.isfinite(self.elevation_m)):
            raise GroundError(
                f"flat ground elevation_m = {self.elevation_m!r} is not a number; give the ground "
                f"elevation in metres"
            )
        if not -500.0 <= self.elevation_m <= 9000.0:
            raise GroundError(
                f"flat ground elevation_m = {self.elevation_m} is outside -500..9000 m; give the "
                f"ground elevation in metres"
            )
        try:
            object.__setattr__(self, "reference", AltitudeReference(self.reference))
        except ValueError:
            choices = ", ".join(r.value for r in AltitudeReference)
            raise GroundError(f"flat ground reference {self.reference!r} is not one of {choices}") from None
        if self.reference is AltitudeReference.AGL and self.elevation_m != 0.0:
            raise GroundError(
                f"flat ground above 'agl' must have elevation_m = 0 (the ground itself), not "
                f"{self.elevation_m}"
            )

    @property
    def description(self) -> str:
        text = f"flat ground at {self.elevation_m:.2f} m ({self.reference.value})"
        return f"{text}, {self.source}" if self.source else text

    def elevation_at(self, x_m: ArrayLike, y_m: ArrayLike, frame: LocalFrame) -> F64:
        x, _ = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        return np.full(x.shape, float(self.elevation_m))


@dataclass(frozen=True, kw_only=True)
class DemGround(Dem):
    """A gridded elevation model as the ground (:class:`planner.terrain.Dem`, bilinear), with
    the vertical reference its elevations are in. Built with :meth:`from_geotiff`."""

    reference: AltitudeReference
    error: ClassVar[type[SfapError]] = GroundError

    @classmethod
    def from_geotiff(
        cls,
        path: str | Path,
        *,
        bounds_lonlat: tuple[float, float, float, float] | None = None,
        reference: AltitudeReference | str = AltitudeReference.AMSL,
        **fields: Any,
    ) -> Self:
        """Read a DEM as the ground. ``reference`` is its vertical reference: DEMs (SRTM, national
        LiDAR) are usually orthometric heights, ``amsl``."""
        try:
            ref = AltitudeReference(reference)
        except ValueError:
            raise GroundError(f"DEM reference {reference!r} is not an altitude reference") from None
        return super().from_geotiff(path, bounds_lonlat=bounds_lonlat, reference=ref, **fields)

    @property
    def description(self) -> str:
        return f"{super().description} ({self.reference.value})"


def check_reference(ground: Ground, frames_reference: AltitudeReference) -> None:
    """Refuse a ground whose vertical reference is not the frames' (heights would be wrong)."""
    if AltitudeReference(ground.reference) is not AltitudeReference(frames_reference):
        raise GroundError(
            f"the frames' altitudes are {AltitudeReference(frames_reference).value} but the ground "
            f"({ground.description}) is {AltitudeReference(ground.reference).value}; give the ground "
            f"in the frames' reference (e.g. the take-off elevation for rel_home altitudes)"
        )
