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
- **skip edges** (:mod:`.skips`) between observation frames 2, 4, … frames apart on a chain:
  the composed increment of the steps between them, contracted like a motion step;
- **observation** ``j`` from node ``node[j]`` with range ``ρ_j`` and bearing ``α_j`` intervals
  (noise folded in) of landmark ``lm[j]``, or (``lm[j] = −1``) of the robot at node
  ``tnode[j]`` of another chain. The pose at the observation lies in ``PS[node] ⊕ reach[j]``
  (``reach`` = position and heading half-widths: the lag of the true pose behind the
  modelled one, or the motion possible between the observation's stamp and its node's);
  the observed robot's true pose lies in its node's set ``⊕ treach[j]``.

Robustness (q-relaxed intersections where constraints meet, Jaulin's robust set inversion):

- per landmark: ``L_i ∩= qinter(candidates of its observations, q_i)``, the candidate of
  observation ``j`` being the hull, over the slices of its pose set, of the landmark boxes
  each slice and the measurement allow, then refined on a grid with the candidates kept as
  unions of those per-slice boxes (the cells at least ``m − q_i`` unions meet); an
  observation whose candidate misses ``L_i`` is **rejected**;
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
landmark ``i`` and ``q_pose`` observations at each pose (in each pose window with
``robust.q_pose_scope = "window"``) break theirs, every true pose
lies in its node's set and every landmark in its box (every contractor rounds outward).
"""

from __future__ import annotations

import numpy as np
from numba import njit, objmode

from ivslam_cli.slam.landmarks.observations import (  # noqa: F401
    NW, OBS_REJECTED_LANDMARK, OBS_REJECTED_POSE, OBS_USED, landmark_update, pose_update)
from ivslam_cli.slam.landmarks.pose_sets import (  # noqa: F401
    STEP_NONE, _circular_hull, all_hulls, count_boxes, flatten_sets, make_bins, set_from_box, step_sets)
from ivslam_cli.slam.landmarks.skips import skip_sets
from ivslam_cli.slam.motion_kernel import INCREMENT, cap_heading, init_headings, step_contract  # noqa: F401
from ivslam_cli.slam.progress import tell

LANDMARK_GRID = 32  # landmark boxes are refined on a grid of this many cells a side (observations.landmark_update)
BIG = 1e6  # widths are capped at this in the convergence measure (unbounded boxes)


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
          width_trace, skip_a, skip_b, skip_R, skip_in_off, skip_out, skip_out_off, skip_events, per_node):
    """Sweep forward and backward to a fixpoint (see the module docstring). In place.

    ``by_node``: observation indices sorted by (chain, node) (``obs_node_stamp``: their nodes'
    stamps; ``chain_obs[c]:chain_obs[c + 1]`` the part on chain ``c``); ``node_first_obs[k]``
    is −1 for nodes without observations of their own or of their robot by others.
    ``step_events[k]`` / ``pose_events[k]`` / ``lm_events[i]`` count the skipped
    contractions. ``width_trace[it]`` is the summed width after sweep ``it``.

    Skip edges (:mod:`.skips`): edge ``e`` links nodes ``skip_a[e] < skip_b[e]`` by the composed
    increment ``skip_R[e]``; those into node ``b`` are ``skip_in_off[b]:skip_in_off[b + 1]``
    (contracted in the forward sweep on reaching ``b``), those from node ``a`` are
    ``skip_out[skip_out_off[a]:skip_out_off[a + 1]]`` (in the backward sweep);
    ``skip_events[e]`` counts the skipped contractions. Returns the number of sweeps done.
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
    W = np.empty((m_max, NW))  # the pose update's window table
    groups = np.empty((6, m_max), np.int64)  # its groupings of the window's wrong observations
    stack = np.empty((pieces + 2, 3, 2))
    cand = np.empty((node.shape[0], 2, 2))
    cimg = np.empty((node.shape[0], S, 2, 2))
    count = np.zeros((LANDMARK_GRID, LANDMARK_GRID), np.int64)
    mark = np.zeros((LANDMARK_GRID, LANDMARK_GRID), np.int64)
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
    skipdone = np.full(max(skip_a.shape[0], 1), -1, np.int64)
    all_hulls(PS, H)
    prev = total_width(H, L)
    done = 0
    for it in range(max_iterations):
        for k in range(n - 1):  # forward
            if not step_sets(PS, H, k, kind, U, BINS, accA, accC, h_lo, h_hi, ver, stepdone, clock):
                step_events[k] += 1
            k1 = k + 1
            for e in range(skip_in_off[k1], skip_in_off[k1 + 1]):
                if not skip_sets(PS, H, e, skip_a, skip_b, skip_R, accA, accC, h_lo, h_hi, ver, skipdone, clock):
                    skip_events[e] += 1
            if node_first_obs[k1] >= 0:
                c = chain_of[k1]
                if not pose_update(PS, H, L, U, k1, by_node, node_stamp, obs_node_stamp, chain_obs[c], chain_obs[c + 1],
                                   travel, turn, turn_err, window, window_obs, q_pose, pieces, node, lm, tnode, treach,
                                   by_target, target_first, rho, alpha, reach, status, buf, lo, hi, idx, src, agree,
                                   W, groups, stack, accA, h_lo, h_hi, ver, posedone, lver, clock, q, per_node):
                    pose_events[k1] += 1
        landmark_update(PS, H, L, q, lm_offsets, lm_order, node, rho, alpha, reach, status, lm_events, cand, cimg, cver,
                        lrej, lver, ver, clock, lo, hi, count, mark)
        for k in range(n - 2, -1, -1):  # backward
            if not step_sets(PS, H, k, kind, U, BINS, accA, accC, h_lo, h_hi, ver, stepdone, clock):
                step_events[k] += 1
            for t in range(skip_out_off[k], skip_out_off[k + 1]):
                e = skip_out[t]
                if not skip_sets(PS, H, e, skip_a, skip_b, skip_R, accA, accC, h_lo, h_hi, ver, skipdone, clock):
                    skip_events[e] += 1
            if node_first_obs[k] >= 0:
                c = chain_of[k]
                if not pose_update(PS, H, L, U, k, by_node, node_stamp, obs_node_stamp, chain_obs[c], chain_obs[c + 1],
                                   travel, turn, turn_err, window, window_obs, q_pose, pieces, node, lm, tnode, treach,
                                   by_target, target_first, rho, alpha, reach, status, buf, lo, hi, idx, src, agree,
                                   W, groups, stack, accA, h_lo, h_hi, ver, posedone, lver, clock, q, per_node):
                    pose_events[k] += 1
        landmark_update(PS, H, L, q, lm_offsets, lm_order, node, rho, alpha, reach, status, lm_events, cand, cimg, cver,
                        lrej, lver, ver, clock, lo, hi, count, mark)
        w = total_width(H, L)
        width_trace[it] = w
        done = it + 1
        with objmode():
            tell(done, max_iterations)
        if prev > 0.0 and (prev - w) <= tolerance * prev:
            break
        prev = w
    return done
