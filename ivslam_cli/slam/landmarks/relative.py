"""Relative pose constraints of the landmark CSP: two nodes that observed the same landmarks.

Observation ``i`` from node ``k`` and ``j`` from node ``l`` of the same landmark ``m``:
``m = p_k ⊕ u_i = p_l ⊕ u_j`` with ``u = ρ (cos α, sin α)`` in the robot's frame. In the frame
of node ``k`` (modelled poses, :mod:`.kernel`), the pose of node ``l`` relative to it,
``d = R(−θ_k)(p_l − p_k)`` and ``Δ = θ_l − θ_k``, satisfies

    d ∈ ρ_i ∠ (α_i ± rt_i) − ρ_j ∠ (α_j ± rt_j + Δ) ± √2 (rp_i + rp_j)        (per coordinate)

(``rp``, ``rt``: the reach of each observation, the true pose at its stamp within that of the
modelled one at its node): **independent of the landmark's box and of the absolute heading**.
With two or more common landmarks this pins ``(d, Δ)`` like a scan match. The chain of motion
increments from ``k`` to ``l`` bounds it too (composed as :func:`.steps.compose_increments`
does, or by the distance and turn bounds for long chains).

:func:`pair_pieces` contracts ``(d, Δ)`` by set inversion on ``Δ``: the chain's ``Δ`` (or the
circle) is bisected, each piece keeping the ``d`` box the q-relaxed intersection over the
common landmarks allows (met with the chain's), a piece with none dropped; the survivors,
merged into a few pieces, are increments ``(ρ, α, δθ)`` like the motion steps'. In the
sweeps each pair is an extra edge, contracted slice pair by slice pair like a motion step
(:func:`pair_sets`): ``PS[l] ∩= PS[k] ⊕ R_kl`` and ``PS[k] ∩= PS[l] ⊖ R_kl`` at once.

Outliers: a pair's constraint from landmark ``m`` uses one observation at each node, so an
outlier at either node breaks it. With at most ``q_pose`` outliers among each node's
observations (the pose window's assumption), at most ``2·q_pose`` of a pair's common
landmarks are broken: the q-relaxed intersection over them with ``q = 2·q_pose`` holds the
true relative pose. Pairs are only made of nodes with more than ``2·q_pose`` common landmarks
(each seen once at each node), at least ``min_common``.

Every bound is rounded outward.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ivslam_cli.interval.angles import arg_box
from ivslam_cli.interval.arith import add, cos, mul, sin, sqr, sqrt, sub
from ivslam_cli.interval.rounding import PI_HI, TWO_PI_LO, down, up
from ivslam_cli.slam.landmarks.pose_sets import _commit, _set_empty3, increment_pairs

MAX_CHAIN = 256  # chains of more steps bound the relative pose by their travel and turn bounds
SQRT2_HI = float(np.nextafter(math.sqrt(2.0), np.inf))
PIECE_BUDGET = 256  # Δ pieces evaluated per bisection round at most
MAX_PIECES = 16  # pieces kept per pair (neighbours merged)
MERGE_GROWTH = 0.5  # neighbours are merged while the d box grows by at most this fraction
CIRCLE_START = 16  # a whole circle of Δ starts as this many pieces


# ------------------------------------------------------------------ which pairs
def pair_candidates(node: np.ndarray, lm: np.ndarray, n_nodes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                                           np.ndarray, np.ndarray]:
    """The observations a pair may use: of a landmark seen once at its node. Returns
    ``single`` (their indices sorted by node, then landmark), ``frame_node`` (the nodes that
    have some), ``frame_off`` (their runs in ``single``), ``lm_off`` and ``lm_frames`` (per
    landmark, the frames that saw it, ascending)."""
    sel = np.flatnonzero(lm >= 0)
    order = sel[np.lexsort((lm[sel], node[sel]))]
    key = node[order] * (int(lm.max(initial=0)) + 1) + lm[order]
    first = np.ones(order.size, bool)
    first[1:] = key[1:] != key[:-1]
    last = np.ones(order.size, bool)
    last[:-1] = key[1:] != key[:-1]
    single = order[first & last].astype(np.int64)
    frame_node, start = np.unique(node[single], return_index=True)
    frame_off = np.concatenate([start, [single.size]]).astype(np.int64)
    frame_of = np.repeat(np.arange(frame_node.size), np.diff(frame_off))
    n_lm = int(lm.max(initial=-1)) + 1
    by_lm = np.lexsort((frame_of, lm[single]))
    lm_frames = frame_of[by_lm].astype(np.int64)
    lm_off = np.concatenate([[0], np.cumsum(np.bincount(lm[single], minlength=n_lm))]).astype(np.int64)
    return single, frame_node.astype(np.int64), frame_off, lm_off, lm_frames


@njit(cache=True)
def select_pairs(single, frame_node, frame_off, lm_off, lm_frames, lm, chain_of, partners, need, out_k, out_l):
    """For each frame ``a`` (a node with observations), up to ``partners`` earlier frames of
    its chain sharing at least ``need`` landmarks: the most recent, the earliest, and frames
    spread geometrically in between (by rank from the most recent). ``out_k``, ``out_l``:
    the frame indices of each pair (sized ``partners × frames``); returns their count."""
    F = frame_node.shape[0]
    counts = np.zeros(F, np.int64)
    touched = np.empty(F, np.int64)
    cand = np.empty(F, np.int64)
    n = 0
    for a in range(F):
        ca = chain_of[frame_node[a]]
        nt = 0
        for s in range(frame_off[a], frame_off[a + 1]):
            m = lm[single[s]]
            for t in range(lm_off[m], lm_off[m + 1]):
                b = lm_frames[t]
                if b >= a:
                    break
                if chain_of[frame_node[b]] != ca:
                    continue
                if counts[b] == 0:
                    touched[nt] = b
                    nt += 1
                counts[b] += 1
        nc = 0
        for t in range(nt):
            b = touched[t]
            if counts[b] >= need:
                cand[nc] = b
                nc += 1
            counts[b] = 0
        if nc == 0:
            continue
        c = np.sort(cand[:nc])[::-1]  # the most recent first
        if nc <= partners:
            for t in range(nc):
                out_k[n], out_l[n] = c[t], a
                n += 1
            continue
        prev = -1
        for s in range(partners):
            pos = 0 if partners == 1 else int(round(math.exp(s / (partners - 1) * math.log(nc)))) - 1
            pos = min(max(pos, prev + 1), nc - 1 - (partners - 1 - s))
            out_k[n], out_l[n] = c[pos], a
            n += 1
            prev = pos
    return n


@njit(cache=True)
def common_observations(single, frame_off, lm, fk, fl, pair_off, oi, oj):
    """For each pair of frames ``(fk[p], fl[p])``: the observations ``oi`` (at the first) and
    ``oj`` (at the second) of their common landmarks, ``pair_off[p]:pair_off[p + 1]``
    (``pair_off[0]`` given; ``oi``, ``oj`` sized for the worst case). Returns the total."""
    t = pair_off[0]
    for p in range(fk.shape[0]):
        s = frame_off[fk[p]]
        e = frame_off[fk[p] + 1]
        u = frame_off[fl[p]]
        f = frame_off[fl[p] + 1]
        while s < e and u < f:  # both runs sorted by landmark
            a = lm[single[s]]
            b = lm[single[u]]
            if a == b:
                oi[t] = single[s]
                oj[t] = single[u]
                t += 1
                s += 1
                u += 1
            elif a < b:
                s += 1
            else:
                u += 1
        pair_off[p + 1] = t
    return t


# ------------------------------------------------------------------ the relative pose
@njit(cache=True)
def chain_bound(U, travel, turn, turn_err, k, l, out):
    """``out`` (3, 2) ⊇ ``(d_x, d_y, Δ)``: node ``l``'s modelled pose in the frame of node ``k``'s
    (same chain, ``k < l``): the composed increments, or for more than ``MAX_CHAIN`` steps the
    distance and turn bounds."""
    if l - k <= MAX_CHAIN:
        xl, xh, yl, yh, tl, th = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        for f in range(k, l):
            pl, ph = add(tl, th, U[f, 1, 0], U[f, 1, 1])
            cl, ch = cos(pl, ph)
            sl, sh = sin(pl, ph)
            xl, xh = add(xl, xh, *mul(U[f, 0, 0], U[f, 0, 1], cl, ch))
            yl, yh = add(yl, yh, *mul(U[f, 0, 0], U[f, 0, 1], sl, sh))
            tl, th = add(tl, th, U[f, 2, 0], U[f, 2, 1])
    else:
        # the cumulative sums' float error: below (n + 4)·2⁻⁵¹ of the larger
        dp = up(up(travel[l] - travel[k]) + up((travel.shape[0] + 4) * 2.0**-51 * travel[l]))
        xl, xh, yl, yh = -dp, dp, -dp, dp
        tl = down(down(turn[l, 0] - turn[k, 0]) - turn_err)
        th = up(up(turn[l, 1] - turn[k, 1]) + turn_err)
    out[0, 0], out[0, 1], out[1, 0], out[1, 1], out[2, 0], out[2, 1] = xl, xh, yl, yh, tl, th


@njit(cache=True)
def observation_vectors(oi, oj, rho, alpha, reach, vi, rj, aj, e):
    """Per common landmark ``c``: ``vi[c]`` (2, 2) the box of ``ρ_i ∠ (α_i ± rt_i)``, ``rj[c]``,
    ``aj[c]`` the range and bearing (``± rt_j``) of the other observation, ``e[c]`` the
    position reaches ``√2 (rp_i + rp_j)``."""
    for c in range(oi.shape[0]):
        i = oi[c]
        j = oj[c]
        al, ah = down(alpha[i, 0] - reach[i, 1]), up(alpha[i, 1] + reach[i, 1])
        vi[c, 0, 0], vi[c, 0, 1] = mul(rho[i, 0], rho[i, 1], *cos(al, ah))
        vi[c, 1, 0], vi[c, 1, 1] = mul(rho[i, 0], rho[i, 1], *sin(al, ah))
        rj[c, 0], rj[c, 1] = rho[j, 0], rho[j, 1]
        aj[c, 0], aj[c, 1] = down(alpha[j, 0] - reach[j, 1]), up(alpha[j, 1] + reach[j, 1])
        e[c] = up(up(reach[i, 0] + reach[j, 0]) * SQRT2_HI)


@njit(cache=True)
def relative_d(vi, rj, aj, e, q, chain, dl, dh, lo, hi, out):
    """``out`` (2, 2) = the ``d`` box for ``Δ ∈ [dl, dh]``: the hull of the q-relaxed
    intersection over the common landmarks of the boxes ``vi − ρ_j ∠ (α_j + Δ) ± e``, within the
    chain's. False if empty. ``lo``, ``hi``: (2, n) work arrays."""
    n = vi.shape[0]
    for c in range(n):
        bl, bh = add(aj[c, 0], aj[c, 1], dl, dh)
        wxl, wxh = mul(rj[c, 0], rj[c, 1], *cos(bl, bh))
        wyl, wyh = mul(rj[c, 0], rj[c, 1], *sin(bl, bh))
        xl, xh = sub(vi[c, 0, 0], vi[c, 0, 1], wxl, wxh)
        yl, yh = sub(vi[c, 1, 0], vi[c, 1, 1], wyl, wyh)
        lo[0, c], hi[0, c] = down(xl - e[c]), up(xh + e[c])
        lo[1, c], hi[1, c] = down(yl - e[c]), up(yh + e[c])
    return _qinter_2d(lo, hi, n, q, chain, out)


