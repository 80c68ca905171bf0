"""A block without positions judged on its pixels alone.

Kite, balloon and pole photographs, and cameras without GPS, give frames that no tag puts on the
ground: no footprints, no area, no coverage, overlap or GSD from the tags, and no flight log to
geotag them from. What predicts their reconstruction is still measurable
(:mod:`processing.pixel_match`): whether the frames match, the parts the matched pairs form, and
a quick reconstruction of the matches (COLMAP's incremental mapper). :func:`check_pixels_only`
matches every pair of frames (up to :data:`MAX_EXHAUSTIVE_FRAMES` frames; beyond, each frame with
the next :data:`SEQUENTIAL_WINDOW` in name order, which is capture order on a camera's card) and
judges them on the two pixel rules of :class:`processing.verdict.Thresholds`
(``min_connected_frames_pct``, ``min_registered_pct``), saying that coverage, overlap, GSD and blur
were not judged. On copr_kap (41 kite frames, no GPS) it registers the 38 frames COLMAP's
reconstruction does (DESIGN.md, "The field check's verdict").
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import ProcessingError
from .pixel_match import (
    MIN_INLIERS,
    MIN_KEYPOINTS,
    PixelFigures,
    PixelOptions,
    affine_fit,
    components,
    describe,
    mapped_overlap_pct,
)
from .verdict import Thresholds, pixel_reasons

#: Up to this many frames every pair is matched (1770 pairs; COLMAP's own exhaustive matcher is
#: its default up to a few hundred frames); beyond, sequential pairs.
MAX_EXHAUSTIVE_FRAMES = 60
#: Beyond MAX_EXHAUSTIVE_FRAMES, each frame is matched with this many frames after it (name order).
SEQUENTIAL_WINDOW = 10


def pairs_without_positions(count: int) -> NDArray[np.int64]:
    """The pairs of frame rows to match when no position says which frames overlap: every pair up
    to :data:`MAX_EXHAUSTIVE_FRAMES` frames, else each frame with the next
    :data:`SEQUENTIAL_WINDOW`. (M, 2), i < j, sorted."""
    window = count if count <= MAX_EXHAUSTIVE_FRAMES else SEQUENTIAL_WINDOW
    pairs = [(i, j) for i in range(count) for j in range(i + 1, min(i + window, count - 1) + 1)]
    return np.asarray(pairs, dtype=np.int64).reshape(-1, 2)


@dataclass(frozen=True, kw_only=True)
class PixelOnlyCheck:
    """The verdict on a block without positions: what the pixels say (``figures``: every pair
    tried is in ``figures.pair_index``, consecutive frames marked as along a line), the reasons it
    fails, warnings and notes."""

    image_dir: Path
    names: tuple[str, ...]
    figures: PixelFigures
    thresholds: Thresholds
    reasons: tuple[str, ...]
    warnings: tuple[str, ...]
    notes: tuple[str, ...]

    @property
    def passed(self) -> bool:
        return not self.reasons

    def key_figures(self) -> list[tuple[str, str]]:
        rows = [
            ("frames", f"{len(self.names)}, without positions: judged on the pixels alone"),
            ("not judged", "coverage, gaps, overlap from the tags, GSD, B/H, blur (no positions)"),
        ]
        return rows + describe(self.figures)

    def as_dict(self) -> dict[str, Any]:
        return {
            "verdict": "pass" if self.passed else "fail",
            "passed": self.passed,
            "exit_code": 0 if self.passed else 1,
            "judged_on": "pixels only (no positions)",
            "reasons": list(self.reasons),
            "warnings": list(self.warnings),
            "notes": list(self.notes),
            "thresholds": {
                "min_connected_frames_pct": self.thresholds.min_connected_frames_pct,
                "min_registered_pct": self.thresholds.min_registered_pct,
            },
            "frames": {"count": len(self.names), "names": list(self.names)},
            "pixels": self.figures.as_dict(),
        }


def check_pixels_only(
    image_dir: str | Path, names: Sequence[str], options: PixelOptions, thresholds: Thresholds
) -> PixelOnlyCheck:
    """Match the frames ``names`` in ``image_dir`` (:func:`pairs_without_positions`) and judge them
    on the pixel rules (module docstring). ProcessingError with fewer than three frames."""
    from .pixel_colmap import match_pairs

    ordered = sorted(names)
    if len(ordered) < 3:
        raise ProcessingError(
            f"{len(ordered)} image(s) without positions: a block needs at least 3 frames to be judged on "
            "its pixels; geotag them (`sfap geotag`) or add the frames"
        )
    start = time.monotonic()
    index = pairs_without_positions(len(ordered))
    run = match_pairs(
        Path(image_dir),
        ordered,
        [(ordered[i], ordered[j]) for i, j in index.tolist()],
        max_image_size_px=options.max_image_size_px,
        max_features=options.max_features,
        num_threads=options.num_threads or 2,
        log_path=options.log_path,
        map_models=options.reconstruct,
    )
    m = len(index)
    inliers = np.array([p.count for p in run.pairs], dtype=np.int64).reshape(m)
    matched = inliers >= MIN_INLIERS
    overlap = np.full(m, np.nan)
    for k, pair in enumerate(run.pairs):
        if matched[k]:
            overlap[k] = mapped_overlap_pct(
                affine_fit(pair.xy_a, pair.xy_b), run.size_px[pair.a], run.size_px[pair.b]
            )
    row_of = {name: k for k, name in enumerate(ordered)}
    figures = PixelFigures(
        pair_index=index,
        pair_along=(index[:, 1] - index[:, 0]) == 1,
        inliers=inliers,
        matched=matched,
        overlap_pct=overlap,
        shift_px=np.full(m, np.nan),
        gsd_cm=np.full(m, np.nan),  # no baseline without positions: no scale
        component=components(len(ordered), index[matched]),
        frame_count=len(ordered),
        match_size_px=options.max_image_size_px,
        seconds=time.monotonic() - start,
        tagged_gsd_cm=None,
        focal_px=float("nan"),
        models=(
            tuple(tuple(sorted(row_of[name] for name in model)) for model in run.models)
            if run.models is not None
            else None
        ),
        keypoints_median=float(np.median(list(run.keypoints.values()))) if run.keypoints else 0.0,
    )
    warnings = [
        "the images carry no positions: coverage, gaps, GSD, B/H and blur were not judged, only whether "
        "the frames match and reconstruct (their pixels); geotag them (`sfap geotag`) for the whole check"
    ]
    if not figures.conclusive:
        reasons: tuple[str, ...] = (
            f"the frames carry too few features to match (median {figures.keypoints_median:.0f} SIFT "
            f"features per frame, under {MIN_KEYPOINTS}): featureless ground (water, snow, fresh tarmac) "
            "will not reconstruct, and without positions nothing else can be judged",
        )
    else:
        reasons = tuple(pixel_reasons(thresholds, figures))
    pairing = (
        f"every pair of the {len(ordered)} frames"
        if len(ordered) <= MAX_EXHAUSTIVE_FRAMES
        else f"each frame with the next {SEQUENTIAL_WINDOW} in name order"
    )
    return PixelOnlyCheck(
        image_dir=Path(image_dir),
        names=tuple(ordered),
        figures=figures,
        thresholds=thresholds,
        reasons=reasons,
        warnings=tuple(warnings),
        notes=(f"pairs matched: {pairing} ({m} pairs), no position to choose them by",),
    )


__all__ = [
    "MAX_EXHAUSTIVE_FRAMES",
    "SEQUENTIAL_WINDOW",
    "PixelOnlyCheck",
    "check_pixels_only",
    "pairs_without_positions",
]
