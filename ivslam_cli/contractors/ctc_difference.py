"""Linear difference contractor: ``a = b - c`` (``dl = d_i - d_j``: Mustafa et al., Eq. (3)-(4)).

Forward ``a ∩= b - c``, backward ``b ∩= a + c``, ``c ∩= b - a``. For a linear constraint with
each variable occurring once, one forward-backward pass is the fixpoint (up to rounding): the
result is the smallest box holding every solution, widened by at most an ulp per bound.

The periodic form reads the constraint modulo 2 pi (``a = b - c + 2 k pi``, k integer), for
angles; each variable keeps its own branch (see
:func:`~ivslam_cli.interval.angles.angle_meet`).

Guarantee: every solution inside the input box is in the output box (outward rounding).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.interval.angles import angle_meet
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, add, inter, sub


@njit(cache=True)
def difference_scalar(al, ah, bl, bh, cl, ch):
    """Contract ``(a, b, c)`` under ``a = b - c``; all six bounds empty if no solution."""
    al, ah = inter(al, ah, *sub(bl, bh, cl, ch))
    bl, bh = inter(bl, bh, *add(al, ah, cl, ch))
    cl, ch = inter(cl, ch, *sub(bl, bh, al, ah))
    if not (al <= ah) or not (bl <= bh) or not (cl <= ch):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    return al, ah, bl, bh, cl, ch


@njit(cache=True)
def angle_difference_scalar(al, ah, bl, bh, cl, ch):
    """Contract ``(a, b, c)`` under ``a = b - c (mod 2 pi)``; each keeps its branch."""
    al, ah = angle_meet(al, ah, *sub(bl, bh, cl, ch))
    bl, bh = angle_meet(bl, bh, *add(al, ah, cl, ch))
    cl, ch = angle_meet(cl, ch, *sub(bl, bh, al, ah))
    if not (al <= ah) or not (bl <= bh) or not (cl <= ch):
        return EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI, EMPTY_LO, EMPTY_HI
    return al, ah, bl, bh, cl, ch


@njit(cache=True)
def difference_kernel(a, b, c, periodic):
    """In place over ``(N, 2)`` arrays; returns the mask of rows that stayed non-empty."""
    n = a.shape[0]
    ok = np.empty(n, dtype=np.bool_)
    for i in range(n):
        if periodic:
            r = angle_difference_scalar(a[i, 0], a[i, 1], b[i, 0], b[i, 1], c[i, 0], c[i, 1])
        else:
            r = difference_scalar(a[i, 0], a[i, 1], b[i, 0], b[i, 1], c[i, 0], c[i, 1])
        a[i, 0], a[i, 1], b[i, 0], b[i, 1], c[i, 0], c[i, 1] = r
        ok[i] = r[0] <= r[1]
    return ok
