"""The image scale the pixels measured, put to use: when it is conclusive and disagrees with the
tags' scale, the check's footprints, coverage, GSD (and, when the heights are to blame, heights)
come from it, and the report says which tag or camera is off, by how much.

The pixels measure the ground size of a pixel: the GPS baseline between two consecutive frames of a
line over the shift of the image between them (:mod:`processing.pixel_match`). The tags give it as
the height above ground over the focal length in pixels. When the two disagree, one of the two tags
is off:

- the camera (its focal length in pixels): a camera known only from its 35 mm equivalent
  (:attr:`processing.image_tags.CameraConfidence.EQUIVALENT_35MM`, a zoom or gimbal camera writes it
  inconsistently), or a wrong camera given. The focal length is then the tagged height over the
  measured GSD; the heights stay as tagged;
- the heights above ground: drifting GPS altitudes (detrended about mid-flight, or trending), a
  ground elevation guessed wrong, ellipsoidal heights taken for heights above mean sea level. The
  height is then the measured GSD times the focal length; the ground under the frames is moved by
  the difference (one offset for the block: a wrong ground, a wrong mid-flight altitude);
- either: the pixels alone cannot tell the two apart (both give the same footprints over flat
  ground; only the heights, hence B/H, differ). The footprints, coverage and GSD then come from the
  measured scale through the camera (the heights stay as tagged), and the report gives both
  readings.

The measured scale is used only when it is conclusive: at least :data:`MIN_SCALE_PAIRS` pairs, the
median's standard error at most :data:`MAX_SCALE_ERROR_RATIO` of it, and a disagreement beyond both
:data:`processing.pixel_match.SCALE_AGREEMENT_RATIO` (the tags' own uncertainty) and three standard
errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import StrEnum
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .errors import GroundError
from .frames import Frames
from .ground import DemGround, FlatGround, Ground
from .pixel_match import SCALE_AGREEMENT_RATIO, PixelFigures

#: Along-line pairs with a usable baseline a scale needs before it replaces the tags' (a median of
#: fewer is one or two pairs' attitude jitter).
MIN_SCALE_PAIRS = 5
#: The median of the pairs' scales must be known to this share (its standard error, from the
#: pairs' robust spread) before it replaces the tags': half the tolerance the tags are held to
#: (:data:`processing.pixel_match.SCALE_AGREEMENT_RATIO`), so that the figures it gives are within
#: that tolerance at two standard errors. A fixed wing's attitude jitter scatters single pairs by
#: 10-30 %; the median of 30 such pairs is known to about 5 %.
MAX_SCALE_ERROR_RATIO = SCALE_AGREEMENT_RATIO / 2.0


class Blame(StrEnum):
    """Which tag the measured scale says is off."""

    CAMERA = "camera"
    HEIGHTS = "heights"
    EITHER = "camera or heights"


def median_error_ratio(values: ArrayLike) -> float:
    """The standard error of the median of ``values`` as a share of it: 1.2533 x sigma / sqrt(n)
    (the median's efficiency for a normal sample), sigma from the median absolute deviation
    (x 1.4826). inf for fewer than two values."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if v.size < 2:
        return math.inf
    median = float(np.median(v))
    if not median > 0:
        return math.inf
    sigma = 1.4826 * float(np.median(np.abs(v - median)))
    return 1.2533 * sigma / math.sqrt(v.size) / median


@dataclass(frozen=True, kw_only=True)
class ScaleFinding:
    """The measured scale against the tags' (:func:`assess_scale`).

    ``ratio``: measured over tagged GSD; ``error_ratio``: the measured median's standard error as a
    share of it; ``pairs``: along-line pairs measured; ``used``: the figures come from the measured
    scale; ``blame``: which tag is off (None when they agree or the measurement is inconclusive);
    the tagged and measured GSD (cm), height above ground (m: measured = measured GSD x the tagged
    focal length) and focal length (px: measured = tagged height / measured GSD).
    """

    ratio: float
    error_ratio: float
    pairs: int
    used: bool
    blame: Blame | None
    suspect: Blame | None = None
    tagged_gsd_cm: float
    measured_gsd_cm: float
    tagged_height_m: float
    measured_height_m: float
    tagged_focal_px: float
    measured_focal_px: float

    @property
    def conclusive(self) -> bool:
        return self.pairs >= MIN_SCALE_PAIRS and self.error_ratio <= MAX_SCALE_ERROR_RATIO

    @property
    def rematch(self) -> bool:
        """The tagged footprints that chose the pairs to match are off by more than the tags'
        uncertainty: the pairs the measured scale's footprints choose should be matched."""
        return self.suspect is not None

    def provisional(self) -> ScaleFinding:
        """This finding as if used (its suspect blamed): to choose the pairs to match again."""
        return replace(self, used=self.suspect is not None, blame=self.suspect)

    @property
    def height_offset_m(self) -> float:
        """How far the ground moves for the heights to match the measured scale (negative: down)."""
        return self.tagged_height_m - self.measured_height_m if self.blame is Blame.HEIGHTS else 0.0

    def words(self) -> str | None:
        """The report's sentence: what disagrees, by how much, what the figures use and what to do;
        None when the scales agree."""
        if self.blame is None and self.conclusive:
            return None
        head = (
            f"the image scale measured in the pixels (GPS baseline over the image shift of {self.pairs} "
            f"pairs along the lines) is {self.measured_gsd_cm:.2f} cm per pixel "
            f"(+-{100 * self.error_ratio:.0f} %) against the {self.tagged_gsd_cm:.2f} cm the tags give "
            f"({100 * (self.ratio - 1):+.0f} %)"
        )
        if not self.used:
            if abs(self.ratio - 1.0) <= SCALE_AGREEMENT_RATIO:
                return None
            return (
                f"{head}, but from too few pairs or too scattered to replace the tags' scale (at least "
                f"{MIN_SCALE_PAIRS} pairs and +-{100 * MAX_SCALE_ERROR_RATIO:g} % needed): the figures "
                "are the tags'; check the camera (--camera) and the ground (--ground-elevation-m)"
            )
        camera_off = (
            f"the camera's focal length is unknown, measured {self.measured_focal_px:.0f} px (the camera "
            f"assumed has {self.tagged_focal_px:.0f} px, "
            f"{100 * (self.tagged_focal_px / self.measured_focal_px - 1):+.0f} %)"
        )
        offset = self.tagged_height_m - self.measured_height_m
        heights_off = (
            f"the heights above ground are {self.measured_height_m:.1f} m (median), not the "
            f"{self.tagged_height_m:.1f} m of the tags: the ground is {abs(offset):.1f} m "
            f"{'lower' if offset < 0 else 'higher'} than given, or the altitudes are that far off"
        )
        if self.blame is Blame.CAMERA:
            return (
                f"{head}: {camera_off}; footprints, coverage and GSD here use the measured focal length "
                "(heights as tagged); give the camera (--camera) to confirm"
            )
        if self.blame is Blame.HEIGHTS:
            return (
                f"{head}: the altitudes drift, so {heights_off}; footprints, coverage, GSD, heights and "
                "B/H here use the heights from the image scale"
            )
        return (
            f"{head}: either {heights_off}, or {camera_off}; footprints, coverage and GSD here use the "
            "measured scale (the same either way), heights and B/H the tagged heights; give the camera "
            "(--camera) or the ground (--ground-elevation-m) that is right"
        )

    def as_dict(self) -> dict[str, Any]:
        return {
            "used": self.used,
            "conclusive": self.conclusive,
            "blame": self.blame.value if self.blame is not None else None,
            "ratio_measured_to_tagged": self.ratio,
            "error_ratio": self.error_ratio,
            "pairs": self.pairs,
            "gsd_cm": {"tagged": self.tagged_gsd_cm, "measured": self.measured_gsd_cm},
            "height_agl_m": {"tagged": self.tagged_height_m, "measured": self.measured_height_m},
            "focal_px": {"tagged": self.tagged_focal_px, "measured": self.measured_focal_px},
            "ground_moved_m": self.height_offset_m if self.used else 0.0,
        }


def assess_scale(
    figures: PixelFigures,
    *,
    tagged_gsd_cm: float,
    tagged_height_m: float,
    camera_rough: bool,
    heights_drift: bool,
) -> ScaleFinding | None:
    """The measured scale of ``figures`` against the tags' (``tagged_gsd_cm``, the block's median
    GSD from the tags; ``tagged_height_m``, its median height above ground): None without a measured
    scale. ``camera_rough``: the camera is known only from its 35 mm equivalent; ``heights_drift``:
    the GPS altitudes drift (or were detrended). Module docstring for the rules."""
    values = figures.gsd_cm[np.isfinite(figures.gsd_cm)]
    if values.size == 0 or not (tagged_gsd_cm > 0 and tagged_height_m > 0):
        return None
    measured = float(np.median(values))
    ratio = measured / tagged_gsd_cm
    error = median_error_ratio(values)
    focal_px = figures.focal_px
    conclusive = values.size >= MIN_SCALE_PAIRS and error <= MAX_SCALE_ERROR_RATIO
    differs = abs(ratio - 1.0) > max(SCALE_AGREEMENT_RATIO, 3.0 * error * ratio)
    suspect: Blame | None = None
    if values.size >= MIN_SCALE_PAIRS and abs(ratio - 1.0) > SCALE_AGREEMENT_RATIO:
        if camera_rough and not heights_drift:
            suspect = Blame.CAMERA
        elif heights_drift and not camera_rough:
            suspect = Blame.HEIGHTS
        else:
            suspect = Blame.EITHER
    blame = suspect if conclusive and differs else None
    return ScaleFinding(
        ratio=ratio,
        error_ratio=error,
        pairs=int(values.size),
        used=blame is not None,
        blame=blame,
        suspect=suspect,
        tagged_gsd_cm=tagged_gsd_cm,
        measured_gsd_cm=measured,
        tagged_height_m=tagged_height_m,
        measured_height_m=tagged_height_m * ratio,
        tagged_focal_px=focal_px,
        measured_focal_px=focal_px / ratio,
    )


def moved_ground(ground: Ground, offset_m: float) -> Ground:
    """``ground`` moved up by ``offset_m`` (down when negative): the ground the measured scale puts
    under the frames when the heights are to blame. Flat ground or a DEM; GroundError otherwise."""
    if isinstance(ground, FlatGround):
        return replace(ground, elevation_m=ground.elevation_m + offset_m)
    if isinstance(ground, DemGround):
        return replace(ground, elevation=ground.elevation + offset_m, _transformers={})
    raise GroundError(f"cannot move a ground of kind {type(ground).__name__}; use FlatGround or DemGround")


def moved_words(offset_m: float) -> str:
    """What the report adds to the ground's description when it was moved."""
    return (
        f", moved {'up' if offset_m > 0 else 'down'} {abs(offset_m):.1f} m to the image scale measured "
        "in the pixels"
    )


def rescaled(frames: Frames, ground: Ground, finding: ScaleFinding) -> tuple[Frames, Ground]:
    """The frames and ground that give the measured scale: the camera's focal length scaled
    (camera or either to blame: the heights stay), or the ground moved (the heights to blame)."""
    if not finding.used:
        return frames, ground
    if finding.blame is Blame.HEIGHTS:
        return frames, moved_ground(ground, finding.height_offset_m)
    camera = frames.camera
    focal_mm = camera.focal_length_mm * finding.measured_focal_px / finding.tagged_focal_px
    scaled = replace(
        camera,
        focal_length_mm=focal_mm,
        source=f"{camera.source}; focal length {focal_mm:.3g} mm from the image scale measured in the pixels",
    )
    return replace(frames, camera=scaled), ground


__all__ = [
    "MAX_SCALE_ERROR_RATIO",
    "MIN_SCALE_PAIRS",
    "Blame",
    "ScaleFinding",
    "assess_scale",
    "median_error_ratio",
    "moved_ground",
    "moved_words",
    "rescaled",
]
