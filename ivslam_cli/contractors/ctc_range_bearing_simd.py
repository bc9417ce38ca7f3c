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

Boxes go through in chunks of ``CHUNK``. A box with exactly one piece (about 97 % of the bench's
mix) takes the fast path: its piece is found, its lane built (:func:`_entry`) and, after the
fixpoint, its result written back (:func:`_exit`) by select-based SIMD loops, its lane at the
box's slot of the chunk. Every other box (several pieces, or none found that way) goes to the
general path (:func:`_general_box`: its pieces as lanes of their own, hulled per box by
:func:`_finish`). Both paths give a box the same bounds.

tests/contractors/test_range_bearing_simd.py checks against the scalar kernel: the same rows
emptied, no bound outside the scalar result by more than ``1e-9`` of its width plus
``1e-12 (1 + |bound|)``, and widths on average no larger.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.simd_polar_lanes import (
    psi_from_tangents,
    in_place,
    CHUNK,
    MAX_PASSES,
    MXH,
    MXL,
    MYH,
    MYL,
    OK,
    RH,
    RL,
    ROWS,
    SXH,
    SXL,
    SYH,
    SYL,
    UH,
    UL,
    VH,
    VL,
    _flip,
    _lane,
    _mn,
    _mx,
    _to_fixpoint,
)
from ivslam_cli.contractors.simd_quadrants import _arc, _from_psi, _meet, _meet3, _shift, _to_psi
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, add, inter, sub
from ivslam_cli.interval.rounding import (
    HALF_PI_HI,
    INF,
    INV_TWO_PI_LO,
    PI_HI,
    PI_LO,
    TWO_PI_HI,
    TWO_PI_LO,
    down,
    up,
)

E = EMPTY_LO
F = EMPTY_HI

GAL, GAH, GSL, GSH, GOK = 0, 1, 2, 3, 4  # rows of the angle buffer G (alpha, sth, in range)


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
def _finish(n, D, box, q, pl, ph, t0l, t0h, ang, acc, G, idx):
    """Lanes ``0..n-1`` done (final states in ``D``): ``psi ∩= atan(t)``, the periodic
    difference, hull into their boxes' rows of ``acc``."""
    C = CHUNK
    psi_from_tangents(n, D, t0l, t0h, pl, ph, idx)
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
def _flush(n, nb, rows, box, q, pl, ph, t0l, t0h, ang, acc, L, S, orig, out, G):
    """Contract the ``n`` lanes (pieces of ``nb`` boxes, output rows ``rows``) and write out."""
    _to_fixpoint(n, L, S, orig, pl, ph, t0l, t0h, MAX_PASSES)
    _finish(n, L, box, q, pl, ph, t0l, t0h, ang, acc, G, orig)
    for j in range(nb):
        k = 2 * rows[j]
        ok = acc[j, 0] <= acc[j, 1]
        for v, arr in enumerate(out):
            arr[k] = acc[j, 2 * v] if ok else E
            arr[k + 1] = acc[j, 2 * v + 1] if ok else F


# what _entry found for a box: no solution, one piece (a lane at the box's slot), several
NONE, ONE, MORE = 0.0, 1.0, 2.0
# The fast path's buffer W: the lane rows (0..ROWS-1, packed during the fixpoint), then per box
# of the chunk (slot = box): its 14 bounds (sx sy st mx my rho alpha, lo hi; replaced by the
# results on exit), the ψ bounds of its lane, its quadrant, its kind, and a flag for the scalar
# angle steps. Every SIMD loop over W reads and writes one base pointer at compile-time row
# offsets, so LLVM vectorises it without runtime alias checks.
BX = ROWS
PSL, PSH, QD, KD, FX = BX + 14, BX + 15, BX + 16, BX + 17, BX + 18
WROWS = BX + 19


