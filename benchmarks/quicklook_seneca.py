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
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from config_runs import parse_configs, run_configurations

REPO = Path(__file__).resolve().parents[1]


def _columns(report: dict[str, Any]) -> str:
    ql = report.get("quicklook") or {}
    geo = ql.get("georegistration") or {}
    stages = ", ".join(f"{s.removesuffix('_s')} {v:.0f}" for s, v in (ql.get("timings_s") or {}).items())
    err = ql.get("mean_reprojection_error_px")
    rmse = f"{geo['camera_rmse_horizontal_m']:.1f} / {geo['camera_rmse_vertical_m']:.1f} m" if geo else "-"
    return (
        f"| {stages} | {ql.get('pairs_matched', '-')} | {ql.get('frames_registered', '-')} of "
        f"{ql.get('frames_total', '-')} {ql.get('models', '')} | {ql.get('points3d', '-')} "
        f"| {f'{err:.2f} px' if err else '-'} | {rmse}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--images", default=str(REPO.parent / "shared" / "data" / "seneca_half" / "images"))
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--config", action="append", required=True, help="name=extra options")
    args = parser.parse_args()
    head = [str(REPO / ".venv" / "bin" / "sfap"), "handoff", args.images, "--to", "colmap", "--run"]
    run_configurations(
        parse_configs(args.config),
        rounds=args.rounds,
        command=lambda out, extra: [*head, "-o", str(out), *extra],
        columns=_columns,
        header="| stages (s) | pairs verified | registered (models) | 3D points | reprojection error "
        "| cameras vs GPS (h / v) |",
    )


if __name__ == "__main__":
    main()
