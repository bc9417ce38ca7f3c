"""Atomic output files: write to a temp file in the same directory, then ``os.replace``.

A reader never sees a partial file: either the old state (nothing, or the previous file
when ``force``) or the complete new one. An existing output is refused unless ``force``.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ivslam_cli.errors import IvslamError


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def refuse_existing(path: str | Path, force: bool) -> None:
    """Raise a one-line IvslamError if ``path`` exists and ``force`` is False."""
    if not force and os.path.lexists(path):
        raise IvslamError("already exists; refusing to overwrite it (use --force)", path)


@contextlib.contextmanager
def atomic_path(path: str | Path, *, force: bool = False) -> Iterator[Path]:
    """Yield a temp path next to ``path``; on success it is renamed onto ``path``.

    On any exception the temp file is removed and ``path`` is left untouched.
    """
    path = Path(path)
    refuse_existing(path, force)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise IvslamError(f"directory {str(parent)!r} does not exist", path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=parent)
    os.close(fd)
    os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; outputs get the usual mode
    try:
        yield Path(tmp)
        refuse_existing(path, force)  # someone may have created it meanwhile
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_text_atomic(path: str | Path, text: str, *, force: bool = False) -> None:
    with atomic_path(path, force=force) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes_atomic(path: str | Path, data: bytes, *, force: bool = False) -> None:
    with atomic_path(path, force=force) as tmp:
        tmp.write_bytes(data)
