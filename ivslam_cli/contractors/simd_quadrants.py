"""Quadrant pieces and periodic angle meets for the SIMD range-bearing and unicycle contractors.

The world bearing of a quadrant piece is ``phi = s psi + c`` with ``psi in [0, pi/2]``
(:func:`_to_psi`, :func:`_from_psi`, outward); :func:`_meet` is
:func:`~ivslam_cli.interval.angles.angle_meet` with the same bounds, :func:`_meet3` /
:func:`_meet3t` the same as selects for a SIMD loop. Every result holds every angle of the
exact operation (all roundings outward).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_polar import _two_pi_times
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
    down_raw,
    up,
    up_raw,
)

E = EMPTY_LO
F = EMPTY_HI


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


@njit(cache=True, inline="always", error_model="numpy")
def _meet3(tl, th, al, ah):
    """:func:`_meet` as selects, for ``w(t) + w(a) < 6`` with moderate bounds (else ``ok`` is
    False and the result is to be ignored): the pieces of the copies ``k0 - 1, k0, k0 + 1``,
    shifted as ``angle_meet`` shifts them, hulled. Where ``ok`` every sum and product here is
    finite, so its roundings need no NaN guard."""
    ok = ((th - tl) + (ah - al) < 6.0) & (-1e15 < tl) & (th < 1e15) & (-1e15 < al) & (ah < 1e15)
    k0 = np.floor((0.5 * (tl + th) - 0.5 * (al + ah)) * INV_TWO_PI_LO + 0.5)
    lo, hi = E, F
    for dk in range(-1, 2):
        k = k0 + dk
        ol = down_raw(k * (TWO_PI_LO if k >= 0.0 else TWO_PI_HI))
        oh = up_raw(k * (TWO_PI_HI if k >= 0.0 else TWO_PI_LO))
        sl = al if k == 0.0 else down_raw(al + ol)
        sh = ah if k == 0.0 else up_raw(ah + oh)
        pl = sl if sl > tl else tl
        ph = sh if sh < th else th
        meets = pl <= ph
        lo = pl if meets & (pl < lo) else lo
        hi = ph if meets & (ph > hi) else hi
    return lo, hi, ok


@njit(cache=True, inline="always", error_model="numpy")
def _meet3t(tl, th, al, ah):
    """:func:`_meet3` that also takes the cases where ``angle_meet`` returns ``[t]`` as it is
    (``[a]`` at least a turn wide, ``[t]`` unbounded), for non-empty ``[t]`` and ``[a]``."""
    whole = (ah - al >= TWO_PI_LO) | (tl == -INF) | (th == INF)
    lo, hi, ok = _meet3(tl, th, al, ah)
    return (tl if whole else lo), (th if whole else hi), whole | ok


@njit(cache=True, inline="always", error_model="numpy")
def _meet1t(tl, th, al, ah):
    """``simd_quadrants._meet3t`` (``angle_meet`` of non-empty ``[t]``, ``[a]`` as selects, ``ok``
    False where it does not apply) from the one copy ``k0`` of ``[a]`` nearest to ``[t]``: for
    ``w(t) + w(a) < 6`` and bounds below 1e6 in magnitude the copies ``k0 ± 1`` cannot meet
    ``[t]`` (their midpoints are at least ``pi - 1e-9`` from ``[t]``'s, a meeting copy's within
    ``3 + 1e-9``), so ``_meet3``'s hull is ``k0``'s piece, the same bounds."""
    whole = (ah - al >= TWO_PI_LO) | (tl == -INF) | (th == INF)
    ok = ((th - tl) + (ah - al) < 6.0) & (-1e6 < tl) & (th < 1e6) & (-1e6 < al) & (ah < 1e6)
    k = np.floor((0.5 * (tl + th) - 0.5 * (al + ah)) * INV_TWO_PI_LO + 0.5)
    ol = down_raw(k * (TWO_PI_LO if k >= 0.0 else TWO_PI_HI))
    oh = up_raw(k * (TWO_PI_HI if k >= 0.0 else TWO_PI_LO))
    sl = al if k == 0.0 else down_raw(al + ol)
    sh = ah if k == 0.0 else up_raw(ah + oh)
    pl = sl if sl > tl else tl
    ph = sh if sh < th else th
    meets = pl <= ph
    lo = pl if meets else E
    hi = ph if meets else F
    return (tl if whole else lo), (th if whole else hi), whole | ok


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
