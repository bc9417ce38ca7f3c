"""The input checksum recorded in a result's provenance."""

from __future__ import annotations

import hashlib
from pathlib import Path

_CHUNK = 1 << 20


def _file_digest(path: Path) -> bytes:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while chunk := f.read(_CHUNK):
            h.update(chunk)
    return h.digest()


def input_sha256(path: str | Path) -> str:
    """Hex sha256 of a file; for a directory, of its regular files (recursively).

    Directory rule: sha256 over, for every file in sorted POSIX relative-path order,
    ``relpath`` + NUL + sha256(content) + NUL. Renaming, adding, removing or changing any
    file changes it; the directory's own name and timestamps do not. A log that is not on
    disk (built in memory, e.g. by the simulator in tests) has no checksum: ``""``.
    """
    path = Path(path)
    if not path.exists():
        return ""
    if path.is_dir():
        h = hashlib.sha256()
        files = sorted((p for p in path.rglob("*") if p.is_file()), key=lambda p: p.relative_to(path).as_posix())
        for p in files:
            h.update(p.relative_to(path).as_posix().encode() + b"\0")
            h.update(_file_digest(p) + b"\0")
        return h.hexdigest()
    return _file_digest(path).hex()
