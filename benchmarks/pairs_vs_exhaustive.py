"""Image pairs from ground footprints against pycolmap's exhaustive and spatial matching, on a
real block, side by side in one run.

Setup (timed separately, shared): the COLMAP project of ``sfap handoff`` (cameras, images, pose
priors in the local frame, footprint pairs) and SIFT features on frames downscaled to
``--max-image-size-px``; the database is then copied three times. Timed per matcher: matching
(with geometric verification) on its own copy, then COLMAP's incremental mapping (the same
options for all three, random seed fixed). Printed per matcher: pairs matched, matching time,
frames registered in the largest model and in any model, 3D points of the largest model.

The spatial matcher uses pycolmap's defaults (the 50 nearest frames within 100 units of the
pose priors, which here are metres).

Run: .venv/bin/python benchmarks/pairs_vs_exhaustive.py [IMAGES] [--ground-elevation-m 258]
     [--max-image-size-px 1000] (default: ../shared/data/garfield_rgb over ground at 258 m AMSL)
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

from processing.handoff import colmap_adapter as colmap
from processing.handoff.colmap_project import DATABASE, PAIRS, write_colmap_project
from processing.handoff.prepare import GroundOptions, prepare

REPO = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("images", nargs="?", default=str(REPO.parent / "shared" / "data" / "garfield_rgb"))
    parser.add_argument("--ground-elevation-m", type=float, default=258.0)
    parser.add_argument("--max-image-size-px", type=int, default=1000)
    parser.add_argument("--max-features", type=int, default=4000)
    parser.add_argument("--min-overlap-pct", type=float, default=5.0)
    args = parser.parse_args()

    prepared = prepare(
        args.images,
        ground=GroundOptions(ground_elevation_m=args.ground_elevation_m),
        min_overlap_pct=args.min_overlap_pct,
    )
    n = len(prepared.block)
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        write_colmap_project(prepared, root / "project")
        db = root / "project" / DATABASE
        t = time.perf_counter()
        colmap.extract_features(
            db,
            prepared.block.image_dir,
            prepared.block.names,
            max_image_size_px=args.max_image_size_px,
            max_features=args.max_features,
        )
        print(
            f"{n} frames; features at {args.max_image_size_px} px: {time.perf_counter() - t:.1f} s",
            flush=True,
        )
        rows = []
        for mode in ("footprint", "exhaustive", "spatial"):
            copy = root / f"{mode}.db"
            shutil.copy(db, copy)
            t = time.perf_counter()
            if mode == "footprint":
                colmap.match_pairs_file(copy, root / "project" / PAIRS)
            elif mode == "exhaustive":
                colmap.match_exhaustive(copy)
            else:
                colmap.match_spatial(copy)
            match_s = time.perf_counter() - t
            pairs, _ = colmap.verified_matches(copy)
            t = time.perf_counter()
            models = colmap.incremental_mapping(copy, prepared.block.image_dir, root / f"sparse-{mode}")
            map_s = time.perf_counter() - t
            largest = models[0] if models else None
            rows.append(
                (
                    mode,
                    pairs,
                    match_s,
                    len(largest.registered) if largest else 0,
                    len({name for m in models for name in m.registered}),
                    len(models),
                    largest.num_points if largest else 0,
                    map_s,
                )
            )
            print(f"  {mode}: done", flush=True)
    print(f"\npossible pairs: {n * (n - 1) // 2}")
    print(
        "| matching | pairs matched | matching time | frames in the largest model "
        "| frames in any model (models) | 3D points (largest) | mapping time |"
    )
    print("|---|---|---|---|---|---|---|")
    for mode, pairs, match_s, big, total, count, points, map_s in rows:
        print(
            f"| {mode} | {pairs} | {match_s:.1f} s | {big} of {n} | {total} ({count}) "
            f"| {points} | {map_s:.1f} s |"
        )


if __name__ == "__main__":
    main()
