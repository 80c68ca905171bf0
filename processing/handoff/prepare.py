"""What every engine's project starts from: the block, the ground under it, and the pairs.

The ground is needed for the footprint pairs only: geo.txt, the images and the reference files
do not depend on it. It comes from what the crew gave (``--dem``, ``--ground-elevation-m``,
``--takeoff-elevation-m``: :func:`processing.ground_choice.ground_from_options`, the same rules
and messages as ``sfap check``), from the frames' own relative altitudes (DJI XMP
RelativeAltitude: flat ground at the take-off point), or from the block's take-off frames
(:mod:`processing.handoff.takeoff`). With none of these, the pairs come from the camera
positions (:func:`processing.handoff.pairs.position_pairs`) and the project says so.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from planner.camera import Camera

from ..frames import AltitudeReference
from ..ground import Ground
from ..ground_choice import ground_from_options
from .block import Block, read_block
from .pairs import (
    DEFAULT_LINE_NEIGHBOURS,
    DEFAULT_MIN_OVERLAP_PCT,
    DEFAULT_POSITION_NEIGHBOURS,
    ImagePairs,
    footprint_pairs,
    position_pairs,
)
from .takeoff import takeoff_ground


@dataclass(frozen=True, kw_only=True)
class GroundOptions:
    """The ground under the frames, as ``sfap check`` takes it (metres above mean sea level)."""

    dem: Path | None = None
    ground_elevation_m: float | None = None
    takeoff_elevation_m: float | None = None

    @property
    def given(self) -> bool:
        return (
            self.dem is not None
            or self.ground_elevation_m is not None
            or self.takeoff_elevation_m is not None
        )


@dataclass(frozen=True, kw_only=True)
class Prepared:
    block: Block
    ground: Ground | None
    ground_description: str
    pairs: ImagePairs


def _takeoff_options(block: Block, options: GroundOptions) -> tuple[GroundOptions, str] | None:
    rows = np.flatnonzero(block.has_position)  # in capture order (the block's order)
    pad = takeoff_ground(
        [block.names[k] for k in rows], block.position_m[rows, :2], block.position_m[rows, 2]
    )
    if pad is None:
        return None
    return replace(options, takeoff_elevation_m=pad.elevation_m), (
        f"flat ground at the take-off point, {pad.description}"
    )


def prepare(
    images: str | os.PathLike[str],
    *,
    ground: GroundOptions | None = None,
    min_overlap_pct: float = DEFAULT_MIN_OVERLAP_PCT,
    line_neighbours: int = DEFAULT_LINE_NEIGHBOURS,
    position_neighbours: int = DEFAULT_POSITION_NEIGHBOURS,
    camera: Camera | None = None,
    progress: Callable[[int], None] | None = None,
) -> Prepared:
    """Read the block, choose the ground (module docstring) and the pairs."""
    options = ground or GroundOptions()
    block = read_block(images, camera=camera, progress=progress)
    if not block.frames:
        pairs = footprint_pairs(block, None, min_overlap_pct=min_overlap_pct, line_neighbours=line_neighbours)
        return Prepared(
            block=block, ground=None, ground_description="none (no image has a position)", pairs=pairs
        )
    absolute = block.alt_reference in (AltitudeReference.AMSL, AltitudeReference.ELLIPSOID)
    override: str | None = None
    if absolute and not options.given:
        found = _takeoff_options(block, options)
        if found is None:
            pairs = position_pairs(block, neighbours=position_neighbours, line_neighbours=line_neighbours)
            return Prepared(
                block=block,
                ground=None,
                ground_description=(
                    "not known (camera altitudes above sea level, no ground elevation, DEM or take-off "
                    "frames): pairs from the camera positions"
                ),
                pairs=pairs,
            )
        options, override = found
    row_of = {n: k for k, n in enumerate(block.names)}
    chosen: Ground | None = None
    description = ""
    frames, rows = [], []
    left_out: list[str] = []
    for f in block.frames:
        choice = ground_from_options(
            frames=f,
            dem=options.dem,
            ground_elevation_m=options.ground_elevation_m,
            takeoff_elevation_m=options.takeoff_elevation_m,
        )
        frames.append(choice.frames)
        rows.append(np.array([row_of[n] for n in choice.frames.name], dtype=np.intp))
        left_out.extend(f"{name} ({why})" for name, why in choice.left_out)
        chosen = choice.ground
        description = override or choice.description
    notes = list(block.notes)
    if left_out:
        notes.append(
            f"{len(left_out)} frame(s) are not survey frames and get no pairs: " + "; ".join(left_out[:10])
        )
    block = replace(block, frames=tuple(frames), frame_rows=tuple(rows), notes=tuple(notes))
    pairs = footprint_pairs(block, chosen, min_overlap_pct=min_overlap_pct, line_neighbours=line_neighbours)
    return Prepared(block=block, ground=chosen, ground_description=description, pairs=pairs)
