"""Polar contractor on boxes of several quadrant pieces: each piece a polar lane of its own.

Same constraint and guarantee as :mod:`~ivslam_cli.contractors.ctc_polar` (``dx = rho
cos(theta)``, ``dy = rho sin(theta)``, ``rho >= 0``, theta in its own branch): every solution in
the input box is in the output box. This is the route of
:mod:`~ivslam_cli.contractors.ctc_polar_simd` for the boxes its fast path does not take but
whose ``(dx, dy)`` box, split along the axes, gives closed quadrant pieces that the polar lane
can contract (:func:`_take` states the condition: finite bounds, solutions not all within
``NEAR_ORIGIN`` of the origin, theta narrower than 4.7, and the origin either outside the
``(dx, dy)`` box or excluded by ``rho > 0``); near an axis that is two pieces, around the
origin four.

The solutions of a box are the union of those of its closed pieces, so the hull of the pieces'
contractions holds every solution. In the piece of quadrant ``q`` (``u = |dx|``, ``v = |dy|``
after the quadrant's sign flips, both ``>= 0``), a solution has ``(dx, dy) != 0`` and
``theta = s psi + C`` with ``psi in [0, pi/2]`` for the one copy ``C`` of the quadrant's arc
that can meet a theta narrower than 4.7 (:func:`_arc_copy`, as the fast path's entry finds it);
the piece is then the polar lane on ``(u, v, rho, t = tan(psi))``, contracted by
:func:`~ivslam_cli.contractors.simd_polar_lanes._to_fixpoint` (``polar=True``) with the lanes
of other boxes' pieces, and taken back by :func:`_finish`: ``psi ∩= atan(t)``, ``theta ∩= s psi
+ C`` in the box's own branch, out of the quadrant frame, hulled per box (a box whose pieces
are all emptied is emptied). Every bound is rounded outward as in the fast path.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_polar import MAX_PASSES, polar_scalar
from ivslam_cli.contractors.simd_polar_lanes import (
    psi_from_tangents,
    CHUNK,
    OK,
    RH,
    RL,
    ROWS,
    TH,
    TL,
    UH,
    UL,
    VH,
    VL,
    _dnf,
    _mn,
    _mx,
    _to_fixpoint,
)
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO
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
    up_raw,
)

E = EMPTY_LO
F = EMPTY_HI

# Per lane of the pieces buffer P (row r of lane i at P[r * CHUNK + i]): the slot of its box,
# its quadrant, the enclosure of its offset C, its psi bounds (handed to tan as they are:
# _to_fixpoint only reads them).
PB, PQ, PCL, PCH, PSL, PSH = 0, 1, 2, 3, 4, 5
PROWS = 6
MAX_PIECES = 4
#: boxes whose rho upper bound, or whose every dx and dy bound, is smaller in magnitude (then
#: every solution is that near the origin) go to ``polar_scalar``, on both SIMD routes: the lanes
#: square their bounds, and a square's rounding error (2^-53 of it) leaves the normal range
#: below ~1.6e-146 (rho 1.5e-148 came out 2e-12 looser than the scalar kernel); 1e-140 keeps
#: a margin for the products of squares with the lanes' other factors
NEAR_ORIGIN = 1e-140


@njit(cache=True, inline="always", error_model="numpy")
def _arc_copy(q, tl, th):
    """``(cl, ch, pl, ph)`` for quadrant ``q`` (0 (+,+), 1 (+,-), 2 (-,-), 3 (-,+)) and theta
    ``[tl, th]`` narrower than 4.7: ``C = 2 k pi + c_q`` enclosed in ``[cl, ch]`` for the copy
    ``k`` of the quadrant's arc whose centre is nearest theta's midpoint, the only copy that can
    meet theta (a meeting copy's centre is within ``w / 2 + pi / 4 < 3.1354`` of the midpoint,
    any other at least ``2 pi - 3.1354``), and ``psi = s (theta - C) ∩ [0, HALF_PI_HI]`` (empty
    when no copy meets theta). The same operations as the fast path's entry."""
    xp = q < 2
    yp = (q == 0) | (q == 3)
    pos = (q == 0) | (q == 2)
    c0 = 0.0 if xp else (math.pi if yp else -math.pi)
    k0 = np.floor((0.5 * (tl + th) - c0 - (0.25 if pos else -0.25) * math.pi) * INV_TWO_PI_LO
                  + 0.5)
    ol = down(k0 * (TWO_PI_LO if k0 >= 0.0 else TWO_PI_HI))
    oh = up(k0 * (TWO_PI_HI if k0 >= 0.0 else TWO_PI_LO))
    cl = ol if xp else down(ol + (PI_LO if yp else -PI_HI))
    ch = oh if xp else up(oh + (PI_HI if yp else -PI_LO))
    pl = _mx(down((tl - ch) if pos else (cl - th)), 0.0)
    ph = _mn(up((th - cl) if pos else (ch - tl)), HALF_PI_HI)
    return cl, ch, pl, ph


