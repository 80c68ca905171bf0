"""What the pixels say: neighbouring frames matched, and the overlap, image scale and height they
show, beside what the tags say.

The tags can be wrong (a drifting GPS altitude, a camera known only roughly, a fixed wing's
attitude); the pixels are not. :func:`measure_pixels` matches every pair of neighbouring frames
(consecutive frames of a line and a frame with the nearest frame of each neighbouring line:
:func:`processing.flight_lines.pair_kinds`) with SIFT on downscaled frames and COLMAP's matcher
and two-view verification (:mod:`processing.pixel_colmap`), then per pair that matches:

- the affine map from frame a to frame b, fitted by least squares to the verified matches
  (near-nadir frames of flat ground; the verification has already removed the outliers);
- the overlap: frame a's outline mapped into frame b, intersected with frame b, as a share of
  the frame (the footprints' overlap, measured without the tags);
- the image shift: how far the centre of frame a moved in frame b, in pixels; with the GPS
  baseline between the two exposures it gives the ground distance of a pixel (image scale), so
  the GSD and, with the focal length in pixels, the height above ground; or, with the tagged
  height, the focal length: the camera's check.

The share of neighbours that match at all and the connected parts of the graph of matched pairs
predict the reconstruction better than the tagged endlap: a frame that matches none of its
neighbours is not registered, and parts that no matched pair ties together become separate
models.
"""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray

from .distribution import Distribution
from .errors import ProcessingError
from .frames import Frames

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]

#: Verified inlier matches a pair needs to count as matched: COLMAP's two-view verification
#: already requires 15 (TwoViewGeometryOptions.min_num_inliers); its incremental mapper registers
#: a frame on 30 or more (IncrementalMapperOptions.abs_pose_min_num_inliers, as COLMAP 3.x-4.x).
MIN_INLIERS = 30
#: The longer side of the frames as matched, px: features at this size tie frames a few seconds
#: apart; the budget below holds at it on two cores.
DEFAULT_MATCH_SIZE_PX = 640
#: SIFT features per frame (COLMAP's default is 8192; 2000 is plenty for pairs of neighbours).
DEFAULT_MAX_FEATURES = 2000
#: Pairs whose GPS baseline is shorter than this carry no usable scale (GPS noise of a metre
#: would be a tenth of it), m; and image shifts shorter than this share of the frame's shorter
#: side are dominated by the attitude's jitter.
MIN_SCALE_BASE_M = 5.0
MIN_SCALE_SHIFT_RATIO = 0.05
#: The measured and the tagged image scale agree within this share (beyond it the report flags
#: the camera or the heights): a tag-derived GSD is good to a few per cent when the camera and
#: the heights are right; the median of a block's pixel scales is good to about as much (B/H and
#: attitude jitter of a fixed wing: seneca_half's pairs scatter 10-15 %, their median far less).
SCALE_AGREEMENT_RATIO = 0.15
#: Frames smaller than this on their longer side are not matched (a simulator's thumbnails; SIFT
#: needs a few octaves of image), px.
MIN_MATCH_SIZE_PX = 256
#: Frames with fewer SIFT features than this (median) carry no texture to judge by: the verdict
#: then rests on the tags alone, and the report says so.
MIN_KEYPOINTS = 100
#: The quick reconstruction's budget: pairs a frame is matched in at most (the neighbour pairs
#: are always matched; BENCHMARKS.md measures the cap on seneca_half and garfield_rgb).
MAX_MAPPER_PAIRS_PER_FRAME = 8


@dataclass(frozen=True, kw_only=True)
class PixelOptions:
    """How to match: the frames' folder, their size as matched, the features per frame, the
    threads, the log file for COLMAP's own log (None: the terminal's standard error), and whether
    to run COLMAP's incremental mapper on the matches (a quick reconstruction of the block)."""

    image_dir: Path
    max_image_size_px: int = DEFAULT_MATCH_SIZE_PX
    max_features: int = DEFAULT_MAX_FEATURES
    num_threads: int = 0
    log_path: Path | None = None
    reconstruct: bool = True
    max_pairs_per_frame: int = MAX_MAPPER_PAIRS_PER_FRAME

    def __post_init__(self) -> None:
        if not (64 <= self.max_image_size_px <= 8192):
            raise ProcessingError(
                f"match size {self.max_image_size_px} px is outside 64-8192 px; give e.g. 640"
            )
        if not (100 <= self.max_features <= 100_000):
            raise ProcessingError(f"max_features = {self.max_features} is outside 100-100000")
        if self.max_pairs_per_frame < 1:
            raise ProcessingError(f"max_pairs_per_frame = {self.max_pairs_per_frame}: give at least 1")


