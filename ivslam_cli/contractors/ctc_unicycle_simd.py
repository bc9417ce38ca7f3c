"""Unicycle motion step contractor over structure-of-arrays chunks: the polar part as SIMD loops.

Same constraint and guarantee as :mod:`~ivslam_cli.contractors.ctc_unicycle` (the kinematic
model of the Guaranteed SLAM slides: ``x1 = x0 + v dt cos(th0) + qx``, ``y1 = y0 + v dt
sin(th0) + qy``, ``th1 = th0 + w dt + qth`` mod 2 pi): every solution in the input box is in
the output box, headings keep their branches.
:func:`~ivslam_cli.contractors.ctc_unicycle.unicycle_scalar` stays the reference;
tests/contractors/test_unicycle_simd.py compares the two.

Decomposition (Jaulin's contractor programming, as in the scalar kernel): the heading
``w dt + qth = th1 - th0`` (mod 2 pi), then the position ``(dx, dy) = s (cos th0, sin th0)``
with ``s = v dt``, ``dx = (x1 - x0) - qx``, ``dy = (y1 - y0) - qy``. A round contracts the
heading (scalar code, the same steps as ``unicycle_pass``), then splits the position part into
pieces: the sign of ``s`` (``s <= 0`` is the polar constraint on ``-s`` and ``th0 + pi``), the
closed quadrant of ``(dx, dy)``, and the copy of that quadrant's arc the bearing meets (the
solutions are the union of those of the pieces, so the hull of the pieces' contractions is
sound). Each piece is contracted by the fused branch-free loop of
:mod:`~ivslam_cli.contractors.ctc_range_bearing_simd` (the polar steps of
:mod:`~ivslam_cli.contractors.ctc_polar_simd` on ``(|dx|, |dy|, |s|, tan psi)`` with the
difference ``dx = a - q``), rounded outward with
:func:`~ivslam_cli.interval.rounding.down` / ``up``; on exit ``psi ∩= atan(t)`` gives ``th0``
back in its branch, ``s = v dt`` is contracted backward onto ``v, dt`` and ``a = x1 - x0``
onto ``x1, x0``. libm is called at most four times per piece and round.

Rounds repeat per box while one shrinks some width by at least ``RELATIVE_STOP`` (at most
``MAX_ROUNDS``, the scalar kernel's ``MAX_PASSES``): the coupling through ``dt`` and ``th0``
between the heading and the position is iterated as the scalar kernel iterates it. Both
kernels stop an iteration of sound contractions when it shrinks no width by ``RELATIVE_STOP``,
so neither result contains the other in general: tests/contractors/test_unicycle_simd.py
checks that no bound of this kernel is outside the scalar result by more than ``2
RELATIVE_STOP`` of the input width (of the scalar result's width where the input is unbounded)
plus rounding, and that the widths are on average no larger. A heading wider than
``MAX_TURNS`` turns (or unbounded) is not contracted by the position part.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_polar import _atan_hi, _atan_lo
from ivslam_cli.contractors.ctc_range_bearing_simd import (
    CHUNK,
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
    TH,
    TL,
    _arc,
    _flip,
    _from_psi,
    _lane,
    _meet,
    _meet3,
    _mn,
    _mx,
    _shift,
    _to_fixpoint,
    _to_psi,
)
from ivslam_cli.contractors.ctc_unicycle import MAX_PASSES as MAX_ROUNDS
from ivslam_cli.contractors.ctc_unicycle import RELATIVE_STOP, shrink
from ivslam_cli.interval.arith import (
    EMPTY_HI,
    EMPTY_LO,
    add,
    bwd_add,
    bwd_mul,
    inter,
    mul,
    sub,
)
from ivslam_cli.interval.rounding import INV_TWO_PI_HI, INV_TWO_PI_LO, PI_HI, PI_LO, TWO_PI_LO, down, up

E = EMPTY_LO
F = EMPTY_HI
PASSES = 16  # at most this many fused passes per piece and round
BLOCK = 64  # boxes contracted together, round after round
MAX_TURNS = 3.0  # a heading wider than 3 turns is not contracted by the position part
PIECES = 56  # at most 2 signs x 4 quadrants x 7 copies per box
# the 24 bounds of a box, in the order of unicycle_scalar
X0, Y0, T0, X1, Y1, T1, V, W, DT, QX, QY, QT = range(0, 24, 2)


@njit(cache=True, inline="always")
def _angle_difference(al, ah, bl, bh, cl, ch):
    """``angle_difference_scalar`` (``a = b - c`` mod 2 pi), the same bounds (``_meet``)."""
    if not (al <= ah and bl <= bh and cl <= ch):
        return E, F, E, F, E, F
    dl, dh = sub(bl, bh, cl, ch)
    al, ah = _meet(al, ah, dl, dh)
    if not (al <= ah):
        return E, F, E, F, E, F
    dl, dh = add(al, ah, cl, ch)
    bl, bh = _meet(bl, bh, dl, dh)
    if not (bl <= bh):
        return E, F, E, F, E, F
    dl, dh = sub(bl, bh, al, ah)
    cl, ch = _meet(cl, ch, dl, dh)
    if not (cl <= ch):
        return E, F, E, F, E, F
    return al, ah, bl, bh, cl, ch


@njit(cache=True)
def _heading(b, j):
    """The heading block of ``unicycle_pass`` on row ``j`` of ``b``; False if it empties."""
    pl, ph = mul(b[j, W], b[j, W + 1], b[j, DT], b[j, DT + 1])
    ul, uh = add(pl, ph, b[j, QT], b[j, QT + 1])
    r = _angle_difference(ul, uh, b[j, T1], b[j, T1 + 1], b[j, T0], b[j, T0 + 1])
    ul, uh = r[0], r[1]
    if not (ul <= uh):
        return False
    b[j, T1], b[j, T1 + 1], b[j, T0], b[j, T0 + 1] = r[2], r[3], r[4], r[5]
    pl, ph, ql, qh = bwd_add(ul, uh, pl, ph, b[j, QT], b[j, QT + 1])
    wl, wh, dl, dh = bwd_mul(pl, ph, b[j, W], b[j, W + 1], b[j, DT], b[j, DT + 1])
    if not (ql <= qh) or not (wl <= wh) or not (dl <= dh):
        return False
    b[j, QT], b[j, QT + 1], b[j, W], b[j, W + 1], b[j, DT], b[j, DT + 1] = ql, qh, wl, wh, dl, dh
    return True


# rows of the heading buffer H (boxes of a block as structure of arrays)
HWL, HWH, HDL, HDH, HQL, HQH, H1L, H1H, H0L, H0H, HPL, HPH, HUL, HUH, HOK = range(15)


@njit(cache=True, inline="always", error_model="numpy")
def _prod(a, c):
    return 0.0 if (a == 0.0) | (c == 0.0) else a * c


@njit(cache=True, error_model="numpy")
def _headings_simd(nb, H):
    """The heading block of ``unicycle_pass`` up to ``bwd_add``, for boxes ``0..nb-1`` of ``H``,
    as selects (a SIMD loop): the same float operations as ``mul``, ``add``, ``_angle_difference``
    (with ``_meet3``) and ``bwd_add`` on non-empty inputs. ``H[HOK]``: 1 if the results hold, 0
    if the box is emptied, -1 if ``_meet3`` does not apply (the scalar steps are then needed)."""
    B = BLOCK
    for j in range(nb):
        wl, wh, dl, dh = H[HWL * B + j], H[HWH * B + j], H[HDL * B + j], H[HDH * B + j]
        ql, qh = H[HQL * B + j], H[HQH * B + j]
        t1l, t1h, t0l, t0h = H[H1L * B + j], H[H1H * B + j], H[H0L * B + j], H[H0H * B + j]
        p1, p2, p3, p4 = _prod(wl, dl), _prod(wl, dh), _prod(wh, dl), _prod(wh, dh)
        pl = down(min(min(p1, p2), min(p3, p4)))
        ph = up(max(max(p1, p2), max(p3, p4)))
        ul, uh = down(pl + ql), up(ph + qh)
        ul, uh, ok1 = _meet3(ul, uh, down(t1l - t0h), up(t1h - t0l))
        t1l, t1h, ok2 = _meet3(t1l, t1h, down(ul + t0l), up(uh + t0h))
        t0l, t0h, ok3 = _meet3(t0l, t0h, down(t1l - uh), up(t1h - ul))
        # bwd_add(u, p, qth): p ∩= u - qth, qth ∩= u - p
        pl, ph = _mx(pl, down(ul - qh)), _mn(ph, up(uh - ql))
        ql, qh = _mx(ql, down(ul - ph)), _mn(qh, up(uh - pl))
        good = (ul <= uh) & (t1l <= t1h) & (t0l <= t0h) & (pl <= ph) & (ql <= qh)
        H[H1L * B + j], H[H1H * B + j], H[H0L * B + j], H[H0H * B + j] = t1l, t1h, t0l, t0h
        H[HPL * B + j], H[HPH * B + j], H[HQL * B + j], H[HQH * B + j] = pl, ph, ql, qh
        H[HOK * B + j] = (1.0 if good else 0.0) if (ok1 & ok2 & ok3) else -1.0


@njit(cache=True)
def _headings(nb, b, active, H, res):
    """``res[j] = _heading(b, j)`` for the active boxes, the same bounds, mostly as a SIMD loop."""
    B = BLOCK
    for j in range(nb):
        H[HWL * B + j], H[HWH * B + j], H[HDL * B + j], H[HDH * B + j] = b[j, W], b[j, W + 1], b[j, DT], b[j, DT + 1]
        H[HQL * B + j], H[HQH * B + j] = b[j, QT], b[j, QT + 1]
        H[H1L * B + j], H[H1H * B + j], H[H0L * B + j], H[H0H * B + j] = b[j, T1], b[j, T1 + 1], b[j, T0], b[j, T0 + 1]
    _headings_simd(nb, H)
    for j in range(nb):
        if not active[j]:
            continue
        ok = H[HOK * B + j]
        if ok < -0.5:
            res[j] = _heading(b, j)
            continue
        if ok < 0.5:
            res[j] = False
            continue
        wl, wh, dl, dh = bwd_mul(H[HPL * B + j], H[HPH * B + j], b[j, W], b[j, W + 1], b[j, DT], b[j, DT + 1])
        if not (wl <= wh) or not (dl <= dh):
            res[j] = False
            continue
        b[j, T1], b[j, T1 + 1], b[j, T0], b[j, T0 + 1] = H[H1L * B + j], H[H1H * B + j], H[H0L * B + j], H[H0H * B + j]
        b[j, QT], b[j, QT + 1] = H[HQL * B + j], H[HQH * B + j]
        b[j, W], b[j, W + 1], b[j, DT], b[j, DT + 1] = wl, wh, dl, dh
        res[j] = True


@njit(cache=True)
def _pieces(b, j, L, m, box, q, kk, sg, pl, ph):
    """Lanes from row ``j`` of ``b`` from slot ``m`` on; returns the new lane count."""
    sl, sh = mul(b[j, V], b[j, V + 1], b[j, DT], b[j, DT + 1])
    axl, axh = sub(b[j, X1], b[j, X1 + 1], b[j, X0], b[j, X0 + 1])
    ayl, ayh = sub(b[j, Y1], b[j, Y1 + 1], b[j, Y0], b[j, Y0 + 1])
    qxl, qxh, qyl, qyh = b[j, QX], b[j, QX + 1], b[j, QY], b[j, QY + 1]
    dxl, dxh = sub(axl, axh, qxl, qxh)
    dyl, dyh = sub(ayl, ayh, qyl, qyh)
    for br in range(2):
        sgn = 1.0 if br == 0 else -1.0
        if (br == 0 and not (sh >= 0.0)) or (br == 1 and not (sl <= 0.0)):
            continue
        rl, rh = _flip(sgn, sl, sh)
        rl = max(rl, 0.0)
        fl, fh = b[j, T0], b[j, T0 + 1]
        if br == 1:
            fl, fh = add(fl, fh, PI_LO, PI_HI)
        wide = not (fh - fl < MAX_TURNS * TWO_PI_LO and -1e15 < fl and fh < 1e15)
        for qq in range(4):
            xs = 1.0 if (qq == 0 or qq == 1) else -1.0
            ys = 1.0 if (qq == 0 or qq == 3) else -1.0
            ul, uh = _flip(xs, dxl, dxh)
            vl, vh = _flip(ys, dyl, dyh)
            ul, vl = max(ul, 0.0), max(vl, 0.0)
            if not (ul <= uh and vl <= vh):
                continue
            cl, ch = _arc(qq)
            # copies f + 2 k pi meeting the arc: k in [(cl - fh) / 2 pi, (ch - fl) / 2 pi], +-1
            k0 = 0.0 if wide else float(np.floor((cl - fh) * INV_TWO_PI_LO)) - 1.0
            nk = 1 if wide else int((ch - fl) * INV_TWO_PI_HI - (k0 + 1.0)) + 3
            for dk in range(nk):
                wl, wh = (cl, ch) if wide else inter(cl, ch, *_shift(fl, fh, k0 + dk))
                a, c = _to_psi(qq, wl, wh) if wl <= wh else (E, F)
                if not (a <= c):
                    continue
                _lane(L, m, ul, uh, vl, vh, rl, rh, xs, ys, qxl, qxh, axl, axh, qyl, qyh, ayl, ayh)
                box[m], q[m], pl[m], ph[m], sg[m] = j, qq, a, c, sgn
                kk[m] = np.nan if wide else k0 + dk
                m += 1
    return m


@njit(cache=True, error_model="numpy")
def _finish(n, D, b, acc, box, q, kk, sg, pl, ph, t0l, t0h):
    """Lanes ``0..n-1`` done (state in ``D``): back to the box's variables, hull into ``acc``."""
    C = CHUNK
    for i in range(n):
        if D[TL * C + i] != t0l[i]:
            pl[i] = max(pl[i], _atan_lo(D[TL * C + i]))
    for i in range(n):
        if D[TH * C + i] != t0h[i]:
            ph[i] = min(ph[i], _atan_hi(D[TH * C + i]))
    for i in range(n):
        if D[OK * C + i] < 0.5 or not (pl[i] <= ph[i]):
            continue
        j = box[i]
        tl, th = b[j, T0], b[j, T0 + 1]
        if kk[i] == kk[i]:  # the bearing's copy is known: th0 from psi
            wl, wh = _from_psi(q[i], pl[i], ph[i])
            wl, wh = _shift(wl, wh, -kk[i])
            if sg[i] < 0.0:
                wl, wh = sub(wl, wh, PI_LO, PI_HI)
            tl, th = inter(tl, th, wl, wh)
            if not (tl <= th):
                continue
        xs = 1.0 if (q[i] == 0 or q[i] == 1) else -1.0
        ys = 1.0 if (q[i] == 0 or q[i] == 3) else -1.0
        sl, sh = _flip(sg[i], D[RL * C + i], D[RH * C + i])
        vl, vh, dl, dh = bwd_mul(sl, sh, b[j, V], b[j, V + 1], b[j, DT], b[j, DT + 1])
        if not (vl <= vh):
            continue
        qxl, qxh = _flip(xs, D[SXL * C + i], D[SXH * C + i])
        axl, axh = _flip(xs, D[MXL * C + i], D[MXH * C + i])
        qyl, qyh = _flip(ys, D[SYL * C + i], D[SYH * C + i])
        ayl, ayh = _flip(ys, D[MYL * C + i], D[MYH * C + i])
        x1l, x1h = inter(b[j, X1], b[j, X1 + 1], *add(axl, axh, b[j, X0], b[j, X0 + 1]))
        x0l, x0h = inter(b[j, X0], b[j, X0 + 1], *sub(x1l, x1h, axl, axh))
        y1l, y1h = inter(b[j, Y1], b[j, Y1 + 1], *add(ayl, ayh, b[j, Y0], b[j, Y0 + 1]))
        y0l, y0h = inter(b[j, Y0], b[j, Y0 + 1], *sub(y1l, y1h, ayl, ayh))
        if not (x1l <= x1h and x0l <= x0h and y1l <= y1h and y0l <= y0h):
            continue
        r = (x0l, x0h, y0l, y0h, tl, th, x1l, x1h, y1l, y1h, b[j, T1], b[j, T1 + 1],
             vl, vh, b[j, W], b[j, W + 1], dl, dh, qxl, qxh, qyl, qyh, b[j, QT], b[j, QT + 1])
        for k in range(0, 24, 2):
            acc[j, k] = min(acc[j, k], r[k])
            acc[j, k + 1] = max(acc[j, k + 1], r[k + 1])