@njit(cache=True)
def _qinter_2d(lo, hi, n, q, chain, out):
    """``out`` (2, 2) = the hull of the points of the chain's box in at least ``n − q`` of the
    boxes ``[lo[0, c], hi[0, c]] × [lo[1, c], hi[1, c]]``: the union, over the subsets that
    leave ``q`` out, of their intersections (exact, no arithmetic). False if empty."""
    if q >= n:
        out[0, 0], out[0, 1] = chain[0, 0], chain[0, 1]
        out[1, 0], out[1, 1] = chain[1, 0], chain[1, 1]
        return True
    left = np.arange(q)
    found = False
    xl, xh, yl, yh = 0.0, 0.0, 0.0, 0.0
    while True:
        t = 0
        cxl, cxh, cyl, cyh = chain[0, 0], chain[0, 1], chain[1, 0], chain[1, 1]
        for c in range(n):
            if t < q and left[t] == c:
                t += 1
                continue
            cxl, cxh = max(cxl, lo[0, c]), min(cxh, hi[0, c])
            cyl, cyh = max(cyl, lo[1, c]), min(cyh, hi[1, c])
        if cxl <= cxh and cyl <= cyh:
            if found:
                xl, xh, yl, yh = min(xl, cxl), max(xh, cxh), min(yl, cyl), max(yh, cyh)
            else:
                xl, xh, yl, yh = cxl, cxh, cyl, cyh
            found = True
        i = q - 1
        while i >= 0 and left[i] == n - q + i:
            i -= 1
        if i < 0:
            break
        left[i] += 1
        for u in range(i + 1, q):
            left[u] = left[u - 1] + 1
    if not found:
        return False
    out[0, 0], out[0, 1], out[1, 0], out[1, 1] = xl, xh, yl, yh
    return True


