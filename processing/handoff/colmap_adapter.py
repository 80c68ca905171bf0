"""The only module that knows pycolmap's API (written for pycolmap 4.x; it changes between
versions). Everything else works with the plain values and :class:`ColmapModel` it returns.

Database layout (COLMAP 3.12+): one camera per camera model with its intrinsics, then the
images imported with that camera (pycolmap makes a trivial rig and a frame per image), then a
pose prior per positioned image in a Cartesian local frame with its covariance. pycolmap's
importer also writes WGS84 priors from the EXIF; those are replaced by ours.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import HandoffError

log = logging.getLogger(__name__)

F64 = NDArray[np.float64]


@contextlib.contextmanager
def stderr_to(log_path: Path | None) -> Iterator[None]:
    """Send file descriptor 2 (where COLMAP's glog writes) to ``log_path`` (appended) for the block."""
    if log_path is None:
        yield
        return
    sys.stderr.flush()
    saved = os.dup(2)
    with open(log_path, "ab") as target:
        os.dup2(target.fileno(), 2)
        try:
            yield
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)


def _threads() -> int:
    """Threads for COLMAP's extraction, matching and mapping: every core, up to 4."""
    return min(os.cpu_count() or 1, 4)


def version() -> str:
    import pycolmap

    return str(pycolmap.__version__)


@dataclass(frozen=True, kw_only=True)
class CameraSpec:
    width_px: int
    height_px: int
    focal_px: float
    principal_xy_px: tuple[float, float]


@dataclass(frozen=True, kw_only=True)
class PriorSpec:
    name: str
    position_m: tuple[float, float, float]
    sigma_xy_m: float
    sigma_z_m: float


def write_database(
    database: Path,
    image_dir: Path,
    cameras: Sequence[CameraSpec],
    images_by_camera: Sequence[Sequence[str]],
    priors: Sequence[PriorSpec],
) -> None:
    """Create ``database``: the cameras (SIMPLE_RADIAL, prior focal length), the images of each
    camera, and one Cartesian pose prior per entry of ``priors`` (covariance diag(sxy², sxy², sz²))."""
    import pycolmap

    camera_ids: list[int] = []
    with pycolmap.Database.open(str(database)) as db:
        for spec in cameras:
            cx, cy = spec.principal_xy_px
            camera = pycolmap.Camera(
                model="SIMPLE_RADIAL",
                width=spec.width_px,
                height=spec.height_px,
                params=[spec.focal_px, cx, cy, 0.0],
                has_prior_focal_length=True,
            )
            camera_ids.append(int(db.write_camera(camera)))
    for camera_id, names in zip(camera_ids, images_by_camera, strict=True):
        if names:
            pycolmap.import_images(
                str(database),
                str(image_dir),
                pycolmap.CameraMode.SINGLE,
                list(names),
                pycolmap.ImageReaderOptions(existing_camera_id=camera_id),
            )
    with pycolmap.Database.open(str(database)) as db:
        db.clear_pose_priors()
        by_name = {im.name: im for im in db.read_all_images()}
        for p in priors:
            image = by_name[p.name]
            cov = np.diag([p.sigma_xy_m**2, p.sigma_xy_m**2, p.sigma_z_m**2])
            db.write_pose_prior(
                pycolmap.PosePrior(
                    corr_data_id=image.data_id,
                    position=np.array(p.position_m, dtype=np.float64),
                    position_covariance=cov,
                    coordinate_system=pycolmap.PosePriorCoordinateSystem.CARTESIAN,
                )
            )


def extract_features(
    database: Path,
    image_dir: Path,
    names: Sequence[str],
    *,
    max_image_size_px: int,
    max_features: int,
    first_octave: int = -1,
) -> None:
    """SIFT on frames downscaled so their longer side is at most ``max_image_size_px`` (keypoints
    are written in full-resolution pixels), on every core (up to 4). ``first_octave``: -1 (COLMAP's
    default) doubles the frame before the first octave, for the finest features, at about three
    times the time; 0 starts at the frame's own pixels."""
    import pycolmap

    options = pycolmap.FeatureExtractionOptions(max_image_size=max_image_size_px)
    options.sift.max_num_features = max_features
    options.sift.first_octave = first_octave
    options.num_threads = _threads()
    pycolmap.extract_features(
        str(database), str(image_dir), list(names), extraction_options=options, device=pycolmap.Device.cpu
    )


