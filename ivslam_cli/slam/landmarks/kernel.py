"""Kernels of the landmark CSP: pose sets (unions of boxes) swept forward and backward over
whole trajectories, landmark boxes in between.

**Pose sets.** The circle of headings is cut into ``S`` fixed slices (``BINS[b]``, adjacent
slices overlapping by an ulp so that their union holds every angle). The set of node ``k``
holds one box per slice, ``PS[k, b] = (x, y, θ)`` with ``θ`` inside slice ``b`` (in its
branch ``[−π, π]``), empty when no pose of that heading is possible; the set is the union of
its boxes, and ``H[k]`` its hull (``θ`` the shortest arc holding every slice's interval). A
pose whose heading is lost is a ring of boxes (one per slice) instead of the ring's bounding
box, so a later observation or motion step can still tell the headings apart. Whatever falls
into a slice is merged into its box (the count per node is bounded by ``S``).

Variables: the pose sets ``PS`` ``(N, S, 3, 2)`` at every node of one or several chains (one
per robot; ``kind[k] = STEP_NONE`` between two chains) and landmark boxes ``L`` ``(L, 2, 2)``.

Constraints:

- **motion** between nodes ``k`` and ``k + 1`` (``kind[k] = INCREMENT``): a pose increment in
  the frame of node ``k``, ``U[k] = [ρ, α, δθ]``: ``(x, y)_{k+1} = (x, y)_k + ρ (cos(θ_k + α),
  sin(θ_k + α))``, ``θ_{k+1} = θ_k + δθ (mod 2π)``; contracted slice pair by slice pair (a slice
  of ``k`` reaches the one or two slices its heading turns into), each slice keeping the hull
  of what its pairs allow (:func:`step_sets`);
- **observation** ``j`` from node ``node[j]`` with range ``ρ_j`` and bearing ``α_j`` intervals
  (noise folded in) of landmark ``lm[j]``, or (``lm[j] = −1``) of the robot at node
  ``tnode[j]`` of another chain. The pose at the observation lies in ``PS[node] ⊕ reach[j]``
  (``reach`` = position and heading half-widths: the lag of the true pose behind the
  modelled one, or the motion possible between the observation's stamp and its node's);
  the observed robot's true pose lies in its node's set ``⊕ treach[j]``.

Robustness (q-relaxed intersections where constraints meet, Jaulin's robust set inversion):

- per landmark: ``L_i ∩= qinter(candidates of its observations, q_i)``, the candidate of
  observation ``j`` being the hull, over the slices of its pose set, of the landmark boxes
  each slice and the measurement allow; an observation whose candidate misses ``L_i`` is
  **rejected**;
- per pose (at nodes with observations): every slice, cut into ``sub`` pieces, is met with
  the q-relaxed intersection (``q_pose``) of the pose boxes the non-rejected observations
  within ``window`` seconds allow (each carried to its own node and stamp and back by the
  motion possible in between: ``travel``, ``turn``), together with the positions the
  observations of this robot by other robots allow; the slice keeps the hull of its
  surviving pieces, and a slice with none is removed (global localisation by set inversion
  with q-relaxed intersections, Kieffer, Jaulin, Walter & Meizel 2000). An observation of the
  node that agrees with no surviving piece is rejected.

Empty motion steps (the data contradict the motion bounds, or an undetected outlier
contracted a pose wrongly) are recorded as events and that step's contraction is skipped;
so are pose and landmark updates that would empty a set: a run never ends silently empty.

Guarantee: if every motion step holds within its bounds and at most ``q_i`` observations of
landmark ``i`` and ``q_pose`` observations in each pose window break theirs, every true pose
lies in its node's set and every landmark in its box (every contractor rounds outward).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_qinter import qinter_interval
from ivslam_cli.contractors.ctc_range_bearing import range_bearing_pass
from ivslam_cli.interval.angles import angle_meet, angle_meet_narrow, arg_box
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, INF, add, cos, mul, sin, sqr, sqrt, sub
from ivslam_cli.interval.rounding import PI_HI, TWO_PI_HI, TWO_PI_LO, down, up

from ivslam_cli.slam.motion_kernel import INCREMENT, cap_heading, init_headings, step_contract  # noqa: F401

STEP_NONE = 0  # no motion constraint between node k and k + 1 (the next robot's chain starts)

OBS_USED = 0
OBS_REJECTED_LANDMARK = 1  # its landmark candidate misses the q-relaxed landmark box
OBS_REJECTED_POSE = 2  # its pose candidate misses the q-relaxed pose set

BIG = 1e6  # widths are capped at this in the convergence measure (unbounded boxes)
MIN_PIECE = 1e-3  # a piece narrower than this (metres; headings times the observed range) is not bisected
SUB_MAX_LIVE = 8  # slices are paved by several pieces only in sets of at most this many slices


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
def _set_empty3(a):
    for d in range(3):
        a[d, 0] = EMPTY_LO
        a[d, 1] = EMPTY_HI


@njit(cache=True)
def _hull_into(acc, xl, xh, yl, yh, tl, th):
    """``acc`` (3, 2) ∪= the box (the empty ``acc`` is neutral)."""
    if acc[0, 0] <= acc[0, 1]:
        acc[0, 0] = min(acc[0, 0], xl)
        acc[0, 1] = max(acc[0, 1], xh)
        acc[1, 0] = min(acc[1, 0], yl)
        acc[1, 1] = max(acc[1, 1], yh)
        acc[2, 0] = min(acc[2, 0], tl)
        acc[2, 1] = max(acc[2, 1], th)
    else:
        acc[0, 0], acc[0, 1], acc[1, 0], acc[1, 1], acc[2, 0], acc[2, 1] = xl, xh, yl, yh, tl, th


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
            _set_empty3(PS[k, b])


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
def node_hull(PS, k, out, h_lo, h_hi):
    """``out`` (3, 2) = the hull of node ``k``'s set: x, y hulls, θ the shortest arc holding
    every slice's interval. Returns False (``out`` empty) when the set is empty."""
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
        _set_empty3(out)
        return False
    tl, th = _circular_hull(h_lo, h_hi, n, -PI_HI, PI_HI)
    out[0, 0], out[0, 1], out[1, 0], out[1, 1], out[2, 0], out[2, 1] = xl, xh, yl, yh, tl, th
    return True