@njit(cache=True)
def pair_pieces(chain, vi, rj, aj, e, q, min_width, out):
    """Set inversion on ``Δ`` (see the module docstring): ``out`` (MAX_PIECES, 3, 2) gets the
    surviving pieces as rows ``(d_x, d_y, Δ)``, neighbours merged; returns their count (0: the
    constraint has no solution, the q assumption is broken)."""
    n = vi.shape[0]
    lo = np.empty((2, n))
    hi = np.empty((2, n))
    cur = np.empty((PIECE_BUDGET, 2))
    nxt = np.empty((PIECE_BUDGET, 2))
    dbox = np.empty((PIECE_BUDGET, 2, 2))
    box = np.empty((2, 2))
    tmp = np.empty((PIECE_BUDGET, 3, 2))
    tl, th = chain[2, 0], chain[2, 1]
    m = 1
    if not (th - tl < TWO_PI_LO):  # the chain allows every heading: the circle
        m = CIRCLE_START
        for s in range(m):
            cur[s, 0] = -PI_HI if s == 0 else down(-math.pi + 2.0 * math.pi * s / m)
            cur[s, 1] = PI_HI if s == m - 1 else up(-math.pi + 2.0 * math.pi * (s + 1) / m)
    else:
        cur[0, 0], cur[0, 1] = tl, th
    while True:
        live = 0
        wide = False
        for s in range(m):
            if relative_d(vi, rj, aj, e, q, chain, cur[s, 0], cur[s, 1], lo, hi, box):
                cur[live] = cur[s]
                dbox[live] = box
                live += 1
                wide = wide or cur[s, 1] - cur[s, 0] > min_width
        m = live
        if m == 0 or not wide or 2 * m > PIECE_BUDGET:
            break
        t = 0
        for s in range(m):
            if cur[s, 1] - cur[s, 0] > min_width:
                mid = 0.5 * (cur[s, 0] + cur[s, 1])  # both halves hold mid
                nxt[t, 0], nxt[t, 1] = cur[s, 0], mid
                nxt[t + 1, 0], nxt[t + 1, 1] = mid, cur[s, 1]
                t += 2
            else:
                nxt[t] = cur[s]
                t += 1
        m = t
        cur[:m] = nxt[:m]
    if m == 0:
        return 0
    # merge touching neighbours while the merged d box's larger side stays within
    # (1 + MERGE_GROWTH) of the smallest piece's in the group (d turns with Δ by |u_j| a radian)
    g = -1
    base = 0.0
    for s in range(m):
        side = max(dbox[s, 0, 1] - dbox[s, 0, 0], dbox[s, 1, 1] - dbox[s, 1, 0])
        if g >= 0 and cur[s, 0] <= tmp[g, 2, 1]:
            hx = max(tmp[g, 0, 1], dbox[s, 0, 1]) - min(tmp[g, 0, 0], dbox[s, 0, 0])
            hy = max(tmp[g, 1, 1], dbox[s, 1, 1]) - min(tmp[g, 1, 0], dbox[s, 1, 0])
            b2 = min(base, side)
            if max(hx, hy) <= (1.0 + MERGE_GROWTH) * b2:
                base = b2
                _hull_piece(tmp[g], dbox[s], cur[s])
                continue
        g += 1
        base = side
        tmp[g, 0] = dbox[s, 0]
        tmp[g, 1] = dbox[s, 1]
        tmp[g, 2] = cur[s]
    g += 1
    # at most MAX_PIECES: equal shares of the groups
    k = min(g, MAX_PIECES)
    for s in range(g):
        t = (s * k) // g
        if s == 0 or t != ((s - 1) * k) // g:
            out[t] = tmp[s]
        else:
            _hull_piece(out[t], tmp[s, :2], tmp[s, 2])
    return k


