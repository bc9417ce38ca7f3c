"""Open text logs that may be plain, gzip or xz compressed (by magic, not by name), and read
them as a stream of lines with bounded memory.

Every text reader goes through :func:`iter_lines` (or :func:`read_text` for formats that
must be parsed whole, JSON): the decompressed size is counted as it is read and refused
beyond ``limits.TEXT_BYTES`` (a compression bomb stops there, not when the memory is gone),
one line beyond ``limits.LINE_BYTES``, and a NUL byte means binary data, not a text log.
"""

from __future__ import annotations

import gzip
import lzma
import zlib
from collections.abc import Iterator
from pathlib import Path

from ivslam_cli import limits
from ivslam_cli.errors import LogError

BLOCK = 1 << 20
_ERRORS = (OSError, EOFError, lzma.LZMAError, zlib.error)


def _opener(path: Path):
    with open(path, "rb") as f:
        head = f.read(6)
    if head.startswith(b"\x1f\x8b"):
        return gzip.open
    if head.startswith(b"\xfd7zXZ\x00"):
        return lzma.open
    return open


def _blocks(path: Path, limit: str) -> Iterator[bytes]:
    """Decompressed blocks, at most ``limits.get(limit)`` bytes in all."""
    cap = limits.get(limit)
    total = 0
    try:
        with _opener(path)(path, "rb") as f:
            while True:
                block = f.read(BLOCK)
                if not block:
                    return
                total += len(block)
                if total > cap:
                    raise limits.LimitExceeded(
                        f"decompresses to more than the limit {limits.describe(limit)} (a compression "
                        f"bomb, or not a log?; raise it with IVSLAM_LIMIT_{limit} if the input is genuine)", path)
                if b"\0" in block:
                    raise LogError("binary data in a text log (corrupt file?)", path)
                yield block
    except _ERRORS as exc:
        raise LogError(f"corrupt or truncated compressed file ({exc})", path) from None


def iter_lines(path: Path, limit: str = "TEXT_BYTES") -> Iterator[str]:
    """The lines of a text log (latin-1, without their end of line), streamed."""
    max_line = limits.get("LINE_BYTES")
    rest = b""
    for block in _blocks(path, limit):
        data = rest + block if rest else block
        lines = data.split(b"\n")
        rest = lines.pop()
        if len(rest) > max_line:
            try:
                limits.check("LINE_BYTES", len(rest), "one line is longer")
            except limits.LimitExceeded as exc:
                raise exc.about(path) from None
        for line in lines:
            yield line.rstrip(b"\r").decode("latin-1")
    if rest:
        yield rest.rstrip(b"\r").decode("latin-1")


def read_text(path: Path, limit: str = "TEXT_BYTES") -> str:
    """The whole decoded text (at most ``limits.get(limit)`` bytes); corrupt compression or
    binary junk -> LogError."""
    return b"".join(_blocks(path, limit)).decode("latin-1")


SNIFF_BYTES = 1 << 20


def first_lines(path: Path, n: int) -> list[str]:
    """Up to ``n`` first lines within the first MiB (for sniffing); unreadable content gives []."""
    out: list[str] = []
    left = SNIFF_BYTES
    try:
        with _opener(path)(path, "rt", encoding="latin-1", errors="replace") as f:
            for _ in range(n):
                line = f.readline(left)
                if not line:
                    break
                out.append(line)
                left -= len(line)
                if left <= 0:
                    break
    except _ERRORS:
        pass
    return out
