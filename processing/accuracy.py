"""Accuracy at ground control and independent check points (the seed's 3-3.7, Tables 3-1 and 3-2).

A reconstruction (in its own model frame) and surveyed points with their image observations:

1. :func:`triangulate` each point from the rays of its observations in registered frames (the
   point nearest all rays in the least-squares sense); a point seen in fewer than two
   registered frames is listed, not used.
2. :func:`~processing.similarity.fit_similarity` from the control points' model positions to
   their surveyed positions (seven parameters).
3. Residuals (surveyed minus transformed model position) at the control points and, separately,
   at the check points: RMSE X, Y, Z, horizontal and total in metres; the image residuals in
   pixels (each observation against the surveyed point carried back into the model and
   projected); and RMSE:range, the range being the mean height of the registered cameras above
   the points (the textbook's flying height).

Everything here works on plain arrays and on :class:`View` objects, so it is tested on synthetic
scenes with known truth and used unchanged on a COLMAP model (the pycolmap adapter provides the
views).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from planner.errors import SfapError

from .gcp import Observation
from .similarity import Similarity, fit_similarity

F64 = NDArray[np.float64]

#: The textbook's figures (seed 3-3.7; REFERENCES.md): its nine-frame block at 75.6 m reached
#: check-point RMSE:range of about 1:950 to 1:1350; Smith and Vericat's mean of 50 surveys 1:639.
TEXTBOOK_RATIO_RANGE = (950.0, 1350.0)
SMITH_VERICAT_RATIO = 639.0

#: Fewest control points that fix a similarity.
MIN_CONTROL_POINTS = 3
#: A point whose triangulated position reprojects farther than this from one of its own
#: observations (pixels) was marked inconsistently (a wrong target, a typo): listed, not used.
MAX_TRIANGULATION_PX = 10.0


class AccuracyError(SfapError):
    """The control cannot place the block (too few usable points): exit code 1."""


class View(Protocol):
    """A registered frame of a model: rays from pixels and projection of model points."""

    @property
    def centre(self) -> F64: ...

    def rays(self, pixels_xy: F64) -> F64:
        """Unit ray directions (K, 3) in the model frame for pixels (K, 2) (x right, y down)."""
        ...

    def project(self, points: F64) -> F64:
        """Pixels (K, 2) of model points (K, 3)."""
        ...


@dataclass(frozen=True, kw_only=True)
class PinholeView:
    """An undistorted pinhole camera: ``x_cam = R @ X + t``, pixel = K @ x_cam / z."""

    focal_px: float
    principal_xy_px: tuple[float, float]
    cam_from_world_rotation: F64
    cam_from_world_translation: F64

    @property
    def centre(self) -> F64:
        return np.asarray(-self.cam_from_world_rotation.T @ self.cam_from_world_translation, dtype=np.float64)

    def rays(self, pixels_xy: F64) -> F64:
        px = np.atleast_2d(np.asarray(pixels_xy, dtype=np.float64))
        cx, cy = self.principal_xy_px
        cam = np.column_stack(
            [(px[:, 0] - cx) / self.focal_px, (px[:, 1] - cy) / self.focal_px, np.ones(len(px))]
        )
        world = cam @ self.cam_from_world_rotation  # R^T applied to rows
        return np.asarray(world / np.linalg.norm(world, axis=1, keepdims=True), dtype=np.float64)

    def project(self, points: F64) -> F64:
        p = np.atleast_2d(np.asarray(points, dtype=np.float64))
        cam = p @ self.cam_from_world_rotation.T + self.cam_from_world_translation
        cx, cy = self.principal_xy_px
        return np.column_stack(
            [self.focal_px * cam[:, 0] / cam[:, 2] + cx, self.focal_px * cam[:, 1] / cam[:, 2] + cy]
        )


def intersect_rays(origins: F64, directions: F64) -> F64:
    """The point nearest (least squares) to rays ``origins + t * directions`` (unit), (K, 3) each."""
    eye = np.eye(3)
    a = np.zeros((3, 3))
    b = np.zeros(3)
    for o, d in zip(origins, directions, strict=True):
        m = eye - np.outer(d, d)
        a += m
        b += m @ o
    return np.asarray(np.linalg.solve(a, b), dtype=np.float64)


@dataclass(frozen=True, kw_only=True)
class Triangulated:
    """A point's model position and the frames it was seen in; ``None`` when fewer than two."""

    name: str
    model_xyz: F64 | None
    used_images: tuple[str, ...]
    missing_images: tuple[str, ...]
    reason: str = ""
    marks_rmse_px: float = 0.0


