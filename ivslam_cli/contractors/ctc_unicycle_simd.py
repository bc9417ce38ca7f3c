"""Unicycle motion step contractor over structure-of-arrays slots: every stage a SIMD loop.

Same constraint and guarantee as :mod:`~ivslam_cli.contractors.ctc_unicycle` (the kinematic
model of the Guaranteed SLAM slides: ``x1 = x0 + v dt cos(th0) + qx``, ``y1 = y0 + v dt
sin(th0) + qy``, ``th1 = th0 + w dt + qth`` mod 2 pi): every solution in the input box is in
the output box, headings keep their branches.
:func:`~ivslam_cli.contractors.ctc_unicycle.unicycle_scalar` stays the reference;
tests/contractors/test_unicycle_simd.py compares the two.

Decomposition (Jaulin's contractor programming, as in the scalar kernel): the heading
``w dt + qth = th1 - th0`` (mod 2 pi), then the position ``(dx, dy) = s (cos th0, sin th0)``
with ``s = v dt``, ``dx = (x1 - x0) - qx``, ``dy = (y1 - y0) - qy``. A round contracts the
heading (the steps of ``unicycle_pass``), then splits the position part into pieces: the sign
of ``s`` (``s <= 0`` is the polar constraint on ``-s`` and ``th0 + pi``), the closed quadrant
of ``(dx, dy)``, and the copy of that quadrant's arc the heading meets (the solutions are the
union of those of the pieces, so the hull of the pieces' contractions is sound). Each piece is
contracted by the fused branch-free loop of
:mod:`~ivslam_cli.contractors.simd_polar_lanes` (the polar steps on ``(|dx|, |dy|, |s|,
tan psi)`` with the difference ``dx = a - q``), rounded outward with
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

Execution: ``NB`` slots hold boxes in flight (:mod:`~ivslam_cli.contractors.unicycle_slots`),
each at its own round; a slot whose box is done writes it out and takes the next one, so every
pass over the slots works on live boxes. A pass is: the heading of every slot as selects
(:func:`~ivslam_cli.contractors.unicycle_heading._heading_step`: the interval operations in
select form, ``mul_s``, ``bwd_mul_s``, ``_meet1t``; the headings outside the one-copy meet's
range packed and taken by ``angle_meet``'s scans as selects, the rare rest by the scalar
``_heading``); the boxes whose round ends there (their position part would be ``KEEP``
and the heading shrank no width by ``RELATIVE_STOP``: :func:`_finish_kept`, most second
rounds) written out, their slots' new boxes taking their heading step at once; the plan of the
position part (:func:`_plan`: a box with at most two
pieces and a heading narrower than 4.7 has them found by selects, any other by
:func:`_pieces`); the lanes built (scalar, a few stores each), contracted to their fixpoint,
taken back to their boxes (:func:`_exit`, selects) and hulled per box; the end of the round
(:func:`_progress`, selects). The bounds are those of the per-box kernel of the scalar steps
this replaced, bit for bit (the same operations in the same order, per box).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.simd_polar_lanes import (
    psi_from_tangents,
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
    UH,
    UL,
    VH,
    VL,
    _flip,
    _lane,
    _mx,
    _to_fixpoint,
    in_place,
)
from ivslam_cli.contractors.simd_quadrants import _arc, _shift, _to_psi
from ivslam_cli.contractors.unicycle_heading import HROWS, _heading_step, _shifted
from ivslam_cli.contractors.unicycle_slots import (  # the slot buffer's layout and rows
    ACC,
    AXH,
    AXL,
    AYH,
    AYL,
    BROWS,
    DT,
    DXH,
    DXL,
    DYH,
    DYL,
    GEN,
    HOK,
    KEEP,
    LDTH,
    LDTL,
    LIVE,
    LT0H,
    LT0L,
    NB,
    NEED,
    NOTHING,
    NPC,
    PC,
    POS,
    QT,
    QX,
    QY,
    RND,
    SH_,
    SIMD,
    SL_,
    T0,
    T1,
    X0,
    X1,
    Y0,
    Y1,
    V,
    W,
    _finish_kept,
    _load,
    _progress,
    _swap,
)
from ivslam_cli.interval.arith import (
    EMPTY_HI,
    EMPTY_LO,
    add,
    inter,
    mul,
    sub,
)
from ivslam_cli.interval.arith_select import bwd_mul_s, mul_s
from ivslam_cli.interval.rounding import (
    HALF_PI_HI,
    INV_TWO_PI_HI,
    INV_TWO_PI_LO,
    PI_HI,
    PI_LO,
    TWO_PI_LO,
    down,
    up,
)

E = EMPTY_LO
F = EMPTY_HI
PASSES = 16  # at most this many fused passes per piece and round
MAX_TURNS = 3.0  # a heading wider than 3 turns is not contracted by the position part
PIECES = 56  # at most 2 signs x 4 quadrants x 7 copies per box




# rows of the lane buffer L after the lane state (ROWS rows, packed during the fixpoint), each
# lane at its slot: its piece; the bounds of its box that its way back reads (copied in when
# the lane is built, so that the loop of _exit reads and writes L only: a SIMD loop); what the
# lane gives the box
MQ, MKK, MSG, MPL, MPH, MT0L, MT0H, MV = (ROWS + k for k in range(8))
MB = ROWS + 8  # 14 rows: th0 v dt x0 x1 y0 y1 of the box (lo, hi), in that order
MR = MB + 14  # 18 rows: x0 y0 th0 x1 y1 v dt qx qy (lo, hi), as the lane contracts them
LROWS = MR + 18



@njit(cache=True)
def _pieces(b, slot, L, m, box):
    """Lanes from the box in row 0 of ``b`` (the bounds of slot ``slot``) from lane ``m`` on;
    returns the new lane count."""
    C = CHUNK
    j = 0
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
                box[m] = slot
                L[MQ * C + m], L[MPL * C + m], L[MPH * C + m], L[MSG * C + m] = qq, a, c, sgn
                L[MKK * C + m] = np.nan if wide else k0 + dk
                for r, v in enumerate((T0, V, DT, X0, X1, Y0, Y1)):  # MB's 14 rows
                    L[(MB + 2 * r) * C + m], L[(MB + 2 * r + 1) * C + m] = b[0, v], b[0, v + 1]
                m += 1
    return m






@njit(cache=True, inline="always", error_model="numpy")
def _psi_s(q, wl, wh):
    """:func:`_to_psi` as selects (``q`` a float), ∩ ``[0, pi/2]``."""
    pl = wl if q == 0.0 else (-wh if q == 1.0 else (
        down(wl + PI_LO) if q == 2.0 else down(PI_LO - wh)))
    ph = wh if q == 0.0 else (-wl if q == 1.0 else (
        up(wh + PI_HI) if q == 2.0 else up(PI_HI - wl)))
    return (pl if pl > 0.0 else 0.0), (ph if ph < HALF_PI_HI else HALF_PI_HI)


@njit(cache=True, error_model="numpy")
def _plan(B):
    """The position part of each live slot's round, as selects (a SIMD loop). ``B[POS]`` is
    ``NOTHING`` (the heading emptied the box), ``KEEP`` (``th0`` and ``dt`` as after the slot's
    last position part, which would give its own output again), ``SIMD`` (``B[NPC]`` pieces,
    at most two, in the ``PC`` rows) or ``GEN`` (a heading wider than 4.7 or more pieces:
    :func:`_pieces`). The pieces are those :func:`_pieces` finds: only one copy of a heading
    narrower than 4.7 (bounds below 1e6 in magnitude) can meet a quadrant's arc: the one whose
    midpoint is nearest to the arc's centre (a meeting copy's midpoint is within ``w / 2 +
    pi / 4 < 3.136`` of that centre, the next copy's at least ``pi`` away, up to roundings
    below 1e-9), and a copy meeting the arc gives a non-empty ψ (checked).
    Also ``s``, ``dx``, ``dy``, ``x1 - x0``, ``y1 - y0``, and the round's hull: the box for
    ``KEEP``, empty otherwise."""
    N = NB
    for j in range(N):
        x0l, x0h, y0l, y0h = B[X0 * N + j], B[(X0 + 1) * N + j], B[Y0 * N + j], B[(Y0 + 1) * N + j]
        x1l, x1h, y1l, y1h = B[X1 * N + j], B[(X1 + 1) * N + j], B[Y1 * N + j], B[(Y1 + 1) * N + j]
        t0l, t0h = B[T0 * N + j], B[(T0 + 1) * N + j]
        vl, vh, dl, dh = B[V * N + j], B[(V + 1) * N + j], B[DT * N + j], B[(DT + 1) * N + j]
        qxl, qxh, qyl, qyh = B[QX * N + j], B[(QX + 1) * N + j], B[QY * N + j], B[(QY + 1) * N + j]
        sl, sh = mul_s(vl, vh, dl, dh)
        axl, axh = down(x1l - x0h), up(x1h - x0l)
        ayl, ayh = down(y1l - y0h), up(y1h - y0l)
        dxl, dxh = down(axl - qxh), up(axh - qxl)
        dyl, dyh = down(ayl - qyh), up(ayh - qyl)
        # the signs of s: s >= 0 with the heading th0, s <= 0 with th0 + pi
        f1l, f1h = down(t0l + PI_LO), up(t0h + PI_HI)
        # (one copy of each quadrant's arc can meet a heading narrower than 4.7: _plan)
        n0 = (t0h - t0l < 4.7) & (-1e6 < t0l) & (t0h < 1e6)
        n1 = (f1h - f1l < 4.7) & (-1e6 < f1l) & (f1h < 1e6)
        # the quadrants (dx, dy) meets: x >= 0 (q0, q1), x <= 0 (q2, q3), y >= 0 (q0, q3), y <= 0
        xp, xn = _mx(dxl, 0.0) <= dxh, _mx(-dxh, 0.0) <= -dxl
        yp, yn = _mx(dyl, 0.0) <= dyh, _mx(-dyh, 0.0) <= -dyl
        f0p, f1p = sh >= 0.0, sl <= 0.0
        cnt = 0
        g1, q1, c1, l1, h1 = 0.0, 0.0, 0.0, 0.0, 0.0
        g2, q2, c2, l2, h2 = 0.0, 0.0, 0.0, 0.0, 0.0
        for br in range(2):
            sgn = 1.0 if br == 0 else -1.0
            brok = f0p if br == 0 else f1p
            nb_ = n0 if br == 0 else n1
            fl = t0l if br == 0 else f1l
            fh = t0h if br == 0 else f1h
            mid = 0.5 * (fl + fh)
            for qi in range(4):
                cl, ch = _arc(qi)
                # the copy of the heading whose midpoint is nearest to the arc's centre
                k = np.floor((0.5 * (cl + ch) - mid) * INV_TWO_PI_LO + 0.5)
                k = k if nb_ else 0.0
                wl0, wh0 = _shifted(k, fl, fh)
                qok = (xp if qi < 2 else xn) & (yp if (qi == 0 or qi == 3) else yn)
                wl = cl if cl > wl0 else wl0
                wh = ch if ch < wh0 else wh0
                meets = brok & qok & (wl <= wh)
                first = meets & (cnt == 0)
                second = meets & (cnt == 1)
                g1 = sgn if first else g1
                q1 = float(qi) if first else q1
                c1 = k if first else c1
                l1 = wl if first else l1
                h1 = wh if first else h1
                g2 = sgn if second else g2
                q2 = float(qi) if second else q2
                c2 = k if second else c2
                l2 = wl if second else l2
                h2 = wh if second else h2
                cnt += 1 if meets else 0
        a1, b1 = _psi_s(q1, l1, h1)
        a2, b2 = _psi_s(q2, l2, h2)
        simd = (n0 | (not f0p)) & (n1 | (not f1p)) & (cnt <= 2)
        simd = simd & ((cnt < 1) | (a1 <= b1)) & ((cnt < 2) | (a2 <= b2))
        keep = (B[RND * N + j] > 0.5) & (t0l == B[LT0L * N + j]) & (t0h == B[LT0H * N + j])
        keep = keep & (dl == B[LDTL * N + j]) & (dh == B[LDTH * N + j])
        pos = (KEEP if keep else (SIMD if simd else GEN)) if B[HOK * N + j] > 0.5 else NOTHING
        pos = pos if B[LIVE * N + j] > 0.5 else NOTHING
        B[POS * N + j] = pos
        B[NPC * N + j] = float(cnt)
        B[PC * N + j], B[(PC + 1) * N + j], B[(PC + 2) * N + j] = g1, q1, c1
        B[(PC + 3) * N + j], B[(PC + 4) * N + j] = a1, b1
        B[(PC + 5) * N + j], B[(PC + 6) * N + j], B[(PC + 7) * N + j] = g2, q2, c2
        B[(PC + 8) * N + j], B[(PC + 9) * N + j] = a2, b2
        B[SL_ * N + j], B[SH_ * N + j] = sl, sh
        B[DXL * N + j], B[DXH * N + j], B[DYL * N + j], B[DYH * N + j] = dxl, dxh, dyl, dyh
        B[AXL * N + j], B[AXH * N + j], B[AYL * N + j], B[AYH * N + j] = axl, axh, ayl, ayh
    for r in range(24):
        for j in range(N):
            keep = B[POS * N + j] == KEEP
            B[(ACC + r) * N + j] = B[r * N + j] if keep else (E if r % 2 == 0 else F)


@njit(cache=True, error_model="numpy")
def _simd_lanes(B, L, box, idx):
    """Lanes ``0..m-1`` from the pieces of the ``SIMD`` slots (as :func:`_pieces` builds them,
    slot by slot, piece by piece); returns ``m``. The list of (slot, piece) is packed first
    (``idx``: ``2 j + t``, no branch), then the lanes are filled by a loop of gathers and
    selects. At most ``2 NB <= CHUNK`` lanes."""
    N = NB
    C = CHUNK
    m = 0
    for j in range(N):
        simd = B[POS * N + j] == SIMD
        npc = B[NPC * N + j]
        idx[m] = 2 * j
        m += 1 if simd & (npc > 0.5) else 0
        idx[m] = 2 * j + 1
        m += 1 if simd & (npc > 1.5) else 0
    for k in range(m):
        j = idx[k] >> 1
        p = PC + 5 * (idx[k] & 1)
        sgn, qq, kk = B[p * N + j], B[(p + 1) * N + j], B[(p + 2) * N + j]
        a, c = B[(p + 3) * N + j], B[(p + 4) * N + j]
        s0, s1 = B[SL_ * N + j], B[SH_ * N + j]
        rl, rh = (s0 if sgn > 0.0 else -s1), (s1 if sgn > 0.0 else -s0)
        xp = (qq == 0.0) | (qq == 1.0)
        yp = (qq == 0.0) | (qq == 3.0)
        d0, d1 = B[DXL * N + j], B[DXH * N + j]
        ul, uh = (d0 if xp else -d1), (d1 if xp else -d0)
        d0, d1 = B[DYL * N + j], B[DYH * N + j]
        vl, vh = (d0 if yp else -d1), (d1 if yp else -d0)
        L[UL * C + k], L[UH * C + k] = _mx(ul, 0.0), uh
        L[VL * C + k], L[VH * C + k] = _mx(vl, 0.0), vh
        L[RL * C + k], L[RH * C + k] = _mx(rl, 0.0), rh
        L[OK * C + k] = 1.0
        d0, d1 = B[QX * N + j], B[(QX + 1) * N + j]
        L[SXL * C + k], L[SXH * C + k] = (d0 if xp else -d1), (d1 if xp else -d0)
        d0, d1 = B[AXL * N + j], B[AXH * N + j]
        L[MXL * C + k], L[MXH * C + k] = (d0 if xp else -d1), (d1 if xp else -d0)
        d0, d1 = B[QY * N + j], B[(QY + 1) * N + j]
        L[SYL * C + k], L[SYH * C + k] = (d0 if yp else -d1), (d1 if yp else -d0)
        d0, d1 = B[AYL * N + j], B[AYH * N + j]
        L[MYL * C + k], L[MYH * C + k] = (d0 if yp else -d1), (d1 if yp else -d0)
        box[k] = j
        L[MQ * C + k], L[MPL * C + k], L[MPH * C + k], L[MSG * C + k] = qq, a, c, sgn
        L[MKK * C + k] = kk
        L[(MB + 0) * C + k] = B[(T0) * N + j]
        L[(MB + 1) * C + k] = B[(T0 + 1) * N + j]
        L[(MB + 2) * C + k] = B[(V) * N + j]
        L[(MB + 3) * C + k] = B[(V + 1) * N + j]
        L[(MB + 4) * C + k] = B[(DT) * N + j]
        L[(MB + 5) * C + k] = B[(DT + 1) * N + j]
        L[(MB + 6) * C + k] = B[(X0) * N + j]
        L[(MB + 7) * C + k] = B[(X0 + 1) * N + j]
        L[(MB + 8) * C + k] = B[(X1) * N + j]
        L[(MB + 9) * C + k] = B[(X1 + 1) * N + j]
        L[(MB + 10) * C + k] = B[(Y0) * N + j]
        L[(MB + 11) * C + k] = B[(Y0 + 1) * N + j]
        L[(MB + 12) * C + k] = B[(Y1) * N + j]
        L[(MB + 13) * C + k] = B[(Y1 + 1) * N + j]
    return m


@njit(cache=True, error_model="numpy")
def _exit(n, L, idx):
    """Lanes ``0..n-1`` done (final states in ``L``): ``psi ∩= atan(t)``; then as selects (a
    SIMD loop) back to the box's variables (``th0`` from ψ in its copy, ``s = v dt`` backward,
    ``x1 = x0 + (x1 - x0)``) into the ``MR`` rows; ``L[MV]``
    is 1 where the lane gives the box something."""
    C = CHUNK
    psi_from_tangents(n, L, L[MT0L * C:(MT0L + 1) * C], L[MT0H * C:(MT0H + 1) * C],
                      L[MPL * C:(MPL + 1) * C], L[MPH * C:(MPH + 1) * C], idx)
    for i in range(n):
        qq, k, sgn = L[MQ * C + i], L[MKK * C + i], L[MSG * C + i]
        lo, hi = L[MPL * C + i], L[MPH * C + i]
        ok = (L[OK * C + i] > 0.5) & (lo <= hi)
        # th0 from psi (_from_psi, _shift by -k, minus pi when reversing), where k is known
        wl = lo if qq == 0.0 else (-hi if qq == 1.0 else (
            down(lo - PI_HI) if qq == 2.0 else down(PI_LO - hi)))
        wh = hi if qq == 0.0 else (-lo if qq == 1.0 else (
            up(hi - PI_LO) if qq == 2.0 else up(PI_HI - lo)))
        wl, wh = _shifted(-k, wl, wh)
        wl = down(wl - PI_HI) if sgn < 0.0 else wl
        wh = up(wh - PI_LO) if sgn < 0.0 else wh
        tl, th = L[MB * C + i], L[(MB + 1) * C + i]
        known = k == k
        ntl = tl if tl > wl else wl
        nth = th if th < wh else wh
        tl, th = (ntl if known else tl), (nth if known else th)
        ok = ok & (tl <= th)
        xp = (qq == 0.0) | (qq == 1.0)
        yp = (qq == 0.0) | (qq == 3.0)
        a, b = L[RL * C + i], L[RH * C + i]
        sl, sh = (a if sgn > 0.0 else -b), (b if sgn > 0.0 else -a)
        vl, vh, dl, dh = bwd_mul_s(sl, sh, L[(MB + 2) * C + i], L[(MB + 3) * C + i],
                                    L[(MB + 4) * C + i], L[(MB + 5) * C + i])
        ok = ok & (vl <= vh)
        a, b = L[SXL * C + i], L[SXH * C + i]
        qxl, qxh = (a if xp else -b), (b if xp else -a)
        a, b = L[MXL * C + i], L[MXH * C + i]
        axl, axh = (a if xp else -b), (b if xp else -a)
        a, b = L[SYL * C + i], L[SYH * C + i]
        qyl, qyh = (a if yp else -b), (b if yp else -a)
        a, b = L[MYL * C + i], L[MYH * C + i]
        ayl, ayh = (a if yp else -b), (b if yp else -a)
        x0l, x0h = L[(MB + 6) * C + i], L[(MB + 7) * C + i]
        x1l, x1h = L[(MB + 8) * C + i], L[(MB + 9) * C + i]
        y0l, y0h = L[(MB + 10) * C + i], L[(MB + 11) * C + i]
        y1l, y1h = L[(MB + 12) * C + i], L[(MB + 13) * C + i]
        # x1 ∩= ax + x0, x0 ∩= x1 - ax (inter: the larger lower bound, the smaller upper one)
        el, eh = down(axl + x0l), up(axh + x0h)
        x1l, x1h = (x1l if x1l > el else el), (x1h if x1h < eh else eh)
        el, eh = down(x1l - axh), up(x1h - axl)
        x0l, x0h = (x0l if x0l > el else el), (x0h if x0h < eh else eh)
        el, eh = down(ayl + y0l), up(ayh + y0h)
        y1l, y1h = (y1l if y1l > el else el), (y1h if y1h < eh else eh)
        el, eh = down(y1l - ayh), up(y1h - ayl)
        y0l, y0h = (y0l if y0l > el else el), (y0h if y0h < eh else eh)
        ok = ok & (x1l <= x1h) & (x0l <= x0h) & (y1l <= y1h) & (y0l <= y0h)
        L[MV * C + i] = 1.0 if ok else 0.0
        L[(MR + 0) * C + i], L[(MR + 1) * C + i] = x0l, x0h
        L[(MR + 2) * C + i], L[(MR + 3) * C + i] = y0l, y0h
        L[(MR + 4) * C + i], L[(MR + 5) * C + i] = tl, th
        L[(MR + 6) * C + i], L[(MR + 7) * C + i] = x1l, x1h
        L[(MR + 8) * C + i], L[(MR + 9) * C + i] = y1l, y1h
        L[(MR + 10) * C + i], L[(MR + 11) * C + i] = vl, vh
        L[(MR + 12) * C + i], L[(MR + 13) * C + i] = dl, dh
        L[(MR + 14) * C + i], L[(MR + 15) * C + i] = qxl, qxh
        L[(MR + 16) * C + i], L[(MR + 17) * C + i] = qyl, qyh


@njit(cache=True, inline="always")
def _into(B, r, j, lo, hi):
    """Hull ``[lo, hi]`` into slot ``j``'s ``ACC`` rows of variable ``r``."""
    N = NB
    a = B[(ACC + r) * N + j]
    B[(ACC + r) * N + j] = lo if lo < a else a
    a = B[(ACC + r + 1) * N + j]
    B[(ACC + r + 1) * N + j] = hi if hi > a else a