@njit(cache=True)
def _hull_piece(piece, dbox, dth):
    """``piece`` (rows ``d_x, d_y, Δ``) ∪= the piece ``dbox`` (2, 2), ``dth`` (2,)."""
    for d in range(2):
        piece[d, 0] = min(piece[d, 0], dbox[d, 0])
        piece[d, 1] = max(piece[d, 1], dbox[d, 1])
    piece[2, 0] = min(piece[2, 0], dth[0])
    piece[2, 1] = max(piece[2, 1], dth[1])


@njit(cache=True)
def as_increment(piece, inc):
    """``inc`` (3, 2) rows ``(ρ, α, δθ)`` of a piece ``(d_x, d_y, Δ)``: ``ρ ⊇ |d|``, ``α ⊇ arg d``."""
    inc[0, 0], inc[0, 1] = sqrt(*add(*sqr(piece[0, 0], piece[0, 1]), *sqr(piece[1, 0], piece[1, 1])))
    inc[1, 0], inc[1, 1] = arg_box(piece[0, 0], piece[0, 1], piece[1, 0], piece[1, 1])
    inc[2, 0], inc[2, 1] = piece[2, 0], piece[2, 1]


@njit(cache=True)
def relative_increments(U, travel, turn, turn_err, pk, pl, pair_off, oi, oj, rho, alpha, reach, q, R, roff, empty):
    """For each pair ``p`` of nodes ``(pk[p], pl[p])`` with common observations
    ``oi, oj[pair_off[p]:pair_off[p + 1]]``: its pieces as increments, ``R[roff[p]:roff[p + 1]]``
    (``R`` sized ``MAX_PIECES`` a pair; ``roff[0]`` given); ``empty[p]`` True when the
    constraint has no solution (no piece). Returns the total number of pieces."""
    chain = np.empty((3, 2))
    pieces = np.empty((MAX_PIECES, 3, 2))
    t = roff[0]
    for p in range(pk.shape[0]):
        a = pair_off[p]
        b = pair_off[p + 1]
        n = b - a
        vi = np.empty((n, 2, 2))
        rj = np.empty((n, 2))
        aj = np.empty((n, 2))
        e = np.empty(n)
        observation_vectors(oi[a:b], oj[a:b], rho, alpha, reach, vi, rj, aj, e)
        chain_bound(U, travel, turn, turn_err, pk[p], pl[p], chain)
        min_width = math.inf
        for c in range(n):
            min_width = min(min_width, aj[c, 1] - aj[c, 0])
        min_width = max(0.25 * min_width, 1e-4)
        g = pair_pieces(chain, vi, rj, aj, e, q, min_width, pieces)
        empty[p] = g == 0
        for s in range(g):
            as_increment(pieces[s], R[t])
            t += 1
        roff[p + 1] = t
    return t


