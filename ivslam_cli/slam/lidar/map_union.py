"""P_EMPTY of a scan whose pose is known only to lie in a union of boxes.

The scan matcher keeps a scan's pose set as one box per heading slice (:mod:`.matcher`); the map
update (:mod:`.map_update`) takes one box, their hull. A cell is free of obstacles whatever the
pose in the union when it is free for every box of it:

    P_EMPTY^k(b_1 ∪ … ∪ b_m) = P_EMPTY^k(b_1) ∩ … ∩ P_EMPTY^k(b_m)  ⊇  P_EMPTY^k(hull),

each term the inner approximation of :mod:`.map_kernel` (so the intersection is inner too). A
slice's box is narrower than the hull in heading, and a cone's free space eroded by a heading
interval shrinks with it: the cells the slices all prove free beyond the hull's are what the set
keeps and the hull loses. P_OBSTACLE^k and the old/new test stay the hull's (outer, sound).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.paving.tiles import TILE
from ivslam_cli.slam.lidar.map_kernel import _level_buffers, _record_buffers, _traverse_grown
from ivslam_cli.slam.lidar.map_tables import _block_cells, _fast_buffers

_LIM = 2**31


@njit(cache=True)
def _keys(ix, iy):
    """Sorted unique int64 keys ``ix·2^32 + iy`` of the cells (int32 range; others dropped)."""
    k = np.empty(ix.shape[0], dtype=np.int64)
    n = 0
    for j in range(ix.shape[0]):
        if -_LIM <= ix[j] < _LIM and -_LIM <= iy[j] < _LIM:
            k[n] = ix[j] * np.int64(2**32) + iy[j]
            n += 1
    return np.unique(k[:n])


@njit(cache=True)
def _meet(a, b):
    """Sorted keys in both sorted unique arrays."""
    out = np.empty(min(a.shape[0], b.shape[0]), dtype=np.int64)
    i = j = n = 0
    while i < a.shape[0] and j < b.shape[0]:
        if a[i] < b[j]:
            i += 1
        elif a[i] > b[j]:
            j += 1
        else:
            out[n] = a[i]
            n += 1
            i += 1
            j += 1
    return out[:n]


@njit(cache=True, nogil=True)
def union_empty(ranges, valid, a0, inc, boxes, r_abs, r_rel, r_alpha, eps, fill):
    """The cells of ``∩_i P_EMPTY^k(boxes[i])`` (sensor boxes ``(m, 6)``, ``m ≥ 1``) as
    ``(ix, iy)``, in increasing ``(ix, iy)`` order; each box's P_EMPTY^k is
    :func:`~.map_kernel.scan_cells`' (the buffers grown once, for every box)."""
    nb = ranges.shape[0]
    lg, T = _fast_buffers(max(nb, 1))
    new = np.zeros(max(nb, 1), dtype=np.bool_)
    keys = np.full(4, np.int64(-(2**63)), dtype=np.int64)
    slots = np.full(4, -1, dtype=np.int64)
    cells = np.zeros((1, TILE, TILE), dtype=np.uint8)
    tl, blk, mblk, cand, cand_f = _record_buffers()
    WF, WI = _level_buffers()
    st = np.zeros(4, dtype=np.int64)
    acc = np.empty(0, dtype=np.int64)
    for i in range(boxes.shape[0]):
        n_tl, n_blk, n_mblk, n_cand, tl, blk, mblk, cand, cand_f, WF, WI = _traverse_grown(
            keys, slots, cells, ranges, valid, a0, inc, boxes[i], r_abs, r_rel, r_alpha, eps, False, lg, T, new,
            tl, blk, mblk, cand, cand_f, st, WF, WI, fill)
        ex = np.empty(st[1], dtype=np.int64)
        ey = np.empty(st[1], dtype=np.int64)
        _block_cells(blk, n_blk, ex, ey, 0)
        k = _keys(ex, ey)
        acc = k if i == 0 else _meet(acc, k)
        if acc.shape[0] == 0:
            break
    iy = np.empty(acc.shape[0], dtype=np.int64)
    ix = np.empty(acc.shape[0], dtype=np.int64)
    for j in range(acc.shape[0]):
        r = (acc[j] + _LIM) % np.int64(2**32) - _LIM
        iy[j] = r
        ix[j] = (acc[j] - r) // np.int64(2**32)
    return ix, iy
