"""What the pixels say (processing/pixel_match.py, processing/pixel_colmap.py): the geometry of a
matched pair against constructions whose answer is known, and COLMAP's real matcher on images
cut from one texture at known offsets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image
from textures import blob_texture

from processing.pixel_match import (
    affine_fit,
    budget_pairs,
    components,
    mapped_overlap_pct,
    neighbour_pairs,
)


@settings(max_examples=50, deadline=None)
@given(
    st.floats(-0.5, 0.5),
    st.floats(0.8, 1.25),
    st.floats(-400, 400),
    st.floats(-400, 400),
    st.integers(0, 2**31 - 1),
)
def test_the_affine_fit_recovers_a_similarity(
    angle: float, scale: float, tx: float, ty: float, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(0, 1000, size=(40, 2))
    c, s = scale * np.cos(angle), scale * np.sin(angle)
    truth = np.array([[c, -s, tx], [s, c, ty]])
    moved = xy @ truth[:, :2].T + truth[:, 2]
    np.testing.assert_allclose(affine_fit(xy, moved), truth, atol=1e-6)


@pytest.mark.parametrize(
    ("dx", "dy"), [(0.0, 0.0), (400.0, 0.0), (0.0, -300.0), (250.0, 150.0), (1200.0, 0.0)]
)
def test_a_shifted_frame_overlaps_by_the_rest_of_it(dx: float, dy: float) -> None:
    """A 1000 x 750 px frame shifted by (dx, dy): the overlap is (1000 - |dx|)(750 - |dy|) of it."""
    affine = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
    expected = 100.0 * max(1000 - abs(dx), 0) * max(750 - abs(dy), 0) / (1000 * 750)
    assert mapped_overlap_pct(affine, (1000, 750), (1000, 750)) == pytest.approx(expected, abs=1e-9)


def _components_by_search(n: int, edges: list[tuple[int, int]]) -> list[set[int]]:
    """Connected parts by breadth-first search (the oracle)."""
    neighbours: dict[int, set[int]] = {k: set() for k in range(n)}
    for a, b in edges:
        neighbours[a].add(b)
        neighbours[b].add(a)
    seen: set[int] = set()
    parts: list[set[int]] = []
    for start in range(n):
        if start in seen:
            continue
        part, queue = {start}, [start]
        while queue:
            for nxt in neighbours[queue.pop()]:
                if nxt not in part:
                    part.add(nxt)
                    queue.append(nxt)
        seen |= part
        parts.append(part)
    return parts


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 30), st.lists(st.tuples(st.integers(0, 29), st.integers(0, 29)), max_size=40))
def test_components_are_the_connected_parts_largest_first(n: int, raw: list[tuple[int, int]]) -> None:
    edges = [(a, b) for a, b in raw if a < n and b < n]
    labels = components(n, np.array(edges, dtype=np.int64).reshape(-1, 2))
    parts = _components_by_search(n, edges)
    assert {frozenset(np.flatnonzero(labels == k).tolist()) for k in range(labels.max() + 1)} == {
        frozenset(p) for p in parts
    }
    sizes = np.bincount(labels)
    assert (np.diff(sizes) <= 0).all() and sizes[0] == max(len(p) for p in parts)


def test_neighbour_pairs_keep_along_and_across_pairs_once() -> None:
    index = np.array([[0, 1], [1, 2], [2, 0], [3, 1], [1, 3]], dtype=np.int64)
    along = np.array([True, True, False, False, False])
    across = np.array([False, False, False, True, True])
    pairs, kind = neighbour_pairs(index, along, across)
    assert pairs.tolist() == [[0, 1], [1, 2], [1, 3]]
    assert kind.tolist() == [True, True, False]


def _grid_block(lines: int, per_line: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A regular block: ``lines`` lines of ``per_line`` frames (row = line * per_line + k), 10 m
    apart along a line, 30 m between lines; its neighbour pairs as the check gives them
    (consecutive frames of a line; each frame and the frame beside it on each neighbouring line)."""
    xyz = np.array([[10.0 * k, 30.0 * line, 0.0] for line in range(lines) for k in range(per_line)])
    along = [
        (line * per_line + k, line * per_line + k + 1) for line in range(lines) for k in range(per_line - 1)
    ]
    across = [
        (line * per_line + k, (line + 1) * per_line + k) for line in range(lines - 1) for k in range(per_line)
    ]
    index = np.array(along + across, dtype=np.int64)
    return index, np.array([True] * len(along) + [False] * len(across)), xyz


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 5), st.integers(2, 9))
def test_mapper_pairs_without_a_cap_are_the_frames_within_two_along_and_one_across(
    lines: int, per_line: int
) -> None:
    """Uncapped, the quick reconstruction's pairs of a regular block are, by construction: frames
    of a line up to two apart, and frames of neighbouring lines at most one apart along them."""
    index, along, xyz = _grid_block(lines, per_line)
    got = {tuple(p) for p in budget_pairs(index, along, None, xyz, max_per_frame=10_000).tolist()}
    expected = set()
    for a in range(lines * per_line):
        for b in range(a + 1, lines * per_line):
            (la, ka), (lb, kb) = divmod(a, per_line), divmod(b, per_line)
            if (la == lb and kb - ka <= 2) or (lb - la == 1 and abs(kb - ka) <= 1):
                expected.add((a, b))
    assert got == expected


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 5), st.integers(2, 9), st.integers(1, 12), st.integers(0, 2**31 - 1))
def test_mapper_pairs_keep_the_neighbours_and_the_budget(
    lines: int, per_line: int, cap: int, seed: int
) -> None:
    """Every neighbour pair is kept; a pair added beyond them never takes a frame past the cap, and
    comes from the candidates when they are given."""
    index, along, xyz = _grid_block(lines, per_line)
    n = lines * per_line
    rng = np.random.default_rng(seed)
    every = np.array([(a, b) for a in range(n) for b in range(a + 1, n)], dtype=np.int64).reshape(-1, 2)
    candidates = every[rng.random(len(every)) < 0.6]
    got = budget_pairs(index, along, candidates, xyz, max_per_frame=cap)
    pairs = {tuple(p) for p in got.tolist()}
    assert len(pairs) == len(got) and all(a < b for a, b in pairs)
    neighbours = {(min(a, b), max(a, b)) for a, b in index.tolist()}
    assert neighbours <= pairs
    allowed = {tuple(p) for p in candidates.tolist()}
    base_degree = (
        np.bincount(np.array(sorted(neighbours)).ravel(), minlength=n) if neighbours else np.zeros(n)
    )
    degree = np.bincount(got.ravel(), minlength=n)
    for a, b in pairs - neighbours:
        assert (a, b) in allowed
    # Frames that gained pairs stay within the cap.
    gained = degree > base_degree
    assert (degree[gained] <= cap).all()