@dataclass(frozen=True, kw_only=True)
class PixelFigures:
    """What the pixels measured.

    ``pair_index``: (M, 2) frame rows of the neighbour pairs tried; ``pair_along``: which are
    consecutive frames of a line (the others: across lines); ``inliers``: verified matches per
    pair; ``matched``: at least :data:`MIN_INLIERS`; ``overlap_pct``: per pair, NaN where it did
    not match; ``gsd_cm``: per along-line pair with a usable baseline, NaN elsewhere;
    ``component``: per frame, the connected part of the matched graph it belongs to (0 the
    largest); ``seconds``: how long the matching took; ``mapper_pair_count``: the pairs matched
    for the quick reconstruction, the neighbour pairs included (:func:`budget_pairs`).
    """

    pair_index: NDArray[np.int64]
    pair_along: NDArray[np.bool_]
    inliers: NDArray[np.int64]
    matched: NDArray[np.bool_]
    overlap_pct: F64
    shift_px: F64
    gsd_cm: F64
    component: NDArray[np.int64]
    frame_count: int
    match_size_px: int
    seconds: float
    tagged_gsd_cm: float | None
    focal_px: float
    min_inliers: int = MIN_INLIERS
    models: tuple[tuple[int, ...], ...] | None = None
    keypoints_median: float = 0.0
    mapper_pair_count: int = 0

    @property
    def conclusive(self) -> bool:
        """The frames carry enough features for the pixels to judge the block."""
        return self.keypoints_median >= MIN_KEYPOINTS

    @property
    def registered_pct(self) -> float | None:
        """Share of the frames the quick reconstruction's largest model registers (None: not run)."""
        if self.models is None or not self.frame_count:
            return None
        return 100.0 * (len(self.models[0]) if self.models else 0) / self.frame_count

    @property
    def registered_any(self) -> int | None:
        """Frames registered in any model (None: not run)."""
        if self.models is None:
            return None
        return len({k for model in self.models for k in model})

    @property
    def along_matched_pct(self) -> float | None:
        n = int(self.pair_along.sum())
        return 100.0 * float((self.matched & self.pair_along).sum()) / n if n else None

    @property
    def across_matched_pct(self) -> float | None:
        n = int((~self.pair_along).sum())
        return 100.0 * float((self.matched & ~self.pair_along).sum()) / n if n else None

    @property
    def matched_pct(self) -> float | None:
        n = len(self.matched)
        return 100.0 * float(self.matched.sum()) / n if n else None

    @property
    def isolated(self) -> NDArray[np.int64]:
        """Frames that match none of their neighbours."""
        tied = np.zeros(self.frame_count, dtype=bool)
        tied[self.pair_index[self.matched].ravel()] = True
        return np.flatnonzero(~tied).astype(np.int64)

    @property
    def component_count(self) -> int:
        return int(self.component.max()) + 1 if self.component.size else 0

    @property
    def largest_component_pct(self) -> float:
        if not self.frame_count:
            return 0.0
        return 100.0 * float((self.component == 0).sum()) / self.frame_count

    @property
    def forward_overlap_pct(self) -> Distribution | None:
        return Distribution.of(self.overlap_pct[self.pair_along & self.matched])

    @property
    def side_overlap_pct(self) -> Distribution | None:
        return Distribution.of(self.overlap_pct[~self.pair_along & self.matched])

    @property
    def measured_gsd_cm(self) -> Distribution | None:
        return Distribution.of(self.gsd_cm[np.isfinite(self.gsd_cm)])

    @property
    def measured_height_m(self) -> float | None:
        """Height above ground from the measured GSD and the camera's focal length in pixels."""
        gsd = self.measured_gsd_cm
        return gsd.median / 100.0 * self.focal_px if gsd is not None else None

    @property
    def scale_ratio(self) -> float | None:
        """Measured over tagged GSD (1: they agree)."""
        gsd = self.measured_gsd_cm
        if gsd is None or self.tagged_gsd_cm is None or not self.tagged_gsd_cm > 0:
            return None
        return gsd.median / self.tagged_gsd_cm

    def as_dict(self) -> dict[str, Any]:
        fwd, side, gsd = self.forward_overlap_pct, self.side_overlap_pct, self.measured_gsd_cm
        return {
            "match_size_px": self.match_size_px,
            "min_inliers": MIN_INLIERS,
            "seconds": self.seconds,
            "seconds_per_frame": self.seconds / max(self.frame_count, 1),
            "keypoints_per_frame_median": self.keypoints_median,
            "conclusive": self.conclusive,
            "pairs_tried": len(self.matched),
            "pairs_matched": int(self.matched.sum()),
            "along_line_matched_pct": self.along_matched_pct,
            "across_lines_matched_pct": self.across_matched_pct,
            "isolated_frames": int(self.isolated.size),
            "connected_parts": self.component_count,
            "largest_part_frames_pct": self.largest_component_pct,
            "forward_overlap_pct": fwd.as_dict() if fwd else None,
            "side_overlap_pct": side.as_dict() if side else None,
            "gsd_cm": gsd.as_dict() if gsd else None,
            "tagged_gsd_cm": self.tagged_gsd_cm,
            "height_agl_m": self.measured_height_m,
            "focal_px": self.focal_px,
            "scale_ratio_measured_to_tagged": self.scale_ratio,
            "quick_reconstruction": (
                {
                    "pairs_matched": self.mapper_pair_count,
                    "models": [len(m) for m in self.models],
                    "largest_model_frames_pct": self.registered_pct,
                    "frames_registered": self.registered_any,
                }
                if self.models is not None
                else None
            ),
        }


