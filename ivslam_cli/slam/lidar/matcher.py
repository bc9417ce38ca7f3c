"""Scan-to-submap matching: the set of poses of a scan, in its submap's frame, that agree with
what the submap proves — a set inversion in ``(x, y, θ)`` (Jaulin, Kieffer, Didrit & Walter,
*Applied Interval Analysis*, 2001) by best-first bound searches.

Two constraints, both ways (the static world but for at most ``q`` beams):

- **rule A** (a return is a surface point): the end-point region of a beam of the scan, over
  every pose of a sub-box, cannot lie in proven-free space — the submap's P_EMPTY cells, or
  the free cones of a reference scan (the submap's anchor scan, exact at the frame's origin,
  and the last scan mapped into it, with its box), tested in continuous polar form;
- **rule B** (free space is free): the scan's free cones, over every pose of a sub-box, cannot
  cover a region proven to hold a surface point: the end-point region of a beam of a reference
  scan.

A sub-box is excluded when more than ``q`` beams of the scan break rule A for all its poses, or
more than ``q`` reference beams break rule B. :func:`bound_kernel` finds the heading's two
bounds over the prior (best-first: sub-boxes popped in the order of that bound, excluded ones
dropped, others split along the widest of x, y and median range × θ — rotation is split first
while it moves the beam ends more than the translation — until the first leaf of the heading
resolution is kept), then cuts the heading interval into slices and finds each slice's x and y
bounds (to a coarser resolution: two searches decide the heading, eight times as many the
slices): the pose set is a union of boxes, one per heading slice, not one hull. A search out
of budget returns the key on top of its heap (no pose beyond it was left): sound, looser.

Cost: the submap's cells not proven free are counted in a summed-area table over a window (a
rectangle of cells in O(1), whatever its size — Cartographer's branch-and-bound scan matcher
precomputes per-level grids for the same reason, Hess, Kohler, Rapp & Andor 2016); a beam's
end-point region over a sub-box is an oriented rectangle from one cosine and sine per sub-box
(no trigonometry per beam). Before the exact test of a rectangle against a scan's free cones,
one point of it is looked up in that scan's free ranges (a necessary condition,
:mod:`.free_cones`): most rectangles straddle a surface and are rejected there, in a third of
the exact test's time, with the same result.

Guarantee: if the true relative pose is in the prior, the bounds hold, the world is static but
for at most ``q`` beams of the scan and ``q`` of each rule's references, each scan's beams are
taken from poses within its ``sweep`` (how far the robot moves and turns from the scan's pose
while they are taken: every pose tested is widened by it) and the submap's P_EMPTY is sound, the
true pose is in the union kept. Interval bounds are rounded outward; the
oriented regions and bearings are evaluated in floating point and widened by explicit bounds on
their error (:data:`MARGIN_ABS` + :data:`MARGIN_REL` of the range; ``ATAN_ERR`` for the
polynomial atan2), which dominate the roundings involved.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.paving.tiles import EMPTY, TILE
from ivslam_cli.slam.lidar.free_cones import _cover_setup, _may_cover, _seg_free
from ivslam_cli.slam.lidar.geometry import MARGIN_ABS, beam_region, dn, range_bounds, sensor_offset, upf
from ivslam_cli.slam.lidar.references import (C_A0, C_AC, C_II, C_MI, C_OK, C_RAD, C_RR, C_RUNS, C_SMIN, C_TH, C_X,
                                              C_Y, own_runs, own_runs_at, reference_rows, runs_may_cover, scan_runs)
from ivslam_cli.slam.lidar.sweep_map import CHUNKS

#: windows of the summed-area table are at most this many cells (beyond: rule A is not used)
MAX_WINDOW_CELLS = 1 << 24


@njit(cache=True, nogil=True)
def build_window(cells, coords, n, wx0, wy0, nx, ny, S):
    """Summed-area table ``S`` ((nx + 1) · (ny + 1), int32) of the cells *not* proven free over
    the window of cells ``[wx0, wx0 + nx) × [wy0, wy0 + ny)`` (cells of no tile are unknown):
    ``S[a (ny + 1) + b]`` counts them over ``[wx0, wx0 + a) × [wy0, wy0 + b)``."""
    m = ny + 1
    F = np.ones((nx, ny), np.int32)
    for t in range(n):
        ox = coords[t, 0] * TILE - wx0
        oy = coords[t, 1] * TILE - wy0
        a0 = max(0, -ox)
        a1 = min(TILE, nx - ox)
        b0 = max(0, -oy)
        b1 = min(TILE, ny - oy)
        for a in range(a0, a1):
            for b in range(b0, b1):
                if cells[t, a, b] & EMPTY:
                    F[ox + a, oy + b] = 0
    for b in range(m):
        S[b] = 0
    for a in range(nx):
        run = 0
        S[(a + 1) * m] = 0
        for b in range(ny):
            run += F[a, b]
            S[(a + 1) * m + b + 1] = S[a * m + b + 1] + run


@njit(cache=True, inline="always")
def _clear(S, m, wx0, wy0, nx, ny, eps, xl, xh, yl, yh):
    """True if every cell that may meet ``[xl, xh] × [yl, yh]`` lies in the window and is proven
    free (closed cells: a point on a border is in both cells, one proven free suffices)."""
    ix0 = math.floor(dn(xl / eps)) - wx0
    ix1 = math.floor(upf(xh / eps)) - wx0 + 1
    iy0 = math.floor(dn(yl / eps)) - wy0
    iy1 = math.floor(upf(yh / eps)) - wy0 + 1
    if ix0 < 0 or iy0 < 0 or ix1 > nx or iy1 > ny:
        return False
    return S[ix1 * m + iy1] - S[ix0 * m + iy1] - S[ix1 * m + iy0] + S[ix0 * m + iy0] == 0


@njit(cache=True)
def _node_test(b, beam_rl, beam_rh, beam_ca, beam_sa, n_beams, free, a0, inc, W, n_w, mx, my, myaw, r_alpha,
               cones_from, q, S, m, wx0, wy0, nx, ny, eps, use_grid, ref_f, ref_a0, ref_inc, ref_c, ref_th, n_ref, sw_d,
               sw_a, sw_e, beam_o, own_c, own_f):
    """True if the sub-box ``b`` (6,) is excluded: more than ``q`` beams break rule A (their end
    points in the submap's proven-free cells, or in the free space of a reference scan: row
    ``r`` of ``ref_*`` (:mod:`.references`), its sensor within its radius of its centre, its
    heading in ``ref_th[r]``, its cones free from its ``smin`` on), or more than ``q`` witnesses break
    rule B (the scan's cones free from ``cones_from`` on; inf: no rule B), for every pose of
    ``b``. The scan's
    beams are taken from poses within ``sw_d`` (x, y) and ``sw_a`` (θ) of the scan's pose (its
    sweep): its free cones are tested over ``b`` widened by as much; beam ``j`` of the table is
    taken from a sensor within ``sw_e`` of the sensor at the scan's pose moved by ``beam_o[j,
    :2]`` (in its frame; ``beam_o[j, 2]`` its length), so rule A tests it over ``b`` widened by
    ``sw_e`` and ``sw_a`` and moved by as much (the sweep's nominal move). Rule B takes the
    scan's cones in the runs ``own_c``, ``own_f`` (:func:`~.references.own_runs`), each from its
    sensor so moved and widened by its spread; with no runs, from ``b`` widened by ``sw_d``."""
    bxl, bxh, byl, byh, btl, bth = b[0], b[1], b[2], b[3], b[4], b[5]
    if sw_a > 0.0:
        btl, bth = dn(btl - sw_a), upf(bth + sw_a)
    ox, oxh, oy, oyh, stl, sth = sensor_offset(btl, bth, mx, my, myaw)
    c = 0.5 * (stl + sth)
    hw = upf(upf(0.5 * (sth - stl)) + 1e-15 * abs(c) + 1e-300)
    d = upf(hw + r_alpha)
    # rule A: the sensor at the scan's pose, within sw_e of each beam's nominal one
    if sw_e > 0.0:
        bxl, bxh, byl, byh = dn(bxl - sw_e), upf(bxh + sw_e), dn(byl - sw_e), upf(byh + sw_e)
    sxl = dn(bxl + ox)
    sxh = upf(bxh + oxh)
    syl = dn(byl + oy)
    syh = upf(byh + oyh)
    ccx, ccy = 0.5 * (sxl + sxh), 0.5 * (syl + syh)
    hsx = upf(upf(0.5 * (sxh - sxl)) + 1e-15 * abs(ccx))
    hsy = upf(upf(0.5 * (syh - syl)) + 1e-15 * abs(ccy))
    rs = upf(math.hypot(hsx, hsy)) + MARGIN_ABS
    if (use_grid or n_ref) and d < 1.0:
        cc = math.cos(c)
        sc = math.sin(c)
        na = 0
        for i in range(n_beams):
            # the beam's nominal move, turned with the sensor (its lever over the heading spread)
            o_x = cc * beam_o[i, 0] - sc * beam_o[i, 1]
            o_y = sc * beam_o[i, 0] + cc * beam_o[i, 1]
            lev = upf(beam_o[i, 2] * (hw + 1e-15)) + 1e-15 * (abs(o_x) + abs(o_y))
            cx, cy, ux, uy, ah, ac, hx, hy = beam_region(ccx + o_x, ccy + o_y, cc, sc, beam_ca[i], beam_sa[i],
                                                         beam_rl[i], beam_rh[i], d)
            hx, hy = upf(hx + lev), upf(hy + lev)
            hit = use_grid and _clear(S, m, wx0, wy0, nx, ny, eps, dn(cx - hx - hsx), upf(cx + hx + hsx),
                                      dn(cy - hy - hsy), upf(cy + hy + hsy))
            r = 0
            while not hit and r < n_ref:  # reference scans, each in rows of runs (references.py)
                n_runs = int(ref_c[r, C_RUNS])
                lev_r = upf(rs + lev)
                if n_runs > 1:
                    t0, t1 = runs_may_cover(cx, cy, ux, uy, ah + lev_r, ref_c, r)
                else:
                    t0, t1 = 0, 0
                for t in range(r + t0, r + t1 + 1):
                    rc = ref_c[t]
                    extra = lev_r + rc[C_RAD]
                    if not _may_cover(cx + (ah + extra) * ux, cy + (ah + extra) * uy, rc[C_X], rc[C_Y], rc[C_TH], ref_f[t],
                                      ref_a0[t], rc[C_II], rc[C_AC], rc[C_MI], rc[C_OK] > 0.0, rc[C_RR],
                                      not (rc[C_SMIN] > 0.0)):
                        continue
                    hit = _seg_free(cx - rc[C_X], cy - rc[C_Y], ux, uy, ah + extra, ac + extra, ref_th[t, 0],
                                    ref_th[t, 1], ref_f[t], ref_a0[t], ref_inc[t], r_alpha, rc[C_SMIN])
                    if hit:
                        break
                r += n_runs
            if hit:
                na += 1
                if na > q:
                    return True
    if cones_from < math.inf and own_c.shape[0] > 0:  # the scan's cones in runs of beams
        own_runs_at(own_c, ccx, ccy, math.cos(c), math.sin(c), c, rs, hw)
        nb = 0
        for j in range(n_w):
            t0, t1 = runs_may_cover(W[j, 0], W[j, 1], W[j, 2], W[j, 3], W[j, 4], own_c, 0)
            for t in range(t0, t1 + 1):
                rc = own_c[t]
                e = W[j, 4] + rc[C_RAD]
                if not _may_cover(W[j, 0] + e * W[j, 2], W[j, 1] + e * W[j, 3], rc[C_X], rc[C_Y], c, own_f[t], rc[C_A0],
                                  rc[C_II], rc[C_AC], rc[C_MI], rc[C_OK] > 0.0, rc[C_RR], not (cones_from > 0.0)):
                    continue
                if _seg_free(W[j, 0] - rc[C_X], W[j, 1] - rc[C_Y], W[j, 2], W[j, 3], W[j, 4] + rc[C_RAD],
                             W[j, 5] + rc[C_RAD], stl, sth, own_f[t], rc[C_A0], inc, r_alpha, cones_from):
                    nb += 1
                    break
            if nb > q:
                return True
    elif cones_from < math.inf:
        if sw_d > sw_e:  # the scan's cones: its sensor anywhere the sweep takes it
            sxl = dn(dn(b[0] - sw_d) + ox)
            sxh = upf(upf(b[1] + sw_d) + oxh)
            syl = dn(dn(b[2] - sw_d) + oy)
            syh = upf(upf(b[3] + sw_d) + oyh)
            ccx, ccy = 0.5 * (sxl + sxh), 0.5 * (syl + syh)
            hsx = upf(upf(0.5 * (sxh - sxl)) + 1e-15 * abs(ccx))
            hsy = upf(upf(0.5 * (syh - syl)) + 1e-15 * abs(ccy))
            rs = upf(math.hypot(hsx, hsy)) + MARGIN_ABS
        nb = 0
        ii, acb, mi, ok, rr = _cover_setup(free.shape[0], a0, inc, r_alpha)
        for j in range(n_w):
            ahj = W[j, 4] + rs
            if not _may_cover(W[j, 0] + ahj * W[j, 2], W[j, 1] + ahj * W[j, 3], ccx, ccy, c, free, a0, ii, acb, mi, ok,
                              rr, not (cones_from > 0.0)):
                continue
            if _seg_free(W[j, 0] - ccx, W[j, 1] - ccy, W[j, 2], W[j, 3], W[j, 4] + rs, W[j, 5] + rs, stl, sth, free, a0,
                         inc, r_alpha, cones_from):
                nb += 1
                if nb > q:
                    return True
    return False


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
    """Remove and return the index of the smallest key: ``(index, n)``."""
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


@njit(cache=True, inline="always")
def _meets_roots(b, roots, n_roots):
    for r in range(n_roots):
        if (b[0] <= roots[r, 1] and roots[r, 0] <= b[1] and b[2] <= roots[r, 3] and roots[r, 2] <= b[3]
                and b[4] <= roots[r, 5] and roots[r, 4] <= b[5]):
            return True
    return False


@njit(cache=True, inline="always")
def split_axis(wx, wy, wt, fine):
    """The axis a sub-box of widths ``wx``, ``wy`` and ``wt`` (θ width × median range) is split
    along: the widest (rotation first when it moves the beam ends most); −1 for a leaf (every
    width at most ``fine``)."""
    if wx <= fine and wy <= fine and wt <= fine:
        return -1
    return 0 if (wx >= wy and wx >= wt) else (1 if wy >= wt else 2)


@njit(cache=True)
def _search(box, side, roots, n_roots, beam_rl, beam_rh, beam_ca, beam_sa, n_beams, free, a0, inc, W, n_w, mx, my,
            myaw, r_alpha, cones_from, q, S, m, wx0, wy0, nx, ny, eps, use_grid, ref_f, ref_a0, ref_inc, ref_c, ref_th,
            n_ref, sw_d, sw_a, sw_e, beam_o, own_c, own_f, fine, reach, budget, bx, keys, heap):
    """The extreme of side ``side`` (0..5: x_lo, x_hi, y_lo, y_hi, θ_lo, θ_hi) over the poses of
    ``box`` not excluded (and in some root), by a best-first search: sub-boxes popped in the
    order of that side; excluded ones dropped, others split along the widest of x, y and
    reach·θ; the first leaf kept (sides ≤ ``fine``) holds the extreme. With ``budget`` tests
    spent, the key on top of the heap is returned (no pose beyond it was left). Returns
    ``(bound, tested)``; the bound is NaN when every pose is excluded."""
    d = side // 2
    lo_side = side % 2 == 0
    cap = bx.shape[0]
    for e in range(6):
        bx[0, e] = box[e]
    keys[0] = box[2 * d] if lo_side else -box[2 * d + 1]
    n = _push(heap, 0, keys, 0)
    used = 1
    t = 0
    while n > 0:
        if t >= budget or used + 2 > cap:
            top = keys[heap[0]]
            return (top if lo_side else -top), t
        i, n = _pop(heap, n, keys)
        b = bx[i]
        if not _meets_roots(b, roots, n_roots):
            continue
        t += 1
        if _node_test(b, beam_rl, beam_rh, beam_ca, beam_sa, n_beams, free, a0, inc, W, n_w, mx, my, myaw, r_alpha,
                      cones_from, q, S, m, wx0, wy0, nx, ny, eps, use_grid, ref_f, ref_a0, ref_inc, ref_c, ref_th, n_ref,
                      sw_d, sw_a, sw_e, beam_o, own_c, own_f):
            continue
        s = split_axis(b[1] - b[0], b[3] - b[2], (b[5] - b[4]) * reach, fine)
        if s < 0:
            return (keys[i] if lo_side else -keys[i]), t
        mid = 0.5 * (b[2 * s] + b[2 * s + 1])
        for h in range(2):
            c = used
            used += 1
            for e in range(6):
                bx[c, e] = b[e]
            if h == 0:
                bx[c, 2 * s + 1] = mid
            else:
                bx[c, 2 * s] = mid
            keys[c] = bx[c, 2 * d] if lo_side else -bx[c, 2 * d + 1]
            n = _push(heap, n, keys, c)
    return np.nan, t


@njit(cache=True)
def beam_table(ranges, valid, a0, inc, r_abs, r_rel, stride, off):
    """The tested beams (every ``stride``-th valid one): true-distance bounds ``beam_rl``,
    ``beam_rh``, the cosine and sine of their angle and ``beam_o`` their sensor's nominal move
    (``off[i]``, x, y in the sensor frame at the stamp, and its length rounded up; ``off`` may
    have no rows: none); ``free[i]``: beam ``i``'s free range (−1 invalid), for every beam.
    Returns ``(beam_rl, beam_rh, beam_ca, beam_sa, free, n_beams, beam_o)`` (all but ``free``
    hold ``n_beams`` tested beams)."""
    nb_all = ranges.shape[0]
    beam_rl = np.empty(nb_all)
    beam_rh = np.empty(nb_all)
    beam_ca = np.empty(nb_all)
    beam_sa = np.empty(nb_all)
    beam_o = np.zeros((nb_all, 3))
    moved = off.shape[0] == nb_all
    free = np.empty(nb_all)
    n_beams = 0
    for i in range(ranges.shape[0]):
        if valid[i]:
            rl, rh = range_bounds(float(ranges[i]), r_abs, r_rel)
            free[i] = rl
            if i % stride == 0:
                ang = a0 + i * inc
                beam_rl[n_beams] = rl
                beam_rh[n_beams] = rh
                beam_ca[n_beams] = math.cos(ang)
                beam_sa[n_beams] = math.sin(ang)
                if moved:
                    beam_o[n_beams, 0], beam_o[n_beams, 1] = off[i, 0], off[i, 1]
                    beam_o[n_beams, 2] = upf(math.hypot(off[i, 0], off[i, 1]) * (1.0 + 1e-12))
                n_beams += 1
        else:
            free[i] = -1.0
    return beam_rl, beam_rh, beam_ca, beam_sa, free, n_beams, beam_o


@njit(cache=True, nogil=True)
def bound_kernel(roots, n_roots, ranges, valid, a0, inc, mx, my, myaw, r_abs, r_rel, r_alpha, cones_from, q, stride,
                 W, n_w, S, m, wx0, wy0, nx, ny, eps, use_grid, ref_f, ref_a0, ref_inc, ref_c, ref_th, n_ref, sw_d, sw_a,
                 sw_e, off,
                 fine, reach, max_nodes, max_slices, kept, fine_th):
    """The poses of the prior ``roots[:n_roots]`` not excluded, as boxes per heading slice:
    first the heading's two bounds (best-first searches over the prior's hull, to leaves of
    ``fine_th``), then the heading interval cut into at most ``max_slices`` slices and each
    slice's x and y bounds (to leaves of ``fine``).
    Writes the slices to ``kept``; returns ``(n_slices, tested)`` (0 slices: every pose
    excluded)."""
    beam_rl, beam_rh, beam_ca, beam_sa, free, n_beams, beam_o = beam_table(ranges, valid, a0, inc, r_abs, r_rel,
                                                                         stride, off)
    own_c, own_f = own_runs(free, off, a0, inc, r_alpha, cones_from, CHUNKS)
    hull = np.empty(6)
    for e in range(6):
        hull[e] = roots[0, e]
    for r in range(1, n_roots):
        for e in range(3):
            hull[2 * e] = min(hull[2 * e], roots[r, 2 * e])
            hull[2 * e + 1] = max(hull[2 * e + 1], roots[r, 2 * e + 1])
    b_th = max(max_nodes // 4, 16)
    cap = 2 * b_th + 8
    bx = np.empty((cap, 6))
    keys = np.empty(cap)
    heap = np.empty(cap, np.int64)
    tested = 0
    for side in (4, 5):
        v, t = _search(hull, side, roots, n_roots, beam_rl, beam_rh, beam_ca, beam_sa, n_beams, free, a0, inc, W, n_w,
                       mx, my, myaw, r_alpha, cones_from, q, S, m, wx0, wy0, nx, ny, eps, use_grid, ref_f, ref_a0, ref_inc,
                       ref_c, ref_th, n_ref, sw_d, sw_a, sw_e, beam_o, own_c, own_f, fine_th, reach, b_th, bx, keys,
                       heap)
        tested += t
        if math.isnan(v):
            return 0, tested
        if side == 4:
            hull[4] = max(hull[4], v)
        else:
            hull[5] = min(hull[5], v)
    ns = int(min(max_slices, max(1, math.ceil((hull[5] - hull[4]) * reach / fine))))
    b_s = max((max_nodes - tested) // (4 * ns), 8)
    sl = np.empty(6)
    out = 0
    for k in range(ns):
        tl = hull[4] + (hull[5] - hull[4]) * (k / ns)
        th = hull[5] if k == ns - 1 else hull[4] + (hull[5] - hull[4]) * ((k + 1) / ns)
        # the slice's box: the hull of the roots meeting it
        sl[0], sl[1], sl[2], sl[3] = np.inf, -np.inf, np.inf, -np.inf
        for r in range(n_roots):
            if roots[r, 4] <= th and tl <= roots[r, 5]:
                sl[0] = min(sl[0], roots[r, 0])
                sl[1] = max(sl[1], roots[r, 1])
                sl[2] = min(sl[2], roots[r, 2])
                sl[3] = max(sl[3], roots[r, 3])
        if not sl[0] <= sl[1]:
            continue
        sl[4], sl[5] = tl, th
        ok = True
        for side in range(4):
            v, t = _search(sl, side, roots, n_roots, beam_rl, beam_rh, beam_ca, beam_sa, n_beams, free, a0, inc, W,
                           n_w, mx, my, myaw, r_alpha, cones_from, q, S, m, wx0, wy0, nx, ny, eps, use_grid, ref_f, ref_a0,
                           ref_inc, ref_c, ref_th, n_ref, sw_d, sw_a, sw_e, beam_o, own_c, own_f, fine, reach, b_s, bx,
                           keys, heap)
            tested += t
            if math.isnan(v):
                ok = False
                break
            if side % 2 == 0:
                sl[side] = max(sl[side], v)
            else:
                sl[side] = min(sl[side], v)
        if ok:
            for e in range(6):
                kept[out, e] = sl[e]
            out += 1
    return out, tested


def join_slices(kept: np.ndarray, max_boxes: int) -> np.ndarray:
    """The union ``kept`` (n, 6) as at most ``max_boxes`` boxes, one per heading slice: boxes with
    the same heading interval are joined (hull in x, y), then neighbouring slices (by heading)
    are joined until at most ``max_boxes`` remain (each join keeps every kept pose)."""
    if kept.shape[0] == 0:
        return kept.reshape(0, 6)
    keys = np.round(kept[:, 4:6], 15)
    order = np.lexsort((keys[:, 1], keys[:, 0]))
    k = kept[order]
    kk = keys[order]
    change = np.concatenate([[True], np.any(kk[1:] != kk[:-1], axis=1)])
    starts = np.flatnonzero(change)
    out = np.empty((starts.size, 6))
    out[:, 0] = np.minimum.reduceat(k[:, 0], starts)
    out[:, 1] = np.maximum.reduceat(k[:, 1], starts)
    out[:, 2] = np.minimum.reduceat(k[:, 2], starts)
    out[:, 3] = np.maximum.reduceat(k[:, 3], starts)
    out[:, 4] = np.minimum.reduceat(k[:, 4], starts)
    out[:, 5] = np.maximum.reduceat(k[:, 5], starts)
    boxes = [row for row in out[np.argsort(out[:, 4], kind="stable")]]
    while len(boxes) > max(1, max_boxes):
        # join the neighbouring pair whose hull grows the least
        best, bi = math.inf, 0
        for i in range(len(boxes) - 1):
            a, c = boxes[i], boxes[i + 1]
            grow = ((max(a[1], c[1]) - min(a[0], c[0])) * (max(a[3], c[3]) - min(a[2], c[2]))
                    - (a[1] - a[0]) * (a[3] - a[2]) - (c[1] - c[0]) * (c[3] - c[2]))
            if grow < best:
                best, bi = grow, i
        a, c = boxes[bi], boxes[bi + 1]
        boxes[bi:bi + 2] = [np.array([min(a[0], c[0]), max(a[1], c[1]), min(a[2], c[2]), max(a[3], c[3]),
                                      min(a[4], c[4]), max(a[5], c[5])])]
    return np.array(boxes).reshape(-1, 6)


def hull(boxes: np.ndarray) -> np.ndarray:
    """The hull (6,) of boxes (n, 6)."""
    return np.array([boxes[:, 0].min(), boxes[:, 1].max(), boxes[:, 2].min(), boxes[:, 3].max(),
                     boxes[:, 4].min(), boxes[:, 5].max()])


class Matcher:
    """Scan-to-submap matching with reusable buffers (one per tracker).

    :meth:`match` returns ``(union (m, 6), kept_any, tested)``: the poses of the prior that agree
    with the submap, as boxes; ``kept_any`` False when none agrees (the data contradict the
    model beyond q: the caller keeps the prior and records it)."""

    def __init__(self, params, scans, model=None, chunks=None) -> None:
        b = params.beams
        # the sweep (prediction.SweepModel; None: every beam at the stamp): per scan, how far the
        # robot may move and turn while its beams are taken, the distance from its sensor below
        # which its cones prove nothing (sweep_free_from), each beam's nominal move and its error
        S = len(scans)
        self.sweep = np.zeros((S, 2)) if model is None else np.asarray(model.reach, float)
        self.smin = np.zeros(S) if model is None else np.asarray(model.smin, float)
        self.err = self.sweep[:, 0] if model is None else np.asarray(model.err, float)
        self.off = np.zeros((0, 2)) if model is None else np.ascontiguousarray(model.offset, float)
        self.lever = np.zeros(S) if model is None else np.asarray(model.turn_lever, float)
        self.run_turn = None if model is None else model.run_turn
        self.run_err = None if model is None else model.run_err
        # a swept reference scan in runs of beams, each from its nominal sensor (sweep_map.Chunks)
        self.chunks = chunks
        self.p = params
        self.scans = scans
        self.r_abs, self.r_rel, self.r_alpha = float(b.range_abs), float(b.range_rel), float(b.bearing)
        self.fill = bool(b.fill_gaps)
        self.mount = tuple(float(v) for v in scans.mount)
        nb = int(np.max(np.diff(scans.offsets))) if len(scans) else 1
        self.W = np.empty((2 * nb + 4, 6))
        self.kept = np.empty((params.match_slices + 64, 6))
        self.S = np.zeros(1, np.int32)
        self.last_beams = 0

    def _scan(self, k: int):
        sc = self.scans
        b0, b1 = int(sc.offsets[k]), int(sc.offsets[k + 1])
        return sc.ranges[b0:b1], sc.valid[b0:b1], float(sc.angle_min[k]), float(sc.angle_increment[k])

    def references(self, refs, stride: int | None = None):
        """Witness disks (rule B) and the reference scans' free spaces (rule A) of ``refs``:
        (scan index, robot box (6,)) pairs; a swept reference in runs of beams
        (:mod:`.references`)."""
        sc = self.scans
        rt, re = self.run_turn, self.run_err
        runs = [scan_runs(k, box, int(sc.offsets[k + 1] - sc.offsets[k]), self.chunks, self.sweep[k],
                          float(self.err[k]) if re is None else re[k], float(self.lever[k]),
                          None if rt is None else rt[k]) for k, box in refs]
        out = reference_rows(sc, refs, runs, self.mount, self.r_abs, self.r_rel, self.r_alpha, self.smin,
                             int(self.p.match_stride if stride is None else stride), self.W)
        self.W = out[-1]
        return out[:-1]

    def window(self, tmap, roots: np.ndarray, reach: float):
        """The summed-area table over the cells the scan's endpoints can reach from ``roots``
        (clipped to the submap's tiles). Returns ``(m, wx0, wy0, nx, ny, use_grid)``."""
        eps = tmap.eps
        if tmap.n_tiles == 0:
            return 1, 0, 0, 0, 0, False
        co = tmap.coords[: tmap.n]
        tx0, ty0 = int(co[:, 0].min()) * TILE, int(co[:, 1].min()) * TILE
        tx1, ty1 = (int(co[:, 0].max()) + 1) * TILE, (int(co[:, 1].max()) + 1) * TILE
        pad = reach + math.hypot(self.mount[0], self.mount[1]) + 2 * eps
        x0 = max(tx0, math.floor((roots[:, 0].min() - pad) / eps))
        x1 = min(tx1, math.ceil((roots[:, 1].max() + pad) / eps))
        y0 = max(ty0, math.floor((roots[:, 2].min() - pad) / eps))
        y1 = min(ty1, math.ceil((roots[:, 3].max() + pad) / eps))
        nx, ny = x1 - x0, y1 - y0
        if nx <= 0 or ny <= 0 or nx * ny > MAX_WINDOW_CELLS:
            return 1, 0, 0, 0, 0, False
        need = (nx + 1) * (ny + 1)
        if self.S.shape[0] < need:
            self.S = np.zeros(max(need, 2 * self.S.shape[0]), np.int32)
        build_window(tmap.cells, tmap.coords, tmap.n, x0, y0, nx, ny, self.S)
        return ny + 1, x0, y0, nx, ny, True

    def kernel_args(self, k: int, roots: np.ndarray, tmap, refs, stride: int, q: int | None = None):
        """The kernels' arguments for scan ``k`` over ``roots`` against ``tmap`` and ``refs``:
        ``(scan, rules, split_reach)`` — scan ``(ranges, valid, a0, inc)``, rules the tuple from
        the mount to ``sw_a`` in :func:`bound_kernel`'s order — or None when nothing can be
        tested (no valid beam, unbounded roots, no map and no reference)."""
        r, v, a0, inc = self._scan(k)
        self.last_beams = int(np.count_nonzero(v[::stride]))
        if not np.all(np.isfinite(roots)) or not v.any():
            return None
        z = r[v].astype(np.float64)
        reach = float(np.max(z)) + self.r_abs + self.r_rel * float(np.max(z)) + 1e-6
        cones = self.fill or self.r_alpha >= 0.5 * inc  # as the map kernels decide (their _cos_gap)
        refs = refs if cones else []
        n_w, ref_f, ref_a0, ref_inc, ref_c, ref_th, n_ref = self.references(refs, stride)
        m, wx0, wy0, nx, ny, use_grid = self.window(tmap, roots, reach + float(self.sweep[k, 0]))
        if not (use_grid or n_w or n_ref):
            return None
        mx, my, myaw = self.mount
        q = int(self.p.q_beams if q is None else q)
        cones_from = float(self.smin[k]) if cones else math.inf
        rules = (mx, my, myaw, self.r_abs, self.r_rel, self.r_alpha, cones_from, q, stride, self.W, n_w,
                 self.S, m, wx0, wy0, nx, ny, float(tmap.eps), use_grid, ref_f, ref_a0, ref_inc, ref_c, ref_th, n_ref,
                 float(self.sweep[k, 0]), float(self.sweep[k, 1]), float(self.err[k]),
                 self.off[int(self.scans.offsets[k]):int(self.scans.offsets[k + 1])] if self.off.shape[0] else self.off)
        return (r, v, a0, inc), rules, float(np.median(z))

    def match(self, k: int, roots: np.ndarray, tmap, refs, budget: int | None = None,
              stride: int | None = None, q: int | None = None, slices: int | None = None,
              resolution: float | None = None) -> tuple[np.ndarray, bool, int]:
        """Match scan ``k`` from the prior ``roots`` against the submap ``tmap``'s proven-free
        cells and the ``refs`` scans ((scan, robot box) pairs: their free space for rule A, their
        beam ends for rule B); ``budget``: sub-boxes tested at most (default ``match_boxes``),
        ``stride``: every n-th beam (default ``match_stride``); ``q``: beams allowed to break each
        rule (default ``q_beams``); ``slices``: heading slices at most (default ``match_slices``;
        1: the hull alone, the whole budget on its four sides); ``resolution``: the slices' x and
        y leaves (default ``match_resolution``)."""
        p = self.p
        stride = int(p.match_stride if stride is None else stride)
        n_slices = int(p.match_slices if slices is None else slices)
        fine = float(p.match_resolution if resolution is None else resolution)
        roots = np.ascontiguousarray(roots, float).reshape(-1, 6)
        setup = self.kernel_args(k, roots, tmap, refs, stride, q)
        if setup is None:
            return roots, True, 0
        scan, rules, split_reach = setup
        budget = int(p.match_boxes if budget is None else budget)
        need = n_slices + roots.shape[0] + 66
        if self.kept.shape[0] < need:
            self.kept = np.empty((need, 6))
        n_kept, tested = bound_kernel(roots, roots.shape[0], *scan, *rules, fine, split_reach, budget, n_slices,
                                      self.kept, float(p.match_heading_resolution))
        if n_kept == 0:
            return roots, False, int(tested)
        return join_slices(self.kept[:n_kept].copy(), n_slices), True, int(tested)
