"""The process that copies a card's frames into ``sfap geotag``'s staging folder ahead of its
writers, then writes the tags of the frames it is given (:mod:`acquisition.card_ahead` starts it
and talks to it).

It runs as ``python -I -S``: no site-packages, so that it starts in a few tens of milliseconds;
it needs nothing but the standard library and this package's pure-Python modules (a header only
exiv2 writes is left to the parent, which loads exiv2).

Protocol. Standard input: a pickled list of ``(source, destination)`` pairs, then pickled lists
of ``(i, GeoTag)`` jobs, until the input ends. Standard output: messages, each a 4-byte
big-endian length and a pickled tuple:

- ``("copy", i, identity)`` for every pair in order, the frame copied to its destination
  (created, never overwritten) by :func:`acquisition.kernel_copy.copy_file`, or ``("copy", i,
  None, reason)`` with nothing left at the destination (it existed already: the parent took it;
  or the copy failed);
- then, for each list of jobs as it comes, ``("write", i, None, warnings)`` for every job, the
  frame's tags written over its copy
  (:func:`acquisition.exif.write_geotag_without_exiv2`), or ``("write", i, reason, ())`` with
  nothing left at the destination: the parent writes that frame itself.

It stops when its standard output is closed (the parent is gone).
"""

from __future__ import annotations

import pickle
import sys
from pathlib import Path
from typing import Any, BinaryIO

from .kernel_copy import copy_file


def _send(out: BinaryIO, message: tuple[object, ...]) -> None:
    data = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    out.write(len(data).to_bytes(4, "big") + data)
    out.flush()


def copy_frames(pairs: list[tuple[str, str]], out: BinaryIO) -> dict[int, tuple[int, int, int, int]]:
    """Copy every frame to its destination; the answers to ``out``. The identities copied."""
    copied = {}
    for i, (src, dst) in enumerate(pairs):
        try:
            copied[i] = copy_file(src, dst)
        except OSError as error:
            _send(out, ("copy", i, None, str(error)))
            continue
        _send(out, ("copy", i, copied[i]))
    return copied


def write_frames(
    pairs: list[tuple[str, str]],
    copied: dict[int, tuple[int, int, int, int]],
    jobs: list[tuple[int, Any]],
    out: BinaryIO,
) -> None:
    """Write the tags of the frames in ``jobs`` over their copies; the answers to ``out``."""
    from . import exif
    from .card_ahead import Copied

    for i, tag in jobs:
        src, dst = pairs[i]
        made = copied.get(i)
        try:
            warnings = exif.write_geotag_without_exiv2(
                src, dst, tag, copied=None if made is None else Copied(Path(dst), made)
            )
        except Exception as error:  # any failure: the parent writes the frame itself
            _send(out, ("write", i, f"{type(error).__name__}: {error}", ()))
            continue
        _send(out, ("write", i, None, tuple(warnings)))


def main() -> int:
    try:
        pairs = pickle.load(sys.stdin.buffer)
        copied = copy_frames(pairs, sys.stdout.buffer)
        while True:
            try:
                jobs = pickle.load(sys.stdin.buffer)
            except EOFError:  # no more jobs
                return 0
            write_frames(pairs, copied, jobs, sys.stdout.buffer)
    except (BrokenPipeError, KeyboardInterrupt):  # the parent is gone, or stopped the run
        return 0
    return 0
