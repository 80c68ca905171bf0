"""The hand-off's branch of the error tree."""

from __future__ import annotations

from planner.errors import InputError

from ..errors import ProcessingError


class HandoffError(ProcessingError):
    """The hand-off could not be done (an engine failed, a block did not reconstruct): exit code 1."""


class HandoffInputError(InputError):
    """The frames or options cannot make a project (exit code 2)."""


class NodeError(HandoffError):
    """A NodeODM node is unreachable, refuses the task, or the task failed (exit code 1)."""
