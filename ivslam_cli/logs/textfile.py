"""Open text logs that may be plain, gzip or xz compressed (by magic, not by name)."""

from __future__ import annotations

import gzip
import lzma
import zlib
from pathlib import Path

from ivslam_cli.errors import LogError


def _opener(path: Path):
    with open(path, "rb") as f:
        head = f.read(6)
    if head.startswith(b"\x1f\x8b"):
        return gzip.open
    if head.startswith(b"\xfd7zXZ\x00"):
        return lzma.open
    return open


def read_text(path: Path) -> str:
    """The whole decoded text; corrupt compression or binary junk -> LogError."""
    try:
        with _opener(path)(path, "rb") as f:
            raw = f.read()
    except (OSError, EOFError, lzma.LZMAError, zlib.error) as exc:
        raise LogError(f"corrupt or truncated compressed file ({exc})", path) from None
    if b"\0" in raw:
        raise LogError("binary data in a text log (corrupt file?)", path)
    return raw.decode("latin-1")


def first_lines(path: Path, n: int) -> list[str]:
    """Up to ``n`` first lines (for sniffing); unreadable content gives []."""
    out: list[str] = []
    try:
        with _opener(path)(path, "rt", encoding="latin-1", errors="replace") as f:
            for _ in range(n):
                line = f.readline(1 << 20)
                if not line:
                    break
                out.append(line)
    except (OSError, EOFError, lzma.LZMAError, zlib.error):
        pass
    return out
