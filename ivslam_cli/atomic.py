"""Atomic outputs: a file or a directory is written under a temporary name beside its final
path, then renamed into place (``os.replace``), so a reader sees either the old state or the
complete new output, never a partial one.

An existing output is refused unless ``force``: the one message for that is
:data:`EXISTS`. :func:`refuse_existing` is the check a command makes before it starts work.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ivslam_cli.errors import IvslamError

EXISTS = "already exists; refusing to overwrite it (use --force)"


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def refuse_existing(path: str | Path, force: bool) -> None:
    """Raise a one-line IvslamError if ``path`` exists and ``force`` is False."""
    if not force and os.path.lexists(path):
        raise IvslamError(EXISTS, path)


def _parent(path: Path) -> Path:
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise IvslamError(f"directory {str(parent)!r} does not exist", path)
    return parent


@contextlib.contextmanager
def atomic_path(path: str | Path, *, force: bool = False) -> Iterator[Path]:
    """Yield a temp file path next to ``path``; on success it is renamed onto ``path``.

    On any exception the temp file is removed and ``path`` is left untouched.
    """
    path = Path(path)
    refuse_existing(path, force)
    parent = _parent(path)
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


@contextlib.contextmanager
def atomic_output(path: str | Path, *, force: bool = False) -> Iterator[Path]:
    """Yield a path to write, a file or a directory (a ROS 2 bag), that is renamed to
    ``path`` on success.

    The temporary lives in a fresh directory beside ``path`` (same file system), so the final
    rename is atomic; on error nothing is left behind and ``path`` is untouched.
    """
    path = Path(path)
    refuse_existing(path, force)
    parent = _parent(path)
    tmpdir = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=parent))
    try:
        target = tmpdir / path.name
        yield target
        if not target.exists():
            raise IvslamError("writer produced no output", path)
        refuse_existing(path, force)
        if path.exists():  # force: move the old one aside, then swap
            os.replace(path, tmpdir / (path.name + ".old"))
        os.replace(target, path)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)


def write_text_atomic(path: str | Path, text: str, *, force: bool = False) -> None:
    with atomic_path(path, force=force) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes_atomic(path: str | Path, data: bytes, *, force: bool = False) -> None:
    with atomic_path(path, force=force) as tmp:
        tmp.write_bytes(data)
