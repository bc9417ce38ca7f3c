"""Pose contraction against the map (second seed): old beams end on obstacles, not in free space.

The map's P_EMPTY cells are proven free of obstacles (closed squares). A beam's endpoint is a
surface point, so for a pose consistent with beam ``i`` the endpoint region

    E_i(b) = s + [z_i ± r_ρ] (cos, sin)(θ_s + α_i + [±r_α])      (s, θ_s: the sensor pose of b)

cannot lie inside P_EMPTY. Over the pose box of a scan, a set inversion in pose space keeps
the sub-boxes ``b`` for which at most ``q`` beams are *excluded* (``E_i(b)`` covered by P_EMPTY
cells only): q-relaxation for moving people, glass and other beams the static-world model does
not explain. The hull of the kept sub-boxes is the contracted pose box.

Why sub-boxes: on a whole pose box the endpoint regions are wide and meet obstacle or unknown
cells almost always, so nothing is excluded; on small sub-boxes the wrong poses put many
endpoints in proven-free space (measured on the URG-04LX log: for over 90 % of beams the
endpoint region of a whole box lies in P_OBSTACLE; the contraction comes from what the map
excludes).

Guarantee: if the true pose is in the box, the world is static but for at most ``q`` beams
of the scan, and the map's P_EMPTY is sound (built from pose boxes that held the truth), the
true pose stays in the result. Every bound is rounded outward; cells are enumerated
generously (a region's cells include every cell it may touch).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval.arith import add, cos, mul, sin
from ivslam_cli.interval.rounding import down, up
from ivslam_cli.paving.tiles import EMPTY, cell_flags
from ivslam_cli.slam.lidar_geometry import range_bounds, sensor_box

#: an endpoint region over more cells than this is not tested (kept: sound, cheaper)
MAX_REGION_CELLS = 64


@njit(cache=True)
def _region_free(keys, slots, cells, eps, xl, xh, yl, yh):
    """True if every cell that may meet ``[xl, xh] x [yl, yh]`` is proven free."""
    ix0 = math.floor(down(xl / eps))
    ix1 = math.floor(up(xh / eps))
    iy0 = math.floor(down(yl / eps))
    iy1 = math.floor(up(yh / eps))
    if (ix1 - ix0 + 1) * (iy1 - iy0 + 1) > MAX_REGION_CELLS:
        return False
    for ix in range(ix0, ix1 + 1):
        for iy in range(iy0, iy1 + 1):
            if not (cell_flags(keys, slots, cells, ix, iy) & EMPTY):
                return False
    return True


@njit(cache=True)
def excluded_beams(keys, slots, cells, eps, ranges, valid, a0, inc, sb, r_abs, r_rel, r_alpha, stride, q):
    """Number of beams (every ``stride``-th valid one) whose endpoint region from the sensor box
    ``sb`` lies in proven-free cells; stops counting past ``q``."""
    n = 0
    for i in range(0, ranges.shape[0], stride):
        if not valid[i]:
            continue
        rl, rh = range_bounds(float(ranges[i]), r_abs, r_rel)
        al, ah = add(sb[4], sb[5], a0 + i * inc, a0 + i * inc)
        al = down(down(al - r_alpha) - 1e-15 * abs(al))
        ah = up(up(ah + r_alpha) + 1e-15 * abs(ah))
        cl, ch = cos(al, ah)
        sl, sh = sin(al, ah)
        dxl, dxh = mul(rl, rh, cl, ch)
        dyl, dyh = mul(rl, rh, sl, sh)
        xl, xh = add(sb[0], sb[1], dxl, dxh)
        yl, yh = add(sb[2], sb[3], dyl, dyh)
        if _region_free(keys, slots, cells, eps, xl, xh, yl, yh):
            n += 1
            if n > q:
                return n
    return n


@njit(cache=True)
def contract_kernel(keys, slots, cells, eps, ranges, valid, a0, inc, box, mx, my, myaw, r_abs, r_rel, r_alpha,
                    q, stride, min_xy, min_th, reach, max_boxes, out):
    """Set inversion over the robot pose ``box`` (6,): the hull of the sub-boxes not excluded,
    in ``out`` (6,). Returns ``(kept leaves, tested boxes)``; 0 kept means every pose is excluded
    (``out`` then unchanged).

    Breadth first: every box of a level is tested before the next level, each surviving box
    bisected along the widest of x, y and ``reach·θ``, down to ``min_xy`` / ``min_th``; when
    the next level would pass ``max_boxes`` tests in all, its boxes are kept untested (the
    budget refines evenly instead of exhausting itself in one corner)."""
    cap = max_boxes + 2
    cur = np.empty((cap, 6))
    nxt = np.empty((cap, 6))
    cur[0] = box
    n_cur = 1
    tested = 0
    kept = 0
    hull = np.empty(6)
    hull[0::2] = np.inf
    hull[1::2] = -np.inf
    while n_cur > 0:
        if tested + n_cur > max_boxes:  # out of budget: keep this level as it is
            for j in range(n_cur):
                kept += 1
                for d in range(6):
                    hull[d] = min(hull[d], cur[j, d]) if d % 2 == 0 else max(hull[d], cur[j, d])
            break
        n_nxt = 0
        for j in range(n_cur):
            b = cur[j]
            tested += 1
            sb = sensor_box(b[0], b[1], b[2], b[3], b[4], b[5], mx, my, myaw)
            sba = np.array(sb)
            if excluded_beams(keys, slots, cells, eps, ranges, valid, a0, inc, sba, r_abs, r_rel, r_alpha,
                              stride, q) > q:
                continue
            wx = b[1] - b[0]
            wy = b[3] - b[2]
            wt = (b[5] - b[4]) * reach
            if (wx <= min_xy and wy <= min_xy and b[5] - b[4] <= min_th) or n_nxt + 2 > cap:
                kept += 1
                for d in range(6):
                    hull[d] = min(hull[d], b[d]) if d % 2 == 0 else max(hull[d], b[d])
                continue
            d = 0 if (wx >= wy and wx >= wt) else (1 if wy >= wt else 2)
            m = 0.5 * (b[2 * d] + b[2 * d + 1])
            nxt[n_nxt] = b
            nxt[n_nxt, 2 * d + 1] = m
            nxt[n_nxt + 1] = b
            nxt[n_nxt + 1, 2 * d] = m
            n_nxt += 2
        cur, nxt = nxt, cur
        n_cur = n_nxt
    if kept > 0:
        for d in range(6):
            out[d] = hull[d]
    return kept, tested


def contract_pose(tmap, scans, k: int, robot_box, bounds, *, q: int = 0, stride: int = 1, min_xy: float = 0.02,
                  min_th: float = 0.005, reach: float = 4.0, max_boxes: int = 4096):
    """Contract the robot pose box (6,) of scan ``k`` against ``tmap`` (see the module docstring).

    Returns ``(box, kept, tested)``: the contracted box (the input box when no sub-box is kept,
    ``kept == 0``: the scan contradicts the map beyond ``q``)."""
    from ivslam_cli.interval.rounding import ensure_round_to_nearest

    ensure_round_to_nearest()
    bounds.check()
    b0, b1 = int(scans.offsets[k]), int(scans.offsets[k + 1])
    box = np.ascontiguousarray(robot_box, dtype=np.float64).reshape(6)
    out = box.copy()
    mx, my, myaw = (float(v) for v in scans.mount)
    kept, tested = contract_kernel(*tmap.arrays()[:3], float(tmap.eps), scans.ranges[b0:b1], scans.valid[b0:b1],
                                   float(scans.angle_min[k]), float(scans.angle_increment[k]), box, mx, my, myaw,
                                   float(bounds.range_abs), float(bounds.range_rel), float(bounds.bearing),
                                   int(q), int(stride), float(min_xy), float(min_th), float(reach),
                                   int(max_boxes), out)
    return out, int(kept), int(tested)


__all__ = ["contract_pose", "contract_kernel", "excluded_beams"]
