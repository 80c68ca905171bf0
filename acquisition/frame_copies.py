"""The card's frames copied into geotag's staging folder while the log and the headers are read.

Writing a tagged copy is, byte for byte, copying the frame and writing its new header over the
first bytes (the header keeps its length, :func:`acquisition.jpeg_meta.patch_header`). The copy
is most of the cost on full-size frames, and it does not depend on the tags: so ``sfap geotag``
starts it first, in a separate process (:mod:`acquisition.copy_worker`; a thread would wait for
the interpreter lock that reading the log and the headers holds), on the other core, while this
process loads its libraries, reads the log and the headers and places the frames. Writing a frame
then takes its copy (:meth:`FrameCopies.take`) and writes the header over it
(:func:`acquisition.exif.write_geotags`).

The writers take the frames from the other end of the list, and a frame the worker has not
reached yet is theirs: the destination file is created exclusively (``O_EXCL``) by whichever of
the two comes first, and the other leaves it alone. So once this process has nothing else to do,
both cores copy, and neither waits for the other.

A copy is used only when it is of the same file the header was read from: the source's identity
(device, inode, size, modification time in ns) when copied, unchanged during the copy, equal to
what the writer sees when it opens the source. Otherwise, or when the copy failed, the frame is
written from the source as without copies. Copies of frames that are not written (not placed)
are removed before the staging folder is moved into place; on any failure the staging folder is
removed whole (:class:`planner.outputs.StagedOutputDir`).

Standard library only: it is started before numpy is loaded.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import select
import subprocess
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO

log = logging.getLogger(__name__)

WORKER = Path(__file__).with_name("copy_worker.py")


@dataclass(frozen=True)
class Copied:
    """A frame's file at ``path`` made ahead of its writer: a byte copy of the source whose
    identity (:func:`acquisition.copy_worker.identity`) was ``identity``; or, with ``identity``
    None, an empty file reserved for the writer, which writes the frame whole into it."""

    path: Path
    identity: tuple[int, int, int, int] | None


class FrameCopies:
    """Byte copies of ``frames`` (source path, name in ``folder``) made by a worker process.

    :meth:`start` launches it; :meth:`take` (thread-safe) gives a frame's copy, or reserves its
    file for the writer; :meth:`writing_order` is the order in which writers meet the worker
    last; :meth:`wait` waits for the worker; :meth:`finish` stops it and removes the copies
    nobody took. Without a worker (it could not start) every :meth:`take` returns None and the
    frames are written as usual."""

    def __init__(self, folder: Path, frames: Sequence[tuple[Path, str]]) -> None:
        self.folder = folder
        self._order = [str(src) for src, _ in frames]
        self._index = {src: i for i, src in enumerate(self._order)}
        self._targets = [folder / name for _, name in frames]
        self._answers: dict[int, Copied | None] = {}
        self._taken: set[int] = set()
        self._reserved: set[int] = set()  # files a writer created before the worker reached them
        self._lock = threading.Lock()
        self._process: subprocess.Popen[bytes] | None = None
        self._feeder: threading.Thread | None = None
        self._unread = b""

    @classmethod
    def start(cls, folder: Path, frames: Sequence[tuple[Path, str]]) -> FrameCopies:
        """The copies of ``frames`` into ``folder``, begun in a worker process."""
        copies = cls(folder, frames)
        if not frames or not sys.executable:
            return copies
        try:
            copies._process = subprocess.Popen(
                [sys.executable, "-I", "-S", str(WORKER)],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                close_fds=True,
                bufsize=0,
            )
        except OSError as error:
            log.debug("frames not copied ahead (%s): each is copied when written", error)
            return copies
        request = json.dumps(
            [[src, str(dst)] for src, dst in zip(copies._order, copies._targets, strict=True)]
        )
        # A thread writes the request: a large one fills the pipe before the worker reads it.
        copies._feeder = threading.Thread(
            target=_feed, args=(copies._process.stdin, request.encode()), daemon=True
        )
        copies._feeder.start()
        return copies

    def writing_order(self, srcs: Sequence[str]) -> list[int]:
        """Indexes into ``srcs``: the frames the worker copies last first."""
        last = len(self._order)
        return sorted(range(len(srcs)), key=lambda k: -self._index.get(srcs[k], last))

    def take(self, src: str | os.PathLike[str]) -> Copied | None:
        """``src``'s file in the folder: its byte copy once the worker has made it, or an empty
        file reserved for the caller when the worker has not begun it; None when neither (not a
        frame of this run, or the worker's copy failed: the caller writes the frame as usual).
        Taken files are the caller's: :meth:`finish` leaves them."""
        i = self._index.get(os.fspath(src))
        if i is None:
            return None
        with self._lock:
            if i in self._reserved:  # taken before: the same answer
                return Copied(self._targets[i], None)
            self._taken.add(i)
            self._read_answers(wait=False)
            if i in self._answers:
                return self._answers[i]
            if self._process is not None:
                try:
                    os.close(os.open(self._targets[i], os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
                    self._reserved.add(i)
                    return Copied(self._targets[i], None)  # the worker will find it taken
                except FileExistsError:
                    pass  # the worker is copying it
            while i not in self._answers and self._read_answers(wait=True):
                pass
            return self._answers.get(i)

    def wait(self) -> None:
        """Wait until the worker has answered for every frame (or has ended)."""
        with self._lock:
            while len(self._answers) < len(self._targets) and self._read_answers(wait=True):
                pass

    def _read_answers(self, *, wait: bool) -> bool:
        """Read the worker's answers that are there (``wait``: at least one); False when the
        worker has ended."""
        process = self._process
        if process is None or process.stdout is None:
            return False
        fd = process.stdout.fileno()
        if not wait and not select.select([fd], [], [], 0)[0]:
            return True
        chunk = os.read(fd, 1 << 16)
        if not chunk:  # the worker ended
            self._stop_worker()
            return False
        *lines, self._unread = (self._unread + chunk).split(b"\n")
        for line in lines:
            i, ident, *reason = json.loads(line)
            if ident is None:
                log.debug("%s not copied ahead: %s", self._order[i], reason)
                self._answers[i] = None
            else:
                self._answers[i] = Copied(self._targets[i], tuple(ident))
        return True

    def _stop_worker(self) -> None:
        """Stop the worker; a frame it did not answer for has no copy (a partial one is removed;
        a file a writer reserved is the writer's) and is written as usual."""
        process, self._process = self._process, None
        if process is None:
            return
        if process.poll() is None:
            process.kill()
        process.wait()
        if process.stdout is not None:
            process.stdout.close()
        if self._feeder is not None:
            self._feeder.join()
        for i, target in enumerate(self._targets):
            if i not in self._answers and i not in self._reserved:
                self._answers[i] = None
                with contextlib.suppress(FileNotFoundError):
                    target.unlink()

    def finish(self) -> None:
        """Stop the worker and remove every copy not taken (frames not written). Idempotent."""
        with self._lock:
            self._stop_worker()
            for i, answer in self._answers.items():
                if i not in self._taken and answer is not None:
                    with contextlib.suppress(FileNotFoundError):
                        answer.path.unlink()


def _feed(pipe: IO[bytes] | None, request: bytes) -> None:
    """Write the worker's request and close its input."""
    assert pipe is not None
    with contextlib.suppress(OSError):  # the worker is gone: its answers end, frames are written as usual
        pipe.write(request)
        pipe.close()
