"""The check's only pycolmap code (pycolmap 4.x; its API changes between versions): SIFT features on
downscaled frames and verified matches between given pairs of them, returned as plain arrays.

:mod:`processing.pixel_match` turns the matches into overlaps, image scale and the share of
neighbours that match. This module extracts and matches, in a temporary database, with COLMAP's
log (glog, written by the C++ library to the process's standard error) sent to a log file instead
of the terminal; the quick reconstruction runs the hand-off's mapper
(:func:`processing.handoff.colmap_adapter.incremental_mapping`), the one mapping code of both.
"""

from __future__ import annotations

import logging
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from .errors import ProcessingError

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True)
class PairMatches:
    """The verified (inlier) matches of two frames: the same points in frame ``a`` and frame ``b``,
    in full-resolution pixels (x right, y down, origin at the top-left pixel's corner as COLMAP)."""

    a: str
    b: str
    xy_a: F64
    xy_b: F64

    @property
    def count(self) -> int:
        return int(self.xy_a.shape[0])


@dataclass(frozen=True, kw_only=True)
class MatchRun:
    """Every pair asked for (pairs COLMAP could not verify have no matches), each frame's size in
    pixels, and its keypoint count."""

    pairs: tuple[PairMatches, ...]
    size_px: dict[str, tuple[int, int]]
    keypoints: dict[str, int]
    models: tuple[frozenset[str], ...] | None = None


def match_pairs(
    image_dir: Path,
    names: Sequence[str],
    pairs: Sequence[tuple[str, str]],
    *,
    max_image_size_px: int,
    max_features: int,
    num_threads: int,
    log_path: Path | None,
    map_models: bool = False,
    priors_m: dict[str, tuple[float, float, float]] | None = None,
    prior_sigma_m: tuple[float, float] = (5.0, 10.0),
) -> MatchRun:
    """One camera for every frame (the check's block has one camera and image size; its
    intrinsics shared, as in a real reconstruction). SIFT on ``names`` (files in ``image_dir``)
    downscaled to ``max_image_size_px`` on their longer side, then COLMAP's matcher and two-view
    verification on ``pairs`` only; with ``map_models``, COLMAP's incremental mapper on those
    matches too (the frames each model registers, largest first); ``priors_m``: each frame's
    position in metres (a local Cartesian frame), given to the mapper as pose priors with standard
    deviations ``prior_sigma_m`` (horizontal, vertical) under a robust loss. ProcessingError when
    COLMAP fails on the images. Repeatable: the same frames and pairs give the same matches and
    models, run after run (the verification's RANSAC seeded, the mapper seeded on one thread).
    ``num_threads``: the extraction's and the matcher's."""
    import pycolmap

    from .handoff import colmap_adapter as colmap

    with tempfile.TemporaryDirectory(prefix="sfap-match-") as tmp, colmap.stderr_to(log_path):
        database = Path(tmp) / "match.db"
        pairs_file = Path(tmp) / "pairs.txt"
        pairs_file.write_text("".join(f"{a} {b}\n" for a, b in pairs), encoding="utf-8")
        try:
            pycolmap.Database.open(str(database)).close()
            pycolmap.import_images(str(database), str(image_dir), pycolmap.CameraMode.SINGLE, list(names))
            if priors_m:
                _write_priors(database, priors_m, prior_sigma_m)
            extraction = pycolmap.FeatureExtractionOptions(max_image_size=max_image_size_px)
            extraction.sift.max_num_features = max_features
            extraction.num_threads = num_threads
            pycolmap.extract_features(
                str(database),
                str(image_dir),
                list(names),
                extraction_options=extraction,
                device=pycolmap.Device.cpu,
            )
            matching = pycolmap.FeatureMatchingOptions()
            matching.num_threads = num_threads
            verification = pycolmap.TwoViewGeometryOptions()
            verification.ransac.random_seed = 1  # default: a new seed each run
            if pairs:
                pycolmap.match_image_pairs(
                    str(database),
                    matching_options=matching,
                    pairing_options=pycolmap.ImportedPairingOptions(match_list_path=str(pairs_file)),
                    verification_options=verification,
                    device=pycolmap.Device.cpu,
                )
        except (RuntimeError, ValueError) as error:
            raise ProcessingError(f"COLMAP could not match the frames: {error}") from error
        with pycolmap.Database.open(str(database)) as db:
            images = {im.name: im for im in db.read_all_images()}
            size_px: dict[str, tuple[int, int]] = {}
            keypoints: dict[str, F64] = {}
            for name, image in images.items():
                camera = db.read_camera(image.camera_id)
                size_px[name] = (int(camera.width), int(camera.height))
                if db.exists_keypoints(image.image_id):
                    kp = np.asarray(db.read_keypoints(image.image_id), dtype=np.float64)
                    keypoints[name] = kp[:, :2] if kp.size else np.zeros((0, 2))
                else:
                    keypoints[name] = np.zeros((0, 2))
            out: list[PairMatches] = []
            for a, b in pairs:
                xy_a = xy_b = np.zeros((0, 2))
                if a in images and b in images:
                    ia, ib = images[a].image_id, images[b].image_id
                    if db.exists_two_view_geometry(ia, ib):
                        geometry = db.read_two_view_geometry(ia, ib)
                        index = np.asarray(geometry.inlier_matches, dtype=np.int64).reshape(-1, 2)
                        if index.size:
                            xy_a = keypoints[a][index[:, 0]]
                            xy_b = keypoints[b][index[:, 1]]
                out.append(PairMatches(a=a, b=b, xy_a=xy_a, xy_b=xy_b))
        models: tuple[frozenset[str], ...] | None = None
        if map_models:
            models = _map(database, image_dir, Path(tmp) / "sparse", use_priors=bool(priors_m))
    return MatchRun(
        pairs=tuple(out),
        size_px=size_px,
        keypoints={name: len(kp) for name, kp in keypoints.items()},
        models=models,
    )


