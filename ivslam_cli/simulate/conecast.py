"""Cone casting against wall segments (numba kernel; many cones x many segments).

The cone of a beam at angle ``a`` with half-width ``h`` (``0 <= h < pi/2``) is the closed
angular sector ``W = {o + r (cos phi, sin phi) : r >= 0, |phi - a| <= h}``. Its return is the
distance from ``o`` to the nearest wall point in ``W``: every point of ``W`` closer than
that is free. Only the distance is computed, not the direction it lies at.

A segment ``p + t (q - p)``, ``t`` in [0, 1], is clipped against the three half-planes whose
intersection is ``W`` for ``h < pi/2``: left of the ray at ``a - h``, right of the ray at
``a + h`` (both through ``o``), and ahead of ``o`` along the bisector ``a`` (the first two
alone hold the opposite sector too when ``h`` is 0). The distance of ``o`` to the clipped
piece ``[t_lo, t_hi]`` is that of the point at ``clamp(t_perp, t_lo, t_hi)``, ``t_perp`` the
foot of the perpendicular from ``o`` on the segment's line.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _clip(f0, f1, lo, hi):
    """Clip ``[lo, hi]`` to where ``f0 + t (f1 - f0) >= 0`` (a linear function of ``t``)."""
    if f0 >= 0.0 and f1 >= 0.0:
        return lo, hi
    if f0 < 0.0 and f1 < 0.0:
        return 1.0, 0.0
    t = f0 / (f0 - f1)
    if f0 < 0.0:
        return max(lo, t), hi
    return lo, min(hi, t)


@njit(cache=True, inline="always")
def _in_cone(px, py, ex, ey, tp, cx, cy, lx, ly, rx, ry):
    """Distance from the sensor to the segment ``p + t e`` (relative to it; ``tp`` the foot of
    the perpendicular) clipped to the cone of bisector ``(cx, cy)`` and edges ``(lx, ly)``,
    ``(rx, ry)``; ``inf`` when no part of it is in the cone."""
    qx, qy = px + ex, py + ey
    lo, hi = _clip(cx * px + cy * py, cx * qx + cy * qy, 0.0, 1.0)  # ahead
    if lo > hi:
        return np.inf
    lo, hi = _clip(lx * py - ly * px, lx * qy - ly * qx, lo, hi)  # left of a - h
    if lo > hi:
        return np.inf
    lo, hi = _clip(px * ry - py * rx, qx * ry - qy * rx, lo, hi)  # right of a + h
    if lo > hi:
        return np.inf
    t = min(hi, max(lo, tp))
    return math.hypot(px + t * ex, py + t * ey)


@njit(cache=True)
def cone_scans(pose: np.ndarray, beam_angle: np.ndarray, half_width: float,
               segments: np.ndarray) -> np.ndarray:
    """Distance from the sensor to the nearest wall point within every beam's cone, ``inf``
    if none.

    ``pose`` ``(T, 3)`` = sensor x, y, yaw; ``beam_angle`` ``(B,)`` nominal angles in the
    sensor frame; ``half_width`` the cone half-width ``h`` (``0 <= h < pi/2``); ``segments``
    ``(K, 4)``; returns ``(T, B)``. Per scan the segments are taken relative to the sensor,
    with their distance to it (a lower bound of their distance within any cone): a segment
    no nearer than the best distance found so far is skipped.
    """
    n, m, k = pose.shape[0], beam_angle.shape[0], segments.shape[0]
    out = np.empty((n, m))
    rel = np.empty((k, 4))
    tp = np.empty(k)
    near = np.empty(k)
    for i in range(n):
        ox, oy, yaw = pose[i, 0], pose[i, 1], pose[i, 2]
        for j in range(k):
            px, py = segments[j, 0] - ox, segments[j, 1] - oy
            ex, ey = segments[j, 2] - segments[j, 0], segments[j, 3] - segments[j, 1]
            rel[j, 0], rel[j, 1], rel[j, 2], rel[j, 3] = px, py, ex, ey
            e2 = ex * ex + ey * ey
            t = -(px * ex + py * ey) / e2 if e2 > 0.0 else 0.0
            tp[j] = t
            tc = min(1.0, max(0.0, t))
            near[j] = math.hypot(px + tc * ex, py + tc * ey)
        for b in range(m):
            a = yaw + beam_angle[b]
            cx, cy = math.cos(a), math.sin(a)
            lx, ly = math.cos(a - half_width), math.sin(a - half_width)
            rx, ry = math.cos(a + half_width), math.sin(a + half_width)
            best = np.inf
            for j in range(k):
                if near[j] >= best:
                    continue
                d = _in_cone(rel[j, 0], rel[j, 1], rel[j, 2], rel[j, 3], tp[j], cx, cy, lx, ly, rx, ry)
                if d < best:
                    best = d
            out[i, b] = best
    return out


@njit(cache=True)
def swept_cone_scans(pose: np.ndarray, twist: np.ndarray, stamp: np.ndarray, mount: np.ndarray,
                     beam_angle: np.ndarray, beam_time: np.ndarray, half_width: float,
                     segments: np.ndarray) -> np.ndarray:
    """:func:`cone_scans` with each beam taken at its own time: beam ``b`` of scan ``i`` from the
    sensor of the robot ``beam_time[b]`` after pose ``i``, on the arcs it drives (robot poses
    ``(T, 3)`` at ``stamp`` ``(T,)``, each twist ``(v, ω)`` ``(T, 2)`` held until the next
    stamp; ``mount`` (3,) the sensor on the robot): the exact unicycle motion the poses come
    from (:func:`~.motion.step_scalar`)."""
    n, m, k = pose.shape[0], beam_angle.shape[0], segments.shape[0]
    out = np.empty((n, m))
    for i in range(n):
        for b in range(m):
            j = i
            while j + 1 < n and stamp[j + 1] - stamp[i] <= beam_time[b]:
                j += 1
            t = beam_time[b] - (stamp[j] - stamp[i])
            half = 0.5 * twist[j, 1] * t
            chord = twist[j, 0] * t * (math.sin(half) / half if half != 0.0 else 1.0)
            x = pose[j, 0] + chord * math.cos(pose[j, 2] + half)
            y = pose[j, 1] + chord * math.sin(pose[j, 2] + half)
            th = pose[j, 2] + 2.0 * half
            c, s = math.cos(th), math.sin(th)
            ox, oy = x + c * mount[0] - s * mount[1], y + s * mount[0] + c * mount[1]
            a = th + mount[2] + beam_angle[b]
            cx, cy = math.cos(a), math.sin(a)
            lx, ly = math.cos(a - half_width), math.sin(a - half_width)
            rx, ry = math.cos(a + half_width), math.sin(a + half_width)
            best = np.inf
            for j in range(k):
                px, py = segments[j, 0] - ox, segments[j, 1] - oy
                ex, ey = segments[j, 2] - segments[j, 0], segments[j, 3] - segments[j, 1]
                e2 = ex * ex + ey * ey
                tp = -(px * ex + py * ey) / e2 if e2 > 0.0 else 0.0
                d = _in_cone(px, py, ex, ey, tp, cx, cy, lx, ly, rx, ry)
                if d < best:
                    best = d
            out[i, b] = best
    return out


def cone_cast(pose: np.ndarray, beam_angle: np.ndarray, half_width: float,
              segments: np.ndarray) -> np.ndarray:
    """:func:`cone_scans` on any array-likes (made contiguous float64)."""
    h = float(half_width)
    if not 0.0 <= h < 0.5 * math.pi:
        raise ValueError(f"cone half-width must be in [0, pi/2), got {h}")
    return cone_scans(np.ascontiguousarray(np.atleast_2d(pose), dtype=np.float64),
                      np.ascontiguousarray(np.atleast_1d(beam_angle), dtype=np.float64), h,
                      np.ascontiguousarray(segments, dtype=np.float64))