@njit(cache=True, inline="always", error_model="numpy")
def fits_lanes(xl, xh, yl, yh, rl, rh, tl, th):
    """Whether a box (``rl`` already ``>= 0``) may go on a lane, on either SIMD route: non-empty,
    finite (``|bound| < 1e300``, ``|theta| < 1e6``), theta narrower than 4.7, and not every
    solution within ``NEAR_ORIGIN`` of the origin. Selects only (no branch): it stays in SIMD
    loops."""
    return ((-1e300 < xl) & (xl <= xh) & (xh < 1e300) & (-1e300 < yl) & (yl <= yh)
            & (yh < 1e300) & (0.0 <= rl) & (rl <= rh) & (rh < 1e300) & (-1e6 < tl)
            & (tl <= th) & (th < 1e6) & (th - tl < 4.7)
            & (rh >= NEAR_ORIGIN) & (_mx(_mx(xh, -xl), _mx(yh, -yl)) >= NEAR_ORIGIN))


@njit(cache=True, inline="always", error_model="numpy")
def _take(i, dx, dy, rho, theta, L, P, tb, rows, cnt):
    """Box ``i`` of the flat bound arrays onto the pieces route, if it fits (:func:`fits_lanes`,
    and ``rho > 0`` or the origin outside its ``(dx, dy)`` box). Its non-empty closed pieces become lanes
    ``cnt[0]..`` of ``L`` (``t ∩= v / u`` in the t rows, as :func:`_to_fixpoint`'s polar lanes
    expect) and ``P``; the box takes slot ``cnt[1]`` (its row in ``rows``, its theta in
    ``tb``). Returns False, taking nothing, for a box that does not fit."""
    C = CHUNK
    k = 2 * i
    xl, xh, yl, yh = dx[k], dx[k + 1], dy[k], dy[k + 1]
    rl, rh, tl, th = _mx(rho[k], 0.0), rho[k + 1], theta[k], theta[k + 1]
    fin = fits_lanes(xl, xh, yl, yh, rl, rh, tl, th)
    origin = (xl <= 0.0) & (0.0 <= xh) & (yl <= 0.0) & (0.0 <= yh)
    if not fin or (origin and not rl > 0.0):
        return False
    m, nb = cnt[0], cnt[1]
    for q in range(4):
        xp = q < 2
        yp = (q == 0) | (q == 3)
        ul, uh = (xl, xh) if xp else (-xh, -xl)
        vl, vh = (yl, yh) if yp else (-yh, -yl)
        ul, vl = _mx(ul, 0.0), _mx(vl, 0.0)
        if not (ul <= uh and vl <= vh):
            continue
        cl, ch, pl, ph = _arc_copy(q, tl, th)
        if not (pl <= ph):
            continue
        L[UL * C + m], L[UH * C + m] = ul, uh
        L[VL * C + m], L[VH * C + m] = vl, vh
        L[RL * C + m], L[RH * C + m] = rl, rh
        L[OK * C + m] = 1.0
        # t = v / u: 0 / 0 (a piece at the origin) is NaN, x / 0 is +inf; both bounds dropped
        L[TL * C + m] = _mx(0.0, _dnf(vl / uh))
        L[TH * C + m] = _mn(INF, up_raw(vh / ul))
        P[PB * C + m], P[PQ * C + m] = nb, q
        P[PCL * C + m], P[PCH * C + m] = cl, ch
        P[PSL * C + m], P[PSH * C + m] = pl, ph
        m += 1
    rows[nb] = i
    tb[nb, 0], tb[nb, 1] = tl, th
    cnt[0], cnt[1] = m, nb + 1
    return True


