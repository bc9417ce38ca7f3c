"""Checks on input paths before anything opens them.

A FIFO blocks ``open`` until someone writes to it; a character device (``/dev/zero``,
``/dev/urandom``) never ends; a socket cannot be read as a file. None of them is a log, a
result or a configuration: :func:`check_input` refuses them (and missing paths) with a
one-line error naming the path, before any ``open``. Directories are accepted only where a
format is a directory (ROS 2 bags, MRCLAM datasets), and then every file directly inside
must be a regular file or a directory.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from ivslam_cli.errors import IvslamError

_KIND = ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
         (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def special_kind(mode: int) -> str | None:
    """``"a FIFO (named pipe)"`` etc. for a special file mode, None for a file or directory."""
    for test, name in _KIND:
        if test(mode):
            return name
    return None


def check_input(path: str | Path, what: str = "file", *, dir_ok: bool = False,
                error: type[IvslamError] = IvslamError) -> Path:
    """``path`` if it is a readable regular file (or, with ``dir_ok``, a directory of them).

    Raises ``error`` (one line, naming ``path``) for a missing path, a special file, a
    directory where a file is expected, or a path that cannot be accessed.
    """
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise error("no such file or directory", path) from None
    except OSError as exc:
        raise error(f"cannot access: {exc.strerror or exc}", path) from None
    kind = special_kind(st.st_mode)
    if kind is not None:
        raise error(f"is {kind}, not a {what}: refusing to read it", path)
    if stat.S_ISDIR(st.st_mode):
        if not dir_ok:
            raise error(f"is a directory, not a {what}", path)
        try:
            entries = list(os.scandir(path))
        except OSError as exc:
            raise error(f"cannot list the directory: {exc.strerror or exc}", path) from None
        for entry in entries:
            try:
                mode = entry.stat().st_mode
            except OSError:
                continue  # a dangling link: the reader says what it misses
            kind = special_kind(mode)
            if kind is not None:
                raise error(f"contains {entry.name!r}, which is {kind}: refusing to read it", path)
        return path
    if not os.access(path, os.R_OK):
        raise error(f"cannot read: {os.strerror(errno.EACCES)}", path)
    return path


def same_or_inside(a: str | Path, b: str | Path) -> bool:
    """True if ``a`` is ``b`` (the same file, by inode when both exist) or lies inside ``b``
    (a directory), or ``b`` lies inside ``a``."""
    a, b = Path(a), Path(b)
    try:
        if a.exists() and b.exists() and os.path.samefile(a, b):
            return True
    except OSError:
        pass
    ra, rb = _resolved(a), _resolved(b)
    return ra == rb or rb in ra.parents or ra in rb.parents


def _resolved(p: Path) -> Path:
    try:
        return p.resolve()
    except OSError:
        return Path(os.path.abspath(p))
