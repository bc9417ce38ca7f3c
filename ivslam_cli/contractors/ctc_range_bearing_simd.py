"""Range-bearing contractor over structure-of-arrays chunks: one fused SIMD loop per chunk.

Same constraint and guarantee as :mod:`~ivslam_cli.contractors.ctc_range_bearing` (the sensor
model of the Guaranteed SLAM slides: ``rho = |m - s|``, ``alpha = atan2(my - sy, mx - sx) - sth``
mod 2 pi, ``rho >= 0``): every solution in the input box is in the output box, angles keep their
branches. :func:`~ivslam_cli.contractors.ctc_range_bearing.range_bearing_scalar` stays the
reference; tests/contractors/test_range_bearing_simd.py compares the two.

Decomposition (Jaulin's contractor programming: a network of primitive contractors, each
applied forward and backward, iterated): ``dx = mx - sx``, ``dy = my - sy``, the polar
constraint on ``(dx, dy, rho, phi)`` and ``alpha = phi - sth`` (mod 2 pi) with the auxiliary
world bearing ``phi``. The box is split along the axes of ``(dx, dy)`` into its closed quadrant
pieces (one piece for most boxes; the solutions of the box are the union of those of its
pieces, so the hull of the pieces' contractions is sound). In a piece, with the x variables
negated when ``dx <= 0`` and the y ones when ``dy <= 0``, ``u = |dx|, v = |dy| >= 0`` and the
bearing is ``phi = s psi + c`` with ``psi in [0, pi/2]``. ``psi`` starts as the hull of the
copies of ``alpha + sth`` meeting the quadrant (``phi`` is auxiliary: any branch will do) and
is carried as ``t = tan(psi)``: the polar steps of
:mod:`~ivslam_cli.contractors.ctc_polar_simd` (``v = u t``, ``rho^2 = u^2 + v^2``,
``u = rho cos``, ``v = rho sin`` from ``t`` by square roots) and the two differences forward and
backward are then a fixed sequence of min/max, products, quotients and square roots, rounded
outward with :func:`~ivslam_cli.interval.rounding.down` / ``up``: one branch-free loop over the
chunk that LLVM turns into SIMD code. libm is called at most four times per piece (tan of the
two ``psi`` bounds on entry, atan of the two ``t`` bounds on exit, each skipped when the bound
is 0, pi/2 or unchanged). On exit ``psi ∩= atan(t)`` and ``alpha``, ``sth`` are contracted by
the periodic difference (:func:`~ivslam_cli.interval.angles.angle_meet`); nothing else
depends on ``phi``, so this one backward step is all the angle part can give.

Passes repeat per piece while one shrinks some width by at least ``RELATIVE_STOP`` (at least
two, at most ``MAX_PASSES``); a piece that stops is written out and the chunk is packed.
tests/contractors/test_range_bearing_simd.py checks against the scalar kernel: the same rows
emptied, no bound outside the scalar result by more than ``1e-9`` of its width plus
``1e-12 (1 + |bound|)``, and widths on average no larger.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_polar import _atan_hi, _atan_lo, _tan_hi, _tan_lo, _two_pi_times
from ivslam_cli.contractors.ctc_polar_simd import BIG, _mn, _mx
from ivslam_cli.contractors.ctc_range_bearing import RELATIVE_STOP
from ivslam_cli.interval.angles import angle_meet
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, add, inter, sub
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
    up,
)

CHUNK = 256
MAX_FLOAT = float(np.finfo(np.float64).max)
MAX_PASSES = 16
E = EMPTY_LO
F = EMPTY_HI

# Lane state, row r of lane i at L[r * CHUNK + i] (one base pointer, compile-time offsets).
UL, UH, VL, VH, RL, RH, TL, TH = 0, 1, 2, 3, 4, 5, 6, 7
SXL, SXH, MXL, MXH, SYL, SYH, MYL, MYH = 8, 9, 10, 11, 12, 13, 14, 15
OK = 16  # 1.0 while the lane is non-empty
PROG = 17  # 1.0 if the last pass shrank some width by RELATIVE_STOP
ROWS = 18


@njit(cache=True, inline="always", error_model="numpy")
def _shrunk(ol, oh, nl, nh):
    """Did ``[ol, oh] -> [nl, nh]`` shrink the width by ``RELATIVE_STOP``? (inf -> finite: yes)."""
    w0 = oh - ol
    return (w0 > 0.0) & ((w0 - (nh - nl)) >= RELATIVE_STOP * w0)


@njit(cache=True, inline="always", error_model="numpy")
def _dnf(c):
    """A lower bound of a nonnegative quotient or product rounded to ``c``: ``down(c)``, except
    that an overflow (``c = +inf``, the real value above ``MAX_FLOAT``) gives ``MAX_FLOAT``
    (``down`` would give ``-inf``: nothing; this keeps ``t = v / u`` huge when ``u`` is a few
    subnormals, i.e. ``psi`` at pi/2)."""
    return MAX_FLOAT if c == INF else down(c)


@njit(cache=True, error_model="numpy")
def _passes(n, L):
    """One pass over lanes ``0..n-1`` (straight-line code: a SIMD loop)."""
    C = CHUNK
    for i in range(n):
        a0, b0, c0, d0 = L[UL * C + i], L[UH * C + i], L[VL * C + i], L[VH * C + i]
        e0, f0, g0, h0 = L[RL * C + i], L[RH * C + i], L[TL * C + i], L[TH * C + i]
        p0, q0, r0, s0 = L[SXL * C + i], L[SXH * C + i], L[MXL * C + i], L[MXH * C + i]
        w0, x0, y0, z0 = L[SYL * C + i], L[SYH * C + i], L[MYL * C + i], L[MYH * C + i]
        sxl, sxh, mxl, mxh, syl, syh, myl, myh = p0, q0, r0, s0, w0, x0, y0, z0
        # u = mx - sx, v = my - sy (frame: both >= 0)
        a = _mx(a0, down(mxl - sxh))
        b = _mn(b0, up(mxh - sxl))
        c = _mx(c0, down(myl - syh))
        d = _mn(d0, up(myh - syl))
        e, f, g, h = e0, f0, g0, h0
        # v = u t (u, v >= 0, t >= 0; t may be +inf above; 0 / 0 and 0 * inf are NaN: ignored)
        a = _mx(a, _dnf(c / h))
        b = _mn(b, up(d / g))
        g = _mx(g, _dnf(c / b))
        h = _mn(h, up(d / a))
        c = _mx(c, _dnf(a * g))
        d = _mn(d, up(b * h))
        # rho^2 = u^2 + v^2
        u2l, u2h = down(a * a), up(b * b)
        v2l, v2h = down(c * c), up(d * d)
        sl = _mx(_mx(down(u2l + v2l), down(e * e)), 0.0)
        sh = _mn(up(u2h + v2h), up(f * f))
        e = _mx(e, down(np.sqrt(sl)))
        f = _mn(f, up(np.sqrt(_mx(sh, 0.0))))
        u2l = _mx(u2l, down(sl - v2h))
        u2h = _mn(u2h, up(sh - v2l))
        v2l = _mx(v2l, down(sl - u2h))
        v2h = _mn(v2h, up(sh - u2l))
        a = _mx(a, down(np.sqrt(_mx(u2l, 0.0))))
        b = _mn(b, up(np.sqrt(_mx(u2h, 0.0))))
        c = _mx(c, down(np.sqrt(_mx(v2l, 0.0))))
        d = _mn(d, up(np.sqrt(_mx(v2h, 0.0))))
        # u ∩= rho cos(psi), v ∩= rho sin(psi), cos and sin from t = tan(psi)
        big = h > BIG
        hb = _mn(h, BIG)
        gb = _mn(g, BIG)
        cos_l = _mx(0.0, down(1.0 / up(np.sqrt(up(1.0 + up(hb * hb))))))
        sin_h = _mn(1.0, up(hb / down(np.sqrt(down(1.0 + down(hb * hb))))))
        cos_l = 0.0 if big else cos_l
        sin_h = 1.0 if big else sin_h
        cos_h = _mn(1.0, up(1.0 / down(np.sqrt(down(1.0 + down(gb * gb))))))
        sin_l = _mx(0.0, down(gb / up(np.sqrt(up(1.0 + up(gb * gb))))))
        a = _mx(a, down(e * cos_l))
        b = _mn(b, up(f * cos_h))
        c = _mx(c, down(e * sin_l))
        d = _mn(d, up(f * sin_h))
        # back to the differences: mx ∩= u + sx, sx ∩= mx - u (y likewise)
        mxl = _mx(mxl, down(a + sxl))
        mxh = _mn(mxh, up(b + sxh))
        sxl = _mx(sxl, down(mxl - b))
        sxh = _mn(sxh, up(mxh - a))
        myl = _mx(myl, down(c + syl))
        myh = _mn(myh, up(d + syh))
        syl = _mx(syl, down(myl - d))
        syh = _mn(syh, up(myh - c))
        L[UL * C + i], L[UH * C + i], L[VL * C + i], L[VH * C + i] = a, b, c, d
        L[RL * C + i], L[RH * C + i], L[TL * C + i], L[TH * C + i] = e, f, g, h
        L[SXL * C + i], L[SXH * C + i], L[MXL * C + i], L[MXH * C + i] = sxl, sxh, mxl, mxh
        L[SYL * C + i], L[SYH * C + i], L[MYL * C + i], L[MYH * C + i] = syl, syh, myl, myh
        good = ((a <= b) & (c <= d) & (e <= f) & (g <= h) & (sl <= sh) & (u2l <= u2h)
                & (v2l <= v2h) & (sxl <= sxh) & (mxl <= mxh) & (syl <= syh) & (myl <= myh))
        L[OK * C + i] = L[OK * C + i] if good else 0.0
        prog = (_shrunk(a0, b0, a, b) | _shrunk(c0, d0, c, d) | _shrunk(e0, f0, e, f)
                | _shrunk(g0, h0, g, h) | _shrunk(p0, q0, sxl, sxh) | _shrunk(r0, s0, mxl, mxh)
                | _shrunk(w0, x0, syl, syh) | _shrunk(y0, z0, myl, myh))
        L[PROG * C + i] = 1.0 if prog else 0.0


@njit(cache=True, inline="always")
def _flip(sign, lo, hi):
    """``sign * [lo, hi]`` for ``sign = ±1`` (exact)."""
    if sign > 0.0:
        return lo, hi
    return -hi, -lo


@njit(cache=True, inline="always")
def _arc(q):
    """The quadrant's arc of world bearings (``q`` as in ``catan2``)."""
    if q == 0:
        return 0.0, HALF_PI_HI
    if q == 1:
        return -HALF_PI_HI, 0.0
    if q == 2:
        return -PI_HI, -HALF_PI_LO
    return HALF_PI_LO, PI_HI


