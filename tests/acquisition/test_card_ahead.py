"""acquisition.card_ahead, card_worker and kernel_copy: the frames copied ahead of geotag's writing
by a real worker process. Oracles: the source files' own bytes and os.stat, the filesystem (what
exists afterwards), and the writer without copies (tested against exiftool in test_exif.py and
test_geotag.py) for the tagged files."""

from __future__ import annotations

import os
import pickle
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from jpeg_edits import without_xmp_padding
from PIL import Image
from shared_data import SHARED_DATA

from acquisition import card_ahead, exif, kernel_copy
from acquisition.card_ahead import CardAhead

GARFIELD = SHARED_DATA / "garfield_rgb"


def _ident(path: Path) -> list[int]:
    stat = path.stat()
    return [stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns]


def _tag(lat_deg: float) -> exif.GeoTag:
    return exif.GeoTag(lat_deg=lat_deg, lon_deg=-93.25, alt_amsl_m=312.5, time_utc_s=1715933472.25)


def _card(folder: Path, count: int) -> list[Path]:
    """Real Sequoia frames (XMP padding: the header keeps its length when tagged), the first
    without XMP padding to spare (its header grows) and the sixth a JPEG without EXIF (exiv2
    writes it), ``count`` in all."""
    folder.mkdir(parents=True)
    frames = sorted(GARFIELD.glob("*.JPG"))
    paths = []
    for k in range(count):
        path = folder / f"F{k:03d}.JPG"
        shutil.copyfile(frames[k % len(frames)], path)
        paths.append(path)
    paths[0].write_bytes(without_xmp_padding(paths[0].read_bytes()))
    if count > 5:  # no EXIF at all: a header only exiv2 writes
        pixels = np.random.default_rng(5).integers(0, 256, size=(32, 48, 3), dtype=np.uint8)
        Image.fromarray(pixels).save(paths[5], format="JPEG", quality=85)
    return paths


def _run_worker(pairs: list[list[str]]) -> list[tuple[object, ...]]:
    """The worker as geotag starts it, its answers decoded."""
    done = subprocess.run(
        [sys.executable, "-I", "-S", "-c", card_ahead._WORKER, card_ahead._ROOT],
        input=pickle.dumps(pairs),
        capture_output=True,
        check=True,
        timeout=60,
    )
    answers, data = [], done.stdout
    while data:
        size = int.from_bytes(data[:4], "big")
        answers.append(pickle.loads(data[4 : 4 + size]))
        data = data[4 + size :]
    return answers


def test_the_worker_copies_byte_for_byte_and_never_overwrites(tmp_path: Path) -> None:
    src = tmp_path / "src"
    src.mkdir()
    rng = np.random.default_rng(7)
    sources = {
        "empty": b"",
        "one": b"\xff",
        "noise": rng.integers(0, 256, 3_000_001, dtype=np.uint8).tobytes(),
        "frame": (GARFIELD / "IMG_161122_163234_0000_RGB.JPG").read_bytes(),
    }
    for name, data in sources.items():
        (src / name).write_bytes(data)
    out = tmp_path / "out"
    out.mkdir()
    (out / "taken").write_bytes(b"the writer's")
    pairs = [[str(src / name), str(out / name)] for name in sources]
    pairs += [[str(src / "noise"), str(out / "taken")], [str(src / "missing"), str(out / "missing")]]
    answers = _run_worker(pairs)
    assert [a[0] for a in answers] == list(range(len(pairs)))
    for k, name in enumerate(sources):
        assert (out / name).read_bytes() == sources[name]
        assert list(answers[k][1]) == _ident(src / name)  # type: ignore[call-overload]
    assert answers[4][1] is None and (out / "taken").read_bytes() == b"the writer's"
    assert answers[5][1] is None and "missing" in str(answers[5][2]) and not (out / "missing").exists()


def test_a_frame_the_worker_has_not_reached_is_reserved_for_the_writer(tmp_path: Path) -> None:
    """The worker is held at its first frame (a FIFO: opening it waits for a writer); the second
    frame is then the caller's, an empty file the worker leaves alone."""
    src = tmp_path / "src"
    src.mkdir()
    fifo = src / "A.JPG"
    os.mkfifo(fifo)
    frame = src / "B.JPG"
    shutil.copyfile(GARFIELD / "IMG_161122_163234_0000_RGB.JPG", frame)
    out = tmp_path / "out"
    out.mkdir()
    copies = CardAhead.start(out, [(fifo, "A.JPG"), (frame, "B.JPG")])
    try:
        reserved = copies.take(frame)
        assert reserved is not None and reserved.identity is None and reserved.path == out / "B.JPG"
        assert (out / "B.JPG").read_bytes() == b""
        os.close(os.open(fifo, os.O_WRONLY))  # lets the worker go on: A is empty, B is taken
        copies.wait()
        first = copies.take(fifo)
        assert first is not None and first.identity == tuple(_ident(fifo))
    finally:
        copies.finish()
    assert (out / "A.JPG").read_bytes() == b"" and (out / "B.JPG").read_bytes() == b""


