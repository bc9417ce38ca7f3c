"""Map-update kernels of the feature-less LiDAR SLAM (numba, outward rounding).

One scan from a sensor pose box is processed as a whole, coarse to fine over the tiles of
:mod:`ivslam_cli.paving.tiles` (a quadtree per tile, 64 -> 1 cells): for a block ``C`` the
range interval and beam window of ``C - [x] x [y]`` (see :mod:`.lidar_geometry`) and four
per-scan sparse tables (O(1) range-minimum/maximum over any beam window) decide:

- **P_EMPTY^k (inner)**: the window's cones cover the block's bearings and its largest range is
  below the smallest free range of the window -> every cell is free for every pose of the box;
  the whole block is proven at once.
- **P_OBSTACLE^k (outer)**: a cell may hold an endpoint iff some beam of its window has a range
  interval ``[lo_i, hi_i]`` meeting the cell's range interval (checked beam by beam at the
  cell level; blocks are pruned when even the window's hull ``[min lo, max hi]`` misses).
- blocks are refined only while one of the two may still hold in a sub-block.

Old/new (cheap form of the seed, ``P_OBSTACLE^{i,k} ∩ P_UNKNOWN = ∅``): P_UNKNOWN is the set of
cells never measured (no flag) before this scan; a beam is *new* when a cell of its
P_OBSTACLE^{i,k} is in it. The full form (``P_EMPTY^{i,k} ⊂ measured``, with P_EMPTY^{i,k}
taken outer over the pose box) is :func:`inclusion_new`.

Map update (seed): EMPTY |= P_EMPTY^k; OBST_NEW |= cells of new beams' P_OBSTACLE^{i,k};
OBST_OLD |= cells of old beams' P_OBSTACLE^{i,k} (= P_OLD^k). The old/new test reads the map
as it was before the scan.

Two implementations of the same definitions (the leaf tests above, float expression for float
expression):

- ``traverse_reference`` / ``apply_reference`` / ``update_log_reference`` /
  ``scan_cells_reference``: the quadtree refined to single cells wherever a cell may be in
  P_OBSTACLE^k (the oracle of ``tests/test_lidar_map.py``, timed beside the fast path by
  ``bench/bench_lidar_map.py``);
- ``traverse`` / ``apply`` / ``update_log`` / ``scan_cells`` (used by
  :mod:`.lidar_map`): the same cells, beams, flags, tiles (in the same order) and counts, with
  blocks decided whole where the reference refines them (see "the fast path" below: outer
  windows with margins, a certificate that every cell of a block is in P_OBSTACLE^k, a test
  that none can be proven empty, fast bearings whose error is checked before they decide an
  index, an O(1) "does a beam of this window meet this range" test).

Hot helpers are inlined (``inline="always"``: a call with a dozen array arguments costs more
than their geometry) and take scalars where they can (an array made in the caller and passed to
an inlined helper gets its reference count changed, atomically, on every use). The few that
stay calls (the rare exact cell tests, the writes) and never allocate are compiled with
numba's private ``_nrt=False`` option: without it numba increments and decrements the reference
count of every array argument on each call, which made the bench log ~25 % slower (measured
when the others were inlined); a numba upgrade that drops the option breaks them at compile time.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval.rounding import INF, down, up
from ivslam_cli.paving.tiles import (
    EMPTY,
    OBST_NEW,
    OBST_OLD,
    TILE,
    TILE_MASK,
    TILE_SHIFT,
    add_tile,
    find,
)
from ivslam_cli.slam.lidar.geometry import (
    ATAN_ERR,
    atan2_fast,
    beam_window,
    box_bearings,
    box_bearings_fast,
    box_ranges,
    FIN_MAX,
    box_ranges_fin,
    dn,
    range_bounds,
    upf,
    window_in_branch,
)

_LEVELS = TILE_SHIFT  # quadtree levels per tile (64 = 2^6 cells)


# ---------------------------------------------------------------- per-scan beam tables
@njit(cache=True)
def _log2_table(n):
    t = np.zeros(n + 2, dtype=np.int64)
    for i in range(2, n + 2):
        t[i] = t[i >> 1] + 1
    return t


@njit(cache=True)
def _build(tab, nb, is_min):
    """Sparse table in place: ``tab[k, i]`` = min/max of ``tab[0, i : i + 2^k]``."""
    k = 1
    while (1 << k) <= nb:
        half = 1 << (k - 1)
        for i in range(nb - (1 << k) + 1):
            a, b = tab[k - 1, i], tab[k - 1, i + half]
            if is_min:
                tab[k, i] = a if a < b else b
            else:
                tab[k, i] = a if a > b else b
        k += 1


@njit(cache=True)
def _qmin(tab, lg, l, r):
    k = lg[r - l + 1]
    a, b = tab[k, l], tab[k, r - (1 << k) + 1]
    return a if a < b else b


@njit(cache=True)
def _qmax(tab, lg, l, r):
    k = lg[r - l + 1]
    a, b = tab[k, l], tab[k, r - (1 << k) + 1]
    return a if a > b else b


@njit(cache=True)
def beam_tables(ranges, valid, r_abs, r_rel, cos_gap, t_free, t_lo, t_hi, t_fmax):
    """Per-beam intervals and their sparse tables (row 0 = the values).

    ``lo, hi``: range interval of the true distance (``+inf, -inf`` for invalid beams, which
    prove no obstacle); ``free = lo * cos_gap`` (``-inf`` for invalid beams: no free space).
    Returns the largest ``hi`` of the scan (``-inf`` if no valid beam).
    """
    nb = ranges.shape[0]
    rmax = -INF
    for i in range(nb):
        if valid[i]:
            lo, hi = range_bounds(float(ranges[i]), r_abs, r_rel)
            t_lo[0, i] = lo
            t_hi[0, i] = hi
            t_free[0, i] = down(lo * cos_gap)
            rmax = max(rmax, hi)
        else:
            t_lo[0, i] = INF
            t_hi[0, i] = -INF
            t_free[0, i] = -INF
        t_fmax[0, i] = t_free[0, i]
    _build(t_free, nb, True)
    _build(t_fmax, nb, False)
    _build(t_lo, nb, True)
    _build(t_hi, nb, False)
    return rmax


@njit(cache=True)
def _cos_gap(r_alpha, inc, fill):
    """Factor of the free ranges. Cones that do not touch (``r_alpha < inc / 2``): the gap
    between two beams is filled (free range times ``cos(inc / 2)``) only under the stated
    assumption ``fill``; else no free space (a negative factor proves nothing free)."""
    if r_alpha >= 0.5 * inc:
        return 1.0
    if fill:
        return max(0.0, down(down(math.cos(0.5 * inc)) - 1e-16))
    return -1.0


MAX_SPAN_TILES = 4096  # tiles a side one scan may reach (its work and tables grow with the square)


@njit(cache=True)
def _tile_range(pxl, pxh, pyl, pyh, rmax, eps):
    """Tiles ``[tx0, tx1] x [ty0, ty1]`` holding every point within ``rmax`` of the box (one
    tile of margin). Raises ValueError beyond ``MAX_SPAN_TILES`` tiles a side (the pipeline
    refuses such ranges first, with the log's name: lidar.usable_scans) or 2^30 tiles from the
    origin (the tile index's int32 coordinates)."""
    side = TILE * eps
    if not (max(pxh - pxl, pyh - pyl) + 2.0 * rmax < (MAX_SPAN_TILES - 4) * side):
        raise ValueError("lidar map: a scan reaches over 4096 tiles (2^18 cells) a side")
    if not (max(max(abs(pxl), abs(pxh)), max(abs(pyl), abs(pyh))) + rmax < 2.0**30 * side):
        # the tile index holds int32 tile coordinates
        raise ValueError("lidar map: a scan reaches beyond 2^30 tiles from the origin")
    tx0 = int(math.floor(down(down(pxl - rmax) / side))) - 1
    tx1 = int(math.floor(up(up(pxh + rmax) / side))) + 1
    ty0 = int(math.floor(down(down(pyl - rmax) / side))) - 1
    ty1 = int(math.floor(up(up(pyh + rmax) / side))) + 1
    return tx0, tx1, ty0, ty1


# ---------------------------------------------------------------- growable buffers
@njit(cache=True)
def _grow_i(a, need):
    if need <= a.shape[0]:
        return a
    b = np.empty((max(need, 2 * a.shape[0]),) + a.shape[1:], dtype=a.dtype)
    b[: a.shape[0]] = a
    return b


@njit(cache=True, inline="always")
def _unmeasured(cells, t, lx, ly):
    return t < 0 or cells[t, lx, ly] == 0


# ---------------------------------------------------------------- one scan, pass 1
@njit(cache=True)
def traverse_reference(keys, slots, cells, ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps,
             exact, lg, t_free, t_lo, t_hi, t_fmax, new, blk, cand, cand_f, stats, fill=True):
    """P_EMPTY^k blocks, P_OBSTACLE^k cells and new beams of one scan from a sensor box.

    ``box`` = (xl, xh, yl, yh, θl, θh) of the sensor. The map (``keys, slots, cells``) is only
    read (P_UNKNOWN = cells without flags). ``new[i]`` is set for the beams whose
    P_OBSTACLE^{i,k} meets P_UNKNOWN. Output: ``blk[k] = (ix, iy, level)`` proven-empty blocks
    of ``2^level`` cells, ``cand[k] = (ix, iy, o_lo, o_hi)`` with ``cand_f[k] = (r_lo, r_hi)``
    the P_OBSTACLE^k cells. Returns ``(n_blk, n_cand, blk, cand, cand_f)`` (buffers grown).
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
                if cover and r_hi < _qmin(t_free, lg, e_lo, e_hi):
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
               boxes, order, r_abs, r_rel, r_alpha, eps, exact, write, is_old, scan_stats, fill=True):
    """Process scans ``order`` (in that order) from sensor boxes ``boxes`` (S, 6).

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
            new, blk, cand, cand_f, st, fill)
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
def scan_cells_reference(ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps, exact, fill=True):
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
                                                t_lo, t_hi, t_fmax, new, blk, cand, cand_f, st, fill)
    ex = np.empty(st[1], dtype=np.int64)
    ey = np.empty(st[1], dtype=np.int64)
    _block_cells(blk, n_blk, ex, ey, 0)
    return ex, ey, cand[:n_cand, 0].copy(), cand[:n_cand, 1].copy()


