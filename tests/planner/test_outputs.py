"""json_safe: random nested values built together with what strict JSON must hold for them (an
independent construction), numpy scalars and arrays, NaN and infinities among them."""

from __future__ import annotations

import json
import math
import os
import stat
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from planner.errors import OutputExistsError
from planner.outputs import StagedOutputDir, atomic_file, json_safe, staged_output_dir


def _leaf() -> st.SearchStrategy[tuple[Any, Any]]:
    """(value, what JSON must hold for it)."""
    plain = st.one_of(
        st.integers(-(10**9), 10**9).map(lambda v: (v, v)),
        st.floats(allow_nan=False, allow_infinity=False).map(lambda v: (v, v)),
        st.sampled_from([math.nan, math.inf, -math.inf]).map(lambda v: (v, None)),
        st.text(max_size=5).map(lambda v: (v, v)),
        st.booleans().map(lambda v: (v, v)),
        st.none().map(lambda v: (v, v)),
    )
    numpy = st.one_of(
        st.floats(width=32, allow_nan=False, allow_infinity=False).map(lambda v: (np.float32(v), float(v))),
        st.integers(-(2**31), 2**31 - 1).map(lambda v: (np.int64(v), v)),
        st.sampled_from([np.float64(math.nan), np.float32(math.nan), np.float32(-math.inf)]).map(
            lambda v: (v, None)
        ),
        st.booleans().map(lambda v: (np.bool_(v), v)),
        st.lists(st.floats(-1e9, 1e9), max_size=4).map(lambda v: (np.array(v, dtype=np.float64), v)),
    )
    return st.one_of(plain, numpy)


def _nest(children: st.SearchStrategy[tuple[Any, Any]]) -> st.SearchStrategy[tuple[Any, Any]]:
    as_list = st.lists(children, max_size=4).map(lambda kids: ([k for k, _ in kids], [v for _, v in kids]))
    as_tuple = st.lists(children, max_size=4).map(
        lambda kids: (tuple(k for k, _ in kids), [v for _, v in kids])
    )
    as_dict = st.dictionaries(st.one_of(st.text(max_size=4), st.integers(0, 99)), children, max_size=4).map(
        lambda d: ({k: raw for k, (raw, _) in d.items()}, {str(k): want for k, (_, want) in d.items()})
    )
    return st.one_of(as_list, as_tuple, as_dict)


@given(st.recursive(_leaf(), _nest, max_leaves=20))
def test_json_safe_gives_what_strict_json_holds(pair: tuple[Any, Any]) -> None:
    raw, want = pair
    text = json.dumps(json_safe(raw), allow_nan=False)  # strict JSON: raises on NaN or numpy
    assert json.loads(text) == json.loads(json.dumps(want, allow_nan=False))


def test_atomic_file_replaces_the_target_only_when_the_block_ends(tmp_path: Path) -> None:
    """An error inside the block leaves the old file as it was and no temporary file; a clean
    block replaces it whole, with the permissions a plain open() gives (the umask's)."""
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), atomic_file(target, overwrite=True) as handle:
        handle.write(b"half of the new")
        raise RuntimeError("the card was pulled")
    assert target.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]

    with atomic_file(target, overwrite=True) as handle:
        handle.write(b"new")
    assert target.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]
    mask = os.umask(0)
    os.umask(mask)
    plain = tmp_path / "plain.bin"
    plain.write_bytes(b"")
    assert stat.S_IMODE(target.stat().st_mode) == stat.S_IMODE(plain.stat().st_mode) == 0o666 & ~mask


def test_atomic_file_refuses_an_existing_target_without_overwrite(tmp_path: Path) -> None:
    target = tmp_path / "out.bin"
    target.write_bytes(b"keep")
    with (
        pytest.raises(OutputExistsError, match="--overwrite"),
        atomic_file(target, overwrite=False) as handle,
    ):
        handle.write(b"lost")
    assert target.read_bytes() == b"keep"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.bin"]


def _tree(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_a_staged_folder_moves_into_place_whole_or_not_at_all(tmp_path: Path) -> None:
    """StagedOutputDir: built beside the target, moved in by commit() (replacing an old folder
    with --overwrite, nothing of it left), removed by discard(); once ended, it stays ended."""
    target = tmp_path / "out"
    first = StagedOutputDir(target)
    assert first.path.parent == tmp_path and first.path.name.startswith(".out.")
    (first.path / "a.txt").write_bytes(b"one")
    (first.path / "sub").mkdir()
    (first.path / "sub" / "b.txt").write_bytes(b"two")
    assert not target.exists()
    first.commit()
    assert _tree(target) == {"a.txt": b"one", "sub/b.txt": b"two"}
    first.discard()  # after the commit: nothing happens
    assert _tree(target) == {"a.txt": b"one", "sub/b.txt": b"two"}
    with pytest.raises(RuntimeError):
        first.commit()

    with pytest.raises(OutputExistsError):
        StagedOutputDir(target)  # not empty, no overwrite
    second = StagedOutputDir(target, overwrite=True)
    (second.path / "c.txt").write_bytes(b"three")
    second.discard()
    assert _tree(target) == {"a.txt": b"one", "sub/b.txt": b"two"}  # untouched
    third = StagedOutputDir(target, overwrite=True)
    (third.path / "c.txt").write_bytes(b"three")
    third.commit()
    assert _tree(target) == {"c.txt": b"three"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # no staging, no old folder


def test_staged_output_dir_leaves_nothing_when_the_block_fails(tmp_path: Path) -> None:
    target = tmp_path / "out"
    target.mkdir()
    (target / "kept.txt").write_bytes(b"old")
    with pytest.raises(KeyboardInterrupt), staged_output_dir(target, overwrite=True) as staging:
        (staging / "new.txt").write_bytes(b"new")
        raise KeyboardInterrupt
    assert _tree(target) == {"kept.txt": b"old"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
