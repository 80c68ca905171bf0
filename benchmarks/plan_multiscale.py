"""Benchmark: the 100 km2 concave area with 20 holes of benchmarks/plan_large.py, at 3 cm GSD
plus a second nadir pass at 110 m ([[survey.scale]]), written with every output; then split
into sorties of a 4-hour endurance less 20 % (see SORTIES). Prints wall time and peak memory.

    .venv/bin/python benchmarks/plan_multiscale.py [--out DIR] [--no-sorties]

Each case runs in a fresh child process so that its peak memory is its own.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from plan_large import SPEC, make_area  # the same area as the large benchmark

SCALE = """
[[survey.scale]]
altitude_agl_m = 110
front_overlap_pct = 75
side_overlap_pct = 60
"""
#: From one home at the block's corner a 30-min multirotor battery cannot reach the far lines (sfap
#: refuses: the nearest line alone takes about 100 min as a sortie), so the split is timed with
#: a long-endurance vehicle: 4 h less 20 %.
SORTIES = """endurance_s = 14400
reserve_pct = 20
"""


def run_case(spec: Path, out: Path, sorties: bool) -> dict[str, float]:
    code = (
        "import json, resource, time\n"
        "t0 = time.perf_counter()\n"
        "from planner.spec import load_spec\n"
        "from planner.survey import plan_survey\n"
        "from planner.plan_folder import write_outputs\n"
        "from planner.sorties import split_sorties, write_with_sorties\n"
        "t1 = time.perf_counter()\n"
        f"plan = plan_survey(load_spec({str(spec)!r}))\n"
        "t2 = time.perf_counter()\n"
        f"sorties = split_sorties(plan) if {sorties!r} else []\n"
        "t3 = time.perf_counter()\n"
        "if sorties:\n"
        f"    write_with_sorties(plan, sorties, {str(out)!r}, overwrite=True)\n"
        "else:\n"
        f"    write_outputs(plan, {str(out)!r}, overwrite=True)\n"
        "t4 = time.perf_counter()\n"
        "peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024\n"
        "print(json.dumps({'plan_s': t2 - t1, 'split_s': t3 - t2, 'write_s': t4 - t3,\n"
        "  'peak_mb': peak, 'photos': len(plan.stations), 'passes': len(plan.passes),\n"
        "  'sorties': len(sorties), 'area_km2': plan.summary.area_m2 / 1e6}))\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"planning {spec} failed:\n{result.stderr}")
    return json.loads(result.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=None, help="keep outputs here")
    parser.add_argument("--no-sorties", action="store_true", help="plan and write only")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        make_area(folder)
        spec_text = SPEC.replace("[vehicle]", SCALE + "\n[vehicle]")
        if not args.no_sorties:
            spec_text += SORTIES
        (folder / "bench.toml").write_text(spec_text)
        out = (args.out or folder / "out") / "multiscale"
        r = run_case(folder / "bench.toml", out, not args.no_sorties)
        print(
            f"100 km2, 20 holes, 3 cm + 110 m pass: {r['area_km2']:.1f} km2, {r['passes']} passes, "
            f"{r['photos']:,} photos; plan {r['plan_s']:.1f} s, split into {r['sorties']} sorties "
            f"{r['split_s']:.1f} s, write {r['write_s']:.1f} s; peak memory {r['peak_mb']:.0f} MB"
        )


if __name__ == "__main__":
    main()
