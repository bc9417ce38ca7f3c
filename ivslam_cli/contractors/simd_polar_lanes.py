"""The polar lane of the SIMD polar, range-bearing and unicycle contractors: state, pass, fixpoint.

A lane is one closed quadrant piece of the range-bearing constraint (Jaulin's contractor
programming: ``u = mx - sx``, ``v = my - sy``, the polar constraint on ``(u, v, rho, t)`` with
``t = tan(psi)``, ``u, v >= 0`` after the quadrant's sign flips), kept as rows of one buffer so
that a pass over the lanes is one branch-free loop LLVM turns into SIMD code; a polar lane
(:func:`_polar_lane_pass`) is the polar constraint on ``(u, v, rho, t)`` alone. Every bound is
rounded outward (:func:`~ivslam_cli.interval.rounding.down` / ``up`` or their sign-aware forms,
bit for bit, or products by ``LO_SLACK`` / ``HI_SLACK`` where stated); a lane keeps every
solution of its piece. :mod:`~ivslam_cli.contractors.ctc_range_bearing_simd`,
:mod:`~ivslam_cli.contractors.ctc_unicycle_simd` and
:mod:`~ivslam_cli.contractors.ctc_polar_simd` build the lanes and take them back.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_polar import _atan_hi, _atan_lo, _tan_hi, _tan_lo
from ivslam_cli.contractors.ctc_range_bearing import RELATIVE_STOP
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO
from ivslam_cli.interval.rounding import HALF_PI_LO, INF, down, down_pos, down_raw, up_pos, up_raw

# Lanes per chunk, and the stride of the rows of every lane buffer: not a multiple of 512 (4 KiB
# rows apart alias in the store buffer: a scalar loop writing a lane across the rows of L
# while reading another buffer ran 6x slower at 256).
CHUNK = 264
MAX_FLOAT = float(np.finfo(np.float64).max)
MAX_PASSES = 16
E = EMPTY_LO
F = EMPTY_HI

# Lane state, row r of lane i at L[r * CHUNK + i] (one base pointer, compile-time offsets).
UL, UH, VL, VH, RL, RH, TL, TH = 0, 1, 2, 3, 4, 5, 6, 7
SXL, SXH, MXL, MXH, SYL, SYH, MYL, MYH = 8, 9, 10, 11, 12, 13, 14, 15
OK = 16  # 1.0 while the lane is non-empty
PROG = 17  # 1.0 if the last pass shrank some width by RELATIVE_STOP
ACT = 18  # 1.0 while the lane takes passes (the passes of _passes_live leave the others)
ROWS = 19
BIG = 1e150  # tan bounds above this are treated as unbounded in the sin/cos step (no overflow)


@njit(cache=True, inline="always", error_model="numpy")
def _mx(a, b):
    """``max`` as a select (``a`` when ``b`` is NaN)."""
    return b if b > a else a


@njit(cache=True, inline="always", error_model="numpy")
def _mn(a, b):
    """``min`` as a select (``a`` when ``b`` is NaN)."""
    return b if b < a else a


@njit(cache=True, inline="always", error_model="numpy")
def _shrunk(ol, oh, nl, nh):
    """Did ``[ol, oh] -> [nl, nh]`` shrink the width by ``RELATIVE_STOP``? (inf -> finite: yes)."""
    w0 = oh - ol
    return (w0 > 0.0) & ((w0 - (nh - nl)) >= RELATIVE_STOP * w0)


@njit(cache=True, inline="always", error_model="numpy")
def _dnf(c):
    """A lower bound of a nonnegative quotient or product rounded to ``c``, to be taken by
    ``_mx`` (NaN is ignored there): ``down_pos(c)``, except that an overflow (``c = +inf``, the
    real value above ``MAX_FLOAT``) gives ``MAX_FLOAT`` (``down`` would give ``-inf``: nothing;
    this keeps ``t = v / u`` huge when ``u`` is a few subnormals, i.e. ``psi`` at pi/2)."""
    return MAX_FLOAT if c == INF else down_pos(c)


TINY = 2.0**-969  # below it PHI * |c| in down(c) is subnormal: a microcode assist on x86


@njit(cache=True, inline="always", error_model="numpy")
def _down_tiny(c):
    """A lower bound of the real number rounded to ``c``: ``down(c)`` where ``|c| >= TINY``,
    below it ``c - 2^-1020`` (at most ``pred(c)``: the ulp there is at most ``2^-1021``), never
    multiplying a number below ``TINY``. (``u^2 + v^2`` is ``-2^-1073`` at the origin: in some
    lane of most vectors of a unicycle chunk.) It differs from ``down`` only for ``0 < c <
    TINY``, by less than ``2^-1020``, lower."""
    big = abs(c) >= TINY
    r = down(c if big else 1.0)
    return r if big else c - 2.0**-1020


@njit(cache=True, inline="always", error_model="numpy")
def _lane_pass(L, i):
    """One pass of lane ``i``: its 16 new bounds, whether it stays non-empty, whether it shrank
    some width by ``RELATIVE_STOP``, whether it moved some bound (else it is at a fixpoint).

    In a lane that stays non-empty every bound of ``u, v, rho, t`` is ``>= 0`` or ``-0``
    throughout the pass (lower bounds start so and only grow, an upper bound below its lower
    bound empties the lane), so their products, sums and square roots are ``>= 0`` or ``±0``
    and rounded with ``down_pos`` / ``up_pos``. A quotient by ``-0`` is ``-inf``: the upper
    bounds of quotients keep the ``abs`` (``up_raw``: NaN, ignored, where ``up`` gives
    ``+inf``); their lower bounds (``_dnf``) give NaN there, ignored too. A bound that only
    enters ``_mx`` / ``_mn`` as the argument whose NaN is ignored takes no NaN guard. The
    results are those of ``down`` / ``up`` everywhere, bit for bit, except cos and sin of the t
    bounds (:func:`_cos_sin`, each on its side of the real value); an emptied lane's values are
    never used. Between the differences, :func:`_polar_steps` (``t = v / u`` at their end)."""
    C = CHUNK
    a0, b0, c0, d0 = L[UL * C + i], L[UH * C + i], L[VL * C + i], L[VH * C + i]
    e0, f0, g0, h0 = L[RL * C + i], L[RH * C + i], L[TL * C + i], L[TH * C + i]
    p0, q0, r0, s0 = L[SXL * C + i], L[SXH * C + i], L[MXL * C + i], L[MXH * C + i]
    w0, x0, y0, z0 = L[SYL * C + i], L[SYH * C + i], L[MYL * C + i], L[MYH * C + i]
    sxl, sxh, mxl, mxh, syl, syh, myl, myh = p0, q0, r0, s0, w0, x0, y0, z0
    # u = mx - sx, v = my - sy (frame: both >= 0)
    a = _mx(a0, down_raw(mxl - sxh))
    b = _mn(b0, up_raw(mxh - sxl))
    c = _mx(c0, down_raw(myl - syh))
    d = _mn(d0, up_raw(myh - syl))
    # the polar steps (t = v / u at their end, and before the first pass: _to_fixpoint)
    a, b, c, d, e, f, g, h, ok = _polar_steps(a, b, c, d, e0, f0, g0, h0)
    # back to the differences: mx ∩= u + sx, sx ∩= mx - u (y likewise)
    mxl = _mx(mxl, down_raw(a + sxl))
    mxh = _mn(mxh, up_raw(b + sxh))
    sxl = _mx(sxl, down_raw(mxl - b))
    sxh = _mn(sxh, up_raw(mxh - a))
    myl = _mx(myl, down_raw(c + syl))
    myh = _mn(myh, up_raw(d + syh))
    syl = _mx(syl, down_raw(myl - d))
    syh = _mn(syh, up_raw(myh - c))
    good = (ok & (a <= b) & (c <= d) & (e <= f) & (g <= h) & (sxl <= sxh) & (mxl <= mxh)
            & (syl <= syh) & (myl <= myh))
    prog = (_shrunk(a0, b0, a, b) | _shrunk(c0, d0, c, d) | _shrunk(e0, f0, e, f)
            | _shrunk(g0, h0, g, h) | _shrunk(p0, q0, sxl, sxh) | _shrunk(r0, s0, mxl, mxh)
            | _shrunk(w0, x0, syl, syh) | _shrunk(y0, z0, myl, myh))
    # a pass that moved no bound leaves the lane at a fixpoint of the pass: every bound above
    # is replaced only by one strictly inside it (_mx, _mn), so equal bounds are the same
    # floats, and a further pass gives them again. (A subnormal width has RELATIVE_STOP
    # times it rounded to 0, so _shrunk holds for it even when nothing moved.)
    moved = ((a != a0) | (b != b0) | (c != c0) | (d != d0) | (e != e0) | (f != f0) | (g != g0)
             | (h != h0) | (sxl != p0) | (sxh != q0) | (mxl != r0) | (mxh != s0) | (syl != w0)
             | (syh != x0) | (myl != y0) | (myh != z0))
    return (a, b, c, d, e, f, g, h, sxl, sxh, mxl, mxh, syl, syh, myl, myh, good, prog, moved)


# cos(psi) = 1 / sqrt(1 + t^2), sin(psi) = t cos(psi) for t = tan(psi) in [0, BIG]: the float
# R = fl(1 / fl(sqrt(fl(1 + fl(t t))))) is within a factor (1 ± 3.01 u) of cos (u = 2^-53: one
# rounding of t t, relative to 1 + t^2 even when t t is subnormal, one of the sum, both halved
# by the sqrt, one of the sqrt, one of the quotient), fl(t R) within (1 ± 4.01 u) of sin. A
# product by LO_SLACK = 1 - 2^-50 (one more rounding) is then below the real value,
# (1 + 4.01 u)(1 - 8 u)(1 + u) < 1, and by HI_SLACK = 1 + 2^-50 above it, (1 - 4.01 u)(1 + 8 u)
# (1 - u) > 1. The results are >= 0 (or -0), and none is subnormal (R >= 1e-150).
LO_SLACK = 1.0 - 2.0**-50
HI_SLACK = 1.0 + 2.0**-50


@njit(cache=True, inline="always", error_model="numpy")
def _cos_sin(t):
    """``(cos_lo, cos_hi, sin_lo, sin_hi)`` of ``psi = atan(t)`` for ``t`` in ``[0, BIG]`` (or
    ``-0``): ``cos = 1 / sqrt(1 + t^2)``, ``sin = t cos``, from one rounded sqrt and quotient and
    products by ``LO_SLACK`` / ``HI_SLACK`` (see there): each bound on its side of the real
    value. ``t r`` is subnormal for ``t < 2^-1022``, where the slack products cannot move it:
    the sine's lower bound then steps one subnormal down (``sin < t``, and ``t - sin < t^3 / 2``
    is far below 2^-1074), which leaves a normal bound unchanged."""
    r = 1.0 / np.sqrt(1.0 + t * t)
    st = t * r
    return r * LO_SLACK, r * HI_SLACK, _mx(0.0, st * LO_SLACK - 2.0**-1074), st * HI_SLACK


@njit(cache=True, inline="always", error_model="numpy")
def _polar_steps(a, b, c, d, e, f, g, h):
    """The polar constraint on ``u = [a, b]``, ``v = [c, d]``, ``rho = [e, f]``, ``t = [g, h]``
    (``t = tan(psi)``, all ``>= 0`` or ``-0``) in one sweep: ``v = u t`` backward and forward,
    ``rho^2 = u^2 + v^2`` forward and backward, ``u ∩= rho cos``, ``v ∩= rho sin``
    (:func:`_cos_sin`), then ``t ∩= v / u``; every rounding outward, every solution kept.
    Returns the 8 bounds and whether the intermediate squares stayed non-empty."""
    # v = u t (u, v >= 0, t >= 0; t may be +inf above; 0 / 0 and 0 * inf are NaN: ignored)
    a = _mx(a, _dnf(c / h))
    b = _mn(b, up_raw(d / g))
    c = _mx(c, _dnf(a * g))
    d = _mn(d, up_pos(b * h))
    # rho^2 = u^2 + v^2 (u2l, v2l and their sum enter _mx first: guarded)
    u2l, u2h = down(a * a), up_pos(b * b)
    v2l, v2h = down(c * c), up_pos(d * d)
    sl = _mx(_mx(_down_tiny(u2l + v2l), down_pos(e * e)), 0.0)
    sh = _mn(up_pos(u2h + v2h), up_pos(f * f))
    e = _mx(e, down_pos(np.sqrt(sl)))
    f = _mn(f, up_pos(np.sqrt(_mx(sh, 0.0))))
    u2l = _mx(u2l, down_raw(sl - v2h))
    u2h = _mn(u2h, up_raw(sh - v2l))
    v2l = _mx(v2l, down_raw(sl - u2h))
    v2h = _mn(v2h, up_raw(sh - u2l))
    a = _mx(a, down_pos(np.sqrt(_mx(u2l, 0.0))))
    b = _mn(b, up_pos(np.sqrt(_mx(u2h, 0.0))))
    c = _mx(c, down_pos(np.sqrt(_mx(v2l, 0.0))))
    d = _mn(d, up_pos(np.sqrt(_mx(v2h, 0.0))))
    # u ∩= rho cos(psi), v ∩= rho sin(psi), cos and sin of the t bounds by _cos_sin (bounds of
    # t above BIG: cos >= 0, sin <= 1; a lower bound of t lowered to BIG is still one)
    big = h > BIG
    cos_l, _, _, sin_h = _cos_sin(_mn(h, BIG))
    cos_l = 0.0 if big else cos_l
    sin_h = 1.0 if big else _mn(1.0, sin_h)
    _, cos_h, sin_l, _ = _cos_sin(_mn(g, BIG))
    cos_h = _mn(1.0, cos_h)
    a = _mx(a, down_pos(e * cos_l))
    b = _mn(b, up_pos(f * cos_h))
    c = _mx(c, down_pos(e * sin_l))
    d = _mn(d, up_pos(f * sin_h))
    # t = v / u again: what u and v gained above reaches t in this pass, not the next one
    g = _mx(g, _dnf(c / b))
    h = _mn(h, up_raw(d / a))
    return a, b, c, d, e, f, g, h, (sl <= sh) & (u2l <= u2h) & (v2l <= v2h)


@njit(cache=True, inline="always", error_model="numpy")
def _polar_lane_pass(L, i):
    """One pass of the polar lane ``i`` (the polar constraint on ``(u, v, rho, t)`` alone, rows
    ``UL..TH``): its 8 new bounds, whether it stays non-empty, whether it shrank some width by
    ``RELATIVE_STOP``. :func:`_lane_pass` without its difference steps (``u``, ``v`` are the
    lane's own variables here): :func:`_polar_steps`, with the same invariants (every bound
    ``>= 0`` or ``-0`` in a lane that stays non-empty, NaN only where ``_mx`` / ``_mn`` ignore
    it); every result holds every solution of the lane."""
    C = CHUNK
    a0, b0, c0, d0 = L[UL * C + i], L[UH * C + i], L[VL * C + i], L[VH * C + i]
    e0, f0, g0, h0 = L[RL * C + i], L[RH * C + i], L[TL * C + i], L[TH * C + i]
    # the polar steps (t = v / u at their end, and before the first pass: _to_fixpoint's entry)
    a, b, c, d, e, f, g, h, ok = _polar_steps(a0, b0, c0, d0, e0, f0, g0, h0)
    good = ok & (a <= b) & (c <= d) & (e <= f) & (g <= h)
    prog = (_shrunk(a0, b0, a, b) | _shrunk(c0, d0, c, d) | _shrunk(e0, f0, e, f)
            | _shrunk(g0, h0, g, h))
    return (a, b, c, d, e, f, g, h, good, prog)


@njit(cache=True, error_model="numpy")
def _polar_passes(n, L):
    """One pass of the polar lanes ``0..n-1`` (straight-line code: a SIMD loop)."""
    C = CHUNK
    for i in range(n):
        r = _polar_lane_pass(L, i)
        L[UL * C + i] = r[0]
        L[UH * C + i] = r[1]
        L[VL * C + i] = r[2]
        L[VH * C + i] = r[3]
        L[RL * C + i] = r[4]
        L[RH * C + i] = r[5]
        L[TL * C + i] = r[6]
        L[TH * C + i] = r[7]
        L[OK * C + i] = L[OK * C + i] if r[8] else 0.0
        L[PROG * C + i] = 1.0 if r[9] else 0.0


@njit(cache=True, error_model="numpy")
def _polar_passes_live(n, L):
    """:func:`_polar_passes` on the lanes with ``L[ACT]`` set; the others keep their state."""
    C = CHUNK
    for i in range(n):
        r = _polar_lane_pass(L, i)
        act = L[ACT * C + i] > 0.5
        L[UL * C + i] = r[0] if act else L[UL * C + i]
        L[UH * C + i] = r[1] if act else L[UH * C + i]
        L[VL * C + i] = r[2] if act else L[VL * C + i]
        L[VH * C + i] = r[3] if act else L[VH * C + i]
        L[RL * C + i] = r[4] if act else L[RL * C + i]
        L[RH * C + i] = r[5] if act else L[RH * C + i]
        L[TL * C + i] = r[6] if act else L[TL * C + i]
        L[TH * C + i] = r[7] if act else L[TH * C + i]
        L[OK * C + i] = (L[OK * C + i] if r[8] else 0.0) if act else L[OK * C + i]
        L[PROG * C + i] = (1.0 if r[9] else 0.0) if act else L[PROG * C + i]


@njit(cache=True, error_model="numpy")
def _passes(n, L, fixstop=False):
    """One pass over lanes ``0..n-1`` (straight-line code: a SIMD loop). With ``fixstop`` a
    lane that moved no bound has ``L[PROG]`` 0 (see :func:`_to_fixpoint`)."""
    C = CHUNK
    for i in range(n):
        r = _lane_pass(L, i)
        L[UL * C + i] = r[0]
        L[UH * C + i] = r[1]
        L[VL * C + i] = r[2]
        L[VH * C + i] = r[3]
        L[RL * C + i] = r[4]
        L[RH * C + i] = r[5]
        L[TL * C + i] = r[6]
        L[TH * C + i] = r[7]
        L[SXL * C + i] = r[8]
        L[SXH * C + i] = r[9]
        L[MXL * C + i] = r[10]
        L[MXH * C + i] = r[11]
        L[SYL * C + i] = r[12]
        L[SYH * C + i] = r[13]
        L[MYL * C + i] = r[14]
        L[MYH * C + i] = r[15]
        L[OK * C + i] = L[OK * C + i] if r[16] else 0.0
        L[PROG * C + i] = 1.0 if r[17] & (r[18] | (not fixstop)) else 0.0


@njit(cache=True, error_model="numpy")
def _passes_live(n, L, fixstop=False):
    """:func:`_passes` on the lanes with ``L[ACT]`` set; the others keep their state (selects:
    a SIMD loop)."""
    C = CHUNK
    for i in range(n):
        r = _lane_pass(L, i)
        act = L[ACT * C + i] > 0.5
        L[UL * C + i] = r[0] if act else L[UL * C + i]
        L[UH * C + i] = r[1] if act else L[UH * C + i]
        L[VL * C + i] = r[2] if act else L[VL * C + i]
        L[VH * C + i] = r[3] if act else L[VH * C + i]
        L[RL * C + i] = r[4] if act else L[RL * C + i]
        L[RH * C + i] = r[5] if act else L[RH * C + i]
        L[TL * C + i] = r[6] if act else L[TL * C + i]
        L[TH * C + i] = r[7] if act else L[TH * C + i]
        L[SXL * C + i] = r[8] if act else L[SXL * C + i]
        L[SXH * C + i] = r[9] if act else L[SXH * C + i]
        L[MXL * C + i] = r[10] if act else L[MXL * C + i]
        L[MXH * C + i] = r[11] if act else L[MXH * C + i]
        L[SYL * C + i] = r[12] if act else L[SYL * C + i]
        L[SYH * C + i] = r[13] if act else L[SYH * C + i]
        L[MYL * C + i] = r[14] if act else L[MYL * C + i]
        L[MYH * C + i] = r[15] if act else L[MYH * C + i]
        L[OK * C + i] = (L[OK * C + i] if r[16] else 0.0) if act else L[OK * C + i]
        L[PROG * C + i] = (1.0 if r[17] & (r[18] | (not fixstop)) else 0.0) if act else L[PROG * C + i]


@njit(cache=True, inline="always")
def _flip(sign, lo, hi):
    """``sign * [lo, hi]`` for ``sign = ±1`` (exact)."""
    if sign > 0.0:
        return lo, hi
    return -hi, -lo


@njit(cache=True, error_model="numpy")
def _to_fixpoint(n, L, S, orig, pl, ph, t0l, t0h, passes, polar=False, fixstop=False):
    """Load the ``n`` lanes' tangents of their ψ bounds ``pl``, ``ph`` and run passes (at most
    ``passes``) until every lane has stopped; the final states are left in ``L``, each lane at
    its slot. The passes are :func:`_passes` (range-bearing lanes: ``t = v / u`` from their
    ``u``, ``v`` rows first) or, with ``polar``, :func:`_polar_passes` (polar lanes: rows
    ``SXL..MYH`` unused; their ``TL``, ``TH`` rows hold ``v / u`` on entry); either way the
    tangents are intersected with it. After each pass from the second on, a lane stops if it
    shrank no width by ``RELATIVE_STOP`` or is empty (a dead lane, ``L[OK]`` 0 from the start,
    stops there too; it should have ``pl = 0``, ``ph = pi/2``: no libm call). With ``fixstop``
    (the unicycle's lanes) a lane also stops after a pass that moved none of its bounds: it is
    at a fixpoint of the pass, so the passes it is spared would give the same bounds (a
    subnormal width counts as shrunk by ``RELATIVE_STOP`` even when nothing moved, and such a
    lane took all ``passes``, each slowed by subnormal operands).

    While at least half the lanes take passes they stay in place (:func:`_passes_live`: the
    stopped ones keep their state); then the others are packed into ``S`` (``orig``: their
    slots), contracted there, and each written back when it stops."""
    C = CHUNK
    # the libm calls on a packed list of the lanes that need them (no branch to mispredict);
    # elsewhere _tan_lo is 0 (pl <= 0) and _tan_hi +inf (ph >= HALF_PI_LO)
    m = 0
    for i in range(n):
        t0l[i] = 0.0
        orig[m] = i
        m += 1 if pl[i] > 0.0 else 0
    for k in range(m):
        t0l[orig[k]] = _tan_lo(pl[orig[k]])
    m = 0
    for i in range(n):
        t0h[i] = INF
        orig[m] = i
        m += 1 if ph[i] < HALF_PI_LO else 0
    for k in range(m):
        t0h[orig[k]] = _tan_hi(ph[orig[k]])
    if not polar:  # t = v / u from the lane's own u, v (a polar lane's entry has set it)
        for i in range(n):
            L[TL * C + i] = _mx(0.0, _dnf(L[VL * C + i] / L[UH * C + i]))
            L[TH * C + i] = _mn(INF, up_raw(L[VH * C + i] / L[UL * C + i]))
    for i in range(n):
        L[TL * C + i] = _mx(L[TL * C + i], t0l[i])
        L[TH * C + i] = _mn(L[TH * C + i], t0h[i])
        L[ACT * C + i] = 1.0
    if polar:
        _polar_passes(n, L)
    else:
        _passes(n, L, fixstop)
    p = 1
    na = n
    while p < passes and 2 * na >= n:
        if polar:
            if na == n:
                _polar_passes(n, L)
            else:
                _polar_passes_live(n, L)
        elif na == n:
            _passes(n, L, fixstop)
        else:
            _passes_live(n, L, fixstop)
        na = 0
        for i in range(n):
            go = (L[ACT * C + i] > 0.5) & (L[OK * C + i] > 0.5) & (L[PROG * C + i] > 0.5)
            go = go & (p + 1 < passes)
            L[ACT * C + i] = 1.0 if go else 0.0
            na += 1 if go else 0
        p += 1
    if na == 0:
        return
    m = 0
    for i in range(n):
        if L[ACT * C + i] > 0.5:
            orig[m] = i
            for r in range(ROWS):
                if not (polar and SXL <= r <= MYH):
                    S[r * C + m] = L[r * C + i]
            m += 1
    while m > 0:
        if polar:
            _polar_passes(m, S)
        else:
            _passes(m, S, fixstop)
        k = 0
        for i in range(m):
            if S[OK * C + i] < 0.5 or S[PROG * C + i] < 0.5 or p + 1 == passes:
                o = orig[i]
                for r in range(OK + 1):
                    if not (polar and SXL <= r <= MYH):
                        L[r * C + o] = S[r * C + i]
                continue
            if k != i:
                orig[k] = orig[i]
                for r in range(ROWS):
                    if not (polar and SXL <= r <= MYH):
                        S[r * C + k] = S[r * C + i]
            k += 1
        m = k
        p += 1


@njit(cache=True, inline="always")
def _lane(L, m, ul, uh, vl, vh, rl, rh, xs, ys, sxl, sxh, mxl, mxh, syl, syh, myl, myh):
    """Lane ``m``'s state from one quadrant piece of a box (x variables negated by ``xs``, y by ``ys``)."""
    C = CHUNK
    L[UL * C + m], L[UH * C + m], L[VL * C + m], L[VH * C + m] = ul, uh, vl, vh
    L[RL * C + m], L[RH * C + m] = rl, rh
    L[OK * C + m] = 1.0
    L[SXL * C + m], L[SXH * C + m] = _flip(xs, sxl, sxh)
    L[MXL * C + m], L[MXH * C + m] = _flip(xs, mxl, mxh)
    L[SYL * C + m], L[SYH * C + m] = _flip(ys, syl, syh)
    L[MYL * C + m], L[MYH * C + m] = _flip(ys, myl, myh)


@njit(cache=True, error_model="numpy")
def psi_from_tangents(n, L, t0l, t0h, pl, ph, idx):
    """``psi ∩= atan(t)`` for lanes ``0..n-1`` (final states in ``L``; ``t0l``, ``t0h`` the
    tangents they were loaded with, ``pl``, ``ph`` their ψ bounds): only where the lane is
    alive and its ``t`` bound moved (``atan(tan(psi))`` holds ψ already), on a packed list of
    those lanes (``idx``, at least ``n`` long: no branch to mispredict). Outward: ``_atan_lo``,
    ``_atan_hi``."""
    C = CHUNK
    m = 0
    for i in range(n):
        idx[m] = i
        m += 1 if (L[TL * C + i] != t0l[i]) & (L[OK * C + i] > 0.5) else 0
    for k in range(m):
        i = idx[k]
        pl[i] = _mx(pl[i], _atan_lo(L[TL * C + i]))
    m = 0
    for i in range(n):
        idx[m] = i
        m += 1 if (L[TH * C + i] != t0h[i]) & (L[OK * C + i] > 0.5) else 0
    for k in range(m):
        i = idx[k]
        ph[i] = _mn(ph[i], _atan_hi(L[TH * C + i]))


def in_place(kernel, arrs):
    """``kernel(flat)`` on the C-contiguous flat views of the ``(N, 2)`` arrays ``arrs`` (copies
    of the others, written back after): a SIMD kernel's in-place call; returns its result."""
    if all(a.flags.c_contiguous for a in arrs):
        return kernel([a.reshape(-1) for a in arrs])
    flat = [np.ascontiguousarray(a).reshape(-1) for a in arrs]
    ok = kernel(flat)
    for a, f in zip(arrs, flat):
        a[...] = f.reshape(a.shape)
    return ok
