"""Scalar interval arithmetic with outward rounding (numba kernels).

An interval is a pair of float64 ``(lo, hi)``; every function takes and returns bounds as
separate floats so callers keep structure-of-arrays data in registers.

Representation, used everywhere in ivslam:
- ``[lo, hi]`` with ``lo <= hi`` is the closed set of reals between them; infinite bounds
  are allowed (``[-inf, inf]`` is the whole line).
- The empty set is ``(EMPTY_LO, EMPTY_HI) = (+inf, -inf)``; any pair with ``not lo <= hi``
  (including NaN) is treated as empty by :func:`is_empty`.

Guarantee: for every forward operation ``f`` and all reals ``x in [x]`` (``y in [y]``),
``f(x, y)`` lies in the returned interval. Backward operations (``bwd_*``) return the
contracted arguments: no solution of the relation inside the input boxes is removed.
"""

from __future__ import annotations

import math

from numba import njit

from ivslam_cli.interval.rounding import (
    HALF_PI_HI,
    HALF_PI_LO,
    INF,
    INV_TWO_PI_HI,
    INV_TWO_PI_LO,
    PI_HI,
    PI_LO,
    down,
    down2,
    up,
    up2,
)

EMPTY_LO = INF
EMPTY_HI = -INF


# ---------------------------------------------------------------- set operations
@njit(cache=True)
def is_empty(lo: float, hi: float) -> bool:
    return not (lo <= hi)


@njit(cache=True)
def inter(al, ah, bl, bh):
    """Intersection; empty if disjoint (or if either is empty)."""
    lo = al if al > bl else bl
    hi = ah if ah < bh else bh
    if not (lo <= hi):
        return EMPTY_LO, EMPTY_HI
    return lo, hi


@njit(cache=True)
def hull(al, ah, bl, bh):
    """Smallest interval containing both (the empty set is neutral)."""
    if not (al <= ah):
        return bl, bh
    if not (bl <= bh):
        return al, ah
    return (al if al < bl else bl), (ah if ah > bh else bh)


@njit(cache=True)
def width(lo, hi):
    """``hi - lo`` rounded up; 0 for the empty set."""
    if not (lo <= hi):
        return 0.0
    return up(hi - lo)


@njit(cache=True)
def contains(lo, hi, x):
    return lo <= x <= hi


# ---------------------------------------------------------------- forward operations
@njit(cache=True)
def add(al, ah, bl, bh):
    if not (al <= ah) or not (bl <= bh):
        return EMPTY_LO, EMPTY_HI
    return down(al + bl), up(ah + bh)


@njit(cache=True)
def sub(al, ah, bl, bh):
    if not (al <= ah) or not (bl <= bh):
        return EMPTY_LO, EMPTY_HI
    return down(al - bh), up(ah - bl)


@njit(cache=True)
def neg(al, ah):
    if not (al <= ah):
        return EMPTY_LO, EMPTY_HI
    return -ah, -al


@njit(cache=True)
def _prod(a, b):
    # 0 * inf is 0 in interval arithmetic (a bound that is 0 times an unbounded one).
    if a == 0.0 or b == 0.0:
        return 0.0
    return a * b


@njit(cache=True)
def mul(al, ah, bl, bh):
    if not (al <= ah) or not (bl <= bh):
        return EMPTY_LO, EMPTY_HI
    p1 = _prod(al, bl)
    p2 = _prod(al, bh)
    p3 = _prod(ah, bl)
    p4 = _prod(ah, bh)
    lo = min(min(p1, p2), min(p3, p4))
    hi = max(max(p1, p2), max(p3, p4))
    return down(lo), up(hi)


@njit(cache=True)
def scale(al, ah, k):
    """``k * [a]`` for a float ``k`` (exact in the input, rounded outward)."""
    return mul(al, ah, k, k)


@njit(cache=True)
def _quot_lo(a, b):
    q = a / b
    return INF if q != q else q  # inf/inf: ignored in a min


@njit(cache=True)
def _quot_hi(a, b):
    q = a / b
    return -INF if q != q else q  # ignored in a max


