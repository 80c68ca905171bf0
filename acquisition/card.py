"""The frames of a card: finding them, naming them in the outputs, and checking the options before
a slow log is read (:func:`prepare_images`). Reading their tags is :mod:`acquisition.geotag_frames`.

Standard library only, so that ``sfap geotag`` can check its options and start the card's worker
(:mod:`acquisition.card_ahead`) before the heavier modules are loaded.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from pathlib import Path

from planner.errors import InputError
from planner.outputs import check_output_dir, check_writable

from .sync_points import SyncPoint

JPEG_SUFFIXES = (".jpg", ".jpeg")


def list_images(image_dir: str | os.PathLike[str]) -> list[Path]:
    """JPEG files under ``image_dir`` (recursively: a card's DCIM folder holds 100CANON,
    101CANON...), by path."""
    root = Path(image_dir)
    if not root.is_dir():
        raise InputError(f"{root} is not a folder of images; give the folder that holds the JPEGs")
    return sorted(
        p
        for p in root.rglob("*")
        if p.is_file() and p.suffix.lower() in JPEG_SUFFIXES and not p.name.startswith(".")
    )


def output_names(image_dir: str | os.PathLike[str], paths: Sequence[Path]) -> dict[Path, str]:
    """The name each frame gets in the outputs (tagged copies, geo.txt, the CSV, the report).

    Its own file name while names are unique; when names repeat across folders (cameras
    restart at IMG_0001 in each DCIM subfolder), every frame in a subfolder is prefixed with
    its folder path relative to ``image_dir``: ``100CANON/IMG_0001.JPG`` becomes
    ``100CANON_IMG_0001.JPG``, so that the copies sit side by side in one flat folder, as
    reconstruction tools want them, and nothing is overwritten."""
    root = Path(image_dir)
    names = {p: p.name for p in paths}
    if len({n.lower() for n in names.values()}) == len(names):
        return names
    out: dict[Path, str] = {}
    for p in paths:
        try:
            folders = p.relative_to(root).parts[:-1]
        except ValueError:
            folders = p.parent.parts[-1:]
        prefix = "_".join(re.sub(r"[\s,]+", "-", part) for part in folders)
        out[p] = f"{prefix}_{p.name}" if prefix else p.name
    return out


def resolve_sync_frame(frame: str, root: Path, paths: Sequence[Path], names: dict[Path, str]) -> Path:
    wanted = frame.replace("\\", "/").strip("/").lower()
    by_output = [p for p in paths if names[p].lower() == wanted]
    by_relative = [p for p in paths if p.relative_to(root).as_posix().lower() == wanted]
    by_name = [p for p in paths if p.name.lower() == wanted]
    for found in (by_relative, by_output, by_name):
        if len(found) == 1:
            return found[0]
    if len(by_name) > 1:
        options = ", ".join(p.relative_to(root).as_posix() for p in by_name[:4])
        raise InputError(f"sync frame {frame} names several images ({options}); give its folder too")
    raise InputError(f"sync frame {frame} is not an image under {root}")


def prepare_images(
    image_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    *,
    dry_run: bool = False,
    in_place: bool = False,
    backup_dir: str | os.PathLike[str] | None = None,
    overwrite: bool = False,
    sync: Sequence[SyncPoint] = (),
) -> list[Path]:
    """Check the images and the options before anything slow (reading a large log): the
    folder holds JPEGs, the output can be written, the sync frames exist. Returns the images."""
    paths = list_images(image_dir)
    if not paths:
        raise InputError(f"no JPEG images (.jpg, .jpeg) under {image_dir}: give the card's DCIM folder")
    if in_place and backup_dir is None:
        raise InputError("--in-place needs --backup-dir: the originals are copied there first")
    if in_place and backup_dir is not None and not dry_run:
        check_writable(backup_dir, "backup folder")
    if not dry_run:
        check_output_dir(out_dir, overwrite=overwrite)
        if not in_place and Path(out_dir).resolve() == Path(image_dir).resolve():
            raise InputError("the output folder is the image folder; choose another -o or use --in-place")
    names = output_names(image_dir, paths)
    for point in sync:
        resolve_sync_frame(point.frame, Path(image_dir), paths, names)
    return paths
