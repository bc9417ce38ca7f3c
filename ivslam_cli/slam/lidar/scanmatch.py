"""Interval scan matching: the pose of a scan relative to a keyframe scan, contracted by what
each scan proves free.

In the keyframe's robot frame the keyframe scan ``j`` was taken from the origin, exactly; the
pose ``b`` of scan ``k`` in that frame is unknown within a box. A beam's return is the first
surface along it, so everything nearer than the true distance, ``(z − r_abs)/(1 + r_rel)``,
is free — in the whole beam cone (P_EMPTY^{i,k} of the slides' sensor model). For a pose ``b``:

- **rule A**: a beam of ``k`` whose endpoint region (``s_k(b) + [ρ]·(cos, sin)(θ_k + α ± r_α)``)
  lies in the free space of ``j`` cannot be explained by a static world;
- **rule B**: nor can a beam of ``j`` whose endpoint region lies in the free space of ``k``
  seen from ``b``.

A sub-box of poses is excluded when more than ``q`` beams break rule A for all its poses, or
more than ``q`` break rule B (q-relaxation: a person walking, glass). Set inversion over the
box (breadth first under a budget) keeps the hull of the sub-boxes not excluded.

The tests are continuous (polar intervals against the other scan's free ranges, beam by
beam), not on a grid: free space here is not eroded by cells or by a global pose box, so
both rules bite as soon as a pose moves an endpoint past the range bound — rule A when it
moves endpoints into free space, rule B when it moves them behind a wall.

Free space between beams: beam cones cover the bearings between two beams when the bearing
bound is at least half the beam step; with narrower cones nothing between two beams is
proven free unless ``fill_gaps`` states the assumption (as for the map, see
:class:`ivslam_cli.slam.lidar.map_update.LidarBounds`); without either, neither rule excludes anything.

Guarantee: if the true relative pose is in the box, the world is static but for at most ``q``
beams of each scan, and the bounds hold, the true relative pose stays in the result. Every
bound is rounded outward.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval.arith import add
from ivslam_cli.interval.rounding import down, up
from ivslam_cli.slam.lidar.geometry import beam_offset, box_bearings, box_ranges, range_bounds, sensor_box

TWO_PI = 2.0 * math.pi
#: margin on bearings shifted by whole turns (2π·n in floating point, |n| small)
SHIFT_MARGIN = 1e-12


@njit(cache=True)
def free_ranges(ranges, valid, r_abs, r_rel, out):
    """``out[i]`` = the true distance's lower bound of beam ``i`` (every point of its cone nearer
    than this is free), −1 for an invalid beam."""
    for i in range(ranges.shape[0]):
        if valid[i]:
            out[i] = range_bounds(float(ranges[i]), r_abs, r_rel)[0]
        else:
            out[i] = -1.0


@njit(cache=True)
def covered_free(f, a0, inc, bl, bh, rho_h):
    """True if every point at bearing in ``[bl, bh]`` (sensor frame) and distance ≤ ``rho_h``
    is proven free by a scan with free ranges ``f`` (beams at ``a0 + i·inc`` whose cones
    touch, or whose gaps are assumed free): all beams from the one at or before ``bl`` to the
    one at or after ``bh`` valid with free range > ``rho_h``."""
    nb = f.shape[0]
    if not (bh - bl < TWO_PI):
        return False
    ac = a0 + 0.5 * (nb - 1) * inc
    n = math.floor((0.5 * (bl + bh) - ac) / TWO_PI + 0.5)
    if n != 0:
        bl = down(bl - n * TWO_PI) - SHIFT_MARGIN
        bh = up(bh - n * TWO_PI) + SHIFT_MARGIN
    i0 = math.floor(down(down(bl - a0) / inc))
    i1 = math.ceil(up(up(bh - a0) / inc))
    if i0 < 0 or i1 > nb - 1:
        return False
    for i in range(i0, i1 + 1):
        if not (rho_h < f[i]):
            return False
    return True


@njit(cache=True)
def _endpoint(sxl, sxh, syl, syh, stl, sth, z, a, r_abs, r_rel, r_alpha):
    """Endpoint region (box) of a beam of range ``z`` at angle ``a`` from the sensor box."""
    rl, rh = range_bounds(z, r_abs, r_rel)
    dxl, dxh, dyl, dyh = beam_offset(stl, sth, rl, rh, a, r_alpha)
    xl, xh = add(sxl, sxh, dxl, dxh)
    yl, yh = add(syl, syh, dyl, dyh)
    return xl, xh, yl, yh


@njit(cache=True)
def violations(b, mx, my, myaw, rk, vk, a0k, inck, fk, Ej, vj, a0j, incj, fj, r_abs, r_rel, r_alpha,
               stride, q, cones):
    """``(A, B)``: beams of ``k`` breaking rule A and of ``j`` breaking rule B for every pose of
    the robot box ``b`` (6,) of scan ``k`` in the keyframe frame; each count stops past ``q``.
    ``Ej`` (nj, 4): endpoint regions of the keyframe's beams in its frame."""
    if not cones:
        return 0, 0
    sxl, sxh, syl, syh, stl, sth = sensor_box(b[0], b[1], b[2], b[3], b[4], b[5], mx, my, myaw)
    # the keyframe's sensor: the mount, exactly
    na = 0
    for i in range(0, rk.shape[0], stride):
        if not vk[i]:
            continue
        xl, xh, yl, yh = _endpoint(sxl, sxh, syl, syh, stl, sth, float(rk[i]), a0k + i * inck, r_abs, r_rel,
                                   r_alpha)
        dxl, dxh = down(xl - mx), up(xh - mx)
        dyl, dyh = down(yl - my), up(yh - my)
        bl, bh, full = box_bearings(dxl, dxh, dyl, dyh)
        if full:
            continue
        rho_h = box_ranges(dxl, dxh, dyl, dyh)[1]
        if covered_free(fj, a0j, incj, down(bl - myaw), up(bh - myaw), rho_h):
            na += 1
            if na > q:
                break
    nbv = 0
    for i in range(0, Ej.shape[0], stride):
        if not vj[i]:
            continue
        dxl, dxh = down(Ej[i, 0] - sxh), up(Ej[i, 1] - sxl)
        dyl, dyh = down(Ej[i, 2] - syh), up(Ej[i, 3] - syl)
        bl, bh, full = box_bearings(dxl, dxh, dyl, dyh)
        if full:
            continue
        rho_h = box_ranges(dxl, dxh, dyl, dyh)[1]
        if covered_free(fk, a0k, inck, down(bl - sth), up(bh - stl), rho_h):
            nbv += 1
            if nbv > q:
                break
    return na, nbv