@njit(cache=True, inline="always", error_model="numpy")
def _copy(k, dl, dh, fl, fh):
    """Copy ``k`` of the bearing ``f`` as :func:`_shift` gives it, for the piece search of
    :func:`_entry` (``dl``, ``dh``: the whole line, or nothing, for a wide bearing)."""
    ol = down(k * (TWO_PI_LO if k >= 0.0 else TWO_PI_HI))
    oh = up(k * (TWO_PI_HI if k >= 0.0 else TWO_PI_LO))
    sl = fl if k == 0.0 else down(fl + ol)
    sh = fh if k == 0.0 else up(fh + oh)
    return dl if dl == dl else sl, dh if dh == dh else sh


@njit(cache=True, error_model="numpy")
def _entry(s, nb, out, W):
    """Boxes ``s..s+nb-1`` into ``W`` and, as selects (a SIMD loop), their kinds: a box with one
    piece gets its lane at its slot (``W`` rows ``PSL``, ``PSH``, ``QD`` and the lane rows, as
    :func:`_general_box` builds it), any other box a dead lane (``OK`` 0, ψ = [0, pi/2]).

    The pieces are counted over the copies ``K - 1, K, K + 1`` of the bearing around the one
    nearest to 0 (``K``): every copy meeting a quadrant's arc is one of them, so the count is
    :func:`_general_box`'s (a copy meeting the arc always gives a non-empty ψ; a box is only
    taken as ``ONE`` if its piece's ψ is checked non-empty)."""
    C = CHUNK
    for v in range(7):
        a = out[v]
        r = (BX + 2 * v) * C
        for j in range(nb):
            W[r + j] = a[2 * (s + j)]
            W[r + C + j] = a[2 * (s + j) + 1]
    for j in range(nb):
        sxl, sxh = W[(BX + 0) * C + j], W[(BX + 1) * C + j]
        syl, syh = W[(BX + 2) * C + j], W[(BX + 3) * C + j]
        stl, sth = W[(BX + 4) * C + j], W[(BX + 5) * C + j]
        mxl, mxh = W[(BX + 6) * C + j], W[(BX + 7) * C + j]
        myl, myh = W[(BX + 8) * C + j], W[(BX + 9) * C + j]
        rl, rh = _mx(W[(BX + 10) * C + j], 0.0), W[(BX + 11) * C + j]
        al, ah = W[(BX + 12) * C + j], W[(BX + 13) * C + j]
        valid = ((sxl <= sxh) & (syl <= syh) & (stl <= sth) & (mxl <= mxh) & (myl <= myh)
                 & (rl <= rh) & (al <= ah))
        dxl, dxh = down(mxl - sxh), up(mxh - sxl)
        dyl, dyh = down(myl - syh), up(myh - syl)
        fl, fh = down(al + stl), up(ah + sth)
        wide = not ((fh - fl < TWO_PI_LO) & (-1e15 < fl) & (fh < 1e15))
        # the quadrants (dx, dy) meets: x >= 0 (q0, q1), x <= 0 (q2, q3), y >= 0 (q0, q3), y <= 0
        xp, xn = _mx(dxl, 0.0) <= dxh, _mx(-dxh, 0.0) <= -dxl
        yp, yn = _mx(dyl, 0.0) <= dyh, _mx(-dyh, 0.0) <= -dyl
        kc = np.floor(-0.5 * (fl + fh) * INV_TWO_PI_LO + 0.5)
        kc = 0.0 if wide else kc
        wn = -INF if wide else np.nan  # a wide bearing: copy K (= 0) is the whole line
        wp = INF if wide else np.nan
        l0, h0 = _copy(kc - 1.0, INF if wide else np.nan, -INF if wide else np.nan, fl, fh)
        l1, h1 = _copy(kc, wn, wp, fl, fh)
        l2, h2 = _copy(kc + 1.0, INF if wide else np.nan, -INF if wide else np.nan, fl, fh)
        cnt = 0
        qq, wl, wh = 0.0, 0.0, 0.0
        for qi in range(4):
            cl, ch = _arc(qi)
            qok = (xp if qi < 2 else xn) & (yp if (qi == 0 or qi == 3) else yn)
            for sl, sh in ((l0, h0), (l1, h1), (l2, h2)):
                pl = cl if cl > sl else sl
                ph = ch if ch < sh else sh
                meets = qok & (pl <= ph)
                cnt += 1 if meets else 0
                qq = float(qi) if meets else qq
                wl = pl if meets else wl
                wh = ph if meets else wh
        # the piece's psi (_to_psi)
        pl = wl if qq == 0.0 else (-wh if qq == 1.0 else (down(wl + PI_LO) if qq == 2.0 else down(PI_LO - wh)))
        ph = wh if qq == 0.0 else (-wl if qq == 1.0 else (up(wh + PI_HI) if qq == 2.0 else up(PI_HI - wl)))
        a = pl if pl > 0.0 else 0.0
        b = ph if ph < HALF_PI_HI else HALF_PI_HI
        one = valid & (cnt == 1) & (a <= b)
        xs = (qq == 0.0) | (qq == 1.0)
        ys = (qq == 0.0) | (qq == 3.0)
        ul, uh = _mx(dxl if xs else -dxh, 0.0), dxh if xs else -dxl
        vl, vh = _mx(dyl if ys else -dyh, 0.0), dyh if ys else -dyl
        W[UL * C + j], W[UH * C + j], W[VL * C + j], W[VH * C + j] = ul, uh, vl, vh
        W[RL * C + j], W[RH * C + j] = rl, rh
        W[SXL * C + j] = sxl if xs else -sxh
        W[SXH * C + j] = sxh if xs else -sxl
        W[MXL * C + j] = mxl if xs else -mxh
        W[MXH * C + j] = mxh if xs else -mxl
        W[SYL * C + j] = syl if ys else -syh
        W[SYH * C + j] = syh if ys else -syl
        W[MYL * C + j] = myl if ys else -myh
        W[MYH * C + j] = myh if ys else -myl
        W[OK * C + j] = 1.0 if one else 0.0
        W[QD * C + j] = qq
        W[PSL * C + j] = a if one else 0.0
        W[PSH * C + j] = b if one else HALF_PI_HI
        W[KD * C + j] = ONE if one else (MORE if valid & (cnt > 0) else NONE)