def affine_fit(xy_a: F64, xy_b: F64, *, iterations: int = 4) -> F64:
    """The 2 x 3 affine map taking ``xy_a`` to ``xy_b``: least squares, refitted ``iterations``
    times without the points whose residual exceeds 3 times the median residual (at least 1 px).
    The two-view verification keeps matches that agree with the epipolar geometry, and along a
    straight line the epipolar lines run with the motion: a wrong match that slid along one stays
    in; this trims it."""
    keep = np.ones(len(xy_a), dtype=bool)
    solution: NDArray[np.floating[Any]] = np.zeros((3, 2))
    for _ in range(max(iterations, 0) + 1):
        design = np.column_stack([xy_a[keep], np.ones(int(keep.sum()))])
        solution, *_ = np.linalg.lstsq(design, xy_b[keep], rcond=None)
        residual = np.hypot(*(np.column_stack([xy_a, np.ones(len(xy_a))]) @ solution - xy_b).T)
        limit = max(3.0 * float(np.median(residual[keep])), 1.0)
        new_keep = residual <= limit
        if new_keep.sum() < 3 or (new_keep == keep).all():
            break
        keep = new_keep
    return np.asarray(solution.T, dtype=np.float64)


def mapped_overlap_pct(affine: F64, size_a: tuple[int, int], size_b: tuple[int, int]) -> float:
    """Share of frame b (percent) that frame a's outline covers once mapped by ``affine``."""
    wa, ha = size_a
    wb, hb = size_b
    corners = np.array([[0.0, 0.0], [wa, 0.0], [wa, ha], [0.0, ha]])
    mapped = corners @ affine[:, :2].T + affine[:, 2]
    outline = shapely.Polygon(mapped)
    if not outline.is_valid or outline.area <= 0:
        return 0.0
    frame_b = shapely.box(0.0, 0.0, float(wb), float(hb))
    return float(100.0 * outline.intersection(frame_b).area / frame_b.area)


