"""Interval multiplication and its backward contractor as selects, for SIMD loops.

:func:`mul_s`, :func:`div_meet_s` and :func:`bwd_mul_s` give the bounds of
:func:`~ivslam_cli.interval.arith.mul`, :func:`~ivslam_cli.interval.arith.div_meet` and
:func:`~ivslam_cli.interval.arith.bwd_mul` bit for bit on non-empty intervals (the same float
operations, rounded outward by :func:`~ivslam_cli.interval.rounding.down` / ``up``), with the
case that applies selected rather than branched to (a division's operands are picked before
it: two quotients per ``div_meet_s``): no branch, so LLVM vectorises the loop that calls them.
tests/contractors/test_unicycle_simd.py compares them with the branching forms.
"""

from __future__ import annotations

from numba import njit

from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO
from ivslam_cli.interval.rounding import INF, down, up

E = EMPTY_LO
F = EMPTY_HI


@njit(cache=True, inline="always", error_model="numpy")
def _prod(a, c):
    return 0.0 if (a == 0.0) | (c == 0.0) else a * c


@njit(cache=True, inline="always", error_model="numpy")
def mul_s(al, ah, bl, bh):
    """:func:`~ivslam_cli.interval.arith.mul` of non-empty intervals as selects."""
    p1, p2, p3, p4 = _prod(al, bl), _prod(al, bh), _prod(ah, bl), _prod(ah, bh)
    return down(min(min(p1, p2), min(p3, p4))), up(max(max(p1, p2), max(p3, p4)))


@njit(cache=True, inline="always", error_model="numpy")
def div_meet_s(tl, th, al, ah, bl, bh):
    """:func:`~ivslam_cli.interval.arith.div_meet` (``[t] ∩ [a] / [b]``, both pieces of the
    extended division) of non-empty intervals as selects, from two quotients: the case of
    :func:`~ivslam_cli.interval.arith.div2` that applies picks their operands, and each is
    the quotient that case rounds (a bound of ``[a] / [b]`` for ``0`` not in ``[b]`` is the
    quotient of the corner the signs give, which is the least or greatest of the four
    quotients ``_div_nozero`` compares, the division being monotone; where a corner is
    ``inf / inf`` its NaN is ignored there, and the next corner stands in)."""
    apos = al >= 0.0
    bpos = bl > 0.0
    nz = bpos | (bh < 0.0)
    zb = (bl == 0.0) & (bh == 0.0)
    za = (al == 0.0) & (ah == 0.0)
    sa = (al < 0.0) & (0.0 < ah)
    lb = bl == 0.0  # [0, bh]
    hb = bh == 0.0  # [bl, 0]
    # 0 not in [b]: the lower bound at a = al (b > 0) or ah (b < 0), the upper one at the other
    # end; a nonnegative numerator over the end of [b] farthest from 0, a negative one over
    # the nearest (b > 0), the other way round for b < 0
    n1 = al if bpos else ah
    n2 = ah if bpos else al
    d1 = bh if n1 >= 0.0 else bl
    d2 = bl if n2 >= 0.0 else bh
    # inf / inf (an infinite numerator over an infinite end of [b]): NaN, ignored; the other
    # end of [a] over the same end of [b] gives the bound (0, or NaN again if that end is
    # infinite too, as every corner then is)
    n1 = (ah if bpos else al) if (abs(n1) == INF) & (abs(d1) == INF) else n1
    n2 = (al if bpos else ah) if (abs(n2) == INF) & (abs(d2) == INF) else n2
    # 0 in [b]: the numerator a_lo for a >= 0, a_hi otherwise; [0, bh] and [bl, 0] one
    # quotient, bl < 0 < bh two (t1h over bl for a >= 0, t2l over bh; the other way for a < 0)
    na = al if apos else ah
    n1 = n1 if nz else na
    n2 = n2 if nz else na
    d1 = d1 if nz else (bh if lb else (bl if hb else (bl if apos else bh)))
    d2 = d2 if nz else (bh if apos else bl)
    q1 = n1 / d1
    q2 = n2 / d2
    lo = down(INF if q1 != q1 else q1)
    hi = up(-INF if q2 != q2 else q2)
    l1, h1, l2, h2 = lo, hi, E, F
    # [b] = [0, bh]: a >= 0 -> [a_lo / bh, inf], else [-inf, a_hi / bh]
    c1l = down(q1) if apos else -INF
    c1h = INF if apos else up(q1)
    # [b] = [bl, 0]: a >= 0 -> [-inf, a_lo / bl], else [a_hi / bl, inf]
    c2l = -INF if apos else down(q1)
    c2h = up(q1) if apos else INF
    # bl < 0 < bh: two pieces
    t1h = up(q1)
    t2l = down(q2)
    l1 = l1 if nz else (0.0 if za else (-INF if sa else (c1l if lb else (c2l if hb else -INF))))
    h1 = h1 if nz else (0.0 if za else (INF if sa else (c1h if lb else (c2h if hb else t1h))))
    two = (not nz) & (not za) & (not sa) & (not lb) & (not hb)
    l2 = t2l if two else E
    h2 = INF if two else F
    l1 = E if zb else l1
    h1 = F if zb else h1
    # inter with [t] of each piece, hull (the empty set is neutral)
    p1l, p1h = (tl if tl > l1 else l1), (th if th < h1 else h1)
    p2l, p2h = (tl if tl > l2 else l2), (th if th < h2 else h2)
    e1 = not (p1l <= p1h)
    e2 = not (p2l <= p2h)
    rl = (E if e2 else p2l) if e1 else (p1l if e2 else (p1l if p1l < p2l else p2l))
    rh = (F if e2 else p2h) if e1 else (p1h if e2 else (p1h if p1h > p2h else p2h))
    return rl, rh


@njit(cache=True, inline="always", error_model="numpy")
def bwd_mul_s(zl, zh, xl, xh, yl, yh):
    """:func:`~ivslam_cli.interval.arith.bwd_mul` (contract ``x, y`` under ``z = x y``) of
    non-empty ``x, y`` as selects; the result is empty (``x`` and ``y``) where it empties."""
    z0 = (zl <= 0.0) & (0.0 <= zh)
    nxl, nxh = div_meet_s(xl, xh, zl, zh, yl, yh)
    keep_x = z0 & (yl <= 0.0) & (0.0 <= yh)
    xl, xh = (xl if keep_x else nxl), (xh if keep_x else nxh)
    nyl, nyh = div_meet_s(yl, yh, zl, zh, xl, xh)
    keep_y = z0 & (xl <= 0.0) & (0.0 <= xh)
    yl, yh = (yl if keep_y else nyl), (yh if keep_y else nyh)
    ok = (zl <= zh) & (xl <= xh) & (yl <= yh)
    return (xl if ok else E), (xh if ok else F), (yl if ok else E), (yh if ok else F)
