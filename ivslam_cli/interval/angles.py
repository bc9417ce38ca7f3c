"""Angles: arguments of boxes, atan2, and intervals on the circle (numba kernels).

Headings and bearings are real intervals read modulo 2 pi. Nothing here loses an angle across
the ±pi cut of atan2 or across any multiple of 2 pi (a known soundness bug of generic atan2
contractors). Bounds are rounded outward like everything in :mod:`ivslam_cli.interval.arith`.
"""

from __future__ import annotations

import math

from numba import njit

from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, add, inter, mul, sub
from ivslam_cli.interval.rounding import (
    HALF_PI_HI,
    HALF_PI_LO,
    INF,
    INV_TWO_PI_HI,
    INV_TWO_PI_LO,
    PI_HI,
    TWO_PI_HI,
    TWO_PI_LO,
    down,
    down2,
    up,
    up2,
)


@njit(cache=True)
def _corner_angle(x, y):
    # +0.0 turns -0.0 into +0.0, so a corner on the negative x-axis has angle +pi.
    return math.atan2(y + 0.0, x + 0.0)


@njit(cache=True)
def arg_box(xl, xh, yl, yh):
    """The arguments of the points of the box ``[x] x [y]``, as a real interval.

    Returns ``(lo, hi)`` such that every point ``(x, y) != 0`` of the box has an argument in
    ``[lo, hi] + 2 pi Z``. When the box holds the origin it is ``[-pi, pi]`` (every angle).
    When the box crosses the negative x-axis the interval is around pi (``hi > pi``), so the
    result never loses angles across the ±pi cut of atan2.
    """
    if not (xl <= xh) or not (yl <= yh):
        return EMPTY_LO, EMPTY_HI
    if xl <= 0.0 <= xh and yl <= 0.0 <= yh:
        return -PI_HI, PI_HI
    straddle = xl < 0.0 and yl < 0.0 <= yh
    lo = INF
    hi = -INF
    for k in range(4):
        cx = xl if (k & 1) == 0 else xh
        cy = yl if (k & 2) == 0 else yh
        if cx == -INF or cx == INF or cy == -INF or cy == INF:
            # unbounded box: fall back to the angles of the directions it spans
            return _arg_unbounded(xl, xh, yl, yh)
        t = _corner_angle(cx, cy)
        tl = down2(t)
        th = up2(t)
        if straddle and cy < 0.0:
            tl = down(tl + TWO_PI_LO)
            th = up(th + TWO_PI_HI)
        lo = min(lo, tl)
        hi = max(hi, th)
    return lo, hi


@njit(cache=True)
def _arg_unbounded(xl, xh, yl, yh):
    # Half-plane bounds are enough (tightness here is irrelevant in practice).
    if xl > 0.0:
        return -HALF_PI_HI, HALF_PI_HI
    if yl > 0.0:
        return 0.0, PI_HI
    if yh < 0.0:
        return -PI_HI, 0.0
    if xh < 0.0:
        return HALF_PI_LO, 1.5 * PI_HI
    return -PI_HI, PI_HI


@njit(cache=True)
def atan2(yl, yh, xl, xh):
    """``atan2([y], [x])`` as a real interval within ``[-pi, pi]`` (the hull across the cut)."""
    lo, hi = arg_box(xl, xh, yl, yh)
    if not (lo <= hi):
        return lo, hi
    if xl < 0.0 and yl < 0.0 <= yh:  # crosses the cut: values near -pi and near pi
        return -PI_HI, PI_HI
    return max(lo, -PI_HI), min(hi, PI_HI)


# ---------------------------------------------------------------- angles on the circle
@njit(cache=True)
def shift(al, ah, k):
    """``[a] + 2 k pi`` (k an integer given as float), rounded outward."""
    if k == 0.0:
        return al, ah
    sl, sh = mul(k, k, TWO_PI_LO, TWO_PI_HI)
    return add(al, ah, sl, sh)


@njit(cache=True)
def angle_meet(tl, th, al, ah):
    """``[t] ∩ ([a] + 2 pi Z)``, as the hull of the pieces, in ``[t]``'s own branch.

    ``[t]`` is any real interval of angles (it keeps its representation: ``[10, 11]`` stays
    near 10). Sound across every multiple of 2 pi: no angle equal to some ``a + 2 k pi``
    inside ``[t]`` is removed.
    """
    if not (tl <= th) or not (al <= ah):
        return EMPTY_LO, EMPTY_HI
    if ah - al >= TWO_PI_LO or tl == -INF or th == INF:
        return tl, th
    # Fast path: when w(t) + w(a) < 2 pi at most one copy of [a] meets [t]; if k = 0 does, done.
    if up(up(th - tl) + up(ah - al)) < TWO_PI_LO:
        pl, ph = inter(tl, th, al, ah)
        if pl <= ph:
            return pl, ph
    # candidate k: (t - a) / 2pi in [k] (enclosed outward, then one extra k each side is tried)
    ql, qh = sub(tl, th, al, ah)
    ql, qh = mul(ql, qh, INV_TWO_PI_LO, INV_TWO_PI_HI)
    # decide in floats: numba's math.ceil/floor return int64, which overflows past 2^63
    if not (qh - ql <= 1e6 and -1e15 < ql and qh < 1e15):
        return tl, th
    k_lo = math.ceil(ql)
    k_hi = math.floor(qh)
    # first non-empty piece from below
    lo = EMPTY_LO
    k = k_lo - 1.0
    while k <= k_hi + 1.0:
        pl, ph = inter(tl, th, *shift(al, ah, k))
        if pl <= ph:
            lo = pl
            break
        k += 1.0
    if lo == EMPTY_LO:
        return EMPTY_LO, EMPTY_HI
    hi = EMPTY_HI
    k = k_hi + 1.0
    while k >= k_lo - 1.0:
        pl, ph = inter(tl, th, *shift(al, ah, k))
        if pl <= ph:
            hi = ph
            break
        k -= 1.0
    return lo, hi


@njit(cache=True)
def angle_meet_narrow(tl, th, al, ah):
    """``[t] ∩ ([a] + 2 pi Z)`` up to representation: the narrower of ``angle_meet(t, a)`` (in
    ``[t]``'s branch) and ``angle_meet(a, t)`` (in ``[a]``'s branch).

    Both hold every angle of the meet modulo 2 pi, so either is sound where angles are only
    used modulo 2 pi; a meet in a wide ``[t]`` (several turns) keeps every copy of ``[a]``
    and its hull hardly shrinks, while the other branch gives the narrow arc.
    """
    pl, ph = angle_meet(tl, th, al, ah)
    if not (pl <= ph):
        return pl, ph
    ql, qh = angle_meet(al, ah, tl, th)
    if ql <= qh and qh - ql < ph - pl:
        return ql, qh
    return pl, ph
