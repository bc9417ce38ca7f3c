"""Pose contraction against the map, cell by cell: the definition of :mod:`.contract`.

For each sub-box of the set inversion, each tested beam's endpoint region is enclosed outward
(:func:`~.geometry.sensor_box`, :func:`~.geometry.beam_offset`) and every cell it may touch is
looked up in the tiles (:func:`_region_free`): the beam is *excluded* when all are proven free.
:func:`contract_kernel_reference` is the oracle of the fast path
(:func:`.contract.contract_kernel`: the same kept count, hull and tested count, checked by
``tests/test_lidar_contract.py`` and ``bench/bench_lidar_contract.py``); :func:`_region_free`,
:func:`_empty_hull` and :func:`_join` are also the fast path's own (a region outside its dense
window is looked up here).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval.arith import add
from ivslam_cli.interval.rounding import down, up
from ivslam_cli.paving.tiles import EMPTY, cell_flags
from ivslam_cli.slam.lidar.geometry import beam_offset, range_bounds, sensor_box


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
def _empty_hull():
    """The hull of no box: ``[+inf, -inf]`` on each of the six bounds."""
    hull = np.empty(6)
    hull[0::2] = np.inf
    hull[1::2] = -np.inf
    return hull


@njit(cache=True, inline="always")
def _join(hull, b):
    """``hull`` (6,) := the hull of ``hull`` and the box ``b`` (6,)."""
    for d in range(6):
        hull[d] = min(hull[d], b[d]) if d % 2 == 0 else max(hull[d], b[d])


@njit(cache=True)
def excluded_beams(keys, slots, cells, eps, ranges, valid, a0, inc, sb, r_abs, r_rel, r_alpha, stride, q):
    """Number of beams (every ``stride``-th beam, those valid) whose endpoint region from the
    sensor box ``sb`` lies in proven-free cells; stops counting past ``q``."""
    n = 0
    for i in range(0, ranges.shape[0], stride):
        if not valid[i]:
            continue
        rl, rh = range_bounds(float(ranges[i]), r_abs, r_rel)
        dxl, dxh, dyl, dyh = beam_offset(sb[4], sb[5], rl, rh, a0 + i * inc, r_alpha)
        xl, xh = add(sb[0], sb[1], dxl, dxh)
        yl, yh = add(sb[2], sb[3], dyl, dyh)
        if _region_free(keys, slots, cells, eps, xl, xh, yl, yh):
            n += 1
            if n > q:
                return n
    return n


@njit(cache=True)
def contract_kernel_reference(keys, slots, cells, eps, ranges, valid, a0, inc, box, mx, my, myaw, r_abs, r_rel, r_alpha,
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
    hull = _empty_hull()
    while n_cur > 0:
        if tested + n_cur > max_boxes:  # out of budget: keep this level as it is
            for j in range(n_cur):
                _join(hull, cur[j])
            kept += n_cur
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
                _join(hull, b)
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