@njit(cache=True, inline="always")
def _to_psi(q, tl, th):
    """World bearing in the quadrant's arc -> ``psi in [0, pi/2]`` (outward)."""
    if q == 0:
        pl, ph = tl, th
    elif q == 1:
        pl, ph = -th, -tl
    elif q == 2:
        pl, ph = add(tl, th, PI_LO, PI_HI)
    else:
        pl, ph = sub(PI_LO, PI_HI, tl, th)
    return inter(pl, ph, 0.0, HALF_PI_HI)


@njit(cache=True, inline="always")
def _from_psi(q, pl, ph):
    if q == 0:
        return pl, ph
    if q == 1:
        return -ph, -pl
    if q == 2:
        return sub(pl, ph, PI_LO, PI_HI)
    return sub(PI_LO, PI_HI, pl, ph)


@njit(cache=True, inline="always")
def _shift(al, ah, k):
    """:func:`~ivslam_cli.interval.angles.shift` (``[a] + 2 k pi``, same roundings) for a
    non-empty ``[a]``."""
    if k == 0.0:
        return al, ah
    ol, oh = _two_pi_times(k)
    return down(al + ol), up(ah + oh)


@njit(cache=True, inline="always")
def _meet(tl, th, al, ah):
    """:func:`~ivslam_cli.interval.angles.angle_meet`, the same bounds: when ``w(t) + w(a) < 6``
    only the copies ``k0 - 1, k0, k0 + 1`` around the nearest one can meet ``[t]``, so their
    pieces (shifted as ``angle_meet`` shifts them) are hulled without its search."""
    if not (tl <= th and al <= ah and (th - tl) + (ah - al) < 6.0 and -1e15 < tl and th < 1e15
            and -1e15 < al and ah < 1e15):
        return angle_meet(tl, th, al, ah)
    k0 = float(round((0.5 * (tl + th) - 0.5 * (al + ah)) * INV_TWO_PI_LO))
    lo, hi = E, F
    for dk in range(-1, 2):
        sl, sh = _shift(al, ah, k0 + dk)
        pl, ph = (sl if sl > tl else tl), (sh if sh < th else th)
        if pl <= ph:
            lo = pl if pl < lo else lo
            hi = ph if ph > hi else hi
    return lo, hi