def components(frame_count: int, pairs: NDArray[np.int64]) -> NDArray[np.int64]:
    """Connected parts of the graph whose edges are ``pairs``, numbered by size (0: the largest;
    ties by the lowest frame)."""
    parent = list(range(frame_count))

    def root(k: int) -> int:
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    for i, j in pairs.tolist():
        ri, rj = root(i), root(j)
        if ri != rj:
            parent[max(ri, rj)] = min(ri, rj)
    roots = np.array([root(k) for k in range(frame_count)], dtype=np.int64)
    labels, inverse, counts = np.unique(roots, return_inverse=True, return_counts=True)
    order = sorted(range(len(labels)), key=lambda c: (-int(counts[c]), int(labels[c])))
    rank = np.empty(len(labels), dtype=np.int64)
    rank[order] = np.arange(len(labels))
    return rank[inverse].astype(np.int64)


def measure_pixels(
    frames: Frames,
    *,
    pair_index: NDArray[np.int64],
    pair_along: NDArray[np.bool_],
    camera_xyz_m: F64,
    tagged_gsd_cm: float | None,
    options: PixelOptions,
    mapper_pairs: NDArray[np.int64] | None = None,
) -> PixelFigures:
    """Match the neighbour pairs ``pair_index`` (rows of ``frames``; ``pair_along``: consecutive
    frames of a line) in ``options.image_dir`` and measure them (module docstring).
    ``camera_xyz_m``: the frames' positions in metres (the check's local frame), for the GPS
    baselines and the quick reconstruction's pose priors; ``tagged_gsd_cm``: the block's median
    GSD from the tags, to compare; ``mapper_pairs``: the pairs the quick reconstruction may match
    besides the neighbour pairs (every pair whose footprints overlap), of which it matches those
    :func:`budget_pairs` chooses (``options.max_pairs_per_frame``: neighbour pairs alone leave
    too few points seen three times for the mapper)."""
    from .pixel_colmap import match_pairs

    start = time.monotonic()
    names = list(frames.name)
    pairs = [(names[int(i)], names[int(j)]) for i, j in pair_index.tolist()]
    asked = set(pairs) | {(b, a) for a, b in pairs}
    for_mapper = (
        budget_pairs(
            pair_index, pair_along, mapper_pairs, camera_xyz_m, max_per_frame=options.max_pairs_per_frame
        )
        if options.reconstruct
        else np.zeros((0, 2), dtype=np.int64)
    )
    extra = [
        (names[int(i)], names[int(j)])
        for i, j in for_mapper.tolist()
        if (names[int(i)], names[int(j)]) not in asked
    ]
    every = np.concatenate([pair_index.ravel(), for_mapper.ravel()])
    used = sorted({int(k) for k in every})
    threads = options.num_threads or min(os.cpu_count() or 1, 4)
    run = match_pairs(
        options.image_dir,
        [names[k] for k in used],
        [*pairs, *dict.fromkeys(extra)],
        max_image_size_px=options.max_image_size_px,
        max_features=options.max_features,
        num_threads=threads,
        log_path=options.log_path,
        map_models=options.reconstruct,
        # No pose priors: with them COLMAP 4's mapper forces garfield_rgb's fragments into one
        # model (20 of 28 frames and counting, at 10 s a bundle adjustment) that its own
        # reconstruction without priors does not find (13 of 28), and takes many minutes.
        priors_m=None,
    )
    run_pairs = run.pairs[: len(pairs)]
    camera = frames.camera
    m = len(pairs)
    inliers = np.array([p.count for p in run_pairs], dtype=np.int64).reshape(m)
    matched = inliers >= MIN_INLIERS
    overlap = np.full(m, np.nan)
    shift = np.full(m, np.nan)
    gsd = np.full(m, np.nan)
    focal_px = camera.focal_length_mm / camera.pixel_pitch_x_mm
    for k, pair in enumerate(run_pairs):
        if not matched[k]:
            continue
        size_a, size_b = run.size_px[pair.a], run.size_px[pair.b]
        affine = affine_fit(pair.xy_a, pair.xy_b)
        overlap[k] = mapped_overlap_pct(affine, size_a, size_b)
        centre = np.array([size_a[0] / 2.0, size_a[1] / 2.0])
        moved = affine[:, :2] @ centre + affine[:, 2]
        # In the camera's pixels (the image may have been resized since the camera was read).
        to_camera = camera.image_width_px / size_a[0]
        shift[k] = float(np.hypot(*(moved - centre))) * to_camera
        i, j = pair_index[k]
        base = float(np.hypot(*(camera_xyz_m[i, :2] - camera_xyz_m[j, :2])))
        short_px = min(camera.image_width_px, camera.image_height_px)
        if pair_along[k] and base >= MIN_SCALE_BASE_M and shift[k] >= MIN_SCALE_SHIFT_RATIO * short_px:
            gsd[k] = 100.0 * base / shift[k]
    component = components(len(frames), pair_index[matched])
    # Frames not in any pair tried are their own parts (components() numbers them too).
    seconds = time.monotonic() - start
    log.info(
        "matched %d of %d neighbour pairs of %d frames in %.1f s (%.2f s per frame)",
        int(matched.sum()),
        m,
        len(used),
        seconds,
        seconds / max(len(used), 1),
    )
    row_of = {name: k for k, name in enumerate(names)}
    models = (
        tuple(tuple(sorted(row_of[name] for name in model)) for model in run.models)
        if run.models is not None
        else None
    )
    return PixelFigures(
        mapper_pair_count=len(for_mapper),
        keypoints_median=float(np.median(list(run.keypoints.values()))) if run.keypoints else 0.0,
        models=models,
        pair_index=np.asarray(pair_index, dtype=np.int64).reshape(m, 2),
        pair_along=np.asarray(pair_along, dtype=bool),
        inliers=inliers,
        matched=matched,
        overlap_pct=overlap,
        shift_px=shift,
        gsd_cm=gsd,
        component=component,
        frame_count=len(frames),
        match_size_px=options.max_image_size_px,
        seconds=seconds,
        tagged_gsd_cm=tagged_gsd_cm,
        focal_px=float(focal_px),
    )


