"""planner.aside: a job run in a child process beside this one (map.png while `sfap plan` writes
the other files), its error raised here, and no child left behind.

Exercised in real processes started for the test (``python -c``), each with one thread: the test
runner's own process may have threads (pytest-xdist), where a fork is refused and start_aside
runs the job in place, which one test here checks on purpose. A Helper is a spawned interpreter:
its warm-up and jobs are named functions of tests/support/aside_jobs.py.
"""

from __future__ import annotations

import json
import os
import platform
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
    from tests.support.aside_jobs import (
        allocate_canvases, begin_then_record, die, record, refuse, wait_for_rss
    )

    def wait_for(path, seconds=30.0):
        end = time.monotonic() + seconds
        while not os.path.exists(path):
            if time.monotonic() > end:
                raise TimeoutError(path)
            time.sleep(0.005)

    WARM = "tests.support.aside_jobs:warm"
    """
)


def run(body: str, tmp_path: Path, timeout: float = 60.0, **env: str) -> dict[str, object]:
    """Run PRELUDE + body in a fresh Python (one thread); body prints one JSON line last."""
    script = PRELUDE + textwrap.dedent(body)
    done = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path)],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1", **env},
    )
    assert done.returncode == 0, done.stderr
    result: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


needs_fork = pytest.mark.skipif(
    not hasattr(os, "fork") or len(os.sched_getaffinity(0)) < 2, reason="needs fork and two cores"
)
needs_spawn = pytest.mark.skipif(
    not hasattr(os, "posix_spawn") or len(os.sched_getaffinity(0)) < 2,
    reason="needs posix_spawn and two cores",
)


@needs_spawn
def test_helper_runs_the_job_in_its_warmed_child(tmp_path: Path) -> None:
    result = run(
        """
        out = sys.argv[1] + "/job.json"
        helper = Helper(warm=WARM)
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
    assert result["tunables"] == "glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=268435456"


@needs_spawn
@pytest.mark.parametrize(
    ("users", "helpers"),
    [
        (
            "glibc.malloc.check=0",
            "glibc.malloc.check=0:glibc.malloc.mmap_threshold=33554432:glibc.malloc.trim_threshold=268435456",
        ),
        (  # the user's say stands
            "glibc.malloc.trim_threshold=0",
            "glibc.malloc.trim_threshold=0:glibc.malloc.mmap_threshold=33554432",
        ),
    ],
)
def test_the_helper_keeps_the_users_own_glibc_tunables(tmp_path: Path, users: str, helpers: str) -> None:
    result = run(
        """
        out = sys.argv[1] + "/job.json"
        helper = Helper()
        helper.submit(record, out, what="job.json").wait()
        print(json.dumps({"mine": os.environ["GLIBC_TUNABLES"], **json.load(open(out))}))
        """,
        tmp_path,
        GLIBC_TUNABLES=users,
    )
    assert result["mine"] == users  # this process's environment is not changed
    assert result["tunables"] == helpers


def _glibc() -> bool:
    return sys.platform == "linux" and platform.libc_ver()[0] == "glibc"


@needs_spawn
@pytest.mark.skipif(not _glibc(), reason="the room is kept by glibc's malloc (Linux, glibc)")
@pytest.mark.parametrize("room_mib", [0, 48])
def test_the_job_finds_its_memory_already_faulted_in(tmp_path: Path, room_mib: int) -> None:
    """A helper given a room faults it in while it waits (its resident memory grows by the room,
    the kernel's count), and a job allocating a map page's canvases (Pillow, 3 x 10 MB, each
    freed before the next) then takes almost no page fault (getrusage): without a room, a fault
    for every page of the first canvas at least."""
    result = run(
        f"""
        out = sys.argv[1] + "/job.json"
        helper = Helper(warm=WARM, room_bytes={room_mib} << 20)
        rss = wait_for_rss(helper.pid, {room_mib} * 1024 + 10_000) if {room_mib} else 0
        helper.submit(allocate_canvases, out, what="canvases").wait()
        print(json.dumps({{"rss_kib": rss, **json.load(open(out))}}))
        """,
        tmp_path,
    )
    pages = result["bytes"] // os.sysconf("SC_PAGESIZE")
    if room_mib:
        assert result["rss_kib"] >= room_mib * 1024 + 10_000
        assert result["faults"] < 0.1 * pages
    else:
        assert result["faults"] > 0.9 * pages


@needs_spawn
def test_a_helper_stops_faulting_in_its_room_when_the_job_comes(tmp_path: Path) -> None:
    """A room of 2 GiB: the job, sent at once, runs at once, and the helper stopped touching its
    room a few MiB after the job came (its highest resident memory, the kernel's count, far
    below)."""
    result = run(
        """
        out = sys.argv[1] + "/job.json"
        helper = Helper(warm=WARM, room_bytes=2 << 30)
        began = time.monotonic()
        helper.submit(record, out, what="job.json").wait()
        print(json.dumps({"seconds": time.monotonic() - began, **json.load(open(out))}))
        """,
        tmp_path,
    )
    assert result["seconds"] < 20
    assert 0 < result["peak_rss_kib"] < 512 * 1024  # under a quarter of the 2 GiB asked