def keypoint_counts(database: Path) -> dict[str, int]:
    import pycolmap

    with pycolmap.Database.open(str(database)) as db:
        return {im.name: int(db.num_keypoints_for_image(im.image_id)) for im in db.read_all_images()}


def match_pairs_file(database: Path, pairs_file: Path) -> None:
    """Match the pairs listed in ``pairs_file`` ("name1 name2" lines) and verify them, on every
    core (up to 4)."""
    import pycolmap

    matching = pycolmap.FeatureMatchingOptions()
    matching.num_threads = _threads()
    pycolmap.match_image_pairs(
        str(database),
        matching_options=matching,
        pairing_options=pycolmap.ImportedPairingOptions(match_list_path=str(pairs_file)),
        device=pycolmap.Device.cpu,
    )


def match_exhaustive(database: Path) -> None:
    import pycolmap

    pycolmap.match_exhaustive(str(database), device=pycolmap.Device.cpu)


def match_spatial(database: Path) -> None:
    """pycolmap's spatial matching on the pose priors (its defaults: nearest 50 within 100 units)."""
    import pycolmap

    pycolmap.match_spatial(str(database), device=pycolmap.Device.cpu)


def verified_matches(database: Path) -> tuple[int, dict[str, int]]:
    """(number of pairs matched, inlier matches per image summed over its verified pairs)."""
    import pycolmap

    with pycolmap.Database.open(str(database)) as db:
        name_of = {im.image_id: im.name for im in db.read_all_images()}
        per_image = dict.fromkeys(name_of.values(), 0)
        pair_ids, inliers = db.read_two_view_geometry_num_inliers()
        for pair_id, count in zip(pair_ids, inliers, strict=True):
            a, b = pycolmap.pair_id_to_image_pair(pair_id)
            per_image[name_of[a]] += int(count)
            per_image[name_of[b]] += int(count)
        return int(db.num_matched_image_pairs()), per_image


class ColmapView:
    """A registered image of a model as a :class:`processing.accuracy.View`."""

    def __init__(self, image: Any, camera: Any) -> None:
        pose = image.cam_from_world()
        self._r = np.asarray(pose.rotation.matrix(), dtype=np.float64)
        self._t = np.asarray(pose.translation, dtype=np.float64).reshape(3)
        self._camera = camera

    @property
    def centre(self) -> F64:
        return np.asarray(-self._r.T @ self._t, dtype=np.float64)

    def rays(self, pixels_xy: F64) -> F64:
        px = np.atleast_2d(np.asarray(pixels_xy, dtype=np.float64))
        xy = np.asarray(self._camera.cam_from_img(px), dtype=np.float64)
        cam = np.column_stack([xy, np.ones(len(xy))])
        world = cam @ self._r
        return np.asarray(world / np.linalg.norm(world, axis=1, keepdims=True), dtype=np.float64)

    def project(self, points: F64) -> F64:
        p = np.atleast_2d(np.asarray(points, dtype=np.float64))
        cam = p @ self._r.T + self._t
        return np.asarray(self._camera.img_from_cam(cam, check_cheirality=False), dtype=np.float64)


@dataclass(frozen=True, kw_only=True)
class ColmapModel:
    """One reconstruction: registered images and their views, points and statistics."""

    handle: Any
    registered: tuple[str, ...]
    views: dict[str, ColmapView]
    points_xyz: F64
    track_lengths: NDArray[np.int64]
    mean_reprojection_error_px: float
    focal_px: tuple[float, ...]

    @property
    def num_points(self) -> int:
        return int(self.points_xyz.shape[0])

    @property
    def mean_track_length(self) -> float:
        return float(self.track_lengths.mean()) if len(self.track_lengths) else 0.0