GAL, GAH, GSL, GSH, GOK = 0, 1, 2, 3, 4  # rows of the angle buffer G (alpha, sth, in range)


@njit(cache=True, inline="always", error_model="numpy")
def _meet3(tl, th, al, ah):
    """:func:`_meet` as selects, for ``w(t) + w(a) < 6`` with moderate bounds (else ``ok`` is
    False and the result is to be ignored): the pieces of the copies ``k0 - 1, k0, k0 + 1``,
    shifted as ``angle_meet`` shifts them, hulled."""
    ok = ((th - tl) + (ah - al) < 6.0) & (-1e15 < tl) & (th < 1e15) & (-1e15 < al) & (ah < 1e15)
    k0 = np.floor((0.5 * (tl + th) - 0.5 * (al + ah)) * INV_TWO_PI_LO + 0.5)
    lo, hi = E, F
    for dk in range(-1, 2):
        k = k0 + dk
        ol = down(k * TWO_PI_LO) if k >= 0.0 else down(k * TWO_PI_HI)
        oh = up(k * TWO_PI_HI) if k >= 0.0 else up(k * TWO_PI_LO)
        sl = al if k == 0.0 else down(al + ol)
        sh = ah if k == 0.0 else up(ah + oh)
        pl = sl if sl > tl else tl
        ph = sh if sh < th else th
        meets = pl <= ph
        lo = pl if meets & (pl < lo) else lo
        hi = ph if meets & (ph > hi) else hi
    return lo, hi, ok