# ------------------------------------------------------------------ in the sweeps
@njit(cache=True)
def pair_sets(PS, H, p, pk, pl, R, roff, accA, accC, h_lo, h_hi, ver, pairdone, clock):
    """Contract the sets of nodes ``pk[p]`` and ``pl[p]`` with pair ``p``'s pieces, slice pair
    by slice pair (as a motion step); False (nothing written) if none has a solution. Skipped
    when neither set changed since the pair last ran (``pairdone``)."""
    k = pk[p]
    l = pl[p]
    if ver[k] <= pairdone[p] and ver[l] <= pairdone[p]:
        return True
    for b in range(PS.shape[1]):
        _set_empty3(accA[b])
        _set_empty3(accC[b])
    found = False
    for s in range(roff[p], roff[p + 1]):
        if increment_pairs(PS, k, l, R[s], accA, accC):
            found = True
    if not found:
        pairdone[p] = clock[0]
        return False
    _commit(PS, H, k, accA, h_lo, h_hi, ver, clock)
    _commit(PS, H, l, accC, h_lo, h_hi, ver, clock)
    pairdone[p] = clock[0]
    return True



# ------------------------------------------------------------------ the pairs of a problem
@dataclass
class Relative:
    """The pair constraints of a problem: pair ``p`` relates nodes ``k[p] < l[p]`` (sorted by
    ``l``) by the increments ``R[off[p]:off[p + 1]]`` (rows ``ρ, α, δθ``: node ``l`` in the
    frame of node ``k``); ``out`` the pairs sorted by ``k``, ``in_off``/``out_off`` (N + 1) the
    runs of each node; ``common`` the common landmarks of each pair; ``broken``: the node pairs
    whose constraint had no solution (left out), ``q`` the q of their intersections."""

    k: np.ndarray
    l: np.ndarray
    R: np.ndarray
    off: np.ndarray
    in_off: np.ndarray
    out: np.ndarray
    out_off: np.ndarray
    common: np.ndarray
    broken: np.ndarray
    q: int

    @property
    def count(self) -> int:
        return int(self.k.size)


