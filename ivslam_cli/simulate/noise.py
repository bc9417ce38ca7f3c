"""Bounded noise and gross outliers.

In-bound errors satisfy ``|e| <= INSIDE * bound`` so that rounding of the written values
(float64 arithmetic, float32 LaserScan ranges) cannot push them past ``bound``.
Outliers satisfy ``|e| >= bound * (1 + 0.1 * magnitude)``: clearly out of bounds.
"""

from __future__ import annotations

import numpy as np

INSIDE = 0.999


def bounded(rng: np.random.Generator, bound: np.ndarray | float, kind: str, size: int) -> np.ndarray:
    """``size`` errors within ``[-INSIDE * bound, INSIDE * bound]`` (bound may be per sample)."""
    half = INSIDE * np.broadcast_to(np.asarray(bound, dtype=np.float64), (size,))
    if kind == "uniform":
        u = rng.uniform(-1.0, 1.0, size)
    elif kind == "triangular":
        u = rng.triangular(-1.0, 0.0, 1.0, size)
    elif kind == "edges":
        u = np.where(rng.random(size) < 0.5, -1.0, 1.0)
    else:  # pragma: no cover - validated by SimConfig
        raise ValueError(kind)
    return u * half


def outlier(rng: np.random.Generator, bound: np.ndarray | float, magnitude: float, size: int,
            sign: np.ndarray | None = None) -> np.ndarray:
    """``size`` gross errors, ``|e| = bound * (1 + U(0.1, 1) * magnitude)`` (random sign
    unless ``sign`` is given). A zero bound gets ``magnitude * 1e-3`` units instead."""
    b = np.broadcast_to(np.asarray(bound, dtype=np.float64), (size,))
    b = np.where(b > 0, b, 1e-3)
    mag = b * (1.0 + rng.uniform(0.1, 1.0, size) * magnitude)
    if sign is None:
        sign = np.where(rng.random(size) < 0.5, -1.0, 1.0)
    return sign * mag


def pick(rng: np.random.Generator, rate: float, size: int) -> np.ndarray:
    """Boolean mask selecting each of ``size`` items with probability ``rate``."""
    if rate <= 0 or size == 0:
        return np.zeros(size, dtype=bool)
    return rng.random(size) < rate