@njit(cache=True)
def _div_nozero(al, ah, bl, bh):
    lo = min(min(_quot_lo(al, bl), _quot_lo(al, bh)), min(_quot_lo(ah, bl), _quot_lo(ah, bh)))
    hi = max(max(_quot_hi(al, bl), _quot_hi(al, bh)), max(_quot_hi(ah, bl), _quot_hi(ah, bh)))
    return down(lo), up(hi)


@njit(cache=True)
def div(al, ah, bl, bh):
    """``[a] / [b]``; when 0 is inside ``[b]`` the hull of the (possibly two-piece) result."""
    lo1, hi1, lo2, hi2 = div2(al, ah, bl, bh)
    return hull(lo1, hi1, lo2, hi2)


@njit(cache=True)
def div2(al, ah, bl, bh):
    """Extended division as up to two intervals ``(lo1, hi1, lo2, hi2)`` (second may be empty).

    ``{a / b : a in [a], b in [b], b != 0}``; ``[b] = [0, 0]`` gives the empty set.
    """
    E = EMPTY_LO
    F = EMPTY_HI
    if not (al <= ah) or not (bl <= bh):
        return E, F, E, F
    if bl == 0.0 and bh == 0.0:
        return E, F, E, F
    if bl > 0.0 or bh < 0.0:
        lo, hi = _div_nozero(al, ah, bl, bh)
        return lo, hi, E, F
    # 0 in [b] (and b is not {0})
    if al == 0.0 and ah == 0.0:
        return 0.0, 0.0, E, F
    if al < 0.0 < ah:
        return -INF, INF, E, F
    if bl == 0.0:  # [b] = [0, bh], bh > 0
        if al >= 0.0:
            return down(al / bh), INF, E, F
        return -INF, up(ah / bh), E, F
    if bh == 0.0:  # [b] = [bl, 0], bl < 0
        if al >= 0.0:
            return -INF, up(al / bl), E, F
        return down(ah / bl), INF, E, F
    # bl < 0 < bh: two pieces
    if al >= 0.0:
        return -INF, up(al / bl), down(al / bh), INF
    return -INF, up(ah / bh), down(ah / bl), INF


@njit(cache=True)
def sqr(al, ah):
    if not (al <= ah):
        return EMPTY_LO, EMPTY_HI
    if al >= 0.0:
        return max(0.0, down(al * al)), up(ah * ah)
    if ah <= 0.0:
        return max(0.0, down(ah * ah)), up(al * al)
    m = max(-al, ah)
    return 0.0, up(m * m)


@njit(cache=True)
def sqrt(al, ah):
    """Square root of ``[a] ∩ [0, inf]`` (IEEE sqrt is correctly rounded: one ulp suffices)."""
    if not (al <= ah) or ah < 0.0:
        return EMPTY_LO, EMPTY_HI
    lo = 0.0 if al <= 0.0 else max(0.0, down(math.sqrt(al)))
    return lo, up(math.sqrt(ah))


@njit(cache=True)
def _has_point(al, ah, offset_lo, offset_hi):
    """May ``[a]`` contain a point ``offset + 2 k pi`` (k integer)? Conservative: True if unsure."""
    # k must satisfy (a - offset) / (2 pi) in [k, k]; enclose the quotient outward.
    ql, qh = sub(al, ah, offset_lo, offset_hi)
    ql, qh = mul(ql, qh, INV_TWO_PI_LO, INV_TWO_PI_HI)
    if not (-1e15 < ql and qh < 1e15):  # numba's ceil/floor return int64: undecidable, say yes
        return True
    return math.ceil(ql) <= math.floor(qh)


@njit(cache=True)
def sin(al, ah):
    if not (al <= ah):
        return EMPTY_LO, EMPTY_HI
    if not (ah - al < 6.0) or al == -INF or ah == INF:  # >= 2pi - margin: whole range
        return -1.0, 1.0
    s1 = math.sin(al)
    s2 = math.sin(ah)
    lo = max(-1.0, down2(min(s1, s2)))
    hi = min(1.0, up2(max(s1, s2)))
    if _has_point(al, ah, HALF_PI_LO, HALF_PI_HI):
        hi = 1.0
    if _has_point(al, ah, -HALF_PI_HI, -HALF_PI_LO):
        lo = -1.0
    return lo, hi


