"""Kernels of the landmark CSP: forward-backward sweeps over a whole trajectory.

Variables: pose boxes ``P`` ``(N, 3, 2)`` (x, y, θ at every node) and landmark boxes ``L``
``(L, 2, 2)``. Constraints:

- **motion** between nodes ``k`` and ``k + 1``: a pose increment in the frame of node ``k``
  (measured, or the enclosure of every unicycle path a twist allows), ``U[k] = [ρ, α, δθ]``:
  ``(x, y)_{k+1} = (x, y)_k + ρ (cos(θ_k + α), sin(θ_k + α))``, ``θ_{k+1} = θ_k + δθ (mod 2π)``;
- **observation** ``j`` of landmark ``lm[j]`` from node ``node[j]`` with range ``ρ_j`` and
  bearing ``α_j`` intervals (noise folded in). An observation made between two nodes is
  attached to the nearer one with ``reach[j] = (position, heading)`` half-widths bounding the
  motion possible in between: the pose at the observation lies in ``P[node] ⊕ reach``.

Robustness (q-relaxed intersections where constraints meet):

- per landmark: ``L_i ∩= qinter(candidates of its observations, q_i)``, where the candidate of
  observation ``j`` is the landmark box its pose box and measurement allow (the landmark box
  itself not used); an observation whose candidate misses ``L_i`` is **rejected**;
- per pose (at nodes with observations): ``P_k ∩= qinter(pose candidates, q_pose)`` over the
  non-rejected observations within ``window`` seconds, each candidate being the pose box its
  observation and landmark box allow, widened by the motion possible between the two stamps
  (``travel``: cumulative upper bound of the distance along the trajectory; ``turn``: cumulative
  lower and upper bounds of the heading change, ``turn_err`` bounding their float error). An observation whose
  pose candidate misses the result is rejected.

Empty motion steps (the data contradict the motion bounds, or an undetected outlier
contracted a pose wrongly) are recorded as events and that step's contraction is skipped, so
a run never ends silently empty.

Guarantee: if every motion step holds within its bounds and at most ``q_i`` observations of
landmark ``i`` and ``q_pose`` observations in each pose window break theirs, the true poses
and landmarks stay in the boxes (every contractor rounds outward).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_qinter import qinter_interval
from ivslam_cli.contractors.ctc_range_bearing import range_bearing_scalar
from ivslam_cli.interval.angles import angle_meet, angle_meet_narrow
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, INF
from ivslam_cli.interval.rounding import TWO_PI_HI, TWO_PI_LO, down, up

from ivslam_cli.slam.motion_kernel import INCREMENT, cap_heading, init_headings, step_contract  # noqa: F401

OBS_USED = 0
OBS_REJECTED_LANDMARK = 1  # its landmark candidate misses the q-relaxed landmark box
OBS_REJECTED_POSE = 2  # its pose candidate misses the q-relaxed pose box

BIG = 1e6
MIN_SLICE = 1e-4  # headings narrower than this are not sliced  # widths are capped at this in the convergence measure (unbounded boxes)


@njit(cache=True)
def _box_ok(b):
    for d in range(b.shape[0]):
        if not (b[d, 0] <= b[d, 1]):
            return False
    return True


@njit(cache=True)
def _widen(lo, hi, r):
    return down(lo - r), up(hi + r)


@njit(cache=True)
def landmark_candidate(P, j, node, rho, alpha, reach, out):
    """The landmark box observation ``j`` allows from its pose box alone; False if empty."""
    k = node[j]
    rp = reach[j, 0]
    rt = reach[j, 1]
    xl, xh = _widen(P[k, 0, 0], P[k, 0, 1], rp)
    yl, yh = _widen(P[k, 1, 0], P[k, 1, 1], rp)
    tl, th = _widen(P[k, 2, 0], P[k, 2, 1], rt)
    r = range_bearing_scalar(xl, xh, yl, yh, tl, th, -INF, INF, -INF, INF,
                             rho[j, 0], rho[j, 1], alpha[j, 0], alpha[j, 1])
    if not (r[0] <= r[1]):
        return False
    out[0, 0], out[0, 1] = r[6], r[7]
    out[1, 0], out[1, 1] = r[8], r[9]
    return True


@njit(cache=True)
def landmark_update(P, L, q, lm_offsets, lm_order, node, rho, alpha, reach, status, events_lm):
    """``L_i ∩= qinter(candidates, q_i − r_i)`` for every landmark, ``r_i`` of its observations
    being rejected already (proven outliers count against the q allowed); rejects the
    observations whose candidate misses the result. A landmark the q-relaxed intersection would empty keeps its
    box and counts an event in ``events_lm[i]``."""
    n_lm = L.shape[0]
    cand = np.empty((lm_order.shape[0], 2, 2))
    lo = np.empty(lm_order.shape[0])
    hi = np.empty(lm_order.shape[0])
    for i in range(n_lm):
        a = lm_offsets[i]
        b = lm_offsets[i + 1]
        m = 0
        rejected = 0
        for t in range(a, b):
            j = lm_order[t]
            if status[j] != OBS_USED:
                rejected += 1
                continue
            if not landmark_candidate(P, j, node, rho, alpha, reach, cand[m]):
                cand[m, 0, 0] = EMPTY_LO
                cand[m, 0, 1] = EMPTY_HI
                cand[m, 1, 0] = EMPTY_LO
                cand[m, 1, 1] = EMPTY_HI
            m += 1
        if m == 0:
            continue
        new = np.empty((2, 2))
        ok = True
        for d in range(2):
            for t in range(m):
                lo[t] = cand[t, d, 0]
                hi[t] = cand[t, d, 1]
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
        L[i] = new
        m = 0
        for t in range(a, b):
            j = lm_order[t]
            if status[j] != OBS_USED:
                continue
            c = cand[m]
            m += 1
            if (not (c[0, 0] <= c[0, 1]) or c[0, 1] < new[0, 0] or c[0, 0] > new[0, 1]
                    or c[1, 1] < new[1, 0] or c[1, 0] > new[1, 1]):
                status[j] = OBS_REJECTED_LANDMARK


@njit(cache=True)
def _obs_pose_candidate(P, L, B, k, j, node, lm, rho, alpha, reach, travel, turn, turn_err, out):
    """The part of pose box ``B`` (node ``k``) that observation ``j`` allows, in ``out``; False if none.

    ``B`` is carried to the observation's node (widened by the motion possible in between) and
    stamp (``reach[j]``), contracted there with the observation and its landmark box, and
    carried back; headings are matched modulo 2π on each node's own branch.
    """
    kj = node[j]
    i = lm[j]
    dp = 0.0
    # heading change from node k to node kj: [dl, dh] (exact along the chain of steps)
    dl = 0.0
    dh = 0.0
    if kj != k:
        dp = up(up(abs(travel[k] - travel[kj])) * (1.0 + 1e-15))
        a = min(k, kj)
        b = max(k, kj)
        el = down(down(turn[b, 0] - turn[a, 0]) - turn_err)
        eh = up(up(turn[b, 1] - turn[a, 1]) + turn_err)
        if kj > k:
            dl, dh = el, eh
        else:
            dl, dh = -eh, -el
    rp = up(dp + reach[j, 0])
    rt = reach[j, 1]
    # B at the observation's stamp (and within P[kj] at its node, when that is another one)
    xl, xh = _widen(B[0, 0], B[0, 1], rp)
    yl, yh = _widen(B[1, 0], B[1, 1], rp)
    tl, th = _widen(down(B[2, 0] + dl), up(B[2, 1] + dh), rt)
    if kj != k:
        xl = max(xl, down(P[kj, 0, 0] - reach[j, 0]))
        xh = min(xh, up(P[kj, 0, 1] + reach[j, 0]))
        yl = max(yl, down(P[kj, 1, 0] - reach[j, 0]))
        yh = min(yh, up(P[kj, 1, 1] + reach[j, 0]))
        pl, ph = _widen(P[kj, 2, 0], P[kj, 2, 1], reach[j, 1])
        tl, th = angle_meet_narrow(pl, ph, tl, th)
    if not (xl <= xh) or not (yl <= yh) or not (tl <= th):
        return False
    r = range_bearing_scalar(xl, xh, yl, yh, tl, th, L[i, 0, 0], L[i, 0, 1], L[i, 1, 0], L[i, 1, 1],
                             rho[j, 0], rho[j, 1], alpha[j, 0], alpha[j, 1])
    if not (r[0] <= r[1]):
        return False
    # back to node k, within B
    xl, xh = _widen(r[0], r[1], rp)
    yl, yh = _widen(r[2], r[3], rp)
    tl, th = _widen(down(r[4] - dh), up(r[5] - dl), rt)
    out[0, 0], out[0, 1] = max(xl, B[0, 0]), min(xh, B[0, 1])
    out[1, 0], out[1, 1] = max(yl, B[1, 0]), min(yh, B[1, 1])
    out[2, 0], out[2, 1] = angle_meet(B[2, 0], B[2, 1], tl, th)
    return out[0, 0] <= out[0, 1] and out[1, 0] <= out[1, 1] and out[2, 0] <= out[2, 1]


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
def pose_update(P, L, k, node_obs, node_stamp, obs_node_stamp, travel, turn, turn_err, window, q_pose, slices,
                node, lm, rho, alpha, reach, status, buf, lo, hi, idx, agree):
    """``P_k ∩= hull over heading slices of qinter(pose candidates in the window, q_pose)``.

    The heading interval of ``P_k`` is cut into ``slices`` pieces (set inversion in pose space:
    a box contractor cannot couple heading and position across several bearings); each piece
    is contracted by every observation in the window and the q-relaxed intersection taken; the
    hull of the surviving pieces is kept. Returns False if nothing survives (nothing written).
    ``node_obs`` are the observation indices sorted by node, ``obs_node_stamp`` their nodes'
    stamps (sorted). Observations of node ``k`` that agree with no surviving piece are rejected.
    """
    t = node_stamp[k]
    n_obs = node_obs.shape[0]
    first = np.searchsorted(obs_node_stamp, t - window, side="left")
    last = min(np.searchsorted(obs_node_stamp, t + window, side="right"), n_obs)
    m = 0
    for s in range(first, last):
        j = node_obs[s]
        if status[j] == OBS_USED:
            idx[m] = j
            agree[m] = False
            m += 1
    if m == 0:
        return True
    cap_heading(P, k)
    thl = P[k, 2, 0]
    thh = P[k, 2, 1]
    ns = slices
    if not (thh - thl > MIN_SLICE) or not (thh - thl < INF):
        ns = 1
    hull = np.empty((3, 2))
    for d in range(3):
        hull[d, 0] = EMPTY_LO
        hull[d, 1] = EMPTY_HI
    # heading pieces of the surviving slices, in slice order (for the hull on the circle)
    h_lo = np.empty(ns)
    h_hi = np.empty(ns)
    n_live = 0
    B = P[k].copy()
    width = thh - thl
    for sl in range(ns):
        # adjacent slices share their float boundary: the slices cover [thl, thh] exactly
        B[2, 0] = thl if sl == 0 else thl + width * sl / ns
        B[2, 1] = thh if sl == ns - 1 else thl + width * (sl + 1) / ns
        for s in range(m):
            if not _obs_pose_candidate(P, L, B, k, idx[s], node, lm, rho, alpha, reach, travel, turn, turn_err, buf[s]):
                for d in range(3):
                    buf[s, d, 0] = EMPTY_LO
                    buf[s, d, 1] = EMPTY_HI
        ok = True
        piece = np.empty((3, 2))
        for d in range(3):
            for s in range(m):
                lo[s] = buf[s, d, 0]
                hi[s] = buf[s, d, 1]
            rl, rh = qinter_interval(lo[:m], hi[:m], q_pose)
            rl = max(rl, B[d, 0])
            rh = min(rh, B[d, 1])
            if not (rl <= rh):
                ok = False
                break
            piece[d, 0] = rl
            piece[d, 1] = rh
        if not ok:
            continue
        for d in range(2):
            hull[d, 0] = min(hull[d, 0], piece[d, 0])
            hull[d, 1] = max(hull[d, 1], piece[d, 1])
        h_lo[n_live] = piece[2, 0]
        h_hi[n_live] = piece[2, 1]
        n_live += 1
        for s in range(m):
            inside = True
            for d in range(3):
                if not (buf[s, d, 0] <= buf[s, d, 1]) or buf[s, d, 1] < piece[d, 0] or buf[s, d, 0] > piece[d, 1]:
                    inside = False
            if inside:
                agree[s] = True
    if n_live == 0:
        return False
    hull[2, 0], hull[2, 1] = _circular_hull(h_lo, h_hi, n_live, thl, thh)
    P[k] = hull
    for s in range(m):
        if not agree[s] and node[idx[s]] == k:
            status[idx[s]] = OBS_REJECTED_POSE
    return True


@njit(cache=True)
def total_width(P, L):
    s = 0.0
    for k in range(P.shape[0]):
        for d in range(3):
            w = P[k, d, 1] - P[k, d, 0]
            s += min(w, BIG) if w >= 0.0 else 0.0
    for i in range(L.shape[0]):
        for d in range(2):
            w = L[i, d, 1] - L[i, d, 0]
            s += min(w, BIG) if w >= 0.0 else 0.0
    return s


@njit(cache=True)
def solve(P, L, kind, U, node_stamp, travel, turn, turn_err, node, lm, rho, alpha, reach, obs_node_stamp, by_node,
          node_first_obs, lm_offsets, lm_order, q, q_pose, window, slices, max_iterations, tolerance,
          status, step_events, pose_events, lm_events, width_trace):
    """Sweep forward and backward to a fixpoint (see the module docstring). In place.

    ``by_node``: observation indices sorted by node (``obs_node_stamp``: their nodes' stamps);
    ``node_first_obs[k]`` is -1 for nodes without observations. ``step_events[k]`` /
    ``pose_events[k]`` / ``lm_events[i]`` count the skipped contractions. ``width_trace[it]``
    is the summed width after sweep ``it``. Returns the number of sweeps done.
    """
    n = P.shape[0]
    m_max = by_node.shape[0] + 1
    buf = np.empty((m_max, 3, 2))
    lo = np.empty(m_max)
    hi = np.empty(m_max)
    idx = np.empty(m_max, dtype=np.int64)
    agree = np.empty(m_max, dtype=np.bool_)
    init_headings(P, kind, U)
    prev = total_width(P, L)
    done = 0
    for it in range(max_iterations):
        for k in range(n - 1):  # forward
            if not step_contract(P, k, kind, U):
                step_events[k] += 1
            if node_first_obs[k + 1] >= 0:
                if not pose_update(P, L, k + 1, by_node, node_stamp, obs_node_stamp, travel, turn, turn_err, window, q_pose,
                                   slices, node, lm, rho, alpha, reach, status, buf, lo, hi, idx, agree):
                    pose_events[k + 1] += 1
        landmark_update(P, L, q, lm_offsets, lm_order, node, rho, alpha, reach, status, lm_events)
        for k in range(n - 2, -1, -1):  # backward
            if not step_contract(P, k, kind, U):
                step_events[k] += 1
            if node_first_obs[k] >= 0:
                if not pose_update(P, L, k, by_node, node_stamp, obs_node_stamp, travel, turn, turn_err, window, q_pose,
                                   slices, node, lm, rho, alpha, reach, status, buf, lo, hi, idx, agree):
                    pose_events[k] += 1
        landmark_update(P, L, q, lm_offsets, lm_order, node, rho, alpha, reach, status, lm_events)
        w = total_width(P, L)
        width_trace[it] = w
        done = it + 1
        if prev > 0.0 and (prev - w) <= tolerance * prev:
            break
        prev = w
    return done