@njit(cache=True)
def all_hulls(PS, H):
    S = PS.shape[1]
    h_lo = np.empty(S)
    h_hi = np.empty(S)
    for k in range(PS.shape[0]):
        node_hull(PS, k, H[k], h_lo, h_hi)


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
    S = PS.shape[1]
    w = TWO_PI_HI / S
    for b in range(S):
        _set_empty3(accA[b])
        _set_empty3(accC[b])
    rl, rh = U[k, 0, 0], U[k, 0, 1]
    al, ah = U[k, 1, 0], U[k, 1, 1]
    dl, dh = U[k, 2, 0], U[k, 2, 1]
    found = False
    for b in range(S):
        if _empty(PS, k, b):
            continue
        A = PS[k, b]
        fl, fh = add(A[2, 0], A[2, 1], dl, dh)  # the heading at k + 1
        if fh - fl >= TWO_PI_LO - w:
            b0 = 0
            nb = S
        else:
            b0 = _bin_of(fl, S) - 1
            nb = min(S, int((fh - fl) / w) + 3)
        for i in range(nb):
            c = (b0 + i) % S
            if _empty(PS, k + 1, c):
                continue
            C = PS[k + 1, c]
            ctl, cth = angle_meet(C[2, 0], C[2, 1], fl, fh)
            if not (ctl <= cth):
                continue
            btl, bth = angle_meet(A[2, 0], A[2, 1], *sub(ctl, cth, dl, dh))
            if not (btl <= bth):
                continue
            r = range_bearing_pass(A[0, 0], A[0, 1], A[1, 0], A[1, 1], btl, bth,
                                   C[0, 0], C[0, 1], C[1, 0], C[1, 1], rl, rh, al, ah, 1)
            if not (r[0] <= r[1]):
                continue
            if r[5] - r[4] < bth - btl:  # the step's direction narrowed the heading at k
                ctl, cth = angle_meet(ctl, cth, *add(r[4], r[5], dl, dh))
                if not (ctl <= cth):
                    continue
            _hull_into(accA[b], r[0], r[1], r[2], r[3], r[4], r[5])
            _hull_into(accC[c], r[6], r[7], r[8], r[9], ctl, cth)
            found = True
    if not found:
        stepdone[k] = clock[0]
        return False
    _commit(PS, H, k, accA, h_lo, h_hi, ver, clock)
    _commit(PS, H, k + 1, accC, h_lo, h_hi, ver, clock)
    stepdone[k] = clock[0]
    return True


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
        PS[k, b] = NEW[b]
    node_hull(PS, k, H[k], h_lo, h_hi)
    clock[0] += 1
    ver[k] = clock[0]


