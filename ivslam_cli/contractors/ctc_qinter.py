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


SMALL_M = 32  # up to this many inputs, qinter_interval counts per candidate instead of sorting


@njit(cache=True)
def qinter_prefix(lo, hi, m, q):
    """:func:`qinter_interval` of the first ``m`` entries (no view made for few of them)."""
    if m - q <= 0:
        return -INF, INF
    if m <= SMALL_M:
        return _qinter_counted(lo, hi, m, m - q)
    return qinter_interval(lo[:m], hi[:m], q)


@njit(cache=True)
def qinter_interval(lo, hi, q):
    """Hull of ``{x : x in [lo_i, hi_i] for at least m - q indices i}`` for 1-D arrays."""
    m = lo.shape[0]
    k = m - q
    if k <= 0:
        return -INF, INF
    if m <= SMALL_M:
        return _qinter_counted(lo, hi, m, k)
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
def _qinter_counted(lo, hi, m, k):
    """:func:`qinter_interval` of the first ``m`` inputs when few, ``k = m − q ≥ 1`` of them
    to agree: the least lower end ``x`` with ``#{lo_j ≤ x} − #{hi_j < x} ≥ k`` over the
    non-empty inputs, and symmetrically the greatest upper end (the sorted sweep's answer,
    O(m²) comparisons, no allocation). :func:`qinter_capped_prefix` scans the ends the same
    way; the count is written out in each, since a shared test function would take the arrays
    a call per end, and each array argument costs numba a reference count a call."""
    n = 0
    for i in range(m):
        n += lo[i] <= hi[i]
    if n < k:
        return EMPTY_LO, EMPTY_HI
    rlo = EMPTY_LO
    found = False
    for i in range(m):
        x = lo[i]
        if not (x <= hi[i]) or (found and x >= rlo):
            continue
        c = 0
        for j in range(m):
            if lo[j] <= hi[j]:
                c += (lo[j] <= x) - (hi[j] < x)
        if c >= k:
            rlo = x
            found = True
    if not found:
        return EMPTY_LO, EMPTY_HI
    rhi = EMPTY_HI
    found = False
    for i in range(m):
        x = hi[i]
        if not (lo[i] <= x) or (found and x <= rhi):
            continue
        c = 0
        for j in range(m):
            if lo[j] <= hi[j]:
                c += (hi[j] >= x) - (lo[j] > x)
        if c >= k:
            rhi = x
            found = True
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


@njit(cache=True)
def _over(cnt, cap, g, step):
    """Add ``step`` (±1) to group ``g``'s count; the change in the number of groups over their cap."""
    if g < 0:
        return 0
    before = cnt[g] > cap[g]
    cnt[g] += step
    return int(cnt[g] > cap[g]) - int(before)


@njit(cache=True)
def droppable(fail, ga, ca, gb, cb):
    """Do the inputs with ``fail[i]`` keep to the caps: at most ``ca[g]`` of group ``g`` of the
    first grouping (``ga[i]``, −1: none) and ``cb[g]`` of the second (``gb``)?"""
    na = np.zeros(ca.shape[0], np.int64)
    nb = np.zeros(cb.shape[0], np.int64)
    for i in range(fail.shape[0]):
        if fail[i]:
            if ga[i] >= 0:
                na[ga[i]] += 1
                if na[ga[i]] > ca[ga[i]]:
                    return False
            if gb[i] >= 0:
                nb[gb[i]] += 1
                if nb[gb[i]] > cb[gb[i]]:
                    return False
    return True


@njit(cache=True)
def _caps_hold(x, everything, lo, hi, m, groups, ka, kb):
    """Do the first ``m`` inputs failing at ``x`` (all of them with ``everything``) keep to the
    caps (:func:`droppable`)? ``groups`` as :func:`qinter_capped_prefix` takes it."""
    for g in range(ka):
        groups[4, g] = 0
    for g in range(kb):
        groups[5, g] = 0
    for i in range(m):
        if everything or not (lo[i] <= x and x <= hi[i]):  # empty (NaN) inputs fail at every x
            g = groups[0, i]
            if g >= 0:
                groups[4, g] += 1
                if groups[4, g] > groups[2, g]:
                    return False
            g = groups[1, i]
            if g >= 0:
                groups[5, g] += 1
                if groups[5, g] > groups[3, g]:
                    return False
    return True


