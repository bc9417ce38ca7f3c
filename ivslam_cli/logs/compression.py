"""Decompression with a bound on the output, for chunks of bags and MCAP files.

A chunk declares its uncompressed size, but a hostile one may inflate far beyond it (a
"zip bomb"). Every chunk is decompressed here with at most ``limits.CHUNK_BYTES`` (and at
most the size the chunk declares, when it declares one) of output; beyond that it is a
one-line :class:`~ivslam_cli.limits.LimitExceeded` or :class:`LogError`, before the
memory is taken.
"""

from __future__ import annotations

import bz2

from ivslam_cli import limits
from ivslam_cli.errors import LogError


def _check_declared(declared: int | None) -> int:
    cap = limits.get("CHUNK_BYTES")
    if declared is not None:
        limits.check("CHUNK_BYTES", declared, "a chunk declares an uncompressed size")
        return declared
    return cap


def decompress(kind: str, data: bytes, declared: int | None = None) -> bytes:
    """``data`` decompressed (``kind``: ``""``/``none``, ``zstd``, ``lz4``, ``bz2``), never
    more than the declared size (if given) or ``CHUNK_BYTES``."""
    cap = _check_declared(declared)
    if kind in ("", "none"):
        out = bytes(data)
    elif kind == "zstd":
        import zstandard

        with zstandard.ZstdDecompressor().stream_reader(data, read_across_frames=True) as r:
            out = r.read(cap + 1)
    elif kind == "lz4":
        import lz4.frame

        dec = lz4.frame.LZ4FrameDecompressor()
        out = dec.decompress(data, max_length=cap + 1)
    elif kind == "bz2":
        dec = bz2.BZ2Decompressor()
        out = dec.decompress(data, max_length=cap + 1)
    else:
        raise LogError(f"unknown chunk compression {kind!r}")
    if len(out) > cap:
        if declared is not None:
            raise LogError(f"corrupt chunk: it inflates beyond the {declared} bytes it declares")
        limits.check("CHUNK_BYTES", len(out), "a chunk inflates to more")
    if declared is not None and len(out) != declared:
        raise LogError(f"corrupt chunk: {len(out)} bytes where it declares {declared}")
    return out
