"""The card's frames copied ahead of ``sfap geotag``'s writers, by a worker process.

Writing a tagged copy is, byte for byte, copying the frame and writing its new header over the
first bytes (the header keeps its length, :func:`acquisition.jpeg_meta.patch_header`). On
full-size frames the copy is most of the cost, and it does not depend on the tags. So ``sfap
geotag`` starts it first, in a worker process (:mod:`acquisition.card_worker`; a thread would wait
for the interpreter lock that this process holds while it loads numpy, reads the log and the
headers), on the other core. Writing a frame then takes its copy (:meth:`CardAhead.take`) and
writes the header over it (:func:`acquisition.exif.write_geotags`).

The writers follow the worker, in its order: by the time this process has placed the frames,
the worker has copied most of them, and the page a writer overwrites is still in the CPU's
caches. A frame the worker has not reached when a writer comes to it is the writer's: the
destination file is created exclusively (``O_EXCL``) by whichever of the two comes first, and
the other leaves it alone. (Taking the frames from the other end, so that both sides copy, was
slower: this process is the slower of the two, and its writers then copied 40-80 frames
themselves; see BENCHMARKS.md.)

A copy is used only when it is of the same file the header was read from: the source's identity
(device, inode, size, modification time in ns) when copied, unchanged during the copy, equal to
what the writer sees when it opens the source. Otherwise, or when the copy failed, the frame is
written from the source as without the worker. Copies of frames that are not written (not placed)
are removed before the staging folder is moved into place; on any failure the staging folder is
removed whole (:class:`planner.outputs.StagedOutputDir`).

(Reading the headers in a second worker was tried: three processes on two cores, and the reads
pickled across, made a run slower, not faster; see BENCHMARKS.md.)

Standard library only: it is loaded, and the worker started, before numpy.
"""

from __future__ import annotations

import contextlib
import logging
import os
import pickle
import subprocess
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

log = logging.getLogger(__name__)

_CLOEXEC = getattr(os, "O_CLOEXEC", 0)

#: The folder that holds the ``acquisition`` package: the worker imports it from there.
_ROOT = str(Path(__file__).resolve().parents[1])
_WORKER = (
    "import sys; sys.path.insert(0, sys.argv[1]); from acquisition.card_worker import main; sys.exit(main())"
)


@dataclass(frozen=True)
class Copied:
    """A frame's file at ``path`` made ahead of its writer: a byte copy of the source whose
    identity (:func:`acquisition.kernel_copy.identity`) was ``identity``; or, with ``identity``
    None, an empty file reserved for the writer, which writes the frame whole into it."""

    path: Path
    identity: tuple[int, int, int, int] | None


