"""Kernels of the LiDAR pipeline's pose prediction (numba): dead reckoning over the motion
steps of :func:`ivslam_cli.slam.landmarks.motion_steps` and the boxes at the scan stamps."""

from __future__ import annotations

from numba import njit

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


