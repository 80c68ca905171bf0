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
from .similarity import Similarity, SimilarityError, fit_horizontal_similarity, fit_similarity

F64 = NDArray[np.float64]

#: The textbook's figures (seed 3-3.7; REFERENCES.md): its nine-frame block at 75.6 m reached
#: check-point RMSE:range of about 1:950 to 1:1350; Smith and Vericat's mean of 50 surveys 1:639.
TEXTBOOK_RATIO_RANGE = (950.0, 1350.0)
SMITH_VERICAT_RATIO = 639.0

#: Control residuals larger than this many ground pixels are far beyond what marking errors
#: explain (careful marks: 1-3 px): the report says the surveyed coordinates or the model are off.
SUSPECT_CONTROL_RMSE_PX = 50.0

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
class DroppedMark:
    """An observation left out of a point's triangulation: it lies ``residual_px`` from where
    the point's other marks meet (a wrong target, a typo)."""

    point: str
    image: str
    residual_px: float

    def warning(self) -> str:
        return (
            f"{self.point}: its mark in {self.image} is {self.residual_px:.0f} px from where its other marks "
            f"meet (more than {MAX_TRIANGULATION_PX:g} px): left out; re-mark it"
        )


@dataclass(frozen=True, kw_only=True)
class Triangulated:
    """A point's model position and the frames it was seen in; ``None`` when fewer than two."""

    name: str
    model_xyz: F64 | None
    used_images: tuple[str, ...]
    missing_images: tuple[str, ...]
    reason: str = ""
    marks_rmse_px: float = 0.0
    dropped: tuple[DroppedMark, ...] = ()
    widest_angle_deg: float = 0.0


def _meet(used: Sequence[Observation], views: Mapping[str, View]) -> tuple[F64, list[float], float]:
    """The point ``used`` marks meet at, each mark's reprojection error (px), widest ray angle (deg)."""
    origins = np.array([views[o.image].centre for o in used])
    directions = np.vstack([views[o.image].rays(np.array([[o.x_px, o.y_px]])) for o in used])
    cos = np.clip(directions @ directions.T, -1.0, 1.0)
    widest_deg = float(np.degrees(np.arccos(cos.min())))
    xyz = intersect_rays(origins, directions) if widest_deg > 0.0 else origins[0]
    errors = [
        math.hypot(*(views[o.image].project(xyz[None, :])[0] - np.array([o.x_px, o.y_px]))) for o in used
    ]
    return xyz, errors, widest_deg


def triangulate(
    name: str,
    observations: Sequence[Observation],
    views: Mapping[str, View],
    *,
    max_error_px: float = MAX_TRIANGULATION_PX,
) -> Triangulated:
    """The point seen by ``observations``, from the views of the registered frames; None (with
    the reason) when it is seen in fewer than two, its rays are nearly parallel, or its marks
    disagree by more than ``max_error_px``.

    A mark that disagrees with the others is found by leaving each out in turn: when the point
    has three marks or more and the others meet within
    ``max_error_px`` of their own marks while the one left out lies farther, that one is dropped
    (listed in ``dropped``, never silently) and the point is kept. Two marks that disagree cannot
    say which one is wrong: the point is not used."""
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
    dropped: list[DroppedMark] = []
    xyz, errors, widest_deg = _meet(used, views)
    while max(errors) > max_error_px and len(used) >= 3:
        best: tuple[float, int, float] | None = None  # (worst of the rest, index left out, its error)
        for k in range(len(used)):
            rest = used[:k] + used[k + 1 :]
            xyz_k, err_k, _ = _meet(rest, views)
            out_k = views[used[k].image].project(xyz_k[None, :])[0] - np.array([used[k].x_px, used[k].y_px])
            if best is None or max(err_k) < best[0]:
                best = (max(err_k), k, math.hypot(*out_k))
        assert best is not None
        if best[0] > max_error_px or best[2] <= max_error_px:
            break
        dropped.append(DroppedMark(point=name, image=used[best[1]].image, residual_px=best[2]))
        used = used[: best[1]] + used[best[1] + 1 :]
        xyz, errors, widest_deg = _meet(used, views)
    images = tuple(o.image for o in used)
    # Nearly parallel rays (the same spot from one place) fix no depth.
    if widest_deg < 0.5:
        return Triangulated(
            name=name,
            model_xyz=None,
            used_images=images,
            missing_images=missing,
            reason=f"its rays meet at {widest_deg:.2f} deg at most: no depth",
            dropped=tuple(dropped),
            widest_angle_deg=widest_deg,
        )
    worst = int(np.argmax(errors))
    if errors[worst] > max_error_px:
        return Triangulated(
            name=name,
            model_xyz=None,
            used_images=images,
            missing_images=missing,
            reason=(
                f"its observations disagree: the point they meet at is {errors[worst]:.0f} px from its mark "
                f"in {used[worst].image} (more than {max_error_px:g} px): re-mark it"
            ),
            dropped=tuple(dropped),
            widest_angle_deg=widest_deg,
        )
    return Triangulated(
        name=name,
        model_xyz=xyz,
        used_images=images,
        missing_images=missing,
        marks_rmse_px=float(np.sqrt(np.mean(np.square(errors)))),
        dropped=tuple(dropped),
        widest_angle_deg=widest_deg,
    )