def _wrap(rec: Any) -> ColmapModel:
    views: dict[str, ColmapView] = {}
    for image_id in rec.reg_image_ids():
        image = rec.image(image_id)
        views[image.name] = ColmapView(image, rec.camera(image.camera_id))
    points = rec.points3D
    xyz = np.array([p.xyz for p in points.values()], dtype=np.float64).reshape(-1, 3)
    tracks = np.array([p.track.length() for p in points.values()], dtype=np.int64)
    return ColmapModel(
        handle=rec,
        registered=tuple(sorted(views)),
        views=views,
        points_xyz=xyz,
        track_lengths=tracks,
        mean_reprojection_error_px=float(rec.compute_mean_reprojection_error()),
        focal_px=tuple(float(c.params[0]) for c in rec.cameras.values()),
    )


def incremental_mapping(
    database: Path,
    image_dir: Path,
    output_dir: Path,
    *,
    min_model_size: int = 3,
    use_priors: bool = False,
    num_threads: int | None = None,
) -> list[ColmapModel]:
    """COLMAP's incremental mapper on the matches in ``database`` (the random seed fixed, models
    of ``min_model_size`` frames or more); the models it kept, largest first. ``use_priors``: the
    pose priors constrain the bundle adjustment (robust loss), so a frame matched to the wrong
    place cannot pull the model apart. ``num_threads``: None for every core (up to 4). The one
    mapping code of the hand-off's quick-look and the check's quick reconstruction
    (:mod:`processing.pixel_colmap`). HandoffError when COLMAP fails."""
    import pycolmap

    output_dir.mkdir(parents=True, exist_ok=True)
    options = pycolmap.IncrementalPipelineOptions()
    options.min_model_size = min_model_size
    options.num_threads = num_threads if num_threads is not None else _threads()
    options.random_seed = 1
    if use_priors:
        options.use_prior_position = True
        options.use_robust_loss_on_prior_position = True
    try:
        result = pycolmap.incremental_mapping(str(database), str(image_dir), str(output_dir), options=options)
    except RuntimeError as error:
        raise HandoffError(f"COLMAP's mapper failed: {error}") from error
    models = [_wrap(rec) for rec in result.values()]
    return sorted(models, key=lambda m: len(m.registered), reverse=True)


def transform_model(model: ColmapModel, scale: float, rotation: F64, translation: F64) -> ColmapModel:
    """The model moved by ``x -> scale * rotation @ x + translation`` (new views and points)."""
    import pycolmap

    sim = pycolmap.Sim3d(
        scale, pycolmap.Rotation3d(np.asarray(rotation, dtype=np.float64)), np.asarray(translation)
    )
    model.handle.transform(sim)
    return _wrap(model.handle)


def write_model(model: ColmapModel, folder: Path) -> None:
    """COLMAP's binary model files (cameras.bin, images.bin, points3D.bin...) in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    model.handle.write(str(folder))


def read_model(folder: Path) -> ColmapModel:
    import pycolmap

    return _wrap(pycolmap.Reconstruction(str(folder)))


# --- The hand-off's quick-look: COLMAP's global mapper (GLOMAP) ------------------------------------


def global_mapping(
    database: Path, image_dir: Path, output_dir: Path, *, min_model_size: int = 3
) -> list[ColmapModel]:
    """COLMAP's global mapper (GLOMAP, in COLMAP since 3.12): rotation averaging, then every
    camera and point placed at once, then bundle adjustment; the models it kept, largest first. It
    takes no pose priors: the quick-look places its model on them afterwards."""
    import pycolmap

    output_dir.mkdir(parents=True, exist_ok=True)
    options = pycolmap.GlobalPipelineOptions()
    options.min_model_size = min_model_size
    options.num_threads = _threads()
    options.random_seed = 1
    try:
        result = pycolmap.global_mapping(str(database), str(image_dir), str(output_dir), options=options)
    except RuntimeError as error:
        raise HandoffError(f"COLMAP's global mapper failed: {error}") from error
    models = [_wrap(rec) for rec in result.values()]
    return sorted(models, key=lambda m: len(m.registered), reverse=True)
