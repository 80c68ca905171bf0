"""Paired whole-process timing, shared by every benchmark in this folder.

A comparison between two programs on a shared, noisy machine is only worth what its method is:

- each side runs as a whole process (start-up, imports and writing the outputs included), started
  with ``subprocess.Popen`` and reaped with ``os.wait4``, which also gives that one child's CPU
  times and peak resident set size (``ru_maxrss``, KiB on Linux);
- the two sides alternate (A B, B A, A B...), so that a slow minute of the machine lands on both;
- at least five pairs; the ratio (peer time / sfap time, > 1: sfap faster) of each pair is
  reported as its minimum and median, with each side's minimum and median time and peak RSS;
- the machine's load average is recorded before and after (``os.getloadavg``), with the date,
  the CPU, the core count and the Python version, so that a figure can be reproduced or doubted.

Run as a script it times two shell commands against each other:
``python benchmarks/paired.py --pairs 7 -- 'sfap --help' -- 'python -c pass'``.
"""

from __future__ import annotations

import argparse
import os
import platform
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

GNU_TIME = "/usr/bin/time"  # Debian: apt-get install time


@dataclass(frozen=True)
class Sample:
    """One process: wall time, CPU times (user, system) and peak resident set size."""

    wall_s: float
    user_s: float
    sys_s: float
    max_rss_mib: float


def run_process(
    command: Sequence[str],
    *,
    cwd: str | None = None,
    env: dict[str, str] | None = None,
    stdin: int | None = subprocess.DEVNULL,
) -> Sample:
    """Run ``command`` to its end; its wall time, CPU times and peak RSS. Exits on failure.

    The peak RSS comes from GNU time (``/usr/bin/time -f %M``) wrapped around the command:
    a child forked from this (large) Python process would otherwise report this process's
    size as its own peak, since Linux keeps ``ru_maxrss`` across exec.
    """
    with tempfile.NamedTemporaryFile("r", suffix=".rss") as rss_file:
        wrapped = list(command)
        if os.path.exists(GNU_TIME):
            wrapped = [GNU_TIME, "-f", "%M", "-o", rss_file.name, *wrapped]
        start = time.perf_counter()
        child = subprocess.Popen(
            wrapped, cwd=cwd, env=env, stdin=stdin, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
        )
        assert child.stderr is not None
        errors = child.stderr.read()
        _, status, usage = os.wait4(child.pid, 0)
        wall = time.perf_counter() - start
        child.returncode = os.waitstatus_to_exitcode(status)
        child.stderr.close()
        if child.returncode != 0:
            text = errors.decode(errors="replace")[-2000:]
            sys.exit(f"{shlex.join(command)} failed ({child.returncode}):\n{text}")
        try:
            rss_mib = int(rss_file.read().split()[-1]) / 1024.0
        except (ValueError, IndexError):
            rss_mib = float("nan")  # no GNU time: say so rather than report the parent's size
    return Sample(wall, usage.ru_utime, usage.ru_stime, rss_mib)


@dataclass
class Side:
    """One of the two programs of a comparison."""

    label: str
    command: Sequence[str]
    before: Callable[[], None] | None = None  # untimed, before every run (e.g. remove the output)
    samples: list[Sample] = field(default_factory=list)

    def run(self, cwd: str | None = None, env: dict[str, str] | None = None) -> Sample:
        if self.before is not None:
            self.before()
        sample = run_process(self.command, cwd=cwd, env=env)
        self.samples.append(sample)
        return sample


