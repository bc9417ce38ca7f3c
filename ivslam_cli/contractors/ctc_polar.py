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
    atan,
    bwd_add,
    bwd_mul,
    bwd_sqr,
    cos,
    div,
    hull,
    inter,
    mul,
    neg,
    sin,
    sqr,
    sub,
)
from ivslam_cli.interval.rounding import HALF_PI_HI, HALF_PI_LO, INF, PI_HI, PI_LO, down2, up2

MAX_PASSES = 8
RELATIVE_STOP = 1e-3


@njit(cache=True)
def _tan_quadrant(pl, ph):
    """Enclosure of ``tan`` over ``[pl, ph] ⊂ [0, pi/2]`` (``+inf`` reached at pi/2)."""
    if pl >= HALF_PI_LO:
        lo = down2(math.tan(HALF_PI_LO))
    else:
        lo = max(0.0, down2(math.tan(max(pl, 0.0))))
    if ph >= HALF_PI_LO:
        hi = INF
    else:
        hi = up2(math.tan(ph))
    return lo, hi


@njit(cache=True)
def _atan2_first_quadrant(ul, uh, vl, vh, pl, ph):
    """Contract ``v = u tan(phi)``, ``phi = atan(v / u)`` for ``u, v >= 0``, ``phi ⊂ [0, pi/2]``."""
    if not (ul <= uh) or not (vl <= vh) or not (pl <= ph):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    if uh == 0.0 and vh == 0.0:  # the origin: every angle is a solution
        return ul, uh, vl, vh, pl, ph
    tl, th = _tan_quadrant(pl, ph)
    ul, uh, tl, th = bwd_mul(vl, vh, ul, uh, tl, th)
    if not (ul <= uh):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    vl, vh = inter(vl, vh, *mul(ul, uh, tl, th))
    if not (vl <= vh):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    if not (ul == 0.0 and vl == 0.0):  # the box misses the origin: phi = atan(v / u)
        ql, qh = div(vl, vh, ul, uh)
        al, ah = atan(ql, qh)
        if uh == 0.0:  # u = 0, v > 0: phi = pi/2 exactly
            al, ah = HALF_PI_LO, HALF_PI_HI
        pl, ph = inter(pl, ph, al, ah)
        if not (pl <= ph):
            return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    return ul, uh, vl, vh, pl, ph


@njit(cache=True)
def catan2(xl, xh, yl, yh, tl, th):
    """Contract ``(x, y, theta)`` under ``theta = atan2(y, x) mod 2 pi`` (quadrant by quadrant)."""
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
            ql, qh = angle_meet(0.0, HALF_PI_HI, tl, th)
            pl, ph = ql, qh
        elif q == 1:
            ql, qh = angle_meet(-HALF_PI_HI, 0.0, tl, th)
            pl, ph = neg(ql, qh)
        elif q == 2:
            ql, qh = angle_meet(-PI_HI, -HALF_PI_LO, tl, th)
            pl, ph = add(ql, qh, PI_LO, PI_HI)
        else:
            ql, qh = angle_meet(HALF_PI_LO, PI_HI, tl, th)
            pl, ph = sub(PI_LO, PI_HI, ql, qh)
        pl, ph = inter(pl, ph, 0.0, HALF_PI_HI)
        if not (pl <= ph):
            continue
        ul, uh, vl, vh, pl, ph = _atan2_first_quadrant(ul, uh, vl, vh, pl, ph)
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
        sl, sh = angle_meet(tl, th, sl, sh)
        if not (sl <= sh):
            continue
        if q >= 2:
            ul, uh = neg(ul, uh)
        if q == 1 or q == 2:
            vl, vh = neg(vl, vh)
        rxl, rxh = hull(rxl, rxh, ul, uh)
        ryl, ryh = hull(ryl, ryh, vl, vh)
        rtl, rth = hull(rtl, rth, sl, sh)
    return rxl, rxh, ryl, ryh, rtl, rth


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


@njit(cache=True)
def polar_pass(xl, xh, yl, yh, rl, rh, tl, th, cl, ch, sl, sh):
    """One forward-backward pass (the body of Codac's ``CtcPolar::_contract``).

    ``[cl, ch]``, ``[sl, sh]`` are cos and sin of the incoming ``[tl, th]`` (pass NaN to have them
    computed); returns the 8 contracted bounds then cos and sin of the outgoing theta.
    """
    E = EMPTY_LO
    F = EMPTY_HI
    ntl, nth = tl, th
    xl, xh, yl, yh, ntl, nth = catan2(xl, xh, yl, yh, tl, th)
    if not (xl <= xh) or not (ntl <= nth):
        return E, F, E, F, E, F, E, F, E, F, E, F
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
    if ntl != tl or nth != th or not (cl <= ch):
        cl, ch = cos(ntl, nth)
        sl, sh = sin(ntl, nth)
    xl, xh = inter(xl, xh, *mul(rl, rh, cl, ch))
    yl, yh = inter(yl, yh, *mul(rl, rh, sl, sh))
    if not (xl <= xh) or not (yl <= yh) or not (rl <= rh):
        return E, F, E, F, E, F, E, F, E, F, E, F
    return xl, xh, yl, yh, rl, rh, ntl, nth, cl, ch, sl, sh


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
    cl = math.nan
    ch = math.nan
    sl = math.nan
    sh = math.nan
    for k in range(MAX_PASSES):
        r = polar_pass(xl, xh, yl, yh, rl, rh, tl, th, cl, ch, sl, sh)
        if not (r[0] <= r[1]):
            return E, F, E, F, E, F, E, F
        progress = max(
            max(_shrink(xl, xh, r[0], r[1]), _shrink(yl, yh, r[2], r[3])),
            max(_shrink(rl, rh, r[4], r[5]), _shrink(tl, th, r[6], r[7])),
        )
        unchanged = (
            r[0] == xl and r[1] == xh and r[2] == yl and r[3] == yh
            and r[4] == rl and r[5] == rh and r[6] == tl and r[7] == th
        )
        xl, xh, yl, yh, rl, rh, tl, th = r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7]
        cl, ch, sl, sh = r[8], r[9], r[10], r[11]
        if unchanged or (k >= 1 and progress < RELATIVE_STOP):
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