@njit(cache=True, error_model="numpy")
def _flush(n, L, S, orig, B, box):
    """Contract the ``n`` lanes to their fixpoint (:func:`_to_fixpoint`),
    back to their boxes, hull into the boxes' ``ACC`` rows."""
    C = CHUNK
    N = NB
    pl, ph = L[MPL * C:(MPL + 1) * C], L[MPH * C:(MPH + 1) * C]
    t0l, t0h = L[MT0L * C:(MT0L + 1) * C], L[MT0H * C:(MT0H + 1) * C]
    _to_fixpoint(n, L, S, orig, pl, ph, t0l, t0h, PASSES, fixstop=True)
    _exit(n, L, orig)
    for i in range(n):
        if L[MV * C + i] < 0.5:
            continue
        j = box[i]
        _into(B, X0, j, L[(MR + 0) * C + i], L[(MR + 1) * C + i])
        _into(B, Y0, j, L[(MR + 2) * C + i], L[(MR + 3) * C + i])
        _into(B, T0, j, L[(MR + 4) * C + i], L[(MR + 5) * C + i])
        _into(B, X1, j, L[(MR + 6) * C + i], L[(MR + 7) * C + i])
        _into(B, Y1, j, L[(MR + 8) * C + i], L[(MR + 9) * C + i])
        _into(B, V, j, L[(MR + 10) * C + i], L[(MR + 11) * C + i])
        _into(B, DT, j, L[(MR + 12) * C + i], L[(MR + 13) * C + i])
        _into(B, QX, j, L[(MR + 14) * C + i], L[(MR + 15) * C + i])
        _into(B, QY, j, L[(MR + 16) * C + i], L[(MR + 17) * C + i])
        _into(B, T1, j, B[T1 * N + j], B[(T1 + 1) * N + j])
        _into(B, W, j, B[W * N + j], B[(W + 1) * N + j])
        _into(B, QT, j, B[QT * N + j], B[(QT + 1) * N + j])




