"""Benchmark: plan a 100 km2 concave area with 20 holes at 3 cm GSD and write every output;
then the oblique example (missions/quarry-block.toml). Prints wall time and peak memory.

    .venv/bin/python benchmarks/plan_large.py [--out DIR]

Target (issue 2): under 30 s and 2 GB peak memory for the large area on this machine
(2 cores). Each case runs in a fresh child process so that its peak memory is its own; the total
is that process's wall time, start-up and imports included. For small plans against a peer see
plan_vs_flightplan.py.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

SPEC = """
name = "Benchmark: 100 km2 concave block with 20 holes"
area = "area.geojson"

[camera]
model = "dji-phantom-4-pro"

[survey]
gsd_cm = 3.0
front_overlap_pct = 88
side_overlap_pct = 80
speed_m_s = 6
direction_deg = "auto"
turnaround_m = 20
exclusion_clearance_m = 5

[vehicle]
type = "multirotor"
takeoff_alt_m = 40
max_alt_agl_m = 120
"""


def make_area(folder: Path) -> None:
    """An L-shaped 100 km2 block (concave) with 20 polygonal holes, near Zaragoza."""
    lon0, lat0 = -0.90, 41.60
    m_lon = 111_320.0 * math.cos(math.radians(lat0))
    m_lat = 111_132.0

    def ll(x: float, y: float) -> list[float]:
        return [round(lon0 + x / m_lon, 9), round(lat0 + y / m_lat, 9)]

    # 13 km x 11 km minus a 8.5 km x 5.4 km notch: about 97 km2 before the holes
    outer = [ll(0, 0), ll(13000, 0), ll(13000, 11000), ll(8500, 11000), ll(8500, 5600), ll(0, 5600)]
    outer = [*outer, outer[0]]
    holes = []
    k = 0
    for i in range(5):
        for j in range(4):
            cx = 1200 + i * 2300 + (j % 2) * 400
            cy = 900 + j * 1200
            if cx > 8000 and cy > 5000:
                cy -= 3000
            r = 120 + 40 * ((i + j) % 3)
            ring = [ll(cx + r * math.cos(a), cy + r * math.sin(a) * 0.7)
                    for a in [2 * math.pi * t / 7 for t in range(7)]]  # fmt: skip
            holes.append([*ring, ring[0]][::-1])
            k += 1
    geojson = {"type": "Feature", "properties": {"name": "bench"},
               "geometry": {"type": "Polygon", "coordinates": [outer, *holes]}}  # fmt: skip
    (folder / "area.geojson").write_text(json.dumps(geojson))
    (folder / "bench.toml").write_text(SPEC)


def run_case(spec: Path, out: Path) -> dict[str, float]:
    code = (
        "import json, resource, sys, time\n"
        "t0 = time.perf_counter()\n"
        "from planner.spec import load_spec\n"
        "from planner.survey import plan_survey\n"
        "from planner.plan_folder import write_outputs\n"
        "t1 = time.perf_counter()\n"
        f"plan = plan_survey(load_spec({str(spec)!r}))\n"
        "t2 = time.perf_counter()\n"
        f"write_outputs(plan, {str(out)!r}, overwrite=True)\n"
        "t3 = time.perf_counter()\n"
        "peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024\n"
        "print(json.dumps({'import_s': t1 - t0, 'plan_s': t2 - t1, 'write_s': t3 - t2,\n"
        "  'total_s': t3 - t0, 'peak_mb': peak, 'photos': len(plan.stations),\n"
        "  'items': len(plan.mission.items), 'area_km2': plan.summary.area_m2 / 1e6}))\n"
    )
    start = time.perf_counter()
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    process_s = time.perf_counter() - start
    if result.returncode != 0:
        raise SystemExit(f"planning {spec} failed:\n{result.stderr}")
    figures: dict[str, float] = json.loads(result.stdout.strip().splitlines()[-1])
    figures["process_s"] = process_s  # start-up and imports included
    return figures


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=None, help="keep outputs here")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        make_area(folder)
        out_root = args.out or folder / "out"
        cases = [
            ("large concave 100 km2, 20 holes, 3 cm", folder / "bench.toml", out_root / "large"),
            (
                "oblique example (quarry-block)",
                REPO / "missions" / "quarry-block.toml",
                out_root / "quarry",
            ),
        ]
        for label, spec, out in cases:
            r = run_case(spec, out)
            print(
                f"{label}: area {r['area_km2']:.1f} km2, {r['photos']:,} photos, {r['items']:,} items; "
                f"total {r['process_s']:.1f} s as a whole process (imports {r['import_s']:.1f} s, "
                f"plan {r['plan_s']:.1f} s, write {r['write_s']:.1f} s); "
                f"peak RSS {r['peak_mb']:.0f} MiB; load {' '.join(format(v, '.2f') for v in os.getloadavg())}"
            )


if __name__ == "__main__":
    main()
