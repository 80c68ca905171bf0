"""Import every module of the project before any test runs.

Hypothesis mixes constants found in the project's loaded modules into the examples it draws
(hypothesis.internal.conjecture.providers, "local constants"), so the examples of a property test,
even a derandomized one, would otherwise depend on which modules earlier tests happened to import:
a test could pass alone and fail in the whole suite. With every module loaded first, each property
test draws the same examples whatever runs before it.
"""

from __future__ import annotations

import importlib
from pathlib import Path

_ROOT = Path(__file__).resolve().parent

for _package_name in ("planner", "acquisition", "processing", "sfap"):
    for _file in sorted((_ROOT / _package_name).rglob("*.py")):
        _parts = _file.relative_to(_ROOT).with_suffix("").parts
        if _parts[-1] == "__main__":  # runs the CLI
            continue
        if _parts[-1] == "__init__":
            _parts = _parts[:-1]
        if all(
            (_ROOT.joinpath(*_parts[:k]) / "__init__.py").is_file() for k in range(1, len(_parts) + 1)
        ) or (
            _parts[-1] != "__init__"
            and all((_ROOT.joinpath(*_parts[:k]) / "__init__.py").is_file() for k in range(1, len(_parts)))
        ):
            importlib.import_module(".".join(_parts))