@njit(cache=True, error_model="numpy")
def _finish(m, nb, L, P, t0l, t0h, idx, acc, tb, rows, dx, dy, rho, theta):
    """Lanes ``0..m-1`` done (final states in ``L``; ``t0l``, ``t0h`` the tangents they were
    loaded with): ``psi ∩= atan(t)`` where ``t`` moved, ``theta ∩= s psi + C``, ``u``, ``v``
    back from the quadrant frame, hulled into their boxes' rows of ``acc``; boxes ``0..nb-1``
    written out to their rows (all bounds empty for a box with no non-empty piece)."""
    C = CHUNK
    psi_from_tangents(m, L, t0l, t0h, P[PSL * C:(PSL + 1) * C], P[PSH * C:(PSH + 1) * C], idx)
    for b in range(nb):
        for v in range(4):
            acc[b, 2 * v], acc[b, 2 * v + 1] = E, F
    for i in range(m):
        b = int(P[PB * C + i])
        q = P[PQ * C + i]
        pl, ph = P[PSL * C + i], P[PSH * C + i]
        cl, ch = P[PCL * C + i], P[PCH * C + i]
        xp = (q == 0.0) | (q == 1.0)
        yp = (q == 0.0) | (q == 3.0)
        pos = (q == 0.0) | (q == 2.0)
        tl = _mx(tb[b, 0], down((pl + cl) if pos else (cl - ph)))
        th = _mn(tb[b, 1], up((ph + ch) if pos else (ch - pl)))
        if not ((L[OK * C + i] > 0.5) & (pl <= ph) & (tl <= th)):
            continue
        a, c = L[UL * C + i], L[UH * C + i]
        xl, xh = (a, c) if xp else (-c, -a)
        a, c = L[VL * C + i], L[VH * C + i]
        yl, yh = (a, c) if yp else (-c, -a)
        acc[b, 0], acc[b, 1] = _mn(acc[b, 0], xl), _mx(acc[b, 1], xh)
        acc[b, 2], acc[b, 3] = _mn(acc[b, 2], yl), _mx(acc[b, 3], yh)
        acc[b, 4], acc[b, 5] = _mn(acc[b, 4], L[RL * C + i]), _mx(acc[b, 5], L[RH * C + i])
        acc[b, 6], acc[b, 7] = _mn(acc[b, 6], tl), _mx(acc[b, 7], th)
    for b in range(nb):
        k = 2 * rows[b]
        ok = acc[b, 0] <= acc[b, 1]
        for v, out in enumerate((dx, dy, rho, theta)):
            out[k] = acc[b, 2 * v] if ok else E
            out[k + 1] = acc[b, 2 * v + 1] if ok else F


@njit(cache=True, error_model="numpy")
def _flush(L, S, P, orig, t0l, t0h, acc, tb, rows, cnt, dx, dy, rho, theta):
    """Contract the pieces buffered (``cnt``: lanes, boxes) to their fixpoint, write their boxes
    out and empty the buffers."""
    C = CHUNK
    m, nb = cnt[0], cnt[1]
    if nb == 0:
        return
    pl, ph = P[PSL * C:(PSL + 1) * C], P[PSH * C:(PSH + 1) * C]
    _to_fixpoint(m, L, S, orig, pl, ph, t0l, t0h, MAX_PASSES, True)
    _finish(m, nb, L, P, t0l, t0h, orig, acc, tb, rows, dx, dy, rho, theta)
    cnt[0], cnt[1] = 0, 0


@njit(cache=True)
def buffers():
    """The route's buffers: ``(L, S, P, orig, t0l, t0h, acc, tb, rows, cnt)``."""
    C = CHUNK
    return (np.empty(ROWS * C), np.empty(ROWS * C), np.empty(PROWS * C), np.empty(C, np.int64),
            np.empty(C), np.empty(C), np.empty((C, 8)), np.empty((C, 2)),
            np.empty(C, np.int64), np.zeros(2, np.int64))


@njit(cache=True, error_model="numpy")
def off_fast_path(s, nb, fast, dx, dy, rho, theta, B):
    """Boxes ``s + j`` (``j < nb``) with ``fast[j]`` 0: onto the pieces route (:func:`_take`;
    the buffers ``B`` flushed first when they may not hold a box's pieces), or when a box does
    not fit it, through ``polar_scalar``, its result written to its row."""
    L, S, P, orig, t0l, t0h, acc, tb, rows, cnt = B
    for j in range(nb):
        if fast[j] > 0.5:
            continue
        if cnt[0] + MAX_PIECES > CHUNK or cnt[1] == CHUNK:
            _flush(L, S, P, orig, t0l, t0h, acc, tb, rows, cnt, dx, dy, rho, theta)
        if _take(s + j, dx, dy, rho, theta, L, P, tb, rows, cnt):
            continue
        k = 2 * (s + j)
        r = polar_scalar(dx[k], dx[k + 1], dy[k], dy[k + 1], rho[k], rho[k + 1], theta[k],
                         theta[k + 1])
        for v, out in enumerate((dx, dy, rho, theta)):
            out[k], out[k + 1] = r[2 * v], r[2 * v + 1]


@njit(cache=True, error_model="numpy")
def flush(dx, dy, rho, theta, B):
    """Contract and write out what the buffers ``B`` hold."""
    L, S, P, orig, t0l, t0h, acc, tb, rows, cnt = B
    _flush(L, S, P, orig, t0l, t0h, acc, tb, rows, cnt, dx, dy, rho, theta)
