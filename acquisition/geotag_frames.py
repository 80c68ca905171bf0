"""The frames of a card and their tags: reading every frame's header (:func:`read_frames`), the
frames in capture-time order, and the sync frames' capture times. Finding and naming the frames is
:mod:`acquisition.card`."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from planner.errors import InputError

from . import exif
from .card import resolve_sync_frame
from .errors import GeotagError
from .sync_points import SyncPoint


@dataclass
class Frame:
    """One image and its tags (None when unreadable, with the reason in ``error``)."""

    path: Path
    tags: exif.ImageTags | None = None
    error: str | None = None
    #: the header as read, so that writing the frame does not parse it again
    seen: exif.HeaderSnapshot | None = None


def _read_frame(path: Path) -> Frame:
    try:
        tags, seen = exif.read_tags_and_header(path)
        return Frame(path, tags=tags, seen=seen)
    except (GeotagError, OSError) as error:
        return Frame(path, error=str(error))


#: Frames whose first bytes are asked of the disk ahead of reading them (posix_fadvise
#: WILLNEED): a card that is not in the page cache is read while the frames before are parsed.
#: One thread parses (a second would mostly wait for the interpreter lock).
READ_AHEAD = 8
#: The bytes asked ahead of each frame: its header, as far as most cameras go.
HEADER_BYTES = 1 << 16


def _advise(path: Path) -> None:
    """Ask the kernel to read ``path``'s first bytes now, without waiting for them."""
    advise = getattr(os, "posix_fadvise", None)
    if advise is None:  # pragma: no cover - not Linux
        return
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
        try:
            advise(fd, 0, HEADER_BYTES, os.POSIX_FADV_WILLNEED)
        finally:
            os.close(fd)


def read_frames(paths: Sequence[Path], progress: Callable[[int], None]) -> list[Frame]:
    """The tags of every image (header segments only), in the order of ``paths``; an unreadable
    one keeps its reason. ``progress(n)`` after each."""
    frames: list[Frame] = []
    for path in paths[:READ_AHEAD]:
        _advise(path)
    for done, path in enumerate(paths, start=1):
        if done - 1 + READ_AHEAD < len(paths):
            _advise(paths[done - 1 + READ_AHEAD])
        frames.append(_read_frame(path))
        progress(done)
    return frames


def timed_frames(frames: Sequence[Frame]) -> list[Frame]:
    """The frames with a capture time, in capture-time order (then by path)."""
    timed = [fr for fr in frames if fr.tags is not None and fr.tags.capture_time_s is not None]
    timed.sort(key=lambda fr: (fr.tags.capture_time_s if fr.tags else 0.0, str(fr.path)))
    return timed


def sync_capture_times(
    sync: Sequence[SyncPoint], frames: Sequence[Frame], root: Path, names: dict[Path, str]
) -> list[tuple[SyncPoint, float]]:
    """Each sync point with its frame's capture time (camera clock)."""
    by_path = {fr.path: fr for fr in frames}
    paths = [fr.path for fr in frames]
    out: list[tuple[SyncPoint, float]] = []
    for point in sync:
        frame = by_path[resolve_sync_frame(point.frame, root, paths, names)]
        if frame.tags is None or frame.tags.capture_time_s is None:
            raise InputError(
                f"sync frame {point.frame} has no capture time (DateTimeOriginal): choose another"
            )
        out.append((point, float(frame.tags.capture_time_s)))
    return out