# ------------------------------------------------------------------ observations
@njit(cache=True)
def _widen(lo, hi, r):
    return down(lo - r), up(hi + r)


@njit(cache=True)
def _target_box(H, L, j, lm, tnode, treach):
    """(x lo, x hi, y lo, y hi) of what observation ``j`` sees: its landmark's box, or the
    observed robot's position hull widened by its reach."""
    i = lm[j]
    if i >= 0:
        return L[i, 0, 0], L[i, 0, 1], L[i, 1, 0], L[i, 1, 1]
    t = tnode[j]
    r = treach[j, 0]
    a, b = _widen(H[t, 0, 0], H[t, 0, 1], r)
    c, d = _widen(H[t, 1, 0], H[t, 1, 1], r)
    return a, b, c, d


@njit(cache=True)
def _all_live(PS, k):
    for b in range(PS.shape[1]):
        if _empty(PS, k, b):
            return False
    return True


@njit(cache=True)
def image_candidate(PS, H, j, node, rho, alpha, reach, out):
    """``out`` (2, 2) = the hull over the slices of ``PS[node[j]] ⊕ reach[j]`` of the positions
    observation ``j`` allows for what it sees (one pass: the annulus sector moved by the pose
    box). False if none."""
    k = node[j]
    rp = reach[j, 0]
    rt = reach[j, 1]
    S = PS.shape[1]
    xl, xh, yl, yh = INF, -INF, INF, -INF
    for b in range(S):
        if _empty(PS, k, b):
            continue
        full = b == 0 and _all_live(PS, k)
        # a whole ring of slices: the hull's image is as good as the hull of the slices' images
        B = H[k] if full else PS[k, b]
        sxl, sxh = _widen(B[0, 0], B[0, 1], rp)
        syl, syh = _widen(B[1, 0], B[1, 1], rp)
        stl, sth = _widen(B[2, 0], B[2, 1], rt)
        r = range_bearing_pass(sxl, sxh, syl, syh, stl, sth, -INF, INF, -INF, INF,
                               rho[j, 0], rho[j, 1], alpha[j, 0], alpha[j, 1], 1)
        if r[0] <= r[1]:
            xl = min(xl, r[6])
            xh = max(xh, r[7])
            yl = min(yl, r[8])
            yh = max(yh, r[9])
        if full:
            break
    out[0, 0], out[0, 1], out[1, 0], out[1, 1] = xl, xh, yl, yh
    return xl <= xh


@njit(cache=True)
def landmark_update(PS, H, L, q, lm_offsets, lm_order, node, rho, alpha, reach, status, events_lm, cand, cver, lrej,
                    lver, ver, clock, lo, hi):
    """``L_i ∩= qinter(candidates, q_i − r_i)`` for every landmark, ``r_i`` of its observations
    being rejected already (proven outliers count against the q allowed); rejects the
    observations whose candidate misses the result. A landmark the q-relaxed intersection
    would empty keeps its box and counts an event in ``events_lm[i]``.

    ``cand[j]`` caches observation ``j``'s candidate, computed at ``clock`` value ``cver[j]``
    (recomputed when its node's set changed since, ``ver``); a landmark none of whose
    candidates or rejections changed is skipped. ``lver[i]``: when ``L_i`` last changed."""
    n_lm = L.shape[0]
    new = np.empty((2, 2))
    for i in range(n_lm):
        a = lm_offsets[i]
        b = lm_offsets[i + 1]
        m = 0
        rejected = 0
        fresh = False
        for t in range(a, b):
            j = lm_order[t]
            if status[j] != OBS_USED:
                rejected += 1
                continue
            if ver[node[j]] > cver[j]:
                if not image_candidate(PS, H, j, node, rho, alpha, reach, cand[j]):
                    cand[j, 0, 0] = EMPTY_LO
                    cand[j, 0, 1] = EMPTY_HI
                    cand[j, 1, 0] = EMPTY_LO
                    cand[j, 1, 1] = EMPTY_HI
                cver[j] = clock[0]
                fresh = True
            m += 1
        if m == 0 or (not fresh and rejected == lrej[i]):
            continue
        lrej[i] = rejected
        ok = True
        for d in range(2):
            m = 0
            for t in range(a, b):
                j = lm_order[t]
                if status[j] == OBS_USED:
                    lo[m] = cand[j, d, 0]
                    hi[m] = cand[j, d, 1]
                    m += 1
            rl, rh = qinter_interval(lo[:m], hi[:m], max(q[i] - rejected, 0))
            rl = max(rl, L[i, d, 0])
            rh = min(rh, L[i, d, 1])
            if not (rl <= rh):
                ok = False
            new[d, 0] = rl
            new[d, 1] = rh
        if not ok:
            events_lm[i] += 1
            continue
        if new[0, 0] != L[i, 0, 0] or new[0, 1] != L[i, 0, 1] or new[1, 0] != L[i, 1, 0] or new[1, 1] != L[i, 1, 1]:
            L[i] = new
            clock[0] += 1
            lver[i] = clock[0]
        for t in range(a, b):
            j = lm_order[t]
            if status[j] != OBS_USED:
                continue
            c = cand[j]
            if (not (c[0, 0] <= c[0, 1]) or c[0, 1] < new[0, 0] or c[0, 0] > new[0, 1]
                    or c[1, 1] < new[1, 0] or c[1, 0] > new[1, 1]):
                status[j] = OBS_REJECTED_LANDMARK