@njit(cache=True, error_model="numpy")
def _flush(n, L, D, orig, b, acc, box, q, kk, sg, pl, ph, t0l, t0h):
    """Contract the ``n`` lanes to their fixpoint (``ctc_range_bearing_simd._to_fixpoint``)."""
    _to_fixpoint(n, L, D, orig, pl, ph, t0l, t0h, PASSES)
    _finish(n, D, b, acc, box, q, kk, sg, pl, ph, t0l, t0h)


@njit(cache=True, error_model="numpy")
def _block(b, nb):
    """Contract the ``nb`` boxes of ``b`` (rows of 24 bounds) in place, round after round."""
    C = CHUNK
    L = np.empty(ROWS * C)
    D = np.empty(ROWS * C)
    orig = np.empty(C, np.int64)
    box = np.empty(C, np.int64)
    q = np.empty(C, np.int64)
    kk, sg, pl, ph = np.empty(C), np.empty(C), np.empty(C), np.empty(C)
    t0l, t0h = np.empty(C), np.empty(C)
    acc = np.empty((nb, 24))
    last = np.empty((nb, 4))  # th0, dt after each box's last position part
    active = np.ones(nb, np.bool_)
    H = np.empty(15 * BLOCK)
    hres = np.zeros(nb, np.bool_)
    for j in range(nb):
        for k in range(12):
            if not (b[j, 2 * k] <= b[j, 2 * k + 1]):
                active[j] = False
        if not active[j]:
            for k in range(24):
                b[j, k] = E if k % 2 == 0 else F
    for rnd in range(MAX_ROUNDS):
        m = 0
        _headings(nb, b, active, H, hres)
        for j in range(nb):
            if not active[j]:
                continue
            for k in range(24):
                acc[j, k] = E if k % 2 == 0 else F
            if not hres[j]:
                continue
            if (rnd > 0 and b[j, T0] == last[j, 0] and b[j, T0 + 1] == last[j, 1]
                    and b[j, DT] == last[j, 2] and b[j, DT + 1] == last[j, 3]):
                # the position part would get its own last output again: nothing to redo
                for k in range(24):
                    acc[j, k] = b[j, k]
                continue
            m = _pieces(b, j, L, m, box, q, kk, sg, pl, ph)
            if m + PIECES > C:
                _flush(m, L, D, orig, b, acc, box, q, kk, sg, pl, ph, t0l, t0h)
                m = 0
        if m > 0:
            _flush(m, L, D, orig, b, acc, box, q, kk, sg, pl, ph, t0l, t0h)
        more = False
        for j in range(nb):
            if not active[j]:
                continue
            if not (acc[j, 0] <= acc[j, 1]):
                for k in range(24):
                    b[j, k] = E if k % 2 == 0 else F
                active[j] = False
                continue
            progress = 0.0
            for k in range(0, 24, 2):
                progress = max(progress, shrink(b[j, k], b[j, k + 1], acc[j, k], acc[j, k + 1]))
            for k in range(24):
                b[j, k] = acc[j, k]
            last[j, 0], last[j, 1], last[j, 2], last[j, 3] = b[j, T0], b[j, T0 + 1], b[j, DT], b[j, DT + 1]
            active[j] = progress >= RELATIVE_STOP
            more |= active[j]
        if not more:
            break


@njit(cache=True, error_model="numpy")
def _kernel(arrs):
    n = arrs[0].shape[0]
    ok = np.empty(n, np.bool_)
    b = np.empty((BLOCK, 24))
    for s in range(0, n, BLOCK):
        nb = min(BLOCK, n - s)
        for j in range(nb):
            for v in range(12):
                b[j, 2 * v], b[j, 2 * v + 1] = arrs[v][s + j, 0], arrs[v][s + j, 1]
        _block(b, nb)
        for j in range(nb):
            for v in range(12):
                arrs[v][s + j, 0], arrs[v][s + j, 1] = b[j, 2 * v], b[j, 2 * v + 1]
            ok[s + j] = b[j, 0] <= b[j, 1]
    return ok


def unicycle_simd_kernel(x0, y0, th0, x1, y1, th1, v, w, dt, qx, qy, qth):
    """In place over twelve ``(N, 2)`` arrays; returns the mask of rows that stayed non-empty."""
    return _kernel((x0, y0, th0, x1, y1, th1, v, w, dt, qx, qy, qth))
