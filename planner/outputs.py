"""Writing outputs without ever leaving a half-written file or folder behind.

- :func:`atomic_file` (a file written in a with-block), :func:`atomic_write_bytes` /
  :func:`atomic_write_text`: one file, via a temporary file in the same folder and ``os.replace``.
- :func:`staged_output_dir` (:class:`StagedOutputDir` when the staging must begin early): a whole
  output folder, built in a temporary sibling folder and moved into place only when everything in
  it was written.
- :func:`json_safe`: a value made fit for strict JSON (every JSON file and ``--json`` output).

Nothing is overwritten unless the caller passes ``overwrite=True`` (the CLI's ``--overwrite``).
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

from .errors import OutputExistsError

_UMASK: int | None = None


def process_umask() -> int:
    """The process's umask, read once (reading it sets and resets it, which is not safe while
    other threads create files: call it before starting them)."""
    global _UMASK
    if _UMASK is None:
        mask = os.umask(0)
        os.umask(mask)
        _UMASK = mask
    return _UMASK


@contextlib.contextmanager
def atomic_file(target: Path, *, overwrite: bool, buffering: int = -1) -> Iterator[BinaryIO]:
    """A binary file that replaces ``target`` only when the block ends without error: written to
    a temporary file in the same folder, synced, given the permissions a plain open() would, then
    renamed over ``target``; on any error the temporary file is removed and ``target`` untouched."""
    if not overwrite and target.exists():
        raise OutputExistsError(f"{target} exists; pass --overwrite to replace it")
    blocker = _file_in_the_way(target)
    if blocker is not None:
        raise OutputExistsError(
            f"output file {target}: {blocker} is a file, not a folder; choose another path"
        )
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as error:  # name the file the user gave, not the hidden temporary one
        raise cannot_write(target, error, "file") from error
    try:
        with os.fdopen(fd, "wb", buffering=buffering) as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        # mkstemp creates 0600; give the file the permissions a plain open() would.
        os.chmod(tmp_name, 0o666 & ~process_umask())
        os.replace(tmp_name, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp_name)
        raise


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, *, overwrite: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder, then rename)."""
    target = Path(path)
    with atomic_file(target, overwrite=overwrite) as handle:
        handle.write(data)
    return target


def atomic_write_text(
    path: str | os.PathLike[str], text: str, *, overwrite: bool = True, encoding: str = "utf-8"
) -> Path:
    """Write ``text`` to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode(encoding), overwrite=overwrite)


def _file_in_the_way(path: Path) -> Path | None:
    """The first of ``path``'s folders (from the top) that exists as something other than a
    folder (a file where the path needs a folder), or None."""
    for ancestor in reversed(path.parents):
        if ancestor.exists() and not ancestor.is_dir():
            return ancestor
    return None


def cannot_write(
    target: str | os.PathLike[str], error: OSError, what: str = "output folder", where: Path | None = None
) -> OSError:
    """``error`` (raised while writing ``target`` or its hidden staging) restated naming the path
    the user gave, the folder that refused (``where``, default its parent) and the fix, for the
    CLI's one line (an OSError: exit 1, the operation failed)."""
    given = Path(target)
    reason = error.strerror or str(error)
    folder = given.parent if where is None else where
    if error.errno in (errno.EACCES, errno.EPERM, errno.EROFS):
        return OSError(
            error.errno,
            f"cannot write the {what} {given}: {folder} is not writable ({reason}); choose a place "
            f"you can write to, or make {folder} writable",
        )
    return OSError(error.errno, f"cannot write the {what} {given}: {reason} (in {folder})")


def check_writable(target: str | os.PathLike[str], what: str = "output folder") -> None:
    """Refuse, before any work, a ``target`` that cannot be created: a file where its path needs a
    folder (bad input), or a nearest existing folder this process cannot write into."""
    path = Path(target)
    blocker = _file_in_the_way(path)
    if blocker is not None:
        raise OutputExistsError(f"{what} {path}: {blocker} is a file, not a folder; choose another path")
    existing = path if path.is_dir() else next((p for p in path.parents if p.is_dir()), Path("."))
    if not os.access(existing, os.W_OK | os.X_OK):
        code = errno.EACCES
        raise cannot_write(path, PermissionError(code, os.strerror(code)), what, where=existing) from None