class CardAhead:
    """``frames`` (source path, name in ``folder``) copied by a worker process.

    :meth:`start` launches it. :meth:`take` gives a frame's copy, or reserves its file for the
    caller; :meth:`writing_order` is the order in which writers follow the worker;
    :meth:`wait` waits for the worker; :meth:`finish` stops it and removes the copies nobody
    took. All are thread-safe. Without a worker (it could not start, or it died) :meth:`take`
    returns None and the frames are written as usual."""

    def __init__(self, folder: Path, frames: Sequence[tuple[Path, str]]) -> None:
        self.folder = folder
        self._sources = [str(src) for src, _ in frames]
        self._index = {src: i for i, src in enumerate(self._sources)}
        self._targets = [folder / name for _, name in frames]
        self._answers: dict[int, Copied | None] = {}
        self._taken: set[int] = set()
        self._reserved: set[int] = set()  # files a writer created before the worker reached them
        self._changed = threading.Condition()
        self._ended = True  # until a worker runs
        self._process: subprocess.Popen[bytes] | None = None
        self._threads: list[threading.Thread] = []

    @classmethod
    def start(cls, folder: Path, frames: Sequence[tuple[Path, str]]) -> CardAhead:
        """``frames`` copied into ``folder`` by a worker process, begun now."""
        ahead = cls(folder, frames)
        if not frames or not sys.executable or getattr(sys, "frozen", False):
            return ahead  # nothing to copy, or no interpreter to run the worker with
        try:
            process = subprocess.Popen(
                [sys.executable, "-I", "-S", "-c", _WORKER, _ROOT],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                close_fds=True,
                bufsize=0,
            )
        except OSError as error:
            log.debug("frames not copied ahead (%s): each is copied when written", error)
            return ahead
        ahead._process, ahead._ended = process, False
        request = pickle.dumps(list(zip(ahead._sources, map(str, ahead._targets), strict=True)))
        # The request is written, and the answers read, by threads: either can fill its pipe
        # while this process is busy, and the worker must not wait for it.
        ahead._threads = [
            threading.Thread(target=_feed, args=(process.stdin, request), daemon=True),
            threading.Thread(target=ahead._listen, args=(process,), daemon=True),
        ]
        for thread in ahead._threads:
            thread.start()
        return ahead

    # ---------------------------------------------------------------------------- the worker's answers

    def _listen(self, process: subprocess.Popen[bytes]) -> None:
        """Receive the worker's answers until it ends (then reap it)."""
        assert process.stdout is not None
        stream = process.stdout
        try:
            while True:
                size = _read_exactly(stream, 4)
                body = _read_exactly(stream, int.from_bytes(size, "big")) if size else b""
                if not body:
                    break
                self._receive(pickle.loads(body))
        except (OSError, pickle.UnpicklingError, EOFError, ValueError) as error:
            log.debug("the card worker's answers ended (%s)", error)
        finally:
            stream.close()
            process.wait()
            with self._changed:
                self._ended = True
                self._changed.notify_all()

    def _receive(self, answer: tuple[Any, ...]) -> None:
        i, identity, *reason = answer
        with self._changed:
            if identity is None:
                log.debug("%s not copied ahead: %s", self._sources[i], reason)
                self._answers[i] = None
            else:
                self._answers[i] = Copied(self._targets[i], tuple(identity))
            self._changed.notify_all()

    # ---------------------------------------------------------------------------- the writers' side

    def writing_order(self, srcs: Sequence[str]) -> list[int]:
        """Indexes into ``srcs``: the frames in the order the worker copies them (frames it does
        not copy last)."""
        last = len(self._sources)
        return sorted(range(len(srcs)), key=lambda k: self._index.get(srcs[k], last))

    def take(self, src: str | os.PathLike[str]) -> Copied | None:
        """``src``'s file in the folder: its byte copy once the worker has made it, or an empty
        file reserved for the caller when the worker has not begun it; None when neither (not a
        frame of this run, the copy failed, or no worker: the caller writes the frame as usual).
        Taken files are the caller's: :meth:`finish` leaves them."""
        i = self._index.get(os.fspath(src))
        if i is None:
            return None
        target = self._targets[i]
        with self._changed:
            if i in self._reserved:  # taken before: the same answer
                return Copied(target, None)
            self._taken.add(i)
            if i not in self._answers and not self._ended:
                try:
                    os.close(os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _CLOEXEC, 0o666))
                    self._reserved.add(i)
                    return Copied(target, None)  # the worker will find it taken
                except FileExistsError:
                    pass  # the worker is copying it
            self._changed.wait_for(lambda: i in self._answers or self._ended)
            if i not in self._answers:  # the worker died during its copy: the copy is not whole
                self._answers[i] = None
                with contextlib.suppress(FileNotFoundError):
                    target.unlink()
            return self._answers[i]

    def wait(self) -> None:
        """Wait until the worker has answered for every frame, or has ended."""
        with self._changed:
            self._changed.wait_for(lambda: len(self._answers) == len(self._targets) or self._ended)

    def finish(self) -> None:
        """Stop the worker and remove every copy not taken (frames not written), and any copy it
        left unfinished. Idempotent."""
        process = self._process
        if process is not None and process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                process.kill()
        for thread in self._threads:
            thread.join()
        with self._changed:
            for i, target in enumerate(self._targets):
                if i in self._taken:
                    continue  # the writer's (its copy, or what it wrote itself)
                with contextlib.suppress(FileNotFoundError):
                    target.unlink()
                self._answers.setdefault(i, None)


def _feed(pipe: IO[bytes] | None, request: bytes) -> None:
    """Write the worker's request and close its input."""
    assert pipe is not None
    try:
        with contextlib.suppress(OSError):  # the worker is gone: its answers end, frames are written here
            pipe.write(request)
    finally:
        with contextlib.suppress(OSError):
            pipe.close()


def _read_exactly(stream: IO[bytes], size: int) -> bytes:
    """``size`` bytes of ``stream``, or b"" at its end (a message cut short counts as the end)."""
    parts, left = [], size
    while left > 0:
        part = stream.read(left)
        if not part:
            return b""
        parts.append(part)
        left -= len(part)
    return b"".join(parts)