def triangulate(
    name: str,
    observations: Sequence[Observation],
    views: Mapping[str, View],
    *,
    max_error_px: float = MAX_TRIANGULATION_PX,
) -> Triangulated:
    """The point seen by ``observations``, from the views of the registered frames; None (with
    the reason) when it is seen in fewer than two, its rays are nearly parallel, or it
    reprojects more than ``max_error_px`` from one of its marks."""
    used = [o for o in observations if o.image in views]
    missing = tuple(o.image for o in observations if o.image not in views)
    if len(used) < 2:
        return Triangulated(
            name=name,
            model_xyz=None,
            used_images=tuple(o.image for o in used),
            missing_images=missing,
            reason=f"seen in {len(used)} registered frame(s) (needs two)"
            + (f"; not registered: {', '.join(missing)}" if missing else ""),
        )
    origins = np.array([views[o.image].centre for o in used])
    directions = np.vstack([views[o.image].rays(np.array([[o.x_px, o.y_px]])) for o in used])
    # Nearly parallel rays (the same spot from one place) fix no depth.
    cos = np.clip(directions @ directions.T, -1.0, 1.0)
    widest_deg = float(np.degrees(np.arccos(cos.min())))
    if widest_deg < 0.5:
        return Triangulated(
            name=name,
            model_xyz=None,
            used_images=tuple(o.image for o in used),
            missing_images=missing,
            reason=f"its rays meet at {widest_deg:.2f} deg at most: no depth",
        )
    xyz = intersect_rays(origins, directions)
    errors = [
        math.hypot(*(views[o.image].project(xyz[None, :])[0] - np.array([o.x_px, o.y_px]))) for o in used
    ]
    worst = int(np.argmax(errors))
    if errors[worst] > max_error_px:
        return Triangulated(
            name=name,
            model_xyz=None,
            used_images=tuple(o.image for o in used),
            missing_images=missing,
            reason=(
                f"its observations disagree: the point they meet at is {errors[worst]:.0f} px from its mark "
                f"in {used[worst].image} (more than {max_error_px:g} px): re-mark it"
            ),
        )
    return Triangulated(
        name=name,
        model_xyz=xyz,
        used_images=tuple(o.image for o in used),
        missing_images=missing,
        marks_rmse_px=float(np.sqrt(np.mean(np.square(errors)))),
    )


@dataclass(frozen=True, kw_only=True)
class PointResidual:
    name: str
    role: str  # "control" | "check"
    dx_m: float
    dy_m: float
    dz_m: float
    image_rmse_px: float
    n_images: int
    marks_rmse_px: float = 0.0


@dataclass(frozen=True, kw_only=True)
class RmseRow:
    """One line of the Table 3-2 layout: RMSE of a set of points."""

    role: str
    n_points: int
    rmse_x_m: float
    rmse_y_m: float
    rmse_z_m: float
    rmse_horizontal_m: float
    rmse_total_m: float
    rmse_image_px: float
    range_m: float
    rmse_marks_px: float = 0.0

    @property
    def ratio(self) -> float:
        """The range over the total RMSE: the N of 1:N (inf when the RMSE is 0)."""
        return self.range_m / self.rmse_total_m if self.rmse_total_m > 0 else math.inf

    def as_dict(self) -> dict[str, float | int | str]:
        return {
            "role": self.role,
            "n_points": self.n_points,
            "rmse_x_m": self.rmse_x_m,
            "rmse_y_m": self.rmse_y_m,
            "rmse_z_m": self.rmse_z_m,
            "rmse_horizontal_m": self.rmse_horizontal_m,
            "rmse_total_m": self.rmse_total_m,
            "rmse_image_px": self.rmse_image_px,
            "rmse_marks_px": self.rmse_marks_px,
            "range_m": self.range_m,
            "rmse_to_range": f"1:{self.ratio:.0f}" if math.isfinite(self.ratio) else "1:inf",
        }


