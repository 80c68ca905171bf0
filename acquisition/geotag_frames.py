"""The frames of a card and their tags: reading every frame's header (:func:`read_frames`), the
frames in capture-time order, and the sync frames' capture times. Finding and naming the frames is
:mod:`acquisition.card`."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
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


#: Frames read at once: reading a header is mostly waiting for the disk (the GIL is released),
#: so a few threads overlap the waits of a card that is not in the page cache.
READ_THREADS = 4


def read_frames(paths: Sequence[Path], progress: Callable[[int], None]) -> list[Frame]:
    """The tags of every image (header segments only), in the order of ``paths``; an unreadable
    one keeps its reason. ``progress(n)`` after each."""
    frames: list[Frame] = []
    with ThreadPoolExecutor(max_workers=READ_THREADS) as pool:
        for done, frame in enumerate(pool.map(_read_frame, paths), start=1):
            frames.append(frame)
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
