"""Copying a file byte for byte in the kernel (``copy_file_range``, else ``sendfile``): the bytes
never enter Python. Standard library only (the card worker, :mod:`acquisition.card_worker`, runs
without site-packages)."""

from __future__ import annotations

import contextlib
import errno
import os

#: errno values of a kernel or filesystem that refuses an in-kernel copy between two files
_NO_KERNEL_COPY = (errno.EXDEV, errno.ENOSYS, errno.EINVAL, errno.EOPNOTSUPP)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)


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
    src_fd = os.open(src, os.O_RDONLY | _CLOEXEC)
    try:
        before = identity(os.fstat(src_fd))
        dst_fd = os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _CLOEXEC, 0o666)
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