# --- COLMAP's matcher on a texture cut at known offsets --------------------------------------------


def test_colmap_measures_the_overlap_and_shift_of_frames_cut_from_one_texture(tmp_path: Path) -> None:
    """Three 800 x 600 frames cut from one texture, each 240 px right of the last (70 % endlap),
    and one cut from another texture: the neighbours match with the shift and overlap of their
    construction, the unrelated frame matches nothing."""
    from processing.pixel_colmap import match_pairs

    texture = blob_texture(2000, 600, seed=1)
    names = []
    for k in range(3):
        name = f"f{k}.jpg"
        Image.fromarray(texture[:, 240 * k : 240 * k + 800]).save(tmp_path / name, quality=95)
        names.append(name)
    Image.fromarray(blob_texture(800, 600, seed=2)).save(tmp_path / "other.jpg", quality=95)
    names.append("other.jpg")
    log = tmp_path / "colmap.log"
    run = match_pairs(
        tmp_path,
        names,
        [("f0.jpg", "f1.jpg"), ("f1.jpg", "f2.jpg"), ("f0.jpg", "f2.jpg"), ("f1.jpg", "other.jpg")],
        max_image_size_px=800,
        max_features=2000,
        num_threads=2,
        log_path=log,
    )
    assert run.size_px["f0.jpg"] == (800, 600)
    counts = [p.count for p in run.pairs]
    assert min(counts[:3]) >= 100 and counts[3] < 15, counts
    for pair, shift in zip(run.pairs[:3], (240.0, 240.0, 480.0), strict=True):
        affine = affine_fit(pair.xy_a, pair.xy_b)
        centre = np.array([400.0, 300.0])
        np.testing.assert_allclose(affine[:, :2] @ centre + affine[:, 2] - centre, [-shift, 0.0], atol=3.0)
        assert mapped_overlap_pct(affine, (800, 600), (800, 600)) == pytest.approx(
            100 * (1 - shift / 800), abs=0.3
        )
    # COLMAP's log went to the file, not the terminal.
    assert log.stat().st_size > 0


def test_without_pycolmap_the_check_says_it_judged_on_the_tags(monkeypatch: pytest.MonkeyPatch) -> None:
    """pycolmap is an optional dependency (sfap[colmap]): a check where it is not installed does
    not end in a traceback; it says the frames were not matched and how to install it."""
    import sys
    from types import SimpleNamespace

    from processing.check import measure_in_pixels
    from processing.pixel_match import PixelOptions

    monkeypatch.setitem(sys.modules, "pycolmap", None)  # `import pycolmap` now fails as if absent
    frames = SimpleNamespace(camera=SimpleNamespace(image_width_px=4000, image_height_px=3000))
    measured = measure_in_pixels(
        frames,  # type: ignore[arg-type]
        None,  # type: ignore[arg-type]
        None,  # type: ignore[arg-type]
        PixelOptions(image_dir=Path(".")),
        camera_rough=False,
        drift=False,
    )
    assert measured.figures is None
    assert len(measured.warnings) == 1 and "pycolmap is not installed" in measured.warnings[0]
    assert "sfap[colmap]" in measured.warnings[0]