@njit(cache=True, error_model="numpy")
def _kernel(arrs):
    """Over twelve flat ``[lo0, hi0, lo1, hi1, ...]`` arrays: NB slots, a round of each at a
    time (:func:`_heading_step`, :func:`_finish_kept`, :func:`_plan`, lanes, :func:`_flush`,
    :func:`_progress`); a slot whose box is done writes it out and takes the next."""
    n = arrs[0].shape[0] // 2
    N = NB
    C = CHUNK
    ok = np.empty(n, np.bool_)
    B = np.zeros(BROWS * N)
    boxid = np.full(N, -1, np.int64)
    L = np.empty(LROWS * C)
    S = np.empty(ROWS * C)
    orig = np.empty(C, np.int64)
    box = np.empty(C, np.int64)
    idx = np.empty(2 * N + 2, np.int64)
    row = np.empty((1, 24))
    hb = np.empty(HROWS * N)  # the headings _meet1t does not take, packed
    nxt = 0
    for j in range(N):
        nxt = _load(arrs, B, j, nxt, n, ok)
        boxid[j] = nxt - 1 if B[LIVE * N + j] > 0.5 else -1
    while True:
        live = 0
        for j in range(N):
            go = B[LIVE * N + j] > 0.5
            live += 1 if go else 0
            B[NEED * N + j] = 1.0 if go else 0.0
        if live == 0:
            break
        _heading_step(B, row, idx, hb)
        if _finish_kept(B) > 0:  # their slots take new boxes, which start with the heading
            nxt = _swap(arrs, B, boxid, ok, nxt, n)
            _heading_step(B, row, idx, hb)
        _plan(B)
        m = _simd_lanes(B, L, box, idx)
        for j in range(N):
            pos = B[POS * N + j]
            if pos == GEN:
                if m + PIECES > C:
                    _flush(m, L, S, orig, B, box)
                    m = 0
                for r in range(24):
                    row[0, r] = B[r * N + j]
                m = _pieces(row, j, L, m, box)
        if m > 0:
            _flush(m, L, S, orig, B, box)
        _progress(B)
        nxt = _swap(arrs, B, boxid, ok, nxt, n)
    return ok


def unicycle_simd_kernel(x0, y0, th0, x1, y1, th1, v, w, dt, qx, qy, qth):
    """In place over twelve ``(N, 2)`` arrays; returns the mask of rows that stayed non-empty."""
    return in_place(lambda flat: _kernel(tuple(flat)), (x0, y0, th0, x1, y1, th1, v, w, dt, qx, qy, qth))
