"""The image pairs to match, chosen from the frames' ground footprints, or from their positions
when the ground is not known.

A pair is matched when the two footprints overlap by at least ``min_overlap_pct`` of the
smaller one (:func:`processing.stereo.overlapping_pairs` on the footprints of
:func:`processing.footprints.project_footprints`), or when the two frames are within
``line_neighbours`` of each other in capture order on the same flight line
(:func:`processing.stereo.flight_lines`): a tilt the tags do not record can move a footprint
off its neighbour's, and neighbours along a line are the pairs most sure to match.

Without a ground (EXIF altitudes above sea level and no ground elevation, DEM or take-off
frames), there are no footprints: :func:`position_pairs` pairs each frame with its
``neighbours`` nearest frames by horizontal distance between the cameras, as COLMAP's spatial
matcher and ODM's ``matcher-neighbors`` do, plus the same neighbours along the line in capture
order (a turn or a gap of more than three median steps ends a line).

Images without a position have no footprint: each is paired with every other image (said so).
With no position at all, every pair is matched (exhaustive).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..flight_lines import capture_order, flight_lines
from ..footprints import Footprints, project_footprints
from ..ground import Ground
from ..stereo import overlapping_pairs
from .block import Block

#: Default smallest footprint overlap of a pair, percent of the smaller footprint.
DEFAULT_MIN_OVERLAP_PCT = 5.0
#: Default neighbours along a line paired regardless of their footprints.
DEFAULT_LINE_NEIGHBOURS = 2
#: Nearest frames by position a frame is paired with when the ground is not known (the pairs from
#: positions; BENCHMARKS.md measures it on a real block against footprints and exhaustive).
DEFAULT_POSITION_NEIGHBOURS = 20
#: A step in capture order longer than this many median steps is not along a line.
LINE_STEP_RATIO = 3.0


@dataclass(frozen=True, kw_only=True)
class ImagePairs:
    """Pairs (i < j) of block rows; ``reason`` per pair: "overlap", "line", "no position",
    "exhaustive". ``footprints`` holds each camera group's footprints (for reports)."""

    i: NDArray[np.intp]
    j: NDArray[np.intp]
    reason: tuple[str, ...]
    overlap_pct: NDArray[np.float64]
    footprints: tuple[Footprints, ...]
    notes: tuple[str, ...]

    def __len__(self) -> int:
        return int(self.i.shape[0])

    def names(self, block: Block) -> list[tuple[str, str]]:
        return [(block.names[a], block.names[b]) for a, b in zip(self.i, self.j, strict=True)]

    def text(self, block: Block) -> str:
        """The pairs file COLMAP's matches importer reads: one "name1 name2" per line."""
        return "".join(f"{a} {b}\n" for a, b in self.names(block))


def _concat(parts: list[Footprints]) -> Footprints:
    if len(parts) == 1:
        return parts[0]
    return Footprints(
        xy_m=np.concatenate([p.xy_m for p in parts]),
        camera_xyz_m=np.concatenate([p.camera_xyz_m for p in parts]),
        principal_xyz_m=np.concatenate([p.principal_xyz_m for p in parts]),
        ground_nadir_m=np.concatenate([p.ground_nadir_m for p in parts]),
        height_above_ground_m=np.concatenate([p.height_above_ground_m for p in parts]),
        gsd_cm=np.concatenate([p.gsd_cm for p in parts]),
        area_m2=np.concatenate([p.area_m2 for p in parts]),
        valid=np.concatenate([p.valid for p in parts]),
        reason=tuple(r for p in parts for r in p.reason),
        world_from_camera=np.concatenate([p.world_from_camera for p in parts]),
        edge_samples=parts[0].edge_samples,
        ground_description=parts[0].ground_description,
    )


