"""What a mission transfer leaves on the vehicle and says: the vehicle's state after it
(:class:`MissionState`), an upload's result, the transfer errors, and MAV_MISSION_RESULT codes
in words."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from planner.errors import InputError, MissionValidationError
from planner.mission import Autopilot, VehicleType

from .errors import TransferError, VerificationError, join_sentences
from .mavlink_items import PARAM_NAMES, MissionType
from .readback import ItemDifference


class MissionState(StrEnum):
    """What the vehicle holds after a transfer."""

    UNCHANGED = "unchanged"
    PARTIAL = "partial"
    REPLACED_VERIFIED = "replaced and verified"
    REPLACED_DIFFERS = "replaced, but differs from what was sent"
    REPLACED_UNVERIFIED = "replaced, not verified"
    CLEARED = "cleared"

    @property
    def sentence(self) -> str:
        """The state said to a person, with what to do about it."""
        return _STATE_SENTENCES[self]


_STATE_SENTENCES = {
    MissionState.UNCHANGED: "The vehicle's mission is unchanged.",
    MissionState.PARTIAL: (
        "The vehicle's mission is now PARTIAL: it may hold a mix of old and new items. Do not "
        "fly it: upload again, or clear it with `sfap clear`."
    ),
    MissionState.REPLACED_VERIFIED: "The vehicle's mission was replaced and verified.",
    MissionState.REPLACED_DIFFERS: (
        "The vehicle's mission was replaced but DIFFERS from what was sent. Do not fly it: "
        "upload again, or clear it with `sfap clear`."
    ),
    MissionState.REPLACED_UNVERIFIED: (
        "The vehicle accepted the mission but it could not be read back to verify it: check it "
        "with `sfap download` or upload again before flying."
    ),
    MissionState.CLEARED: "The vehicle's mission is cleared.",
}


# --- MAV_MISSION_RESULT in words ------------------------------------------------------------------

_RESULT_SENTENCES: dict[int, str] = {
    0: "the vehicle accepted it (MAV_MISSION_ACCEPTED)",
    1: ("the vehicle reported an unspecified error (MAV_MISSION_ERROR); its status messages may say why"),
    2: (
        "the vehicle does not support the coordinate frame of an item "
        "(MAV_MISSION_UNSUPPORTED_FRAME); use altitudes relative to home or AMSL"
    ),
    3: (
        "the vehicle does not support a command in the mission (MAV_MISSION_UNSUPPORTED); "
        "check the mission's commands against this autopilot and its firmware version"
    ),
    4: (
        "the vehicle has no room for this many items (MAV_MISSION_NO_SPACE); split the mission "
        "into sorties, or wait a few seconds after boot and try again"
    ),
    5: "the vehicle found an item invalid (MAV_MISSION_INVALID)",
    13: (
        "the vehicle received an item out of sequence (MAV_MISSION_INVALID_SEQUENCE); the link "
        "may be losing or reordering messages"
    ),
    14: (
        "the vehicle refuses to change its mission now (MAV_MISSION_DENIED); it may be armed "
        "and flying a mission, or another ground station is transferring one"
    ),
    15: "the vehicle cancelled the transfer (MAV_MISSION_OPERATION_CANCELLED)",
}


def describe_mission_result(code: int) -> str:
    """A MAV_MISSION_RESULT code as a sentence a person understands."""
    if code in _RESULT_SENTENCES:
        return _RESULT_SENTENCES[code]
    if 6 <= code <= 12:
        n = code - 5
        suffix = {5: "_X", 6: "_Y"}.get(n, "")
        return (
            f"the vehicle found {PARAM_NAMES[n]} of an item out of its range "
            f"(MAV_MISSION_INVALID_PARAM{n}{suffix})"
        )
    return f"the vehicle answered with an unknown mission result code {code}"


@dataclass(frozen=True, kw_only=True)
class UploadResult:
    """What an upload did. ``upload_s``/``verify_s`` are wall-clock seconds."""

    url: str
    autopilot: Autopilot
    vehicle_type: VehicleType | None
    mission_type: MissionType
    state: MissionState
    items: int  # mission items, home not counted
    items_sent: int  # MISSION_COUNT: with ArduPilot's home item
    differences: tuple[ItemDifference, ...] = ()
    upload_s: float = 0.0
    verify_s: float = 0.0
    items_resent: int = 0  # item messages sent more than once (loss, repeated requests)
    notes: tuple[str, ...] = ()

    @property
    def verified(self) -> bool:
        return self.state is MissionState.REPLACED_VERIFIED

    def summary(self) -> str:
        head = (
            f"{self.items} items to {self.autopilot.value} on {self.url} in "
            f"{self.upload_s:.1f} s, read back in {self.verify_s:.1f} s: {self.state.sentence}"
        )
        if not self.differences:
            return head
        lines = [d.describe() for d in self.differences[:30]]
        more = len(self.differences) - len(lines)
        if more > 0:
            lines.append(f"... and {more} more differences")
        return head + "\nDifferences:\n  " + "\n  ".join(lines)

    def to_dict(self) -> dict[str, object]:
        return {
            "url": self.url,
            "autopilot": self.autopilot.value,
            "vehicle_type": None if self.vehicle_type is None else self.vehicle_type.value,
            "mission_type": self.mission_type.name.lower(),
            "state": self.state.value,
            "verified": self.verified,
            "items": self.items,
            "items_sent": self.items_sent,
            "upload_s": round(self.upload_s, 3),
            "verify_s": round(self.verify_s, 3),
            "items_resent": self.items_resent,
            "differences": [d.to_dict() for d in self.differences],
            "notes": list(self.notes),
        }


class MissionTransferError(TransferError):
    """A transfer failed; ``mission_state`` says what the vehicle now holds."""

    def __init__(self, message: str, *, mission_state: MissionState) -> None:
        super().__init__(join_sentences(message, mission_state.sentence))
        self.mission_state = mission_state


class MissionInterruptedError(MissionTransferError):
    """The user stopped a transfer (Ctrl-C); ``mission_state`` says what the vehicle now holds
    (a real ArduPilot may keep a partial mission). Exit code 130, as any interrupt."""

    exit_code = 130


class MissionTooLargeError(MissionTransferError):
    """The vehicle holds fewer items than the mission has (MAV_MISSION_NO_SPACE with its
    capacity, "Only N items are supported"); nothing changed on the vehicle."""

    def __init__(self, message: str, *, items: int, capacity: int | None) -> None:
        super().__init__(message, mission_state=MissionState.UNCHANGED)
        self.items = items
        self.capacity = capacity


class MissionInputError(InputError, MissionValidationError):
    """The mission cannot be sent as it is (it fails validation, or it was planned for the
    other autopilot): bad input, exit code 2; nothing was sent."""


class MissionVerificationError(VerificationError):
    """The read-back differs from what was sent; ``result`` lists the differences."""

    def __init__(self, result: UploadResult) -> None:
        super().__init__(
            f"the mission read back from {result.url} differs from the one sent in "
            f"{len(result.differences)} places. {result.summary()}"
        )
        self.result = result
        self.mission_state = result.state
