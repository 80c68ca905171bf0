"""What every engine's project starts from: the block, the ground under it, and the pairs."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

from planner.camera import Camera

from ..ground import Ground
from ..ground_choice import ground_from_options
from .block import Block, read_block
from .pairs import DEFAULT_LINE_NEIGHBOURS, DEFAULT_MIN_OVERLAP_PCT, ImagePairs, footprint_pairs


@dataclass(frozen=True, kw_only=True)
class GroundOptions:
    """The ground under the frames, as ``sfap check`` takes it (metres above mean sea level)."""

    dem: Path | None = None
    ground_elevation_m: float | None = None
    takeoff_elevation_m: float | None = None


@dataclass(frozen=True, kw_only=True)
class Prepared:
    block: Block
    ground: Ground | None
    ground_description: str
    pairs: ImagePairs


def prepare(
    images: str | os.PathLike[str],
    *,
    ground: GroundOptions | None = None,
    min_overlap_pct: float = DEFAULT_MIN_OVERLAP_PCT,
    line_neighbours: int = DEFAULT_LINE_NEIGHBOURS,
    camera: Camera | None = None,
    progress: Callable[[int], None] | None = None,
) -> Prepared:
    """Read the block, choose the ground (:func:`processing.ground_choice.ground_from_options`: the
    same rules and messages as ``sfap check``) and the pairs."""
    ground = ground or GroundOptions()
    block = read_block(images, camera=camera, progress=progress)
    chosen: Ground | None = None
    description = "none (no image has a position)"
    if block.frames:
        frames = []
        for f in block.frames:
            choice = ground_from_options(
                frames=f,
                dem=ground.dem,
                ground_elevation_m=ground.ground_elevation_m,
                takeoff_elevation_m=ground.takeoff_elevation_m,
            )
            frames.append(choice.frames)
            chosen = choice.ground
            description = choice.description
        block = replace(block, frames=tuple(frames))
    pairs = footprint_pairs(block, chosen, min_overlap_pct=min_overlap_pct, line_neighbours=line_neighbours)
    return Prepared(block=block, ground=chosen, ground_description=description, pairs=pairs)