@needs_spawn
def test_the_childs_error_is_raised_here_as_it_was(tmp_path: Path) -> None:
    result = run(
        """
        helper = Helper(warm=WARM)
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


@needs_spawn
@needs_fork
def test_close_and_cancel_stop_the_child_at_once_and_reap_it(tmp_path: Path) -> None:
    result = run(
        """
        helper = Helper(warm="tests.support.aside_jobs:warm_for_long")
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


@needs_fork
def test_a_child_reports_its_job_done_or_its_error(tmp_path: Path) -> None:
    """What a child says on its report's pipe: one byte (planner.aside._DONE) for a job done, the
    pickled error for one that failed."""
    result = run(
        """
        import pickle
        from planner import aside

        def child(run):
            read_fd, write_fd = os.pipe()
            pid = os.fork()
            if pid == 0:
                os.close(read_fd)
                aside._report_and_exit(write_fd, run)
            os.close(write_fd)
            with os.fdopen(read_fd, "rb") as pipe:
                report = pipe.read()
            os.waitpid(pid, 0)
            return report

        done = child(lambda: None)
        failed = pickle.loads(child(lambda: refuse(-1.0)))
        print(json.dumps({"done": done.hex(), "failed": str(failed), "is_done": done == aside._DONE}))
        """,
        tmp_path,
    )
    assert result == {
        "done": "00",
        "failed": "gsd_cm = -1.0: must be above 0; give the GSD in centimetres",
        "is_done": True,
    }


@needs_spawn
def test_a_helper_done_is_not_waited_for_to_exit_and_is_reaped_later(tmp_path: Path) -> None:
    """wait() returns on the helper's word that its job is done; the helper, which may still be
    exiting then, is reaped by the next wait or reap_exited (here made to wait): no zombie is
    left, and a helper that did not say so (killed) is waited for as before."""
    result = run(
        """
        from planner import aside
        out = sys.argv[1] + "/job.json"
        helper = Helper(warm=WARM)
        pid = helper.pid
        helper.submit(record, out, what="job.json").wait()
        aside.reap_exited(block=True)
        try:
            os.waitpid(pid, os.WNOHANG)
            gone = False
        except ChildProcessError:
            gone = True
        print(json.dumps({"pid": pid, "ran_in": json.load(open(out))["pid"], "gone": gone,
                          "exiting": sorted(aside._exiting)}))
        """,
        tmp_path,
    )
    assert result["pid"] == result["ran_in"]
    assert result["gone"] is True
    assert result["exiting"] == []


@needs_spawn
def test_with_a_thread_running_a_helper_still_runs_the_job_and_a_fork_does_not(tmp_path: Path) -> None:
    """A spawned helper is safe beside other threads; a fork is not, so start_aside runs in place."""
    result = run(
        """
        stop = threading.Event()
        thread = threading.Thread(target=stop.wait)
        thread.start()
        try:
            out = sys.argv[1] + "/job.json"
            helper = Helper(warm=WARM)
            aside = helper.submit(record, out, what="job.json")
            aside.wait()
            refused = start_aside(lambda: refuse(0), "x")
            in_place = not refused.forked
            try:
                refused.wait()
                raised = None
            except InputError as error:
                raised = str(error)
        finally:
            stop.set()
            thread.join()
        print(json.dumps({"me": os.getpid(), "in_place": in_place, "raised": raised, **json.load(open(out))}))
        """,
        tmp_path,
    )
    assert result["pid"] != result["me"] and result["ppid"] == result["me"]
    assert result["warmed"] == result["pid"]
    assert result["in_place"] is True
    assert result["raised"] == "gsd_cm = 0: must be above 0; give the GSD in centimetres"


@needs_spawn
@needs_fork
def test_a_job_the_helper_cannot_import_is_forked_instead(tmp_path: Path) -> None:
    result = run(
        """
        def local_record(path):  # in __main__: another interpreter cannot import it by name
            record(path)

        out = sys.argv[1] + "/job.json"
        helper = Helper(warm=WARM)
        helper_pid = helper.pid
        helper.submit(local_record, out, what="job.json").wait()
        gone = False
        try:
            os.waitpid(helper_pid, os.WNOHANG)
        except ChildProcessError:  # stopped and reaped
            gone = True
        print(json.dumps({"me": os.getpid(), "helper": helper_pid, "gone": gone, **json.load(open(out))}))
        """,
        tmp_path,
    )
    assert result["pid"] not in (result["me"], result["helper"])  # a fork of this process ran it
    assert result["ppid"] == result["me"]
    assert result["warmed"] is None
    assert result["gone"] is True


@needs_spawn
@needs_fork
def test_a_helper_that_died_is_done_without(tmp_path: Path) -> None:
    """The helper killed before its job came: the job runs in a fork all the same, no error."""
    result = run(
        """
        out = sys.argv[1] + "/job.json"
        helper = Helper(warm=WARM)
        dead = helper.pid
        os.kill(dead, signal.SIGKILL)
        time.sleep(0.2)
        helper.submit(record, out, what="job.json").wait()
        gone = False
        try:
            os.waitpid(dead, os.WNOHANG)
        except ChildProcessError:  # reaped
            gone = True
        print(json.dumps({"me": os.getpid(), "dead": dead, "gone": gone, **json.load(open(out))}))
        """,
        tmp_path,
    )
    assert result["pid"] not in (result["me"], result["dead"])
    assert result["ppid"] == result["me"]
    assert result["gone"] is True


@needs_spawn
def test_a_started_job_runs_its_first_part_before_it_is_sent_its_value(tmp_path: Path) -> None:
    result = run(
        """
        begun, out = sys.argv[1] + "/begun", sys.argv[1] + "/job.json"
        helper = Helper(warm=WARM)
        aside = helper.start(begin_then_record, begun, out, what="job.json")
        wait_for(begun)  # the job has begun: no value was sent yet
        sent_after = os.path.exists(out)
        aside.send({"header": "GSD 2.40 cm", "path": "x/map.png"})
        aside.wait()
        print(json.dumps({"me": os.getpid(), "done_before_send": sent_after,
                          "begun_by": int(open(begun).read()), **json.load(open(out))}))
        """,
        tmp_path,
    )
    assert result["done_before_send"] is False
    assert result["begun_by"] == result["pid"] != result["me"]
    assert result["warmed"] == result["pid"]
    assert result["value"] == {"header": "GSD 2.40 cm", "path": "x/map.png"}


@needs_spawn
@needs_fork
def test_a_started_job_the_helper_cannot_import_begins_at_its_send(tmp_path: Path) -> None:
    result = run(
        """
        def local(begun, out, receive):  # in __main__: another interpreter cannot import it
            begin_then_record(begun, out, receive)

        begun, out = sys.argv[1] + "/begun", sys.argv[1] + "/job.json"
        helper = Helper(warm=WARM)
        helper_pid = helper.pid
        aside = helper.start(local, begun, out, what="job.json")
        early = os.path.exists(begun)
        aside.send([1, 2])
        aside.wait()
        print(json.dumps({"me": os.getpid(), "helper": helper_pid, "early": early, **json.load(open(out))}))
        """,
        tmp_path,
    )
    assert result["early"] is False
    assert result["pid"] not in (result["me"], result["helper"])
    assert result["ppid"] == result["me"]
    assert result["value"] == [1, 2]


@needs_spawn
def test_a_started_job_never_sent_is_stopped_not_waited_for_ever(tmp_path: Path) -> None:
    result = run(
        """
        begun, out = sys.argv[1] + "/begun", sys.argv[1] + "/job.json"
        outcomes = []
        for how in ("wait", "cancel"):
            aside = Helper(warm=WARM).start(begin_then_record, begun, out, what="map.png")
            pid = aside.pid
            wait_for(begun)
            os.remove(begun)
            if how == "wait":
                try:
                    aside.wait()
                    outcomes.append("no error")
                except RuntimeError as error:
                    outcomes.append(str(error))
            else:
                aside.cancel()
                outcomes.append("cancelled")
            try:
                os.waitpid(pid, os.WNOHANG)
                outcomes.append("child left")
            except ChildProcessError:
                outcomes.append("reaped")
        print(json.dumps({"outcomes": outcomes, "recorded": os.path.exists(out)}))
        """,
        tmp_path,
        timeout=30.0,
    )
    assert result["outcomes"] == [
        "map.png: waited on before it was sent its value (Aside.send)",
        "reaped",
        "cancelled",
        "reaped",
    ]
    assert result["recorded"] is False


@needs_spawn
def test_a_started_job_whose_helper_died_is_an_error_at_wait_not_at_send(tmp_path: Path) -> None:
    result = run(
        """
        begun, out = sys.argv[1] + "/begun", sys.argv[1] + "/job.json"
        aside = Helper(warm=WARM).start(begin_then_record, begun, out, what="out/map.png")
        wait_for(begun)
        os.kill(aside.pid, signal.SIGKILL)
        time.sleep(0.2)
        aside.send("x" * 200_000)  # more than the pipe holds were nobody reading
        try:
            aside.wait()
            outcome = None
        except OSError as error:
            outcome = str(error)
        print(json.dumps({"outcome": outcome}))
        """,
        tmp_path,
        timeout=30.0,
    )
    assert result["outcome"] == "out/map.png: the process writing it was ended by signal 9"


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


def test_a_frozen_application_starts_no_helper(monkeypatch: pytest.MonkeyPatch) -> None:
    """A frozen application's executable is not Python's: it would read the helper's ``-c`` as an
    option of its own."""
    from planner.aside import can_spawn

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    assert can_spawn() is hasattr(os, "posix_spawn")
    monkeypatch.setattr(sys, "frozen", True, raising=False)
    assert can_spawn() is False