@njit(cache=True)
def qinter_capped_prefix(lo, hi, m, groups, ka, kb):
    """:func:`qinter_capped_interval` of the first ``m`` inputs, the groupings in the rows of
    one int64 array (one array argument, not six: numba counts references per array per call):
    ``groups[0, :m]``, ``groups[1, :m]`` the groups of the inputs (``ga``, ``gb``),
    ``groups[2, :ka]``, ``groups[3, :kb]`` their caps (``ca``, ``cb``), rows 4 and 5 work space.
    Up to ``SMALL_M`` inputs, each lower end is tried as the least real whose failing inputs
    keep to the caps (the sweep's answer; symmetrically the upper ends), O(m²) and no
    allocation; beyond, the sweep."""
    if m > SMALL_M:
        return qinter_capped_interval(lo[:m], hi[:m], groups[0, :m], groups[2, :ka], groups[1, :m], groups[3, :kb])
    if _caps_hold(0.0, True, lo, hi, m, groups, ka, kb):  # all may fail together
        return -INF, INF
    rlo = EMPTY_LO
    found = False
    for i in range(m):
        x = lo[i]
        if not (x <= hi[i]) or (found and x >= rlo):
            continue
        if _caps_hold(x, False, lo, hi, m, groups, ka, kb):
            rlo = x
            found = True
    if not found:
        return EMPTY_LO, EMPTY_HI
    rhi = EMPTY_HI
    found = False
    for i in range(m):
        x = hi[i]
        if not (lo[i] <= x) or (found and x <= rhi):
            continue
        if _caps_hold(x, False, lo, hi, m, groups, ka, kb):
            rhi = x
            found = True
    return rlo, rhi


@njit(cache=True)
def qinter_capped_interval(lo, hi, ga, ca, gb, cb):
    """Hull of the reals ``x`` whose failing inputs ``{i : x ∉ [lo_i, hi_i]}`` keep to the caps
    of two groupings (:func:`droppable`): the q-relaxed intersection when the wrong inputs are
    bounded per group (per pose and per landmark) rather than in all. It holds every ``x`` that
    all inputs but such a set contain; it is never wider than :func:`qinter_interval` with ``q``
    the largest number of inputs the caps let fail together. Exact (no arithmetic), O(m log m)."""
    m = lo.shape[0]
    na = np.zeros(ca.shape[0], np.int64)
    nb = np.zeros(cb.shape[0], np.int64)
    bad = 0
    for i in range(m):  # below every input, all fail
        bad += _over(na, ca, ga[i], 1) + _over(nb, cb, gb[i], 1)
    if bad == 0:  # all may fail together
        return -INF, INF
    ok = np.empty(m, np.bool_)
    for i in range(m):
        ok[i] = lo[i] <= hi[i]  # empty (NaN) inputs fail at every x
    ol = np.argsort(lo)
    oh = np.argsort(hi)
    # lower bound: sweep x up through the lower ends; input i stops failing at lo_i, fails again past hi_i
    rlo = EMPTY_LO
    p = 0
    j = 0
    while j < m:
        x = lo[ol[j]]
        if not ok[ol[j]]:
            j += 1
            continue
        while j < m and (lo[ol[j]] <= x or not ok[ol[j]]):
            i = ol[j]
            if ok[i]:
                bad += _over(na, ca, ga[i], -1) + _over(nb, cb, gb[i], -1)
            j += 1
        while p < m and (not ok[oh[p]] or hi[oh[p]] < x):
            i = oh[p]
            if ok[i]:
                bad += _over(na, ca, ga[i], 1) + _over(nb, cb, gb[i], 1)
            p += 1
        if bad == 0:
            rlo = x
            break
    if rlo == EMPTY_LO:
        return EMPTY_LO, EMPTY_HI
    # upper bound: the same from above
    na[:] = 0
    nb[:] = 0
    bad = 0
    for i in range(m):
        bad += _over(na, ca, ga[i], 1) + _over(nb, cb, gb[i], 1)
    rhi = EMPTY_HI
    p = m - 1
    j = m - 1
    while j >= 0:
        x = hi[oh[j]]
        if not ok[oh[j]]:
            j -= 1
            continue
        while j >= 0 and (hi[oh[j]] >= x or not ok[oh[j]]):
            i = oh[j]
            if ok[i]:
                bad += _over(na, ca, ga[i], -1) + _over(nb, cb, gb[i], -1)
            j -= 1
        while p >= 0 and (not ok[ol[p]] or lo[ol[p]] > x):
            i = ol[p]
            if ok[i]:
                bad += _over(na, ca, ga[i], 1) + _over(nb, cb, gb[i], 1)
            p -= 1
        if bad == 0:
            rhi = x
            break
    return rlo, rhi