@njit(cache=True, error_model="numpy")
def _differences(n, q, pl, ph, G):
    """``alpha ∩= phi - sth``, ``sth ∩= phi - alpha`` (mod 2 pi) for lanes ``0..n-1`` in ``G``,
    ``phi`` the world bearing of ``psi``; ``G[GOK]`` is 0 where ``_meet3`` does not apply."""
    C = CHUNK
    for i in range(n):
        lo, hi, qi = pl[i], ph[i], q[i]
        wl = lo if qi == 0 else (-hi if qi == 1 else (down(lo - PI_HI) if qi == 2 else down(PI_LO - hi)))
        wh = hi if qi == 0 else (-lo if qi == 1 else (up(hi - PI_LO) if qi == 2 else up(PI_HI - lo)))
        al, ah, stl, sth = G[GAL * C + i], G[GAH * C + i], G[GSL * C + i], G[GSH * C + i]
        nal, nah, ok1 = _meet3(al, ah, down(wl - sth), up(wh - stl))
        nsl, nsh, ok2 = _meet3(stl, sth, down(wl - nah), up(wh - nal))
        ok = ok1 & ok2 & (lo <= hi)
        G[GAL * C + i] = nal if ok else al
        G[GAH * C + i] = nah if ok else ah
        G[GSL * C + i] = nsl if ok else stl
        G[GSH * C + i] = nsh if ok else sth
        G[GOK * C + i] = 1.0 if ok else 0.0