@njit(cache=True)
def _push(heap, n, keys, i):
    """Insert index ``i`` into the binary min-heap ``heap[:n]`` ordered by ``keys``."""
    heap[n] = i
    c = n
    while c > 0:
        p = (c - 1) // 2
        if keys[heap[p]] <= keys[heap[c]]:
            break
        heap[p], heap[c] = heap[c], heap[p]
        c = p
    return n + 1


@njit(cache=True)
def _pop(heap, n, keys):
    """Remove and return the index of the smallest key; returns ``(index, n)``."""
    top = heap[0]
    n -= 1
    heap[0] = heap[n]
    c = 0
    while True:
        a = 2 * c + 1
        if a >= n:
            break
        if a + 1 < n and keys[heap[a + 1]] < keys[heap[a]]:
            a += 1
        if keys[heap[c]] <= keys[heap[a]]:
            break
        heap[c], heap[a] = heap[a], heap[c]
        c = a
    return top, n


@njit(cache=True)
def match_kernel(rk, vk, a0k, inck, rj, vj, a0j, incj, box, mx, my, myaw, r_abs, r_rel, r_alpha, cones, q, stride,
                 min_xy, min_th, reach, max_boxes, out):
    """The hull of the poses of ``box`` (6,) not excluded, bound by bound, in ``out``.
    Returns ``(kept, tested)``: ``kept`` = 0 when every pose is excluded (``out`` unchanged),
    else the number of bounds found at leaf resolution (≤ 6).

    Each of the six bounds is found by a best-first search (a heap ordered by that bound of
    the sub-boxes, e.g. smallest ``x_lo`` first): the first consistent leaf popped (a sub-box
    not excluded, sides ≤ ``min_xy`` / ``min_th``) holds the extreme; excluded sub-boxes are
    dropped, others bisected along the widest of x, y and ``reach·θ``. With its share of the
    budget spent (``max_boxes`` / 6 tests), a search stops at the key on top of the heap: no
    pose beyond it was left. Each bound found narrows the box for the next search."""
    fk = np.empty(rk.shape[0])
    fj = np.empty(rj.shape[0])
    free_ranges(rk, vk, r_abs, r_rel, fk)
    free_ranges(rj, vj, r_abs, r_rel, fj)
    Ej = np.zeros((rj.shape[0], 4))
    for i in range(rj.shape[0]):
        if vj[i]:
            e = _endpoint(mx, mx, my, my, myaw, myaw, float(rj[i]), a0j + i * incj, r_abs, r_rel, r_alpha)
            Ej[i, 0], Ej[i, 1], Ej[i, 2], Ej[i, 3] = e
    per = max(max_boxes // 6, 1)
    cap = 2 * per + 4
    bx = np.empty((cap, 6))
    keys = np.empty(cap)
    heap = np.empty(cap, np.int64)
    cur = box.copy()
    tested = 0
    found = 0
    for side in range(6):
        d = side // 2
        lo_side = side % 2 == 0
        bx[0] = cur
        keys[0] = cur[2 * d] if lo_side else -cur[2 * d + 1]
        n = _push(heap, 0, keys, 0)
        used = 1
        t = 0
        best = np.nan
        while n > 0:
            if t >= per or used + 2 > cap:
                i = heap[0]  # out of budget: no pose before the top of the heap was left
                best = keys[i]
                break
            i, n = _pop(heap, n, keys)
            b = bx[i]
            t += 1
            na, nbv = violations(b, mx, my, myaw, rk, vk, a0k, inck, fk, Ej, vj, a0j, incj, fj, r_abs, r_rel,
                                 r_alpha, stride, q, cones)
            if na > q or nbv > q:
                continue
            wx = b[1] - b[0]
            wy = b[3] - b[2]
            wt = (b[5] - b[4]) * reach
            if wx <= min_xy and wy <= min_xy and b[5] - b[4] <= min_th:
                best = keys[i]
                found += 1
                break
            s = 0 if (wx >= wy and wx >= wt) else (1 if wy >= wt else 2)
            m = 0.5 * (b[2 * s] + b[2 * s + 1])
            for h in range(2):
                c = used
                used += 1
                bx[c] = b
                if h == 0:
                    bx[c, 2 * s + 1] = m
                else:
                    bx[c, 2 * s] = m
                keys[c] = bx[c, 2 * d] if lo_side else -bx[c, 2 * d + 1]
                n = _push(heap, n, keys, c)
        tested += t
        if math.isnan(best):
            return 0, tested  # every pose excluded
        if lo_side:
            cur[2 * d] = max(cur[2 * d], best)
        else:
            cur[2 * d + 1] = min(cur[2 * d + 1], -best)
    for k in range(6):
        out[k] = cur[k]
    return max(found, 1), tested


def match_scan(scans, j: int, k: int, rel_box, bounds, *, q: int = 0, stride: int = 1, min_xy: float = 0.01,
               min_th: float = 0.002, reach: float = 4.0, max_boxes: int = 1024):
    """Contract the robot pose box (6,) of scan ``k`` in the robot frame of scan ``j`` (see the
    module docstring). Returns ``(box, kept, tested)``; ``kept == 0``: no pose of the box is
    consistent with the two scans beyond ``q`` (the input box is returned)."""
    from ivslam_cli.interval.rounding import ensure_round_to_nearest

    ensure_round_to_nearest()
    bounds.check()
    box = np.ascontiguousarray(rel_box, dtype=np.float64).reshape(6)
    out = box.copy()
    jk = []
    for s in (k, j):
        b0, b1 = int(scans.offsets[s]), int(scans.offsets[s + 1])
        jk += [scans.ranges[b0:b1], scans.valid[b0:b1], float(scans.angle_min[s]), float(scans.angle_increment[s])]
    inc = max(float(scans.angle_increment[j]), float(scans.angle_increment[k]))
    cones = bool(bounds.fill_gaps) or float(bounds.bearing) >= 0.5 * inc  # as the map kernels decide
    mx, my, myaw = (float(v) for v in scans.mount)
    kept, tested = match_kernel(*jk, box, mx, my, myaw, float(bounds.range_abs), float(bounds.range_rel),
                                float(bounds.bearing), cones, int(q), int(stride), float(min_xy), float(min_th),
                                float(reach), int(max_boxes), out)
    return out, int(kept), int(tested)


__all__ = ["match_scan", "match_kernel", "violations", "covered_free", "free_ranges"]