# ---------------------------------------------------------------- full old/new test
@njit(cache=True)
def inclusion_new(keys, slots, cells, ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps):
    """The seed's full test: beam ``i`` is new unless every cell its free cone may cover for some
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


# ================================================================ the fast path
# The same per-cell results as the reference traversal above (P_EMPTY^k, P_OBSTACLE^k, the new
# beams, the map flags, the tiles and their order), with fewer and cheaper tests:
#   - one interleaved sparse table per scan (range lo, range hi, free range, its max, and the gap
#     between consecutive valid beams): a window's summary costs two cache lines, and "does a
#     beam of this window meet this range interval" is O(1) unless the window holds a jump
#     larger than the interval (_meets);
#   - blocks away from the sensor box and from the back of the scan ("simple": one branch of
#     the bearings, see _level_geom) are tested with an *outer* window of beam indices that
#     holds the reference window of each of their cells whatever the roundings (fast bearings,
#     ATAN_ERR and rounding margins): proven empty, or pruned when no beam of it meets the
#     block's range interval and no cell can be proven free (_inner's lower bound of every
#     cell's largest range against the free ranges of beams in every cell's window), or proven
#     all-P_OBSTACLE^k at once (_inner's certificate) instead of being refined to single cells;
#   - a cell's reference window is computed from fast bearings when every index is farther from
#     a rounding boundary than the error allows (_geom1), else exactly as the reference;
#   - a window holding a jump is searched by halving (_meets_g), not beam by beam;
#   - each tile is visited level by level (breadth first): the geometry of all blocks of a level
#     (ranges, fast bearings, windows, _inner), or of all cells, in one pass written with selects
#     only, which the compiler vectorises (_level_geom, _cell_geom: 8 blocks at a time with
#     AVX-512), then the decisions block by block, the blocks to refine listed for the next
#     level. Records of a tile come in another order than the reference's; tiles in the same.
# Blocks that are not simple (around the sensor box, the back of the scan) use the reference's
# own block test. update_log / scan_cells / traverse / apply are the fast path; the *_reference
# functions are the oracle of tests/test_lidar_map.py.
_NF = 5  # fields of the interleaved table: lo (min), hi (max), free (min), free (max), gap (max)


@njit(cache=True)
def _fast_tables(ranges, valid, r_abs, r_rel, cos_gap, T):
    """``T[0, i] = (lo_i, hi_i, free_i, free_i, gap_i)`` (the values of :func:`beam_tables`;
    ``gap_i`` bounds the distance from beam ``i``'s range interval to the next valid beam's:
    ``+inf`` if none, ``-inf`` for an invalid beam), then ``T[k, i]`` = min / max / min / max /
    max over beams ``i .. i + 2^k - 1``. Returns the largest ``hi`` (``-inf``: no valid beam)."""
    nb = ranges.shape[0]
    rmax = -INF
    for i in range(nb):
        if valid[i]:
            lo, hi = range_bounds(float(ranges[i]), r_abs, r_rel)
            T[0, i, 0] = lo
            T[0, i, 1] = hi
            T[0, i, 2] = down(lo * cos_gap)
            rmax = max(rmax, hi)
        else:
            T[0, i, 0] = INF
            T[0, i, 1] = -INF
            T[0, i, 2] = -INF
        T[0, i, 3] = T[0, i, 2]
    nxt = -1
    for i in range(nb - 1, -1, -1):
        if valid[i]:
            if nxt < 0:
                T[0, i, 4] = INF
            else:
                g1 = up(T[0, nxt, 0] - T[0, i, 1])
                g2 = up(T[0, i, 0] - T[0, nxt, 1])
                T[0, i, 4] = g1 if g1 > g2 else g2
            nxt = i
        else:
            T[0, i, 4] = -INF
    k = 1
    while (1 << k) <= nb:
        half = 1 << (k - 1)
        for i in range(nb - (1 << k) + 1):
            j = i + half
            T[k, i, 0] = min(T[k - 1, i, 0], T[k - 1, j, 0])
            T[k, i, 1] = max(T[k - 1, i, 1], T[k - 1, j, 1])
            T[k, i, 2] = min(T[k - 1, i, 2], T[k - 1, j, 2])
            T[k, i, 3] = max(T[k - 1, i, 3], T[k - 1, j, 3])
            T[k, i, 4] = max(T[k - 1, i, 4], T[k - 1, j, 4])
        k += 1
    return rmax


@njit(cache=True, inline="always")
def _win(T, lg, l, r):
    """Over beams ``[l, r]`` (``l <= r``): min lo, max hi, min free, max free."""
    k = lg[r - l + 1]
    j = r - (1 << k) + 1
    return (min(T[k, l, 0], T[k, j, 0]), max(T[k, l, 1], T[k, j, 1]), min(T[k, l, 2], T[k, j, 2]),
            max(T[k, l, 3], T[k, j, 3]))


@njit(cache=True, inline="always")
def _meets(T, lg, l, r, a, b, lo_min, hi_max, st):
    """Whether a valid beam ``i`` in ``[l, r]`` has ``lo_i <= a`` and ``hi_i >= b`` (exact);
    ``lo_min, hi_max``: the window's hull (:func:`_win`).

    O(1) unless the window holds a jump: if the hull test passes, walking from a beam with
    ``lo <= a`` to one with ``hi >= b`` through consecutive valid beams, if none meets, some
    pair must jump over ``[b, a]`` (gap > a - b). So when no gap of the window exceeds
    ``a - b`` a beam meets; else the window is scanned."""
    return _meets_g(T, lg, l, r, a, b, lo_min, hi_max, down(a - b), st)


@njit(cache=True, inline="always")
def _meets_g(T, lg, l, r, a, b, lo_min, hi_max, g, st):
    """:func:`_meets`, the gaps allowed up to ``g`` (``g <= a - b``, or see the callers)."""
    if l > r or lo_min > a or hi_max < b:
        return False
    if l == r:
        return True
    k = lg[r - l]
    if max(T[k, l, 4], T[k, r - (1 << k), 4]) <= g:
        return True
    # a jump: the same two tests on sub-windows [p, p + 2^k - 1] (the argument holds on any
    # run of consecutive beams), halving those whose hull meets but which hold a jump, skipping
    # those whose hull misses; single beams are tested exactly
    p = l
    while p <= r:
        k = lg[r - p + 1]
        while True:
            st[2] += 1
            if T[k, p, 0] > a or T[k, p, 1] < b:
                p += 1 << k
                break
            if k == 0:
                return True
            j = k - 1
            if max(T[j, p, 4], T[j, p + (1 << j) - 1, 4]) <= g:  # gaps of beams p .. p + 2^k - 2
                return True
            k = j
    return False


@njit(cache=True, _nrt=False)
def _scan_new(T, o_lo, o_hi, r_lo, r_hi, new, st):
    """Mark every beam of ``[o_lo, o_hi]`` meeting ``[r_lo, r_hi]`` as new."""
    for i in range(o_lo, o_hi + 1):
        st[2] += 1
        if T[0, i, 0] <= r_hi and T[0, i, 1] >= r_lo:
            new[i] = True


@njit(cache=True, inline="always")
def _window_fast(pl, ph, a0, inc, h, nb, mid, lo_edge, hi_edge):
    """:func:`beam_window` (same results): the branch search is skipped when the bearings'
    middle is within 3 rad of the scan's (then ``round(c / 2π) = 0``)."""
    if not (ph - pl < 6.0):
        return 0, nb - 1, 0, -1, False
    c = 0.5 * (pl + ph) - mid
    if not (-3.0 < c < 3.0):
        return beam_window(pl, ph, a0, inc, h, nb)
    return window_in_branch(pl, ph, a0, inc, h, nb, lo_edge, hi_edge)


