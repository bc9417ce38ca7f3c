"""Polar contractor over structure-of-arrays chunks: branch-free stages LLVM vectorises.

Same constraint and guarantee as :mod:`~ivslam_cli.contractors.ctc_polar` (``dx = rho
cos(theta)``, ``dy = rho sin(theta)``, ``rho >= 0``, theta in its own branch): every solution in
the input box is in the output box. :func:`~ivslam_cli.contractors.ctc_polar.polar_scalar` stays
the reference; tests/test_polar_simd.py compares the two.

The fast path takes a box whose ``(dx, dy)`` lies in one open quadrant, with finite bounds and a
theta narrower than ``3 pi / 2`` that meets exactly one copy of that quadrant's arc (the usual
case in a SLAM sweep); every other box goes to ``polar_scalar`` (origin, axes, unbounded or
very wide boxes). In the quadrant, with ``u = |dx|``, ``v = |dy|`` and ``phi in [0, pi/2]``
given by ``theta = s phi + C`` (``s = ±1``, ``C`` a multiple of ``pi / 2`` fixed per box and
enclosed once), the constraint is ``u = rho cos(phi)``, ``v = rho sin(phi)``: every function is
monotone on the quadrant and every interval nonnegative, so each step is a fixed sequence of
min/max, products, quotients and square roots, rounded outward with
:func:`~ivslam_cli.interval.rounding.down` / ``up`` (``down2`` / ``up2`` for libm results), with
no sign cases and no branches: a chunk of boxes goes through each step as one loop LLVM turns
into SIMD code. The libm calls (atan, sin, cos; tan is bounded by ``sin / cos``) are each in a
loop of their own, memoised per lane by argument.

A pass (the body of Codac's ``CtcPolar``, in the quadrant): ``v = u tan(phi)`` backward and
forward, ``phi ∩= atan(v / u)``, ``rho^2 = u^2 + v^2`` forward-backward, ``u ∩= rho cos(phi)``,
``v ∩= rho sin(phi)``. Passes repeat over the whole chunk while some lane shrinks a width by at
least ``RELATIVE_STOP`` (at least two, at most ``MAX_PASSES``): a lane never gets fewer passes
than the scalar kernel would give it, and an extra pass is only a further sound contraction.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_polar import (
    MAX_PASSES,
    RELATIVE_STOP,
    _atan_hi,
    _atan_lo,
    _tan_hi,
    _tan_lo,
    _two_pi_times,
    polar_scalar,
)
from ivslam_cli.contractors.simd_polar_lanes import BIG, _mn, _mx
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO
from ivslam_cli.interval.rounding import (
    HALF_PI_HI,
    INV_TWO_PI_LO,
    PI_HI,
    PI_LO,
    down,
    up,
)

CHUNK = 256
# quadrant q: (sign of x, sign of y) = q0 (+,+), q1 (+,-), q2 (-,-), q3 (-,+);
# theta = s phi + 2 k pi + c with (s, c) = q0 (1, 0), q1 (-1, 0), q2 (1, -pi), q3 (-1, pi)


@njit(cache=True, inline="always", error_model="numpy")
def _offset(q, k):
    """``C = 2 k pi + c_q`` enclosed (``c_q`` in {0, -pi, pi})."""
    ol, oh = _two_pi_times(k)
    if q == 2:
        return down(ol - PI_HI), up(oh - PI_LO)
    if q == 3:
        return down(ol + PI_LO), up(oh + PI_HI)
    return ol, oh


@njit(cache=True, inline="always", error_model="numpy")
def _to_phi(s, cl, ch, tl, th):
    """``phi = s (theta - C)`` enclosed, ∩ ``[0, HALF_PI_HI]``."""
    if s > 0.0:
        pl, ph = down(tl - ch), up(th - cl)
    else:
        pl, ph = down(cl - th), up(ch - tl)
    return _mx(pl, 0.0), _mn(ph, HALF_PI_HI)


@njit(cache=True, error_model="numpy")
def _setup(xl, xh, yl, yh, rl, rh, tl, th):
    """Is the box on the fast path? Returns ``(ok, q, s, cl, ch, ul, uh, vl, vh, pl, ph)``."""
    z = 0.0
    bad = (False, 0, z, z, z, z, z, z, z, z, z)
    if not (-1e300 < xl <= xh < 1e300 and -1e300 < yl <= yh < 1e300 and 0.0 <= rl <= rh < 1e300
            and -1e6 < tl <= th < 1e6 and th - tl < 4.7):
        return bad
    if xl > 0.0:
        ul, uh = xl, xh
        xs = 0
    elif xh < 0.0:
        ul, uh = -xh, -xl
        xs = 1
    else:
        return bad
    if yl > 0.0:
        vl, vh = yl, yh
        ys = 0
    elif yh < 0.0:
        vl, vh = -yh, -yl
        ys = 1
    else:
        return bad
    q = (0 if ys == 0 else 1) if xs == 0 else (2 if ys == 1 else 3)
    s = 1.0 if (q == 0 or q == 2) else -1.0
    c0 = 0.0 if q < 2 else (-math.pi if q == 2 else math.pi)
    # the copy of the quadrant's arc theta meets: k near (mid theta - c0) / 2 pi, and neighbours
    k0 = float(round((0.5 * (tl + th) - c0 - s * 0.25 * math.pi) * INV_TWO_PI_LO))
    found = 0
    cl = ch = pl = ph = 0.0
    for dk in range(-1, 2):
        ol, oh = _offset(q, k0 + dk)
        al, ah = _to_phi(s, ol, oh, tl, th)
        if al <= ah:
            found += 1
            cl, ch, pl, ph = ol, oh, al, ah
    if found != 1:
        return bad
    return (True, q, s, cl, ch, ul, uh, vl, vh, pl, ph)


# Lane state of a chunk: one flat float64 buffer, row r of lane i at L[r * CHUNK + i], so every
# access in the pass loop is one base pointer plus a compile-time offset (LLVM can then prove
# the rows independent and vectorise without runtime alias checks).
UL, UH, VL, VH, RL, RH, TL, TH = 0, 1, 2, 3, 4, 5, 6, 7
OLD = 8  # rows 8..15: the same before the pass
OK = 16  # 1.0 while the lane is non-empty
ROWS = 17


@njit(cache=True, error_model="numpy")
def _passes(n, L):
    """One pass over lanes ``0..n-1``, straight-line code (a SIMD loop): ``v = u t`` backward and
    forward; ``rho^2 = u^2 + v^2`` forward-backward; ``u ∩= rho cos(phi)``, ``v ∩= rho sin(phi)``
    with ``cos = 1 / sqrt(1 + t^2)`` (decreasing in t) and ``sin = t / sqrt(1 + t^2)``
    (increasing) on ``t = tan(phi) >= 0``. Rows ``OLD..`` receive the bounds before the pass."""
    C = CHUNK
    for i in range(n):
        a, b, c, d = L[UL * C + i], L[UH * C + i], L[VL * C + i], L[VH * C + i]
        e, f, g, h = L[RL * C + i], L[RH * C + i], L[TL * C + i], L[TH * C + i]
        L[(OLD + UL) * C + i], L[(OLD + UH) * C + i] = a, b
        L[(OLD + VL) * C + i], L[(OLD + VH) * C + i] = c, d
        L[(OLD + RL) * C + i], L[(OLD + RH) * C + i] = e, f
        L[(OLD + TL) * C + i], L[(OLD + TH) * C + i] = g, h
        # v = u t (u, v > 0, t >= 0; t may be +inf above)
        a = _mx(a, down(c / h))
        b = _mn(b, up(d / g))
        g = _mx(g, down(c / b))
        h = _mn(h, up(d / a))
        c = _mx(c, down(a * g))
        d = _mn(d, up(b * h))
        # rho^2 = u^2 + v^2
        u2l, u2h = down(a * a), up(b * b)
        v2l, v2h = down(c * c), up(d * d)
        sl = _mx(_mx(down(u2l + v2l), down(e * e)), 0.0)
        sh = _mn(up(u2h + v2h), up(f * f))
        e = _mx(e, down(math.sqrt(sl)))
        f = _mn(f, up(math.sqrt(_mx(sh, 0.0))))
        u2l = _mx(u2l, down(sl - v2h))
        u2h = _mn(u2h, up(sh - v2l))
        v2l = _mx(v2l, down(sl - u2h))
        v2h = _mn(v2h, up(sh - u2l))
        a = _mx(a, down(math.sqrt(_mx(u2l, 0.0))))
        b = _mn(b, up(math.sqrt(_mx(u2h, 0.0))))
        c = _mx(c, down(math.sqrt(_mx(v2l, 0.0))))
        d = _mn(d, up(math.sqrt(_mx(v2h, 0.0))))
        # cos and sin of phi from t (bounds of t above BIG: cos >= 0, sin <= 1)
        big = h > BIG
        hb = _mn(h, BIG)
        gb = _mn(g, BIG)  # a lower bound of t lowered: still a lower bound
        cos_l = _mx(0.0, down(1.0 / up(math.sqrt(up(1.0 + up(hb * hb))))))
        sin_h = _mn(1.0, up(hb / down(math.sqrt(down(1.0 + down(hb * hb))))))
        cos_l = 0.0 if big else cos_l
        sin_h = 1.0 if big else sin_h
        cos_h = _mn(1.0, up(1.0 / down(math.sqrt(down(1.0 + down(gb * gb))))))
        sin_l = _mx(0.0, down(gb / up(math.sqrt(up(1.0 + up(gb * gb))))))
        a = _mx(a, down(e * cos_l))
        b = _mn(b, up(f * cos_h))
        c = _mx(c, down(e * sin_l))
        d = _mn(d, up(f * sin_h))
        L[UL * C + i], L[UH * C + i], L[VL * C + i], L[VH * C + i] = a, b, c, d
        L[RL * C + i], L[RH * C + i], L[TL * C + i], L[TH * C + i] = e, f, g, h
        good = ((a <= b) & (c <= d) & (e <= f) & (g <= h) & (sl <= sh) & (u2l <= u2h)
                & (v2l <= v2h))
        L[OK * C + i] = L[OK * C + i] if good else 0.0


@njit(cache=True, error_model="numpy")
def _shrink(ol, oh, nl, nh):
    w0 = oh - ol
    return (w0 - (nh - nl)) / w0 if w0 > 0.0 else 0.0  # NaN (inf widths) is ignored by _mx


@njit(cache=True, error_model="numpy")
def _write(i, ok, q, s, cl, ch, ul, uh, vl, vh, rl, rh, pl, ph, tl, th, dx, dy, rho, theta,
           ok_out):
    """Row ``i`` of the output from one lane (back from the quadrant frame; phi ∩= atan(t))."""
    pl = _mx(pl, _atan_lo(tl))
    ph = _mn(ph, _atan_hi(th))
    if not ok or not (pl <= ph):
        dx[i, 0], dx[i, 1], dy[i, 0], dy[i, 1] = EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
        rho[i, 0], rho[i, 1], theta[i, 0], theta[i, 1] = EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
        ok_out[i] = False
        return
    if q == 0 or q == 1:
        dx[i, 0], dx[i, 1] = ul, uh
    else:
        dx[i, 0], dx[i, 1] = -uh, -ul
    if q == 0 or q == 3:
        dy[i, 0], dy[i, 1] = vl, vh
    else:
        dy[i, 0], dy[i, 1] = -vh, -vl
    rho[i, 0], rho[i, 1] = rl, rh
    if s > 0.0:
        a, b = down(pl + cl), up(ph + ch)
    else:
        a, b = down(cl - ph), up(ch - pl)
    theta[i, 0] = _mx(theta[i, 0], a)
    theta[i, 1] = _mn(theta[i, 1], b)
    ok_out[i] = True


@njit(cache=True, error_model="numpy")
def _flush(n, idx, q, s, cl, ch, pl, ph, L, dx, dy, rho, theta, ok_out):
    """Contract the ``n`` lanes of the chunk (state in ``L``) and write them to the output rows
    ``idx``.

    After each pass from the second on, a lane whose pass shrank no width by ``RELATIVE_STOP``
    (or that was emptied) is written out and the remaining lanes are packed to the front, so
    the next pass runs on the lanes still contracting only (the scalar kernel's stopping rule,
    lane by lane)."""
    C = CHUNK
    for i in range(n):
        L[OK * C + i] = 1.0
        L[TL * C + i] = _tan_lo(pl[i])
        L[TH * C + i] = _tan_hi(ph[i])
    for p in range(MAX_PASSES):
        _passes(n, L)
        if p == 0:
            continue
        m = 0
        for i in range(n):
            sh = 0.0
            for r in range(0, 8, 2):
                sh = _mx(sh, _shrink(L[(OLD + r) * C + i], L[(OLD + r + 1) * C + i],
                                     L[r * C + i], L[(r + 1) * C + i]))
            ok = L[OK * C + i] > 0.5
            if not ok or not (sh >= RELATIVE_STOP) or p + 1 == MAX_PASSES:
                _write(idx[i], ok, q[i], s[i], cl[i], ch[i], L[UL * C + i], L[UH * C + i],
                       L[VL * C + i], L[VH * C + i], L[RL * C + i], L[RH * C + i], pl[i], ph[i],
                       L[TL * C + i], L[TH * C + i], dx, dy, rho, theta, ok_out)
                continue
            if m != i:  # pack lane i into slot m
                idx[m], q[m], s[m], cl[m], ch[m], pl[m], ph[m] = idx[i], q[i], s[i], cl[i], ch[i], pl[i], ph[i]
                for r in range(ROWS):
                    L[r * C + m] = L[r * C + i]
            m += 1
        n = m
        if n == 0:
            break


@njit(cache=True, error_model="numpy")
def _kernel(dx, dy, rho, theta):
    n = dx.shape[0]
    C = CHUNK
    ok_out = np.empty(n, np.bool_)
    idx = np.empty(C, np.int64)
    q = np.empty(C, np.int64)
    s = np.empty(C)
    cl = np.empty(C)
    ch = np.empty(C)
    pl = np.empty(C)
    ph = np.empty(C)
    L = np.empty(ROWS * C)
    m = 0
    for i in range(n):
        xl, xh, yl, yh = dx[i, 0], dx[i, 1], dy[i, 0], dy[i, 1]
        r0, r1, t0, t1 = max(rho[i, 0], 0.0), rho[i, 1], theta[i, 0], theta[i, 1]
        f = _setup(xl, xh, yl, yh, r0, r1, t0, t1)
        if not f[0]:
            r = polar_scalar(xl, xh, yl, yh, rho[i, 0], r1, t0, t1)
            dx[i, 0], dx[i, 1], dy[i, 0], dy[i, 1] = r[0], r[1], r[2], r[3]
            rho[i, 0], rho[i, 1], theta[i, 0], theta[i, 1] = r[4], r[5], r[6], r[7]
            ok_out[i] = r[0] <= r[1]
            continue
        idx[m] = i
        q[m], s[m], cl[m], ch[m] = f[1], f[2], f[3], f[4]
        L[UL * C + m], L[UH * C + m], L[VL * C + m], L[VH * C + m] = f[5], f[6], f[7], f[8]
        L[RL * C + m], L[RH * C + m] = r0, r1
        pl[m], ph[m] = f[9], f[10]
        m += 1
        if m == C:
            _flush(m, idx, q, s, cl, ch, pl, ph, L, dx, dy, rho, theta, ok_out)
            m = 0
    if m > 0:
        _flush(m, idx, q, s, cl, ch, pl, ph, L, dx, dy, rho, theta, ok_out)
    return ok_out


def polar_simd_kernel(dx, dy, rho, theta):
    """In place over ``(N, 2)`` arrays; returns the mask of rows that stayed non-empty."""
    return _kernel(dx, dy, rho, theta)