@dataclass
class Comparison:
    """The result of :func:`compare`: sfap's side, the peer's side and the machine's load."""

    name: str
    sfap: Side
    peer: Side
    load_before: tuple[float, float, float]
    load_after: tuple[float, float, float]
    started: str

    @property
    def ratios(self) -> list[float]:
        """peer wall / sfap wall for each pair (> 1: sfap is faster)."""
        return [p.wall_s / s.wall_s for s, p in zip(self.sfap.samples, self.peer.samples, strict=True)]

    def report(self) -> str:
        def side(s: Side) -> str:
            walls = [x.wall_s for x in s.samples]
            cpu = [x.user_s + x.sys_s for x in s.samples]
            rss = max(x.max_rss_mib for x in s.samples)
            return (
                f"  {s.label:<28} wall min {min(walls):7.3f} s  median {statistics.median(walls):7.3f} s"
                f"   cpu median {statistics.median(cpu):7.3f} s   peak RSS {rss:7.1f} MiB"
            )

        ratios = self.ratios
        lines = [
            f"{self.name}: {len(ratios)} alternating pairs, {self.started}",
            side(self.sfap),
            side(self.peer),
            f"  ratio {self.peer.label} / {self.sfap.label}: min {min(ratios):.2f}  "
            f"median {statistics.median(ratios):.2f}  max {max(ratios):.2f}",
            f"  load average before {_load(self.load_before)}, after {_load(self.load_after)}",
        ]
        return "\n".join(lines)


def _load(values: tuple[float, float, float]) -> str:
    return " ".join(f"{v:.2f}" for v in values)


def machine() -> str:
    """CPU model, cores, memory, OS and Python: the line every figure is reported with."""
    model = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as handle:
            for line in handle:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    memory = ""
    try:
        with open("/proc/meminfo") as handle:
            kib = int(handle.readline().split()[1])
            memory = f", {kib / 1024 / 1024:.0f} GiB"
    except (OSError, ValueError, IndexError):
        pass
    line = (
        f"{model}, {os.cpu_count()} cores{memory}, {platform.system()} {platform.release()}, "
        f"Python {platform.python_version()}"
    )
    if os.environ.get("PYTHONDONTWRITEBYTECODE"):
        # The warm-up run cannot leave .pyc files: every module whose .pyc is missing or older
        # than its source is compiled again in every timed run (0.1-0.2 s for sfap's own).
        line += "; PYTHONDONTWRITEBYTECODE is set (stale .pyc files are recompiled in every run)"
    return line


def compare(
    name: str,
    sfap: Side,
    peer: Side,
    *,
    pairs: int = 5,
    warmup: bool = True,
    cwd: str | None = None,
    env: dict[str, str] | None = None,
) -> Comparison:
    """Run ``pairs`` alternating pairs (sfap first in even pairs, the peer first in odd ones).

    With ``warmup`` each side runs once untimed first (page cache, pyc files), as a user who
    runs the command a second time would see it.
    """
    if pairs < 1:
        raise ValueError(f"pairs is {pairs}; give 1 or more (5 or more for a figure worth quoting)")
    if warmup:
        for s in (sfap, peer):
            if s.before is not None:
                s.before()
            run_process(s.command, cwd=cwd, env=env)
    started = datetime.now(UTC).strftime("%Y-%m-%d %H:%M UTC")
    load_before = os.getloadavg()
    for k in range(pairs):
        order = (sfap, peer) if k % 2 == 0 else (peer, sfap)
        for s in order:
            s.run(cwd=cwd, env=env)
    return Comparison(name, sfap, peer, load_before, os.getloadavg(), started)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--pairs", type=int, default=7)
    parser.add_argument(
        "commands",
        nargs="*",
        help="-- SFAP_COMMAND -- PEER_COMMAND (each quoted); default: sfap --help against python -c pass",
    )
    args = parser.parse_args()
    sfap = str(Path(sys.executable).with_name("sfap"))
    words = [w for w in args.commands if w != "--"] or [f"{sfap} --help", f"{sys.executable} -c pass"]
    if len(words) != 2:
        parser.error("give exactly two commands, each quoted: -- 'sfap --help' -- 'python -c pass'")
    result = compare(
        "paired",
        Side(words[0], shlex.split(words[0])),
        Side(words[1], shlex.split(words[1])),
        pairs=args.pairs,
    )
    print(machine())
    print(result.report())


if __name__ == "__main__":
    main()
