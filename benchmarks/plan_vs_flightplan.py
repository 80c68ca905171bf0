"""Small plans, whole process against whole process: `sfap plan` against hotosm's drone-flightplan.

The crews' everyday plans are small. Each case runs both tools as the command a user runs, in a
fresh process (start-up and imports included), in alternating pairs (benchmarks/paired.py):

- ``sfap plan SPEC -o OUT --overwrite --no-progress``: all nine outputs (.plan, .waypoints, four
  GeoJSON files, KML, map.png, summary.json);
- ``python -m drone_flightplan.create_flightplan --project_geojson AREA --gsd G --forward_overlap F
  --side_overlap S --drone_type DJI_MINI_4_PRO --use_centroid_as_take_off_point --outfile OUT``
  (drone-flightplan 1.0.0 from PyPI; its one output, a DJI WPML .kmz).

The cases, same area, GSD and overlaps for both, a DJI Mini 4 Pro (12 MP) for both:

- ``gully``: missions/bardenas-gully.geojson (about 2.6 ha), 2.4 cm, 80 % / 70 %;
- ``square``: a 1 km x 1 km square near the gully, 2.4 cm, 80 % / 70 %.

And ``sfap --help`` against ``python -c pass`` (Python's own start-up).

drone-flightplan pins gdal==3.10.3, which has no wheel and needs GDAL's headers to build; it runs
with Debian's GDAL 3.6.2 bindings (``apt-get install python3-gdal``) in a venv made with
``/usr/bin/python3 -m venv --system-site-packages V; V/bin/pip install --no-deps drone-flightplan;
V/bin/pip install geojson pyproj shapely``. Give that venv's python with ``--peer-python``.

Run: .venv/bin/python benchmarks/plan_vs_flightplan.py --peer-python V/bin/python [--pairs 5]
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from paired import Side, compare, machine

REPO = Path(__file__).resolve().parents[1]
GSD_CM, FORWARD_PCT, SIDE_PCT = 2.4, 80, 70

SPEC = """name = "{name}"
area = "{area}"

[camera]
model = "dji-mini-4-pro"

[survey]
gsd_cm = {gsd}
front_overlap_pct = {forward}
side_overlap_pct = {side}
speed_m_s = 5
direction_deg = "auto"
turnaround_m = 10

[vehicle]
type = "multirotor"
takeoff_alt_m = 30
max_alt_agl_m = 120
autopilot = "ardupilot"
"""


def square_geojson(path: Path, side_m: float = 1000.0) -> None:
    lon0, lat0 = -1.4866, 42.2012
    m_lon = 111_320.0 * math.cos(math.radians(lat0))
    d_lon, d_lat = side_m / m_lon, side_m / 111_132.0
    ring = [[lon0, lat0], [lon0 + d_lon, lat0], [lon0 + d_lon, lat0 + d_lat], [lon0, lat0 + d_lat]]
    ring = [[round(x, 9), round(y, 9)] for x, y in [*ring, ring[0]]]
    doc = {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "properties": {"name": "1 km2 square"},
                "geometry": {"type": "Polygon", "coordinates": [ring]},
            }
        ],
    }
    path.write_text(json.dumps(doc))


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--peer-python", type=Path, default=None, help="python with drone_flightplan")
    parser.add_argument("--cases", default="help,gully,square", help="comma-separated: help,gully,square")
    args = parser.parse_args()
    sfap = str(Path(sys.executable).with_name("sfap"))
    cases = args.cases.split(",")
    print(machine())
    with tempfile.TemporaryDirectory(prefix="plan-bench-") as tmp:
        work = Path(tmp)
        if "help" in cases:
            result = compare(
                "sfap --help against Python's start-up",
                Side("sfap --help", [sfap, "--help"]),
                Side("python -c pass", [sys.executable, "-c", "pass"]),
                pairs=max(args.pairs, 10),
            )
            print(result.report(), flush=True)
        areas = {"gully": REPO / "missions" / "bardenas-gully.geojson", "square": work / "square.geojson"}
        square_geojson(areas["square"])
        for case in ("gully", "square"):
            if case not in cases:
                continue
            area = areas[case]
            spec = work / f"{case}.toml"
            spec.write_text(SPEC.format(name=case, area=area, gsd=GSD_CM, forward=FORWARD_PCT, side=SIDE_PCT))
            out_sfap, out_peer = work / f"sfap_{case}", work / f"peer_{case}"
            sfap_side = Side(
                f"sfap plan ({case})",
                [sfap, "plan", str(spec), "-o", str(out_sfap), "--overwrite", "--no-progress"],
                before=lambda o=out_sfap: shutil.rmtree(o, ignore_errors=True),  # type: ignore[misc]
            )
            if args.peer_python is None:
                only = compare(
                    f"sfap plan ({case}), no peer given",
                    sfap_side,
                    Side("python -c pass", [sys.executable, "-c", "pass"]),
                    pairs=args.pairs,
                )
                print(only.report(), flush=True)
                continue
            peer_side = Side(
                f"drone-flightplan ({case})",
                [
                    str(args.peer_python),
                    *("-m", "drone_flightplan.create_flightplan", "--project_geojson", str(area)),
                    *("--gsd", str(GSD_CM), "--forward_overlap", str(FORWARD_PCT)),
                    *("--side_overlap", str(SIDE_PCT), "--drone_type", "DJI_MINI_4_PRO"),
                    *("--use_centroid_as_take_off_point", "--outfile", str(out_peer)),
                ],
                before=lambda o=out_peer: shutil.rmtree(o, ignore_errors=True),  # type: ignore[misc]
            )
            result = compare(f"plan {case}", sfap_side, peer_side, pairs=args.pairs)
            print(result.report(), flush=True)
            summary = json.loads((out_sfap / "summary.json").read_text())
            print(
                f"  sfap: {summary['photo_count']} photos, {summary['line_count']} lines, "
                f"{len(list(out_sfap.iterdir()))} files; drone-flightplan: "
                f"{[p.name for p in out_peer.rglob('*') if p.is_file()]}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