CARRY_OWN = 0  # the observation is the node's own
CARRY_FORWARD = 1  # made later on the chain: carried through the composed increment
CARRY_BACKWARD = 2  # made earlier on the chain: carried through the inverse of the composed increment
CARRY_TRAVEL = 3  # too far along the chain: carried by the distance and turn bounds
MAX_CARRY_STEPS = 256  # observations more steps away are carried by the travel bounds


@njit(cache=True)
def compose_range(U, a, b, out):
    """``out`` (3, 2) ⊇ the composition of steps ``a .. b − 1`` (rows ``ρ, α, δθ``): node
    ``b`` relative to node ``a``, in the frame of node ``a``. Outward rounding."""
    xl, xh, yl, yh, tl, th = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for f in range(a, b):
        pl, ph = add(tl, th, U[f, 1, 0], U[f, 1, 1])
        cl, ch = cos(pl, ph)
        sl, sh = sin(pl, ph)
        xl, xh = add(xl, xh, *mul(U[f, 0, 0], U[f, 0, 1], cl, ch))
        yl, yh = add(yl, yh, *mul(U[f, 0, 0], U[f, 0, 1], sl, sh))
        tl, th = add(tl, th, U[f, 2, 0], U[f, 2, 1])
    out[0, 0], out[0, 1] = sqrt(*add(*sqr(xl, xh), *sqr(yl, yh)))
    out[1, 0], out[1, 1] = arg_box(xl, xh, yl, yh)
    out[2, 0], out[2, 1] = tl, th


@njit(cache=True)
def _move(xl, xh, yl, yh, tl, th, cr, back):
    """``p + ρ e^{i(θ + α)}`` (``back``: ``p − ρ e^{i(θ + α)}``) for the increment ``cr``
    (``ρ, α`` rows), ``θ`` the heading at the increment's start. Outward rounding."""
    pl, ph = add(tl, th, cr[1, 0], cr[1, 1])
    cl, ch = cos(pl, ph)
    sl, sh = sin(pl, ph)
    dxl, dxh = mul(cr[0, 0], cr[0, 1], cl, ch)
    dyl, dyh = mul(cr[0, 0], cr[0, 1], sl, sh)
    if back:
        return (*sub(xl, xh, dxl, dxh), *sub(yl, yh, dyl, dyh))
    return (*add(xl, xh, dxl, dxh), *add(yl, yh, dyl, dyh))