@dataclass(frozen=True, kw_only=True)
class PointResidual:
    """Surveyed minus placed position; ``dz_m`` is None when the surveyed heights are unknown."""

    name: str
    role: str  # "control" | "check"
    dx_m: float
    dy_m: float
    dz_m: float | None
    image_rmse_px: float
    n_images: int
    marks_rmse_px: float = 0.0
    widest_angle_deg: float = 0.0
    #: Control points: the horizontal miss when the fit is made without this point (None for
    #: check points, and with only three control points).
    left_out_horizontal_m: float | None = None


@dataclass(frozen=True, kw_only=True)
class RmseRow:
    """One line of the Table 3-2 layout: RMSE of a set of points (Z and total None when the
    surveyed heights are unknown: then RMSE:range is taken on the horizontal RMSE)."""

    role: str
    n_points: int
    rmse_x_m: float
    rmse_y_m: float
    rmse_z_m: float | None
    rmse_horizontal_m: float
    rmse_total_m: float | None
    rmse_image_px: float
    range_m: float
    rmse_marks_px: float = 0.0

    @property
    def ratio_basis(self) -> str:
        return "total" if self.rmse_total_m is not None else "horizontal"

    @property
    def ratio(self) -> float:
        """The range over the total RMSE (horizontal when Z is not measured): the N of 1:N."""
        rmse = self.rmse_total_m if self.rmse_total_m is not None else self.rmse_horizontal_m
        return self.range_m / rmse if rmse > 0 else math.inf

    def as_dict(self) -> dict[str, float | int | str | None]:
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
            "rmse_to_range_on": self.ratio_basis,
        }


def _weighted_px(values: Sequence[float], counts: NDArray[np.int64]) -> float:
    v = np.asarray(values, dtype=np.float64)
    return float(np.sqrt(np.sum(v**2 * counts) / max(int(counts.sum()), 1)))


def rmse_row(role: str, residuals: Sequence[PointResidual], range_m: float) -> RmseRow | None:
    if not residuals:
        return None
    d = np.array([[r.dx_m, r.dy_m] for r in residuals])
    rx, ry = np.sqrt(np.mean(d**2, axis=0))
    dz = [r.dz_m for r in residuals]
    rz = None if any(z is None for z in dz) else float(np.sqrt(np.mean(np.square(np.asarray(dz, float)))))
    n_img = np.array([r.n_images for r in residuals], dtype=np.int64)
    return RmseRow(
        role=role,
        n_points=len(residuals),
        rmse_x_m=float(rx),
        rmse_y_m=float(ry),
        rmse_z_m=rz,
        rmse_horizontal_m=float(math.hypot(rx, ry)),
        rmse_total_m=None if rz is None else float(math.sqrt(rx * rx + ry * ry + rz * rz)),
        rmse_image_px=_weighted_px([r.image_rmse_px for r in residuals], n_img),
        rmse_marks_px=_weighted_px([r.marks_rmse_px for r in residuals], n_img),
        range_m=range_m,
    )


#: What the fit is when the surveyed heights are known.
SEVEN_PARAMETER_FIT = "seven-parameter similarity (scale, rotation, translation) on X, Y and Z"


