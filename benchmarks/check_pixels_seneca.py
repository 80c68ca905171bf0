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
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))
from config_runs import parse_configs, run_configurations

REPO = Path(__file__).resolve().parents[1]


def _columns(report: dict[str, Any]) -> str:
    px = report.get("pixels") or {}
    verdict = "PASS" if report.get("passed") else "FAIL"
    if not px:
        return f"| - | - | - | - | - | - | {verdict} (no pixel figures in report.json)"
    quick = px.get("quick_reconstruction") or {}
    nan = float("nan")
    return (
        f"| {px.get('seconds', nan):.0f} s | {px.get('seconds_per_frame', nan):.2f} s "
        f"| {px.get('pairs_matched', '-')} of {px.get('pairs_tried', '-')} "
        f"| {quick.get('pairs_matched', '-')} | {quick.get('models', '-')} "
        f"| {quick.get('largest_model_frames_pct', nan):.0f} % | {verdict}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--images", default=str(REPO.parent / "shared" / "data" / "seneca_half" / "images"))
    parser.add_argument("--ground-elevation-m", type=float, default=220.0)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--config", action="append", default=None, help="name=extra options")
    args = parser.parse_args()
    sfap = str(REPO / ".venv" / "bin" / "sfap")
    head = [sfap, "check", args.images, "--ground-elevation-m", str(args.ground_elevation_m), "--no-progress"]
    run_configurations(
        parse_configs(args.config or ["defaults="]),
        rounds=args.rounds,
        command=lambda out, extra: [*head, "-o", str(out), *extra],
        columns=_columns,
        header="| pixel step | per frame | neighbour pairs matched | mapper pairs | models | largest model "
        "| verdict |",
    )


if __name__ == "__main__":
    main()