@njit(cache=True)
def _obs_pose_candidate(H, L, B, k, j, node, lm, tnode, treach, rho, alpha, reach, travel, turn, turn_err, cr, mode,
                        out):
    """The part of pose box ``B`` (of node ``k``) that observation ``j`` allows, in ``out``;
    False if none.

    ``B`` is carried to the observation's node (through ``cr``, the composed increment between
    the two nodes, as ``mode`` says; or widened by the distance and turn possible in between),
    met with that node's hull, widened to the observation's stamp (``reach[j]``), contracted
    there with the observation and what it sees, and carried back; headings are matched
    modulo 2π in each box's branch.
    """
    kj = node[j]
    rp = reach[j, 0]
    rt = reach[j, 1]
    dp = 0.0
    dl = 0.0
    dh = 0.0
    if mode == CARRY_TRAVEL:
        dp = up(up(abs(travel[k] - travel[kj])) * (1.0 + 1e-15))
        a = min(k, kj)
        b = max(k, kj)
        el = down(down(turn[b, 0] - turn[a, 0]) - turn_err)
        eh = up(up(turn[b, 1] - turn[a, 1]) + turn_err)
        if kj > k:
            dl, dh = el, eh
        else:
            dl, dh = -eh, -el
    # B at node kj (the modelled pose there)
    if mode == CARRY_FORWARD:  # k -> kj is the increment
        xl, xh, yl, yh = _move(B[0, 0], B[0, 1], B[1, 0], B[1, 1], B[2, 0], B[2, 1], cr, False)
        tl, th = add(B[2, 0], B[2, 1], cr[2, 0], cr[2, 1])
    elif mode == CARRY_BACKWARD:  # kj -> k is the increment
        tl, th = sub(B[2, 0], B[2, 1], cr[2, 0], cr[2, 1])
        xl, xh, yl, yh = _move(B[0, 0], B[0, 1], B[1, 0], B[1, 1], tl, th, cr, True)
    else:
        xl, xh = _widen(B[0, 0], B[0, 1], dp)
        yl, yh = _widen(B[1, 0], B[1, 1], dp)
        tl, th = down(B[2, 0] + dl), up(B[2, 1] + dh)
    if mode != CARRY_OWN:
        xl, xh = max(xl, H[kj, 0, 0]), min(xh, H[kj, 0, 1])
        yl, yh = max(yl, H[kj, 1, 0]), min(yh, H[kj, 1, 1])
        tl, th = angle_meet_narrow(H[kj, 2, 0], H[kj, 2, 1], tl, th)
        if not (xl <= xh) or not (yl <= yh) or not (tl <= th):
            return False
    # the true pose at the observation's stamp
    xl, xh = _widen(xl, xh, rp)
    yl, yh = _widen(yl, yh, rp)
    tl, th = _widen(tl, th, rt)
    mxl, mxh, myl, myh = _target_box(H, L, j, lm, tnode, treach)
    r = range_bearing_pass(xl, xh, yl, yh, tl, th, mxl, mxh, myl, myh,
                           rho[j, 0], rho[j, 1], alpha[j, 0], alpha[j, 1], 2)
    if not (r[0] <= r[1]):
        return False
    # back to the modelled pose at node kj, then to node k, within B
    xl, xh = _widen(r[0], r[1], rp)
    yl, yh = _widen(r[2], r[3], rp)
    tl, th = _widen(r[4], r[5], rt)
    if mode == CARRY_FORWARD:
        tl, th = angle_meet(B[2, 0], B[2, 1], *sub(tl, th, cr[2, 0], cr[2, 1]))
        if not (tl <= th):
            return False
        xl, xh, yl, yh = _move(xl, xh, yl, yh, tl, th, cr, True)
    elif mode == CARRY_BACKWARD:
        xl, xh, yl, yh = _move(xl, xh, yl, yh, tl, th, cr, False)
        tl, th = add(tl, th, cr[2, 0], cr[2, 1])
    elif mode == CARRY_TRAVEL:
        xl, xh = _widen(xl, xh, dp)
        yl, yh = _widen(yl, yh, dp)
        tl, th = down(tl - dh), up(th - dl)
    out[0, 0], out[0, 1] = max(xl, B[0, 0]), min(xh, B[0, 1])
    out[1, 0], out[1, 1] = max(yl, B[1, 0]), min(yh, B[1, 1])
    out[2, 0], out[2, 1] = angle_meet(B[2, 0], B[2, 1], tl, th)
    return out[0, 0] <= out[0, 1] and out[1, 0] <= out[1, 1] and out[2, 0] <= out[2, 1]


@njit(cache=True)
def _contract_piece(H, L, B, k, m, idx, src, node, lm, tnode, treach, rho, alpha, reach, travel, turn, turn_err,
                    q_pose, timg, carry, cmode, buf, lo, hi, piece):
    """``piece`` = ``B`` ∩ the q-relaxed intersection (``q_pose``) of the ``m`` candidates
    (``buf``: each candidate, empty when the observation allows nothing in ``B``). Returns
    False as soon as more than ``q_pose`` candidates are empty, or if the result is empty."""
    n_empty = 0
    for s in range(m):
        j = idx[s]
        if src[s] == 0:
            ok = _obs_pose_candidate(H, L, B, k, j, node, lm, tnode, treach, rho, alpha, reach, travel,
                                     turn, turn_err, carry[s], cmode[s], buf[s])
        else:
            ok = timg[s, 0, 0] <= timg[s, 0, 1]
            if ok:
                buf[s, 0, 0], buf[s, 0, 1] = max(B[0, 0], timg[s, 0, 0]), min(B[0, 1], timg[s, 0, 1])
                buf[s, 1, 0], buf[s, 1, 1] = max(B[1, 0], timg[s, 1, 0]), min(B[1, 1], timg[s, 1, 1])
                buf[s, 2, 0], buf[s, 2, 1] = B[2, 0], B[2, 1]
                ok = buf[s, 0, 0] <= buf[s, 0, 1] and buf[s, 1, 0] <= buf[s, 1, 1]
        if not ok:
            _set_empty3(buf[s])
            n_empty += 1
            if n_empty > q_pose:
                return False
    for d in range(3):
        for s in range(m):
            lo[s] = buf[s, d, 0]
            hi[s] = buf[s, d, 1]
        rl, rh = qinter_interval(lo[:m], hi[:m], q_pose)
        rl = max(rl, B[d, 0])
        rh = min(rh, B[d, 1])
        if not (rl <= rh):
            return False
        piece[d, 0] = rl
        piece[d, 1] = rh
    return True


