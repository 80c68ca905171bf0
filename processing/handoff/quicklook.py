"""``sfap handoff --to colmap --run``: the field quick-look that proves the block reconstructs.

Stages (each reported through ``progress(stage)``): SIFT features on frames downscaled to
``max_image_size_px`` (:data:`DEFAULT_MAX_IMAGE_SIZE_PX`), matching of the footprint pairs only,
COLMAP's incremental mapping, georegistration of the largest model to the pose priors (a
seven-parameter similarity fitted on the camera centres, :mod:`processing.similarity`), then
the comparison with the coverage check's prediction: sparse points per cell of a grid beside
the check's view counts, and the cells the check called covered (two views or more) where
nothing reconstructed.

The verdict (:attr:`QuickLook.reconstructs`): the largest model registers at least
:data:`MIN_REGISTERED_RATIO` of the frames and no second model holds :data:`SPLIT_MODEL_FRAMES`
frames and :data:`SPLIT_MODEL_RATIO` of them or more (a block in several pieces has no common frame).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from pyproj import Transformer

from ..similarity import Similarity, SimilarityError, fit_similarity
from . import colmap_adapter as colmap
from .colmap_project import DATABASE, PAIRS
from .prepare import Prepared

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]

#: Longer side of the frames features are extracted on, pixels (speed against detail).
DEFAULT_MAX_IMAGE_SIZE_PX = 1000
#: SIFT features per frame.
DEFAULT_MAX_FEATURES = 2000
#: SIFT's first octave: -1 doubles the frame first (finer features, about three times the time),
#: 0 starts at the frame's own pixels (BENCHMARKS.md: the quick-look on seneca_half).
SIFT_FIRST_OCTAVES = (-1, 0)
DEFAULT_SIFT_FIRST_OCTAVE = -1
#: COLMAP's mapper: "incremental" (with the pose priors) or "global" (GLOMAP).
MAPPERS = ("incremental", "global")
DEFAULT_MAPPER = "incremental"
#: The block reconstructs when its largest model holds at least this share of the frames...
MIN_REGISTERED_RATIO = 0.5
#: ... and no other model holds this many frames and this share of them.
SPLIT_MODEL_FRAMES = 3
SPLIT_MODEL_RATIO = 0.1
#: Views the check must predict for a cell to count as covered (stereo needs two).
COVERED_VIEWS = 2


@dataclass(frozen=True, kw_only=True)
class Georegistration:
    similarity: Similarity
    used: tuple[str, ...]
    rejected: tuple[str, ...]
    residual_m: dict[str, tuple[float, float, float]]
    rmse_horizontal_m: float
    rmse_vertical_m: float
    rmse_total_m: float

    def as_dict(self) -> dict[str, Any]:
        return {
            "scale": self.similarity.scale,
            "rotation_angle_deg": self.similarity.rotation_angle_deg,
            "cameras_used": len(self.used),
            "cameras_rejected": list(self.rejected),
            "camera_rmse_horizontal_m": self.rmse_horizontal_m,
            "camera_rmse_vertical_m": self.rmse_vertical_m,
            "camera_rmse_total_m": self.rmse_total_m,
            "camera_residuals_m": {k: list(v) for k, v in self.residual_m.items()},
        }


@dataclass(frozen=True, kw_only=True)
class Comparison:
    """The check's prediction against the reconstruction on the check's grid (see module doc);
    the points are those of every model the pose priors could place, not only the largest."""

    cell_m: float
    extent_xy_m: tuple[float, float, float, float]
    view_count: NDArray[np.int32]
    point_count: NDArray[np.int32]
    covered_cells: int
    covered_empty_cells: int
    covered_empty_area_m2: float
    covered_empty_lonlat: list[tuple[float, float]]
    check_gap_area_m2: float
    check_passed: bool

    def as_dict(self) -> dict[str, Any]:
        return {
            "cell_m": self.cell_m,
            "covered_cells": self.covered_cells,
            "covered_but_empty_cells": self.covered_empty_cells,
            "covered_but_empty_area_m2": self.covered_empty_area_m2,
            "covered_but_empty_pct": 100.0 * self.covered_empty_cells / self.covered_cells
            if self.covered_cells
            else None,
            "covered_but_empty_centres_lonlat": [list(p) for p in self.covered_empty_lonlat],
            "check_gap_area_m2": self.check_gap_area_m2,
            "check_passed": self.check_passed,
        }


@dataclass(frozen=True, kw_only=True)
class QuickLook:
    n_frames: int
    models: tuple[colmap.ColmapModel, ...]
    registered: tuple[str, ...]
    unregistered: dict[str, int]  # name -> verified inlier matches
    keypoints: dict[str, int]
    pairs_matched: int
    timings_s: dict[str, float]
    georegistration: Georegistration | None
    comparison: Comparison | None
    max_image_size_px: int
    max_features: int = DEFAULT_MAX_FEATURES
    mapper: str = DEFAULT_MAPPER
    sift_first_octave: int = DEFAULT_SIFT_FIRST_OCTAVE
    messages: tuple[str, ...] = field(default_factory=tuple)
    frames_in_placed_models: tuple[str, ...] = ()

    @property
    def largest(self) -> colmap.ColmapModel | None:
        return self.models[0] if self.models else None

    @property
    def reconstructs(self) -> bool:
        if not self.models:
            return False
        if len(self.models[0].registered) < MIN_REGISTERED_RATIO * self.n_frames:
            return False
        return not self._split_models()

    def _split_models(self) -> list[colmap.ColmapModel]:
        least = max(SPLIT_MODEL_FRAMES, SPLIT_MODEL_RATIO * self.n_frames)
        return [m for m in self.models[1:] if len(m.registered) >= least]

    def verdict(self) -> str:
        """In words a crew can act on."""
        if not self.models:
            return (
                "the block did NOT reconstruct: no two frames could be tied together. Check that the frames "
                "overlap (sfap check), that they are sharp and not over- or under-exposed; over uniform "
                "ground (crops, water, snow) fly lower or with more overlap"
            )
        big = self.models[0]
        others = self._split_models()
        parts = []
        if len(big.registered) < MIN_REGISTERED_RATIO * self.n_frames:
            parts.append(
                f"only {len(big.registered)} of {self.n_frames} frames registered in the largest model"
            )
        if others:
            parts.append(
                f"the block fell apart into {1 + len(others)} models ("
                + ", ".join(str(len(m.registered)) for m in (big, *others))
                + " frames) with no frames in common"
            )
        worst = sorted(self.unregistered.items(), key=lambda kv: kv[1])[:8]
        if not parts:
            text = f"the block reconstructs: {len(big.registered)} of {self.n_frames} frames in one model"
            if self.unregistered:
                text += "; not registered: " + ", ".join(f"{n} ({m} matches)" for n, m in worst)
            return text
        return (
            "the block did NOT reconstruct: "
            + "; ".join(parts)
            + (
                ". Frames not registered (verified matches): " + ", ".join(f"{n} ({m})" for n, m in worst)
                if worst
                else ""
            )
            + ". Re-fly the gaps between the pieces with more overlap (sfap check --refly), or add "
            + "cross lines "
            "that tie the lines together; frames with few matches may be blurred or over uniform ground"
        )


def _georegister(prepared: Prepared, model: colmap.ColmapModel) -> Georegistration | None:
    block = prepared.block
    row = {n: k for k, n in enumerate(block.names)}
    names = [n for n in model.registered if block.has_position[row[n]]]
    if len(names) < 3:
        return None
    src = np.array([model.views[n].centre for n in names])
    dst = np.array([block.position_m[row[n]] for n in names])
    try:
        sim = fit_similarity(src, dst)
    except SimilarityError:
        return None
    res = dst - sim.apply(src)
    dist = np.linalg.norm(res, axis=1)
    sigma = np.array([math.hypot(block.sigma_xy_m[row[n]], block.sigma_z_m[row[n]]) for n in names])
    bad = dist > np.maximum(3.0 * np.median(dist), 3.0 * sigma)
    rejected: list[str] = []
    if bad.any() and (~bad).sum() >= 3:
        try:
            sim = fit_similarity(src[~bad], dst[~bad])
            rejected = [n for n, b in zip(names, bad, strict=True) if b]
        except SimilarityError:
            pass
        res = dst - sim.apply(src)
    used = [n for n in names if n not in rejected]
    keep = np.array([n not in rejected for n in names])
    r = res[keep]
    return Georegistration(
        similarity=sim,
        used=tuple(used),
        rejected=tuple(rejected),
        residual_m={n: (float(a), float(b), float(c)) for n, (a, b, c) in zip(names, res, strict=True)},
        rmse_horizontal_m=float(np.sqrt(np.mean(r[:, 0] ** 2 + r[:, 1] ** 2))),
        rmse_vertical_m=float(np.sqrt(np.mean(r[:, 2] ** 2))),
        rmse_total_m=float(np.sqrt(np.mean(np.sum(r**2, axis=1)))),
    )


def compare_with_check(prepared: Prepared, points_xyz: F64) -> Comparison | None:
    """The check's view counts (:func:`processing.check.run_check`) beside the sparse points'
    density on the same grid; ``points_xyz`` in the block's local frame."""
    from ..check import run_check

    block = prepared.block
    if not block.frames or prepared.ground is None or block.frame is None:
        return None
    frames = block.frames[0]
    result = run_check(frames, ground=prepared.ground, ground_description=prepared.ground_description)
    grid = result.grid
    to_check = Transformer.from_crs(block.frame.crs, result.frame.crs, always_xy=True)
    x, y = (
        to_check.transform(points_xyz[:, 0], points_xyz[:, 1])
        if len(points_xyz)
        else (np.zeros(0), np.zeros(0))
    )
    cols = np.floor((np.asarray(x) - grid.west_m) / grid.cell_m).astype(np.int64)
    rows = np.floor((grid.north_m - np.asarray(y)) / grid.cell_m).astype(np.int64)
    inside = (rows >= 0) & (rows < grid.rows) & (cols >= 0) & (cols < grid.cols)
    fine = np.zeros(grid.shape, dtype=np.int32)
    np.add.at(fine, (rows[inside], cols[inside]), 1)
    # Sparse points are sparse: compare on blocks of cells about a tenth of a footprint wide.
    fp_side = (
        float(np.sqrt(np.median(prepared.pairs.footprints[0].area_m2))) if prepared.pairs.footprints else 50.0
    )
    factor = max(1, round(fp_side / 10.0 / grid.cell_m))
    r2, c2 = math.ceil(grid.rows / factor), math.ceil(grid.cols / factor)

    def coarse(a: NDArray[Any], reduce: str) -> NDArray[Any]:
        pad = np.zeros((r2 * factor, c2 * factor), dtype=a.dtype)
        pad[: a.shape[0], : a.shape[1]] = a
        blocks = pad.reshape(r2, factor, c2, factor)
        return blocks.sum(axis=(1, 3)) if reduce == "sum" else blocks.min(axis=(1, 3))

    views = coarse(np.where(result.in_area, result.view_count, 0).astype(np.int32), "min")
    points = coarse(fine, "sum")
    covered = views >= COVERED_VIEWS
    empty = covered & (points == 0)
    cell = grid.cell_m * factor
    rr, cc = np.nonzero(empty)
    cx = grid.west_m + (cc + 0.5) * cell
    cy = grid.north_m - (rr + 0.5) * cell
    lon, lat = result.frame.to_lonlat(cx, cy) if len(cx) else (np.zeros(0), np.zeros(0))
    return Comparison(
        cell_m=cell,
        extent_xy_m=(grid.west_m, grid.north_m - r2 * cell, grid.west_m + c2 * cell, grid.north_m),
        view_count=views.astype(np.int32),
        point_count=points.astype(np.int32),
        covered_cells=int(covered.sum()),
        covered_empty_cells=int(empty.sum()),
        covered_empty_area_m2=float(empty.sum() * cell * cell),
        covered_empty_lonlat=[(float(a), float(b)) for a, b in zip(lon, lat, strict=True)],
        check_gap_area_m2=float(sum(g.area_m2 for g in result.gaps)),
        check_passed=bool(result.passed),
    )


