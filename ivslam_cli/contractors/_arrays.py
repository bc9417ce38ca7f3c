"""Argument checking shared by the Python-facing contractor API."""

from __future__ import annotations

import numpy as np

from ivslam_cli.interval.rounding import ensure_round_to_nearest


def boxes(name: str, a: np.ndarray, n: int | None = None) -> int:
    """Check ``a`` is a writable C-contiguous ``(N, 2)`` float64 array; return N.

    Contractors work in place, so a copy would silently drop the result: refuse instead.
    Also restores round-to-nearest, which the kernels' outward rounding assumes.
    """
    ensure_round_to_nearest()
    if not isinstance(a, np.ndarray) or a.dtype != np.float64 or a.ndim != 2 or a.shape[1] != 2:
        raise TypeError(f"{name}: expected an (N, 2) float64 numpy array of [lo, hi] rows")
    if not a.flags.c_contiguous or not a.flags.writeable:
        raise ValueError(f"{name}: array must be C-contiguous and writable (contracted in place)")
    if n is not None and a.shape[0] != n:
        raise ValueError(f"{name}: has {a.shape[0]} rows, expected {n}")
    return a.shape[0]
