"""The field quick-look, ``sfap handoff IMAGES --to colmap --run``, as whole processes on a real
block (default ../shared/data/seneca_half, 167 frames): configurations given as extra options,
run in alternating order (A B A B ...), each in a fresh output folder.

Printed per run: the configuration, wall time, the child's CPU time (user + system, every thread:
on the shared machine the wall time follows the load, the CPU time much less; on two quiet cores
the wall time is at least half of it), the stages' times from report.json (features, matching,
mapping, georegistration), pairs matched, frames registered, 3D points, mean reprojection error,
the cameras' RMSE against the GPS, and the machine's load (``os.getloadavg``) at the start.

Run: nice .venv/bin/python benchmarks/quicklook_seneca.py [--images DIR] [--rounds 1]
     --config "name=OPTIONS" [--config ...]
e.g. --config "defaults=" --config "global=--mapper global"
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shlex
import shutil
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
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--config", action="append", required=True, help="name=extra options")
    args = parser.parse_args()
    configs = [(c.split("=", 1)[0], shlex.split(c.split("=", 1)[1])) for c in args.config]
    sfap = str(REPO / ".venv" / "bin" / "sfap")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.rounds):
            for name, extra in configs if k % 2 == 0 else configs[::-1]:
                work = Path(tmp) / f"{name}-{k}"
                load = "/".join(f"{v:.1f}" for v in os.getloadavg())
                started = time.strftime("%H:%M", time.gmtime())
                cpu0, t0 = _children_cpu_s(), time.perf_counter()
                done = subprocess.run(
                    [sfap, "handoff", args.images, "--to", "colmap", "--run", "-o", str(work), *extra],
                    capture_output=True,
                    text=True,
                )
                wall, cpu = time.perf_counter() - t0, _children_cpu_s() - cpu0
                report = (
                    json.loads((work / "report.json").read_text()) if (work / "report.json").exists() else {}
                )
                ql = report.get("quicklook") or {}
                geo = ql.get("georegistration") or {}
                stages = ", ".join(
                    f"{s.removesuffix('_s')} {v:.0f}" for s, v in (ql.get("timings_s") or {}).items()
                )
                err = ql.get("mean_reprojection_error_px")
                row = (
                    f"| {name} | {started} | {load} | {done.returncode} | {wall:.0f} s | {cpu:.0f} s "
                    f"| {stages} "
                    f"| {ql.get('pairs_matched', '-')} | {ql.get('frames_registered', '-')} of "
                    f"{ql.get('frames_total', '-')} {ql.get('models', '')} | {ql.get('points3d', '-')} "
                    f"| {f'{err:.2f} px' if err else '-'} | "
                    + (
                        f"{geo['camera_rmse_horizontal_m']:.1f} / {geo['camera_rmse_vertical_m']:.1f} m"
                        if geo
                        else "-"
                    )
                    + " |"
                )
                rows.append(row)
                print(row, flush=True)
                if done.returncode not in (0, 1):
                    print(done.stderr[-2000:], flush=True)
                shutil.rmtree(work, ignore_errors=True)
    print(
        "\n| configuration | start UTC | load | exit | wall | CPU | stages (s) | pairs verified "
        "| registered (models) | 3D points | reprojection error | cameras vs GPS (h / v) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