@njit(cache=True, inline="always")
def _classify(T, lg, o_lo, o_hi, e_lo, e_hi, cover, r_lo, r_hi, st):
    """The reference's leaf decision for a cell with window ``[o_lo, o_hi]`` (``[e_lo, e_hi]``
    unclipped) and range interval ``[r_lo, r_hi]``: 0 nothing, 1 proven empty, 2 the hull
    test passes but no beam meets, 3 in P_OBSTACLE^k."""
    if o_lo > o_hi:
        return 0
    lo_min, hi_max, f_min, f_max = _win(T, lg, o_lo, o_hi)
    if cover:
        if e_lo != o_lo or e_hi != o_hi:
            f_min = _win(T, lg, e_lo, e_hi)[2]
        if r_hi < f_min:
            return 1
    if not (r_hi >= lo_min and r_lo <= hi_max):
        return 0
    return 3 if _meets(T, lg, o_lo, o_hi, r_hi, r_lo, lo_min, hi_max, st) else 2


@njit(cache=True, _nrt=False)
def _cell_window(ix, iy, eps, box, a0, inc, h, nb, rmax, mid, lo_edge, hi_edge, err=-1.0):
    """The reference's window and range interval of cell ``(ix, iy)`` (same float expressions):
    ``(o_lo, o_hi, e_lo, e_hi, cover, r_lo, r_hi)``, the window empty beyond every beam. With
    ``err >= 0`` (the margin of :func:`_geom1`), from fast bearings when they decide it."""
    pxl, pxh, pyl, pyh, thl, thh = box[0], box[1], box[2], box[3], box[4], box[5]
    if err >= 0.0:
        r_lo, r_hi, o_lo, o_hi, e_lo, e_hi, cover, state = _geom1(
            ix, iy, eps, pxl, pxh, pyl, pyh, thl, thh, a0, h, nb, mid, lo_edge, hi_edge, err, 1.0 / inc)
        if r_lo > rmax:
            return 0, -1, 0, -1, False, r_lo, r_hi
        if state == 0:
            return o_lo, o_hi, e_lo, e_hi, cover, r_lo, r_hi
    x0 = down(ix * eps)
    x1 = up((ix + 1) * eps)
    y0 = down(iy * eps)
    y1 = up((iy + 1) * eps)
    dxl, dxh = down(x0 - pxh), up(x1 - pxl)
    dyl, dyh = down(y0 - pyh), up(y1 - pyl)
    r_lo, r_hi = box_ranges(dxl, dxh, dyl, dyh)
    if r_lo > rmax:
        return 0, -1, 0, -1, False, r_lo, r_hi
    bl, bh, full = box_bearings(dxl, dxh, dyl, dyh)
    if full:
        return 0, nb - 1, 0, -1, False, r_lo, r_hi
    o_lo, o_hi, e_lo, e_hi, cover = _window_fast(down(bl - thh), up(bh - thl), a0, inc, h, nb, mid, lo_edge,
                                                 hi_edge)
    return o_lo, o_hi, e_lo, e_hi, cover, r_lo, r_hi


@njit(cache=True, _nrt=False)
def _cell(ix, iy, eps, box, a0, inc, h, nb, rmax, mid, lo_edge, hi_edge, T, lg, st, err=-1.0):
    """The reference's leaf test of cell ``(ix, iy)`` (:func:`_cell_window`, then
    :func:`_classify`): ``(code, o_lo, o_hi, r_lo, r_hi)``, code 0 also beyond every beam."""
    o_lo, o_hi, e_lo, e_hi, cover, r_lo, r_hi = _cell_window(ix, iy, eps, box, a0, inc, h, nb, rmax, mid,
                                                             lo_edge, hi_edge, err)
    return _classify(T, lg, o_lo, o_hi, e_lo, e_hi, cover, r_lo, r_hi, st), o_lo, o_hi, r_lo, r_hi


@njit(cache=True, inline="always")
def _geom1(cx, cy, eps, pxl, pxh, pyl, pyh, thl, thh, a0, h, nb, mid, lo_edge, hi_edge, err, inv_inc):
    """The reference's range interval and window of cell ``(cx, cy)``: ``(r_lo, r_hi, o_lo,
    o_hi, e_lo, e_hi, cover, state)``, state 0 = window decided, -1 = undecided (then use
    :func:`_cell`).

    The bearings come from :func:`box_bearings_fast`; the reference's window is ``floor /
    ceil`` of ``(bearing -/+ theta -/+ h - a0) / inc`` after a shift by ``2 pi m``: when the
    approximate value is farther than ``err / inc`` (``err``: ATAN_ERR plus every rounding of
    the reference's chain) from an integer, the floor / ceil are those of the exact value, and
    so are the branch and the "other branch" test when farther than ``err`` from their limits.
    """
    return _geom1_d(dn(dn(cx * eps) - pxh), upf(upf((cx + 1) * eps) - pxl), dn(dn(cy * eps) - pyh),
                    upf(upf((cy + 1) * eps) - pyl), thl, thh, a0, h, nb, mid, lo_edge, hi_edge, err, inv_inc)


@njit(cache=True, inline="always")
def _geom1_d(dxl, dxh, dyl, dyh, thl, thh, a0, h, nb, mid, lo_edge, hi_edge, err, inv_inc):
    """:func:`_geom1` from the cell's offsets from the sensor box ``[dxl, dxh] x [dyl, dyh]``
    (:func:`_axis_table`). Selects only, no branches: vectorised in :func:`_cell_geom`."""
    r_lo, r_hi = box_ranges_fin(dxl, dxh, dyl, dyh)
    bl, bh, full = box_bearings_fast(dxl, dxh, dyl, dyh)
    pl = bl - thh
    ph = bh - thl
    c = 0.5 * (pl + ph) - mid
    s1 = 3.3 < c and c < 9.2
    s2 = -9.2 < c and c < -3.3
    bad = not ((-3.0 < c and c < 3.0) or s1 or s2)  # the reference's branch m = round(c / 2 pi): 0, +-1
    sh = -2.0 * math.pi if s1 else (2.0 * math.pi if s2 else 0.0)
    pl += sh
    ph += sh
    u_lo = (pl - h - a0) * inv_inc
    u_hi = (ph + h - a0) * inv_inc
    ok = ph - pl < 5.9 and -1e5 < u_lo and u_hi < 1e5
    u_lo = u_lo if ok else 0.0
    u_hi = u_hi if ok else 0.0
    d = err * inv_inc + 1e-9
    f_lo = math.floor(u_lo - d)
    f_hi = math.ceil(u_hi + d)
    und = bad or f_lo != math.floor(u_lo + d) or f_hi != math.ceil(u_hi - d)
    e_lo = int(f_lo)
    e_hi = int(f_hi)
    g1 = pl + 2.0 * math.pi - hi_edge  # the reference widens to the whole scan when <= 0
    g2 = ph - 2.0 * math.pi - lo_edge  # ... or when >= 0
    wide = g1 <= -err or g2 >= err
    und = und or ((not wide) and (g1 <= err or g2 >= -err))
    # full: every bearing, the whole scan, decided; not ok: undecided (empty window)
    o_lo = 0 if (full or not ok or wide) else max(e_lo, 0)
    o_hi = nb - 1 if full else (-1 if not ok else (nb - 1 if wide else min(e_hi, nb - 1)))
    cover = (not full) and ok and e_lo >= 0 and e_hi <= nb - 1
    state = 0 if full else (-1 if (und or not ok) else 0)
    return (r_lo, r_hi, o_lo, o_hi, 0 if (full or not ok) else e_lo, -1 if (full or not ok) else e_hi, cover,
            state)


@njit(cache=True)
def _axis_table(i0, n, eps, pl, ph):
    """Per grid column (or row) ``i0 + k`` of a scan's tiles, ``k < n``: the cell's sides
    rounded outward ``(dn(i eps), upf((i + 1) eps))`` and its offsets from the sensor box's
    ``[pl, ph]`` on that axis, ``(dn(dn(i eps) - ph), upf(upf((i + 1) eps) - pl))`` (the values
    the blocks and cells of the scan use, computed once)."""
    A = np.empty((n, 4))
    for k in range(n):
        i = i0 + k
        A[k, 0] = dn(i * eps)
        A[k, 1] = upf((i + 1) * eps)
        A[k, 2] = dn(A[k, 0] - ph)
        A[k, 3] = upf(A[k, 1] - pl)
    return A


@njit(cache=True)
def _level_consts(eps):
    """Per quadtree level ``lev`` (blocks of ``2^lev`` cells): ``(w, |(w, w)|, c, |(c, c)|)``
    with ``w`` a bound of a block's half-width and ``c`` of the offset of a cell centre from
    the block's centre along an axis (margins for the roundings of block corners; _inner
    checks them and computes the diagonals itself otherwise), diagonals rounded up."""
    LC = np.empty((_LEVELS + 1, 4))
    for lev in range(_LEVELS + 1):
        s = float(1 << lev)
        w = up(0.5 * s * eps * (1.0 + 1e-12) + 1e-12)
        c = up(0.5 * (s - 1.0) * eps * (1.0 + 1e-12) + 1e-9)
        LC[lev, 0] = w
        LC[lev, 1] = up(math.sqrt(up(2.0 * up(w * w))))
        LC[lev, 2] = c
        LC[lev, 3] = up(math.sqrt(up(2.0 * up(c * c))))
    return LC


