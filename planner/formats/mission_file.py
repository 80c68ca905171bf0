"""What the mission file readers share: reading a file's bytes with the errors a person
understands, a frame number checked, and an item from its seven params."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from ..errors import MissionFileError
from ..mission import MavFrame, MissionItem


def read_mission_bytes(file: Path, kind: str) -> bytes:
    """The bytes of ``file``; ``kind`` (".plan", ".waypoints") names what was expected."""
    try:
        return file.read_bytes()
    except IsADirectoryError:
        raise MissionFileError(f"{file} is a folder; give the {kind} file inside it") from None
    except OSError as exc:
        raise MissionFileError(f"cannot read {file}: {exc.strerror or exc}") from None


def mav_frame(frame_number: int) -> MavFrame | str:
    """The frame of that number, or (not one sfap handles) the text listing those it does."""
    try:
        return MavFrame(frame_number)
    except ValueError:
        known = ", ".join(f"{f.value} ({f.name})" for f in MavFrame)
        return f"frame {frame_number} is not a mission frame sfap handles ({known})"


def item_from_params(
    command: int, frame: MavFrame, params: Sequence[float], autocontinue: bool
) -> MissionItem:
    """A mission item from the seven params as written (NaN in params 1-4: unused, None)."""
    p1, p2, p3, p4 = (None if math.isnan(p) else p for p in params[:4])
    return MissionItem(
        command=command,
        frame=frame,
        param1=p1,
        param2=p2,
        param3=p3,
        param4=p4,
        param5=params[4],
        param6=params[5],
        param7=params[6],
        autocontinue=autocontinue,
    )
