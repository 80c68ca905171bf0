"""acquisition's branch of the sfap error tree (root: planner.errors.SfapError)."""

from __future__ import annotations

from planner.errors import InputError, SfapError


class AcquisitionError(SfapError):
    """Something went wrong talking to a vehicle or reading its logs (exit code 1)."""


class LinkError(AcquisitionError):
    """A MAVLink link could not be opened, heard nothing, or dropped."""


class TransferError(AcquisitionError):
    """A mission transfer failed; the message states the vehicle's mission state."""


class VerificationError(TransferError):
    """The mission read back from the vehicle differs from the one sent."""


class TelemetryError(InputError):
    """A flight log cannot be read (wrong format, empty, no usable messages)."""


class GeotagError(AcquisitionError):
    """Frames could not be matched or tagged."""