@njit(cache=True)
def _inner_consts(box, inc):
    """Per-scan constants of :func:`_inner`: the centre ``(cx, cy)`` of the sensor box, the
    half-widths ``(wx, wy)`` of a sub-box centred on it and their diagonal (rounded up), the
    angular margin (fast atan2 error and roundings), ``1 / inc``, the box's smaller side
    (rounded down)."""
    pxl, pxh, pyl, pyh, thl, thh = box[0], box[1], box[2], box[3], box[4], box[5]
    cx = 0.5 * (pxl + pxh)
    cy = 0.5 * (pyl + pyh)
    wx = down(min(down(cx - pxl), down(pxh - cx)))
    wy = down(min(down(cy - pyl), down(pyh - cy)))
    rc = up(math.sqrt(up(up(wx * wx) + up(wy * wy))))
    amg = ATAN_ERR + 1e-10 * (1.0 + abs(thl) + abs(thh))
    # a point p outside the box: maxdist(p, box) - dist(p, box) >= the box's smaller side (from
    # the nearest point, the box extends at least that far straight away from p)
    gmin = down(min(down(pxh - pxl), down(pyh - pyl)))
    return cx, cy, wx, wy, rc, amg, 1.0 / inc, gmin


@njit(cache=True, inline="always")
def _inner(x0, x1, y0, y1, eps, pxl, pxh, pyl, pyh, thl, thh, a0, h, mid, cx, cy, wx, wy, rc, amg, inv_inc,
           lw, lrb, lc, lrbc):
    """What holds for *every* cell inside ``[x0, x1] x [y0, y1]`` (real geometry, margins far
    above every rounding): ``(i_lo, i_hi, k_lo, k_hi)``.

    - ``[i_lo, i_hi]`` (empty when ``i_lo > i_hi``; not clipped to the scan): beams in every
      cell's window (an index outside the scan: no cell's cones cover it). With the centre
      ``c`` and half-widths ``w`` of a sub-box of the sensor box (:func:`_inner_consts`), the
      block's centre ``b`` (``v = b - c``, ``L = |v|``), and ``(hx, hy)`` bounding the offsets
      of its cell centres from ``b``: a cell (half-width ``eps / 2``) meets the box's shadow
      strip in direction ``psi`` (normal ``n``) when their projections on ``n`` overlap, which
      holds for every cell when ``|n . v| = L |sin(psi - angle(v))| <= dx |sin psi| + dy |cos
      psi|`` (``dx = w_x + eps / 2 - hx``, ``dy = w_y + eps / 2 - hy``); the right side varies
      by at most ``(dx + dy) |psi - angle(v)|``, so every ``psi`` with ``|psi - angle(v)| <=
      rho = (dx |v_y| + dy |v_x|) / (L (L + dx + dy))`` qualifies, the block being ahead
      (``L cos(rho) > |wb| + |w| + eps``): then ``psi`` is the bearing of a sensor-to-point vector
      into every cell. A beam whose cone meets ``[angle(v) - rho, angle(v) + rho] - [theta]``
      is in the real window of every cell, hence in the reference's (outer) one.
    - ``k_lo >= dist(c, box) - eps / 2`` and ``k_hi <= maxdist(c, box) + eps / 2`` for the
      centre ``c`` of every cell of the block: ``[dist(c, box) - eps / 2, maxdist(c, box) + eps
      / 2]`` lies in the cell's range interval (half a cell straight towards the box's nearest
      point, or away from its farthest, stays in the cell; the lower end is used only when the
      window is not empty, the block then being more than ``eps`` away from the box), and
      ``k_hi`` bounds every cell's largest range from below. A beam with ``lo <= k_hi`` and
      ``hi >= k_lo`` meets the range interval of every cell.
    """
    bx = 0.5 * (x0 + x1)
    by = 0.5 * (y0 + y1)
    wbx = upf(max(upf(bx - x0), upf(x1 - bx)))  # a super-box of the block, centred on b
    wby = upf(max(upf(by - y0), upf(y1 - by)))
    # the level's bounds ``LC[lev]`` (see _level_consts) when they hold
    rb = lrb if (wbx <= lw and wby <= lw) else upf(math.sqrt(upf(upf(wbx * wbx) + upf(wby * wby))))
    # the range interval common to the block
    ex = max(max(upf(pxl - bx), upf(bx - pxh)), 0.0)
    ey = max(max(upf(pyl - by), upf(by - pyh)), 0.0)
    d_up = upf(math.sqrt(upf(upf(ex * ex) + upf(ey * ey))))
    mx = max(max(dn(bx - pxl), dn(pxh - bx)), 0.0)
    my = max(max(dn(by - pyl), dn(pyh - by)), 0.0)
    dm = dn(math.sqrt(dn(dn(mx * mx) + dn(my * my))))
    # cell centres lie within rbc of b: [k_lo, k_hi] meets the range interval of every centre
    hx = max(upf(bx - upf(x0 + 0.5 * eps)), upf(dn(x1 - 0.5 * eps) - bx))
    hy = max(upf(by - upf(y0 + 0.5 * eps)), upf(dn(y1 - 0.5 * eps) - by))
    hx = upf(max(hx, 0.0) + 1e-12 * (1.0 + abs(bx)))
    hy = upf(max(hy, 0.0) + 1e-12 * (1.0 + abs(by)))
    rbc = lrbc if (hx <= lc and hy <= lc) else upf(math.sqrt(upf(upf(hx * hx) + upf(hy * hy))))
    # a cell reaches eps / 2 nearer / farther than its centre (straight to the nearest / from the
    # farthest point of the box; the nearer side used only with the block ahead of the box)
    k_lo = upf(upf(d_up + rbc) - 0.5 * eps)
    k_hi = dn(dn(dm - rbc) + 0.5 * eps)
    # beams common to the block's cells: a cell (half-width eps / 2, centre within (hx, hy) of
    # b) meets the box's shadow strip in direction psi when |n . v| <= dx |sin psi| + dy |cos psi|
    # (selects, no branches: vectorised in _level_geom; ok False: no common beam)
    ddx = dn(dn(wx + 0.5 * eps) - hx)
    ddy = dn(dn(wy + 0.5 * eps) - hy)
    vx = bx - cx
    vy = by - cy
    L = math.sqrt(vx * vx + vy * vy)
    ok = ddx > 0.0 and ddy > 0.0 and L > 1e-3
    Ls = L if ok else 1.0
    rho = (ddx * abs(vy) + ddy * abs(vx)) / (Ls * (Ls + ddx + ddy))
    # every rounding here is relative ~1e-16 of the coordinates: margins far larger than that
    rho = rho * (1.0 - 1e-9) - 1e-10 * (1.0 + abs(bx) + abs(by) + abs(cx) + abs(cy)) / Ls - amg
    ok = ok and rho > 0.0 and not (rho > 0.5)
    ok = ok and L * (1.0 - 0.5 * rho * rho) > (rb + rc + eps) * (1.0 + 1e-9) + 1e-9
    alpha = atan2_fast(vy, vx)  # within ATAN_ERR (in amg, taken off rho)
    lo_ang = alpha - rho - thh - h
    hi_ang = alpha + rho - thl + h
    ok = ok and lo_ang < hi_ang
    # any branch 2 pi k: the cones meeting [lo_ang, hi_ang] + 2 pi Z are in every real window
    c = 0.5 * (lo_ang + hi_ang) - mid
    k = 0.0 if (-3.0 < c and c < 3.0) else math.floor(c / (2.0 * math.pi) + 0.5)
    u_lo = (lo_ang - k * 2.0 * math.pi - a0) * inv_inc
    u_hi = (hi_ang - k * 2.0 * math.pi - a0) * inv_inc
    ok = ok and -1e6 < u_lo and u_hi < 1e6
    i_lo = int(math.ceil((u_lo if ok else 0.0) + 1e-6))
    i_hi = int(math.floor((u_hi if ok else 0.0) - 1e-6))
    return (i_lo if ok else 0), (i_hi if ok else -1), k_lo, k_hi


@njit(cache=True, inline="always")
def _tile_slot(tl, n_tl, slot, tx, ty, what):
    """The index of the current tile in the scan's tile list (added on its first record);
    ``what`` (1 empty, 2 obstacle) is or-ed into its flags. -1 when the list is full."""
    if slot < 0:
        if n_tl >= tl.shape[0]:
            return -1
        slot = n_tl
        tl[slot, 0] = tx
        tl[slot, 1] = ty
        tl[slot, 2] = 0
    tl[slot, 2] |= what
    return slot