def rmse_row(role: str, residuals: Sequence[PointResidual], range_m: float) -> RmseRow | None:
    if not residuals:
        return None
    d = np.array([[r.dx_m, r.dy_m, r.dz_m] for r in residuals])
    rx, ry, rz = np.sqrt(np.mean(d**2, axis=0))
    img = np.array([r.image_rmse_px for r in residuals])
    n_img = np.array([r.n_images for r in residuals])
    img_rmse = float(np.sqrt(np.sum(img**2 * n_img) / max(n_img.sum(), 1)))
    return RmseRow(
        role=role,
        n_points=len(residuals),
        rmse_x_m=float(rx),
        rmse_y_m=float(ry),
        rmse_z_m=float(rz),
        rmse_horizontal_m=float(math.hypot(rx, ry)),
        rmse_total_m=float(math.sqrt(rx * rx + ry * ry + rz * rz)),
        rmse_image_px=img_rmse,
        rmse_marks_px=float(
            np.sqrt(np.sum(np.array([r.marks_rmse_px for r in residuals]) ** 2 * n_img) / max(n_img.sum(), 1))
        ),
        range_m=range_m,
    )


@dataclass(frozen=True, kw_only=True)
class AccuracyResult:
    """The similarity (model -> ground frame), per-point residuals and the two RMSE rows."""

    similarity: Similarity
    control: RmseRow
    check: RmseRow | None
    residuals: tuple[PointResidual, ...]
    unused: tuple[Triangulated, ...]
    ground_xyz_m: dict[str, F64] = field(default_factory=dict)
    placed_xyz_m: dict[str, F64] = field(default_factory=dict)

    def as_dict(self) -> dict[str, object]:
        return {
            "similarity": {
                "scale": self.similarity.scale,
                "rotation_angle_deg": self.similarity.rotation_angle_deg,
                "translation_m": self.similarity.translation_m.tolist(),
            },
            "control": self.control.as_dict(),
            "check": None if self.check is None else self.check.as_dict(),
            "points": [vars(r) for r in self.residuals],
            "unused_points": [{"name": t.name, "reason": t.reason} for t in self.unused],
            "textbook": {
                "check_rmse_to_range": [
                    f"1:{TEXTBOOK_RATIO_RANGE[0]:.0f}",
                    f"1:{TEXTBOOK_RATIO_RANGE[1]:.0f}",
                ],
                "smith_vericat_mean": f"1:{SMITH_VERICAT_RATIO:.0f}",
            },
        }