def test_the_writers_follow_the_worker_in_its_order(tmp_path: Path) -> None:
    """Jobs in any order are written in the worker's order (it copies the list from its start),
    frames it does not copy last."""
    frames = [(tmp_path / f"F{k}.JPG", f"F{k}.JPG") for k in range(6)]
    copies = CardAhead(tmp_path / "out", frames)  # the order alone: no worker started
    srcs = [str(frames[k][0]) for k in (4, 1, 5, 0, 3, 2)] + [str(tmp_path / "other.JPG")]
    order = copies.writing_order(srcs)
    assert [srcs[k] for k in order] == [str(src) for src, _ in frames] + [str(tmp_path / "other.JPG")]


def test_finish_removes_every_copy_nobody_took(tmp_path: Path) -> None:
    paths = _card(tmp_path / "card", 40)
    out = tmp_path / "out"
    out.mkdir()
    copies = CardAhead.start(out, [(p, p.name) for p in paths])
    kept = paths[::7]
    for path in kept:
        copied = copies.take(path)
        assert copied is not None and copied.path == out / path.name
        assert copies.take(path) == copied  # the same answer again
    copies.finish()
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in kept)
    copies.finish()  # idempotent

    # Stopped at once: whatever the worker had begun is gone too.
    again = tmp_path / "again"
    again.mkdir()
    CardAhead.start(again, [(p, p.name) for p in paths]).finish()
    assert list(again.iterdir()) == []


@pytest.mark.parametrize("workers", [1, 2])
def test_writing_over_copies_gives_the_bytes_of_writing_without(tmp_path: Path, workers: int) -> None:
    paths = _card(tmp_path / "card", 24)
    seen = {str(p): exif.read_tags_and_header(p)[1] for p in paths}
    outputs = {}
    for mode in ("plain", "copies"):
        out = tmp_path / mode
        out.mkdir()
        jobs = [
            exif.GeotagJob(src=str(p), dst=str(out / p.name), tag=_tag(40.0 + k / 1000), seen=seen[str(p)])
            for k, p in enumerate(paths[:-3])  # the last three are not placed: not written
        ]
        copies = CardAhead.start(out, [(p, p.name) for p in paths]) if mode == "copies" else None
        done: list[int] = []
        try:
            results = exif.write_geotags(
                jobs, workers=workers, atomic=False, ahead=copies, progress=done.append
            )
        finally:
            if copies is not None:
                copies.finish()
        assert [r.src for r in results] == [j.src for j in jobs] and all(r.written for r in results)
        assert done == list(range(1, len(jobs) + 1))
        outputs[mode] = out
    names = sorted(p.name for p in outputs["plain"].iterdir())
    assert names == sorted(p.name for p in paths[:-3])
    assert sorted(p.name for p in outputs["copies"].iterdir()) == names
    for name in names:
        assert (outputs["copies"] / name).read_bytes() == (outputs["plain"] / name).read_bytes()
    grown = paths[0].name  # the frame without padding: its header grew, the copy was rewritten
    assert exif._split_bytes((outputs["copies"] / grown).read_bytes(), "out").sos_offset > (
        exif._split_bytes(paths[0].read_bytes(), "in").sos_offset
    )


def test_a_source_changed_after_its_copy_is_written_from_the_source(tmp_path: Path) -> None:
    """The copy is of the file as it was; the frame changed since (the crew replaced it, or
    the card was still being written): the copy is not used, the frame as it is now is."""
    paths = _card(tmp_path / "card", 6)
    out = tmp_path / "out"
    out.mkdir()
    copies = CardAhead.start(out, [(p, p.name) for p in paths])
    try:
        copies.wait()
        assert all(getattr(copies.take(p), "identity", None) == tuple(_ident(p)) for p in paths)
        replaced, broken = paths[1], paths[2]
        shutil.copyfile(sorted(GARFIELD.glob("*.JPG"))[-1], replaced)
        broken.write_bytes(b"not a JPEG any more")
        jobs = [exif.GeotagJob(src=str(p), dst=str(out / p.name), tag=_tag(41.0)) for p in paths]
        results = exif.write_geotags(jobs, atomic=False, ahead=copies)
    finally:
        copies.finish()
    assert [r.written for r in results] == [True, True, False, True, True, True]
    assert not (out / broken.name).exists()  # no untagged copy where the frame's would be
    assert exif.compressed_image_data(out / replaced.name) == exif.compressed_image_data(replaced)
    for path in (paths[0], replaced, *paths[3:]):
        assert exif.read_tags(out / path.name).gps_lat_deg == pytest.approx(41.0)


