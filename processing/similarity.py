"""The seven-parameter similarity (Helmert) transform between two 3D point sets.

``target = scale * R @ source + t``, fitted by least squares on paired points with Umeyama's
closed form (Umeyama 1991, "Least-squares estimation of transformation parameters between two
point patterns", IEEE PAMI 13(4)): the rotation from the SVD of the cross-covariance, with the
reflection guard, the scale from the singular values over the source variance. Names follow
destination-from-source: :class:`Similarity` maps the model frame to the ground frame.
"""

from __future__ import annotations

import math
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


#: Significance level of the test that decides whether the control points' horizontal positions
#: fix the model's tilt (:func:`fit_horizontal_similarity`).
TILT_TEST_ALPHA = 0.01


@dataclass(frozen=True, kw_only=True)
class HorizontalFit:
    """A similarity fitted to horizontal control only (heights unknown).

    ``tilt_fitted``: the tilt came from the control points' horizontal positions (their relief
    fixes it, by the F test at :data:`TILT_TEST_ALPHA`); otherwise the model is levelled on the
    control points' best-fit plane. ``tilt_p_value``: that test's p value (None with fewer than
    four points: no redundancy to test with)."""

    similarity: Similarity
    tilt_fitted: bool
    tilt_p_value: float | None
    tilt_from_level_deg: float

    def describe(self) -> str:
        if self.tilt_fitted:
            assert self.tilt_p_value is not None
            return (
                "horizontal similarity (scale, rotation, east, north) with the tilt fitted from the control "
                f"points' relief ({self.tilt_from_level_deg:.2f} deg from their plane, p = "
                f"{self.tilt_p_value:.2g})"
            )
        why = (
            "fewer than four control points cannot test a tilt"
            if self.tilt_p_value is None
            else f"their horizontal positions do not fix a tilt, p = {self.tilt_p_value:.2g}"
        )
        return (
            "horizontal similarity (scale, rotation, east, north), the model levelled on the control points' "
            f"best-fit plane ({why})"
        )


def _rotation_to(a: F64, b: F64) -> F64:
    """The proper rotation taking unit vector ``a`` to unit vector ``b`` (the shortest one)."""
    v = np.cross(a, b)
    c = float(a @ b)
    if c < -1.0 + 1e-12:  # opposite: half a turn about any axis normal to a
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis)
        return np.asarray(2.0 * np.outer(axis, axis) - np.eye(3), dtype=np.float64)
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.asarray(np.eye(3) + vx + vx @ vx / (1.0 + c), dtype=np.float64)


def _exp_so3(w: F64) -> F64:
    theta = float(np.linalg.norm(w))
    if theta < 1e-15:
        return np.eye(3)
    k = w / theta
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.asarray(np.eye(3) + math.sin(theta) * kx + (1.0 - math.cos(theta)) * kx @ kx, dtype=np.float64)


def _fit_2d(src_xy: F64, dst_xy: F64) -> tuple[float, F64, F64]:
    """Least-squares 2D similarity (scale, 2x2 rotation, translation) with dst ~ s R src + t."""
    mu_s, mu_d = src_xy.mean(axis=0), dst_xy.mean(axis=0)
    s0, d0 = src_xy - mu_s, dst_xy - mu_d
    a = float(np.sum(s0 * d0))
    b = float(np.sum(s0[:, 0] * d0[:, 1] - s0[:, 1] * d0[:, 0]))
    var = float(np.sum(s0 * s0))
    angle = math.atan2(b, a)
    scale = math.hypot(a, b) / var
    rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    return scale, rot, mu_d - scale * rot @ mu_s


def _horizontal_refine(src: F64, dst_xy: F64, start: Similarity) -> tuple[Similarity, float]:
    """Gauss-Newton (Levenberg damping) on the horizontal residuals over rotation (3), scale and
    east/north translation, from ``start``; returns the fit and its residual sum of squares."""

    def rss(sim: Similarity) -> float:
        return float(np.sum((dst_xy - sim.apply(src)[:, :2]) ** 2))

    sim, cost, damping = start, rss(start), 1e-6
    for _ in range(500):
        q = sim.apply(src) - sim.translation_m  # s R x
        r = (dst_xy - sim.apply(src)[:, :2]).reshape(-1)
        n = len(src)
        jac = np.zeros((2 * n, 6))
        # d(p) = w x q + lam q + dt: rows x and y of each point.
        jac[0::2, 0:3] = np.column_stack([np.zeros(n), q[:, 2], -q[:, 1]])
        jac[1::2, 0:3] = np.column_stack([-q[:, 2], np.zeros(n), q[:, 0]])
        jac[0::2, 3], jac[1::2, 3] = q[:, 0], q[:, 1]
        jac[0::2, 4], jac[1::2, 5] = 1.0, 1.0
        normal = jac.T @ jac
        grad = jac.T @ r
        improved = False
        while damping < 1e12:
            step = np.asarray(
                np.linalg.solve(normal + damping * np.diag(np.diag(normal) + 1e-12), grad), dtype=np.float64
            )
            trial = Similarity(
                scale=sim.scale * math.exp(step[3]),
                rotation=_exp_so3(step[0:3]) @ sim.rotation,
                translation_m=sim.translation_m + np.array([step[4], step[5], 0.0]),
            )
            trial_cost = rss(trial)
            if trial_cost <= cost:
                sim, improved = trial, cost - trial_cost > 1e-15 * max(cost, 1e-300)
                cost = trial_cost
                damping = max(damping / 10.0, 1e-9)
                break
            damping *= 10.0
        if not improved:
            break
    return sim, cost


