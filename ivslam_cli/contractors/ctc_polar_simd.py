"""Polar contractor over structure-of-arrays chunks: one fused SIMD loop per chunk.

Same constraint and guarantee as :mod:`~ivslam_cli.contractors.ctc_polar` (``dx = rho
cos(theta)``, ``dy = rho sin(theta)``, ``rho >= 0``, theta in its own branch): every solution in
the input box is in the output box. :func:`~ivslam_cli.contractors.ctc_polar.polar_scalar` stays
the reference; tests/contractors/test_polar_simd.py compares the two.

The fast path takes a box whose ``(dx, dy)`` lies in one open quadrant, with finite bounds and a
theta narrower than ``3 pi / 2`` that meets exactly one copy of that quadrant's arc (the usual
case in a SLAM sweep; :func:`_setup` states the condition); every other box goes to the pieces
route of :mod:`~ivslam_cli.contractors.ctc_polar_pieces` (boxes near an axis or around the
origin, with finite bounds: each closed quadrant piece a polar lane of its own, hulled per box)
or, if it does not fit there either, to ``polar_scalar`` (unbounded or very wide boxes, the
origin with ``rho`` reaching 0, boxes whose solutions all lie within ``NEAR_ORIGIN`` of the
origin, where the lanes' squares would leave the normal range). In the quadrant, with ``u =
|dx|``, ``v = |dy|`` and ``psi in [0, pi/2]`` given by ``theta = s psi + C`` (``s = ±1``, ``C``
a multiple of ``pi / 2`` fixed per box and enclosed once), the constraint is the polar lane of
:mod:`~ivslam_cli.contractors.simd_polar_lanes` on ``(u, v, rho, t)``, ``t = tan(psi)``
(:func:`~ivslam_cli.contractors.simd_polar_lanes._polar_lane_pass`: ``v = u t`` forward and
backward, ``rho^2 = u^2 + v^2`` forward-backward, ``u ∩= rho cos(psi)``, ``v ∩= rho sin(psi)``
with cos and sin from ``t`` by a square root and a quotient, ``t ∩= v / u``), a fixed sequence
of min/max, products, quotients and square roots rounded outward: one branch-free loop over the
chunk that LLVM turns into SIMD code. The box's piece is found and its lane built
(:func:`_entry`, ``t ∩= v / u`` once before the first pass), and the result taken back
(:func:`_exit`: ``psi ∩= atan(t)``, ``theta ∩= s psi + C``, out of the quadrant frame), by
select loops of the same kind.

libm is called at most twice per box on entry (tan of the two ``psi`` bounds) and twice on exit
(atan of the two ``t`` bounds), on packed lists of the lanes that need them: a tan is skipped
when its bound is 0 or pi/2 or when series bounds of tan show that ``v / u`` bounds ``t`` at
least as tightly (:func:`_tan_at_most`, :func:`_tan_at_least`), an atan when ``t`` did not move
(``atan(tan(psi))`` holds ``psi`` already). On the bench's regular boxes that is about one tan
and 1.3 atan per box.

Passes repeat per lane while one shrinks some width by at least ``RELATIVE_STOP`` (at least
two, at most ``MAX_PASSES``; :func:`~ivslam_cli.contractors.simd_polar_lanes._to_fixpoint`):
a lane never gets fewer passes than the scalar kernel's stopping rule would give it, and an
extra pass is only a further sound contraction. (With ``t ∩= v / u`` at the end of each pass,
the regular boxes' lanes all stop after two.)
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_polar import (
    MAX_PASSES,
    _two_pi_times,
)
from ivslam_cli.contractors.ctc_polar_pieces import buffers as pieces_buffers
from ivslam_cli.contractors.ctc_polar_pieces import _arc_copy, fits_lanes
from ivslam_cli.contractors.ctc_polar_pieces import flush as flush_pieces
from ivslam_cli.contractors.ctc_polar_pieces import off_fast_path
from ivslam_cli.contractors.simd_polar_lanes import (
    psi_from_tangents,
    in_place,
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
    down,
    up,
    up_raw,
)

E = EMPTY_LO
F = EMPTY_HI
# quadrant q: (sign of x, sign of y) = q0 (+,+), q1 (+,-), q2 (-,-), q3 (-,+);
# theta = s psi + 2 k pi + c with (s, c) = q0 (1, 0), q1 (-1, 0), q2 (1, -pi), q3 (-1, pi)


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
    """``psi = s (theta - C)`` enclosed, ∩ ``[0, HALF_PI_HI]``."""
    if s > 0.0:
        pl, ph = down(tl - ch), up(th - cl)
    else:
        pl, ph = down(cl - th), up(ch - tl)
    return _mx(pl, 0.0), _mn(ph, HALF_PI_HI)


@njit(cache=True, error_model="numpy")
def _setup(xl, xh, yl, yh, rl, rh, tl, th):
    """Is the box on the fast path? Returns ``(ok, q, s, cl, ch, ul, uh, vl, vh, pl, ph)``:
    its quadrant, ``theta = s psi + C`` with ``C`` in ``[cl, ch]``, the piece ``u``, ``v`` and
    ``psi``. The statement of the condition :func:`_entry` evaluates as selects (``rl`` is the
    rho lower bound after ``max(rl, 0)``)."""
    z = 0.0
    bad = (False, 0, z, z, z, z, z, z, z, z, z)
    if not fits_lanes(xl, xh, yl, yh, rl, rh, tl, th):
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


# tan on [0, 1.5] bounded by Taylor polynomials of sin and cos (alternating series, truncated
# after a term of known sign), for deciding which tan calls can be skipped: a wrong decision
# would only cost tightness (a t bound left to the passes), never a solution.
@njit(cache=True, inline="always", error_model="numpy")
def _sin_cos_series(p):
    """``(sin_hi, sin_lo, cos_hi, cos_lo)`` bounding sin and cos of ``p`` in ``[0, 1.5]``
    (up to the rounding of the polynomials, a few ulps)."""
    p2 = p * p
    s_hi = p * (1.0 + p2 * (-1.0 / 6 + p2 * (1.0 / 120 + p2 * (-1.0 / 5040 + p2 / 362880))))
    s_lo = s_hi - p * p2 ** 5 / 39916800
    c_lo = 1.0 + p2 * (-0.5 + p2 * (1.0 / 24 + p2 * (-1.0 / 720 + p2 * (1.0 / 40320
                                                                         - p2 / 3628800))))
    c_hi = c_lo + p2 ** 6 / 479001600
    return s_hi, s_lo, c_hi, c_lo


@njit(cache=True, inline="always", error_model="numpy")
def _tan_at_most(p, y, x):
    """Is ``tan(p) <= y / x`` for sure (``x, y > 0``)? True only for ``p`` in ``[0, 1.5]`` with
    ``cos(p) > 0.01`` and the series bound of ``tan(p)`` at least ``2e-12`` (relative) below
    ``y / x``: far above the polynomials' rounding; both products normal (``> 1e-300``) or
    the left one 0. Products, no quotient."""
    s_hi, _, _, c_lo = _sin_cos_series(p)
    lhs = s_hi * x * (1.0 + 2e-12)
    rhs = y * c_lo
    ok = (p >= 0.0) & (p <= 1.5) & (c_lo > 0.01) & ((lhs == 0.0) | (lhs > 1e-300)) & (rhs > 1e-300)
    return ok & (lhs <= rhs)


@njit(cache=True, inline="always", error_model="numpy")
def _tan_at_least(p, y, x):
    """Is ``tan(p) >= y / x`` for sure (``x, y > 0``)? As :func:`_tan_at_most`."""
    _, s_lo, c_hi, c_lo = _sin_cos_series(p)
    lhs = s_lo * x * (1.0 - 2e-12)
    rhs = y * c_hi
    ok = (p >= 0.0) & (p <= 1.5) & (c_lo > 0.01) & (lhs > 1e-300) & (rhs > 1e-300)
    return ok & (lhs >= rhs)


# The fast path's buffer W: the lane rows (0..ROWS-1, as simd_polar_lanes lays them out; packed
# during the fixpoint), then per box of the chunk (slot = box): its 8 bounds (dx dy rho theta,
# lo hi; replaced by the results on exit), the psi bounds of its lane, the psi bounds handed to
# tan, its quadrant, its kind (1.0 on the fast path), the enclosure of its offset C. Every SIMD
# loop over W reads and writes one base pointer at compile-time row offsets.
BX = ROWS
PSL, PSH, QL, QH, QD, KD, CL, CH = BX + 8, BX + 9, BX + 10, BX + 11, BX + 12, BX + 13, BX + 14, BX + 15
WROWS = BX + 16


@njit(cache=True, inline="always")
def _rows_in(s, nb, a, W, r):
    """Bounds ``s..s+nb-1`` of the flat ``[lo, hi, ...]`` array ``a`` into rows ``r``, ``r + 1``
    of ``W``."""
    C = CHUNK
    for j in range(nb):
        W[r * C + j] = a[2 * (s + j)]
        W[(r + 1) * C + j] = a[2 * (s + j) + 1]


@njit(cache=True, inline="always")
def _rows_out(s, nb, a, W, r):
    """Rows ``r``, ``r + 1`` of ``W`` back into bounds ``s..s+nb-1`` of ``a``."""
    C = CHUNK
    for j in range(nb):
        a[2 * (s + j)] = W[r * C + j]
        a[2 * (s + j) + 1] = W[(r + 1) * C + j]


@njit(cache=True, error_model="numpy")
def _entry(s, nb, dx, dy, rho, theta, W):
    """Boxes ``s..s+nb-1`` into ``W`` and, as selects (a SIMD loop), :func:`_setup`'s condition
    and results: a box on the fast path gets its lane at its slot (``u``, ``v``, ``rho``, ``OK``
    1; ``psi`` in rows ``PSL``, ``PSH`` and ``QL``, ``QH``), any other box a dead lane (``OK``
    0, ``u = v = rho = [1, 1]``, ``psi = [0, pi/2]``: no libm call)."""
    C = CHUNK
    _rows_in(s, nb, dx, W, BX)
    _rows_in(s, nb, dy, W, BX + 2)
    _rows_in(s, nb, rho, W, BX + 4)
    _rows_in(s, nb, theta, W, BX + 6)
    for j in range(nb):
        xl, xh = W[(BX + 0) * C + j], W[(BX + 1) * C + j]
        yl, yh = W[(BX + 2) * C + j], W[(BX + 3) * C + j]
        rl, rh = _mx(W[(BX + 4) * C + j], 0.0), W[(BX + 5) * C + j]
        tl, th = W[(BX + 6) * C + j], W[(BX + 7) * C + j]
        fin = fits_lanes(xl, xh, yl, yh, rl, rh, tl, th)
        xp, yp = xl > 0.0, yl > 0.0
        quad = (xp | (xh < 0.0)) & (yp | (yh < 0.0))
        q = (0.0 if yp else 1.0) if xp else (3.0 if yp else 2.0)
        # the copy k0 of the quadrant's arc nearest theta, the only one that can meet it, so
        # _setup's count over k0 - 1, k0, k0 + 1 is 1 exactly when its piece is non-empty
        cl, ch, pl, ph = _arc_copy(q, tl, th)
        fast = fin & quad & (pl <= ph)
        ul, uh = (xl, xh) if xp else (-xh, -xl)
        vl, vh = (yl, yh) if yp else (-yh, -yl)
        W[UL * C + j], W[UH * C + j] = (ul, uh) if fast else (1.0, 1.0)
        W[VL * C + j], W[VH * C + j] = (vl, vh) if fast else (1.0, 1.0)
        W[RL * C + j], W[RH * C + j] = (rl, rh) if fast else (1.0, 1.0)
        W[OK * C + j] = 1.0 if fast else 0.0
        W[TL * C + j] = _dnf(vl / uh) if fast else 0.0  # t = v / u, before the first pass
        W[TH * C + j] = up_raw(vh / ul) if fast else INF
        W[KD * C + j] = 1.0 if fast else 0.0
        W[QD * C + j] = q
        W[CL * C + j], W[CH * C + j] = cl, ch
        W[PSL * C + j] = pl if fast else 0.0
        W[PSH * C + j] = ph if fast else HALF_PI_HI
        # tan of a psi bound is wanted only where it may contract: where tan(pl) <= vl / uh
        # (or tan(ph) >= vh / ul) the first pass's v / u bounds of t hold it already
        need_l = fast & (not _tan_at_most(pl, vl, uh))
        need_h = fast & (not _tan_at_least(ph, vh, ul))
        W[QL * C + j] = pl if need_l else 0.0
        W[QH * C + j] = ph if need_h else HALF_PI_HI


@njit(cache=True, error_model="numpy")
def _exit(s, nb, dx, dy, rho, theta, W, t0l, t0h, idx):
    """Rows ``s..s+nb-1`` of the fast path from their lanes (final states in ``W``): ``psi ∩=
    atan(t)`` where ``t`` moved, then as selects (a SIMD loop) ``theta ∩= s psi + C`` and ``u``,
    ``v`` back from the quadrant frame; a lane emptied (or a psi or theta emptied) empties its
    row. A row off the fast path takes the bounds its box rows hold (its input, contracted
    afterwards by :func:`_kernel`). All rows are then written out (an unconditional copy)."""
    C = CHUNK
    psi_from_tangents(nb, W, t0l, t0h, W[PSL * C:(PSL + 1) * C], W[PSH * C:(PSH + 1) * C], idx)
    for i in range(nb):
        pl, ph, q = W[PSL * C + i], W[PSH * C + i], W[QD * C + i]
        cl, ch = W[CL * C + i], W[CH * C + i]
        xp = (q == 0.0) | (q == 1.0)
        yp = (q == 0.0) | (q == 3.0)
        pos = (q == 0.0) | (q == 2.0)
        al = down((pl + cl) if pos else (cl - ph))
        ah = up((ph + ch) if pos else (ch - pl))
        tl = _mx(W[(BX + 6) * C + i], al)
        th = _mn(W[(BX + 7) * C + i], ah)
        a, b = W[UL * C + i], W[UH * C + i]
        xl, xh = (a, b) if xp else (-b, -a)
        a, b = W[VL * C + i], W[VH * C + i]
        yl, yh = (a, b) if yp else (-b, -a)
        rl, rh = W[RL * C + i], W[RH * C + i]
        live = (W[OK * C + i] > 0.5) & (pl <= ph) & (tl <= th)
        fast = W[KD * C + i] > 0.5  # a row off the fast path holds its input
        xl, xh = ((xl, xh) if live else (E, F)) if fast else (W[BX * C + i], W[(BX + 1) * C + i])
        yl, yh = (((yl, yh) if live else (E, F)) if fast
                  else (W[(BX + 2) * C + i], W[(BX + 3) * C + i]))
        rl, rh = (((rl, rh) if live else (E, F)) if fast
                  else (W[(BX + 4) * C + i], W[(BX + 5) * C + i]))
        tl, th = (((tl, th) if live else (E, F)) if fast
                  else (W[(BX + 6) * C + i], W[(BX + 7) * C + i]))
        W[(BX + 0) * C + i], W[(BX + 1) * C + i] = xl, xh
        W[(BX + 2) * C + i], W[(BX + 3) * C + i] = yl, yh
        W[(BX + 4) * C + i], W[(BX + 5) * C + i] = rl, rh
        W[(BX + 6) * C + i], W[(BX + 7) * C + i] = tl, th
    _rows_out(s, nb, dx, W, BX)
    _rows_out(s, nb, dy, W, BX + 2)
    _rows_out(s, nb, rho, W, BX + 4)
    _rows_out(s, nb, theta, W, BX + 6)


@njit(cache=True, error_model="numpy")
def _kernel(dx, dy, rho, theta):
    """Over four flat ``[lo0, hi0, lo1, hi1, ...]`` arrays, a chunk of ``CHUNK`` boxes at a time:
    :func:`_entry`, the fixpoint of the lanes, :func:`_exit`, then the boxes off the fast path
    onto the pieces route (buffered across chunks, flushed when full and at the end) or through
    ``polar_scalar``."""
    n = dx.shape[0] // 2
    C = CHUNK
    okm = np.empty(n, np.bool_)
    W = np.empty(WROWS * C)
    S = np.empty(ROWS * C)
    orig = np.empty(C, np.int64)
    t0l, t0h = np.empty(C), np.empty(C)
    ql, qh = W[QL * C:(QL + 1) * C], W[QH * C:(QH + 1) * C]
    kind = W[KD * C:(KD + 1) * C]
    B = pieces_buffers()
    for s in range(0, n, C):
        nb = min(C, n - s)
        _entry(s, nb, dx, dy, rho, theta, W)
        _to_fixpoint(nb, W, S, orig, ql, qh, t0l, t0h, MAX_PASSES, True)
        _exit(s, nb, dx, dy, rho, theta, W, t0l, t0h, orig)
        off_fast_path(s, nb, kind, dx, dy, rho, theta, B)  # their rows hold their input again
    flush_pieces(dx, dy, rho, theta, B)
    for i in range(n):
        okm[i] = dx[2 * i] <= dx[2 * i + 1]
    return okm


def polar_simd_kernel(dx, dy, rho, theta):
    """In place over four ``(N, 2)`` arrays; returns the mask of rows that stayed non-empty."""
    return in_place(lambda flat: _kernel(*flat), (dx, dy, rho, theta))
