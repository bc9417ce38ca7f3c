"""Pose sets of the landmark CSP (:mod:`.kernel`): unions of boxes, one per slice of the
circle of headings, their hulls, and the motion constraint between consecutive sets.

``PS`` ``(N, S, 3, 2)``: the set of node ``k`` holds one box per slice ``b`` (``BINS[b]``,
adjacent slices overlapping by an ulp so that their union holds every angle), empty when no
pose of that heading is possible; ``H[k]`` is its hull (``θ`` the shortest arc holding every
slice's interval). :func:`step_sets` contracts the sets of nodes ``k`` and ``k + 1`` by the
pose increment ``U[k]`` slice pair by slice pair, each slice keeping the hull of what its
pairs allow. Every bound is rounded outward: the union of a node's boxes holds every pose
the constraints allow.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_range_bearing import range_bearing_pass
from ivslam_cli.interval.angles import angle_meet
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, INF, add, sub
from ivslam_cli.interval.rounding import PI_HI, TWO_PI_HI, TWO_PI_LO, down, up

STEP_NONE = 0  # no motion constraint between node k and k + 1 (the next robot's chain starts)


# ------------------------------------------------------------------ slices of the circle
@njit(cache=True)
def make_bins(S):
    """``(S, 2)``: slice ``b`` covers ``[−π + 2πb/S, −π + 2π(b+1)/S]``, each end rounded
    outward (neighbours overlap by an ulp; the union holds ``[−π, π]``)."""
    B = np.empty((S, 2))
    for b in range(S):
        B[b, 0] = down(-math.pi + 2.0 * math.pi * b / S)
        B[b, 1] = up(-math.pi + 2.0 * math.pi * (b + 1) / S)
    B[0, 0] = -PI_HI
    B[S - 1, 1] = PI_HI
    return B


@njit(cache=True)
def _bin_of(t, S):
    """The slice holding angle ``t`` (any branch), up to rounding (callers try neighbours)."""
    u = (t + math.pi) / (2.0 * math.pi)
    u = u - math.floor(u)
    b = int(u * S)
    return min(max(b, 0), S - 1)


@njit(cache=True)
def _empty(PS, k, b):
    return not (PS[k, b, 0, 0] <= PS[k, b, 0, 1])


@njit(cache=True)
def live_slices(PS, k):
    """How many slices of node ``k``'s set are not empty."""
    n = 0
    for b in range(PS.shape[1]):
        if not _empty(PS, k, b):
            n += 1
    return n


@njit(cache=True)
def _set_empty_at(acc, b):
    """Box ``acc[b]`` (a (3, 2) box of ``acc``) empty. Indexed, not a view: numba counts
    references to a view on every call."""
    for d in range(3):
        acc[b, d, 0] = EMPTY_LO
        acc[b, d, 1] = EMPTY_HI


@njit(cache=True)
def _set_empty_slices(acc):
    """Every box of ``acc`` (S, 3, 2) empty."""
    for b in range(acc.shape[0]):
        _set_empty_at(acc, b)


@njit(cache=True)
def _hull_into(acc, b, xl, xh, yl, yh, tl, th):
    """``acc[b]`` (a (3, 2) box of ``acc``) ∪= the box (the empty one is neutral). Indexed,
    not a view: numba counts references to a view on every call."""
    if acc[b, 0, 0] <= acc[b, 0, 1]:
        acc[b, 0, 0] = min(acc[b, 0, 0], xl)
        acc[b, 0, 1] = max(acc[b, 0, 1], xh)
        acc[b, 1, 0] = min(acc[b, 1, 0], yl)
        acc[b, 1, 1] = max(acc[b, 1, 1], yh)
        acc[b, 2, 0] = min(acc[b, 2, 0], tl)
        acc[b, 2, 1] = max(acc[b, 2, 1], th)
    else:
        acc[b, 0, 0], acc[b, 0, 1], acc[b, 1, 0], acc[b, 1, 1], acc[b, 2, 0], acc[b, 2, 1] = xl, xh, yl, yh, tl, th


