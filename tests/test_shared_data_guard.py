"""The root conftest.py's guard for tests that need ../shared/data: run in a pytest of its own on
small test files, with the data folder pointed somewhere absent, with and without CI=true."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

TESTS = """
import pytest
from pathlib import Path
from shared_data import SHARED_DATA, needs, require

FOLDER = SHARED_DATA / "garfield_rgb"
NAMES = sorted(p.name for p in FOLDER.glob("*.JPG"))


def _first_frame() -> Path:
    return sorted(FOLDER.glob("*.JPG"))[0]


@pytest.fixture
def frames() -> list[Path]:
    return sorted(FOLDER.glob("*.JPG"))  # empty, no error, when the folder is absent


def test_constant():
    assert FOLDER.is_dir()


def test_helper():
    assert _first_frame().stat().st_size > 0


def test_fixture(frames):
    assert frames


@pytest.mark.parametrize("name", NAMES)
def test_empty_parameters(name):
    assert (FOLDER / name).is_file()


def test_built_at_run_time():
    import os  # a path the conftest cannot see in the code: caught as its FileNotFoundError

    (Path(os.environ["SFAP_SHARED_DATA"]) / "copr_kap" / "gcp_list.txt").read_text()


@needs("seneca_half")
def test_mark():
    assert True


def test_require():
    require("copr_kap")


def test_no_data_needed(tmp_path):
    assert not (tmp_path / "x").exists()
"""


def _run(tmp_path: Path, ci: bool) -> subprocess.CompletedProcess[str]:
    (tmp_path / "test_guarded.py").write_text(TESTS)
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    env = {k: v for k, v in os.environ.items() if k not in {"CI", "PYTEST_XDIST_WORKER", "PYTEST_ADDOPTS"}}
    env["SFAP_SHARED_DATA"] = str(tmp_path / "absent" / "data")
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), str(REPO / "tests" / "support")])
    if ci:
        env["CI"] = "true"
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-p",
            "conftest",
            "-p",
            "no:cacheprovider",
            "-rsfE",
            "-q",
            "test_guarded.py",
        ],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )


GUARDED = ["constant", "helper", "fixture", "empty_parameters", "built_at_run_time", "mark", "require"]


@pytest.mark.parametrize("ci", [False, True], ids=["clone", "ci"])
def test_every_kind_of_reference_is_answered(tmp_path: Path, ci: bool) -> None:
    """Each way a test reaches the data (a module constant, a helper, a fixture, parameters drawn
    from the folder, a path built at run time, the mark, the call) is skipped on a clone with one
    reason naming the folder and how to get it, and fails where CI=true; a test needing no data runs."""
    result = _run(tmp_path, ci)
    out = result.stdout
    reason = f"the real data folder {tmp_path / 'absent' / 'data'} is absent: put the project's shared folder"
    if ci:
        assert result.returncode == 1, out
        for name in GUARDED:
            line = next(line for line in out.splitlines() if f"test_guarded.py::test_{name}" in line)
            assert line.startswith(("FAILED", "ERROR")) and f"CI=true and {reason}" in line, line
        assert "1 passed" in out, out
    else:
        assert result.returncode == 0, out
        assert "1 passed, 7 skipped" in out, out
        summary = [line for line in out.splitlines() if line.startswith("SKIPPED")]
        assert len(summary) == 1 and summary[0].startswith("SKIPPED [7]"), out  # one reason for all
        assert reason in summary[0] and "SFAP_SHARED_DATA" in summary[0], summary
