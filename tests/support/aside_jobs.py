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
            }
        )
    )


def refuse(value: float) -> None:
    raise InputError(f"gsd_cm = {value}: must be above 0; give the GSD in centimetres")


def die() -> None:
    os.kill(os.getpid(), signal.SIGKILL)


def _large_advised_mappings() -> int:
    """Anonymous mappings of 24 MiB or more the kernel marks advised for huge pages ("hg")."""
    count, size_kib = 0, 0
    with open("/proc/self/smaps") as smaps:
        for line in smaps:
            if line.startswith("Size:"):
                size_kib = int(line.split()[1])
            elif line.startswith("VmFlags:") and size_kib >= 24 * 1024 and "hg" in line.split()[1:]:
                count += 1
    return count


def allocate_a_map_page(path: str) -> None:
    """A page as large as a whole map page supersampled (Pillow, 29 MB), and whether the kernel was
    advised to back it with huge pages: the advised mappings before and while it exists."""
    from PIL import Image

    before = _large_advised_mappings()
    page = Image.new("RGB", (3445, 2119), "white")
    during = _large_advised_mappings()
    Path(path).write_text(json.dumps({"before": before, "during": during, "size": page.size}))


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