@njit(cache=True)
def set_from_box(PS, k, box, BINS):
    """``PS[k]`` = the pieces of the box ``(3, 2)`` in each slice (a heading of a whole turn or
    more, or unbounded: every slice, whole). Headings are matched modulo 2π."""
    S = PS.shape[1]
    tl = box[2, 0]
    th = box[2, 1]
    whole = not (th - tl < TWO_PI_LO)
    for b in range(S):
        if whole:
            pl, ph = BINS[b, 0], BINS[b, 1]
        else:
            pl, ph = angle_meet(BINS[b, 0], BINS[b, 1], tl, th)
        if pl <= ph and box[0, 0] <= box[0, 1] and box[1, 0] <= box[1, 1]:
            PS[k, b, 0, 0], PS[k, b, 0, 1] = box[0, 0], box[0, 1]
            PS[k, b, 1, 0], PS[k, b, 1, 1] = box[1, 0], box[1, 1]
            PS[k, b, 2, 0], PS[k, b, 2, 1] = pl, ph
        else:
            _set_empty_at(PS[k], b)


@njit(cache=True)
def _circular_hull(h_lo, h_hi, n, thl, thh):
    """Hull of the ``n`` increasing pieces ``[h_lo, h_hi]`` of ``[thl, thh]``, on the circle
    when ``[thl, thh]`` is a whole turn: the largest gap (the one across the wrap included) is
    left out. Pieces are sorted and disjoint up to shared ends."""
    lo = h_lo[0]
    hi = h_hi[n - 1]
    if not (thh - thl >= TWO_PI_LO) or n < 2:
        return lo, hi
    # the gap across the wrap: from the last piece's end to the first piece's start + 2π
    best = down(down(h_lo[0] + TWO_PI_LO) - h_hi[n - 1])
    cut = -1
    for i in range(n - 1):
        g = h_lo[i + 1] - h_hi[i]
        if g > best:
            best = g
            cut = i
    if cut < 0:
        return lo, hi
    # start after the gap, wrap once (the arc holds every piece, shifted by 2π or not)
    return min(h_lo[cut + 1], down(h_lo[0] + TWO_PI_LO)), up(h_hi[cut] + TWO_PI_HI)


@njit(cache=True)
def node_hull(PS, k, H, h_lo, h_hi):
    """``H[k]`` (3, 2) = the hull of node ``k``'s set: x, y hulls, θ the shortest arc holding
    every slice's interval. Returns False (``H[k]`` empty) when the set is empty."""
    S = PS.shape[1]
    n = 0
    xl, xh, yl, yh = INF, -INF, INF, -INF
    for b in range(S):
        if _empty(PS, k, b):
            continue
        xl = min(xl, PS[k, b, 0, 0])
        xh = max(xh, PS[k, b, 0, 1])
        yl = min(yl, PS[k, b, 1, 0])
        yh = max(yh, PS[k, b, 1, 1])
        h_lo[n] = PS[k, b, 2, 0]
        h_hi[n] = PS[k, b, 2, 1]
        n += 1
    if n == 0:
        _set_empty_at(H, k)
        return False
    tl, th = _circular_hull(h_lo, h_hi, n, -PI_HI, PI_HI)
    H[k, 0, 0], H[k, 0, 1], H[k, 1, 0], H[k, 1, 1], H[k, 2, 0], H[k, 2, 1] = xl, xh, yl, yh, tl, th
    return True


@njit(cache=True)
def all_hulls(PS, H):
    S = PS.shape[1]
    h_lo = np.empty(S)
    h_hi = np.empty(S)
    for k in range(PS.shape[0]):
        node_hull(PS, k, H, h_lo, h_hi)


# ------------------------------------------------------------------ motion
@njit(cache=True)
def step_sets(PS, H, k, kind, U, BINS, accA, accC, h_lo, h_hi, ver, stepdone, clock):
    """Contract the sets of nodes ``k`` and ``k + 1`` with motion step ``k``, slice pair by
    slice pair; False (nothing written) if no pair has a solution. ``accA``, ``accC``: (S, 3,
    2) work arrays. Skipped when neither set changed since the step last ran (``ver``: the
    ``clock`` value of a set's last change; ``stepdone``: of the step's last run)."""
    if kind[k] == STEP_NONE:
        return True
    if ver[k] <= stepdone[k] and ver[k + 1] <= stepdone[k]:
        return True
    _set_empty_slices(accA)
    _set_empty_slices(accC)
    found = increment_pairs(PS, k, k + 1, (U[k, 0, 0], U[k, 0, 1], U[k, 1, 0], U[k, 1, 1], U[k, 2, 0], U[k, 2, 1]),
                            accA, accC)
    if not found:
        stepdone[k] = clock[0]
        return False
    _commit(PS, H, k, accA, h_lo, h_hi, ver, clock)
    _commit(PS, H, k + 1, accC, h_lo, h_hi, ver, clock)
    stepdone[k] = clock[0]
    return True