def run_quicklook(
    prepared: Prepared,
    folder: Path,
    *,
    max_image_size_px: int = DEFAULT_MAX_IMAGE_SIZE_PX,
    max_features: int = DEFAULT_MAX_FEATURES,
    mapper: str = DEFAULT_MAPPER,
    sift_first_octave: int = DEFAULT_SIFT_FIRST_OCTAVE,
    progress: Callable[[str], None] | None = None,
) -> QuickLook:
    """Run the stages on the project in ``folder`` (written by
    :func:`~processing.handoff.colmap_project.write_colmap_project`); the models go to
    ``folder/sparse/N`` and the georegistered largest one to ``folder/sparse/georegistered``."""
    block = prepared.block

    def say(text: str) -> None:
        log.info(text)
        if progress is not None:
            progress(text)

    db = folder / DATABASE
    timings: dict[str, float] = {}
    t = time.perf_counter()
    say(f"features: SIFT on {len(block)} frames at {max_image_size_px} px")
    colmap.extract_features(
        db,
        block.image_dir,
        block.names,
        max_image_size_px=max_image_size_px,
        max_features=max_features,
        first_octave=sift_first_octave,
    )
    timings["features_s"] = time.perf_counter() - t
    keypoints = colmap.keypoint_counts(db)
    t = time.perf_counter()
    say(f"matching: {len(prepared.pairs)} pairs")
    colmap.match_pairs_file(db, folder / PAIRS)
    timings["matching_s"] = time.perf_counter() - t
    pairs_matched, inliers = colmap.verified_matches(db)
    t = time.perf_counter()
    if mapper == "global":
        say("mapping: global (GLOMAP)")
        models = colmap.global_mapping(db, block.image_dir, folder / "sparse")
    else:
        say("mapping: incremental")
        models = colmap.incremental_mapping(
            db, block.image_dir, folder / "sparse", use_priors=int(block.has_position.sum()) >= 3
        )
    timings["mapping_s"] = time.perf_counter() - t
    geo: Georegistration | None = None
    comparison: Comparison | None = None
    placed_frames: set[str] = set()
    messages: list[str] = []
    if models:
        say("georegistration: to the pose priors")
        t = time.perf_counter()
        geo = _georegister(prepared, models[0])
        if geo is not None:
            s = geo.similarity
            models[0] = colmap.transform_model(models[0], s.scale, s.rotation, s.translation_m)
            colmap.write_model(models[0], folder / "sparse" / "georegistered")
            sigma = float(np.median(np.hypot(block.sigma_xy_m, block.sigma_z_m)[block.has_position]))
            if geo.rmse_total_m > 3.0 * sigma:
                messages.append(
                    f"the largest model disagrees with the GPS positions by {geo.rmse_total_m:.1f} "
                    "m RMSE while the "
                    f"positions are good to about {sigma:.1f} m: its geometry is suspect (frames "
                    "matched to the "
                    "wrong place); do not trust its shape"
                )
            # What reconstructed: the points of every model the priors can place.
            placed = [models[0].points_xyz]
            for k in range(1, len(models)):
                g = _georegister(prepared, models[k])
                if g is not None:
                    placed.append(g.similarity.apply(models[k].points_xyz))
                    placed_frames.update(models[k].registered)
            placed_frames.update(models[0].registered)
            say("comparison: the check's view counts against the sparse points")
            comparison = compare_with_check(prepared, np.concatenate(placed))
        else:
            messages.append(
                "the model is not georegistered: fewer than three registered frames have a position (or they "
                "lie on a line); it stays in COLMAP's arbitrary frame"
            )
        timings["georegistration_s"] = time.perf_counter() - t
    registered = models[0].registered if models else ()
    unregistered = {n: inliers.get(n, 0) for n in block.names if n not in registered}
    return QuickLook(
        n_frames=len(block),
        models=tuple(models),
        registered=registered,
        unregistered=unregistered,
        keypoints=keypoints,
        pairs_matched=pairs_matched,
        timings_s=timings,
        georegistration=geo,
        comparison=comparison,
        max_image_size_px=max_image_size_px,
        max_features=max_features,
        mapper=mapper,
        sift_first_octave=sift_first_octave,
        messages=tuple(messages),
        frames_in_placed_models=tuple(sorted(placed_frames)),
    )
