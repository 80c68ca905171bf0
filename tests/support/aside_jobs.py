"""Jobs and warm-ups for planner.aside's tests, importable by name as a helper interpreter needs
them (planner.aside.Helper: spawned, it imports its warm-up and its job by name)."""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from collections.abc import Callable
from pathlib import Path

from planner.errors import InputError

WARMED: int | None = None


def warm() -> None:
    global WARMED
    WARMED = os.getpid()


def warm_for_long() -> None:
    time.sleep(30)


def record(path: str) -> None:
    """What the process running the job is: its pid, its parent, whether it was warmed, its
    modules and its glibc tunables."""
    Path(path).write_text(
        json.dumps(
            {
                "pid": os.getpid(),
                "ppid": os.getppid(),
                "warmed": WARMED,
                "modules": sorted(sys.modules),
                "tunables": os.environ.get("GLIBC_TUNABLES"),
                "rss_kib": _rss_kib(),
                "peak_rss_kib": _rss_kib(field="VmHWM"),
            }
        )
    )


def _rss_kib(pid: int | str = "self", field: str = "VmRSS") -> int:
    """The resident memory (KiB) of process ``pid``: the kernel's count, /proc/PID/status VmRSS
    (``field`` VmHWM: its highest so far; 0 where there is none)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return 0
    return int(next(line for line in status.splitlines() if line.startswith(f"{field}:")).split()[1])


def wait_for_rss(pid: int, at_least_kib: int, seconds: float = 60.0) -> int:
    """The resident memory (KiB) of process ``pid`` once it reaches ``at_least_kib``, or when
    ``seconds`` have passed."""
    end = time.monotonic() + seconds
    while (rss := _rss_kib(pid)) < at_least_kib and time.monotonic() < end:
        time.sleep(0.01)
    return rss


def refuse(value: float) -> None:
    raise InputError(f"gsd_cm = {value}: must be above 0; give the GSD in centimetres")


def die() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def allocate_canvases(path: str) -> None:
    """Three canvases the size of the map's (Pillow, 10 MB each), one after the other, and the
    page faults they took (the kernel's count, getrusage): the bytes of a canvas and the faults."""
    import resource

    from PIL import Image

    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(3):
        canvas = Image.new("RGB", (1750, 1500), "white")
        del canvas
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
    Path(path).write_text(json.dumps({"faults": faults, "bytes": 1750 * 1500 * 4}))


def draw_map_then_record(view: object, png: str, path: str) -> None:
    """map.png of ``view`` as `sfap plan`'s helper draws it, then :func:`record`."""
    from planner.mapview import write_map_png

    write_map_png(view, png)  # type: ignore[arg-type]
    record(path)


def begin_then_record(begun: str, path: str, receive: Callable[[], object]) -> None:
    """Started by Helper.start: says it has begun (the file ``begun``), waits for its value, then
    :func:`record` with the value."""
    Path(begun).write_text(str(os.getpid()))
    value = receive()
    record(path)
    data = json.loads(Path(path).read_text())
    Path(path).write_text(json.dumps({**data, "value": value}))
