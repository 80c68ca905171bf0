"""A block without positions judged on its pixels alone (processing/check_pixels.py, sfap check).

Oracles: a construction (frames cut from two unrelated textures cannot be one model) and
copr_kap's own reconstruction (38 of its 41 kite frames in COLMAP's largest model, `sfap handoff
--run` at 1200 px, BENCHMARKS.md)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given
from hypothesis import strategies as st
from PIL import Image
from shared_data import SHARED_DATA
from textures import blob_texture

from processing.check_pixels import MAX_EXHAUSTIVE_FRAMES, SEQUENTIAL_WINDOW, pairs_without_positions
from sfap.cli import cli

COPR = SHARED_DATA / "copr_kap" / "images"


@given(st.integers(min_value=0, max_value=150))
def test_pairs_without_positions_are_every_pair_then_a_sliding_window(count: int) -> None:
    pairs = pairs_without_positions(count)
    assert (pairs[:, 0] < pairs[:, 1]).all() and len({tuple(p) for p in pairs.tolist()}) == len(pairs)
    if count <= MAX_EXHAUSTIVE_FRAMES:
        assert len(pairs) == count * (count - 1) // 2
    else:
        partners = np.bincount(pairs[:, 0], minlength=count)
        expected = [min(SEQUENTIAL_WINDOW, count - 1 - i) for i in range(count)]
        assert partners.tolist() == expected
        assert (pairs[:, 1] - pairs[:, 0] <= SEQUENTIAL_WINDOW).all()


@pytest.mark.slow  # COLMAP's SIFT, matching and mapper on 10 synthetic frames: 20-60 s
def test_frames_of_two_unrelated_grounds_without_positions_fail_as_two_parts(tmp_path: Path) -> None:
    """Five frames cut along one texture and five along another (no GPS tags: PIL writes none):
    two parts of 50 % each, under the 70 % one part must hold: FAIL, exit 1, and the report says
    what was not judged."""
    for seed, prefix in ((1, "a"), (2, "b")):
        texture = blob_texture(800 + 4 * 200, 600, seed=seed)
        for k in range(5):
            Image.fromarray(texture[:, 200 * k : 200 * k + 800]).save(
                tmp_path / f"{prefix}{k}.jpg", quality=95
            )
    out = tmp_path.parent / f"{tmp_path.name}-report"
    result = CliRunner().invoke(cli, ["check", str(tmp_path), "--no-progress", "--json", "-o", str(out)])
    assert result.exit_code == 1, result.output
    data = json.loads(result.stdout)
    assert data["judged_on"] == "pixels only (no positions)" and data["verdict"] == "fail"
    pixels = data["pixels"]
    assert pixels["connected_parts"] == 2 and pixels["largest_part_frames_pct"] == pytest.approx(50.0)
    assert pixels["pairs_tried"] == 45  # every pair of 10 frames
    assert any("separate parts" in r for r in data["reasons"])
    assert any("coverage, gaps, GSD, B/H and blur were not judged" in w for w in data["warnings"])
    assert json.loads((out / "report.json").read_text())["verdict"] == "fail"
    assert (out / "colmap-match.log").stat().st_size > 0


@pytest.mark.slow  # 41 frames, all 820 pairs through COLMAP and its mapper: 2-10 minutes (load)
def test_copr_kap_without_gps_is_judged_on_its_pixels_as_its_reconstruction(tmp_path: Path) -> None:
    """copr_kap's kite frames have no GPS. COLMAP's reconstruction (`sfap handoff --run`, 1200 px,
    exhaustive) registers 38 of 41 in its largest model (IMG_0022, 0025, 0028 apart): it
    reconstructs. The check, as a crew runs it, now says so from the pixels (it refused before)."""
    result = CliRunner().invoke(cli, ["check", str(COPR), "--no-progress", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    quick = data["pixels"]["quick_reconstruction"]
    assert quick["largest_model_frames_pct"] >= 100 * 36 / 41  # 38 of 41 measured at 640 px
    assert data["pixels"]["largest_part_frames_pct"] >= 90.0
    assert data["verdict"] == "pass" and data["judged_on"] == "pixels only (no positions)"
