"""Numeric whitespace tables (``#`` comments) to numpy, with clear errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ivslam_cli.errors import LogError
from ivslam_cli.logs.textfile import read_text


def table(path: Path, ncols: int) -> np.ndarray:
    """``(rows, ncols)`` float64 of a text table; ragged or non-numeric -> LogError."""
    lines = [ln for ln in read_text(path).splitlines() if ln.strip() and
             not ln.lstrip().startswith("#")]
    try:
        flat = np.array(" ".join(lines).split(), dtype=np.float64)
    except ValueError:
        raise LogError("non-numeric value in a numeric table", path) from None
    if flat.size % ncols or flat.size != ncols * len(lines):
        raise LogError(f"expected {ncols} columns on every line", path)
    return flat.reshape(-1, ncols)
