"""The hand-off's pycolmap adapter (processing/handoff/colmap_adapter.py): its options reach COLMAP."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

pytest.importorskip("pycolmap")

from processing.handoff import colmap_adapter as colmap


def _texture(size: int, seed: int) -> np.ndarray:
    """Blobs of 2-16 px (features at every octave, the finest below the frame's own pixels)."""
    rng = np.random.default_rng(seed)
    image = np.zeros((size, size))
    for cell in (2, 5, 16):
        coarse = rng.normal(size=(size // cell + 2, size // cell + 2))
        image += np.kron(coarse, np.ones((cell, cell)))[:size, :size]
    image -= image.min()
    return (255 * image / image.max()).astype(np.uint8)


def test_sift_on_the_doubled_frame_finds_the_finer_features(tmp_path: Path) -> None:
    """COLMAP's first octave -1 doubles the frame before SIFT: on a texture with 2-px blobs it
    finds more features than octave 0, which starts at the frame's own pixels; the feature cap
    holds for both (COLMAP keeps up to two orientations a feature)."""
    import pycolmap

    images = tmp_path / "images"
    images.mkdir()
    Image.fromarray(_texture(400, 1)).save(images / "a.png")
    counts = {}
    for octave in (-1, 0):
        db = tmp_path / f"o{octave}.db"
        pycolmap.Database.open(str(db)).close()
        pycolmap.import_images(str(db), str(images), pycolmap.CameraMode.SINGLE, ["a.png"])
        colmap.extract_features(
            db, images, ["a.png"], max_image_size_px=400, max_features=3000, first_octave=octave
        )
        counts[octave] = colmap.keypoint_counts(db)["a.png"]
    assert counts[-1] > 1.3 * counts[0] > 0, counts
    assert max(counts.values()) <= 2 * 3000
