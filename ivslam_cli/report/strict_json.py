"""Strict JSON values for every document ``ivslam`` writes (``report --json``, ``fleet.json``):
NaN → null, ±inf → the strings ``"inf"``/``"-inf"`` (e.g. unbounded config values)."""

from __future__ import annotations

import math
from typing import Any


def strict(x: Any) -> Any:
    """``x`` with every non-finite float replaced (dict keys as strings, tuples as lists)."""
    if isinstance(x, dict):
        return {str(k): strict(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [strict(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else ("inf" if x > 0 else "-inf")
    return x