@njit(cache=True, error_model="numpy")
def _exit(s, nb, out, W, t0l, t0h, idx):
    """Rows ``s..s+nb-1`` from their lanes (final states in ``W``), as :func:`_finish` and
    :func:`_flush` give them for one piece: ``psi ∩= atan(t)``; then as selects (a SIMD loop)
    the periodic difference (``_meet3``), back from the quadrant frame, into ``W``'s box rows;
    the rare lanes outside ``_meet3``'s range take the scalar steps; then written out. Rows of
    kind ``NONE`` are emptied, rows of kind ``MORE`` left to the general path."""
    C = CHUNK
    psi_from_tangents(nb, W, t0l, t0h, W[PSL * C:(PSL + 1) * C], W[PSH * C:(PSH + 1) * C], idx)
    for i in range(nb):
        lo, hi, qi = W[PSL * C + i], W[PSH * C + i], W[QD * C + i]
        live = (W[KD * C + i] == ONE) & (W[OK * C + i] > 0.5) & (lo <= hi)
        # alpha ∩= phi - sth, sth ∩= phi - alpha (mod 2 pi), phi the world bearing of psi
        wl = lo if qi == 0.0 else (-hi if qi == 1.0 else (down(lo - PI_HI) if qi == 2.0 else down(PI_LO - hi)))
        wh = hi if qi == 0.0 else (-lo if qi == 1.0 else (up(hi - PI_LO) if qi == 2.0 else up(PI_HI - lo)))
        al, ah = W[(BX + 12) * C + i], W[(BX + 13) * C + i]
        stl, sth = W[(BX + 4) * C + i], W[(BX + 5) * C + i]
        nal, nah, ok1 = _meet3(al, ah, down(wl - sth), up(wh - stl))
        nsl, nsh, ok2 = _meet3(stl, sth, down(wl - nah), up(wh - nal))
        gok = ok1 & ok2 & (lo <= hi)
        # a lane outside _meet3's range keeps its angles here; the scalar steps below
        # contract them (and empty the row if they empty one) unless they are unbounded
        al, ah = (nal, nah) if gok else (al, ah)
        stl, sth = (nsl, nsh) if gok else (stl, sth)
        xp = (qi == 0.0) | (qi == 1.0)
        yp = (qi == 0.0) | (qi == 3.0)
        a, b = W[SXL * C + i], W[SXH * C + i]
        sxl, sxh = (a if xp else -b), (b if xp else -a)
        a, b = W[SYL * C + i], W[SYH * C + i]
        syl, syh = (a if yp else -b), (b if yp else -a)
        a, b = W[MXL * C + i], W[MXH * C + i]
        mxl, mxh = (a if xp else -b), (b if xp else -a)
        a, b = W[MYL * C + i], W[MYH * C + i]
        myl, myh = (a if yp else -b), (b if yp else -a)
        rl, rh = W[RL * C + i], W[RH * C + i]
        w = live & ((not gok) | ((al <= ah) & (stl <= sth))) & (sxl <= sxh)
        # an infinite bound of alpha or sth: angle_meet leaves both as they are
        finite = (al > -INF) & (ah < INF) & (stl > -INF) & (sth < INF)
        W[FX * C + i] = 1.0 if live & (not gok) & finite & (sxl <= sxh) else 0.0
        W[(BX + 0) * C + i], W[(BX + 1) * C + i] = (sxl if w else E), (sxh if w else F)
        W[(BX + 2) * C + i], W[(BX + 3) * C + i] = (syl if w else E), (syh if w else F)
        W[(BX + 4) * C + i], W[(BX + 5) * C + i] = (stl if w else E), (sth if w else F)
        W[(BX + 6) * C + i], W[(BX + 7) * C + i] = (mxl if w else E), (mxh if w else F)
        W[(BX + 8) * C + i], W[(BX + 9) * C + i] = (myl if w else E), (myh if w else F)
        W[(BX + 10) * C + i], W[(BX + 11) * C + i] = (rl if w else E), (rh if w else F)
        W[(BX + 12) * C + i], W[(BX + 13) * C + i] = (al if w else E), (ah if w else F)
    for i in range(nb):
        if W[FX * C + i] < 0.5:
            continue
        al, ah = W[(BX + 12) * C + i], W[(BX + 13) * C + i]
        stl, sth = W[(BX + 4) * C + i], W[(BX + 5) * C + i]
        wl, wh = _from_psi(int(W[QD * C + i]), W[PSL * C + i], W[PSH * C + i])
        dl, dh = sub(wl, wh, stl, sth)
        al, ah = _meet(al, ah, dl, dh)
        dl, dh = sub(wl, wh, al, ah)
        stl, sth = _meet(stl, sth, dl, dh)
        if (al <= ah) and (stl <= sth):
            W[(BX + 12) * C + i], W[(BX + 13) * C + i] = al, ah
            W[(BX + 4) * C + i], W[(BX + 5) * C + i] = stl, sth
        else:
            for r in range(7):
                W[(BX + 2 * r) * C + i], W[(BX + 2 * r + 1) * C + i] = E, F
    for v in range(7):
        a = out[v]
        r = (BX + 2 * v) * C
        for j in range(nb):
            keep = W[KD * C + j] == MORE
            a[2 * (s + j)] = a[2 * (s + j)] if keep else W[r + j]
            a[2 * (s + j) + 1] = a[2 * (s + j) + 1] if keep else W[r + C + j]


