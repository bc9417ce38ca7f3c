"""Unicycle motion step contractor (the kinematic model of the Guaranteed SLAM slides).

Constraint, over the twelve variables of one step ``k-1 -> k``::

    x1  = x0  + v dt cos(th0) + qx
    y1  = y0  + v dt sin(th0) + qy
    th1 = th0 + w dt + qth            (mod 2 pi: headings are angles)

with bounded noise intervals ``qx, qy, qth``. ``dt`` may be an interval. The heading equation
is read modulo 2 pi, which every real solution also satisfies, so wrapped and unwrapped heading
representations are both sound; each variable keeps its own branch.

Decomposition (one pass, iterated until no width shrinks by more than ``RELATIVE_STOP``):

- heading: ``u = w dt + qth`` and ``u = th1 - th0 (mod 2 pi)`` (periodic difference), then
  ``bwd_add`` / ``bwd_mul`` back onto ``w, dt, qth``;
- position: the displacement ``(dx, dy) = (x1 - x0 - qx, y1 - y0 - qy)`` and the signed
  length ``s = v dt`` satisfy ``(dx, dy) = s (cos th0, sin th0)``. For ``s >= 0`` that is the
  polar constraint on ``(dx, dy, s, th0)``; for ``s <= 0`` (reversing) it is the polar
  constraint on ``(dx, dy, -s, th0 + pi)``. When ``s`` straddles 0 both branches are contracted
  and their hull kept. Then back onto ``v, dt`` (``s = v dt``) and ``x0, x1, qx`` (``y``
  likewise) by linear differences.

Guarantee: every solution inside the input box is in the output box (outward rounding; the
polar contractor's guarantee across the ±pi cut carries over).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_difference import angle_difference_scalar, difference_scalar
from ivslam_cli.contractors.ctc_polar import polar_scalar
from ivslam_cli.interval.arith import (
    EMPTY_HI,
    EMPTY_LO,
    add,
    bwd_add,
    bwd_mul,
    hull,
    inter,
    mul,
    sub,
)
from ivslam_cli.interval.rounding import PI_HI, PI_LO

MAX_PASSES = 6
RELATIVE_STOP = 1e-3

E = EMPTY_LO
F = EMPTY_HI


@njit(cache=True)
def shrink(ol, oh, nl, nh):
    """Relative width reduction ``(w_old - w_new) / w_old`` of one variable (1 if inf -> finite)."""
    w0 = oh - ol
    w1 = nh - nl
    if w0 == np.inf:
        return 1.0 if w1 < np.inf else 0.0
    if not (w0 > 0.0):
        return 0.0
    return (w0 - w1) / w0


@njit(cache=True)
def signed_polar(xl, xh, yl, yh, sl, sh, tl, th):
    """Contract ``(x, y) = s (cos t, sin t)`` with ``s`` of any sign; eight bounds, or empty.

    ``s < 0`` is the polar constraint with length ``-s`` and angle ``t + pi``.
    """
    rxl, rxh, ryl, ryh, rsl, rsh, rtl, rth = E, F, E, F, E, F, E, F
    if sh >= 0.0:  # forward branch, s in [max(sl, 0), sh]
        p = polar_scalar(xl, xh, yl, yh, max(sl, 0.0), sh, tl, th)
        if p[0] <= p[1]:
            rxl, rxh = p[0], p[1]
            ryl, ryh = p[2], p[3]
            rsl, rsh = p[4], p[5]
            rtl, rth = p[6], p[7]
    if sl <= 0.0:  # reversing branch: length -s in [max(-sh, 0), -sl], angle t + pi
        ul, uh = add(tl, th, PI_LO, PI_HI)
        p = polar_scalar(xl, xh, yl, yh, max(-sh, 0.0), -sl, ul, uh)
        if p[0] <= p[1]:
            nl, nh = inter(tl, th, *sub(p[6], p[7], PI_LO, PI_HI))
            if nl <= nh:
                rxl, rxh = hull(rxl, rxh, p[0], p[1])
                ryl, ryh = hull(ryl, ryh, p[2], p[3])
                rsl, rsh = hull(rsl, rsh, -p[5], -p[4])
                rtl, rth = hull(rtl, rth, nl, nh)
    if not (rxl <= rxh):
        return E, F, E, F, E, F, E, F
    return rxl, rxh, ryl, ryh, rsl, rsh, rtl, rth


@njit(cache=True)
def _empty24():
    return (E, F, E, F, E, F, E, F, E, F, E, F, E, F, E, F, E, F, E, F, E, F, E, F)


@njit(cache=True)
def unicycle_pass(x0l, x0h, y0l, y0h, t0l, t0h, x1l, x1h, y1l, y1h, t1l, t1h,
                  vl, vh, wl, wh, dl, dh, qxl, qxh, qyl, qyh, qtl, qth):
    """One forward-backward pass over the 24 bounds (same order as :func:`unicycle_scalar`)."""
    # heading: u = w dt + qth, u = th1 - th0 (mod 2 pi)
    pl, ph = mul(wl, wh, dl, dh)
    ul, uh = add(pl, ph, qtl, qth)
    ul, uh, t1l, t1h, t0l, t0h = angle_difference_scalar(ul, uh, t1l, t1h, t0l, t0h)
    if not (ul <= uh):
        return _empty24()
    pl, ph, qtl, qth = bwd_add(ul, uh, pl, ph, qtl, qth)
    wl, wh, dl, dh = bwd_mul(pl, ph, wl, wh, dl, dh)
    if not (qtl <= qth) or not (wl <= wh) or not (dl <= dh):
        return _empty24()
    # position: (dx, dy) = s (cos th0, sin th0), s = v dt, dx = (x1 - x0) - qx
    sl, sh = mul(vl, vh, dl, dh)
    axl, axh = sub(x1l, x1h, x0l, x0h)
    ayl, ayh = sub(y1l, y1h, y0l, y0h)
    dxl, dxh = sub(axl, axh, qxl, qxh)
    dyl, dyh = sub(ayl, ayh, qyl, qyh)
    dxl, dxh, dyl, dyh, sl, sh, t0l, t0h = signed_polar(dxl, dxh, dyl, dyh, sl, sh, t0l, t0h)
    if not (dxl <= dxh):
        return _empty24()
    vl, vh, dl, dh = bwd_mul(sl, sh, vl, vh, dl, dh)
    dxl, dxh, axl, axh, qxl, qxh = difference_scalar(dxl, dxh, axl, axh, qxl, qxh)
    dyl, dyh, ayl, ayh, qyl, qyh = difference_scalar(dyl, dyh, ayl, ayh, qyl, qyh)
    axl, axh, x1l, x1h, x0l, x0h = difference_scalar(axl, axh, x1l, x1h, x0l, x0h)
    ayl, ayh, y1l, y1h, y0l, y0h = difference_scalar(ayl, ayh, y1l, y1h, y0l, y0h)
    if (not (vl <= vh) or not (dl <= dh) or not (dxl <= dxh) or not (dyl <= dyh)
            or not (axl <= axh) or not (ayl <= ayh)):
        return _empty24()
    return (x0l, x0h, y0l, y0h, t0l, t0h, x1l, x1h, y1l, y1h, t1l, t1h,
            vl, vh, wl, wh, dl, dh, qxl, qxh, qyl, qyh, qtl, qth)


@njit(cache=True)
def unicycle_scalar(x0l, x0h, y0l, y0h, t0l, t0h, x1l, x1h, y1l, y1h, t1l, t1h,
                    vl, vh, wl, wh, dl, dh, qxl, qxh, qyl, qyh, qtl, qth):
    """Contract one step; returns the 24 bounds in argument order, all empty if no solution.

    Order: ``x0 y0 th0 x1 y1 th1 v w dt qx qy qth`` (each as ``lo, hi``).
    """
    b = (x0l, x0h, y0l, y0h, t0l, t0h, x1l, x1h, y1l, y1h, t1l, t1h,
         vl, vh, wl, wh, dl, dh, qxl, qxh, qyl, qyh, qtl, qth)
    for j in range(12):
        if not (b[2 * j] <= b[2 * j + 1]):
            return _empty24()
    for k in range(MAX_PASSES):
        n = unicycle_pass(*b)
        if not (n[0] <= n[1]):
            return n
        progress = 0.0
        for j in range(12):
            progress = max(progress, shrink(b[2 * j], b[2 * j + 1], n[2 * j], n[2 * j + 1]))
        b = n
        if progress < RELATIVE_STOP:
            break
    return b


@njit(cache=True)
def unicycle_kernel(x0, y0, th0, x1, y1, th1, v, w, dt, qx, qy, qth):
    """In place over twelve ``(N, 2)`` arrays; returns the mask of rows that stayed non-empty."""
    n = x0.shape[0]
    ok = np.empty(n, dtype=np.bool_)
    for i in range(n):
        r = unicycle_scalar(
            x0[i, 0], x0[i, 1], y0[i, 0], y0[i, 1], th0[i, 0], th0[i, 1],
            x1[i, 0], x1[i, 1], y1[i, 0], y1[i, 1], th1[i, 0], th1[i, 1],
            v[i, 0], v[i, 1], w[i, 0], w[i, 1], dt[i, 0], dt[i, 1],
            qx[i, 0], qx[i, 1], qy[i, 0], qy[i, 1], qth[i, 0], qth[i, 1],
        )
        x0[i, 0], x0[i, 1], y0[i, 0], y0[i, 1], th0[i, 0], th0[i, 1] = r[0:6]
        x1[i, 0], x1[i, 1], y1[i, 0], y1[i, 1], th1[i, 0], th1[i, 1] = r[6:12]
        v[i, 0], v[i, 1], w[i, 0], w[i, 1], dt[i, 0], dt[i, 1] = r[12:18]
        qx[i, 0], qx[i, 1], qy[i, 0], qy[i, 1], qth[i, 0], qth[i, 1] = r[18:24]
        ok[i] = r[0] <= r[1]
    return ok
