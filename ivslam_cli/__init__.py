"""ivslam: guaranteed (interval, set-membership) SLAM over recorded robot logs.

Data flows one way: ``logs`` (readers) -> ``slam`` (pipelines built on ``interval``,
``contractors`` and ``paving`` kernels) -> ``results`` (HDF5) -> ``report``.
Importing this package is cheap: no numba kernel is compiled or loaded here.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

__version__ = "0.1.0"


def _set_numba_cache_dir() -> None:
    """Point numba's on-disk cache at a directory keyed by the hash of all our sources.

    numba invalidates a cached function only when *its own* file changes, so editing a jitted
    callee in another module would leave callers stale. Keying the cache directory by every
    source file that holds numba code makes any kernel change (or upgrade) start from a clean
    cache, while an unchanged install reuses it across processes. ``NUMBA_CACHE_DIR`` set by
    the user wins.
    """
    if "NUMBA_CACHE_DIR" in os.environ:
        return
    root = os.path.dirname(os.path.realpath(__file__))
    digest = hashlib.sha1(__version__.encode())
    for parts in sorted(_sources(root)):
        with open(os.path.join(root, *parts), "rb") as f:
            text = f.read()
        if b"numba" in text:
            digest.update("/".join(parts).encode())
            digest.update(text)
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    os.environ["NUMBA_CACHE_DIR"] = str(base / "ivslam" / "numba" / digest.hexdigest()[:16])


def _sources(folder: str, parts: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    """The ``*.py`` files under ``folder`` (symbolic links to folders not followed), each as the
    parts of its path relative to it (sorted, the order of ``sorted(Path.rglob("*.py"))``)."""
    found = []
    with os.scandir(folder) as entries:
        for entry in entries:
            if entry.is_dir(follow_symlinks=False):
                found += _sources(entry.path, (*parts, entry.name))
            elif entry.name.endswith(".py"):
                found.append((*parts, entry.name))
    return found


_set_numba_cache_dir()
