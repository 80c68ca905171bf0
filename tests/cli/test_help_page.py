"""`sfap --help` written without click (sfap/help_page.py) against click's own rendering of the
same group: the oracle is click, which lays out every other help page of sfap."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from sfap.cli import cli
from sfap.help_page import COMMANDS, render


def _click_page(prog: str, width: int, capsys: pytest.CaptureFixture[str]) -> str:
    with pytest.raises(SystemExit) as done:
        cli.main(["--help"], prog_name=prog, terminal_width=width)
    assert done.value.code == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("width", [30, 48, 50, 57, 61, 64, 70, 78, 79, 100, 140])
@pytest.mark.parametrize("prog", ["sfap", "a-very-long-program-name-for-the-usage-line"])
def test_page_is_clicks_at_every_width(prog: str, width: int, capsys: pytest.CaptureFixture[str]) -> None:
    assert render(prog, width) == _click_page(prog, width, capsys)


def test_page_lists_every_command_in_order() -> None:
    page = render("sfap", 78)
    commands = page.split("Commands:\n", 1)[1]
    names = [line.split()[0] for line in commands.splitlines() if line.startswith("  ") and line[2] != " "]
    assert names == list(COMMANDS)


@pytest.mark.parametrize("argv", [["--help"], ["-h"]])
@pytest.mark.parametrize("columns", ["52", "80", "200"])
def test_the_program_writes_clicks_page_without_importing_click(argv: list[str], columns: str) -> None:
    """The console script's entry point, in a process of its own, as a user runs it."""
    code = (
        "import sys\n"
        f"sys.argv = ['sfap', *{argv!r}]\n"
        "from sfap.entry import main\n"
        "main()\n"
        "assert 'click' not in sys.modules, 'click was imported'\n"
    )
    env = {**os.environ, "COLUMNS": columns}
    fast = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert fast.returncode == 0, fast.stderr
    slow = subprocess.run(
        [sys.executable, "-c", "from sfap.cli import cli; cli(prog_name='sfap')", *argv],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert slow.returncode == 0, slow.stderr
    assert fast.stdout == slow.stdout


def test_other_arguments_go_to_click() -> None:
    code = "import sys\nsys.argv = ['sfap', '--version']\nfrom sfap.entry import main\nmain()\n"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("sfap, version ")


def test_run_as_a_module_the_page_names_the_program_as_click_does() -> None:
    """`python -m sfap --help` goes through the same entry point (sfap/__main__.py). Click names a
    program run as a module after the interpreter and the module (click.utils
    _detect_program_name: `python -m sfap`); the page written without click names it the same,
    and is click's own page for that name."""
    env = {**os.environ, "COLUMNS": "80"}
    fast = subprocess.run(
        [sys.executable, "-m", "sfap", "--help"], capture_output=True, text=True, env=env, timeout=60
    )
    assert fast.returncode == 0, fast.stderr
    name = f"{os.path.basename(sys.executable)} -m sfap"
    slow = subprocess.run(
        [sys.executable, "-c", f"from sfap.cli import cli; cli(prog_name={name!r})", "--help"],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )
    assert slow.returncode == 0, slow.stderr
    assert fast.stdout.startswith(f"Usage: {name} [OPTIONS]")
    assert fast.stdout == slow.stdout
