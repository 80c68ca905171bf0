"""sfap.entry.exit_at_once: a command's process ends without the interpreter's teardown, and the
user sees the same exit: its status, every byte of its output, its exit functions run; or it
does not end at once where that would differ (a thread still running, a message to print).

Each case is a real process (``python -c`` or ``python -m sfap``): the exit is the behaviour.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

PRELUDE = """
import atexit, sys, threading
from sfap.entry import exit_at_once
"""


def _python(body: str, tmp_path: Path) -> subprocess.CompletedProcess[str]:
    script = textwrap.dedent(PRELUDE) + textwrap.dedent(body)
    buffered = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # CI sets it
    return subprocess.run(
        [sys.executable, "-c", script], cwd=tmp_path, env=buffered, capture_output=True, text=True, timeout=60
    )


def test_the_status_the_output_and_the_exit_functions_all_survive(tmp_path: Path) -> None:
    done = _python(
        """
        atexit.register(lambda: open("exit-functions-ran", "w").write("yes"))
        sys.stdout.write("no newline, still buffered")
        sys.stderr.write("and on stderr")
        exit_at_once(SystemExit(3))
        print("never reached")
        """,
        tmp_path,
    )
    assert done.returncode == 3
    assert done.stdout == "no newline, still buffered"
    assert done.stderr == "and on stderr"
    assert (tmp_path / "exit-functions-ran").read_text() == "yes"


def test_none_is_status_0(tmp_path: Path) -> None:
    done = _python("exit_at_once(SystemExit(None))\nprint('never reached')\n", tmp_path)
    assert (done.returncode, done.stdout) == (0, "")


def test_a_running_thread_or_a_message_leaves_the_exit_to_python(tmp_path: Path) -> None:
    """A normal exit waits for a non-daemon thread, and prints a message status: both return."""
    done = _python(
        """
        stop = threading.Event()
        worker = threading.Thread(target=lambda: (stop.wait(), print("thread finished")))
        worker.start()
        exit_at_once(SystemExit(0))
        print("returned with a thread running")
        stop.set()
        worker.join()
        exit_at_once(SystemExit("a message"))
        print("returned with a message")
        """,
        tmp_path,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        "returned with a thread running",
        "thread finished",
        "returned with a message",
    ]


def test_sfap_plan_in_a_real_process_keeps_its_output_and_statuses(tmp_path: Path) -> None:
    """`python -m sfap` (sfap.entry): the whole JSON summary on stdout with status 0, and a bad
    spec refused with status 2 and its message."""
    out = tmp_path / "gully"
    done = subprocess.run(
        [sys.executable, "-m", "sfap", "plan", "missions/bardenas-gully.toml", "-o", str(out), "--json"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["output_dir"] == str(out)
    assert json.loads((out / "summary.json").read_text())["photo_count"] == summary["photo_count"]

    bad = tmp_path / "bad.toml"
    bad.write_text('name = "bad"\narea = "area.geojson"\n')  # no [camera]
    refused = subprocess.run(
        [sys.executable, "-m", "sfap", "plan", str(bad), "-o", str(tmp_path / "bad")],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert refused.returncode == 2
    assert refused.stderr.startswith("error: ") and "[camera]" in refused.stderr
    assert not (tmp_path / "bad").exists()