def neighbour_pairs(
    pair_index: NDArray[np.int64], along: NDArray[np.bool_], across: NDArray[np.bool_]
) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
    """The pairs to match: consecutive frames of a line and a frame with the nearest frame of each
    neighbouring line (once each); and which of them are along a line."""
    keep = along | across
    index = np.sort(pair_index[keep], axis=1)
    kind = along[keep]
    _, first = np.unique(index, axis=0, return_index=True)
    first.sort()
    return index[first].astype(np.int64).reshape(-1, 2), kind[first]


def budget_pairs(
    pair_index: NDArray[np.int64],
    pair_along: NDArray[np.bool_],
    candidates: NDArray[np.int64] | None,
    camera_xyz_m: F64,
    *,
    max_per_frame: int = MAX_MAPPER_PAIRS_PER_FRAME,
) -> NDArray[np.int64]:
    """The pairs the quick reconstruction matches, within a budget of ``max_per_frame`` pairs a
    frame: the neighbour pairs ``pair_index`` (``pair_along``: consecutive frames of a line; the
    others a frame and the nearest frame of a neighbouring line), always; then a frame with the
    consecutive frames of its nearest frame on a neighbouring line (triangles across the lines:
    the points seen in three frames or more that the mapper needs, which a low endlap leaves
    along a line alone); then a frame with the second frame along its line. Each kind is taken
    shortest GPS baseline first, a pair only while neither frame has ``max_per_frame`` pairs, and,
    when ``candidates`` is given (the pairs whose tagged footprints overlap), only among them.
    Rows (i < j), the neighbour pairs first."""
    pair_index = np.asarray(pair_index, dtype=np.int64).reshape(-1, 2)
    along = np.asarray(pair_along, dtype=bool)
    n = int(max(pair_index.max(initial=-1), candidates.max(initial=-1) if candidates is not None else -1)) + 1
    along_of: list[list[int]] = [[] for _ in range(n)]
    for i, j in pair_index[along].tolist():
        along_of[i].append(j)
        along_of[j].append(i)
    chosen: dict[tuple[int, int], None] = {}
    degree = np.zeros(n, dtype=np.int64)
    for i, j in pair_index.tolist():
        key = (min(i, j), max(i, j))
        if key not in chosen:
            chosen[key] = None
            degree[list(key)] += 1
    allowed = (
        {(min(a, b), max(a, b)) for a, b in np.asarray(candidates, dtype=np.int64).reshape(-1, 2).tolist()}
        if candidates is not None
        else None
    )
    triangles: set[tuple[int, int]] = set()
    for i, j in pair_index[~along].tolist():
        for a, b in ((i, j), (j, i)):
            triangles.update((min(a, k), max(a, k)) for k in along_of[b] if k != a)
    second: set[tuple[int, int]] = set()
    for b in range(n):
        for a in along_of[b]:
            second.update((min(a, c), max(a, c)) for c in along_of[b] if c != a)

    def base(key: tuple[int, int]) -> float:
        return float(np.hypot(*(camera_xyz_m[key[0], :2] - camera_xyz_m[key[1], :2])))

    for kind in (triangles, second):
        for key in sorted(kind - chosen.keys(), key=lambda k: (base(k), k)):
            if allowed is not None and key not in allowed:
                continue
            if degree[key[0]] < max_per_frame and degree[key[1]] < max_per_frame:
                chosen[key] = None
                degree[list(key)] += 1
    return np.array(list(chosen), dtype=np.int64).reshape(-1, 2)