@njit(cache=True, error_model="numpy")
def _general_box(i, out, L, S, orig, rows, box, q, pl, ph, t0l, t0h, ang, acc, G, cnt):
    """Box ``i`` (kind ``MORE``): its pieces as lanes of the general buffers (``cnt`` holds their
    lane and box counts), contracted and hulled when the buffers are full."""
    C = CHUNK
    sxa, sya, sta, mxa, mya, rhoa, ala = out
    k = 2 * i
    sxl, sxh, syl, syh = sxa[k], sxa[k + 1], sya[k], sya[k + 1]
    stl, sth, mxl, mxh = sta[k], sta[k + 1], mxa[k], mxa[k + 1]
    myl, myh, rl, rh = mya[k], mya[k + 1], max(rhoa[k], 0.0), rhoa[k + 1]
    al, ah = ala[k], ala[k + 1]
    m, nb = cnt[0], cnt[1]
    dxl, dxh = sub(mxl, mxh, sxl, sxh)
    dyl, dyh = sub(myl, myh, syl, syh)
    fl, fh = add(al, ah, stl, sth)
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
    rows[nb] = i
    ang[nb, 0], ang[nb, 1], ang[nb, 2], ang[nb, 3] = al, ah, stl, sth
    for v in range(14):
        acc[nb, v] = E if v % 2 == 0 else F
    nb += 1
    if m + 12 > C:
        _flush(m, nb, rows, box, q, pl, ph, t0l, t0h, ang, acc, L, S, orig, out, G)
        m = 0
        nb = 0
    cnt[0], cnt[1] = m, nb


