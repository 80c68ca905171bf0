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


# ------------------------------------------------------------------ the real data in ../shared/data
# A clone without ../shared runs the suite: a test that needs the real data skips with one reason
# naming the folder and how to get it, and fails instead where CI=true. Nothing is asked of the
# tests: before any runs, each test's code is read (the test, the functions of the test files it
# calls, its fixtures' code, its parameters) for a path under SHARED_DATA; a reference the reading
# cannot see (a path built at run time) is caught when it raises FileNotFoundError under the folder.
# `shared_data.needs(...)` (a mark) and `shared_data.require(...)` (a call) say it explicitly.
import inspect as _inspect  # noqa: E402
import types as _types  # noqa: E402
from collections.abc import Callable, Generator, Iterator  # noqa: E402
from pathlib import PurePath as _PurePath  # noqa: E402
from typing import Any as _Any  # noqa: E402

from shared_data import SHARED_DATA, absent_reason, answer_absent, in_ci, is_shared  # noqa: E402

_TESTS = _ROOT / "tests"
_SHARED_KEY = pytest.StashKey[list[Path]]()


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "shared_data(path): the test needs this path under ../shared/data (see tests/support/shared_data.py)",
    )


def _shared_in_value(value: _Any) -> Iterator[Path]:
    if isinstance(value, _PurePath | str) and is_shared(Path(value)):
        yield Path(value)
    elif isinstance(value, list | tuple | set | frozenset) and len(value) < 1000:
        for element in value:
            if isinstance(element, _PurePath | str) and is_shared(Path(element)):
                yield Path(element)


def _is_test_code(obj: _Any) -> bool:
    code = getattr(obj, "__code__", None)
    filename = getattr(code, "co_filename", "")
    if not filename:
        return False
    name = Path(filename).name
    return filename.startswith(str(_TESTS)) or name.startswith("test_") or name == "conftest.py"


def _shared_in_function(func: Callable[..., _Any], seen: set[int]) -> Iterator[Path]:
    """The paths under SHARED_DATA that `func`'s code names: its globals, closures and default
    arguments, and those of the test-file functions and classes it names, recursively."""
    func = _inspect.unwrap(func)
    if id(func) in seen:
        return
    seen.add(id(func))
    namespace: dict[str, _Any] = getattr(func, "__globals__", {})
    for default in (getattr(func, "__defaults__", None) or ()) + tuple(
        (getattr(func, "__kwdefaults__", None) or {}).values()
    ):
        yield from _shared_in_value(default)
    for cell in getattr(func, "__closure__", None) or ():
        try:
            contents = cell.cell_contents
        except ValueError:  # an empty cell
            continue
        yield from _shared_in_value(contents)
    codes = [getattr(func, "__code__", None)]
    while codes:
        code = codes.pop()
        if code is None:
            continue
        for name in code.co_names:
            if name not in namespace:
                continue
            value = namespace[name]
            yield from _shared_in_value(value)
            if _inspect.isfunction(value) and _is_test_code(value):
                yield from _shared_in_function(value, seen)
            elif _inspect.isclass(value) and id(value) not in seen:
                seen.add(id(value))
                for member in vars(value).values():
                    member = getattr(member, "__func__", member)
                    if _inspect.isfunction(member) and _is_test_code(member):
                        yield from _shared_in_function(member, seen)
        codes.extend(const for const in code.co_consts if isinstance(const, _types.CodeType))


def _shared_needed(item: pytest.Item) -> list[Path]:
    needed: list[Path] = []
    for mark in item.iter_markers("shared_data"):
        needed.extend(Path(arg) for arg in mark.args)
    seen: set[int] = set()
    function = getattr(item, "obj", None)
    if function is not None:
        needed.extend(_shared_in_function(function, seen))
        instance_class = getattr(item, "cls", None)
        if instance_class is not None:  # the methods of a test class it calls through self
            for member in vars(instance_class).values():
                if _inspect.isfunction(member) and _is_test_code(member):
                    needed.extend(_shared_in_function(member, seen))
    callspec = getattr(item, "callspec", None)
    if callspec is not None:
        for value in callspec.params.values():
            needed.extend(_shared_in_value(value))
    fixtureinfo = getattr(item, "_fixtureinfo", None)
    if fixtureinfo is not None:
        for definitions in fixtureinfo.name2fixturedefs.values():
            for definition in definitions:
                needed.extend(_shared_in_function(definition.func, seen))
    return sorted(set(needed))


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        needed = _shared_needed(item)
        if needed:
            item.stash[_SHARED_KEY] = needed


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    """Before the skipping plugin's own setup (a conftest hook runs before the built-in ones of
    its rank): an empty parameter set or a test's own skipif must not hide the absence in CI."""
    reason = absent_reason(item.stash.get(_SHARED_KEY, []))
    if reason is not None:
        answer_absent(reason)


def _answer_missing_file(error: OSError) -> None:
    filename = error.filename
    if filename is not None and is_shared(Path(str(filename))):
        reason = absent_reason([Path(str(filename))])
        if reason is not None:
            answer_absent(reason)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, None, None]:
    try:
        return (yield)
    except (FileNotFoundError, NotADirectoryError) as error:
        _answer_missing_file(error)
        raise


@pytest.hookimpl(wrapper=True)
def pytest_fixture_setup(
    fixturedef: pytest.FixtureDef[_Any], request: pytest.FixtureRequest
) -> Generator[None, None, _Any]:
    try:
        return (yield)
    except (FileNotFoundError, NotADirectoryError) as error:
        _answer_missing_file(error)
        raise


def pytest_report_header(config: pytest.Config) -> str:
    state = (
        "present"
        if SHARED_DATA.is_dir()
        else "ABSENT (tests needing it " + ("fail, CI=true)" if in_ci() else "skip)")
    )
    return f"real data: {SHARED_DATA} {state}"
