"""The process that copies a card's frames into ``sfap geotag``'s staging folder ahead of its
writers (:mod:`acquisition.card_ahead` starts it and talks to it).

It runs as ``python -I -S``: no site-packages, so that it starts in a few tens of milliseconds;
it needs nothing but the standard library and :mod:`acquisition.kernel_copy`.

Protocol. Standard input: a pickled list of ``(source, destination)`` pairs. Standard output:
one message per pair, in order, each a 4-byte big-endian length and a pickled tuple:
``(i, identity)``, the frame copied to its destination (created, never overwritten) by
:func:`acquisition.kernel_copy.copy_file`, or ``(i, None, reason)`` with nothing left at the
destination (it existed already: the parent took it; or the copy failed). It stops when its
standard output is closed (the parent is gone) and exits 0 when every pair was answered.
"""

from __future__ import annotations

import pickle
import sys
from typing import BinaryIO

from .kernel_copy import copy_file


def copy_frames(pairs: list[tuple[str, str]], out: BinaryIO) -> None:
    """Copy every frame to its destination; the answers to ``out``."""
    for i, (src, dst) in enumerate(pairs):
        try:
            answer: tuple[object, ...] = (i, copy_file(src, dst))
        except OSError as error:
            answer = (i, None, str(error))
        data = pickle.dumps(answer, protocol=pickle.HIGHEST_PROTOCOL)
        out.write(len(data).to_bytes(4, "big") + data)
        out.flush()


def main() -> int:
    try:
        copy_frames(pickle.load(sys.stdin.buffer), sys.stdout.buffer)
    except (BrokenPipeError, KeyboardInterrupt):  # the parent is gone, or stopped the run
        return 0
    return 0
