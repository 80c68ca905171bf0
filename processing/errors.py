"""processing's branch of the sfap error tree (root: planner.errors.SfapError)."""

from __future__ import annotations

from planner.errors import InputError, SfapError, TerrainError


class ProcessingError(SfapError):
    """A check or hand-off could not be done (exit code 1)."""


class GroundError(TerrainError):
    """The ground (height above ground) is unknown or its source is unusable."""


class FramesError(InputError):
    """Images or a plan cannot be read as frames (no position, no camera...)."""
