"""The hand-off's pycolmap adapter (processing/handoff/colmap_adapter.py): its options reach COLMAP."""

from __future__ import annotations

from pathlib import Path

import pytest
from PIL import Image
from textures import blob_texture

pytest.importorskip("pycolmap")

from processing.handoff import colmap_adapter as colmap


def test_sift_on_the_doubled_frame_finds_the_finer_features(tmp_path: Path) -> None:
    """COLMAP's first octave -1 doubles the frame before SIFT: on a texture with 2-px blobs it
    finds more features than octave 0, which starts at the frame's own pixels; the feature cap
    holds for both (COLMAP keeps up to two orientations a feature)."""
    import pycolmap

    images = tmp_path / "images"
    images.mkdir()
    Image.fromarray(blob_texture(400, 400, 1, cells=(2, 5, 16))).save(images / "a.png")
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