@dataclass(frozen=True, kw_only=True)
class AccuracyResult:
    """The similarity (model -> ground frame), per-point residuals and the two RMSE rows.

    ``heights_known`` False: the fit used the horizontal positions only
    (:func:`~processing.similarity.fit_horizontal_similarity`) and Z is not measured; the
    placed heights are then relative to the control points' mean."""

    similarity: Similarity
    control: RmseRow
    check: RmseRow | None
    residuals: tuple[PointResidual, ...]
    unused: tuple[Triangulated, ...]
    ground_xyz_m: dict[str, F64] = field(default_factory=dict)
    placed_xyz_m: dict[str, F64] = field(default_factory=dict)
    heights_known: bool = True
    fit: str = SEVEN_PARAMETER_FIT
    dropped_marks: tuple[DroppedMark, ...] = ()
    ground_pixel_m: float = 0.0

    @property
    def warnings(self) -> tuple[str, ...]:
        out = [d.warning() for d in self.dropped_marks]
        limit = SUSPECT_CONTROL_RMSE_PX * self.ground_pixel_m
        if self.ground_pixel_m > 0 and self.control.rmse_horizontal_m > limit:
            out.append(
                "the control points miss their surveyed positions by "
                f"{self.control.rmse_horizontal_m:.2f} m RMSE horizontally, "
                f"{self.control.rmse_horizontal_m / self.ground_pixel_m:.0f} ground pixels "
                f"({1000 * self.ground_pixel_m:.1f} mm), while their marks agree to "
                f"{self.control.rmse_marks_px:.2f} px: marking errors do not explain it. The surveyed "
                "coordinates are less accurate than the model (a hand-held GPS is good to metres), a target "
                "is mis-identified, or the model is distorted: check the survey before trusting these figures"
            )
        return tuple(out)

    def as_dict(self) -> dict[str, object]:
        return {
            "similarity": {
                "scale": self.similarity.scale,
                "rotation_angle_deg": self.similarity.rotation_angle_deg,
                "translation_m": self.similarity.translation_m.tolist(),
            },
            "fit": self.fit,
            "heights_known": self.heights_known,
            "control": self.control.as_dict(),
            "check": None if self.check is None else self.check.as_dict(),
            "points": [vars(r) for r in self.residuals],
            "unused_points": [{"name": t.name, "reason": t.reason} for t in self.unused],
            "dropped_marks": [vars(d) for d in self.dropped_marks],
            "ground_pixel_m": self.ground_pixel_m,
            "warnings": list(self.warnings),
            "textbook": {
                "check_rmse_to_range": [
                    f"1:{TEXTBOOK_RATIO_RANGE[0]:.0f}",
                    f"1:{TEXTBOOK_RATIO_RANGE[1]:.0f}",
                ],
                "smith_vericat_mean": f"1:{SMITH_VERICAT_RATIO:.0f}",
            },
        }


def ground_pixel(view: View, point: F64 | None) -> float:
    """The size of one pixel at ``point`` (model units): its distance from the camera times the
    angle between the rays of neighbouring pixels where it is seen."""
    assert point is not None
    px = view.project(np.asarray(point, dtype=np.float64)[None, :])[0]
    rays = view.rays(np.vstack([px, px + np.array([1.0, 0.0])]))
    angle = math.acos(float(np.clip(rays[0] @ rays[1], -1.0, 1.0)))
    return float(np.linalg.norm(np.asarray(point) - view.centre)) * angle


def heights_unknown(ground_xyz_m: Mapping[str, F64]) -> bool:
    """Every surveyed elevation is exactly 0.0: OpenDroneMap's gcp_list.txt convention for
    control measured in plan only (the heights are unknown, not zero)."""
    return all(float(np.asarray(v)[2]) == 0.0 for v in ground_xyz_m.values())