def footprint_pairs(
    block: Block,
    ground: Ground | None,
    *,
    min_overlap_pct: float = DEFAULT_MIN_OVERLAP_PCT,
    line_neighbours: int = DEFAULT_LINE_NEIGHBOURS,
) -> ImagePairs:
    """The pairs of ``block`` to match (module docstring). ``ground`` in the frames' altitude
    reference (:func:`processing.ground_choice.ground_from_options`); None only when no image has a
    position."""
    found: dict[tuple[int, int], tuple[str, float]] = {}
    notes: list[str] = []
    fps: list[Footprints] = []
    if block.frames:
        assert block.frame is not None and ground is not None
        rows = np.concatenate(block.frame_rows)
        fps = [project_footprints(f, block.frame, ground) for f in block.frames]
        fp = _concat(fps)
        invalid = [block.names[rows[k]] for k in np.flatnonzero(~fp.valid)]
        if invalid:
            notes.append(
                f"{len(invalid)} frame(s) have no footprint (paired along their line only): "
                f"{', '.join(invalid)}"
            )
        ov = overlapping_pairs(fp, ground, block.frame, min_overlap_pct=min_overlap_pct)
        for a, b, pa, pb in zip(ov.i, ov.j, ov.overlap_i_pct, ov.overlap_j_pct, strict=True):
            key = (int(min(rows[a], rows[b])), int(max(rows[a], rows[b])))
            found[key] = ("overlap", float(max(pa, pb)))
        for f, r, p in zip(block.frames, block.frame_rows, fps, strict=True):
            lines = flight_lines(f, p)
            order = capture_order(f)
            for k in range(len(order)):
                for step in range(1, line_neighbours + 1):
                    if k + step >= len(order):
                        break
                    a, b = order[k], order[k + step]
                    if lines[a] != lines[b]:
                        continue
                    key = (int(min(r[a], r[b])), int(max(r[a], r[b])))
                    found.setdefault(key, ("line", 0.0))
    return _with_unpositioned(block, found, notes, tuple(fps))


def position_pairs(
    block: Block,
    *,
    neighbours: int = DEFAULT_POSITION_NEIGHBOURS,
    line_neighbours: int = DEFAULT_LINE_NEIGHBOURS,
) -> ImagePairs:
    """The pairs of ``block`` when the ground is not known (module docstring): each positioned
    frame with its ``neighbours`` nearest positioned frames (horizontal distance between the
    cameras), and with the ``line_neighbours`` next frames in capture order when the step to them
    is at most :data:`LINE_STEP_RATIO` median steps."""
    if neighbours < 1:
        raise ValueError(f"neighbours = {neighbours}: at least 1")
    found: dict[tuple[int, int], tuple[str, float]] = {}
    rows = np.flatnonzero(block.has_position)
    m = len(rows)
    if m >= 2:
        xy = block.position_m[rows, :2]
        k = min(neighbours, m - 1)
        for start in range(0, m, 512):  # distances in blocks of rows: memory stays O(512 m)
            chunk = xy[start : start + 512]
            d = np.hypot(chunk[:, None, 0] - xy[None, :, 0], chunk[:, None, 1] - xy[None, :, 1])
            d[np.arange(len(chunk)), start + np.arange(len(chunk))] = np.inf
            nearest = np.argpartition(d, k - 1, axis=1)[:, :k]
            for a_local, others in enumerate(nearest):
                a = int(rows[start + a_local])
                for b in (int(rows[o]) for o in others):
                    found.setdefault((min(a, b), max(a, b)), ("position", 0.0))
        # Along the line: rows are in capture order (the block's order).
        step = np.hypot(*np.diff(xy, axis=0).T)
        moving = step[step > 1e-3]
        limit = LINE_STEP_RATIO * float(np.median(moving)) if moving.size else 0.0
        for k0 in range(m):
            reach = 0.0
            for s in range(1, line_neighbours + 1):
                if k0 + s >= m:
                    break
                reach = max(reach, float(step[k0 + s - 1]))
                if reach > limit:
                    break
                a, b = int(rows[k0]), int(rows[k0 + s])
                found.setdefault((a, b), ("line", 0.0))
    notes = [
        f"no ground elevation: pairs from the camera positions (each frame with its {neighbours} nearest and "
        f"{line_neighbours} neighbours along its line), not from footprints; give --ground-elevation-m or "
        "--dem for footprint pairs"
    ]
    return _with_unpositioned(block, found, notes, ())


def _with_unpositioned(
    block: Block,
    found: dict[tuple[int, int], tuple[str, float]],
    notes: list[str],
    fps: tuple[Footprints, ...],
) -> ImagePairs:
    """Add the pairs of the images without a position (each with every other) and build the result."""
    n = len(block)
    unpositioned = np.flatnonzero(~block.has_position)
    if len(unpositioned) == n:
        for a, b in itertools.combinations(range(n), 2):
            found[(a, b)] = ("exhaustive", 0.0)
        notes.append(f"no image has a position: all {len(found)} pairs are matched (exhaustive)")
    elif len(unpositioned):
        for a in (int(v) for v in unpositioned):
            for b in range(n):
                if b != a:
                    found.setdefault((min(a, b), max(a, b)), ("no position", 0.0))
        notes.append(f"{len(unpositioned)} image(s) without a position are paired with every other image")
    keys = sorted(found)
    return ImagePairs(
        i=np.array([k[0] for k in keys], dtype=np.intp),
        j=np.array([k[1] for k in keys], dtype=np.intp),
        reason=tuple(found[k][0] for k in keys),
        overlap_pct=np.array([found[k][1] for k in keys], dtype=np.float64),
        footprints=fps,
        notes=tuple(notes),
    )