@njit(cache=True)
def _mark_agree(buf, m, piece, agree):
    """``agree[s]`` = True for the candidates that meet ``piece``."""
    for s in range(m):
        inside = True
        for d in range(3):
            if not (buf[s, d, 0] <= buf[s, d, 1]) or buf[s, d, 1] < piece[d, 0] or buf[s, d, 0] > piece[d, 1]:
                inside = False
        if inside:
            agree[s] = True


@njit(cache=True)
def pose_update(PS, H, L, U, k, node_obs, node_stamp, obs_node_stamp, chain_lo, chain_hi, travel, turn, turn_err,
                window, window_obs, q_pose, pieces, node, lm, tnode, treach, by_target, target_first, rho, alpha,
                reach, status, buf, lo, hi, idx, src, agree, timg, carry, cmode, stack, NEW, h_lo, h_hi, ver, posedone,
                lver, clock):
    """Node ``k``'s set ∩= what the observations in its window allow, slice by slice (see the
    module docstring). Returns False if no slice survives (nothing written).

    ``node_obs`` are the observation indices sorted by node, ``obs_node_stamp`` their nodes'
    stamps (sorted within each chain), ``[chain_lo, chain_hi)`` the part of them on node
    ``k``'s chain; ``by_target[target_first[k]:]`` the observations of this node's robot by
    others (``tnode = k``), or ``target_first[k] = −1``.
    """
    t = node_stamp[k]
    first = chain_lo + np.searchsorted(obs_node_stamp[chain_lo:chain_hi], t - window, side="left")
    last = chain_lo + np.searchsorted(obs_node_stamp[chain_lo:chain_hi], t + window, side="right")
    m = 0
    # the node's own observations first (the tightest: the early exit sees them first), then
    # the others of the window nearest in time, up to window_obs in all (a q-relaxed
    # intersection over a subset of the window holds under the same assumption)
    for s in range(first, last):
        j = node_obs[s]
        if status[j] == OBS_USED and node[j] == k:
            idx[m] = j
            src[m] = 0
            agree[m] = False
            m += 1
    left = chain_lo + np.searchsorted(obs_node_stamp[chain_lo:chain_hi], t, side="left") - 1
    right = left + 1
    while m < window_obs and (left >= first or right < last):
        if right >= last or (left >= first and t - obs_node_stamp[left] <= obs_node_stamp[right] - t):
            s = left
            left -= 1
        else:
            s = right
            right += 1
        j = node_obs[s]
        if status[j] == OBS_USED and node[j] != k:
            idx[m] = j
            src[m] = 0
            agree[m] = False
            m += 1
    f = target_first[k]
    if f >= 0:
        s = f
        while s < by_target.shape[0] and tnode[by_target[s]] == k:
            j = by_target[s]
            s += 1
            if status[j] != OBS_USED:
                continue
            if not image_candidate(PS, H, j, node, rho, alpha, reach, timg[m]):
                timg[m, 0, 0] = EMPTY_LO
                timg[m, 0, 1] = EMPTY_HI
            else:  # the observed robot's modelled pose: within its reach of the true one
                r = treach[j, 0]
                timg[m, 0, 0], timg[m, 0, 1] = _widen(timg[m, 0, 0], timg[m, 0, 1], r)
                timg[m, 1, 0], timg[m, 1, 1] = _widen(timg[m, 1, 0], timg[m, 1, 1], r)
            idx[m] = j
            src[m] = 1
            agree[m] = False
            m += 1
    if m == 0:
        return True
    # nothing this update reads changed since it last ran: skip it (ver, lver: clock values
    # of the last change of a set, of a landmark box; posedone: of this node's last update)
    stale = ver[k] > posedone[k]
    for s in range(m):
        j = idx[s]
        if src[s] == 1 or node[j] != k:
            stale = stale or ver[node[j]] > posedone[k]
        if lm[j] >= 0:
            stale = stale or lver[lm[j]] > posedone[k]
        elif src[s] == 0:
            stale = stale or ver[tnode[j]] > posedone[k]
    if not stale:
        return True
    for s in range(m):
        j = idx[s]
        cmode[s] = CARRY_OWN
        if src[s] == 0 and node[j] != k:
            kj = node[j]
            if abs(kj - k) > MAX_CARRY_STEPS:
                cmode[s] = CARRY_TRAVEL
            elif kj > k:
                cmode[s] = CARRY_FORWARD
                compose_range(U, k, kj, carry[s])
            else:
                cmode[s] = CARRY_BACKWARD
                compose_range(U, kj, k, carry[s])
    S = PS.shape[1]
    B = np.empty((3, 2))
    piece = np.empty((3, 2))
    n_live = 0
    live0 = 0
    for b in range(S):
        if not _empty(PS, k, b):
            live0 += 1
    budget = pieces if live0 <= SUB_MAX_LIVE else 1  # a lost heading: each slice as one box
    lever = 0.0  # metres per radian of heading at the observations (their largest range)
    for s in range(m):
        lever = max(lever, rho[idx[s], 1])
    for b in range(S):
        _set_empty3(NEW[b])
        if _empty(PS, k, b):
            continue
        # a paving of the slice (SIVIA with contraction, depth first, at most `budget`
        # contractions): each box is contracted by the q-relaxed intersection of its candidates
        # (most boxes of a lost heading die after q_pose + 1 of them); a survivor is bisected
        # across its widest side (the heading weighted by `lever`) while the budget allows,
        # else it joins the slice's hull
        for d in range(3):
            stack[0, d, 0], stack[0, d, 1] = PS[k, b, d, 0], PS[k, b, d, 1]
        top = 1
        used = 0
        while top > 0:
            top -= 1
            for d in range(3):
                B[d, 0], B[d, 1] = stack[top, d, 0], stack[top, d, 1]
            used += 1
            if not _contract_piece(H, L, B, k, m, idx, src, node, lm, tnode, treach, rho, alpha, reach, travel, turn,
                                   turn_err, q_pose, timg, carry, cmode, buf, lo, hi, piece):
                continue
            wx = piece[0, 1] - piece[0, 0]
            wy = piece[1, 1] - piece[1, 0]
            wt = (piece[2, 1] - piece[2, 0]) * lever
            wmax = max(wx, max(wy, wt))
            if used + top + 2 <= budget and wmax > MIN_PIECE and wmax < INF:
                d = 0 if wx == wmax else (1 if wy == wmax else 2)
                mid = 0.5 * (piece[d, 0] + piece[d, 1])  # both halves hold mid: they cover the box
                for h in range(2):
                    for e in range(3):
                        stack[top, e, 0], stack[top, e, 1] = piece[e, 0], piece[e, 1]
                    if h == 0:
                        stack[top, d, 1] = mid
                    else:
                        stack[top, d, 0] = mid
                    top += 1
            else:
                _hull_into(NEW[b], piece[0, 0], piece[0, 1], piece[1, 0], piece[1, 1], piece[2, 0], piece[2, 1])
                _mark_agree(buf, m, piece, agree)
        if NEW[b, 0, 0] <= NEW[b, 0, 1]:
            n_live += 1
    if n_live == 0:
        posedone[k] = clock[0]
        return False
    _commit(PS, H, k, NEW, h_lo, h_hi, ver, clock)
    posedone[k] = clock[0]
    for s in range(m):
        j = idx[s]
        if not agree[s] and ((src[s] == 0 and node[j] == k) or src[s] == 1):
            status[j] = OBS_REJECTED_POSE
    return True


