"""Per-scan beam tables of the LiDAR map update, and the parts its two traversals share.

A scan's beams become range intervals ``[lo_i, hi_i]`` (the true distance, for every valid beam)
and free ranges ``free_i = lo_i cos_gap`` (see :func:`_cos_gap`); sparse tables over them
answer min / max over any window of beams in O(1):

- :func:`beam_tables`: four separate tables (the reference's, :mod:`.map_reference`);
- :func:`_fast_tables`: one interleaved table with a fifth field, the gap between consecutive
  valid beams, so that "does a beam of this window meet this range interval" is O(1) unless the
  window holds a jump wider than the interval (:func:`_meets`; exact either way).

Invalid beams prove nothing: ``lo = +inf``, ``hi = -inf``, ``free = -inf``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval.rounding import INF, down, up
from ivslam_cli.paving.tiles import TILE, TILE_SHIFT
from ivslam_cli.slam.lidar.geometry import range_bounds


# ---------------------------------------------------------------- shared by both traversals
_LEVELS = TILE_SHIFT  # quadtree levels per tile (64 = 2^6 cells)


@njit(cache=True)
def _log2_table(n):
    """``t[m] = floor(log2 m)`` for ``2 <= m <= n + 1`` (``t[0] = t[1] = 0``)."""
    t = np.zeros(n + 2, dtype=np.int64)
    for i in range(2, n + 2):
        t[i] = t[i >> 1] + 1
    return t


@njit(cache=True)
def _cos_gap(r_alpha, inc, fill):
    """Factor of the free ranges. Cones that do not touch (``r_alpha < inc / 2``): the gap
    between two beams is filled (free range times ``cos(inc / 2)``) only under the stated
    assumption ``fill``; else no free space (a negative factor proves nothing free)."""
    if r_alpha >= 0.5 * inc:
        return 1.0
    if fill:
        return max(0.0, down(down(math.cos(0.5 * inc)) - 1e-16))
    return -1.0


MAX_SPAN_TILES = 4096  # tiles a side one scan may reach (its work and tables grow with the square)


@njit(cache=True)
def _tile_range(pxl, pxh, pyl, pyh, rmax, eps):
    """Tiles ``[tx0, tx1] x [ty0, ty1]`` holding every point within ``rmax`` of the box (one
    tile of margin). Raises ValueError beyond ``MAX_SPAN_TILES`` tiles a side (the pipeline
    refuses such ranges first, with the log's name: lidar.usable_scans) or 2^30 tiles from the
    origin (the tile index's int32 coordinates)."""
    side = TILE * eps
    if not (max(pxh - pxl, pyh - pyl) + 2.0 * rmax < (MAX_SPAN_TILES - 4) * side):
        raise ValueError("lidar map: a scan reaches over 4096 tiles (2^18 cells) a side")
    if not (max(max(abs(pxl), abs(pxh)), max(abs(pyl), abs(pyh))) + rmax < 2.0**30 * side):
        # the tile index holds int32 tile coordinates
        raise ValueError("lidar map: a scan reaches beyond 2^30 tiles from the origin")
    tx0 = int(math.floor(down(down(pxl - rmax) / side))) - 1
    tx1 = int(math.floor(up(up(pxh + rmax) / side))) + 1
    ty0 = int(math.floor(down(down(pyl - rmax) / side))) - 1
    ty1 = int(math.floor(up(up(pyh + rmax) / side))) + 1
    return tx0, tx1, ty0, ty1


@njit(cache=True, inline="always")
def _unmeasured(cells, t, lx, ly):
    """Whether cell ``(lx, ly)`` of tile index ``t`` (-1: no tile) is in P_UNKNOWN (no flag)."""
    return t < 0 or cells[t, lx, ly] == 0


@njit(cache=True)
def _block_cells(rec, n_rec, ox, oy, k):
    """The cells of blocks ``rec[j] = (ix, iy, level, ...)`` (``j < n_rec``) into ``ox, oy`` from
    index ``k``; returns the next index."""
    for j in range(n_rec):
        s = 1 << rec[j, 2]
        for a in range(s):
            for b in range(s):
                ox[k] = rec[j, 0] + a
                oy[k] = rec[j, 1] + b
                k += 1
    return k


# ---------------------------------------------------------------- the reference's tables
@njit(cache=True)
def _build(tab, nb, is_min):
    """Sparse table in place: ``tab[k, i]`` = min/max of ``tab[0, i : i + 2^k]``."""
    k = 1
    while (1 << k) <= nb:
        half = 1 << (k - 1)
        for i in range(nb - (1 << k) + 1):
            a, b = tab[k - 1, i], tab[k - 1, i + half]
            if is_min:
                tab[k, i] = a if a < b else b
            else:
                tab[k, i] = a if a > b else b
        k += 1


@njit(cache=True)
def _qmin(tab, lg, l, r):
    k = lg[r - l + 1]
    a, b = tab[k, l], tab[k, r - (1 << k) + 1]
    return a if a < b else b


@njit(cache=True)
def _qmax(tab, lg, l, r):
    k = lg[r - l + 1]
    a, b = tab[k, l], tab[k, r - (1 << k) + 1]
    return a if a > b else b


@njit(cache=True)
def beam_tables(ranges, valid, r_abs, r_rel, cos_gap, t_free, t_lo, t_hi, t_fmax):
    """Per-beam intervals and their sparse tables (row 0 = the values).

    ``lo, hi``: range interval of the true distance (``+inf, -inf`` for invalid beams, which
    prove no obstacle); ``free = lo * cos_gap`` (``-inf`` for invalid beams: no free space).
    Returns the largest ``hi`` of the scan (``-inf`` if no valid beam).
    """
    nb = ranges.shape[0]
    rmax = -INF
    for i in range(nb):
        if valid[i]:
            lo, hi = range_bounds(float(ranges[i]), r_abs, r_rel)
            t_lo[0, i] = lo
            t_hi[0, i] = hi
            t_free[0, i] = down(lo * cos_gap)
            rmax = max(rmax, hi)
        else:
            t_lo[0, i] = INF
            t_hi[0, i] = -INF
            t_free[0, i] = -INF
        t_fmax[0, i] = t_free[0, i]
    _build(t_free, nb, True)
    _build(t_fmax, nb, False)
    _build(t_lo, nb, True)
    _build(t_hi, nb, False)
    return rmax


# ---------------------------------------------------------------- the fast path's table
_NF = 5  # fields of the interleaved table: lo (min), hi (max), free (min), free (max), gap (max)


@njit(cache=True)
def _fast_tables(ranges, valid, r_abs, r_rel, cos_gap, T):
    """``T[0, i] = (lo_i, hi_i, free_i, free_i, gap_i)`` (the values of :func:`beam_tables`;
    ``gap_i`` bounds the distance from beam ``i``'s range interval to the next valid beam's:
    ``+inf`` if none, ``-inf`` for an invalid beam), then ``T[k, i]`` = min / max / min / max /
    max over beams ``i .. i + 2^k - 1``. Returns the largest ``hi`` (``-inf``: no valid beam)."""
    nb = ranges.shape[0]
    rmax = -INF
    for i in range(nb):
        if valid[i]:
            lo, hi = range_bounds(float(ranges[i]), r_abs, r_rel)
            T[0, i, 0] = lo
            T[0, i, 1] = hi
            T[0, i, 2] = down(lo * cos_gap)
            rmax = max(rmax, hi)
        else:
            T[0, i, 0] = INF
            T[0, i, 1] = -INF
            T[0, i, 2] = -INF
        T[0, i, 3] = T[0, i, 2]
    nxt = -1
    for i in range(nb - 1, -1, -1):
        if valid[i]:
            if nxt < 0:
                T[0, i, 4] = INF
            else:
                g1 = up(T[0, nxt, 0] - T[0, i, 1])
                g2 = up(T[0, i, 0] - T[0, nxt, 1])
                T[0, i, 4] = g1 if g1 > g2 else g2
            nxt = i
        else:
            T[0, i, 4] = -INF
    k = 1
    while (1 << k) <= nb:
        half = 1 << (k - 1)
        for i in range(nb - (1 << k) + 1):
            j = i + half
            T[k, i, 0] = min(T[k - 1, i, 0], T[k - 1, j, 0])
            T[k, i, 1] = max(T[k - 1, i, 1], T[k - 1, j, 1])
            T[k, i, 2] = min(T[k - 1, i, 2], T[k - 1, j, 2])
            T[k, i, 3] = max(T[k - 1, i, 3], T[k - 1, j, 3])
            T[k, i, 4] = max(T[k - 1, i, 4], T[k - 1, j, 4])
        k += 1
    return rmax


@njit(cache=True, inline="always")
def _win(T, lg, l, r):
    """Over beams ``[l, r]`` (``l <= r``): min lo, max hi, min free, max free."""
    k = lg[r - l + 1]
    j = r - (1 << k) + 1
    return (min(T[k, l, 0], T[k, j, 0]), max(T[k, l, 1], T[k, j, 1]), min(T[k, l, 2], T[k, j, 2]),
            max(T[k, l, 3], T[k, j, 3]))


@njit(cache=True, inline="always")
def _meets(T, lg, l, r, a, b, lo_min, hi_max, st):
    """Whether a valid beam ``i`` in ``[l, r]`` has ``lo_i <= a`` and ``hi_i >= b`` (exact);
    ``lo_min, hi_max``: the window's hull (:func:`_win`).

    O(1) unless the window holds a jump: if the hull test passes, walking from a beam with
    ``lo <= a`` to one with ``hi >= b`` through consecutive valid beams, if none meets, some
    pair must jump over ``[b, a]`` (gap > a - b). So when no gap of the window exceeds
    ``a - b`` a beam meets; else the window is scanned."""
    return _meets_g(T, lg, l, r, a, b, lo_min, hi_max, down(a - b), st)


@njit(cache=True, inline="always")
def _meets_g(T, lg, l, r, a, b, lo_min, hi_max, g, st):
    """:func:`_meets`, the gaps allowed up to ``g`` (``g <= a - b``, or see the callers)."""
    if l > r or lo_min > a or hi_max < b:
        return False
    if l == r:
        return True
    k = lg[r - l]
    if max(T[k, l, 4], T[k, r - (1 << k), 4]) <= g:
        return True
    # a jump: the same two tests on sub-windows [p, p + 2^k - 1] (the argument holds on any
    # run of consecutive beams), halving those whose hull meets but which hold a jump, skipping
    # those whose hull misses; single beams are tested exactly
    p = l
    while p <= r:
        k = lg[r - p + 1]
        while True:
            st[2] += 1
            if T[k, p, 0] > a or T[k, p, 1] < b:
                p += 1 << k
                break
            if k == 0:
                return True
            j = k - 1
            if max(T[j, p, 4], T[j, p + (1 << j) - 1, 4]) <= g:  # gaps of beams p .. p + 2^k - 2
                return True
            k = j
    return False


@njit(cache=True)
def _fast_buffers(nbmax):
    """The log2 table and an interleaved table (:func:`_fast_tables`) for scans of up to ``nbmax``
    beams."""
    lg = _log2_table(nbmax)
    return lg, np.empty((lg[nbmax] + 1, nbmax, _NF))
