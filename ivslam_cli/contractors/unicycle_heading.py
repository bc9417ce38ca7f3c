"""The heading step of the SIMD unicycle kernel (:mod:`~ivslam_cli.contractors.ctc_unicycle_simd`).

The heading block of :func:`~ivslam_cli.contractors.ctc_unicycle.unicycle_pass` (``u = w dt +
qth``, ``u = th1 - th0`` mod 2 pi by ``_angle_difference``, then ``bwd_add`` and ``bwd_mul`` back
onto ``w, dt, qth``) for the slots of the slot buffer, as select loops that give the bounds of
the scalar :func:`_heading` bit for bit: :func:`_headings` with the one-copy meet
:func:`~ivslam_cli.contractors.simd_quadrants._meet1t` for every slot; the slots it does not
take (a sum of widths of 6 or more, most often a wide ``w dt``) again with :func:`_meet_wide`,
which adds ``angle_meet``'s own scans (:func:`_meet_scan`) where they end within three copies;
the few left take :func:`_heading`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.simd_polar_lanes import _mn, _mx
from ivslam_cli.contractors.simd_quadrants import _angle_difference, _meet1t
from ivslam_cli.contractors.unicycle_slots import DT, HOK, LIVE, NB, NEED, QT, T0, T1, W
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, add, bwd_add, bwd_mul, mul
from ivslam_cli.interval.arith_select import bwd_mul_s, mul_s
from ivslam_cli.interval.rounding import (
    INF,
    INV_TWO_PI_HI,
    INV_TWO_PI_LO,
    TWO_PI_HI,
    TWO_PI_LO,
    down,
    up,
)

E = EMPTY_LO
F = EMPTY_HI


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



@njit(cache=True, error_model="numpy")
def _headings(B):
    """The heading block of ``unicycle_pass`` (:func:`_heading`) for every slot, as selects (a
    SIMD loop), written back in the live slots where it holds: the same float operations as
    ``mul``, ``add``, ``_angle_difference`` (with ``_meet``: :func:`_meet1t`), ``bwd_add`` and ``bwd_mul``.
    ``B[HOK]``: 1 if it holds, 0 if the box is emptied, -1 if ``_meet1t`` does not apply (then
    :func:`_heading` is to be run). Only the slots with ``B[NEED]`` 1 take the step (their
    ``WID0`` rows hold the widths before it)."""
    N = NB
    for j in range(N):
        wl, wh, dl, dh = B[W * N + j], B[(W + 1) * N + j], B[DT * N + j], B[(DT + 1) * N + j]
        ql, qh = B[QT * N + j], B[(QT + 1) * N + j]
        t1l, t1h = B[T1 * N + j], B[(T1 + 1) * N + j]
        t0l, t0h = B[T0 * N + j], B[(T0 + 1) * N + j]
        pl, ph = mul_s(wl, wh, dl, dh)
        ul, uh = down(pl + ql), up(ph + qh)
        # (an empty meet empties the box whatever _meet1t returns after it)
        ul, uh, ok1 = _meet1t(ul, uh, down(t1l - t0h), up(t1h - t0l))
        t1l, t1h, ok2 = _meet1t(t1l, t1h, down(ul + t0l), up(uh + t0h))
        t0l, t0h, ok3 = _meet1t(t0l, t0h, down(t1l - uh), up(t1h - ul))
        # bwd_add(u, p, qth): p ∩= u - qth, qth ∩= u - p
        pl, ph = _mx(pl, down(ul - qh)), _mn(ph, up(uh - ql))
        ql, qh = _mx(ql, down(ul - ph)), _mn(qh, up(uh - pl))
        good = (ul <= uh) & (t1l <= t1h) & (t0l <= t0h) & (pl <= ph) & (ql <= qh)
        wl, wh, dl, dh = bwd_mul_s(pl, ph, wl, wh, dl, dh)
        good = good & (wl <= wh)
        hok = (1.0 if good else 0.0) if (ok1 & ok2 & ok3) else -1.0
        need = B[NEED * N + j] > 0.5
        put = (hok > 0.5) & (B[LIVE * N + j] > 0.5) & need
        B[HOK * N + j] = hok if need else B[HOK * N + j]
        B[T1 * N + j] = t1l if put else B[T1 * N + j]
        B[(T1 + 1) * N + j] = t1h if put else B[(T1 + 1) * N + j]
        B[T0 * N + j] = t0l if put else B[T0 * N + j]
        B[(T0 + 1) * N + j] = t0h if put else B[(T0 + 1) * N + j]
        B[QT * N + j] = ql if put else B[QT * N + j]
        B[(QT + 1) * N + j] = qh if put else B[(QT + 1) * N + j]
        B[W * N + j] = wl if put else B[W * N + j]
        B[(W + 1) * N + j] = wh if put else B[(W + 1) * N + j]
        B[DT * N + j] = dl if put else B[DT * N + j]
        B[(DT + 1) * N + j] = dh if put else B[(DT + 1) * N + j]



@njit(cache=True, inline="always", error_model="numpy")
def _shifted(k, fl, fh):
    """:func:`_shift` as selects."""
    ol = down(k * (TWO_PI_LO if k >= 0.0 else TWO_PI_HI))
    oh = up(k * (TWO_PI_HI if k >= 0.0 else TWO_PI_LO))
    return (fl if k == 0.0 else down(fl + ol)), (fh if k == 0.0 else up(fh + oh))



@njit(cache=True, inline="always", error_model="numpy")
def _meet_scan(tl, th, al, ah):
    """:func:`~ivslam_cli.interval.angles.angle_meet` of non-empty ``[t]``, ``[a]`` as selects,
    the same bounds, where its scans end within three copies of ``[a]`` (else ``ok`` is False
    and the result is to be ignored): its whole cases and fast path; then from ``k_lo - 1`` up,
    the first copy (shifted as ``shift`` shifts it) that meets ``[t]`` gives the lower bound,
    from ``k_hi + 1`` down the first one the upper bound, none meeting from below the empty
    set. Finite bounds there (``[a]`` narrower than a turn, ``[t]`` bounded)."""
    whole = (ah - al >= TWO_PI_LO) | (tl == -INF) | (th == INF)
    # the fast path: one copy at most meets [t], and k = 0 does (inter(t, a))
    fast = up(up(th - tl) + up(ah - al)) < TWO_PI_LO
    fl = tl if tl > al else al
    fh = th if th < ah else ah
    fast = fast & (fl <= fh)
    # k in (t - a) / 2 pi (sub, then mul by [INV_TWO_PI_LO, INV_TWO_PI_HI])
    ql, qh = mul_s(down(tl - ah), up(th - al), INV_TWO_PI_LO, INV_TWO_PI_HI)
    inside = (qh - ql <= 1e6) & (-1e15 < ql) & (qh < 1e15)
    klo, khi = np.ceil(ql), np.floor(qh)
    lo, found_lo = E, False
    hi, found_hi = F, False
    for d in range(3):
        k = klo - 1.0 + d
        sl, sh = _shifted(k, al, ah)
        pl = tl if tl > sl else sl
        ph = th if th < sh else sh
        hit = (k <= khi + 1.0) & (pl <= ph) & (not found_lo)
        lo = pl if hit else lo
        found_lo = found_lo | hit
        k = khi + 1.0 - d
        sl, sh = _shifted(k, al, ah)
        pl = tl if tl > sl else sl
        ph = th if th < sh else sh
        hit = (k >= klo - 1.0) & (pl <= ph) & (not found_hi)
        hi = ph if hit else hi
        found_hi = found_hi | hit
    none = (not found_lo) & (klo + 1.0 >= khi + 1.0)  # the whole scan from below, no copy met
    scan_ok = (found_lo & found_hi) | none
    lo = E if none else lo
    hi = F if none else hi
    rl = tl if whole else (fl if fast else (tl if not inside else lo))
    rh = th if whole else (fh if fast else (th if not inside else hi))
    return rl, rh, whole | fast | (not inside) | scan_ok


@njit(cache=True, inline="always", error_model="numpy")
def _meet_wide(tl, th, al, ah):
    """``_meet`` (``_angle_difference``'s meet) of non-empty ``[t]``, ``[a]`` as selects:
    :func:`_meet1t` where it applies, else :func:`_meet_scan` where ``_meet`` calls
    ``angle_meet`` and the scans end within three copies; ``ok`` False elsewhere."""
    lo1, hi1, ok1 = _meet1t(tl, th, al, ah)
    lo2, hi2, ok2 = _meet_scan(tl, th, al, ah)
    narrow = (((th - tl) + (ah - al) < 6.0) & (-1e15 < tl) & (th < 1e15) & (-1e15 < al)
              & (ah < 1e15))
    return (lo1 if ok1 else lo2), (hi1 if ok1 else hi2), ok1 | (ok2 & (not narrow))


# rows of the packed buffer of _headings_listed (slot t of the list at hb[r * NB + t])
HW, HDT, HQT, HT1, HT0, HOKP = 0, 2, 4, 6, 8, 10
HROWS = 11


@njit(cache=True, error_model="numpy")
def _headings_listed(hb, m):
    """:func:`_headings` on the ``m`` packed slots of ``hb`` (rows ``HW..HT0``: ``w, dt, qth,
    th1, th0`` lo and hi; a SIMD loop) with :func:`_meet_wide` for its meets: the headings
    :func:`_meet1t` does not take, as selects. ``hb[HOKP]``: 1 if the step holds (the bounds
    in ``hb`` are then its result), 0 if it empties the box, -1 if :func:`_meet_wide` does not
    apply either (then :func:`_heading` is to be run)."""
    N = NB
    for j in range(m):
        wl, wh, dl, dh = hb[HW * N + j], hb[(HW + 1) * N + j], hb[HDT * N + j], hb[(HDT + 1) * N + j]
        ql, qh = hb[HQT * N + j], hb[(HQT + 1) * N + j]
        t1l, t1h = hb[HT1 * N + j], hb[(HT1 + 1) * N + j]
        t0l, t0h = hb[HT0 * N + j], hb[(HT0 + 1) * N + j]
        pl, ph = mul_s(wl, wh, dl, dh)
        ul, uh = down(pl + ql), up(ph + qh)
        # (an empty meet empties the box whatever _meet_wide returns after it)
        ul, uh, ok1 = _meet_wide(ul, uh, down(t1l - t0h), up(t1h - t0l))
        t1l, t1h, ok2 = _meet_wide(t1l, t1h, down(ul + t0l), up(uh + t0h))
        t0l, t0h, ok3 = _meet_wide(t0l, t0h, down(t1l - uh), up(t1h - ul))
        # bwd_add(u, p, qth): p ∩= u - qth, qth ∩= u - p
        pl, ph = _mx(pl, down(ul - qh)), _mn(ph, up(uh - ql))
        ql, qh = _mx(ql, down(ul - ph)), _mn(qh, up(uh - pl))
        good = (ul <= uh) & (t1l <= t1h) & (t0l <= t0h) & (pl <= ph) & (ql <= qh)
        wl, wh, dl, dh = bwd_mul_s(pl, ph, wl, wh, dl, dh)
        good = good & (wl <= wh)
        hb[HOKP * N + j] = (1.0 if good else 0.0) if (ok1 & ok2 & ok3) else -1.0
        hb[HW * N + j], hb[(HW + 1) * N + j], hb[HDT * N + j], hb[(HDT + 1) * N + j] = wl, wh, dl, dh
        hb[HQT * N + j], hb[(HQT + 1) * N + j] = ql, qh
        hb[HT1 * N + j], hb[(HT1 + 1) * N + j] = t1l, t1h
        hb[HT0 * N + j], hb[(HT0 + 1) * N + j] = t0l, t0h


@njit(cache=True, error_model="numpy")
def _heading_step(B, row, idx, hb):
    """The heading step of the slots with ``B[NEED]`` 1 (:func:`_headings`; where ``_meet1t``
    does not apply, :func:`_headings_listed` on those slots packed into ``hb``, and
    :func:`_heading` where that does not apply either); ``B[NEED]`` is 0 after it."""
    N = NB
    _headings(B)
    m = 0
    for j in range(N):  # the heading steps outside _meet1t's range, packed
        idx[m] = j
        m += 1 if (B[NEED * N + j] > 0.5) & (B[LIVE * N + j] > 0.5) & (B[HOK * N + j] < -0.5) else 0
    for t in range(m):
        j = idx[t]
        for r, v in enumerate((W, DT, QT, T1, T0)):
            hb[2 * r * N + t], hb[(2 * r + 1) * N + t] = B[v * N + j], B[(v + 1) * N + j]
    _headings_listed(hb, m)
    for t in range(m):
        j = idx[t]
        hok = hb[HOKP * N + t]
        if hok > 0.5:
            for r, v in enumerate((W, DT, QT, T1, T0)):
                B[v * N + j], B[(v + 1) * N + j] = hb[2 * r * N + t], hb[(2 * r + 1) * N + t]
            B[HOK * N + j] = 1.0
        elif hok > -0.5:
            B[HOK * N + j] = 0.0
        else:
            for r in range(24):
                row[0, r] = B[r * N + j]
            good = _heading(row, 0)
            for r in range(24):
                B[r * N + j] = row[0, r]
            B[HOK * N + j] = 1.0 if good else 0.0
    for j in range(N):
        B[NEED * N + j] = 0.0