@njit(cache=True, error_model="numpy")
def _kernel(sx, sy, st, mx, my, rho, alpha):
    """Over seven flat ``[lo0, hi0, lo1, hi1, ...]`` arrays, a chunk of ``CHUNK`` boxes at a time:
    :func:`_entry`, the boxes of several pieces to :func:`_general_box`, the fixpoint of the
    one-piece lanes, :func:`_exit`."""
    n = sx.shape[0] // 2
    C = CHUNK
    out = (sx, sy, st, mx, my, rho, alpha)
    okm = np.empty(n, np.bool_)
    W = np.empty(WROWS * C)  # the one-piece lanes, slot = box of the chunk
    S = np.empty(ROWS * C)
    orig = np.empty(C, np.int64)
    t0l, t0h = np.empty(C), np.empty(C)
    pl, ph = W[PSL * C:(PSL + 1) * C], W[PSH * C:(PSH + 1) * C]
    # the general path's lanes (pieces of boxes of kind MORE)
    L2 = np.empty(ROWS * C)
    S2 = np.empty(ROWS * C)
    G2 = np.empty(5 * C)
    orig2 = np.empty(C, np.int64)
    rows = np.empty(C, np.int64)
    box = np.empty(C, np.int64)
    q2 = np.empty(C, np.int64)
    pl2, ph2, t0l2, t0h2 = np.empty(C), np.empty(C), np.empty(C), np.empty(C)
    ang = np.empty((C, 4))
    acc = np.empty((C, 14))
    cnt = np.zeros(2, np.int64)
    for s in range(0, n, C):
        nb = min(C, n - s)
        _entry(s, nb, out, W)
        for j in range(nb):
            if W[KD * C + j] == MORE:
                _general_box(s + j, out, L2, S2, orig2, rows, box, q2, pl2, ph2, t0l2, t0h2,
                             ang, acc, G2, cnt)
        _to_fixpoint(nb, W, S, orig, pl, ph, t0l, t0h, MAX_PASSES)
        _exit(s, nb, out, W, t0l, t0h, orig)
    if cnt[0] > 0:
        _flush(cnt[0], cnt[1], rows, box, q2, pl2, ph2, t0l2, t0h2, ang, acc, L2, S2, orig2, out,
               G2)
    for i in range(n):
        okm[i] = sx[2 * i] <= sx[2 * i + 1]
    return okm


def range_bearing_simd_kernel(sx, sy, sth, mx, my, rho, alpha):
    """In place over seven ``(N, 2)`` arrays; returns the mask of rows that stayed non-empty."""
    return in_place(lambda flat: _kernel(*flat), (sx, sy, sth, mx, my, rho, alpha))
