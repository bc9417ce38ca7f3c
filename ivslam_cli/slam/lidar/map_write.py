"""The writes of the fast path's LiDAR map update (:mod:`.map_kernel`), pass 2 of a scan.

The records of :func:`.map_kernel.traverse` become flags of the map, those the reference
(:func:`.map_reference.apply_reference`) writes, in the same tiles allocated in the same order:
EMPTY on the proven-empty blocks; on each cell of P_OBSTACLE^k, OBST_NEW / OBST_OLD for the new /
old valid beams of its window meeting its range interval. A block proven all-P_OBSTACLE^k is
written whole when its window decides the kinds (no new beam, only new ones, or no new one
meeting the block's range), else cell by cell.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.interval.rounding import down, up
from ivslam_cli.paving.tiles import EMPTY, OBST_NEW, OBST_OLD, TILE_MASK, add_tile
from ivslam_cli.slam.lidar.geometry import box_ranges, box_ranges_fin, dn, upf
from ivslam_cli.slam.lidar.map_blocks import _cell_window, _scan_angles


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
    mid, lo_edge, hi_edge, err = _scan_angles(box, a0, inc, h, nb)
    pxl, pxh, pyl, pyh = box[0], box[1], box[2], box[3]
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
