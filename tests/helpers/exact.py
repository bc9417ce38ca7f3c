"""Float intervals that surely hold a real value (mpmath)."""

from __future__ import annotations

import mpmath
import numpy as np


def around(value: mpmath.mpf, below: float, above: float) -> list[float]:
    """A float interval that surely holds the real ``value`` (outward by an ulp past the margins)."""
    v = float(value)
    lo = float(np.nextafter(v - below, -np.inf))
    hi = float(np.nextafter(v + above, np.inf))
    assert mpmath.mpf(lo) <= value <= mpmath.mpf(hi)
    return [lo, hi]
