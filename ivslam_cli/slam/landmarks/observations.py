"""Observations in the landmark CSP (:mod:`.kernel`): landmark boxes from q-relaxed
intersections of the candidates the pose sets and the measurements allow, and pose sets
contracted piece by piece by the q-relaxed intersection of what the observations in a window
allow (Kieffer, Jaulin, Walter & Meizel 2000). An observation whose candidate misses the
q-relaxed result is rejected (its status). Every bound is rounded outward.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_qinter import qinter_capped_prefix, qinter_interval, qinter_prefix
from ivslam_cli.contractors.ctc_range_bearing import range_bearing_pass
from ivslam_cli.interval.angles import angle_meet, angle_meet_narrow, arg_box
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, INF, add, cos, mul, sin, sqr, sqrt, sub
from ivslam_cli.interval.rounding import down, up
from ivslam_cli.slam.landmarks.pose_sets import _commit, _empty, _hull_into, _set_empty_at, live_slices

OBS_USED = 0
OBS_REJECTED_LANDMARK = 1  # its landmark candidate misses the q-relaxed landmark box
OBS_REJECTED_POSE = 2  # its pose candidate misses the q-relaxed pose set

MIN_PIECE = 1e-3  # a piece narrower than this (metres; headings times the observed range) is not bisected
SUB_MAX_LIVE = 8  # slices are paved by several pieces only in sets of at most this many slices


# ------------------------------------------------------------------ observations
@njit(cache=True)
def _widen(lo, hi, r):
    return down(lo - r), up(hi + r)


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
    return slice_images(PS, H, j, node, rho, alpha, reach, out, np.empty((0, 2, 2)), False)


@njit(cache=True)
def slice_images(PS, H, j, node, rho, alpha, reach, out, imgs, keep):
    """:func:`image_candidate`; with ``keep``, ``imgs[b]`` (S, 2, 2) is also the image of slice
    ``b`` alone (empty for an empty slice or one that allows nothing): the candidate is their
    union, ``out`` its hull."""
    k = node[j]
    rp = reach[j, 0]
    rt = reach[j, 1]
    S = PS.shape[1]
    xl, xh, yl, yh = INF, -INF, INF, -INF
    for b in range(S):
        if keep:
            imgs[b, 0, 0], imgs[b, 0, 1] = EMPTY_LO, EMPTY_HI
            imgs[b, 1, 0], imgs[b, 1, 1] = EMPTY_LO, EMPTY_HI
        if _empty(PS, k, b):
            continue
        full = (not keep) and b == 0 and _all_live(PS, k)
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
            if keep:
                imgs[b, 0, 0], imgs[b, 0, 1], imgs[b, 1, 0], imgs[b, 1, 1] = r[6], r[7], r[8], r[9]
        if full:
            break
    out[0, 0], out[0, 1], out[1, 0], out[1, 1] = xl, xh, yl, yh
    return xl <= xh


@njit(cache=True)
def landmark_update(PS, H, L, q, lm_offsets, lm_order, node, rho, alpha, reach, status, events_lm, cand, cimg, cver,
                    lrej, lver, ver, clock, lo, hi, count, mark):
    """``L_i ∩= qinter(candidates, q_i − r_i)`` for every landmark, ``r_i`` of its observations
    being rejected already (proven outliers count against the q allowed); rejects the
    observations whose candidate misses the result. A landmark the q-relaxed intersection
    would empty keeps its box and counts an event in ``events_lm[i]``.

    ``cand[j]`` caches observation ``j``'s candidate, computed at ``clock`` value ``cver[j]``
    (recomputed when its node's set changed since, ``ver``); a landmark none of whose
    candidates or rejections changed is skipped. ``lver[i]``: when ``L_i`` last changed.

    Each candidate is the union of its slices' images (``cimg[j]``, (S, 2, 2)): the box the
    q-relaxed intersection of the hulls gives is refined on a grid of ``G × G`` cells
    (``count``, ``mark``: (G, G) work arrays): a cell is kept if at least ``m − q`` candidates'
    unions meet it, and the box becomes the hull of the kept cells (each widened by half a
    cell: the cell of a point is computed in floating point), repeated on the new box while it
    shrinks (:func:`_grid_refine`). The true landmark's cell is met by every candidate of an
    honest observation, so it is kept."""
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
                if not slice_images(PS, H, j, node, rho, alpha, reach, cand[j], cimg[j], True):
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
        _grid_refine(new, a, b, lm_order, status, cimg, max(q[i] - rejected, 0), count, mark)
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


GRID_PASSES = 3  # grid refinements of a landmark box per update, at most ...
GRID_SHRINK = 0.1  # ... while one shrinks a side by more than this fraction


@njit(cache=True)
def _cell_range(a, b, x0, cw, G):
    """The cells ``[c0, c1]`` of a grid starting at ``x0`` with cells ``cw`` wide that
    ``[a, b]`` meets (``c(x) = ⌊(x − x0)/cw⌋`` is monotone in ``x`` in floating point)."""
    c0 = int(math.floor((a - x0) / cw)) if a > x0 else 0
    c1 = int(math.floor((b - x0) / cw)) if b - x0 < cw * G else G - 1
    return max(c0, 0), min(c1, G - 1)


@njit(cache=True)
def _grid_refine(box, a, b, lm_order, status, cimg, qi, count, mark):
    """``box`` (2, 2) ∩= the hull of the cells of a ``G × G`` grid over it met by the unions
    ``cimg[j]`` of at least ``m − qi`` of the used observations ``j = lm_order[a:b]``."""
    G = count.shape[0]
    S = cimg.shape[1]
    for _ in range(GRID_PASSES):
        x0, y0 = box[0, 0], box[1, 0]
        wx, wy = box[0, 1] - x0, box[1, 1] - y0
        if not (wx > 0.0 and wy > 0.0 and wx < INF and wy < INF):
            return
        cx, cy = wx / G, wy / G
        count[:, :] = 0
        m = 0
        for t in range(a, b):
            j = lm_order[t]
            if status[j] != OBS_USED:
                continue
            m += 1
            mark[:, :] = 0
            for s in range(S):
                im = cimg[j, s]
                if not (im[0, 0] <= im[0, 1]) or im[0, 1] < x0 or im[0, 0] > box[0, 1] \
                        or im[1, 1] < y0 or im[1, 0] > box[1, 1]:
                    continue
                i0, i1 = _cell_range(im[0, 0], im[0, 1], x0, cx, G)
                j0, j1 = _cell_range(im[1, 0], im[1, 1], y0, cy, G)
                mark[i0:i1 + 1, j0:j1 + 1] = 1
            count += mark
        need = m - qi
        if need <= 0:
            return
        i0, i1, j0, j1 = G, -1, G, -1
        for u in range(G):
            for v in range(G):
                if count[u, v] >= need:
                    i0, i1 = min(i0, u), max(i1, u)
                    j0, j1 = min(j0, v), max(j1, v)
        if i1 < 0:  # no cell kept: the q-relaxed hulls' box stays (the caller's event logic)
            return
        nxl = max(box[0, 0], down(x0 + cx * (i0 - 0.5)))
        nxh = min(box[0, 1], up(x0 + cx * (i1 + 1.5)))
        nyl = max(box[1, 0], down(y0 + cy * (j0 - 0.5)))
        nyh = min(box[1, 1], up(y0 + cy * (j1 + 1.5)))
        shrunk = (nxh - nxl) < (1.0 - GRID_SHRINK) * wx or (nyh - nyl) < (1.0 - GRID_SHRINK) * wy
        box[0, 0], box[0, 1], box[1, 0], box[1, 1] = nxl, nxh, nyl, nyh
        if not shrunk:
            return


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
def _move(xl, xh, yl, yh, tl, th, rl, rh, al, ah, back):
    """``p + ρ e^{i(θ + α)}`` (``back``: ``p − ρ e^{i(θ + α)}``) for an increment ``ρ ∈ [rl, rh]``,
    ``α ∈ [al, ah]``, ``θ`` the heading at the increment's start. Outward rounding."""
    pl, ph = add(tl, th, al, ah)
    cl, ch = cos(pl, ph)
    sl, sh = sin(pl, ph)
    dxl, dxh = mul(rl, rh, cl, ch)
    dyl, dyh = mul(rl, rh, sl, sh)
    if back:
        return (*sub(xl, xh, dxl, dxh), *sub(yl, yh, dyl, dyh))
    return (*add(xl, xh, dxl, dxh), *add(yl, yh, dyl, dyh))


@njit(cache=True)
def _obs_pose_candidate(B, mode, cr, hk, tgt, ob, dp, dl, dh):
    """The part of pose box ``B`` (of node ``k``) that one observation allows: ``(ok, xl, xh,
    yl, yh, tl, th)``, ``ok`` False if none. Scalars and tuples only (no array argument, so
    no reference counting a call): ``B`` and ``hk`` (the hull of the observation's node
    ``kj``) as ``(xl, xh, yl, yh, tl, th)``; ``cr`` the composed increment between the two
    nodes ``(ρ, α, δθ)`` as lo/hi pairs; ``tgt`` what the observation sees (x lo, x hi, y lo,
    y hi: its landmark's box, or the observed robot's position widened by its reach); ``ob``
    its range and bearing intervals and its reach (position, heading); ``dp, dl, dh`` the
    distance and turn possible between the nodes (``mode`` CARRY_TRAVEL).

    ``B`` is carried to the observation's node (through ``cr``, or widened by the distance
    and turn possible in between, as ``mode`` says), met with that node's hull, widened to the
    observation's stamp (its reach), contracted there with the observation and what it sees,
    and carried back; headings are matched modulo 2π in each box's branch.
    """
    bxl, bxh, byl, byh, btl, bth = B
    crl, crh, cal, cah, ctl, cth = cr
    rhl, rhh, all_, alh, rp, rt = ob
    # B at node kj (the modelled pose there)
    if mode == CARRY_FORWARD:  # k -> kj is the increment
        xl, xh, yl, yh = _move(bxl, bxh, byl, byh, btl, bth, crl, crh, cal, cah, False)
        tl, th = add(btl, bth, ctl, cth)
    elif mode == CARRY_BACKWARD:  # kj -> k is the increment
        tl, th = sub(btl, bth, ctl, cth)
        xl, xh, yl, yh = _move(bxl, bxh, byl, byh, tl, th, crl, crh, cal, cah, True)
    else:
        xl, xh = _widen(bxl, bxh, dp)
        yl, yh = _widen(byl, byh, dp)
        tl, th = down(btl + dl), up(bth + dh)
    if mode != CARRY_OWN:
        xl, xh = max(xl, hk[0]), min(xh, hk[1])
        yl, yh = max(yl, hk[2]), min(yh, hk[3])
        tl, th = angle_meet_narrow(hk[4], hk[5], tl, th)
        if not (xl <= xh) or not (yl <= yh) or not (tl <= th):
            return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # the true pose at the observation's stamp
    xl, xh = _widen(xl, xh, rp)
    yl, yh = _widen(yl, yh, rp)
    tl, th = _widen(tl, th, rt)
    r = range_bearing_pass(xl, xh, yl, yh, tl, th, tgt[0], tgt[1], tgt[2], tgt[3], rhl, rhh, all_, alh, 2)
    if not (r[0] <= r[1]):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # back to the modelled pose at node kj, then to node k, within B
    xl, xh = _widen(r[0], r[1], rp)
    yl, yh = _widen(r[2], r[3], rp)
    tl, th = _widen(r[4], r[5], rt)
    if mode == CARRY_FORWARD:
        tl, th = angle_meet(btl, bth, *sub(tl, th, ctl, cth))
        if not (tl <= th):
            return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        xl, xh, yl, yh = _move(xl, xh, yl, yh, tl, th, crl, crh, cal, cah, True)
    elif mode == CARRY_BACKWARD:
        xl, xh, yl, yh = _move(xl, xh, yl, yh, tl, th, crl, crh, cal, cah, False)
        tl, th = add(tl, th, ctl, cth)
    elif mode == CARRY_TRAVEL:
        xl, xh = _widen(xl, xh, dp)
        yl, yh = _widen(yl, yh, dp)
        tl, th = down(tl - dh), up(th - dl)
    xl, xh = max(xl, bxl), min(xh, bxh)
    yl, yh = max(yl, byl), min(yh, byh)
    tl, th = angle_meet(btl, bth, tl, th)
    return xl <= xh and yl <= yh and tl <= th, xl, xh, yl, yh, tl, th


# rows of the window's table (``W``, one per observation, filled once per pose update: what a
# candidate needs apart from the piece)
W_MODE = 0  # the CARRY_* mode, or W_IMAGE for an observation of this robot by another
W_CARRY = 1  # the composed increment between the two nodes (ρ, α, δθ), lo/hi pairs
W_HULL = 7  # the hull of the observation's node (x, y, θ)
W_TARGET = 13  # what it sees (x lo, x hi, y lo, y hi); W_IMAGE: the positions it allows this node
W_OBS = 17  # range, bearing and reach (position, heading), lo/hi pairs
W_TRAVEL = 23  # the distance and the turn's bounds possible between the nodes (CARRY_TRAVEL)
NW = 26
W_IMAGE = -1.0


@njit(cache=True)
def _window_row(H, L, U, k, j, node, lm, tnode, treach, rho, alpha, reach, travel, turn, turn_err, W, s, cr):
    """Row ``s`` of the window's table for observation ``j`` seen from node ``k``'s pose
    update: how it is carried to node ``k`` (``cr``: work (3, 2)), its node's hull, what it
    sees, its measurement and reach."""
    kj = node[j]
    mode = CARRY_OWN
    for c in range(W_CARRY, W_CARRY + 6):
        W[s, c] = 0.0
    W[s, W_TRAVEL], W[s, W_TRAVEL + 1], W[s, W_TRAVEL + 2] = 0.0, 0.0, 0.0
    if kj != k:
        if abs(kj - k) > MAX_CARRY_STEPS:
            mode = CARRY_TRAVEL
            W[s, W_TRAVEL] = up(up(abs(travel[k] - travel[kj])) * (1.0 + 1e-15))
            ta, tb = min(k, kj), max(k, kj)
            el = down(down(turn[tb, 0] - turn[ta, 0]) - turn_err)
            eh = up(up(turn[tb, 1] - turn[ta, 1]) + turn_err)
            W[s, W_TRAVEL + 1], W[s, W_TRAVEL + 2] = (el, eh) if kj > k else (-eh, -el)
        else:
            if kj > k:
                mode = CARRY_FORWARD
                compose_range(U, k, kj, cr)
            else:
                mode = CARRY_BACKWARD
                compose_range(U, kj, k, cr)
            for d in range(3):
                W[s, W_CARRY + 2 * d], W[s, W_CARRY + 2 * d + 1] = cr[d, 0], cr[d, 1]
    W[s, W_MODE] = mode
    for d in range(3):
        W[s, W_HULL + 2 * d], W[s, W_HULL + 2 * d + 1] = H[kj, d, 0], H[kj, d, 1]
    i = lm[j]
    if i >= 0:
        W[s, W_TARGET], W[s, W_TARGET + 1], W[s, W_TARGET + 2], W[s, W_TARGET + 3] = (
            L[i, 0, 0], L[i, 0, 1], L[i, 1, 0], L[i, 1, 1])
    else:  # the observed robot's position hull widened by its reach
        t = tnode[j]
        r = treach[j, 0]
        W[s, W_TARGET], W[s, W_TARGET + 1] = _widen(H[t, 0, 0], H[t, 0, 1], r)
        W[s, W_TARGET + 2], W[s, W_TARGET + 3] = _widen(H[t, 1, 0], H[t, 1, 1], r)
    W[s, W_OBS], W[s, W_OBS + 1] = rho[j, 0], rho[j, 1]
    W[s, W_OBS + 2], W[s, W_OBS + 3] = alpha[j, 0], alpha[j, 1]
    W[s, W_OBS + 4], W[s, W_OBS + 5] = reach[j, 0], reach[j, 1]


@njit(cache=True)
def _contract_piece(B, m, W, buf, lo, hi, piece, q_pose, capped, groups, ka, kb):
    """``piece`` = ``B`` ∩ the q-relaxed intersection (``q_pose``) of the ``m`` candidates of
    the window's table ``W`` (``buf``: each candidate, empty when the observation allows nothing
    in ``B``); with ``capped``, the wrong candidates also keep to the caps per pose and per
    landmark (:func:`qinter_capped_prefix` with ``groups``, ``ka``, ``kb``). Returns False as
    soon as more than ``q_pose`` candidates are empty, or if the result is empty. Few array
    arguments: numba counts references to each on every call."""
    n_empty = 0
    bt = (B[0, 0], B[0, 1], B[1, 0], B[1, 1], B[2, 0], B[2, 1])
    for s in range(m):
        if W[s, W_MODE] != W_IMAGE:
            res = _obs_pose_candidate(
                bt, int(W[s, W_MODE]),
                (W[s, W_CARRY], W[s, W_CARRY + 1], W[s, W_CARRY + 2], W[s, W_CARRY + 3], W[s, W_CARRY + 4],
                 W[s, W_CARRY + 5]),
                (W[s, W_HULL], W[s, W_HULL + 1], W[s, W_HULL + 2], W[s, W_HULL + 3], W[s, W_HULL + 4],
                 W[s, W_HULL + 5]),
                (W[s, W_TARGET], W[s, W_TARGET + 1], W[s, W_TARGET + 2], W[s, W_TARGET + 3]),
                (W[s, W_OBS], W[s, W_OBS + 1], W[s, W_OBS + 2], W[s, W_OBS + 3], W[s, W_OBS + 4], W[s, W_OBS + 5]),
                W[s, W_TRAVEL], W[s, W_TRAVEL + 1], W[s, W_TRAVEL + 2])
            ok = res[0]
            buf[s, 0, 0], buf[s, 0, 1], buf[s, 1, 0], buf[s, 1, 1], buf[s, 2, 0], buf[s, 2, 1] = res[1:]
        else:
            ok = W[s, W_TARGET] <= W[s, W_TARGET + 1]
            if ok:
                buf[s, 0, 0], buf[s, 0, 1] = max(B[0, 0], W[s, W_TARGET]), min(B[0, 1], W[s, W_TARGET + 1])
                buf[s, 1, 0], buf[s, 1, 1] = max(B[1, 0], W[s, W_TARGET + 2]), min(B[1, 1], W[s, W_TARGET + 3])
                buf[s, 2, 0], buf[s, 2, 1] = B[2, 0], B[2, 1]
                ok = buf[s, 0, 0] <= buf[s, 0, 1] and buf[s, 1, 0] <= buf[s, 1, 1]
        if not ok:
            _set_empty_at(buf, s)
            n_empty += 1
            if n_empty > q_pose:
                return False
    for d in range(3):
        for s in range(m):
            lo[s] = buf[s, d, 0]
            hi[s] = buf[s, d, 1]
        if capped:
            rl, rh = qinter_capped_prefix(lo, hi, m, groups, ka, kb)
        else:
            rl, rh = qinter_prefix(lo, hi, m, q_pose)
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
def _window_groups(m, idx, src, node, lm, q_pose, q_lm, groups):
    """Group the ``m`` chosen observations by node (``groups[0]``, caps ``groups[2]`` =
    ``q_pose``) and by landmark (``groups[1]``, caps ``groups[3]`` = ``q_lm`` of the landmark);
    −1 for an observation of a robot by another (each may be wrong). Returns how many may be
    wrong together — at most ``q_pose`` at each of their nodes and at most ``q_lm[i]`` of
    landmark ``i``'s — and the numbers of groups of each kind."""
    na = 0
    nb = 0
    other = 0
    for s in range(m):
        groups[0, s] = -1
        groups[1, s] = -1
        j = idx[s]
        if src[s] == 1 or lm[j] < 0:
            other += 1
            continue
        for t in range(s):
            if groups[0, t] >= 0 and node[idx[t]] == node[j]:
                groups[0, s] = groups[0, t]
            if groups[1, t] >= 0 and lm[idx[t]] == lm[j]:
                groups[1, s] = groups[1, t]
        if groups[0, s] < 0:
            groups[0, s] = na
            groups[2, na] = q_pose
            na += 1
        if groups[1, s] < 0:
            groups[1, s] = nb
            groups[3, nb] = q_lm[lm[j]]
            nb += 1
    by_lm = 0
    for g in range(nb):
        cnt = 0
        for s in range(m):
            if groups[1, s] == g:
                cnt += 1
        by_lm += min(cnt, groups[3, g])
    return min(q_pose * na, by_lm) + other, na, nb


@njit(cache=True)
def pose_update(PS, H, L, U, k, node_obs, node_stamp, obs_node_stamp, chain_lo, chain_hi, travel, turn, turn_err,
                window, window_obs, q_pose, pieces, node, lm, tnode, treach, by_target, target_first, rho, alpha,
                reach, status, buf, lo, hi, idx, src, agree, W, groups, stack, NEW, h_lo, h_hi, ver, posedone,
                lver, clock, q_lm, per_node):
    """Node ``k``'s set ∩= what the observations in its window allow, slice by slice (see the
    module docstring). Returns False if no slice survives (nothing written).

    At most ``q_pose`` of the window's observations are taken to be wrong, or with ``per_node``
    (``q_pose`` counted at each node) as many as :func:`_window_groups` allows, the wrong ones
    also capped per node and per landmark in the window's q-relaxed intersection.

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
    m_own = m
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
        img = np.empty((2, 2))
        s = f
        while s < by_target.shape[0] and tnode[by_target[s]] == k:
            j = by_target[s]
            s += 1
            if status[j] != OBS_USED:
                continue
            W[m, W_MODE] = W_IMAGE
            if not image_candidate(PS, H, j, node, rho, alpha, reach, img):
                W[m, W_TARGET], W[m, W_TARGET + 1] = EMPTY_LO, EMPTY_HI
            else:  # the observed robot's modelled pose: within its reach of the true one
                r = treach[j, 0]
                W[m, W_TARGET], W[m, W_TARGET + 1] = _widen(img[0, 0], img[0, 1], r)
                W[m, W_TARGET + 2], W[m, W_TARGET + 3] = _widen(img[1, 0], img[1, 1], r)
            idx[m] = j
            src[m] = 1
            agree[m] = False
            m += 1
    if m == 0:
        return True
    # the window's wrong observations: q_pose per node, q_lm per landmark
    qw, ka, kb = _window_groups(m, idx, src, node, lm, q_pose, q_lm, groups) if per_node else (q_pose, 0, 0)
    capped = per_node and m > m_own
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
    B = np.empty((3, 2))
    piece = np.empty((3, 2))
    for s in range(m):
        if src[s] == 0:
            _window_row(H, L, U, k, idx[s], node, lm, tnode, treach, rho, alpha, reach, travel, turn, turn_err, W, s,
                        piece)
    S = PS.shape[1]
    n_live = 0
    live0 = live_slices(PS, k)
    budget = pieces if live0 <= SUB_MAX_LIVE else 1  # a lost heading: each slice as one box
    lever = 0.0  # metres per radian of heading at the observations (their largest range)
    for s in range(m):
        lever = max(lever, rho[idx[s], 1])
    for b in range(S):
        _set_empty_at(NEW, b)
        if _empty(PS, k, b):
            continue
        # a paving of the slice (SIVIA with contraction, breadth first, at most `budget`
        # contractions): each box is contracted by the q-relaxed intersection of its candidates
        # (most boxes of a lost heading die after q_pose + 1 of them); a survivor is bisected
        # across its widest side (the heading weighted by `lever`) while the budget allows,
        # else it joins the slice's hull. Breadth first, the budget refines the whole slice
        # evenly: the hull is set by its coarsest boxes
        for d in range(3):
            stack[0, d, 0], stack[0, d, 1] = PS[k, b, d, 0], PS[k, b, d, 1]
        head = 0
        tail = 1
        while head < tail:
            for d in range(3):
                B[d, 0], B[d, 1] = stack[head, d, 0], stack[head, d, 1]
            head += 1
            if per_node and 0 < m_own < m:  # the pose's own observations alone first: q_pose of them
                if not _contract_piece(B, m_own, W, buf, lo, hi, piece, q_pose, False, groups, ka, kb):
                    continue
                for d in range(3):
                    B[d, 0], B[d, 1] = piece[d, 0], piece[d, 1]
            if not _contract_piece(B, m, W, buf, lo, hi, piece, qw, capped, groups, ka, kb):
                continue
            wx = piece[0, 1] - piece[0, 0]
            wy = piece[1, 1] - piece[1, 0]
            wt = (piece[2, 1] - piece[2, 0]) * lever
            wmax = max(wx, max(wy, wt))
            if tail + 2 <= budget and wmax > MIN_PIECE and wmax < INF:
                d = 0 if wx == wmax else (1 if wy == wmax else 2)
                mid = 0.5 * (piece[d, 0] + piece[d, 1])  # both halves hold mid: they cover the box
                for h in range(2):
                    for e in range(3):
                        stack[tail, e, 0], stack[tail, e, 1] = piece[e, 0], piece[e, 1]
                    if h == 0:
                        stack[tail, d, 1] = mid
                    else:
                        stack[tail, d, 0] = mid
                    tail += 1
            else:
                _hull_into(NEW, b, piece[0, 0], piece[0, 1], piece[1, 0], piece[1, 1], piece[2, 0], piece[2, 1])
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
