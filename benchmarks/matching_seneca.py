"""Matching that scales: pairs from footprints, from positions, pycolmap's spatial matcher and
exhaustive matching on a real block (default ../shared/data/seneca_half, 167 frames), side by
side in one run.

Setup (timed, shared by every matcher): the COLMAP project of ``sfap handoff`` (cameras, images,
pose priors in the local frame) and SIFT features once, at ``--max-image-size-px``; the database
is then copied per matcher. Per matcher: matching with geometric verification on its own copy
(timed), then COLMAP's incremental mapping with the pose priors (the quick-look's options, seed
fixed; timed). Printed per matcher: pairs matched, matching time, frames registered in the largest
model (and in any model), 3D points and mean reprojection error of the largest model, and the
machine's load (``os.getloadavg``) when the matcher started.

The footprint pairs need the ground. ``--ground-elevation-m`` gives it; without it, it is taken
from the first matcher's model (the position pairs by default): the median elevation of its 3D
points once the model is placed on the pose priors by a similarity on the camera centres (the GPS
altitudes place it, to their own accuracy), and the script says so.

``--features-db PATH`` keeps the database with its features there (and reuses it when it exists),
so a second run skips the extraction.

Run: nice .venv/bin/python benchmarks/matching_seneca.py [IMAGES] [--ground-elevation-m M]
     [--max-image-size-px 1000] [--max-features 2000] [--sift-first-octave -1]
     [--matchers position,footprint,spatial,exhaustive] [--features-db /tmp/seneca_features.db]
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from processing.handoff import colmap_adapter as colmap
from processing.handoff.colmap_project import DATABASE, write_colmap_project
from processing.handoff.prepare import GroundOptions, Prepared, prepare
from processing.similarity import fit_similarity

REPO = Path(__file__).resolve().parents[1]


def _load() -> str:
    return "/".join(f"{v:.1f}" for v in os.getloadavg())


def _cpu_s() -> float:
    """This process's CPU time, every thread (user + system): on a shared machine the wall time
    follows the load, the CPU time much less."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _ground_from_model(prepared: Prepared, model: colmap.ColmapModel) -> float:
    block = prepared.block
    row = {n: k for k, n in enumerate(block.names)}
    names = [n for n in model.registered if block.has_position[row[n]]]
    src = np.array([model.views[n].centre for n in names])
    dst = np.array([block.position_m[row[n]] for n in names])
    sim = fit_similarity(src, dst)
    return float(np.median(sim.apply(model.points_xyz)[:, 2]))


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "images", nargs="?", default=str(REPO.parent / "shared" / "data" / "seneca_half" / "images")
    )
    parser.add_argument("--ground-elevation-m", type=float, default=None)
    parser.add_argument("--max-image-size-px", type=int, default=1000)
    parser.add_argument("--max-features", type=int, default=2000)
    parser.add_argument(
        "--sift-first-octave", type=int, choices=(-1, 0), default=-1, help="-1 doubles the frames first"
    )
    parser.add_argument("--matchers", default="position,footprint,spatial,exhaustive")
    parser.add_argument("--features-db", type=Path, default=None)
    args = parser.parse_args()
    matchers = args.matchers.split(",")

    by_position = prepare(args.images)  # no ground: the pairs from positions
    block = by_position.block
    n = len(block)
    print(f"{n} frames; ground: {by_position.ground_description}; load {_load()}", flush=True)
    ground_m = args.ground_elevation_m
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        write_colmap_project(by_position, root / "project")
        db = root / "project" / DATABASE
        if args.features_db is not None and args.features_db.exists():
            shutil.copy(args.features_db, db)
            print(f"features from {args.features_db}", flush=True)
        else:
            t, c = time.perf_counter(), _cpu_s()
            colmap.extract_features(
                db,
                block.image_dir,
                block.names,
                max_image_size_px=args.max_image_size_px,
                max_features=args.max_features,
                first_octave=args.sift_first_octave,
            )
            print(
                f"features at {args.max_image_size_px} px, {args.max_features} per frame, first octave "
                f"{args.sift_first_octave}: "
                f"{time.perf_counter() - t:.1f} s wall, {_cpu_s() - c:.1f} s CPU (load {_load()})",
                flush=True,
            )
            if args.features_db is not None:
                shutil.copy(db, args.features_db)
        for mode in matchers:
            load = _load()
            copy = root / f"{mode}.db"
            shutil.copy(db, copy)
            pairs_file = root / f"{mode}.txt"
            possible = n * (n - 1) // 2
            listed: int | str = "-"
            if mode == "position":
                pairs_file.write_text(by_position.pairs.text(block), encoding="utf-8")
                listed = len(by_position.pairs)
            elif mode == "footprint":
                if ground_m is None:
                    raise SystemExit("footprint pairs need --ground-elevation-m or another matcher first")
                with_ground = prepare(args.images, ground=GroundOptions(ground_elevation_m=ground_m))
                pairs_file.write_text(with_ground.pairs.text(with_ground.block), encoding="utf-8")
                listed = len(with_ground.pairs)
            t, c = time.perf_counter(), _cpu_s()
            if mode in ("position", "footprint"):
                colmap.match_pairs_file(copy, pairs_file)
            elif mode == "exhaustive":
                colmap.match_exhaustive(copy)
                listed = possible
            else:
                colmap.match_spatial(copy)
            match_s, match_cpu = time.perf_counter() - t, _cpu_s() - c
            matched, _ = colmap.verified_matches(copy)
            t, c = time.perf_counter(), _cpu_s()
            models = colmap.incremental_mapping(
                copy, block.image_dir, root / f"sparse-{mode}", use_priors=True
            )
            map_s, map_cpu = time.perf_counter() - t, _cpu_s() - c
            big = models[0] if models else None
            if ground_m is None and big is not None:
                ground_m = _ground_from_model(by_position, big)
                print(f"ground from the {mode} model's points: {ground_m:.1f} m AMSL", flush=True)
            rows.append(
                (
                    mode,
                    listed,
                    matched,
                    f"{match_s:.1f} s ({match_cpu:.0f} s CPU)",
                    len(big.registered) if big else 0,
                    len({name for m in models for name in m.registered}),
                    len(models),
                    big.num_points if big else 0,
                    big.mean_reprojection_error_px if big else float("nan"),
                    f"{map_s:.1f} s ({map_cpu:.0f} s CPU)",
                    load,
                )
            )
            print(f"  {mode}: done ({match_s:.0f} s matching, {map_s:.0f} s mapping)", flush=True)
            print(f"  row: {rows[-1]}", flush=True)
    print(f"\npossible pairs: {n * (n - 1) // 2}; ground for the footprints: {ground_m} m AMSL")
    print(
        "| matching | pairs listed | pairs verified | matching time | frames in the largest model "
        "| frames in any model (models) | 3D points (largest) | reprojection error | mapping time | load |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for mode, listed, matched, match_s, big_n, total, count, points, err, map_s, load in rows:
        print(
            f"| {mode} | {listed} | {matched} | {match_s} | {big_n} of {n} | {total} ({count}) "
            f"| {points} | {err:.2f} px | {map_s} | {load} |"
        )


if __name__ == "__main__":
    main()