@njit(cache=True)
def increment_pairs(PS, k, l, inc, accA, accC):
    """``accA`` (slices of node ``k``) and ``accC`` (of node ``l``) ∪= what the increment
    ``inc`` (``ρ``, ``α``, ``δθ`` as lo/hi pairs: node ``l`` in the frame of node ``k``) allows,
    slice pair by slice pair (a slice of ``k`` reaches the one or two slices its heading turns
    into). True if some pair has a solution."""
    S = PS.shape[1]
    w = TWO_PI_HI / S
    rl, rh, al, ah, dl, dh = inc
    found = False
    for b in range(S):
        if _empty(PS, k, b):
            continue
        axl, axh, ayl, ayh = PS[k, b, 0, 0], PS[k, b, 0, 1], PS[k, b, 1, 0], PS[k, b, 1, 1]
        atl, ath = PS[k, b, 2, 0], PS[k, b, 2, 1]
        fl, fh = add(atl, ath, dl, dh)  # the heading at l
        if fh - fl >= TWO_PI_LO - w:
            b0 = 0
            nb = S
        else:
            b0 = _bin_of(fl, S) - 1
            nb = min(S, int((fh - fl) / w) + 3)
        for i in range(nb):
            c = (b0 + i) % S
            if _empty(PS, l, c):
                continue
            ctl, cth = angle_meet(PS[l, c, 2, 0], PS[l, c, 2, 1], fl, fh)
            if not (ctl <= cth):
                continue
            btl, bth = angle_meet(atl, ath, *sub(ctl, cth, dl, dh))
            if not (btl <= bth):
                continue
            r = range_bearing_pass(axl, axh, ayl, ayh, btl, bth,
                                   PS[l, c, 0, 0], PS[l, c, 0, 1], PS[l, c, 1, 0], PS[l, c, 1, 1], rl, rh, al, ah, 1)
            if not (r[0] <= r[1]):
                continue
            if r[5] - r[4] < bth - btl:  # the step's direction narrowed the heading at k
                ctl, cth = angle_meet(ctl, cth, *add(r[4], r[5], dl, dh))
                if not (ctl <= cth):
                    continue
            _hull_into(accA, b, r[0], r[1], r[2], r[3], r[4], r[5])
            _hull_into(accC, c, r[6], r[7], r[8], r[9], ctl, cth)
            found = True
    return found


@njit(cache=True)
def _commit(PS, H, k, NEW, h_lo, h_hi, ver, clock):
    """``PS[k] = NEW``; if that changes it, its hull is recomputed and ``ver[k]`` stamped."""
    same = True
    for b in range(PS.shape[1]):
        for d in range(3):
            if PS[k, b, d, 0] != NEW[b, d, 0] or PS[k, b, d, 1] != NEW[b, d, 1]:
                same = False
    if same:
        return
    for b in range(PS.shape[1]):
        for d in range(3):
            PS[k, b, d, 0], PS[k, b, d, 1] = NEW[b, d, 0], NEW[b, d, 1]
    node_hull(PS, k, H, h_lo, h_hi)
    clock[0] += 1
    ver[k] = clock[0]


@njit(cache=True)
def flatten_sets(PS, offsets, out):
    """The non-empty boxes of every node, in slice order: node ``k``'s are
    ``out[offsets[k]:offsets[k + 1]]``; ``offsets`` (N + 1) and ``out`` sized by
    :func:`count_boxes`."""
    n = PS.shape[0]
    S = PS.shape[1]
    t = 0
    for k in range(n):
        offsets[k] = t
        for b in range(S):
            if not _empty(PS, k, b):
                out[t] = PS[k, b]
                t += 1
    offsets[n] = t


@njit(cache=True)
def count_boxes(PS):
    t = 0
    for k in range(PS.shape[0]):
        for b in range(PS.shape[1]):
            if not _empty(PS, k, b):
                t += 1
    return t
