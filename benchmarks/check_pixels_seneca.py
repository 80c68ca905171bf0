"""The field check with its pixel step, ``sfap check IMAGES --ground-elevation-m M -o REPORT``, as
whole processes on a real block (default ../shared/data/seneca_half): configurations given as extra
options, run in alternating order (A B A B ...), each into a fresh report folder.

Printed per run: the configuration, wall time, the child's CPU time (user + system, every thread),
the pixel step's own time and seconds per frame (report.json ``pixels.seconds``), the neighbour
pairs matched, the pairs the quick reconstruction matched, its models and the share of the frames
its largest model registers, the check's verdict, and the machine's load (``os.getloadavg``) at the
start.

Run: .venv/bin/python benchmarks/check_pixels_seneca.py [--images DIR] [--ground-elevation-m 220]
     [--rounds 1] [--config "name=OPTIONS" ...]   (default: one configuration, the defaults)
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shlex
import subprocess
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--images", default=str(REPO.parent / "shared" / "data" / "seneca_half" / "images"))
    parser.add_argument("--ground-elevation-m", type=float, default=220.0)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--config", action="append", default=None, help="name=extra options")
    args = parser.parse_args()
    configs = [(c.split("=", 1)[0], shlex.split(c.split("=", 1)[1])) for c in (args.config or ["defaults="])]
    sfap = str(REPO / ".venv" / "bin" / "sfap")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.rounds):
            for name, extra in configs if k % 2 == 0 else configs[::-1]:
                out = Path(tmp) / f"{name}-{k}"
                load = "/".join(f"{v:.1f}" for v in os.getloadavg())
                started = time.strftime("%H:%M", time.gmtime())
                cpu0, t0 = _children_cpu_s(), time.perf_counter()
                done = subprocess.run(
                    [
                        sfap,
                        "check",
                        args.images,
                        "--ground-elevation-m",
                        str(args.ground_elevation_m),
                        "--no-progress",
                        "-o",
                        str(out),
                        *extra,
                    ],
                    capture_output=True,
                    text=True,
                )
                wall, cpu = time.perf_counter() - t0, _children_cpu_s() - cpu0
                report = (
                    json.loads((out / "report.json").read_text()) if (out / "report.json").exists() else {}
                )
                px = report.get("pixels") or {}
                nan = float("nan")
                quick = px.get("quick_reconstruction") or {}
                frames = report.get("frames") or report.get("frame_count") or "-"
                row = (
                    f"| {name} | {started} | {load} | {done.returncode} | {wall:.0f} s | {cpu:.0f} s "
                    f"| {px.get('seconds', nan):.0f} s | {px.get('seconds_per_frame', nan):.2f} s "
                    f"| {px.get('pairs_matched', '-')} of {px.get('pairs_tried', '-')} "
                    f"| {quick.get('pairs_matched', '-')} | {quick.get('models', '-')} "
                    f"| {quick.get('largest_model_frames_pct', float('nan')):.0f} % "
                    f"| {'PASS' if report.get('passed') else 'FAIL'} |"
                )
                rows.append(row)
                print(row, flush=True)
                if done.returncode not in (0, 1):
                    print(done.stderr[-2000:], flush=True)
                elif not px:
                    print(f"no pixel figures in report.json ({frames} frames)", flush=True)
    print(
        "\n| configuration | start UTC | load | exit | wall | CPU | pixel step | per frame "
        "| neighbour pairs matched | mapper pairs | models | largest model | verdict |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
