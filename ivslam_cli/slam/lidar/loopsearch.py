"""Loop search over wide priors: the poses of a scan in an old submap's frame when the two
global boxes allow metres and any heading.

Where the tracker and the narrow loop search start from a prior a few decimetres wide, a scan
coming back after a long stretch without loops has a prior metres wide with a heading that may
cover the circle; a best-first bound search (:func:`~.matcher.bound_kernel`) then spends its
budget on the wrong headings. This module paves the prior first (SIVIA: Jaulin & Walter,
*Set inversion via interval analysis for nonlinear bounded-error estimation*, Automatica 1993):
a depth-first bisection with the tracker's exclusion test (:func:`~.matcher._node_test`, rules A
and B, q-relaxed) on every ``stride``-th beam, boxes split along the widest of x, y and
median range × θ (rotation first while it moves beam ends more than the translation), down to
leaves of ``fine``. The kept leaves are the roots of the full match, which then bounds them with
every beam. Cartographer's loop closure searches a large window the same way, by branch and
bound over precomputed grids (Hess, Kohler, Rapp & Andor, *Real-time loop closure in 2D LIDAR
SLAM*, ICRA 2016, §V): here the summed-area table answers a sub-box's test in O(beams) whatever
its size.

Guarantee: a leaf is dropped only when the test proves that no pose in it agrees with the
submap (fewer beams make fewer exclusions: every-n-th-beam tests are sound), so if the true pose
is in the prior it is in a kept leaf. A paving out of budget or over ``max_leaves`` reports
itself incomplete: the caller then derives nothing from it (the prior still holds).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.slam.lidar.matcher import _node_test, beam_table, split_axis
from ivslam_cli.slam.lidar.references import own_runs
from ivslam_cli.slam.lidar.sweep_map import CHUNKS

#: the bisection's stack: one entry per level (x, y and θ halvings from the prior to a leaf)
STACK = 192
#: every n-th beam is tested while paving (the full match then uses every beam)
PAVE_STRIDE = 4
#: leaves are at most this wide in x, y and median range × θ [m]
PAVE_LEAF = 0.25
#: tests per paving, and leaves kept, at most (beyond: incomplete, nothing derived)
PAVE_BUDGET = 200_000
PAVE_LEAVES = 4096


@njit(cache=True, nogil=True)
def pave_kernel(prior, ranges, valid, a0, inc, mx, my, myaw, r_abs, r_rel, r_alpha, cones_from, q, stride, W, n_w, S, m,
                wx0, wy0, nx, ny, eps, use_grid, ref_f, ref_a0, ref_inc, ref_c, ref_th, n_ref, sw_d, sw_a, sw_e, off, fine,
                reach,
                budget, leaves):
    """Pave ``prior`` (6,): the sub-boxes of at most ``fine`` (x, y and ``reach``·θ) not
    excluded, written to ``leaves``. Returns ``(n_leaves, tested, complete)``; ``complete`` is
    False when ``budget`` tests or the capacity of ``leaves`` ran out (the leaves are then not a
    cover of the kept poses)."""
    beam_rl, beam_rh, beam_ca, beam_sa, free, n_beams, beam_o = beam_table(ranges, valid, a0, inc, r_abs, r_rel,
                                                                         stride, off)
    own_c, own_f = own_runs(free, off, a0, inc, r_alpha, cones_from, CHUNKS)
    stack = np.empty((STACK, 6))
    b = np.empty(6)
    for e in range(6):
        stack[0, e] = prior[e]
    n = 1
    n_out = 0
    tested = 0
    cap = leaves.shape[0]
    while n > 0:
        if tested >= budget:
            return n_out, tested, False
        n -= 1
        for e in range(6):
            b[e] = stack[n, e]
        tested += 1
        if _node_test(b, beam_rl, beam_rh, beam_ca, beam_sa, n_beams, free, a0, inc, W, n_w, mx, my, myaw, r_alpha,
                      cones_from, q, S, m, wx0, wy0, nx, ny, eps, use_grid, ref_f, ref_a0, ref_inc, ref_c, ref_th, n_ref,
                      sw_d, sw_a, sw_e, beam_o, own_c, own_f):
            continue
        s = split_axis(b[1] - b[0], b[3] - b[2], (b[5] - b[4]) * reach, fine)
        if s < 0:
            if n_out >= cap:
                return n_out, tested, False
            for e in range(6):
                leaves[n_out, e] = b[e]
            n_out += 1
            continue
        if n + 2 > STACK:
            return n_out, tested, False
        mid = 0.5 * (b[2 * s] + b[2 * s + 1])
        for e in range(6):
            stack[n, e] = b[e]
            stack[n + 1, e] = b[e]
        stack[n, 2 * s + 1] = mid
        stack[n + 1, 2 * s] = mid
        n += 2
    return n_out, tested, True


def merge_leaves(leaves: np.ndarray) -> np.ndarray:
    """Fewer boxes holding the same leaves: leaves with the same heading and y interval that
    touch in x are joined (the matcher tests its sub-boxes against every root)."""
    if leaves.shape[0] <= 1:
        return leaves
    order = np.lexsort((leaves[:, 0], leaves[:, 2], leaves[:, 4]))
    lv = leaves[order]
    out = [lv[0].copy()]
    for b in lv[1:]:
        c = out[-1]
        if b[4] == c[4] and b[5] == c[5] and b[2] == c[2] and b[3] == c[3] and b[0] <= c[1]:
            c[1] = max(c[1], b[1])
        else:
            out.append(b.copy())
    return np.array(out)


def pave(matcher, k: int, prior: np.ndarray, tmap, refs, stride: int, fine: float, budget: int,
         max_leaves: int, q: int | None = None) -> tuple[np.ndarray | None, int]:
    """Pave the wide ``prior`` (6,) of scan ``k`` against the submap ``tmap`` and its ``refs``
    with the :class:`~.matcher.Matcher`'s rules. Returns ``(roots, tested)``: the kept leaves
    merged (an empty array: every pose excluded, a contradiction), or None when the paving is
    incomplete or nothing could be tested (then nothing follows from it). ``q``: beams allowed
    to break each rule (default ``q_beams``)."""
    prior = np.ascontiguousarray(prior, float).reshape(6)
    setup = matcher.kernel_args(k, prior[None, :], tmap, refs, int(stride), q)
    if setup is None:
        return None, 0
    scan, rules, split_reach = setup
    leaves = np.empty((int(max_leaves), 6))
    n, tested, complete = pave_kernel(prior, *scan, *rules, float(fine), split_reach, int(budget), leaves)
    if not complete:
        return None, int(tested)
    return merge_leaves(leaves[:n]), int(tested)