def test_takers_in_threads_each_get_their_own_frame(tmp_path: Path) -> None:
    """take() from several threads at once (the writers): every frame is either a complete copy
    or reserved, never both, and the worker never writes into a reserved file."""
    paths = _card(tmp_path / "card", 60)
    out = tmp_path / "out"
    out.mkdir()
    copies = CardAhead.start(out, [(p, p.name) for p in paths])
    got: dict[str, object] = {}

    def take(part: list[Path]) -> None:
        for path in part:
            got[path.name] = copies.take(path)

    threads = [threading.Thread(target=take, args=(paths[k::3][::-1],)) for k in range(3)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(60)
    copies.finish()
    assert len(got) == len(paths)
    for path in paths:
        copied = got[path.name]
        assert copied is not None
        data = (out / path.name).read_bytes()
        if copied.identity is None:  # type: ignore[attr-defined]
            assert data == b""
        else:
            assert data == path.read_bytes() and list(copied.identity) == _ident(path)  # type: ignore[attr-defined]


# ---------------------------------------------------------------------------- the kernel copy


def test_a_source_that_changes_while_it_is_copied_is_not_copied(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A card still being written: the source grows during the copy. No copy is left, and the
    error says why."""
    src, dst = tmp_path / "frame.jpg", tmp_path / "copy.jpg"
    src.write_bytes(b"\xff\xd8" + bytes(100_000))
    real = kernel_copy.copy_range

    def copy_then_grow(src_fd: int, dst_fd: int, offset: int, count: int) -> None:
        real(src_fd, dst_fd, offset, count)
        with src.open("ab") as handle:
            handle.write(b"more")

    monkeypatch.setattr(kernel_copy, "copy_range", copy_then_grow)
    with pytest.raises(OSError, match="changed while it was copied"):
        kernel_copy.copy_file(str(src), str(dst))
    assert not dst.exists()


def test_the_copy_falls_back_to_sendfile_and_notices_a_short_source(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Filesystems that refuse copy_file_range (EXDEV, across devices on older kernels): the
    same bytes by sendfile. A source shorter than its size promised is an error, not a short
    copy."""
    import errno

    data = np.random.default_rng(3).integers(0, 256, 1_234_567, dtype=np.uint8).tobytes()
    src, dst = tmp_path / "frame.jpg", tmp_path / "copy.jpg"
    src.write_bytes(data)

    def refused(*args: object) -> int:
        raise OSError(errno.EXDEV, "cross-device")

    monkeypatch.setattr(os, "copy_file_range", refused)
    assert list(kernel_copy.copy_file(str(src), str(dst))) == _ident(src)
    assert dst.read_bytes() == data
    with (
        src.open("rb") as source,
        (tmp_path / "short.jpg").open("wb") as out,
        pytest.raises(kernel_copy.SourceShrankError),
    ):
        kernel_copy.copy_range(source.fileno(), out.fileno(), 0, len(data) + 10)


@pytest.mark.parametrize(
    "worker",
    [
        "import sys; sys.exit(3)",  # dies at once
        "import sys, time; sys.stdin.buffer.read(); time.sleep(0.2)",  # reads, answers nothing, ends
        # killed in the middle of its first copy: half a file left, no answer
        "import sys, pickle; pairs = pickle.load(sys.stdin.buffer); open(pairs[0][1], 'xb').write(b'half')",
    ],
)
def test_a_worker_that_fails_leaves_every_frame_to_the_writers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, worker: str
) -> None:
    """The worker could not import, ended without a word, or died in the middle of a copy: the
    frames are written here, byte for byte as without a worker, and nothing else is left in the
    folder."""
    paths = _card(tmp_path / "card", 10)
    plain = tmp_path / "plain"
    plain.mkdir()
    jobs_plain = [exif.GeotagJob(src=str(p), dst=str(plain / p.name), tag=_tag(42.0)) for p in paths]
    assert all(r.written for r in exif.write_geotags(jobs_plain, atomic=False))
    monkeypatch.setattr(card_ahead, "_WORKER", worker)
    out = tmp_path / "out"
    out.mkdir()
    ahead = CardAhead.start(out, [(p, p.name) for p in paths])
    try:
        jobs = [exif.GeotagJob(src=str(p), dst=str(out / p.name), tag=_tag(42.0)) for p in paths[:-2]]
        results = exif.write_geotags(jobs, workers=2, atomic=False, ahead=ahead)
    finally:
        ahead.finish()
    assert all(r.written for r in results)
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in paths[:-2])
    for path in paths[:-2]:
        assert (out / path.name).read_bytes() == (plain / path.name).read_bytes()
