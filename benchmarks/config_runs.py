"""Configurations of one sfap command run as whole processes, in alternating order (A B A B ...),
each into a fresh output folder, with the columns every such benchmark prints: the configuration,
the start (UTC), the machine's load (``os.getloadavg``) at the start, the exit status, the wall
time and the child's CPU time (user + system over every thread: on the shared machine the wall
time follows the load, the CPU time much less). The caller adds its own columns from the run's
report.json (benchmarks/quicklook_seneca.py, benchmarks/check_pixels_seneca.py)."""

from __future__ import annotations

import json
import os
import resource
import shlex
import shutil
import subprocess
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

COMMON_HEADER = "| configuration | start UTC | load | exit | wall | CPU |"


def parse_configs(given: Sequence[str]) -> list[tuple[str, list[str]]]:
    """``name=extra options`` into (name, arguments)."""
    return [(c.split("=", 1)[0], shlex.split(c.split("=", 1)[1] if "=" in c else "")) for c in given]


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_configurations(
    configs: Sequence[tuple[str, list[str]]],
    *,
    rounds: int,
    command: Callable[[Path, list[str]], list[str]],
    columns: Callable[[dict[str, Any]], str],
    header: str,
) -> None:
    """Run ``command(output folder, extra options)`` per configuration and round (the order reversed
    in odd rounds); print a row per run as it ends (the common columns, then ``columns(report.json's
    content)``, "| a | b" without the closing bar), then the whole table under ``COMMON_HEADER`` and
    ``header`` (the caller's column names, "| a | b |")."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(rounds):
            for name, extra in configs if k % 2 == 0 else list(configs)[::-1]:
                out = Path(tmp) / f"{name}-{k}"
                load = "/".join(f"{v:.1f}" for v in os.getloadavg())
                started = time.strftime("%H:%M", time.gmtime())
                cpu0, t0 = _children_cpu_s(), time.perf_counter()
                done = subprocess.run(command(out, extra), capture_output=True, text=True)
                wall, cpu = time.perf_counter() - t0, _children_cpu_s() - cpu0
                report_path = out / "report.json"
                report = json.loads(report_path.read_text()) if report_path.exists() else {}
                row = (
                    f"| {name} | {started} | {load} | {done.returncode} | {wall:.0f} s | {cpu:.0f} s "
                    f"{columns(report)} |"
                )
                rows.append(row)
                print(row, flush=True)
                if done.returncode not in (0, 1):
                    print(done.stderr[-2000:], flush=True)
                shutil.rmtree(out, ignore_errors=True)
    names = COMMON_HEADER + header.removeprefix("|")
    print("\n" + names)
    print("|---" * (names.count("|") - 1) + "|")
    print("\n".join(rows))
