"""Hypothesis strategies shared by several test files."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st


@st.composite
def pose_box_around(draw, coord, angle, half, ahalf):
    """A true pose ``[x, y, θ]`` (x, y from ``coord``, θ from ``angle``) and a ``(3, 2)`` box
    holding it anywhere (not only at its centre): half-widths from ``half`` (x, y) and ``ahalf``
    (θ), the truth at a random fraction of each side; rounding never leaves it outside."""
    p = [draw(coord), draw(coord), draw(angle)]
    box = np.empty((3, 2))
    for d in range(3):
        h = draw(ahalf if d == 2 else half)
        f = draw(st.floats(0, 1))
        lo = p[d] - 2 * h * f
        box[d] = (min(lo, p[d]), max(lo + 2 * h, p[d]))
    return p, box