def assess_accuracy(
    *,
    ground_xyz_m: Mapping[str, F64],
    observations: Sequence[Observation],
    views: Mapping[str, View],
    control: Sequence[str],
    check: Sequence[str],
) -> AccuracyResult:
    """Triangulate, fit the similarity on ``control``, and measure control and check residuals.

    ``ground_xyz_m``: each point's surveyed position in a metric ground frame (x east, y north,
    z up); ``views``: the registered frames by image name. Raises AccuracyError when fewer than
    three control points can be triangulated.
    """
    by_point: dict[str, list[Observation]] = {}
    for o in observations:
        by_point.setdefault(o.point, []).append(o)
    tri = {n: triangulate(n, by_point.get(n, []), views) for n in (*control, *check)}
    unused = tuple(t for t in tri.values() if t.model_xyz is None)
    usable_control = [n for n in control if tri[n].model_xyz is not None]
    if len(usable_control) < MIN_CONTROL_POINTS:
        detail = "; ".join(f"{t.name}: {t.reason}" for t in unused if t.name in control)
        raise AccuracyError(
            f"only {len(usable_control)} control point(s) could be triangulated "
            f"({', '.join(usable_control)}); "
            f"{MIN_CONTROL_POINTS} are needed to place the block"
            + (f" ({detail})" if detail else "")
            + "; measure each control point in at least two frames that registered, or use fewer check points"
        )
    src = np.array([tri[n].model_xyz for n in usable_control])
    dst = np.array([ground_xyz_m[n] for n in usable_control])
    sim = fit_similarity(src, dst)
    inverse = sim.inverse()
    residuals: list[PointResidual] = []
    placed: dict[str, F64] = {}
    for role, names in (("control", control), ("check", check)):
        for n in names:
            t = tri[n]
            if t.model_xyz is None:
                continue
            xyz = sim.apply(t.model_xyz)
            placed[n] = xyz
            d = np.asarray(ground_xyz_m[n]) - xyz
            model_truth = inverse.apply(np.asarray(ground_xyz_m[n]))
            errs = []
            for o in by_point[n]:
                if o.image in views:
                    px = views[o.image].project(model_truth[None, :])[0]
                    errs.append(math.hypot(px[0] - o.x_px, px[1] - o.y_px))
            residuals.append(
                PointResidual(
                    name=n,
                    role=role,
                    dx_m=float(d[0]),
                    dy_m=float(d[1]),
                    dz_m=float(d[2]),
                    image_rmse_px=float(np.sqrt(np.mean(np.square(errs)))),
                    marks_rmse_px=t.marks_rmse_px,
                    n_images=len(errs),
                )
            )
    # Range: mean height of the registered cameras above the mean surveyed point (ground frame).
    centres = sim.apply(np.array([v.centre for v in views.values()]))
    ground_z = float(np.mean([ground_xyz_m[n][2] for n in (*control, *check)]))
    range_m = float(np.mean(centres[:, 2]) - ground_z)
    control_row = rmse_row("control", [r for r in residuals if r.role == "control"], range_m)
    assert control_row is not None
    check_row = rmse_row("check", [r for r in residuals if r.role == "check"], range_m)
    return AccuracyResult(
        similarity=sim,
        control=control_row,
        check=check_row,
        residuals=tuple(residuals),
        unused=unused,
        ground_xyz_m={n: np.asarray(v) for n, v in ground_xyz_m.items()},
        placed_xyz_m=placed,
    )


def table_3_2(result: AccuracyResult) -> str:
    """The RMSE rows laid out like the textbook's Table 3-2, beside its figures (plain text).

    "image px": each mark against the surveyed point carried into the model and projected;
    "marks px": each mark against the point its own rays meet at (how well the marks agree)."""
    head = (
        f"{'points':<8} {'n':>3} {'RMSE X m':>9} {'RMSE Y m':>9} {'RMSE Z m':>9} {'horiz. m':>9} "
        f"{'total m':>9} {'image px':>9} {'marks px':>9} {'range m':>8} {'RMSE:range':>11}"
    )
    lines = [head]
    for row in (result.control, result.check):
        if row is None:
            continue
        ratio = f"1:{row.ratio:.0f}" if math.isfinite(row.ratio) else "1:inf"
        lines.append(
            f"{row.role:<8} {row.n_points:>3} {row.rmse_x_m:>9.3f} {row.rmse_y_m:>9.3f} {row.rmse_z_m:>9.3f} "
            f"{row.rmse_horizontal_m:>9.3f} {row.rmse_total_m:>9.3f} {row.rmse_image_px:>9.2f} "
            f"{row.rmse_marks_px:>9.2f} {row.range_m:>8.1f} {ratio:>11}"
        )
    lines.append(
        f"textbook (seed 3-3.7, Table 3-2): check points 1:{TEXTBOOK_RATIO_RANGE[0]:.0f} to "
        f"1:{TEXTBOOK_RATIO_RANGE[1]:.0f} at 75.6 m; Smith and Vericat (2015) mean "
        f"1:{SMITH_VERICAT_RATIO:.0f}"
    )
    return "\n".join(lines)
