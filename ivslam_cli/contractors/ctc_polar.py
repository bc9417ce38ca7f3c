"""Polar contractor: ``dx = rho cos(theta)``, ``dy = rho sin(theta)``, ``rho >= 0``.

Equivalently ``rho^2 = dx^2 + dy^2`` and ``theta = atan2(dy, dx) mod 2 pi``. ``theta`` is any
real interval and keeps its branch (``[10, 11]`` is contracted near 10, not wrapped).

Guarantee: every ``(dx, dy, rho, theta)`` in the input box satisfying the constraint is in the
output box (outward rounding throughout, no loss across the ±pi cut or any multiple of 2 pi).

Tightness: each pass follows Codac's ``CtcPolar`` (B. Desrochers): an atan2 contractor split by
quadrant (``dy = dx tan(phi)`` per quadrant), the forward-backward ``rho^2 = dx^2 + dy^2``, then
``dx ∩= rho cos(theta)``, ``dy ∩= rho sin(theta)``. Codac applies that twice; we iterate until a
pass shrinks no width by more than ``RELATIVE_STOP``, so the result is never looser (up to a few
ulps of rounding) and often tighter. Unlike Codac we keep the origin: ``dx = dy = rho = 0``
satisfies the constraint for every ``theta``.

Speed (same bounds, bit for bit, as the plain loop of general passes; tests/test_polar.py checks
each piece against the general operation it replaces, and the whole against that loop):
theta's branch is found once per box, so each quadrant meets only three candidate copies of
theta (offsets ``2 k pi`` computed once); the first-quadrant step uses nonnegative interval
arithmetic; the extrema of sin/cos are found by comparisons in the principal branch; libm
values (tan, atan at the phi and v/u bounds, sin/cos at theta's bounds) are memoised between
passes by argument; and a pass whose catan2 step changes nothing, after a pass whose later steps
changed nothing, is known to change nothing and stops there.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval.angles import angle_meet
from ivslam_cli.interval.arith import (
    EMPTY_HI,
    EMPTY_LO,
    add,
    _has_point,
    bwd_add,
    bwd_mul,
    bwd_sqr,
    div,
    hull,
    inter,
    mul,
    neg,
    sqr,
    sub,
)
from ivslam_cli.interval.rounding import (
    HALF_PI_HI,
    HALF_PI_LO,
    INF,
    INV_TWO_PI_LO,
    PI_HI,
    PI_LO,
    TWO_PI_HI,
    TWO_PI_LO,
    down,
    down2,
    up,
    up2,
)

MAX_PASSES = 8
RELATIVE_STOP = 1e-3


# Memo of libm results between passes: a pass often meets a bound it has already seen (the
# fixpoint's last pass sees them all), and a libm call costs more than the rest of its step.
# ``memo`` = (phi_lo, tan lower bound, phi_hi, tan upper bound, q_lo, atan lower bound, q_hi,
# atan upper bound); each value is a function of its key alone, so reusing it is exact.
NO_MEMO = (math.nan,) * 8


@njit(cache=True)
def _tan_lo(pl):
    if pl >= HALF_PI_LO:
        return down2(math.tan(HALF_PI_LO))
    if pl <= 0.0:  # tan(0) = 0: the libm call below would give max(0, down2(0)) = 0
        return 0.0
    return max(0.0, down2(math.tan(pl)))


@njit(cache=True)
def _tan_hi(ph):
    if ph >= HALF_PI_LO:
        return INF
    return up2(math.tan(ph))


@njit(cache=True)
def _atan_lo(ql):
    if ql == 0.0:  # atan(±0) = ±0, exactly: the same bound without the libm call
        return down2(0.0)
    return -HALF_PI_HI if ql == -INF else max(-HALF_PI_HI, down2(math.atan(ql)))


@njit(cache=True)
def _atan_hi(qh):
    if qh == 0.0:
        return up2(0.0)
    return HALF_PI_HI if qh == INF else min(HALF_PI_HI, up2(math.atan(qh)))


@njit(cache=True)
def _tan_quadrant(pl, ph):
    """Enclosure of ``tan`` over ``[pl, ph] ⊂ [0, pi/2]`` (``+inf`` reached at pi/2)."""
    return _tan_lo(pl), _tan_hi(ph)


# Nonnegative interval arithmetic: the operations of :mod:`arith` (same float operations, same
# outward rounding, hence the same bounds) for intervals in [0, inf] with a finite lower bound,
# where the sign cases and NaN guards of the general ones cannot occur.
@njit(cache=True, inline="always")
def _div_nonneg(al, ah, bl, bh):
    """``div(a, b)`` for ``0 <= al < inf``, ``0 <= bl < inf``."""
    if bh == 0.0:  # b = {0}
        return EMPTY_LO, EMPTY_HI
    if bl > 0.0:
        return down(al / bh), up(ah / bl)
    if ah == 0.0:  # a = {0}, 0 in b
        return 0.0, 0.0
    return down(al / bh), INF


@njit(cache=True, inline="always")
def _mul_nonneg(al, ah, bl, bh):
    """``mul(a, b)`` for ``0 <= al``, ``0 <= bl`` (``0 * inf = 0``)."""
    lo = 0.0 if (al == 0.0 or bl == 0.0) else al * bl
    hi = 0.0 if (ah == 0.0 or bh == 0.0) else ah * bh
    return down(lo), up(hi)


@njit(cache=True, inline="always")
def _bwd_mul_nonneg(zl, zh, xl, xh, yl, yh):
    """``bwd_mul(z, x, y)`` (contract ``z = x y``) for nonnegative ``x, y, z``, finite lower bounds."""
    if not (zl <= zh):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    if not (zl <= 0.0 and yl <= 0.0):
        xl, xh = inter(xl, xh, *_div_nonneg(zl, zh, yl, yh))
    if not (zl <= 0.0 and xl <= 0.0) and xl <= xh:
        yl, yh = inter(yl, yh, *_div_nonneg(zl, zh, xl, xh))
    if not (xl <= xh) or not (yl <= yh):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    return xl, xh, yl, yh


@njit(cache=True, inline="always")
def _atan2_first_quadrant(ul, uh, vl, vh, pl, ph, m=NO_MEMO):
    """Contract ``v = u tan(phi)``, ``phi = atan(v / u)`` for ``u, v >= 0``, ``phi ⊂ [0, pi/2]``.

    ``m`` is the libm memo (see ``NO_MEMO``); returns the six bounds and the updated memo.
    """
    E = EMPTY_LO
    F = EMPTY_HI
    if not (ul <= uh) or not (vl <= vh) or not (pl <= ph):
        return E, F, E, F, E, F, m
    if uh == 0.0 and vh == 0.0:  # the origin: every angle is a solution
        return ul, uh, vl, vh, pl, ph, m
    m0, m1, m2, m3, m4, m5, m6, m7 = m
    if pl != m0:
        m0, m1 = pl, _tan_lo(pl)
    if ph != m2:
        m2, m3 = ph, _tan_hi(ph)
    m = (m0, m1, m2, m3, m4, m5, m6, m7)
    if ul < INF and vl < INF:  # the usual case, in nonnegative arithmetic
        ul, uh, tl, th = _bwd_mul_nonneg(vl, vh, ul, uh, m1, m3)
        if not (ul <= uh):
            return E, F, E, F, E, F, m
        vl, vh = inter(vl, vh, *_mul_nonneg(ul, uh, tl, th))
    else:
        ul, uh, tl, th = bwd_mul(vl, vh, ul, uh, m1, m3)
        if not (ul <= uh):
            return E, F, E, F, E, F, m
        vl, vh = inter(vl, vh, *mul(ul, uh, tl, th))
    if not (vl <= vh):
        return E, F, E, F, E, F, m
    if not (ul == 0.0 and vl == 0.0):  # the box misses the origin: phi = atan(v / u)
        ql, qh = _div_nonneg(vl, vh, ul, uh) if vl < INF else div(vl, vh, ul, uh)
        if ql <= qh:
            if ql != m4:
                m4, m5 = ql, _atan_lo(ql)
            if qh != m6:
                m6, m7 = qh, _atan_hi(qh)
            m = (m0, m1, m2, m3, m4, m5, m6, m7)
            al, ah = m5, m7
        else:
            al, ah = EMPTY_LO, EMPTY_HI
        if uh == 0.0:  # u = 0, v > 0: phi = pi/2 exactly
            al, ah = HALF_PI_LO, HALF_PI_HI
        pl, ph = inter(pl, ph, al, ah)
        if not (pl <= ph):
            return E, F, E, F, E, F, m
    return ul, uh, vl, vh, pl, ph, m


@njit(cache=True, inline="always")
def _two_pi_times(k):
    """``mul(k, k, TWO_PI_LO, TWO_PI_HI)`` (the same two products, rounded the same way)."""
    if k >= 0.0:
        return down(k * TWO_PI_LO), up(k * TWO_PI_HI)
    return down(k * TWO_PI_HI), up(k * TWO_PI_LO)


@njit(cache=True, inline="always")
def _offsets(k0):
    """``2 k pi`` enclosed as :func:`angles.shift` does, for ``k = k0 - 1, k0, k0 + 1``."""
    al, ah = _two_pi_times(k0 - 1.0)
    bl, bh = _two_pi_times(k0)
    cl, ch = _two_pi_times(k0 + 1.0)
    return (k0, al, ah, bl, bh, cl, ch)


# ``_offsets(0.0)``, evaluated by Python instead of by loading a kernel at import: ``down`` and
# ``up`` are plain float operations, so their Python functions give the kernels' doubles (checked
# by tests/contractors/test_polar.py).
OFFSETS_0 = (0.0, down.py_func(-TWO_PI_HI), up.py_func(-TWO_PI_LO), down.py_func(0.0), up.py_func(0.0),
             down.py_func(TWO_PI_LO), up.py_func(TWO_PI_HI))


@njit(cache=True, inline="always")
def _shifted(al, ah, k, ol, oh):
    """``shift(al, ah, k)`` given ``[ol, oh] = mul(k, k, 2 pi)``."""
    if k == 0.0:
        return al, ah
    return add(al, ah, ol, oh)


@njit(cache=True, inline="always")
def _meet_near(tl, th, al, ah, o):
    """``angle_meet(tl, th, al, ah)`` when only the copies ``[a] + 2 k pi``, ``k = k0 - 1, k0,
    k0 + 1`` (``o = _offsets(k0)``), can meet ``[t]``: the same pieces and roundings, without
    the search for k."""
    if not (tl <= th) or not (al <= ah):
        return EMPTY_LO, EMPTY_HI
    if ah - al >= TWO_PI_LO or tl == -INF or th == INF:
        return tl, th
    k0 = o[0]
    if up(up(th - tl) + up(ah - al)) < TWO_PI_LO:  # at most one copy meets [t]: try k0's
        pl, ph = inter(tl, th, *_shifted(al, ah, k0, o[3], o[4]))
        if pl <= ph:
            return pl, ph
    p1l, p1h = inter(tl, th, *_shifted(al, ah, k0 - 1.0, o[1], o[2]))
    p2l, p2h = inter(tl, th, *_shifted(al, ah, k0, o[3], o[4]))
    p3l, p3h = inter(tl, th, *_shifted(al, ah, k0 + 1.0, o[5], o[6]))
    if p1l <= p1h:
        lo = p1l
    elif p2l <= p2h:
        lo = p2l
    elif p3l <= p3h:
        lo = p3l
    else:
        return EMPTY_LO, EMPTY_HI
    if p3l <= p3h:
        hi = p3h
    elif p2l <= p2h:
        hi = p2h
    else:
        hi = p1h
    return lo, hi


@njit(cache=True, inline="always")
def _meet(tl, th, al, ah, near, o):
    if near:
        return _meet_near(tl, th, al, ah, o)
    return angle_meet(tl, th, al, ah)


@njit(cache=True, inline="always")
def catan2(xl, xh, yl, yh, tl, th, near=False, o_in=OFFSETS_0, o_out=OFFSETS_0, m=NO_MEMO):
    """Contract ``(x, y, theta)`` under ``theta = atan2(y, x) mod 2 pi`` (quadrant by quadrant).

    ``near`` asserts ``[tl, th] - 2 pi turns ⊂ (-6, 6)`` for an integer ``turns``, so only three
    copies of theta can meet each quadrant; then ``o_in = _offsets(-turns)`` and ``o_out =
    _offsets(turns)``. The result is the same, found faster. ``m`` is the libm memo (``NO_MEMO``);
    returns the six bounds and the updated memo.
    """
    rxl = EMPTY_LO
    rxh = EMPTY_HI
    ryl = EMPTY_LO
    ryh = EMPTY_HI
    rtl = EMPTY_LO
    rth = EMPTY_HI
    for q in range(4):
        # (x sign, y sign): q0 (+,+) theta in [0, pi/2]; q1 (+,-) [-pi/2, 0];
        # q2 (-,-) [-pi, -pi/2]; q3 (-,+) [pi/2, pi]
        if q == 0 or q == 1:
            ul, uh = inter(xl, xh, 0.0, INF)
        else:
            ul, uh = neg(*inter(xl, xh, -INF, 0.0))
        if q == 0 or q == 3:
            vl, vh = inter(yl, yh, 0.0, INF)
        else:
            vl, vh = neg(*inter(yl, yh, -INF, 0.0))
        if not (ul <= uh) or not (vl <= vh):
            continue
        # phi in [0, pi/2] is the angle of (u, v); theta = s(phi)
        if q == 0:
            ql, qh = _meet(0.0, HALF_PI_HI, tl, th, near, o_in)
            pl, ph = ql, qh
        elif q == 1:
            ql, qh = _meet(-HALF_PI_HI, 0.0, tl, th, near, o_in)
            pl, ph = neg(ql, qh)
        elif q == 2:
            ql, qh = _meet(-PI_HI, -HALF_PI_LO, tl, th, near, o_in)
            pl, ph = add(ql, qh, PI_LO, PI_HI)
        else:
            ql, qh = _meet(HALF_PI_LO, PI_HI, tl, th, near, o_in)
            pl, ph = sub(PI_LO, PI_HI, ql, qh)
        pl, ph = inter(pl, ph, 0.0, HALF_PI_HI)
        if not (pl <= ph):
            continue
        ul, uh, vl, vh, pl, ph, m = _atan2_first_quadrant(ul, uh, vl, vh, pl, ph, m)
        if not (pl <= ph):
            continue
        if q == 0:
            sl, sh = pl, ph
        elif q == 1:
            sl, sh = neg(pl, ph)
        elif q == 2:
            sl, sh = sub(pl, ph, PI_LO, PI_HI)
        else:
            sl, sh = sub(PI_LO, PI_HI, pl, ph)
        sl, sh = _meet(tl, th, sl, sh, near, o_out)
        if not (sl <= sh):
            continue
        if q >= 2:
            ul, uh = neg(ul, uh)
        if q == 1 or q == 2:
            vl, vh = neg(vl, vh)
        rxl, rxh = hull(rxl, rxh, ul, uh)
        ryl, ryh = hull(ryl, ryh, vl, vh)
        rtl, rth = hull(rtl, rth, sl, sh)
    return rxl, rxh, ryl, ryh, rtl, rth, m


@njit(cache=True)
def _shrink(ol, oh, nl, nh):
    """Relative width reduction of one variable in a pass."""
    w0 = oh - ol
    w1 = nh - nl
    if w0 == INF:
        return 1.0 if w1 < INF else 0.0
    if not (w0 > 0.0):
        return 0.0
    return (w0 - w1) / w0


# 3 pi / 2, enclosed (1.5 * math.pi is within 2 ulps of it; tests check against mpmath)
THREE_HALF_PI_LO = float(np.nextafter(np.nextafter(1.5 * math.pi, -INF), -INF))
THREE_HALF_PI_HI = float(np.nextafter(np.nextafter(1.5 * math.pi, INF), INF))


@njit(cache=True, inline="always")
def _meets(pl, ph, cl, ch):
    return pl <= ch and cl <= ph


@njit(cache=True, inline="always")
def _sin_cos(tl, th, w, pl=0.0, ph=-1.0):
    """``cos`` and ``sin`` of ``[tl, th]`` as :func:`arith.cos` / :func:`arith.sin`, with the libm
    values at each bound memoised in ``w = (tl, sin tl, cos tl, th, sin th, cos th)``.

    ``[pl, ph]`` (when not empty) is ``[tl, th] - 2 k pi`` for some integer k, enclosed, within
    ``(-6, 6)``: the extrema of sin and cos it may hold are then among ``-3pi/2 .. 3pi/2``, tested
    by comparisons instead of :func:`arith._has_point`'s division by 2 pi.
    """
    if not (tl <= th):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI, w
    if not (th - tl < 6.0) or tl == -INF or th == INF:  # >= 2pi - margin: whole range
        return -1.0, 1.0, -1.0, 1.0, w
    w0, s1, c1, w3, s2, c2 = w
    if tl != w0:
        w0, s1, c1 = tl, math.sin(tl), math.cos(tl)
    if th != w3:
        w3, s2, c2 = th, math.sin(th), math.cos(th)
    w = (w0, s1, c1, w3, s2, c2)
    sl = max(-1.0, down2(min(s1, s2)))
    sh = min(1.0, up2(max(s1, s2)))
    cl = max(-1.0, down2(min(c1, c2)))
    ch = min(1.0, up2(max(c1, c2)))
    if pl <= ph and -6.0 < pl and ph < 6.0:
        if _meets(pl, ph, HALF_PI_LO, HALF_PI_HI) or _meets(pl, ph, -THREE_HALF_PI_HI, -THREE_HALF_PI_LO):
            sh = 1.0
        if _meets(pl, ph, -HALF_PI_HI, -HALF_PI_LO) or _meets(pl, ph, THREE_HALF_PI_LO, THREE_HALF_PI_HI):
            sl = -1.0
        if _meets(pl, ph, 0.0, 0.0):
            ch = 1.0
        if _meets(pl, ph, PI_LO, PI_HI) or _meets(pl, ph, -PI_HI, -PI_LO):
            cl = -1.0
    else:
        if _has_point(tl, th, HALF_PI_LO, HALF_PI_HI):
            sh = 1.0
        if _has_point(tl, th, -HALF_PI_HI, -HALF_PI_LO):
            sl = -1.0
        if _has_point(tl, th, 0.0, 0.0):
            ch = 1.0
        if _has_point(tl, th, PI_LO, PI_HI):
            cl = -1.0
    return cl, ch, sl, sh, w


NO_TRIG = (math.nan,) * 6


@njit(cache=True, inline="always")
def polar_pass(xl, xh, yl, yh, rl, rh, tl, th, turns=0.0, o_in=OFFSETS_0, o_out=OFFSETS_0,
               m=NO_MEMO, w=NO_TRIG, settled=False, fast=True):
    """One forward-backward pass (the body of Codac's ``CtcPolar::_contract``).

    ``turns`` (an integer as float): ``theta - 2 pi turns`` is near ``[-pi, pi]``, ``o_in =
    _offsets(-turns)``, ``o_out = _offsets(turns)`` (default: turns = 0); ``m`` and
    ``w`` memoise libm values between passes (``NO_MEMO``, ``NO_TRIG`` for none). Returns the 8
    contracted bounds (all empty if there is no solution), the updated memos, and whether the
    steps after catan2 changed nothing.

    ``settled`` says the previous pass's steps after catan2 changed nothing (so the box is their
    output on the catan2 result it got): if catan2 now changes nothing either, they would get
    that same input again and the whole pass changes nothing, so they are skipped.
    ``fast=False`` takes the general paths (``angle_meet``, ``_has_point``): for tests.
    """
    E = EMPTY_LO
    F = EMPTY_HI
    x0l, x0h, y0l, y0h, t0l, t0h = xl, xh, yl, yh, tl, th
    pl, ph = _shifted(tl, th, -turns, o_in[3], o_in[4])  # theta - 2 pi turns, enclosed
    near = fast and -6.0 < pl and ph < 6.0
    xl, xh, yl, yh, ntl, nth, m = catan2(xl, xh, yl, yh, tl, th, near, o_in, o_out, m)
    if not (xl <= xh) or not (ntl <= nth):
        return E, F, E, F, E, F, E, F, m, w, False
    if settled and xl == x0l and xh == x0h and yl == y0l and yh == y0h and ntl == t0l and nth == t0h:
        return xl, xh, yl, yh, rl, rh, ntl, nth, m, w, True
    x1l, x1h, y1l, y1h, r1l, r1h = xl, xh, yl, yh, rl, rh
    a1l, a1h = sqr(xl, xh)
    a2l, a2h = sqr(yl, yh)
    a3l, a3h = add(a1l, a1h, a2l, a2h)
    a4l, a4h = sqr(rl, rh)
    a4l, a4h = inter(a4l, a4h, a3l, a3h)
    a3l, a3h = a4l, a4h
    rl, rh = bwd_sqr(a4l, a4h, rl, rh)
    a1l, a1h, a2l, a2h = bwd_add(a3l, a3h, a1l, a1h, a2l, a2h)
    xl, xh = bwd_sqr(a1l, a1h, xl, xh)
    yl, yh = bwd_sqr(a2l, a2h, yl, yh)
    pl, ph = _shifted(ntl, nth, -turns, o_in[3], o_in[4])
    if not fast:
        pl, ph = EMPTY_LO, EMPTY_HI
    cl, ch, sl, sh, w = _sin_cos(ntl, nth, w, pl, ph)
    xl, xh = inter(xl, xh, *mul(rl, rh, cl, ch))
    yl, yh = inter(yl, yh, *mul(rl, rh, sl, sh))
    if not (xl <= xh) or not (yl <= yh) or not (rl <= rh):
        return E, F, E, F, E, F, E, F, m, w, False
    settled = (xl == x1l and xh == x1h and yl == y1l and yh == y1h and rl == r1l and rh == r1h)
    return xl, xh, yl, yh, rl, rh, ntl, nth, m, w, settled


@njit(cache=True)
def polar_scalar(xl, xh, yl, yh, rl, rh, tl, th):
    """Contract one box ``(dx, dy, rho, theta)``; all eight bounds empty if no solution.

    Passes repeat while one shrinks some width by at least ``RELATIVE_STOP`` (at least the two
    passes Codac makes, unless the first changes nothing: the second would then be identical).
    """
    E = EMPTY_LO
    F = EMPTY_HI
    rl = max(rl, 0.0)
    if not (xl <= xh) or not (yl <= yh) or not (rl <= rh) or not (tl <= th):
        return E, F, E, F, E, F, E, F
    # turns: theta's branch (theta - 2 pi turns is near [-pi, pi]), where catan2 works
    turns = 0.0
    if th - tl < TWO_PI_LO and -1e15 < tl and th < 1e15:
        turns = float(round(0.5 * (tl + th) * INV_TWO_PI_LO))
    o_in = _offsets(-turns)
    o_out = _offsets(turns)
    m = NO_MEMO
    w = NO_TRIG
    settled = False
    for k in range(MAX_PASSES):
        r = polar_pass(xl, xh, yl, yh, rl, rh, tl, th, turns, o_in, o_out, m, w, settled)
        if not (r[0] <= r[1]):
            return E, F, E, F, E, F, E, F
        unchanged = (
            r[0] == xl and r[1] == xh and r[2] == yl and r[3] == yh
            and r[4] == rl and r[5] == rh and r[6] == tl and r[7] == th
        )
        if unchanged:
            break
        stop = k >= 1 and max(
            max(_shrink(xl, xh, r[0], r[1]), _shrink(yl, yh, r[2], r[3])),
            max(_shrink(rl, rh, r[4], r[5]), _shrink(tl, th, r[6], r[7])),
        ) < RELATIVE_STOP
        xl, xh, yl, yh, rl, rh, tl, th = r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7]
        m = r[8]
        w = r[9]
        settled = r[10]
        if stop:
            break
    return xl, xh, yl, yh, rl, rh, tl, th


@njit(cache=True)
def polar_kernel(dx, dy, rho, theta):
    """In place over ``(N, 2)`` arrays; returns the mask of rows that stayed non-empty."""
    n = dx.shape[0]
    ok = np.empty(n, dtype=np.bool_)
    for i in range(n):
        r = polar_scalar(
            dx[i, 0], dx[i, 1], dy[i, 0], dy[i, 1], rho[i, 0], rho[i, 1], theta[i, 0], theta[i, 1]
        )
        dx[i, 0], dx[i, 1], dy[i, 0], dy[i, 1] = r[0], r[1], r[2], r[3]
        rho[i, 0], rho[i, 1], theta[i, 0], theta[i, 1] = r[4], r[5], r[6], r[7]
        ok[i] = r[0] <= r[1]
    return ok
