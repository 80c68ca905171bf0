"""Where the project's shared real data lives: ../shared/data beside the repository (CI puts
it there too), or $SFAP_SHARED_DATA.

A clone without that folder still runs the suite: every test that needs the real data skips with
one reason naming the folder and how to get it, except where CI=true, where the folder's absence
is a failure (CI promises the data is there; a silent skip would hide that it is not).

Tests need not do anything for that: the root conftest.py finds, before any test runs, the tests
whose code (the test, the module's functions it calls, its fixtures, its parameters) refers to a
path under SHARED_DATA, and skips or fails each whose path is absent; a test that reaches the folder
some other way and meets a FileNotFoundError under it is answered the same way. `needs(...)`
(a mark) and `require(...)` (a call) say it explicitly where the reference is not visible.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NoReturn

import pytest

REPO = Path(__file__).resolve().parents[2]
SHARED_DATA = Path(os.environ.get("SFAP_SHARED_DATA", REPO.parent / "shared" / "data"))

HOW_TO_GET = (
    "put the project's shared folder beside the repository (../shared, whose data/README.md lists "
    "each set and its public origin) or set SFAP_SHARED_DATA to a copy of that data folder"
)


def in_ci() -> bool:
    """True where CI=true (any of true, 1, yes; any case): the shared data must be present."""
    return os.environ.get("CI", "").strip().lower() in {"true", "1", "yes"}


def is_shared(path: Path) -> bool:
    """Whether `path` is the shared data folder or lies below it."""
    try:
        path = Path(path)
    except TypeError:
        return False
    return path == SHARED_DATA or SHARED_DATA in path.parents


def absent_reason(paths: list[Path] | tuple[Path, ...]) -> str | None:
    """The one reason for a test needing `paths`, or None when all of them exist. When the whole
    folder is missing, the reason names the folder alone, so every such skip reads the same."""
    missing = [p for p in paths if not p.exists()]
    if not missing:
        return None
    if not SHARED_DATA.is_dir():
        what = f"the real data folder {SHARED_DATA} is absent"
    else:
        names = ", ".join(sorted({str(p) for p in missing}))
        what = f"{names} absent from the real data folder {SHARED_DATA}"
    return f"{what}: {HOW_TO_GET}"


def answer_absent(reason: str) -> NoReturn:
    """Skip the running test, or fail it where CI=true."""
    if in_ci():
        pytest.fail(f"CI=true and {reason}", pytrace=False)
    pytest.skip(reason)


def require(*parts: str) -> Path:
    """SHARED_DATA / parts, skipping the calling test (failing it where CI=true) when absent."""
    path = SHARED_DATA.joinpath(*parts)
    reason = absent_reason([path])
    if reason is not None:
        answer_absent(reason)
    return path


def needs(*parts: str) -> pytest.MarkDecorator:
    """A mark: the test needs SHARED_DATA / parts (the root conftest.py answers its absence)."""
    return pytest.mark.shared_data(SHARED_DATA.joinpath(*parts))
