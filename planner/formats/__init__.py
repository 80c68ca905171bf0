"""Mission file formats, one module each: QGC ``.plan`` (:mod:`.qgc_plan`) and QGC WPL 110
``.waypoints`` (:mod:`.waypoints`).

:func:`read_mission` opens either, deciding by content rather than by the file's name, since
files travel renamed (``mission.txt`` from Mission Planner, ``.plan`` saved as ``.json``).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import MissionFileError
from ..mission import Mission
from .qgc_plan import parse_plan, plan_document, read_plan, write_plan
from .waypoints import parse_waypoints, read_waypoints, waypoints_text, write_waypoints

__all__ = [
    "parse_plan",
    "parse_waypoints",
    "plan_document",
    "read_mission",
    "read_plan",
    "read_waypoints",
    "waypoints_text",
    "write_plan",
    "write_waypoints",
]

_EXPECTED = (
    'a QGroundControl .plan (JSON with "fileType": "Plan") or a QGC WPL 110 .waypoints file '
    '(first line "QGC WPL 110")'
)


def _first_line(text: str) -> str:
    for line in text.splitlines():
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            return stripped
    return ""


def read_mission(path: str | os.PathLike[str]) -> Mission:
    """Read a mission from a .plan or a .waypoints file, whichever the content is.

    Raises :class:`~planner.errors.MissionFileError` naming the file and what was expected when
    it is neither, or when it is one of them but malformed (with the line or item at fault).
    """
    file = Path(path)
    try:
        raw = file.read_bytes()
    except IsADirectoryError:
        raise MissionFileError(
            f"{file} is a folder; give the mission file inside it (for example mission.plan)"
        ) from None
    except OSError as exc:
        raise MissionFileError(f"cannot read {file}: {exc.strerror or exc}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        text = raw.decode("latin-1")
    if text.startswith("\ufeff"):
        text = text[1:]
    head = text.lstrip()
    if head.startswith("{"):
        return parse_plan(text, source=str(file))
    first = _first_line(text)
    if first.split()[:2] == ["QGC", "WPL"]:
        return parse_waypoints(text, source=str(file))
    shown = first[:60] + ("..." if len(first) > 60 else "")
    start = f"it starts with {shown!r}" if shown else "it is empty"
    raise MissionFileError(f"{file} is not a mission file: expected {_EXPECTED}; {start}")
