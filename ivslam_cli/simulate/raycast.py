"""Ray casting against wall segments (numba kernel; many rays x many segments)."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def cast_scans(pose: np.ndarray, beam_angle: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distance along every beam of every scan to the first wall, ``inf`` if none.

    ``pose`` ``(T, 3)`` = sensor x, y, yaw; ``beam_angle`` ``(B,)`` in the sensor frame;
    ``segments`` ``(K, 4)``; returns ``(T, B)``. A ray ``o + t d`` (t > 0) hits segment
    ``a + s (b - a)`` for ``s`` in [0, 1]; segments parallel to the ray are skipped (their
    end points belong to the walls they join). One division per hit, nothing accumulated.
    """
    n, m, k = pose.shape[0], beam_angle.shape[0], segments.shape[0]
    out = np.empty((n, m))
    for i in range(n):
        ox, oy, yaw = pose[i, 0], pose[i, 1], pose[i, 2]
        for b in range(m):
            dx, dy = np.cos(yaw + beam_angle[b]), np.sin(yaw + beam_angle[b])
            best = np.inf
            for j in range(k):
                ax, ay = segments[j, 0], segments[j, 1]
                ex, ey = segments[j, 2] - ax, segments[j, 3] - ay
                den = dx * ey - dy * ex
                if den == 0.0:
                    continue
                wx, wy = ax - ox, ay - oy
                t = (wx * ey - wy * ex) / den
                s = (wx * dy - wy * dx) / den
                if t > 0.0 and 0.0 <= s <= 1.0 and t < best:
                    best = t
            out[i, b] = best
    return out


def cast(pose: np.ndarray, beam_angle: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """:func:`cast_scans` on any array-likes (made contiguous float64)."""
    return cast_scans(np.ascontiguousarray(np.atleast_2d(pose), dtype=np.float64),
                      np.ascontiguousarray(np.atleast_1d(beam_angle), dtype=np.float64),
                      np.ascontiguousarray(segments, dtype=np.float64))
