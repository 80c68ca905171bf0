"""planner.aside: a job run in a child process forked beside this one (map.png while `sfap plan`
writes the other files), its error raised here, and no child left behind.

The fork path is exercised in real processes started for the test (``python -c``), each with one
thread: the test runner's own process may have threads (pytest-xdist), where a fork is refused
and the job runs in place, which one test here checks on purpose.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from planner.aside import can_fork

REPO = Path(__file__).resolve().parents[2]

PRELUDE = textwrap.dedent(
    """
    import json, os, signal, sys, threading, time
    from planner.aside import Helper, can_fork, start_aside
    from planner.errors import InputError

    WARMED = None

    def warm():
        global WARMED
        WARMED = os.getpid()

    def record(path):
        with open(path, "w") as handle:
            json.dump({"pid": os.getpid(), "ppid": os.getppid(), "warmed": WARMED}, handle)

    def refuse(value):
        raise InputError(f"gsd_cm = {value}: must be above 0; give the GSD in centimetres")

    def die():
        os.kill(os.getpid(), signal.SIGKILL)
    """
)


def run(body: str, tmp_path: Path, timeout: float = 60.0) -> dict[str, object]:
    """Run PRELUDE + body in a fresh Python (one thread); body prints one JSON line last."""
    script = PRELUDE + textwrap.dedent(body)
    done = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    )
    assert done.returncode == 0, done.stderr
    result: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


needs_fork = pytest.mark.skipif(
    not hasattr(os, "fork") or len(os.sched_getaffinity(0)) < 2, reason="needs fork and two cores"
)


@needs_fork
def test_helper_runs_the_job_in_its_warmed_child(tmp_path: Path) -> None:
    result = run(
        """
        out = sys.argv[1] + "/job.json"
        helper = Helper(warm=warm)
        aside = helper.submit(record, out, what="job.json")
        forked = aside.forked
        aside.wait()
        helper.close()
        print(json.dumps({"me": os.getpid(), "forked": forked, **json.load(open(out))}))
        """,
        tmp_path,
    )
    assert result["forked"] is True
    assert result["pid"] != result["me"]  # another process ran it
    assert result["ppid"] == result["me"]  # a child of this one
    assert result["warmed"] == result["pid"]  # warmed up in the process that ran the job


@needs_fork
def test_the_childs_error_is_raised_here_as_it_was(tmp_path: Path) -> None:
    result = run(
        """
        helper = Helper(warm=warm)
        aside = helper.submit(refuse, -1, what="map.png")
        try:
            aside.wait()
            outcome = {"raised": None}
        except InputError as error:
            outcome = {"raised": type(error).__name__, "text": str(error)}
        print(json.dumps({"forked": True, **outcome}))
        """,
        tmp_path,
    )
    assert result["raised"] == "InputError"
    assert result["text"] == "gsd_cm = -1: must be above 0; give the GSD in centimetres"


@needs_fork
def test_a_child_killed_by_a_signal_is_an_error_naming_the_job(tmp_path: Path) -> None:
    result = run(
        """
        aside = start_aside(die, "out/map.png")
        try:
            aside.wait()
            outcome = {"raised": None}
        except OSError as error:
            outcome = {"raised": "OSError", "text": str(error)}
        print(json.dumps({"forked": aside.forked, **outcome}))
        """,
        tmp_path,
    )
    assert result["raised"] == "OSError"
    assert "out/map.png" in str(result["text"]) and "signal 9" in str(result["text"])


@needs_fork
def test_close_and_cancel_stop_the_child_at_once_and_reap_it(tmp_path: Path) -> None:
    result = run(
        """
        helper = Helper(warm=lambda: time.sleep(30))
        helper_pid = helper.pid
        started = time.monotonic()
        helper.close()
        aside = start_aside(lambda: time.sleep(30), "slow")
        aside_pid = aside.pid
        aside.cancel()
        took = time.monotonic() - started
        gone = []
        for pid in (helper_pid, aside_pid):
            try:
                os.waitpid(pid, os.WNOHANG)
                gone.append(False)
            except ChildProcessError:  # reaped already: no zombie left
                gone.append(True)
        print(json.dumps({"pids": [helper_pid, aside_pid], "took": took, "gone": gone}))
        """,
        tmp_path,
    )
    assert all(isinstance(pid, int) for pid in result["pids"])  # type: ignore[union-attr]
    assert result["took"] < 10.0  # type: ignore[operator]
    assert result["gone"] == [True, True]


def test_with_a_thread_running_the_job_runs_here(tmp_path: Path) -> None:
    result = run(
        """
        stop = threading.Event()
        thread = threading.Thread(target=stop.wait)
        thread.start()
        try:
            out = sys.argv[1] + "/job.json"
            helper = Helper(warm=warm)
            aside = helper.submit(record, out, what="job.json")
            aside.wait()
            refused = start_aside(lambda: refuse(0), "x")
            try:
                refused.wait()
                raised = None
            except InputError as error:
                raised = str(error)
        finally:
            stop.set()
            thread.join()
        print(json.dumps({"me": os.getpid(), "helper": helper.pid, "raised": raised, **json.load(open(out))}))
        """,
        tmp_path,
    )
    assert result["helper"] is None  # no child was forked
    assert result["pid"] == result["me"]
    assert result["warmed"] is None  # nothing warmed: the job ran cold, in place
    assert result["raised"] == "gsd_cm = 0: must be above 0; give the GSD in centimetres"


@needs_fork
def test_sfap_plan_draws_the_map_aside_and_the_same_map(tmp_path: Path) -> None:
    """`sfap plan` in a real process: map.png drawn by another process, the same bytes as drawn
    here in place; the planning process itself never loads Pillow nor numpy.ma."""
    out = tmp_path / "gully"
    script = textwrap.dedent(
        f"""
        import json, sys
        sys.argv = ["sfap", "-vv", "plan", "missions/bardenas-gully.toml", "-o", {str(out)!r},
                    "--no-progress"]
        from sfap.cli import main  # the click group: sfap.entry's would end the process at once
        try:
            main()
        except SystemExit as end:
            assert not end.code, end.code
        print(json.dumps({{"PIL": "PIL" in sys.modules, "numpy.ma": "numpy.ma" in sys.modules}}))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", script], cwd=REPO, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    loaded = json.loads(done.stdout.strip().splitlines()[-1])
    assert "map.png: drawn aside by process" in done.stderr
    assert loaded == {"PIL": False, "numpy.ma": False}

    from planner.mapplot import map_png_bytes
    from planner.plan_folder import OUTPUT_FILES
    from planner.spec import load_spec
    from planner.survey import plan_survey

    plan = plan_survey(load_spec(REPO / "missions" / "bardenas-gully.toml"))
    assert (out / "map.png").read_bytes() == map_png_bytes(plan)
    assert sorted(p.name for p in out.iterdir()) == sorted(OUTPUT_FILES)


def test_can_fork_refuses_with_threads() -> None:
    """In this (test runner's) process: with an extra thread running, never a fork."""
    import threading

    stop = threading.Event()
    thread = threading.Thread(target=stop.wait)
    thread.start()
    try:
        assert can_fork() is False
    finally:
        stop.set()
        thread.join()
