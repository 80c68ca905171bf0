"""The seven-parameter similarity (Helmert) transform between two 3D point sets.

``target = scale * R @ source + t``, fitted by least squares on paired points with Umeyama's
closed form (Umeyama 1991, "Least-squares estimation of transformation parameters between two
point patterns", IEEE PAMI 13(4)): the rotation from the SVD of the cross-covariance, with the
reflection guard, the scale from the singular values over the source variance. Names follow
destination-from-source: :class:`Similarity` maps the model frame to the ground frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.errors import SfapError

F64 = NDArray[np.float64]


class SimilarityError(SfapError):
    """The points cannot fix a similarity (fewer than three, or all on a line): exit code 1."""


@dataclass(frozen=True, kw_only=True)
class Similarity:
    """``apply(x) = scale * rotation @ x + translation_m``; rotation is proper (det +1)."""

    scale: float
    rotation: F64
    translation_m: F64

    def apply(self, points: ArrayLike) -> F64:
        """Map (N, 3) or (3,) points."""
        p = np.asarray(points, dtype=np.float64)
        return np.asarray(self.scale * p @ self.rotation.T + self.translation_m, dtype=np.float64)

    def inverse(self) -> Similarity:
        rt = self.rotation.T
        return Similarity(
            scale=1.0 / self.scale, rotation=rt, translation_m=-(rt @ self.translation_m) / self.scale
        )

    @property
    def rotation_angle_deg(self) -> float:
        c = (np.trace(self.rotation) - 1.0) / 2.0
        return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def fit_similarity(source: ArrayLike, target: ArrayLike, weights: ArrayLike | None = None) -> Similarity:
    """Least-squares similarity with ``target ~ apply(source)``; (N, 3) each, N >= 3 not collinear.

    ``weights``: optional (N,) non-negative weights of the squared residuals.
    """
    src = np.asarray(source, dtype=np.float64)
    dst = np.asarray(target, dtype=np.float64)
    if src.ndim != 2 or src.shape[1] != 3 or src.shape != dst.shape:
        raise ValueError(f"source {src.shape} and target {dst.shape} must both be (N, 3)")
    n = src.shape[0]
    if n < 3:
        raise SimilarityError(f"{n} point pair(s): a similarity needs at least three points not on a line")
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != (n,) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError(f"weights must be (N,) = ({n},), non-negative, not all zero")
    w = w / w.sum()
    mu_s = w @ src
    mu_d = w @ dst
    s0 = src - mu_s
    d0 = dst - mu_d
    var_s = float(w @ np.sum(s0 * s0, axis=1))
    cov = (d0 * w[:, None]).T @ s0  # (3, 3): sum w d s^T
    u, sv, vt = np.linalg.svd(cov)
    spread = np.linalg.svd(s0 * np.sqrt(w)[:, None], compute_uv=False)
    if var_s <= 0 or spread[1] <= 1e-9 * max(spread[0], 1e-300):
        raise SimilarityError(
            f"the {n} points lie on a line (or on one point): they fix no rotation about it; use control "
            "points spread over the block"
        )
    d = np.ones(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        d[2] = -1.0
    rotation = u @ np.diag(d) @ vt
    scale = float((sv * d).sum() / var_s)
    translation = mu_d - scale * rotation @ mu_s
    return Similarity(scale=scale, rotation=rotation, translation_m=translation)
