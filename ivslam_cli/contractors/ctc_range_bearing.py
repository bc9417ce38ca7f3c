"""Range-bearing observation contractor (the Guaranteed SLAM slides' sensor model), from the others.

Constraint, for a robot pose ``(sx, sy, sth)`` and a landmark ``(mx, my)``::

    rho   = |m - s| = sqrt((mx - sx)^2 + (my - sy)^2)
    alpha = atan2(my - sy, mx - sx) - sth        (mod 2 pi)

The bounded measurement noise is already folded into the ``rho`` and ``alpha`` intervals
(``[z] + [r]``). ``rho`` has ``rho >= 0`` semantics (a negative part of the box is cut).

Decomposition: ``dx = mx - sx``, ``dy = my - sy`` (linear differences), the polar constraint on
``(dx, dy, rho, phi)`` with the world bearing ``phi``, and ``alpha = phi - sth (mod 2 pi)``
(periodic difference). ``dx, dy, phi`` persist across passes, which are iterated until no
width shrinks by more than ``RELATIVE_STOP`` (at most ``MAX_PASSES``). ``phi`` is an auxiliary
angle known only modulo 2 pi, so it may be moved to any branch: before each polar step it is
re-expressed around the argument of ``(dx, dy)`` when that is narrower (this keeps e.g. a
heading box wider than 2 pi from blurring the bearing into a hull of copies).

Guarantee: every solution inside the input box is in the output box (outward rounding, no
loss across the ±pi cut or any multiple of 2 pi; ``alpha`` and ``sth`` keep their branches).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_difference import angle_difference_scalar, difference_scalar
from ivslam_cli.contractors.ctc_polar import polar_scalar
from ivslam_cli.contractors.ctc_unicycle import shrink
from ivslam_cli.interval.angles import angle_meet, angle_meet_narrow, arg_box
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, add, cos, inter, mul, sin, sqr, sqrt, sub
from ivslam_cli.interval.rounding import TWO_PI_LO

MAX_PASSES = 6
RELATIVE_STOP = 1e-3

E = EMPTY_LO
F = EMPTY_HI


@njit(cache=True)
def range_bearing_scalar(sxl, sxh, syl, syh, stl, sth, mxl, mxh, myl, myh, rl, rh, al, ah):
    """Contract one observation; returns the 14 bounds in argument order, all empty if none.

    Order: ``sx sy sth mx my rho alpha`` (each as ``lo, hi``).
    """
    rl = max(rl, 0.0)
    b = (sxl, sxh, syl, syh, stl, sth, mxl, mxh, myl, myh, rl, rh, al, ah)
    for j in range(7):
        if not (b[2 * j] <= b[2 * j + 1]):
            return (E, F, E, F, E, F, E, F, E, F, E, F, E, F)
    dxl, dxh = sub(mxl, mxh, sxl, sxh)
    dyl, dyh = sub(myl, myh, syl, syh)
    pl, ph = add(al, ah, stl, sth)
    for k in range(MAX_PASSES):
        # phi is only known mod 2 pi: when the argument of (dx, dy) pins it to a narrower
        # representative than alpha + sth (wide, or a hull of several copies), switch to it.
        cl, ch = angle_meet(*arg_box(dxl, dxh, dyl, dyh), pl, ph)
        if not (cl <= ch):
            return (E, F, E, F, E, F, E, F, E, F, E, F, E, F)
        if ch - cl < ph - pl:
            pl, ph = cl, ch
        dxl, dxh, dyl, dyh, rl, rh, pl, ph = polar_scalar(dxl, dxh, dyl, dyh, rl, rh, pl, ph)
        if not (dxl <= dxh):
            return (E, F, E, F, E, F, E, F, E, F, E, F, E, F)
        dxl, dxh, mxl, mxh, sxl, sxh = difference_scalar(dxl, dxh, mxl, mxh, sxl, sxh)
        dyl, dyh, myl, myh, syl, syh = difference_scalar(dyl, dyh, myl, myh, syl, syh)
        al, ah, pl, ph, stl, sth = angle_difference_scalar(al, ah, pl, ph, stl, sth)
        if not (dxl <= dxh) or not (dyl <= dyh) or not (al <= ah):
            return (E, F, E, F, E, F, E, F, E, F, E, F, E, F)
        n = (sxl, sxh, syl, syh, stl, sth, mxl, mxh, myl, myh, rl, rh, al, ah)
        progress = 0.0
        for j in range(7):
            progress = max(progress, shrink(b[2 * j], b[2 * j + 1], n[2 * j], n[2 * j + 1]))
        b = n
        if progress < RELATIVE_STOP:
            break
    return b


@njit(cache=True)
def range_bearing_kernel(sx, sy, sth, mx, my, rho, alpha):
    """In place over seven ``(N, 2)`` arrays; returns the mask of rows that stayed non-empty."""
    n = sx.shape[0]
    ok = np.empty(n, dtype=np.bool_)
    for i in range(n):
        r = range_bearing_scalar(
            sx[i, 0], sx[i, 1], sy[i, 0], sy[i, 1], sth[i, 0], sth[i, 1],
            mx[i, 0], mx[i, 1], my[i, 0], my[i, 1], rho[i, 0], rho[i, 1],
            alpha[i, 0], alpha[i, 1],
        )
        sx[i, 0], sx[i, 1], sy[i, 0], sy[i, 1], sth[i, 0], sth[i, 1] = r[0:6]
        mx[i, 0], mx[i, 1], my[i, 0], my[i, 1] = r[6:10]
        rho[i, 0], rho[i, 1], alpha[i, 0], alpha[i, 1] = r[10:14]
        ok[i] = r[0] <= r[1]
    return ok


@njit(cache=True)
def range_bearing_pass(sxl, sxh, syl, syh, stl, sth, mxl, mxh, myl, myh, rl, rh, al, ah, passes=2):
    """The same constraint contracted by at most ``passes`` forward-backward passes of its
    closed form, ``m − s = ρ (cos φ, sin φ)`` with the world bearing ``φ = s_θ + α``; the 14
    bounds in the order of :func:`range_bearing_scalar`, all empty if there is no solution.

    Each pass: ``φ = s_θ + α``; ``d = (m − s) ∩ ρ (cos φ, sin φ)`` (the bounding box of an
    annulus sector is the product of the intervals ``ρ`` and ``cos φ``: exact for
    independent ``ρ, φ``, up to rounding); ``s ∩= m − d``, ``m ∩= s + d``; ``ρ ∩= |d|``; then
    ``φ ∩= arg(d)`` (modulo 2π, in the narrower branch: ``φ`` is auxiliary) and back to ``s_θ ∩= φ − α``,
    ``α ∩= φ − s_θ`` (skipped when ``d`` is the sector's whole bounding box: its norms then hold
    ``ρ`` and its arguments ``φ``, nothing to contract). A second pass runs only if the first
    narrowed ``φ``.

    It is the cheap contractor of the set-membership inner loops (a fraction of a
    microsecond): on narrow heading slices one pass is close to the fixpoint
    :func:`range_bearing_scalar` reaches (the polar contractor's iterations matter when the
    bearing is wide and the boxes narrow). Guarantee: every solution in the input box is in
    the output box (outward rounding; nothing lost across ±π or any multiple of 2π).
    """
    rl = max(rl, 0.0)
    if not (sxl <= sxh and syl <= syh and stl <= sth and mxl <= mxh and myl <= myh and rl <= rh and al <= ah):
        return (E, F, E, F, E, F, E, F, E, F, E, F, E, F)
    for _ in range(passes):
        pl, ph = add(stl, sth, al, ah)
        cl, ch = cos(pl, ph)
        snl, snh = sin(pl, ph)
        uxl, uxh = mul(rl, rh, cl, ch)
        uyl, uyh = mul(rl, rh, snl, snh)
        dxl, dxh = inter(*sub(mxl, mxh, sxl, sxh), uxl, uxh)
        dyl, dyh = inter(*sub(myl, myh, syl, syh), uyl, uyh)
        if not (dxl <= dxh) or not (dyl <= dyh):
            return (E, F, E, F, E, F, E, F, E, F, E, F, E, F)
        whole = dxl == uxl and dxh == uxh and dyl == uyl and dyh == uyh
        sxl, sxh = inter(sxl, sxh, *sub(mxl, mxh, dxl, dxh))
        mxl, mxh = inter(mxl, mxh, *add(sxl, sxh, dxl, dxh))
        syl, syh = inter(syl, syh, *sub(myl, myh, dyl, dyh))
        myl, myh = inter(myl, myh, *add(syl, syh, dyl, dyh))
        if not (sxl <= sxh and mxl <= mxh and syl <= syh and myl <= myh):
            return (E, F, E, F, E, F, E, F, E, F, E, F, E, F)
        if whole:  # d is the sector's whole bounding box: its norms hold ρ, its arguments φ
            break
        d2l, d2h = add(*sqr(dxl, dxh), *sqr(dyl, dyh))
        r2l, r2h = inter(*sqr(rl, rh), d2l, d2h)
        rl, rh = inter(rl, rh, *sqrt(r2l, r2h))
        if not (rl <= rh):
            return (E, F, E, F, E, F, E, F, E, F, E, F, E, F)
        gl, gh = arg_box(dxl, dxh, dyl, dyh)
        if not (gh - gl < TWO_PI_LO):  # d may be 0 (the origin is in its box): no bearing
            break
        ql, qh = angle_meet_narrow(pl, ph, gl, gh)  # φ is auxiliary: any branch will do
        if not (ql <= qh):
            return (E, F, E, F, E, F, E, F, E, F, E, F, E, F)
        stl, sth = angle_meet(stl, sth, *sub(ql, qh, al, ah))
        al, ah = angle_meet(al, ah, *sub(ql, qh, stl, sth))
        if not (stl <= sth) or not (al <= ah):
            return (E, F, E, F, E, F, E, F, E, F, E, F, E, F)
        if not (qh - ql < 0.9 * (ph - pl)):  # φ hardly narrowed: another pass would repeat this one
            break
    return (sxl, sxh, syl, syh, stl, sth, mxl, mxh, myl, myh, rl, rh, al, ah)


@njit(cache=True)
def range_bearing_pass_kernel(sx, sy, sth, mx, my, rho, alpha, passes):
    """:func:`range_bearing_pass` in place over seven ``(N, 2)`` arrays; the non-empty mask."""
    n = sx.shape[0]
    ok = np.empty(n, dtype=np.bool_)
    for i in range(n):
        r = range_bearing_pass(
            sx[i, 0], sx[i, 1], sy[i, 0], sy[i, 1], sth[i, 0], sth[i, 1],
            mx[i, 0], mx[i, 1], my[i, 0], my[i, 1], rho[i, 0], rho[i, 1],
            alpha[i, 0], alpha[i, 1], passes,
        )
        sx[i, 0], sx[i, 1], sy[i, 0], sy[i, 1], sth[i, 0], sth[i, 1] = r[0:6]
        mx[i, 0], mx[i, 1], my[i, 0], my[i, 1] = r[6:10]
        rho[i, 0], rho[i, 1], alpha[i, 0], alpha[i, 1] = r[10:14]
        ok[i] = r[0] <= r[1]
    return ok