def assess_accuracy(
    *,
    ground_xyz_m: Mapping[str, F64],
    observations: Sequence[Observation],
    views: Mapping[str, View],
    control: Sequence[str],
    check: Sequence[str],
    heights_known: bool | None = None,
) -> AccuracyResult:
    """Triangulate, fit the similarity on ``control``, and measure control and check residuals.

    ``ground_xyz_m``: each point's surveyed position in a metric ground frame (x east, y north,
    z up); ``views``: the registered frames by image name. ``heights_known`` (default: unless
    every elevation is 0.0, :func:`heights_unknown`): False fits the horizontal positions only
    and leaves Z unmeasured. Raises AccuracyError when fewer than three control points can be
    triangulated."""
    names = (*control, *check)
    if heights_known is None:
        heights_known = not heights_unknown({n: ground_xyz_m[n] for n in names})
    by_point: dict[str, list[Observation]] = {}
    for o in observations:
        by_point.setdefault(o.point, []).append(o)
    tri = {n: triangulate(n, by_point.get(n, []), views) for n in names}
    unused = tuple(t for t in tri.values() if t.model_xyz is None)
    dropped = tuple(d for t in tri.values() for d in t.dropped)
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
    centres_model = np.array([v.centre for v in views.values()])

    def place(src: F64, dst: F64) -> tuple[Similarity, str]:
        if heights_known:
            return fit_similarity(src, dst), SEVEN_PARAMETER_FIT
        horizontal = fit_horizontal_similarity(
            src, dst[:, :2], up_hint=centres_model.mean(axis=0) - src.mean(axis=0), datum_z=0.0
        )
        return horizontal.similarity, horizontal.describe()

    sim, fit = place(src, dst)
    # Each control point against the fit made without it (four points or more): a point the
    # others disagree with stands out (a survey blunder, a wrong target).
    left_out_m: dict[str, float] = {}
    if len(usable_control) > MIN_CONTROL_POINTS:
        for k, n in enumerate(usable_control):
            keep = np.arange(len(usable_control)) != k
            try:
                other, _ = place(src[keep], dst[keep])
            except SimilarityError:
                continue
            left_out_m[n] = float(np.linalg.norm((dst[k] - other.apply(src[k]))[:2]))
    inverse = sim.inverse()
    residuals: list[PointResidual] = []
    placed: dict[str, F64] = {}
    pixel_m: list[float] = []
    for n in usable_control:
        for image in tri[n].used_images:
            pixel_m.append(sim.scale * ground_pixel(views[image], tri[n].model_xyz))
    for role, role_names in (("control", control), ("check", check)):
        for n in role_names:
            t = tri[n]
            if t.model_xyz is None:
                continue
            xyz = sim.apply(t.model_xyz)
            placed[n] = xyz
            truth = np.asarray(ground_xyz_m[n], dtype=np.float64).copy()
            if not heights_known:
                truth[2] = xyz[2]  # no surveyed height: the image residual is the horizontal error's
            d = truth - xyz
            model_truth = inverse.apply(truth)
            errs = [
                math.hypot(*(views[o.image].project(model_truth[None, :])[0] - np.array([o.x_px, o.y_px])))
                for o in by_point[n]
                if o.image in t.used_images
            ]
            residuals.append(
                PointResidual(
                    name=n,
                    role=role,
                    dx_m=float(d[0]),
                    dy_m=float(d[1]),
                    dz_m=float(d[2]) if heights_known else None,
                    image_rmse_px=float(np.sqrt(np.mean(np.square(errs)))),
                    marks_rmse_px=t.marks_rmse_px,
                    n_images=len(errs),
                    widest_angle_deg=t.widest_angle_deg,
                    left_out_horizontal_m=left_out_m.get(n),
                )
            )
    # Range: mean height of the registered cameras above the mean surveyed point (ground frame;
    # heights unknown: above the control points' mean, which the fit put at the 0.0 datum).
    centres = sim.apply(centres_model)
    ground_z = float(np.mean([ground_xyz_m[n][2] for n in names]))
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
        heights_known=heights_known,
        fit=fit,
        dropped_marks=dropped,
        ground_pixel_m=float(np.median(pixel_m)),
    )


def _m(value: float | None, width: int = 9) -> str:
    return f"{'n/a':>{width}}" if value is None else f"{value:>{width}.3f}"


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
            f"{row.role:<8} {row.n_points:>3} {row.rmse_x_m:>9.3f} {row.rmse_y_m:>9.3f} {_m(row.rmse_z_m)} "
            f"{row.rmse_horizontal_m:>9.3f} {_m(row.rmse_total_m)} {row.rmse_image_px:>9.2f} "
            f"{row.rmse_marks_px:>9.2f} {row.range_m:>8.1f} {ratio:>11}"
        )
    lines.append(
        f"textbook (seed 3-3.7, Table 3-2): check points 1:{TEXTBOOK_RATIO_RANGE[0]:.0f} to "
        f"1:{TEXTBOOK_RATIO_RANGE[1]:.0f} at 75.6 m; Smith and Vericat (2015) mean "
        f"1:{SMITH_VERICAT_RATIO:.0f}"
    )
    lines.append(f"fit: {result.fit}")
    lines.append(f"a pixel on the ground at the control points: {1000 * result.ground_pixel_m:.1f} mm")
    if not result.heights_known:
        lines.append(
            "Z: not measurable (the surveyed heights are unknown, all 0.0); RMSE:range on the horizontal RMSE"
        )
    return "\n".join(lines)