@njit(cache=True)
def total_width(H, L):
    s = 0.0
    for k in range(H.shape[0]):
        for d in range(3):
            w = H[k, d, 1] - H[k, d, 0]
            s += min(w, BIG) if w >= 0.0 else 0.0
    for i in range(L.shape[0]):
        for d in range(2):
            w = L[i, d, 1] - L[i, d, 0]
            s += min(w, BIG) if w >= 0.0 else 0.0
    return s


@njit(cache=True)
def solve(PS, H, L, BINS, kind, U, node_stamp, chain_of, travel, turn, turn_err, node, lm, tnode, treach, rho, alpha,
          reach, obs_node_stamp, by_node, node_first_obs, chain_obs, by_target, target_first, lm_offsets, lm_order,
          q, q_pose, window, window_obs, pieces, max_iterations, tolerance, status, step_events, pose_events, lm_events,
          width_trace):
    """Sweep forward and backward to a fixpoint (see the module docstring). In place.

    ``by_node``: observation indices sorted by (chain, node) (``obs_node_stamp``: their nodes'
    stamps; ``chain_obs[c]:chain_obs[c + 1]`` the part on chain ``c``); ``node_first_obs[k]``
    is −1 for nodes without observations of their own or of their robot by others.
    ``step_events[k]`` / ``pose_events[k]`` / ``lm_events[i]`` count the skipped
    contractions. ``width_trace[it]`` is the summed width after sweep ``it``. Returns the
    number of sweeps done.
    """
    n = PS.shape[0]
    S = PS.shape[1]
    m_max = by_node.shape[0] + by_target.shape[0] + 1
    buf = np.empty((m_max, 3, 2))
    lo = np.empty(m_max)
    hi = np.empty(m_max)
    idx = np.empty(m_max, dtype=np.int64)
    src = np.empty(m_max, dtype=np.int8)
    agree = np.empty(m_max, dtype=np.bool_)
    timg = np.empty((m_max, 2, 2))
    carry = np.empty((m_max, 3, 2))
    stack = np.empty((pieces + 2, 3, 2))
    cmode = np.empty(m_max, dtype=np.int8)
    cand = np.empty((node.shape[0], 2, 2))
    cver = np.full(node.shape[0], -1, np.int64)
    lrej = np.full(L.shape[0], -1, np.int64)
    lver = np.zeros(L.shape[0], np.int64)
    ver = np.zeros(n, np.int64)
    stepdone = np.full(max(n - 1, 1), -1, np.int64)
    posedone = np.full(n, -1, np.int64)
    clock = np.zeros(1, np.int64)
    accA = np.empty((S, 3, 2))
    accC = np.empty((S, 3, 2))
    h_lo = np.empty(S)
    h_hi = np.empty(S)
    all_hulls(PS, H)
    prev = total_width(H, L)
    done = 0
    for it in range(max_iterations):
        for k in range(n - 1):  # forward
            if not step_sets(PS, H, k, kind, U, BINS, accA, accC, h_lo, h_hi, ver, stepdone, clock):
                step_events[k] += 1
            k1 = k + 1
            if node_first_obs[k1] >= 0:
                c = chain_of[k1]
                if not pose_update(PS, H, L, U, k1, by_node, node_stamp, obs_node_stamp, chain_obs[c], chain_obs[c + 1],
                                   travel, turn, turn_err, window, window_obs, q_pose, pieces, node, lm, tnode, treach,
                                   by_target, target_first, rho, alpha, reach, status, buf, lo, hi, idx, src, agree,
                                   timg, carry, cmode, stack, accA, h_lo, h_hi, ver, posedone, lver, clock):
                    pose_events[k1] += 1
        landmark_update(PS, H, L, q, lm_offsets, lm_order, node, rho, alpha, reach, status, lm_events, cand, cver, lrej,
                        lver, ver, clock, lo, hi)
        for k in range(n - 2, -1, -1):  # backward
            if not step_sets(PS, H, k, kind, U, BINS, accA, accC, h_lo, h_hi, ver, stepdone, clock):
                step_events[k] += 1
            if node_first_obs[k] >= 0:
                c = chain_of[k]
                if not pose_update(PS, H, L, U, k, by_node, node_stamp, obs_node_stamp, chain_obs[c], chain_obs[c + 1],
                                   travel, turn, turn_err, window, window_obs, q_pose, pieces, node, lm, tnode, treach,
                                   by_target, target_first, rho, alpha, reach, status, buf, lo, hi, idx, src, agree,
                                   timg, carry, cmode, stack, accA, h_lo, h_hi, ver, posedone, lver, clock):
                    pose_events[k] += 1
        landmark_update(PS, H, L, q, lm_offsets, lm_order, node, rho, alpha, reach, status, lm_events, cand, cver, lrej,
                        lver, ver, clock, lo, hi)
        w = total_width(H, L)
        width_trace[it] = w
        done = it + 1
        if prev > 0.0 and (prev - w) <= tolerance * prev:
            break
        prev = w
    return done


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
