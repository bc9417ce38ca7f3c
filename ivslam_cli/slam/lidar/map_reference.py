"""The LiDAR map update cell by cell: the definitions, and the oracle of the fast path.

Definitions from the "Guaranteed SLAM – practical considerations" slides (University of
Manchester). One scan from a sensor pose box is processed as a whole, coarse to fine over the
tiles of :mod:`ivslam_cli.paving.tiles` (a quadtree per tile, 64 -> 1 cells): for a block ``C``
the range interval and beam window of ``C - [x] x [y]`` (see :mod:`.geometry`) and four per-scan
sparse tables (:func:`.map_tables.beam_tables`: O(1) range-minimum/maximum over any beam window)
decide:

- **P_EMPTY^k (inner)**: the window's cones cover the block's bearings and its largest range is
  below the smallest free range of the window -> every cell is free for every pose of the box;
  the whole block is proven at once.
- **P_OBSTACLE^k (outer)**: a cell may hold an endpoint iff some beam of its window has a range
  interval ``[lo_i, hi_i]`` meeting the cell's range interval (checked beam by beam at the
  cell level; blocks are pruned when even the window's hull ``[min lo, max hi]`` misses).
- blocks are refined only while one of the two may still hold in a sub-block.

Old/new (the slides' inclusion test in its cheap form, ``P_OBSTACLE^{i,k} ∩ P_UNKNOWN = ∅``):
P_UNKNOWN is the set of cells never measured (no flag) before this scan; a beam is *new* when a
cell of its P_OBSTACLE^{i,k} is in it. The full form (``P_EMPTY^{i,k} ⊂ measured``, with
P_EMPTY^{i,k} taken outer over the pose box) is :func:`inclusion_new`.

Map update (the slides'): EMPTY |= P_EMPTY^k; OBST_NEW |= cells of new beams' P_OBSTACLE^{i,k};
OBST_OLD |= cells of old beams' P_OBSTACLE^{i,k} (= P_OLD^k). The old/new test reads the map as
it was before the scan.

``traverse_reference`` / ``apply_reference`` / ``update_log_reference`` /
``scan_cells_reference`` refine the quadtree to single cells wherever a cell may be in
P_OBSTACLE^k. The fast path (:mod:`.map_kernel`: ``traverse`` / ``apply`` / ``update_log`` /
``scan_cells``) gives the same cells, beams, flags, tiles (in the same order) and counts, the
leaf tests float expression for float expression: ``tests/test_lidar_map.py`` checks it against
these functions, ``bench/bench_lidar_map.py`` times both.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval.rounding import INF, down, up
from ivslam_cli.paving.tiles import EMPTY, OBST_NEW, OBST_OLD, TILE, TILE_MASK, TILE_SHIFT, add_tile, find
from ivslam_cli.slam.lidar.geometry import beam_window, box_bearings, box_ranges, range_bounds
from ivslam_cli.slam.lidar.map_tables import (
    _LEVELS,
    _block_cells,
    _cos_gap,
    _log2_table,
    _qmax,
    _qmin,
    _tile_range,
    _unmeasured,
    beam_tables,
)


# ---------------------------------------------------------------- growable buffers
@njit(cache=True)
def _grow_i(a, need):
    if need <= a.shape[0]:
        return a
    b = np.empty((max(need, 2 * a.shape[0]),) + a.shape[1:], dtype=a.dtype)
    b[: a.shape[0]] = a
    return b


# ---------------------------------------------------------------- one scan, pass 1
@njit(cache=True)
def traverse_reference(keys, slots, cells, ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps,
             exact, lg, t_free, t_lo, t_hi, t_fmax, new, blk, cand, cand_f, stats, fill=True, smin=0.0):
    """P_EMPTY^k blocks, P_OBSTACLE^k cells and new beams of one scan from a sensor box.

    ``box`` = (xl, xh, yl, yh, θl, θh) of the sensor. The map (``keys, slots, cells``) is only
    read (P_UNKNOWN = cells without flags). ``new[i]`` is set for the beams whose
    P_OBSTACLE^{i,k} meets P_UNKNOWN. Output: ``blk[k] = (ix, iy, level)`` proven-empty blocks
    of ``2^level`` cells, ``cand[k] = (ix, iy, o_lo, o_hi)`` with ``cand_f[k] = (r_lo, r_hi)``
    the P_OBSTACLE^k cells; no cell nearer than ``smin`` to the box is proven empty. Returns ``(n_blk, n_cand, blk, cand, cand_f)`` (buffers grown).
    ``stats`` += [nodes visited, empty cells].
    """
    nb = ranges.shape[0]
    h = max(r_alpha, 0.5 * inc)
    cos_gap = _cos_gap(r_alpha, inc, fill)
    rmax = beam_tables(ranges, valid, r_abs, r_rel, cos_gap, t_free, t_lo, t_hi, t_fmax)
    n_blk = 0
    n_cand = 0
    if rmax == -INF:
        return n_blk, n_cand, blk, cand, cand_f
    pxl, pxh, pyl, pyh, thl, thh = box[0], box[1], box[2], box[3], box[4], box[5]
    tx0, tx1, ty0, ty1 = _tile_range(pxl, pxh, pyl, pyh, rmax, eps)
    sl = np.empty(4 * _LEVELS + 4, dtype=np.int64)
    sx = np.empty(4 * _LEVELS + 4, dtype=np.int64)
    sy = np.empty(4 * _LEVELS + 4, dtype=np.int64)
    nodes = 0
    n_empty = 0
    iters = 0
    for tx in range(tx0, tx1 + 1):
        for ty in range(ty0, ty1 + 1):
            t = find(keys, slots, tx, ty)
            sp = 0
            sl[0], sx[0], sy[0] = _LEVELS, 0, 0
            sp = 1
            while sp > 0:
                sp -= 1
                lev, lx, ly = sl[sp], sx[sp], sy[sp]
                nodes += 1
                s = 1 << lev
                ix = tx * TILE + lx
                iy = ty * TILE + ly
                x0 = down(ix * eps)
                x1 = up((ix + s) * eps)
                y0 = down(iy * eps)
                y1 = up((iy + s) * eps)
                dxl, dxh = down(x0 - pxh), up(x1 - pxl)
                dyl, dyh = down(y0 - pyh), up(y1 - pyl)
                r_lo, r_hi = box_ranges(dxl, dxh, dyl, dyh)
                if r_lo > rmax:
                    continue
                bl, bh, full = box_bearings(dxl, dxh, dyl, dyh)
                if full:
                    o_lo, o_hi, e_lo, e_hi, cover = 0, nb - 1, 0, -1, False
                else:
                    o_lo, o_hi, e_lo, e_hi, cover = beam_window(down(bl - thh), up(bh - thl),
                                                                a0, inc, h, nb)
                if o_lo > o_hi:
                    continue
                if cover and r_hi < _qmin(t_free, lg, e_lo, e_hi) and r_lo >= smin:
                    blk = _grow_i(blk, n_blk + 1)
                    blk[n_blk, 0], blk[n_blk, 1], blk[n_blk, 2] = ix, iy, lev
                    n_blk += 1
                    n_empty += s * s
                    continue
                obs = r_hi >= _qmin(t_lo, lg, o_lo, o_hi) and r_lo <= _qmax(t_hi, lg, o_lo, o_hi)
                if lev == 0:
                    if not obs:
                        continue
                    unknown = _unmeasured(cells, t, lx, ly)
                    found = not exact
                    # the hull test passed: a measured cell needs the beams only for `exact`
                    for i in range(o_lo, o_hi + 1 if (exact or unknown) else o_lo):
                        iters += 1
                        if t_lo[0, i] <= r_hi and t_hi[0, i] >= r_lo:
                            found = True
                            if unknown:
                                new[i] = True
                            else:
                                break
                    if found:
                        cand = _grow_i(cand, n_cand + 1)
                        cand_f = _grow_i(cand_f, n_cand + 1)
                        cand[n_cand, 0], cand[n_cand, 1] = ix, iy
                        cand[n_cand, 2], cand[n_cand, 3] = o_lo, o_hi
                        cand_f[n_cand, 0], cand_f[n_cand, 1] = r_lo, r_hi
                        n_cand += 1
                    continue
                if not obs and not (r_lo < _qmax(t_fmax, lg, o_lo, o_hi)):
                    continue
                half = s >> 1
                for q in range(4):
                    sl[sp] = lev - 1
                    sx[sp] = lx + (half if (q & 1) else 0)
                    sy[sp] = ly + (half if (q & 2) else 0)
                    sp += 1
    stats[0] += nodes
    stats[1] += n_empty
    stats[2] += iters
    return n_blk, n_cand, blk, cand, cand_f


# ---------------------------------------------------------------- one scan, pass 2
@njit(cache=True)
def apply_reference(keys, slots, cells, coords, n, n_blk, blk, n_cand, cand, cand_f, new, valid, t_lo, t_hi):
    """Write one scan into the map: EMPTY on the blocks, OBST_NEW / OBST_OLD on the cells whose
    range interval meets a new / old valid beam of their window. Returns the map arrays."""
    for k in range(n_blk):
        ix, iy, lev = blk[k, 0], blk[k, 1], blk[k, 2]
        t, keys, slots, cells, coords, n = add_tile(keys, slots, cells, coords, n,
                                                    ix >> TILE_SHIFT, iy >> TILE_SHIFT)
        s = 1 << lev
        lx, ly = ix & TILE_MASK, iy & TILE_MASK
        for a in range(lx, lx + s):
            for b in range(ly, ly + s):
                cells[t, a, b] |= EMPTY
    for k in range(n_cand):
        ix, iy = cand[k, 0], cand[k, 1]
        r_lo, r_hi = cand_f[k, 0], cand_f[k, 1]
        f = np.uint8(0)
        for i in range(cand[k, 2], cand[k, 3] + 1):
            if valid[i] and t_lo[0, i] <= r_hi and t_hi[0, i] >= r_lo:
                f |= OBST_NEW if new[i] else OBST_OLD
                if f == (OBST_NEW | OBST_OLD):
                    break
        if f:
            t, keys, slots, cells, coords, n = add_tile(keys, slots, cells, coords, n,
                                                        ix >> TILE_SHIFT, iy >> TILE_SHIFT)
            cells[t, ix & TILE_MASK, iy & TILE_MASK] |= f
    return keys, slots, cells, coords, n


# ---------------------------------------------------------------- a whole log
@njit(cache=True)
def update_log_reference(keys, slots, cells, coords, n, ranges, valid, offsets, angle_min, angle_inc,
               boxes, order, r_abs, r_rel, r_alpha, eps, exact, write, is_old, scan_stats, fill, smin):
    """Process scans ``order`` (in that order) from sensor boxes ``boxes`` (S, 6), no cell of scan
    ``s`` nearer than ``smin[s]`` to its box proven empty.

    ``is_old[b]`` is set for every valid beam found old (cheap form) against the map before
    its scan; with ``write`` the scan is then written into the map. ``scan_stats[s]`` =
    (nodes, empty cells, obstacle cells, new beams, old beams). Returns the map arrays.
    """
    nbmax = 1
    for s in order:
        nbmax = max(nbmax, offsets[s + 1] - offsets[s])
    lg = _log2_table(nbmax)
    lev = lg[nbmax] + 1
    t_free = np.empty((lev, nbmax))
    t_lo = np.empty((lev, nbmax))
    t_hi = np.empty((lev, nbmax))
    t_fmax = np.empty((lev, nbmax))
    new = np.zeros(nbmax, dtype=np.bool_)
    blk = np.empty((1024, 3), dtype=np.int64)
    cand = np.empty((4096, 4), dtype=np.int64)
    cand_f = np.empty((4096, 2))
    st = np.zeros(3, dtype=np.int64)
    for s in order:
        b0, b1 = offsets[s], offsets[s + 1]
        nb = b1 - b0
        if nb == 0:
            continue
        new[:nb] = False
        st[:] = 0
        n_blk, n_cand, blk, cand, cand_f = traverse_reference(
            keys, slots, cells, ranges[b0:b1], valid[b0:b1], angle_min[s], angle_inc[s],
            boxes[s], r_abs, r_rel, r_alpha, eps, exact, lg, t_free, t_lo, t_hi, t_fmax,
            new, blk, cand, cand_f, st, fill, smin[s])
        n_new = 0
        n_old = 0
        for i in range(nb):
            if valid[b0 + i]:
                if new[i]:
                    n_new += 1
                else:
                    is_old[b0 + i] = True
                    n_old += 1
        if write:
            keys, slots, cells, coords, n = apply_reference(keys, slots, cells, coords, n, n_blk, blk,
                                                  n_cand, cand, cand_f, new, valid[b0:b1],
                                                  t_lo, t_hi)
        scan_stats[s, 0] = st[0]
        scan_stats[s, 1] = st[1]
        scan_stats[s, 2] = n_cand
        scan_stats[s, 3] = n_new
        scan_stats[s, 4] = n_old
        scan_stats[s, 5] = st[2]
    return keys, slots, cells, coords, n


@njit(cache=True)
def scan_cells_reference(ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps, exact, fill=True, smin=0.0):
    """P_EMPTY^k and P_OBSTACLE^k of one scan as cell index arrays (for tests and plots):
    ``(empty_ix, empty_iy, obst_ix, obst_iy)``."""
    nb = ranges.shape[0]
    lg = _log2_table(max(nb, 1))
    lev = lg[max(nb, 1)] + 1
    t_free = np.empty((lev, max(nb, 1)))
    t_lo = np.empty((lev, max(nb, 1)))
    t_hi = np.empty((lev, max(nb, 1)))
    t_fmax = np.empty((lev, max(nb, 1)))
    new = np.zeros(max(nb, 1), dtype=np.bool_)
    keys = np.full(4, np.int64(-(2**63)), dtype=np.int64)
    slots = np.full(4, -1, dtype=np.int64)
    cells = np.zeros((1, TILE, TILE), dtype=np.uint8)
    blk = np.empty((1024, 3), dtype=np.int64)
    cand = np.empty((4096, 4), dtype=np.int64)
    cand_f = np.empty((4096, 2))
    st = np.zeros(3, dtype=np.int64)
    n_blk, n_cand, blk, cand, cand_f = traverse_reference(keys, slots, cells, ranges, valid, a0, inc, box,
                                                r_abs, r_rel, r_alpha, eps, exact, lg, t_free,
                                                t_lo, t_hi, t_fmax, new, blk, cand, cand_f, st, fill, smin)
    ex = np.empty(st[1], dtype=np.int64)
    ey = np.empty(st[1], dtype=np.int64)
    _block_cells(blk, n_blk, ex, ey, 0)
    return ex, ey, cand[:n_cand, 0].copy(), cand[:n_cand, 1].copy()


# ---------------------------------------------------------------- full old/new test
@njit(cache=True)
def inclusion_new(keys, slots, cells, ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps):
    """The slides' full test: beam ``i`` is new unless every cell its free cone may cover for some
    pose of the box (range below ``lo_i``, bearing in its cone) is measured in the map.

    Cell by cell over the scan's disk (blocks are pruned only when no beam reaches them):
    the reference for the cheap form, not the hot path. Returns ``new`` (nb,) bool.
    """
    nb = ranges.shape[0]
    new = np.zeros(nb, dtype=np.bool_)
    h = max(r_alpha, 0.5 * inc)
    rmax = -INF
    lo = np.full(nb, -INF)
    for i in range(nb):
        if valid[i]:
            lo[i] = range_bounds(float(ranges[i]), r_abs, r_rel)[0]
            rmax = max(rmax, lo[i])
    if rmax == -INF:
        return new
    pxl, pxh, pyl, pyh, thl, thh = box[0], box[1], box[2], box[3], box[4], box[5]
    ix0 = int(math.floor(down(down(pxl - rmax) / eps))) - 1
    ix1 = int(math.floor(up(up(pxh + rmax) / eps))) + 1
    iy0 = int(math.floor(down(down(pyl - rmax) / eps))) - 1
    iy1 = int(math.floor(up(up(pyh + rmax) / eps))) + 1
    for ix in range(ix0, ix1 + 1):
        t = -1
        for iy in range(iy0, iy1 + 1):
            if (iy & TILE_MASK) == 0 or iy == iy0:
                t = find(keys, slots, ix >> TILE_SHIFT, iy >> TILE_SHIFT)
            if t >= 0 and cells[t, ix & TILE_MASK, iy & TILE_MASK] != 0:
                continue
            dxl, dxh = down(down(ix * eps) - pxh), up(up((ix + 1) * eps) - pxl)
            dyl, dyh = down(down(iy * eps) - pyh), up(up((iy + 1) * eps) - pyl)
            r_lo, r_hi = box_ranges(dxl, dxh, dyl, dyh)
            if r_lo >= rmax:
                continue
            bl, bh, full = box_bearings(dxl, dxh, dyl, dyh)
            if full:
                o_lo, o_hi = 0, nb - 1
            else:
                o_lo, o_hi, _, _, _ = beam_window(down(bl - thh), up(bh - thl), a0, inc, h, nb)
            for i in range(o_lo, o_hi + 1):
                if r_lo < lo[i]:
                    new[i] = True
    return new