@njit(cache=True, error_model="numpy")
def _finish(n, D, box, q, pl, ph, t0l, t0h, ang, acc, G):
    """Lanes ``0..n-1`` done (final state in ``D``): ``psi ∩= atan(t)``, the periodic difference,
    hull into their boxes' rows of ``acc``."""
    C = CHUNK
    for i in range(n):  # atan only where t moved (atan(tan(psi)) holds psi already)
        tl = D[TL * C + i]
        if tl != t0l[i]:
            pl[i] = _mx(pl[i], _atan_lo(tl))
    for i in range(n):
        th = D[TH * C + i]
        if th != t0h[i]:
            ph[i] = _mn(ph[i], _atan_hi(th))
    for i in range(n):  # the lanes' alpha and sth, then the periodic difference as a SIMD loop
        j = box[i]
        G[GAL * C + i], G[GAH * C + i] = ang[j, 0], ang[j, 1]
        G[GSL * C + i], G[GSH * C + i] = ang[j, 2], ang[j, 3]
    _differences(n, q, pl, ph, G)
    for i in range(n):
        if D[OK * C + i] < 0.5 or not (pl[i] <= ph[i]):
            continue
        j = box[i]
        al, ah, stl, sth = G[GAL * C + i], G[GAH * C + i], G[GSL * C + i], G[GSH * C + i]
        if G[GOK * C + i] < 0.5:  # outside _meet3's range: the scalar steps
            wl, wh = _from_psi(q[i], pl[i], ph[i])
            dl, dh = sub(wl, wh, stl, sth)
            al, ah = _meet(al, ah, dl, dh)
            dl, dh = sub(wl, wh, al, ah)
            stl, sth = _meet(stl, sth, dl, dh)
        if not (al <= ah) or not (stl <= sth):
            continue
        sx = 1.0 if (q[i] == 0 or q[i] == 1) else -1.0
        sy = 1.0 if (q[i] == 0 or q[i] == 3) else -1.0
        for k, r, sg in ((0, SXL, sx), (1, SYL, sy), (3, MXL, sx), (4, MYL, sy), (5, RL, 1.0)):
            lo, hi = D[r * C + i], D[(r + 1) * C + i]
            if sg < 0.0:
                lo, hi = -hi, -lo
            acc[j, 2 * k] = _mn(acc[j, 2 * k], lo)
            acc[j, 2 * k + 1] = _mx(acc[j, 2 * k + 1], hi)
        acc[j, 4] = _mn(acc[j, 4], stl)
        acc[j, 5] = _mx(acc[j, 5], sth)
        acc[j, 12] = _mn(acc[j, 12], al)
        acc[j, 13] = _mx(acc[j, 13], ah)


@njit(cache=True, error_model="numpy")
def _to_fixpoint(n, L, D, orig, pl, ph, t0l, t0h, passes):
    """Load the ``n`` lanes' tangents of their ψ bounds ``pl``, ``ph`` and run :func:`_passes`
    (at most ``passes``) until no lane is left. After each pass from the second on, a lane that
    shrank no width by ``RELATIVE_STOP`` (or was emptied) is copied to ``D`` at its first slot
    and the others are packed to the front."""
    C = CHUNK
    for i in range(n):
        t0l[i] = _tan_lo(pl[i])
    for i in range(n):
        t0h[i] = _tan_hi(ph[i])
    for i in range(n):
        L[TL * C + i], L[TH * C + i] = t0l[i], t0h[i]
        L[OK * C + i] = 1.0
        orig[i] = i
    for p in range(passes):
        _passes(n, L)
        if p == 0:
            continue
        m = 0
        for i in range(n):
            if L[OK * C + i] < 0.5 or L[PROG * C + i] < 0.5 or p + 1 == passes:
                o = orig[i]
                for r in range(OK + 1):
                    D[r * C + o] = L[r * C + i]
                continue
            if m != i:
                orig[m] = orig[i]
                for r in range(ROWS):
                    L[r * C + m] = L[r * C + i]
            m += 1
        n = m
        if n == 0:
            break


@njit(cache=True, error_model="numpy")
def _flush(n, nb, rows, box, q, pl, ph, t0l, t0h, ang, acc, L, D, orig, out, G):
    """Contract the ``n`` lanes (pieces of ``nb`` boxes, output rows ``rows``) and write out."""
    _to_fixpoint(n, L, D, orig, pl, ph, t0l, t0h, MAX_PASSES)
    _finish(n, D, box, q, pl, ph, t0l, t0h, ang, acc, G)
    sx, sy, st, mx, my, rho, alpha = out
    for j in range(nb):
        k = rows[j]
        ok = acc[j, 0] <= acc[j, 1]
        for v, arr in enumerate((sx, sy, st, mx, my, rho, alpha)):
            arr[k, 0] = acc[j, 2 * v] if ok else E
            arr[k, 1] = acc[j, 2 * v + 1] if ok else F


@njit(cache=True, inline="always")
def _lane(L, m, ul, uh, vl, vh, rl, rh, xs, ys, sxl, sxh, mxl, mxh, syl, syh, myl, myh):
    """Lane ``m``'s state from one quadrant piece of a box (x variables negated by ``xs``, y by ``ys``)."""
    C = CHUNK
    L[UL * C + m], L[UH * C + m], L[VL * C + m], L[VH * C + m] = ul, uh, vl, vh
    L[RL * C + m], L[RH * C + m] = rl, rh
    L[SXL * C + m], L[SXH * C + m] = _flip(xs, sxl, sxh)
    L[MXL * C + m], L[MXH * C + m] = _flip(xs, mxl, mxh)
    L[SYL * C + m], L[SYH * C + m] = _flip(ys, syl, syh)
    L[MYL * C + m], L[MYH * C + m] = _flip(ys, myl, myh)


