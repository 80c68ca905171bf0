"""Synthetic ground for the tests that run COLMAP on frames cut from one picture at known offsets."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def blob_texture(width: int, height: int, seed: int, cells: Sequence[int] = (4, 9, 23, 61)) -> np.ndarray:
    """Random blobs of each size in ``cells`` (pixels) summed, 8-bit grey: features SIFT finds at
    every octave, the same picture for the same seed."""
    rng = np.random.default_rng(seed)
    image = np.zeros((height, width))
    for cell in cells:
        coarse = rng.normal(size=(height // cell + 2, width // cell + 2))
        image += np.kron(coarse, np.ones((cell, cell)))[:height, :width]
    image -= image.min()
    return (255 * image / image.max()).astype(np.uint8)
