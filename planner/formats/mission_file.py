"""Reading a mission file's bytes with the errors a person understands (shared by the readers)."""

from __future__ import annotations

from pathlib import Path

from ..errors import MissionFileError


def read_mission_bytes(file: Path, kind: str) -> bytes:
    """The bytes of ``file``; ``kind`` (".plan", ".waypoints") names what was expected."""
    try:
        return file.read_bytes()
    except IsADirectoryError:
        raise MissionFileError(f"{file} is a folder; give the {kind} file inside it") from None
    except OSError as exc:
        raise MissionFileError(f"cannot read {file}: {exc.strerror or exc}") from None