def check_output_dir(target: str | os.PathLike[str], *, overwrite: bool) -> Path:
    """Refuse early when ``target`` holds files and ``overwrite`` is False, or cannot be a folder."""
    path = Path(target)
    blocker = _file_in_the_way(path)
    if blocker is not None:
        raise OutputExistsError(
            f"output folder {path}: {blocker} is a file, not a folder; choose another output path (-o)"
        )
    if path.exists() and not path.is_dir():
        raise OutputExistsError(f"{path} exists and is not a folder; choose another output path")
    if path.is_dir() and any(path.iterdir()) and not overwrite:
        raise OutputExistsError(
            f"output folder {path} is not empty; pass --overwrite to replace it or choose "
            f"another folder with -o"
        )
    return path


class StagedOutputDir:
    """An output folder built in a temporary sibling folder (``path``) and moved into place whole
    by :meth:`commit`; :meth:`discard` removes it and leaves ``target`` as it was.

    For a job whose staging must begin before the code that fills it is ready (``sfap geotag``
    starts copying the frames while it reads the log, :mod:`acquisition.card_ahead`); otherwise
    use :func:`staged_output_dir`."""

    def __init__(self, target: str | os.PathLike[str], *, overwrite: bool = False) -> None:
        self.given = Path(target)
        self.final = check_output_dir(target, overwrite=overwrite).resolve()
        try:
            self.final.parent.mkdir(parents=True, exist_ok=True)
            self.path = Path(
                tempfile.mkdtemp(prefix=f".{self.final.name}.", suffix=".staging", dir=self.final.parent)
            )
        except OSError as error:  # name the folder the user gave, not the hidden staging folder
            raise cannot_write(self.given, error) from error
        os.chmod(self.path, 0o777 & ~process_umask())
        self.ended = False

    def commit(self) -> None:
        """Move the staging folder into place (replacing ``target`` when it exists)."""
        if self.ended:
            raise RuntimeError(f"{self.path} was already committed or discarded")
        self.ended = True
        final = self.final
        try:
            if final.exists():
                backup = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".old", dir=final.parent))
                os.rmdir(backup)
                os.replace(final, backup)
                os.replace(self.path, final)
                shutil.rmtree(backup, ignore_errors=True)
            else:
                os.replace(self.path, final)
        except OSError as error:
            shutil.rmtree(self.path, ignore_errors=True)
            raise cannot_write(self.given, error) from error

    def discard(self) -> None:
        """Remove the staging folder (no-op once committed or discarded)."""
        if not self.ended:
            self.ended = True
            shutil.rmtree(self.path, ignore_errors=True)


@contextlib.contextmanager
def staged_output_dir(target: str | os.PathLike[str], *, overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary folder; on success it replaces ``target`` as a whole.

    On any exception the temporary folder is removed and ``target`` is left as it was.
    """
    with staged(StagedOutputDir(target, overwrite=overwrite)) as staging:
        yield staging.path


@contextlib.contextmanager
def staged(staging: StagedOutputDir) -> Iterator[StagedOutputDir]:
    """``staging`` committed when the block ends without error, discarded on any exception."""
    try:
        yield staging
    except BaseException:
        staging.discard()
        raise
    staging.commit()


def json_safe(value: Any) -> Any:
    """``value`` made fit for strict JSON (``json.dumps(..., allow_nan=False)``): NaN and
    infinities as None (JSON has no NaN), numpy scalars and arrays as Python numbers and lists,
    tuples as lists, mapping keys as strings; anything else as it is."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    numpy = sys.modules.get("numpy")  # no numpy value exists unless numpy was imported
    if numpy is not None:
        if isinstance(value, numpy.ndarray):
            return json_safe(value.tolist())
        if isinstance(value, numpy.generic):
            return json_safe(value.item())
    return value