@njit(cache=True, error_model="numpy", _nrt=False)
def _level_geom(n, s, LX, LY, CX, CY, thl, thh, a0, inv_inc, h, nb, mid, lo_edge, hi_edge, err,
                DXL, DXH, DYL, DYH, RL, RH, OL, OH, EL, EH, CV, SM,
                inner, X0, X1, Y0, Y1, IL, IH, KL, KH, eps, pxl, pxh, pyl, pyh, icx, icy, iwx, iwy, irc, amg,
                lw, lrb, lc, lrbc):
    """Geometry of the blocks of ``s x s`` cells with first column ``LX[j]`` and row ``LY[j]``
    in the axis tables (:func:`_axis_table`), ``j < n``: the range
    interval into ``RL, RH`` and the fast outer window into ``OL, OH, EL, EH`` (clipped, then
    unclipped), ``CV`` (cover: inside the scan) and ``SM`` (simple), 1 / 0.

    The window comes from the fast bearings (within ``err``): ``simple`` says the bearings
    minus ``[theta]`` lie within 3 rad of the scan's middle in one branch and no other branch
    meets the scan's cones; then every cell of the block gets, in the reference, its window from
    that branch, inside ``[e_lo, e_hi]`` (and ``cover``: inside the scan). Not simple: the
    caller uses the reference's block test. With ``inner``, :func:`_inner` of every block into
    ``IL, IH, KL, KH`` (corners into ``X0, X1, Y0, Y1``).

    The loops have no branch (selects only): the compiler vectorises them (numpy's error
    model: no zero-division test, every divisor is non-zero by a select). ``DXL .. DYH``: work
    arrays (offsets from the sensor box, gathered first: gathers do not vectorise)."""
    for j in range(n):  # the offsets from the axis tables (gathers: not vectorised)
        ca = LX[j]
        ra = LY[j]
        DXL[j], DXH[j], DYL[j], DYH[j] = CX[ca, 2], CX[ca + s - 1, 3], CY[ra, 2], CY[ra + s - 1, 3]
        X0[j], X1[j], Y0[j], Y1[j] = CX[ca, 0], CX[ca + s - 1, 1], CY[ra, 0], CY[ra + s - 1, 1]
    if inner:  # _inner of every block (used for the simple ones that are neither pruned nor empty)
        for j in range(n):
            IL[j], IH[j], KL[j], KH[j] = _inner(X0[j], X1[j], Y0[j], Y1[j], eps, pxl, pxh, pyl, pyh, thl, thh, a0,
                                                h, mid, icx, icy, iwx, iwy, irc, amg, inv_inc, lw, lrb, lc, lrbc)
    for j in range(n):
        dxl, dxh, dyl, dyh = DXL[j], DXH[j], DYL[j], DYH[j]
        r_lo, r_hi = box_ranges_fin(dxl, dxh, dyl, dyh)
        bl, bh, full = box_bearings_fast(dxl, dxh, dyl, dyh)
        # the window, in the branch 2 pi k nearest the scan's middle (simple checks it is the
        # reference's: then k = round(c / 2 pi), whatever the rounding at half-integers)
        pl = bl - thh - err
        ph = bh - thl + err
        narrow = ph - pl < 5.9
        c = 0.5 * (pl + ph) - mid
        k = 0.0 if (-3.0 < c and c < 3.0) else math.floor(c / (2.0 * math.pi) + 0.5)
        pl -= k * 2.0 * math.pi
        ph -= k * 2.0 * math.pi
        simple = (pl - mid > -3.0 and ph - mid < 3.0 and pl + 2.0 * math.pi - hi_edge > err
                  and ph - 2.0 * math.pi - lo_edge < -err)
        u_lo = (pl - h - a0) * inv_inc - 1e-9
        u_hi = (ph + h - a0) * inv_inc + 1e-9
        ok = (not full) and bh - bl < 3.0 and narrow and -1e5 < u_lo and u_hi < 1e5
        e_lo = int(math.floor(u_lo if ok else 0.0))
        e_hi = int(math.ceil(u_hi if ok else -1.0))
        RL[j] = r_lo
        RH[j] = r_hi
        OL[j] = max(e_lo, 0) if ok else 0
        OH[j] = min(e_hi, nb - 1) if ok else nb - 1
        EL[j] = e_lo
        EH[j] = e_hi
        CV[j] = 1 if (ok and e_lo >= 0 and e_hi <= nb - 1) else 0
        SM[j] = 1 if (ok and simple) else 0


@njit(cache=True, error_model="numpy", _nrt=False)
def _cell_geom(n, LX, LY, CX, CY, thl, thh, a0, h, nb, mid, lo_edge, hi_edge, err, inv_inc,
               DXL, DXH, DYL, DYH, RL, RH, OL, OH, EL, EH, CV, SM):
    """:func:`_geom1_d` of cells ``(LX[j], LY[j])``, ``j < n`` (as :func:`_level_geom`; ``SM``:
    the window decided, state 0). Selects only: vectorised."""
    for j in range(n):
        ca = LX[j]
        ra = LY[j]
        DXL[j], DXH[j], DYL[j], DYH[j] = CX[ca, 2], CX[ca, 3], CY[ra, 2], CY[ra, 3]
    for j in range(n):
        r_lo, r_hi, o_lo, o_hi, e_lo, e_hi, cover, state = _geom1_d(DXL[j], DXH[j], DYL[j], DYH[j], thl, thh, a0,
                                                                    h, nb, mid, lo_edge, hi_edge, err, inv_inc)
        RL[j] = r_lo
        RH[j] = r_hi
        OL[j] = o_lo
        OH[j] = o_hi
        EL[j] = e_lo
        EH[j] = e_hi
        CV[j] = 1 if cover else 0
        SM[j] = 1 if state == 0 else 0


_WF = 12  # rows of the level work arrays: floats (RL .. KH), integers (LX .. SM)
_WI = 12
_CHUNK = 64  # tiles traversed together, level by level (the work arrays need at most 64 * 4096 columns)


@njit(cache=True)
def _level_buffers():
    """Work arrays of :func:`traverse` (rows of :data:`_WF` floats, :data:`_WI` integers, one
    column per block of a level; :func:`_traverse_grown` grows them when a scan needs more)."""
    return np.empty((_WF, 8192)), np.empty((_WI, 8192), dtype=np.int64)