def _affine_start(src: F64, dst_xy: F64) -> Similarity | None:
    """A start from relief: the least-squares affine map of the model points onto the plan
    positions, its 2 x 3 matrix brought to the nearest scaled pair of orthonormal rows (the
    tilt is then in those rows); None when the points are (nearly) on a plane."""
    mu_s, mu_d = src.mean(axis=0), dst_xy.mean(axis=0)
    s0, d0 = src - mu_s, dst_xy - mu_d
    sv = np.linalg.svd(s0, compute_uv=False)
    if sv[2] <= 1e-6 * sv[0]:
        return None
    m = np.linalg.lstsq(s0, d0, rcond=None)[0].T  # (2, 3): d ~ m @ s
    u, sigma, vt = np.linalg.svd(m, full_matrices=False)
    rows = u @ vt  # (2, 3) orthonormal rows
    third = np.cross(rows[0], rows[1])
    rotation = np.vstack([rows, third])
    scale = float(sigma.mean())
    translation = np.array([*mu_d, 0.0]) - scale * rotation @ mu_s
    return Similarity(scale=scale, rotation=rotation, translation_m=translation)


def fit_horizontal_similarity(
    source: ArrayLike, target_xy: ArrayLike, *, up_hint: ArrayLike, datum_z: float = 0.0
) -> HorizontalFit:
    """Place model points ``source`` (N, 3) on surveyed east/north ``target_xy`` (N, 2) whose
    heights are unknown: scale, rotation and east/north translation by least squares on the
    horizontal residuals only (a relief the survey does not know is not flattened, as the
    seven-parameter fit to equal heights would: that one shrinks the scale by about
    var(relief) / var(all coordinates) and tilts the model).

    The tilt needs relief: the model is first levelled on the points' best-fit plane (its
    normal on the side of ``up_hint``, a model-frame vector pointing up, e.g. from the points
    towards the cameras), then the tilt is refined with the other parameters and kept only
    when the F test (2 and 2N - 6 degrees of freedom) says it fits the horizontal positions
    significantly better (started from the levelled fit and from the least-squares affine map
    of the points, the better of the two). The mean height of the placed points is ``datum_z``."""
    src = np.asarray(source, dtype=np.float64)
    dst = np.asarray(target_xy, dtype=np.float64)
    if src.ndim != 2 or src.shape[1] != 3 or dst.shape != (len(src), 2):
        raise ValueError(f"source {src.shape} must be (N, 3) and target {dst.shape} (N, 2)")
    n = len(src)
    centred = src - src.mean(axis=0)
    spread = np.linalg.svd(dst - dst.mean(axis=0), compute_uv=False) if n >= 2 else np.zeros(2)
    if n < 3 or spread[1] <= 1e-9 * max(spread[0], 1e-300):
        raise SimilarityError(
            f"{n} point(s) on a line (or fewer than three): they fix no horizontal similarity; use control "
            "points spread over the block"
        )
    normal = np.linalg.svd(centred)[2][2]
    if normal @ np.asarray(up_hint, dtype=np.float64) < 0:
        normal = -normal
    level = _rotation_to(normal, np.array([0.0, 0.0, 1.0]))
    levelled = centred @ level.T
    s2, r2, t2 = _fit_2d(levelled[:, :2], dst)
    rot = np.eye(3)
    rot[:2, :2] = r2
    rotation = rot @ level
    translation = np.array([t2[0], t2[1], 0.0]) - s2 * rotation @ src.mean(axis=0)
    start = Similarity(scale=s2, rotation=rotation, translation_m=translation)
    levelled_sim = start
    rss_level = float(np.sum((dst - start.apply(src)[:, :2]) ** 2))
    chosen, fitted, p_value = levelled_sim, False, None
    if n >= 4:
        free, rss_free = _horizontal_refine(src, dst, levelled_sim)
        affine = _affine_start(src, dst)
        if affine is not None:
            other, rss_other = _horizontal_refine(src, dst, affine)
            if rss_other < rss_free:
                free, rss_free = other, rss_other
        dof = 2 * n - 6
        if rss_free <= 0.0:
            p_value = 0.0 if rss_level > 0.0 else 1.0
        else:
            f = max(rss_level - rss_free, 0.0) / 2.0 / (rss_free / dof)
            # F(2, d) survival function in closed form: (1 + 2 f / d) ** (-d / 2).
            p_value = float((1.0 + 2.0 * f / dof) ** (-dof / 2.0))
        # A tilt that puts the cameras below the points is not the site.
        above = float((free.rotation @ np.asarray(up_hint, dtype=np.float64))[2]) > 0.0
        if p_value < TILT_TEST_ALPHA and above:
            chosen, fitted = free, True
    z = chosen.apply(src)[:, 2]
    final = Similarity(
        scale=chosen.scale,
        rotation=chosen.rotation,
        translation_m=chosen.translation_m + np.array([0.0, 0.0, datum_z - float(z.mean())]),
    )
    up_after = final.rotation.T @ np.array([0.0, 0.0, 1.0])
    tilt = math.degrees(math.acos(float(np.clip(up_after @ normal, -1.0, 1.0))))
    return HorizontalFit(similarity=final, tilt_fitted=fitted, tilt_p_value=p_value, tilt_from_level_deg=tilt)
