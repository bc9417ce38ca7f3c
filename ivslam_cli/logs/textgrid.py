"""Numeric whitespace tables (``#`` comments) to numpy, with clear errors.

Streamed in blocks of lines (:func:`~.textfile.iter_lines`): the peak memory is the table
itself (8 bytes a value) plus one block, whatever the file's size up to the text limit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ivslam_cli import limits
from ivslam_cli.errors import LogError
from ivslam_cli.logs.textfile import iter_lines

BLOCK_LINES = 65536


def table(path: Path, ncols: int) -> np.ndarray:
    """``(rows, ncols)`` float64 of a text table; ragged or non-numeric -> LogError."""
    parts: list[np.ndarray] = []
    block: list[str] = []
    rows = 0

    def flush() -> None:
        nonlocal rows
        try:
            flat = np.array(" ".join(block).split(), dtype=np.float64)
        except ValueError:
            raise LogError("non-numeric value in a numeric table", path) from None
        if flat.size != ncols * len(block):
            raise LogError(f"expected {ncols} columns on every line", path)
        rows += len(block)
        try:
            limits.check("RECORDS", rows, "rows of the table")
        except limits.LimitExceeded as exc:
            raise exc.about(path) from None
        parts.append(flat.reshape(-1, ncols))
        block.clear()

    for line in iter_lines(path):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        if len(s.split()) != ncols:
            raise LogError(f"expected {ncols} columns on every line", path)
        block.append(s)
        if len(block) == BLOCK_LINES:
            flush()
    if block:
        flush()
    return np.concatenate(parts) if parts else np.zeros((0, ncols))


def int_column(values: np.ndarray, what: str, path: Path, low: int = -(2 ** 31), high: int = 2 ** 31) -> np.ndarray:
    """``values`` as int64 if every one is an integer in ``[low, high)``; else LogError."""
    v = np.asarray(values, np.float64)
    ok = np.isfinite(v) & (v == np.round(v)) & (v >= low) & (v < high)
    if not ok.all():
        bad = v[~ok][0]
        raise LogError(f"{what} {bad!r} is not an integer in [{low}, {high})", path)
    return v.astype(np.int64)