@njit(cache=True)
def traverse(keys, slots, cells, ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps,
             exact, lg, T, new, tl, blk, mblk, cand, cand_f, stats, WF, WI, fill=True):
    """P_EMPTY^k, P_OBSTACLE^k and the new beams of one scan (fast path; the same cells and
    beams as :func:`traverse_reference`). ``T``: the scan's table (:func:`_fast_tables`);
    ``WF, WI``: work arrays (:func:`_level_buffers`). The cells' sides and offsets from the
    sensor box come from per-axis tables (:func:`_axis_table`: the same roundings, once per
    column and row). The tiles are visited together (by chunks of :data:`_CHUNK`), level by
    level: the geometry of all blocks (or cells) of a level first, in a vectorised pass
    (:func:`_level_geom`, :func:`_cell_geom`), then their decisions one by one; the tiles'
    slots are put back in the order of a visit tile by tile at the end (:func:`_tiles_in_order`).

    The map (``keys, slots, cells``) is only read. Outputs, in buffers of fixed size:
    ``tl[j] = (tx, ty, flags)`` the tiles holding records, in traversal order (flags: 1 =
    empty blocks, 2 = cells of P_OBSTACLE^k); ``blk[k] = (ix, iy, level, j)`` proven-empty
    blocks of tile ``tl[j]``; ``mblk[k] = (ix, iy, level, w_lo, w_hi, j)`` blocks whose every
    cell is in P_OBSTACLE^k, ``[w_lo, w_hi]`` holding the window of each; ``cand[k] = (ix, iy,
    o_lo, o_hi, marked, j)``, ``cand_f[k] = (r_lo, r_hi)`` single cells with their window and
    range interval (``marked`` = in P_OBSTACLE^k; unmarked ones only in hull mode, where the
    hull test alone puts a cell in the output). ``new[i]`` is set for the beams whose
    P_OBSTACLE^{i,k} meets P_UNKNOWN. ``stats`` += [nodes, empty cells, beam tests, obstacle
    cells].

    Returns ``(ok, n_tl, n_blk, n_mblk, n_cand, need)``; ``ok`` False: a buffer was too small
    (``need`` > 0: the work arrays, which need that many columns; ``new`` and ``stats`` are then
    partial: grow the buffers, reset them, run again).
    """
    nb = ranges.shape[0]
    h = max(r_alpha, 0.5 * inc)
    cos_gap = _cos_gap(r_alpha, inc, fill)
    rmax = _fast_tables(ranges, valid, r_abs, r_rel, cos_gap, T)
    n_tl = 0
    n_blk = 0
    n_mblk = 0
    n_cand = 0
    if rmax == -INF:
        return True, n_tl, n_blk, n_mblk, n_cand, 0
    if not (abs(box[0]) + abs(box[1]) + abs(box[2]) + abs(box[3]) + 2.0 * rmax + 4.0 * TILE * eps < FIN_MAX):
        # the tile index (int32 tile coordinates) bounds a map far below this
        raise ValueError("lidar map: coordinates or ranges beyond 1e150")
    a_end = a0 + (nb - 1) * inc
    mid = 0.5 * (a0 + a_end)
    lo_edge = down(a0 - h)
    hi_edge = up(up(a_end + h))
    pxl, pxh, pyl, pyh, thl, thh = box[0], box[1], box[2], box[3], box[4], box[5]
    # error of a fast bearing minus theta against the reference's: ATAN_ERR + roundings
    err = ATAN_ERR + 1e-12 * (8.0 + abs(thl) + abs(thh))
    icx, icy, iwx, iwy, irc, amg, inv_inc, gmin = _inner_consts(box, inc)
    iw_min = min(iwx, iwy)
    gmin_c = down(gmin + eps)  # narrowest range interval of a cell: see _inner_consts and _inner
    LC = _level_consts(eps)
    tx0, tx1, ty0, ty1 = _tile_range(pxl, pxh, pyl, pyh, rmax, eps)
    i0 = tx0 * TILE
    j0 = ty0 * TILE
    CX = _axis_table(i0, (tx1 - tx0 + 1) * TILE, eps, pxl, pxh)
    CY = _axis_table(j0, (ty1 - ty0 + 1) * TILE, eps, pyl, pyh)
    # the blocks of a level (LX, LY: columns and rows in the axis tables) and of the next (NX,
    # NY); their geometry
    RL, RH, DXL, DXH, DYL, DYH, X0, X1, Y0, Y1, KL, KH = (WF[0], WF[1], WF[2], WF[3], WF[4], WF[5], WF[6],
                                                          WF[7], WF[8], WF[9], WF[10], WF[11])
    LX, LY, NX, NY, OL, OH, EL, EH, IL, IH, CV, SM = (WI[0], WI[1], WI[2], WI[3], WI[4], WI[5], WI[6], WI[7],
                                                      WI[8], WI[9], WI[10], WI[11])
    cap = min(WF.shape[1], WI.shape[1])
    if cap < _CHUNK:  # a chunk's tiles are listed before any test
        return False, n_tl, n_blk, n_mblk, n_cand, _CHUNK
    cap_blk = blk.shape[0]
    cap_mblk = mblk.shape[0]
    cap_cand = cand.shape[0]
    # the tiles in the reference's order (rank = column-major over the scan's tile range), by
    # chunks: the map index of the chunk's tiles and their slot in ``tl`` (-1: no record yet)
    nty = ty1 - ty0 + 1
    n_tiles = (tx1 - tx0 + 1) * nty
    TT = np.empty(_CHUNK, dtype=np.int64)
    TS = np.empty(_CHUNK, dtype=np.int64)
    nodes = 0
    n_empty = 0
    n_obst = 0
    for q0 in range(0, n_tiles, _CHUNK):  # a chunk of tiles, level by level
        n_lev = 0
        for q in range(q0, min(q0 + _CHUNK, n_tiles)):
            LX[n_lev] = (q // nty) * TILE
            LY[n_lev] = (q % nty) * TILE
            TT[n_lev] = find(keys, slots, tx0 + q // nty, ty0 + q % nty)
            TS[n_lev] = -1
            n_lev += 1
        lev = _LEVELS
        while lev > 0 and n_lev > 0:
            if 4 * n_lev > cap:
                return False, n_tl, n_blk, n_mblk, n_cand, 4 * n_lev
            s = 1 << lev
            half = s >> 1
            inner = LC[lev, 2] < iw_min + 0.5 * eps  # else cells too far apart for a common bearing
            _level_geom(n_lev, s, LX, LY, CX, CY, thl, thh, a0, inv_inc, h, nb, mid, lo_edge, hi_edge,
                        err, DXL, DXH, DYL, DYH, RL, RH, OL, OH, EL, EH, CV, SM, inner, X0, X1, Y0, Y1, IL, IH,
                        KL, KH, eps, pxl, pxh, pyl, pyh, icx, icy, iwx, iwy, irc, amg, LC[lev, 0], LC[lev, 1],
                        LC[lev, 2], LC[lev, 3])
            n_next = 0
            for j in range(n_lev):
                gx, gy = LX[j], LY[j]
                nodes += 1
                r_lo, r_hi = RL[j], RH[j]
                if r_lo > rmax:
                    continue
                ix = i0 + gx
                iy = j0 + gy
                q = (gx >> TILE_SHIFT) * nty + (gy >> TILE_SHIFT) - q0  # in the chunk
                o_lo, o_hi, e_lo, e_hi, cover, simple = OL[j], OH[j], EL[j], EH[j], CV[j] != 0, SM[j] != 0
                if not simple:
                    # the reference's block test (around the sensor box, the back of the scan)
                    dxl, dxh = dn(X0[j] - pxh), upf(X1[j] - pxl)
                    dyl, dyh = dn(Y0[j] - pyh), upf(Y1[j] - pyl)
                    bl, bh, full = box_bearings(dxl, dxh, dyl, dyh)
                    if full:
                        o_lo, o_hi, e_lo, e_hi, cover = 0, nb - 1, 0, -1, False
                    else:
                        o_lo, o_hi, e_lo, e_hi, cover = beam_window(down(bl - thh), up(bh - thl),
                                                                    a0, inc, h, nb)
                if o_lo > o_hi:
                    continue
                lo_min, hi_max, f_min, f_max = _win(T, lg, o_lo, o_hi)
                if cover and (e_lo != o_lo or e_hi != o_hi):
                    f_min = _win(T, lg, e_lo, e_hi)[2]
                if cover and r_hi < f_min:
                    slot = _tile_slot(tl, n_tl, TS[q], ix >> TILE_SHIFT, iy >> TILE_SHIFT, 1)
                    if slot < 0 or n_blk >= cap_blk:
                        return False, n_tl, n_blk, n_mblk, n_cand, 0
                    TS[q] = slot
                    n_tl = max(n_tl, slot + 1)
                    blk[n_blk, 0], blk[n_blk, 1], blk[n_blk, 2], blk[n_blk, 3] = ix, iy, lev, slot
                    n_blk += 1
                    n_empty += s * s
                    continue
                freep = r_lo < f_max
                obs = r_hi >= lo_min and r_lo <= hi_max
                if simple:
                    # [o_lo, o_hi] holds every cell's window
                    if obs and exact:
                        obs = _meets(T, lg, o_lo, o_hi, r_hi, r_lo, lo_min, hi_max, stats)
                    if not obs and not freep:
                        continue
                    if inner:
                        u_lo, u_hi, k_lo, k_hi = IL[j], IH[j], KL[j], KH[j]
                    else:
                        u_lo, u_hi = 0, -1
                    if u_lo <= u_hi:
                        i_lo = max(u_lo, 0)
                        i_hi = min(u_hi, nb - 1)
                        if i_lo <= i_hi:
                            ilo_min, ihi_max, if_min, _ = _win(T, lg, i_lo, i_hi)
                        # no cell can be proven empty: its window reaches outside the scan, or
                        # its largest range reaches the free range of a beam in every window
                        if freep and (u_lo < 0 or u_hi > nb - 1 or k_hi >= if_min):
                            freep = False
                        # every cell is in P_OBSTACLE^k when a beam of [i_lo, i_hi] meets the
                        # range interval of each cell centre: one beam with lo <= k_hi and hi >=
                        # k_lo, or the hull reaching them all with no jump wider than the
                        # narrowest, at least the box's smaller side (see _inner_consts)
                        if obs and i_lo <= i_hi and _meets_g(T, lg, i_lo, i_hi, k_hi, k_lo, ilo_min,
                                                             ihi_max, max(gmin_c, down(k_hi - k_lo)), stats):
                            slot = _tile_slot(tl, n_tl, TS[q], ix >> TILE_SHIFT, iy >> TILE_SHIFT, 2)
                            if slot < 0 or n_mblk >= cap_mblk:
                                return False, n_tl, n_blk, n_mblk, n_cand, 0
                            TS[q] = slot
                            n_tl = max(n_tl, slot + 1)
                            mblk[n_mblk, 0], mblk[n_mblk, 1], mblk[n_mblk, 2] = ix, iy, lev
                            mblk[n_mblk, 3], mblk[n_mblk, 4], mblk[n_mblk, 5] = o_lo, o_hi, slot
                            n_mblk += 1
                            n_obst += s * s
                            # unmeasured cells: their beams are new (each cell once per log)
                            t = TT[q]
                            lx = ix & TILE_MASK
                            ly = iy & TILE_MASK
                            for a in range(lx, lx + s):
                                for b in range(ly, ly + s):
                                    if _unmeasured(cells, t, a, b):
                                        c_lo, c_hi, _, _, _, q_lo, q_hi = _cell_window(
                                            ix - lx + a, iy - ly + b, eps, box, a0, inc, h, nb, rmax, mid, lo_edge,
                                            hi_edge, err)
                                        _scan_new(T, c_lo, c_hi, q_lo, q_hi, new, stats)
                            continue
                if not obs and not freep:
                    continue
                # refine: the four quarters at the next level (cells at level 0)
                NX[n_next], NY[n_next] = gx, gy
                NX[n_next + 1], NY[n_next + 1] = gx + half, gy
                NX[n_next + 2], NY[n_next + 2] = gx, gy + half
                NX[n_next + 3], NY[n_next + 3] = gx + half, gy + half
                n_next += 4
            LX, NX = NX, LX
            LY, NY = NY, LY
            n_lev = n_next
            lev -= 1
        if lev > 0 or n_lev == 0:
            continue
        # the cells: geometry of all, then the reference's leaf decisions
        _cell_geom(n_lev, LX, LY, CX, CY, thl, thh, a0, h, nb, mid, lo_edge, hi_edge, err, inv_inc,
                   DXL, DXH, DYL, DYH, RL, RH, OL, OH, EL, EH, CV, SM)
        for j in range(n_lev):
            nodes += 1
            r_lo, r_hi = RL[j], RH[j]
            if r_lo > rmax:
                continue
            gx, gy = LX[j], LY[j]
            cx_ = i0 + gx
            cy_ = j0 + gy
            q = (gx >> TILE_SHIFT) * nty + (gy >> TILE_SHIFT) - q0  # in the chunk
            if SM[j] != 0:
                o_lo, o_hi = OL[j], OH[j]
                code = _classify(T, lg, o_lo, o_hi, EL[j], EH[j], CV[j] != 0, r_lo, r_hi, stats)
            else:
                code, o_lo, o_hi, r_lo, r_hi = _cell(cx_, cy_, eps, box, a0, inc, h, nb, rmax, mid,
                                                     lo_edge, hi_edge, T, lg, stats)
            if code == 0 or (code == 2 and exact):
                continue
            if code == 1:
                slot = _tile_slot(tl, n_tl, TS[q], cx_ >> TILE_SHIFT, cy_ >> TILE_SHIFT, 1)
                if slot < 0 or n_blk >= cap_blk:
                    return False, n_tl, n_blk, n_mblk, n_cand, 0
                TS[q] = slot
                n_tl = max(n_tl, slot + 1)
                blk[n_blk, 0], blk[n_blk, 1], blk[n_blk, 2], blk[n_blk, 3] = cx_, cy_, 0, slot
                n_blk += 1
                n_empty += 1
                continue
            marked = code == 3
            if marked and _unmeasured(cells, TT[q], cx_ & TILE_MASK, cy_ & TILE_MASK):
                _scan_new(T, o_lo, o_hi, r_lo, r_hi, new, stats)
            slot = _tile_slot(tl, n_tl, TS[q], cx_ >> TILE_SHIFT, cy_ >> TILE_SHIFT, 2 if marked else 0)
            if slot < 0 or n_cand >= cap_cand:
                return False, n_tl, n_blk, n_mblk, n_cand, 0
            TS[q] = slot
            n_tl = max(n_tl, slot + 1)
            cand[n_cand, 0], cand[n_cand, 1] = cx_, cy_
            cand[n_cand, 2], cand[n_cand, 3] = o_lo, o_hi
            cand[n_cand, 4], cand[n_cand, 5] = (1 if marked else 0), slot
            cand_f[n_cand, 0], cand_f[n_cand, 1] = r_lo, r_hi
            n_cand += 1
            n_obst += 1
    _tiles_in_order(tl, n_tl, tx0, ty0, nty, blk, n_blk, mblk, n_mblk, cand, n_cand)
    stats[0] += nodes
    stats[1] += n_empty
    stats[3] += n_obst
    return True, n_tl, n_blk, n_mblk, n_cand, 0


@njit(cache=True)
def _tiles_in_order(tl, n_tl, tx0, ty0, nty, blk, n_blk, mblk, n_mblk, cand, n_cand):
    """Renumber the tile slots in the order of the tiles' ranks (``(tx - tx0) nty + ty - ty0``):
    the reference's order (tiles visited one by one), ``tl`` and the records' slots rewritten."""
    rank = np.empty(max(n_tl, 1), dtype=np.int64)
    in_order = True
    for j in range(n_tl):
        rank[j] = (tl[j, 0] - tx0) * nty + (tl[j, 1] - ty0)
        in_order = in_order and (j == 0 or rank[j] > rank[j - 1])
    if in_order:
        return
    new_of = np.empty(n_tl, dtype=np.int64)
    order = np.argsort(rank[:n_tl])
    for k in range(n_tl):
        new_of[order[k]] = k
    old = tl[:n_tl].copy()
    for j in range(n_tl):
        tl[new_of[j]] = old[j]
    for k in range(n_blk):
        blk[k, 3] = new_of[blk[k, 3]]
    for k in range(n_mblk):
        mblk[k, 5] = new_of[mblk[k, 5]]
    for k in range(n_cand):
        cand[k, 5] = new_of[cand[k, 5]]


@njit(cache=True, _nrt=False)
def _new_meets(o_lo, o_hi, r_lo, r_hi, T, cnt_new, new_idx):
    """Whether a new beam of ``[o_lo, o_hi]`` meets ``[r_lo, r_hi]`` (``new_idx``: the new
    beams in order, ``cnt_new``: their prefix counts)."""
    for q in range(cnt_new[o_lo], cnt_new[o_hi + 1]):
        i = new_idx[q]
        if T[0, i, 0] <= r_hi and T[0, i, 1] >= r_lo:
            return True
    return False


@njit(cache=True, _nrt=False)
def _flags(o_lo, o_hi, r_lo, r_hi, new, valid, T, cnt_new, cnt_valid, new_idx):
    """OBST_NEW / OBST_OLD of a cell of P_OBSTACLE^k with window ``[o_lo, o_hi]`` and range
    interval ``[r_lo, r_hi]``: the kinds of the valid beams of the window meeting it (as the
    reference). Some beam meets: when no new one does, they are old; beam by beam only when a
    new one does and old ones are in the window."""
    if not _new_meets(o_lo, o_hi, r_lo, r_hi, T, cnt_new, new_idx):
        return OBST_OLD
    if cnt_new[o_hi + 1] - cnt_new[o_lo] == cnt_valid[o_hi + 1] - cnt_valid[o_lo]:
        return OBST_NEW
    for i in range(o_lo, o_hi + 1):
        if valid[i] and not new[i] and T[0, i, 0] <= r_hi and T[0, i, 1] >= r_lo:
            return OBST_NEW | OBST_OLD
    return OBST_NEW


@njit(cache=True, _nrt=False)
def _write(cells, ti, n_blk, blk, n_mblk, mblk, n_cand, cand, cand_f, new, valid, box, a0, inc, h,
           eps, rmax, T, lg, cnt_new, cnt_valid, new_idx, st):
    """The writes of :func:`apply` (tiles allocated: ``ti[j]`` is tile ``tl[j]``'s index)."""
    nb = valid.shape[0]
    a_end = a0 + (nb - 1) * inc
    mid = 0.5 * (a0 + a_end)
    lo_edge = down(a0 - h)
    hi_edge = up(up(a_end + h))
    pxl, pxh, pyl, pyh = box[0], box[1], box[2], box[3]
    err = ATAN_ERR + 1e-12 * (8.0 + abs(box[4]) + abs(box[5]))  # as traverse's
    for k in range(n_blk):
        t = ti[blk[k, 3]]
        s = 1 << blk[k, 2]
        lx, ly = blk[k, 0] & TILE_MASK, blk[k, 1] & TILE_MASK
        for a in range(lx, lx + s):
            for b in range(ly, ly + s):
                cells[t, a, b] |= EMPTY
    for k in range(n_mblk):
        ix, iy, w_lo, w_hi, t = mblk[k, 0], mblk[k, 1], mblk[k, 3], mblk[k, 4], ti[mblk[k, 5]]
        s = 1 << mblk[k, 2]
        lx, ly = ix & TILE_MASK, iy & TILE_MASK
        nn = cnt_new[w_hi + 1] - cnt_new[w_lo]
        f = np.uint8(0)
        if nn == 0:
            f = OBST_OLD
        elif nn == cnt_valid[w_hi + 1] - cnt_valid[w_lo]:
            f = OBST_NEW
        else:  # no new beam meets the block's range interval: no cell's either
            r_lo, r_hi = box_ranges(down(down(ix * eps) - pxh), up(up((ix + s) * eps) - pxl),
                                    down(down(iy * eps) - pyh), up(up((iy + s) * eps) - pyl))
            if not _new_meets(w_lo, w_hi, r_lo, r_hi, T, cnt_new, new_idx):
                f = OBST_OLD
        if f != 0:
            for a in range(lx, lx + s):
                for b in range(ly, ly + s):
                    cells[t, a, b] |= f
            continue
        for a in range(lx, lx + s):
            for b in range(ly, ly + s):
                cx, cy = ix - lx + a, iy - ly + b
                r_lo, r_hi = box_ranges_fin(dn(dn(cx * eps) - pxh), upf(upf((cx + 1) * eps) - pxl),
                                            dn(dn(cy * eps) - pyh), upf(upf((cy + 1) * eps) - pyl))
                if not _new_meets(w_lo, w_hi, r_lo, r_hi, T, cnt_new, new_idx):
                    cells[t, a, b] |= OBST_OLD  # no new beam of a wider window meets the cell
                    continue
                o_lo, o_hi, _, _, _, r_lo, r_hi = _cell_window(cx, cy, eps, box, a0, inc, h, nb, rmax, mid, lo_edge,
                                                               hi_edge, err)
                cells[t, a, b] |= _flags(o_lo, o_hi, r_lo, r_hi, new, valid, T, cnt_new, cnt_valid,
                                         new_idx)
    for k in range(n_cand):
        if cand[k, 4] == 0:
            continue
        ix, iy = cand[k, 0], cand[k, 1]
        f = _flags(cand[k, 2], cand[k, 3], cand_f[k, 0], cand_f[k, 1], new, valid, T, cnt_new, cnt_valid,
                   new_idx)
        cells[ti[cand[k, 5]], ix & TILE_MASK, iy & TILE_MASK] |= f


@njit(cache=True)
def apply(keys, slots, cells, coords, n, n_tl, tl, n_blk, blk, n_mblk, mblk, n_cand, cand, cand_f,
          new, valid, box, a0, inc, r_alpha, eps, rmax, T, lg, cnt_new, cnt_valid, new_idx, st):
    """Write one scan into the map (fast path of :func:`apply_reference`, the same cells and
    tiles in the same order): EMPTY on the empty blocks, OBST_NEW / OBST_OLD on the cells of
    P_OBSTACLE^k by the new / old valid beams of their window meeting their range. Returns
    the map arrays."""
    ti = np.empty(max(n_tl, 1), dtype=np.int64)
    for j in range(n_tl):  # tiles of empty blocks first, then of obstacle cells (as the reference)
        if tl[j, 2] & 1:
            ti[j], keys, slots, cells, coords, n = add_tile(keys, slots, cells, coords, n, tl[j, 0], tl[j, 1])
    for j in range(n_tl):
        if tl[j, 2] == 2:
            ti[j], keys, slots, cells, coords, n = add_tile(keys, slots, cells, coords, n, tl[j, 0], tl[j, 1])
    _write(cells, ti, n_blk, blk, n_mblk, mblk, n_cand, cand, cand_f, new, valid, box, a0, inc,
           max(r_alpha, 0.5 * inc), eps, rmax, T, lg, cnt_new, cnt_valid, new_idx, st)
    return keys, slots, cells, coords, n


@njit(cache=True)
def _fast_buffers(nbmax):
    lg = _log2_table(nbmax)
    return lg, np.empty((lg[nbmax] + 1, nbmax, _NF))


@njit(cache=True)
def _record_buffers():
    return (np.empty((64, 3), dtype=np.int64), np.empty((1024, 4), dtype=np.int64),
            np.empty((1024, 6), dtype=np.int64), np.empty((4096, 6), dtype=np.int64),
            np.empty((4096, 2)))


@njit(cache=True)
def _grown(a):
    b = np.empty((2 * a.shape[0],) + a.shape[1:], dtype=a.dtype)
    b[: a.shape[0]] = a
    return b


@njit(cache=True)
def _traverse_grown(keys, slots, cells, ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps, exact, lg, T,
                    new, tl, blk, mblk, cand, cand_f, st, WF, WI, fill):
    """:func:`traverse` of one scan, its record buffers and work arrays grown (and ``new``,
    ``st`` reset) until they hold the scan: ``(n_tl, n_blk, n_mblk, n_cand, tl, blk, mblk, cand,
    cand_f, WF, WI)``."""
    nb = ranges.shape[0]
    while True:
        new[:nb] = False
        st[:] = 0
        ok, n_tl, n_blk, n_mblk, n_cand, need = traverse(keys, slots, cells, ranges, valid, a0, inc, box, r_abs,
                                                         r_rel, r_alpha, eps, exact, lg, T, new, tl, blk, mblk,
                                                         cand, cand_f, st, WF, WI, fill)
        if ok:
            return n_tl, n_blk, n_mblk, n_cand, tl, blk, mblk, cand, cand_f, WF, WI
        if need > 0:
            m = max(need, 2 * WI.shape[1])
            WF = np.empty((WF.shape[0], m))
            WI = np.empty((WI.shape[0], m), dtype=np.int64)
        if n_tl >= tl.shape[0]:
            tl = _grown(tl)
        if n_blk >= blk.shape[0]:
            blk = _grown(blk)
        if n_mblk >= mblk.shape[0]:
            mblk = _grown(mblk)
        if n_cand >= cand.shape[0]:
            cand = _grown(cand)
            cand_f = _grown(cand_f)


@njit(cache=True)
def update_log(keys, slots, cells, coords, n, ranges, valid, offsets, angle_min, angle_inc,
               boxes, order, r_abs, r_rel, r_alpha, eps, exact, write, is_old, scan_stats, fill=True):
    """Process scans ``order`` (in that order) from sensor boxes ``boxes`` (S, 6): the same map,
    ``is_old`` and ``scan_stats`` columns 1-4 as :func:`update_log_reference` (columns 0 and 5,
    nodes visited and beam tests, count this path's own work). Returns the map arrays."""
    nbmax = 1
    for s in order:
        nbmax = max(nbmax, offsets[s + 1] - offsets[s])
    lg, T = _fast_buffers(nbmax)
    new = np.zeros(nbmax, dtype=np.bool_)
    cnt_new = np.zeros(nbmax + 1, dtype=np.int64)
    cnt_valid = np.zeros(nbmax + 1, dtype=np.int64)
    new_idx = np.zeros(nbmax, dtype=np.int64)
    tl, blk, mblk, cand, cand_f = _record_buffers()
    WF, WI = _level_buffers()
    st = np.zeros(4, dtype=np.int64)
    for s in order:
        b0, b1 = offsets[s], offsets[s + 1]
        nb = b1 - b0
        if nb == 0:
            continue
        n_tl, n_blk, n_mblk, n_cand, tl, blk, mblk, cand, cand_f, WF, WI = _traverse_grown(
            keys, slots, cells, ranges[b0:b1], valid[b0:b1], angle_min[s], angle_inc[s], boxes[s], r_abs, r_rel,
            r_alpha, eps, exact, lg, T, new, tl, blk, mblk, cand, cand_f, st, WF, WI, fill)
        n_new = 0
        n_old = 0
        rmax = -INF
        for i in range(nb):
            cnt_new[i + 1] = cnt_new[i]
            cnt_valid[i + 1] = cnt_valid[i]
            if valid[b0 + i]:
                rmax = max(rmax, T[0, i, 1])
                cnt_valid[i + 1] += 1
                if new[i]:
                    new_idx[n_new] = i
                    n_new += 1
                    cnt_new[i + 1] += 1
                else:
                    is_old[b0 + i] = True
                    n_old += 1
        if write and n_tl > 0:
            keys, slots, cells, coords, n = apply(
                keys, slots, cells, coords, n, n_tl, tl, n_blk, blk, n_mblk, mblk, n_cand, cand,
                cand_f, new, valid[b0:b1], boxes[s], angle_min[s], angle_inc[s], r_alpha, eps, rmax,
                T, lg, cnt_new, cnt_valid, new_idx, st)
        scan_stats[s, 0] = st[0]
        scan_stats[s, 1] = st[1]
        scan_stats[s, 2] = st[3]
        scan_stats[s, 3] = n_new
        scan_stats[s, 4] = n_old
        scan_stats[s, 5] = st[2]
    return keys, slots, cells, coords, n


@njit(cache=True)
def scan_cells(ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps, exact, fill=True):
    """P_EMPTY^k and P_OBSTACLE^k of one scan as cell index arrays (for tests and plots):
    ``(empty_ix, empty_iy, obst_ix, obst_iy)`` (the cells of :func:`scan_cells_reference`,
    in another order)."""
    nb = ranges.shape[0]
    lg, T = _fast_buffers(max(nb, 1))
    new = np.zeros(max(nb, 1), dtype=np.bool_)
    keys = np.full(4, np.int64(-(2**63)), dtype=np.int64)
    slots = np.full(4, -1, dtype=np.int64)
    cells = np.zeros((1, TILE, TILE), dtype=np.uint8)
    tl, blk, mblk, cand, cand_f = _record_buffers()
    WF, WI = _level_buffers()
    st = np.zeros(4, dtype=np.int64)
    n_tl, n_blk, n_mblk, n_cand, tl, blk, mblk, cand, cand_f, WF, WI = _traverse_grown(
        keys, slots, cells, ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps, exact, lg, T, new, tl, blk,
        mblk, cand, cand_f, st, WF, WI, fill)
    ex = np.empty(st[1], dtype=np.int64)
    ey = np.empty(st[1], dtype=np.int64)
    _block_cells(blk, n_blk, ex, ey, 0)
    ox = np.empty(st[3], dtype=np.int64)
    oy = np.empty(st[3], dtype=np.int64)
    k = _block_cells(mblk, n_mblk, ox, oy, 0)
    for j in range(n_cand):
        ox[k] = cand[j, 0]
        oy[k] = cand[j, 1]
        k += 1
    return ex, ey, ox, oy


@njit(cache=True)
def _block_cells(rec, n_rec, ox, oy, k):
    """The cells of blocks ``rec[j] = (ix, iy, level, ...)`` (``j < n_rec``) into ``ox, oy`` from
    index ``k``; returns the next index."""
    for j in range(n_rec):
        s = 1 << rec[j, 2]
        for a in range(s):
            for b in range(s):
                ox[k] = rec[j, 0] + a
                oy[k] = rec[j, 1] + b
                k += 1
    return k