@njit(cache=True)
def cos(al, ah):
    if not (al <= ah):
        return EMPTY_LO, EMPTY_HI
    if not (ah - al < 6.0) or al == -INF or ah == INF:
        return -1.0, 1.0
    c1 = math.cos(al)
    c2 = math.cos(ah)
    lo = max(-1.0, down2(min(c1, c2)))
    hi = min(1.0, up2(max(c1, c2)))
    if _has_point(al, ah, 0.0, 0.0):
        hi = 1.0
    if _has_point(al, ah, PI_LO, PI_HI):
        lo = -1.0
    return lo, hi


@njit(cache=True)
def atan(al, ah):
    if not (al <= ah):
        return EMPTY_LO, EMPTY_HI
    lo = -HALF_PI_HI if al == -INF else max(-HALF_PI_HI, down2(math.atan(al)))
    hi = HALF_PI_HI if ah == INF else min(HALF_PI_HI, up2(math.atan(ah)))
    return lo, hi


# ---------------------------------------------------------------- backward operations
@njit(cache=True)
def bwd_add(zl, zh, xl, xh, yl, yh):
    """Contract ``x, y`` under ``z = x + y``; returns ``(x, y)``."""
    xl, xh = inter(xl, xh, *sub(zl, zh, yl, yh))
    yl, yh = inter(yl, yh, *sub(zl, zh, xl, xh))
    return xl, xh, yl, yh


@njit(cache=True)
def bwd_sub(zl, zh, xl, xh, yl, yh):
    """Contract ``x, y`` under ``z = x - y``; returns ``(x, y)``."""
    xl, xh = inter(xl, xh, *add(zl, zh, yl, yh))
    yl, yh = inter(yl, yh, *sub(xl, xh, zl, zh))
    return xl, xh, yl, yh


@njit(cache=True)
def div_meet(tl, th, al, ah, bl, bh):
    """``[t] ∩ ([a] / [b])`` using both pieces of the extended division (tighter than the hull)."""
    l1, h1, l2, h2 = div2(al, ah, bl, bh)
    p1l, p1h = inter(tl, th, l1, h1)
    p2l, p2h = inter(tl, th, l2, h2)
    return hull(p1l, p1h, p2l, p2h)


@njit(cache=True)
def bwd_mul(zl, zh, xl, xh, yl, yh):
    """Contract ``x, y`` under ``z = x * y``; returns ``(x, y)``.

    ``x`` is only contracted where ``0 not in [z] or 0 not in [y]`` (if both hold 0,
    ``y = 0`` allows any ``x``).
    """
    if not (zl <= zh):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    if not (zl <= 0.0 <= zh and yl <= 0.0 <= yh):
        xl, xh = div_meet(xl, xh, zl, zh, yl, yh)
    if not (zl <= 0.0 <= zh and xl <= 0.0 <= xh):
        yl, yh = div_meet(yl, yh, zl, zh, xl, xh)
    if not (xl <= xh) or not (yl <= yh):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    return xl, xh, yl, yh


@njit(cache=True)
def bwd_sqr(zl, zh, xl, xh):
    """Contract ``x`` under ``z = x^2``: ``x ∩ (-sqrt(z) ∪ sqrt(z))``."""
    rl, rh = sqrt(zl, zh)
    if not (rl <= rh):
        return EMPTY_LO, EMPTY_HI
    pl, ph = inter(xl, xh, rl, rh)
    nl, nh = inter(xl, xh, -rh, -rl)
    return hull(pl, ph, nl, nh)


@njit(cache=True)
def bwd_sqrt(zl, zh, xl, xh):
    """Contract ``x`` under ``z = sqrt(x)`` (``z >= 0``)."""
    zl, zh = inter(zl, zh, 0.0, INF)
    return inter(xl, xh, *sqr(zl, zh))
