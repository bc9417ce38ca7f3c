"""q-relaxed intersection: keep what all but at most ``q`` of ``m`` sets agree on.

For ``m`` intervals the q-relaxed intersection is the set of reals that belong to at least
``k = m - q`` of them: a union of closed intervals whose hull is computed **exactly** (no
arithmetic, so no rounding) by sorting the endpoints, O(m log m): the smallest such real is
the first lower bound at which ``#{lo_i <= x} - #{hi_i < x} >= k``, the largest symmetrically.

For ``m`` boxes of dimension ``d`` the exact q-relaxed intersection (Jaulin) is NP-hard; we
return the hull, per dimension, of the q-relaxed intersections of the projections. It is an
**outer approximation**: a point in at least ``k`` boxes is, in every dimension, in at least
``k`` of the intervals, so it is inside the result. It can be larger than the hull of the
exact set.

Conventions: empty inputs (``not lo <= hi``, NaN included) contain no point and so count
against the ``q`` allowed outliers; ``q >= m`` (including ``m = 0``) gives the whole space.
An input is *rejected* (inconsistent with the result) when it is disjoint from the result
(which includes every input when the result is empty): no point the majority agrees on
lies in it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, INF


@njit(cache=True)
def qinter_interval(lo, hi, q):
    """Hull of ``{x : x in [lo_i, hi_i] for at least m - q indices i}`` for 1-D arrays."""
    m = lo.shape[0]
    k = m - q
    if k <= 0:
        return -INF, INF
    keep = lo <= hi  # NaN-safe: empty and NaN rows are dropped
    ls = np.sort(lo[keep])
    hs = np.sort(hi[keep])
    n = ls.shape[0]
    if n < k:
        return EMPTY_LO, EMPTY_HI
    # lower bound: first ls[j] with (j + 1) - #{h < ls[j]} >= k. Within a run of equal ls the
    # count j + 1 undercounts until the run's end, which only delays the hit inside the run.
    rlo = EMPTY_LO
    p = 0
    for j in range(n):
        x = ls[j]
        while p < n and hs[p] < x:
            p += 1
        if j + 1 - p >= k:
            rlo = x
            break
    if rlo == EMPTY_LO:
        return EMPTY_LO, EMPTY_HI
    # upper bound: last hs[j] (from the top) with #{h >= hs[j]} - #{l > hs[j]} >= k
    rhi = EMPTY_HI
    p = n - 1
    for j in range(n - 1, -1, -1):
        x = hs[j]
        while p >= 0 and ls[p] > x:
            p -= 1
        if (n - j) - (n - 1 - p) >= k:
            rhi = x
            break
    return rlo, rhi


@njit(cache=True)
def qinter_group(boxes, q, out, rejected):
    """One group: ``boxes`` ``(m, d, 2)``; writes the ``(d, 2)`` result and the rejected mask."""
    m = boxes.shape[0]
    d = boxes.shape[1]
    empty = False
    for j in range(d):
        lo, hi = qinter_interval(np.ascontiguousarray(boxes[:, j, 0]),
                                 np.ascontiguousarray(boxes[:, j, 1]), q)
        out[j, 0] = lo
        out[j, 1] = hi
        if not (lo <= hi):
            empty = True
    if empty:
        for j in range(d):
            out[j, 0] = EMPTY_LO
            out[j, 1] = EMPTY_HI
    for i in range(m):
        disjoint = empty
        for j in range(d):
            bl = boxes[i, j, 0]
            bh = boxes[i, j, 1]
            if not (bl <= bh) or bh < out[j, 0] or bl > out[j, 1]:
                disjoint = True
        rejected[i] = disjoint


@njit(cache=True)
def qinter_batch_kernel(boxes, offsets, q):
    """Groups ``boxes[offsets[g]:offsets[g+1]]`` with ``q[g]`` outliers each.

    Returns ``(out, rejected)``: ``(G, d, 2)`` results and an ``(M,)`` mask over all inputs.
    """
    g_count = offsets.shape[0] - 1
    d = boxes.shape[1]
    out = np.empty((g_count, d, 2))
    rejected = np.zeros(boxes.shape[0], dtype=np.bool_)
    for g in range(g_count):
        a = offsets[g]
        b = offsets[g + 1]
        qinter_group(boxes[a:b], q[g], out[g], rejected[a:b])
    return out, rejected
