"""The error tree of sfap.

Every error a user can cause or meet is an :class:`SfapError`. Its message names the bad
value, the valid range and the fix. Library code raises these; only the CLI (``sfap/``)
turns them into text and exit codes, in one place (``sfap.cli``).

``planner`` imports nothing of ours, so the root of the tree lives here and the other
packages subclass it (``acquisition.errors``, ``processing.errors``).
"""

from __future__ import annotations


class SfapError(Exception):
    """Root of every sfap error. ``exit_code`` is what the CLI exits with."""

    exit_code: int = 1


class InputError(SfapError):
    """The user's input is invalid (a spec, a file, an option): exit code 2."""

    exit_code = 2


class SpecError(InputError):
    """A mission spec (TOML) is malformed or has an invalid value."""


class CameraError(InputError):
    """A camera has impossible numbers or is not in the database."""


class AreaError(InputError):
    """An area polygon is unusable (empty, self-intersecting, absurd size, wrong CRS)."""


class TerrainError(InputError):
    """A DEM cannot be read or does not cover the survey."""


class OutputExistsError(InputError):
    """An output would overwrite an existing file without --overwrite."""


class PlanningError(SfapError):
    """The inputs are valid but no safe mission can be planned from them (exit code 1)."""


class MissionFileError(InputError):
    """A mission file (.plan, .waypoints) cannot be read or is not a mission."""


class MissionValidationError(SfapError):
    """A mission failed validation and must not be sent to a vehicle."""


class PlanFolderError(InputError):
    """A plan folder (``sfap plan -o DIR``) lacks a file or holds one that cannot be read."""
