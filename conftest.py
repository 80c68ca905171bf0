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


# ------------------------------------------------------------------ plans shared by several tests
import json as _json  # noqa: E402
import os as _os  # noqa: E402

import pytest  # noqa: E402

QUARRY_SORTIES_SPEC = _ROOT / "missions" / "quarry-block-sorties.toml"


@pytest.fixture(scope="session")
def quarry_sorties_cli(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, int, str, str]:
    """`sfap plan missions/quarry-block-sorties.toml -o OUT --json` run once for the whole run:
    (OUT, exit code, stdout, output). Several tests read the 31 folders it writes (about 9 s of CPU, most
    of it the maps); none may modify them. Under pytest-xdist the first worker to ask runs it and
    the others wait on a lock and read its output (the xdist way of sharing a session fixture)."""
    import fcntl

    from click.testing import CliRunner

    from sfap.cli import cli

    shared = tmp_path_factory.getbasetemp()
    if _os.environ.get("PYTEST_XDIST_WORKER"):
        shared = shared.parent  # the run's directory, common to every worker
    out, done = shared / "quarry-block-sorties", shared / "quarry-block-sorties.json"
    with open(shared / "quarry-block-sorties.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            result = CliRunner().invoke(cli, ["plan", str(QUARRY_SORTIES_SPEC), "-o", str(out), "--json"])
            done.write_text(_json.dumps([result.exit_code, result.stdout, result.output]))
    exit_code, stdout, output = _json.loads(done.read_text())
    return out, exit_code, stdout, output
