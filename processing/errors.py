"""processing's branch of the sfap error tree (root: planner.errors.SfapError)."""

from __future__ import annotations

from planner.errors import InputError, SfapError, TerrainError


class ProcessingError(SfapError):
    """A check or hand-off could not be done (exit code 1)."""


class GroundError(TerrainError):
    """The ground (height above ground) is unknown or its source is unusable."""


class FramesError(InputError):
    """Images or a plan cannot be read as frames (no position, no camera...)."""


class NoPositionsError(FramesError):
    """None of the images has a real position (``names``: the images read): nothing to put on the
    ground; ``sfap check`` then judges them on their pixels alone (processing.check_pixels)."""

    def __init__(self, message: str, *, names: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.names = names
