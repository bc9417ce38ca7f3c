"""Kernels of the LiDAR pipeline's pose prediction (numba): dead reckoning over the motion
steps of :func:`ivslam_cli.slam.landmarks.motion_steps` and the boxes at the scan stamps."""

from __future__ import annotations

from numba import njit

from ivslam_cli.interval.angles import angle_meet_narrow
from ivslam_cli.interval.arith import add, cos, mul, sin, sub
from ivslam_cli.interval.rounding import down, up
from ivslam_cli.slam.landmarks_kernel import cap_heading, init_headings, step_contract


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
    n = 0
    for k in range(k_last - 1, -1, -1):
        w0 = (P[k, 0, 1] - P[k, 0, 0]) + (P[k, 1, 1] - P[k, 1, 0]) + (P[k, 2, 1] - P[k, 2, 0])
        if not step_contract(P, k, kind, U):
            step_events[k] += 1
            continue
        cap_heading(P, k)
        if (P[k, 0, 1] - P[k, 0, 0]) + (P[k, 1, 1] - P[k, 1, 0]) + (P[k, 2, 1] - P[k, 2, 0]) < w0:
            n += 1
    return n


@njit(cache=True)
def meet_boxes(a, b, out):
    """``out[j]`` = ``a[j] ∩ b[j]`` for flat pose boxes ``(x_lo, x_hi, y_lo, y_hi, θ_lo, θ_hi)``
    that both hold the same pose (headings met as angles, in the narrower one's branch); a row
    whose intersection is empty keeps ``a[j]``. Returns the number of such rows."""
    bad = 0
    for j in range(a.shape[0]):
        xl = max(a[j, 0], b[j, 0])
        xh = min(a[j, 1], b[j, 1])
        yl = max(a[j, 2], b[j, 2])
        yh = min(a[j, 3], b[j, 3])
        tl, th = angle_meet_narrow(a[j, 4], a[j, 5], b[j, 4], b[j, 5])
        if xl <= xh and yl <= yh and tl <= th:
            out[j, 0], out[j, 1], out[j, 2], out[j, 3], out[j, 4], out[j, 5] = xl, xh, yl, yh, tl, th
        else:
            bad += 1
            out[j] = a[j]
    return bad


@njit(cache=True)
def compose(a, r, out):
    """``out`` ⊇ ``{a ⊕ r}``: the pose ``r`` (relative, in the frame of pose ``a``) in the frame
    ``a`` is given in, for every ``a`` and ``r`` in the flat boxes ``(x_lo, x_hi, y_lo, y_hi,
    θ_lo, θ_hi)``: ``x = x_a + cos θ_a·x_r − sin θ_a·y_r``, ``y = y_a + sin θ_a·x_r + cos θ_a·y_r``,
    ``θ = θ_a + θ_r``; rounded outward."""
    cl, ch = cos(a[4], a[5])
    sl, sh = sin(a[4], a[5])
    p1l, p1h = mul(cl, ch, r[0], r[1])
    p2l, p2h = mul(sl, sh, r[2], r[3])
    dxl, dxh = sub(p1l, p1h, p2l, p2h)
    q1l, q1h = mul(sl, sh, r[0], r[1])
    q2l, q2h = mul(cl, ch, r[2], r[3])
    dyl, dyh = add(q1l, q1h, q2l, q2h)
    out[0], out[1] = add(a[0], a[1], dxl, dxh)
    out[2], out[3] = add(a[2], a[3], dyl, dyh)
    out[4], out[5] = add(a[4], a[5], r[4], r[5])