def _write_priors(
    database: Path, priors_m: dict[str, tuple[float, float, float]], sigma_m: tuple[float, float]
) -> None:
    import pycolmap

    with pycolmap.Database.open(str(database)) as db:
        db.clear_pose_priors()
        cov = np.diag([sigma_m[0] ** 2, sigma_m[0] ** 2, sigma_m[1] ** 2])
        for image in db.read_all_images():
            if image.name in priors_m:
                db.write_pose_prior(
                    pycolmap.PosePrior(
                        corr_data_id=image.data_id,
                        position=np.asarray(priors_m[image.name], dtype=np.float64),
                        position_covariance=cov,
                        coordinate_system=pycolmap.PosePriorCoordinateSystem.CARTESIAN,
                    )
                )


def _map(
    database: Path, image_dir: Path, output_dir: Path, *, use_priors: bool
) -> tuple[frozenset[str], ...]:
    """COLMAP's incremental mapper on the matches in ``database`` (the hand-off's
    :func:`processing.handoff.colmap_adapter.incremental_mapping`: models of 3 frames or more, the
    random seed fixed): the frames of each model, largest first.

    On one thread: the seed fixes the random numbers of the thread that sets it, not those of the
    mapper's workers, and on two threads the same matches of garfield_rgb gave a largest model of
    36 %, then 29 % of the frames (with the verification seeded too); on one, 29 % three times.
    Mapping is a small part of the check's pixel step (seneca_half: 87 s against 84 s, BENCHMARKS.md)."""
    from .handoff.colmap_adapter import incremental_mapping
    from .handoff.errors import HandoffError

    try:
        models = incremental_mapping(
            database, image_dir, output_dir, min_model_size=3, use_priors=use_priors, num_threads=1
        )
    except HandoffError as error:
        raise ProcessingError(f"COLMAP's mapper failed on the matched frames: {error.__cause__}") from error
    return tuple(frozenset(model.registered) for model in models)