def describe(figures: PixelFigures) -> list[tuple[str, str]]:
    """Rows of the key figures: measured beside tagged."""
    rows: list[tuple[str, str]] = []
    along, across = figures.along_matched_pct, figures.across_matched_pct
    parts = [f"{figures.matched.sum()} of {len(figures.matched)} neighbour pairs"]
    if along is not None:
        parts.append(f"along lines {along:.0f} %")
    if across is not None:
        parts.append(f"across lines {across:.0f} %")
    rows.append(
        (
            "matched (pixels)",
            ", ".join(parts)
            + f"; {figures.isolated.size} frame(s) match no neighbour; {figures.component_count} connected "
            f"part(s), the largest {figures.largest_component_pct:.0f} % of the frames "
            f"(SIFT at {figures.match_size_px} px, {figures.seconds:.0f} s, "
            f"{figures.seconds / max(figures.frame_count, 1):.2f} s per frame)",
        )
    )
    if figures.models is not None:
        sizes = [len(m) for m in figures.models]
        rows.append(
            (
                "quick reconstruction",
                (
                    f"{len(sizes)} model(s) of {', '.join(map(str, sizes[:6]))}"
                    f"{' ...' if len(sizes) > 6 else ''} "
                    f"frames; the largest registers {figures.registered_pct:.0f} % of the "
                    f"{figures.frame_count} frames (COLMAP's mapper on {figures.mapper_pair_count} pairs, "
                    f"at most {MAX_MAPPER_PAIRS_PER_FRAME} a frame beyond the neighbour pairs)"
                )
                if sizes
                else "no model: COLMAP's mapper found no pair of frames to start from "
                f"({figures.frame_count} frames)",
            )
        )
    for label, dist in (
        ("forward overlap (pixels)", figures.forward_overlap_pct),
        ("side overlap (pixels)", figures.side_overlap_pct),
    ):
        if dist is not None:
            rows.append(
                (
                    label,
                    f"median {dist.median:.0f} % (10-90 %: {dist.p10:.0f}-{dist.p90:.0f} %, "
                    f"{dist.count} pairs)",
                )
            )
    gsd = figures.measured_gsd_cm
    if gsd is not None:
        tagged = f", tagged {figures.tagged_gsd_cm:.2f} cm" if figures.tagged_gsd_cm else ""
        rows.append(
            (
                "GSD (pixels)",
                f"median {gsd.median:.2f} cm (10-90 %: {gsd.p10:.2f}-{gsd.p90:.2f} cm, {gsd.count} pairs)"
                + tagged
                + f"; height above ground {figures.measured_height_m:.1f} m at "
                f"{figures.focal_px:.0f} px focal length",
            )
        )
    return rows


__all__ = [
    "DEFAULT_MATCH_SIZE_PX",
    "MIN_INLIERS",
    "PixelFigures",
    "PixelOptions",
    "affine_fit",
    "budget_pairs",
    "components",
    "describe",
    "mapped_overlap_pct",
    "measure_pixels",
    "neighbour_pairs",
]