@njit(cache=True, error_model="numpy")
def _kernel(sx, sy, st, mx, my, rho, alpha):
    n = sx.shape[0]
    C = CHUNK
    okm = np.empty(n, np.bool_)
    rows = np.empty(C, np.int64)
    box = np.empty(C, np.int64)
    q = np.empty(C, np.int64)
    pl, ph, t0l, t0h = np.empty(C), np.empty(C), np.empty(C), np.empty(C)
    ang = np.empty((C, 4))
    acc = np.empty((C, 14))
    L = np.empty(ROWS * C)
    D = np.empty(ROWS * C)
    G = np.empty(5 * C)
    orig = np.empty(C, np.int64)
    out = (sx, sy, st, mx, my, rho, alpha)
    m = 0  # lanes in the chunk
    nb = 0  # boxes in the chunk
    for i in range(n):
        sxl, sxh, syl, syh = sx[i, 0], sx[i, 1], sy[i, 0], sy[i, 1]
        stl, sth, mxl, mxh = st[i, 0], st[i, 1], mx[i, 0], mx[i, 1]
        myl, myh, rl, rh = my[i, 0], my[i, 1], max(rho[i, 0], 0.0), rho[i, 1]
        al, ah = alpha[i, 0], alpha[i, 1]
        okm[i] = False
        if not (sxl <= sxh and syl <= syh and stl <= sth and mxl <= mxh and myl <= myh
                and rl <= rh and al <= ah):
            for arr in out:
                arr[i, 0], arr[i, 1] = E, F
            continue
        dxl, dxh = sub(mxl, mxh, sxl, sxh)
        dyl, dyh = sub(myl, myh, syl, syh)
        fl, fh = add(al, ah, stl, sth)
        m0 = m
        for qq in range(4):
            xs = 1.0 if (qq == 0 or qq == 1) else -1.0
            ys = 1.0 if (qq == 0 or qq == 3) else -1.0
            ul, uh = _flip(xs, dxl, dxh)
            vl, vh = _flip(ys, dyl, dyh)
            ul, vl = max(ul, 0.0), max(vl, 0.0)
            if not (ul <= uh and vl <= vh):
                continue
            cl, ch = _arc(qq)
            wide = not (fh - fl < TWO_PI_LO and -1e15 < fl and fh < 1e15)
            k0 = 0.0 if wide else float(round((0.5 * (cl + ch) - 0.5 * (fl + fh)) * INV_TWO_PI_LO))
            for dk in range(-1, 2):
                if wide and dk != 0:
                    continue
                wl, wh = (cl, ch) if wide else inter(cl, ch, *_shift(fl, fh, k0 + dk))
                a, b = _to_psi(qq, wl, wh) if wl <= wh else (E, F)
                if not (a <= b):
                    continue
                _lane(L, m, ul, uh, vl, vh, rl, rh, xs, ys, sxl, sxh, mxl, mxh, syl, syh, myl, myh)
                box[m], q[m], pl[m], ph[m] = nb, qq, a, b
                m += 1
        if m == m0:
            for arr in out:
                arr[i, 0], arr[i, 1] = E, F
            continue
        rows[nb] = i
        ang[nb, 0], ang[nb, 1], ang[nb, 2], ang[nb, 3] = al, ah, stl, sth
        for k in range(14):
            acc[nb, k] = E if k % 2 == 0 else F
        nb += 1
        if m + 12 > C:
            _flush(m, nb, rows, box, q, pl, ph, t0l, t0h, ang, acc, L, D, orig, out, G)
            m = 0
            nb = 0
    if m > 0:
        _flush(m, nb, rows, box, q, pl, ph, t0l, t0h, ang, acc, L, D, orig, out, G)
    for i in range(n):
        okm[i] = sx[i, 0] <= sx[i, 1]
    return okm


def range_bearing_simd_kernel(sx, sy, sth, mx, my, rho, alpha):
    """In place over seven ``(N, 2)`` arrays; returns the mask of rows that stayed non-empty."""
    return _kernel(sx, sy, sth, mx, my, rho, alpha)