def relative_constraints(node: np.ndarray, lm: np.ndarray, chain_of: np.ndarray, U: np.ndarray, travel: np.ndarray,
                         turn: np.ndarray, turn_err: float, rho: np.ndarray, alpha: np.ndarray, reach: np.ndarray,
                         partners: int, min_common: int, q_pose: int) -> Relative:
    """The pairs (:func:`select_pairs`, ``partners`` per observing node, ``0``: none) with more
    than ``2·q_pose`` and at least ``min_common`` common landmarks, and their increments."""
    n_nodes = chain_of.shape[0]
    q = 2 * q_pose
    need = max(min_common, q + 1, 1)
    empty_i = np.zeros(0, np.int64)
    if partners <= 0 or not (lm >= 0).any():
        return Relative(empty_i, empty_i, np.zeros((0, 3, 2)), np.zeros(1, np.int64), np.zeros(n_nodes + 1, np.int64),
                        empty_i, np.zeros(n_nodes + 1, np.int64), empty_i, np.zeros((0, 2), np.int64), q)
    single, frame_node, frame_off, lm_off, lm_frames = pair_candidates(node, lm, n_nodes)
    F = frame_node.size
    fk = np.empty(F * partners, np.int64)
    fl = np.empty(F * partners, np.int64)
    n = select_pairs(single, frame_node, frame_off, lm_off, lm_frames, lm, chain_of, partners, need, fk, fl)
    fk, fl = fk[:n], fl[:n]
    pair_off = np.zeros(n + 1, np.int64)
    worst = int(np.minimum(np.diff(frame_off)[fk], np.diff(frame_off)[fl]).sum())
    oi = np.empty(worst, np.int64)
    oj = np.empty(worst, np.int64)
    common_observations(single, frame_off, lm, fk, fl, pair_off, oi, oj)
    pk, pl = frame_node[fk], frame_node[fl]
    R = np.empty((n * MAX_PIECES, 3, 2))
    roff = np.zeros(n + 1, np.int64)
    empty = np.zeros(n, np.bool_)
    relative_increments(U, travel, turn, turn_err, pk, pl, pair_off, oi, oj, rho, alpha, reach, q, R, roff,
                        empty)
    keep = np.diff(roff) > 0
    rows = np.concatenate([np.arange(roff[p], roff[p + 1]) for p in np.flatnonzero(keep)] or [np.zeros(0, np.int64)])
    R = np.ascontiguousarray(R[rows])
    off = np.concatenate([[0], np.cumsum(np.diff(roff)[keep])]).astype(np.int64)
    k, l, common = pk[keep], pl[keep], np.diff(pair_off)[keep]
    in_off = np.searchsorted(l, np.arange(n_nodes + 1)).astype(np.int64)
    out = np.argsort(k, kind="stable").astype(np.int64)
    out_off = np.searchsorted(k[out], np.arange(n_nodes + 1)).astype(np.int64)
    broken = np.column_stack([pk[empty], pl[empty]]).astype(np.int64)
    return Relative(k.astype(np.int64), l.astype(np.int64), R, off, in_off, out, out_off, common.astype(np.int64),
                    broken, q)
