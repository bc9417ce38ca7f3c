"""Kernels of the motion model (numba), shared by the landmark and LiDAR pipelines.

Pose boxes ``P`` ``(N, 3, 2)`` at the nodes of a trajectory; motion step ``k`` between nodes
``k`` and ``k + 1`` is a pose increment in the frame of node ``k``, ``U[k] = [ρ, α, δθ]``
(:func:`ivslam_cli.slam.motion.motion_steps`):

    (x, y)_{k+1} = (x, y)_k + ρ (cos(θ_k + α), sin(θ_k + α)),   θ_{k+1} = θ_k + δθ (mod 2π)

the unicycle motion constraint ``s_k − h(s_{k−1}, u_k) ∈ [q]`` of the "Guaranteed SLAM –
practical considerations" slides (University of Manchester), with the noise folded into
``U``. :func:`step_contract` contracts both nodes of one step (the range-bearing and
angle-difference contractors, forward and backward); the passes over many steps (dead
reckoning, forward propagation, the backward smoothing sweep) are built on it.

Guarantee: if the true motion of each step lies in its ``U[k]``, the true poses stay in their
boxes (every contractor rounds outward); a step with no solution is counted, never written.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_difference import angle_difference_scalar
from ivslam_cli.contractors.ctc_range_bearing import range_bearing_scalar
from ivslam_cli.contractors.ctc_unicycle import shrink
from ivslam_cli.interval.angles import angle_meet_narrow
from ivslam_cli.interval.arith import EMPTY_HI, EMPTY_LO, INF, add, sub
from ivslam_cli.interval.rounding import PI_HI, TWO_PI_HI, down, up

INCREMENT = 1  # the only step kind (``kind`` is kept for other step models)
INCREMENT_PASSES = 4


@njit(cache=True)
def _empty12():
    e, f = EMPTY_LO, EMPTY_HI
    return (e, f, e, f, e, f, e, f, e, f, e, f)


@njit(cache=True)
def increment_scalar(x0l, x0h, y0l, y0h, t0l, t0h, x1l, x1h, y1l, y1h, t1l, t1h, rl, rh, al, ah, dl, dh):
    """Contract one pose-increment step; the 12 pose bounds, all empty if no solution."""
    b = (x0l, x0h, y0l, y0h, t0l, t0h, x1l, x1h, y1l, y1h, t1l, t1h)
    for _ in range(INCREMENT_PASSES):
        r = range_bearing_scalar(b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8], b[9], rl, rh, al, ah)
        if not (r[0] <= r[1]):
            return _empty12()
        rl, rh, al, ah = r[10], r[11], r[12], r[13]
        h = angle_difference_scalar(dl, dh, b[10], b[11], r[4], r[5])
        if not (h[0] <= h[1]):
            return _empty12()
        dl, dh = h[0], h[1]
        n = (r[0], r[1], r[2], r[3], h[4], h[5], r[6], r[7], r[8], r[9], h[2], h[3])
        progress = 0.0
        for j in range(6):
            progress = max(progress, shrink(b[2 * j], b[2 * j + 1], n[2 * j], n[2 * j + 1]))
        b = n
        if progress < 1e-3:
            break
    return b


@njit(cache=True)
def _write_step(a, c, r):
    """Write 12 pose bounds back to nodes ``a`` and ``c``; False (nothing written) if empty."""
    for d in range(6):
        if not (r[2 * d] <= r[2 * d + 1]):
            return False
    for d in range(3):
        a[d, 0] = r[2 * d]
        a[d, 1] = r[2 * d + 1]
        c[d, 0] = r[6 + 2 * d]
        c[d, 1] = r[6 + 2 * d + 1]
    return True


@njit(cache=True)
def step_contract(P, k, kind, U):
    """Contract nodes ``k`` and ``k + 1`` with motion step ``k``; False (nothing written) if empty."""
    a = P[k]
    c = P[k + 1]
    u = U[k]
    # headings in the branch where they are narrow (a heading wide over several turns keeps
    # every copy of its neighbour's image and would not contract)
    fl, fh = add(a[2, 0], a[2, 1], u[2, 0], u[2, 1])
    c[2, 0], c[2, 1] = angle_meet_narrow(c[2, 0], c[2, 1], fl, fh)
    bl, bh = sub(c[2, 0], c[2, 1], u[2, 0], u[2, 1])
    a[2, 0], a[2, 1] = angle_meet_narrow(a[2, 0], a[2, 1], bl, bh)
    if not (c[2, 0] <= c[2, 1]) or not (a[2, 0] <= a[2, 1]):
        return False
    r2 = increment_scalar(a[0, 0], a[0, 1], a[1, 0], a[1, 1], a[2, 0], a[2, 1],
                          c[0, 0], c[0, 1], c[1, 0], c[1, 1], c[2, 0], c[2, 1],
                          u[0, 0], u[0, 1], u[1, 0], u[1, 1], u[2, 0], u[2, 1])
    return _write_step(a, c, r2)


@njit(cache=True)
def cap_heading(P, k):
    """A heading interval wider than a turn says nothing beyond one turn: keep one turn,
    ``[c − π, c + π]`` around its centre (every angle mod 2π is still in it). Headings are
    angles everywhere they are used (matched modulo 2π), so this loses nothing; without it a
    set inversion over heading slices keeps a copy in every turn and never contracts."""
    tl = P[k, 2, 0]
    th = P[k, 2, 1]
    if tl <= th and th - tl > TWO_PI_HI and tl > -INF and th < INF:
        c = 0.5 * (tl + th)
        P[k, 2, 0] = down(c - PI_HI)
        P[k, 2, 1] = up(c + PI_HI)


@njit(cache=True)
def init_headings(P, kind, U):
    """Give every heading that covers the whole circle the dead-reckoned interval ``θ_k + u_k``.

    A heading is an angle: an interval of width ≥ 2π says nothing, and replacing it by any
    interval holding one representative of the true heading is sound. (The periodic contractors
    cannot do this themselves: the copies of ``θ_k + u_k`` inside the whole line have no hull.)
    """
    for k in range(P.shape[0] - 1):
        if not (P[k + 1, 2, 1] - P[k + 1, 2, 0] >= TWO_PI_HI) or not (P[k, 2, 0] <= P[k, 2, 1]):
            continue
        ul, uh = U[k, 2, 0], U[k, 2, 1]
        P[k + 1, 2, 0], P[k + 1, 2, 1] = add(P[k, 2, 0], P[k, 2, 1], ul, uh)


@njit(cache=True)
def dead_reckon(P, kind, U, step_events):
    """Forward pass of the motion steps from ``P[0]`` (the other boxes unbounded): in place.

    Headings wider than a turn are cut to one turn around their centre (headings are angles:
    nothing is lost). ``step_events[k]`` counts steps that found no solution (skipped).
    """
    init_headings(P, kind, U)
    for k in range(P.shape[0] - 1):
        if not step_contract(P, k, kind, U):
            step_events[k] += 1
        cap_heading(P, k + 1)


@njit(cache=True)
def widen_boxes(P, node, reach, out):
    """``out[j]`` = ``P[node[j]]`` widened by ``reach[j]`` = (position, heading), as the flat
    ``(x_lo, x_hi, y_lo, y_hi, θ_lo, θ_hi)`` rows ``update_map`` takes; rounded outward."""
    for j in range(node.shape[0]):
        b = P[node[j]]
        rp = reach[j, 0]
        rt = reach[j, 1]
        out[j, 0] = down(b[0, 0] - rp)
        out[j, 1] = up(b[0, 1] + rp)
        out[j, 2] = down(b[1, 0] - rp)
        out[j, 3] = up(b[1, 1] + rp)
        out[j, 4] = down(b[2, 0] - rt)
        out[j, 5] = up(b[2, 1] + rt)




@njit(cache=True)
def propagate(P, kind, U, step_events, k0, k1):
    """Forward pass of steps ``k0 .. k1 - 1`` (``P[k0]`` known): in place, as :func:`dead_reckon`."""
    for k in range(k0, k1):
        if not step_contract(P, k, kind, U):
            step_events[k] += 1
        cap_heading(P, k + 1)


@njit(cache=True)
def meet_node(P, k, box, rp, rt):
    """``P[k]`` ∩= the robot box (6,) of an event at node ``k`` widened back by its reach
    ``(rp, rt)`` (the node's box holds the modelled pose, within the reach of the event's).
    Returns False if they do not meet (nothing written)."""
    xl = max(P[k, 0, 0], down(box[0] - rp))
    xh = min(P[k, 0, 1], up(box[1] + rp))
    yl = max(P[k, 1, 0], down(box[2] - rp))
    yh = min(P[k, 1, 1], up(box[3] + rp))
    tl, th = angle_meet_narrow(P[k, 2, 0], P[k, 2, 1], down(box[4] - rt), up(box[5] + rt))
    if not (xl <= xh and yl <= yh and tl <= th):
        return False
    P[k, 0, 0], P[k, 0, 1], P[k, 1, 0], P[k, 1, 1], P[k, 2, 0], P[k, 2, 1] = xl, xh, yl, yh, tl, th
    return True


@njit(cache=True)
def smooth_backward(P, kind, U, step_events, k_last):
    """Backward pass of the motion steps ``k_last - 1 .. 0`` (forward-backward, as the landmark
    CSP): every node box meets what the next one allows through its step, so a contraction
    at a later scan narrows the boxes before it. In place; a step with no solution is counted
    in ``step_events`` and skipped. Returns the number of nodes that got narrower."""
    return smooth_backward_range(P, kind, U, step_events, 0, k_last)


@njit(cache=True)
def smooth_backward_range(P, kind, U, step_events, k_first, k_last):
    """:func:`smooth_backward` over the steps ``k_last - 1 .. k_first`` only (the nodes before
    ``k_first`` are not touched). Returns the number of nodes that got narrower."""
    n = 0
    for k in range(k_last - 1, k_first - 1, -1):
        w0 = (P[k, 0, 1] - P[k, 0, 0]) + (P[k, 1, 1] - P[k, 1, 0]) + (P[k, 2, 1] - P[k, 2, 0])
        if not step_contract(P, k, kind, U):
            step_events[k] += 1
            continue
        cap_heading(P, k)
        if (P[k, 0, 1] - P[k, 0, 0]) + (P[k, 1, 1] - P[k, 1, 0]) + (P[k, 2, 1] - P[k, 2, 0]) < w0:
            n += 1
    return n


@njit(cache=True)
def propagate_boxes(node_box, boxes, reach0, kind, U, k0, k1, reach1, out):
    """Each scan box ``boxes[i]`` (6,) of an event at node ``k0`` (``reach0``: its reach of the
    node) carried through the motion steps ``k0 .. k1 - 1`` to an event at node ``k1`` (reach
    ``reach1``), met with ``node_box`` (3, 2: what is known of node ``k0``): ``out[i]`` (6,).
    Returns a mask of the boxes that have a solution (the others are proven impossible)."""
    n = boxes.shape[0]
    ok = np.zeros(n, np.bool_)
    Q = np.empty((k1 - k0 + 1, 3, 2))
    w = np.empty((1, 6))
    node = np.zeros(1, np.int64)
    r1 = np.empty((1, 2))
    r1[0, 0], r1[0, 1] = reach1[0], reach1[1]
    kk = kind[k0:]
    uu = U[k0:]
    for i in range(n):
        for d in range(3):
            Q[0, d, 0] = node_box[d, 0]
            Q[0, d, 1] = node_box[d, 1]
        for t in range(1, k1 - k0 + 1):
            for d in range(3):
                Q[t, d, 0] = -INF
                Q[t, d, 1] = INF
        if not meet_node(Q, 0, boxes[i], reach0[0], reach0[1]):
            continue
        good = True
        for t in range(k1 - k0):
            if not step_contract(Q, t, kk, uu):
                good = False
                break
            cap_heading(Q, t + 1)
        if not good:
            continue
        node[0] = k1 - k0
        widen_boxes(Q, node, r1, w)
        for d in range(6):
            out[i, d] = w[0, d]
        ok[i] = True
    return ok
