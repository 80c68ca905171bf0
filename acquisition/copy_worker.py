"""Copying files byte for byte in the kernel, and the process that copies a card's frames ahead of
geotag's writing (:mod:`acquisition.frame_copies` starts it).

Standard library only and no package imports: it runs as a script, ``python -I -S
copy_worker.py``, with a start-up of a few milliseconds.

The process reads a JSON list of ``[source, destination]`` pairs on standard input, then copies
each source to its destination (created, never overwritten) and writes one JSON line per pair to
standard output, in order: ``[i, [dev, ino, size, mtime_ns]]`` (the source's identity, the same
before and after the copy) or ``[i, null, "reason"]`` (nothing left at the destination). It stops
when standard output is closed (its parent is gone) and exits 0 when every pair was answered.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import sys

#: errno values of a kernel or filesystem that refuses an in-kernel copy between two files
_NO_KERNEL_COPY = (errno.EXDEV, errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP)


class SourceShrankError(OSError):
    """The source file ended before the bytes its size promised were copied."""


def copy_range(src_fd: int, dst_fd: int, offset: int, count: int) -> None:
    """Copy ``count`` bytes of ``src_fd`` from ``offset`` to ``dst_fd``'s position, in the kernel
    (``copy_file_range``, else ``sendfile``); the bytes never enter Python."""
    copy_file_range = getattr(os, "copy_file_range", None)
    while count > 0:
        try:
            if copy_file_range is not None:
                done = copy_file_range(src_fd, dst_fd, count, offset)
            else:  # pragma: no cover - not Linux
                done = os.sendfile(dst_fd, src_fd, offset, count)
        except OSError as error:
            if error.errno not in _NO_KERNEL_COPY:
                raise
            copy_file_range = None
            done = os.sendfile(dst_fd, src_fd, offset, count)
        if done == 0:
            raise SourceShrankError(f"the source file shrank while it was copied ({count} bytes missing)")
        offset += done
        count -= done


def identity(stat: os.stat_result) -> tuple[int, int, int, int]:
    """What says a file is the same one: device, inode, size, modification time in ns."""
    return (stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns)


def copy_file(src: str, dst: str) -> tuple[int, int, int, int]:
    """Copy ``src`` to the new file ``dst``; the source's identity, unchanged by the copy.
    Raises OSError (``dst`` removed) when it cannot, or when the source changed meanwhile."""
    src_fd = os.open(src, os.O_RDONLY | os.O_CLOEXEC)
    try:
        before = identity(os.fstat(src_fd))
        dst_fd = os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o666)
        try:
            copy_range(src_fd, dst_fd, 0, before[2])
            after = identity(os.fstat(src_fd))
            if after != before:
                raise OSError(errno.EAGAIN, f"{src} changed while it was copied")
        except BaseException:
            os.close(dst_fd)
            with contextlib.suppress(FileNotFoundError):
                os.unlink(dst)
            raise
        os.close(dst_fd)
        return before
    finally:
        os.close(src_fd)


def main() -> int:
    pairs = json.load(sys.stdin)
    out = sys.stdout
    for i, (src, dst) in enumerate(pairs):
        try:
            answer: list[object] = [i, list(copy_file(src, dst))]
        except OSError as error:
            answer = [i, None, str(error)]
        try:
            out.write(json.dumps(answer) + "\n")
            out.flush()
        except BrokenPipeError:  # the parent is gone: nobody will use the copies
            return 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
