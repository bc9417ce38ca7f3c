"""P_EMPTY of a scan whose pose is known only to lie in a union of boxes.

The scan matcher keeps a scan's pose set as one box per heading slice (:mod:`.matcher`); the map
update (:mod:`.map_update`) takes one box, their hull. A cell is free of obstacles whatever the
pose in the union when it is free for every box of it:

    P_EMPTY^k(b_1 ∪ … ∪ b_m) = P_EMPTY^k(b_1) ∩ … ∩ P_EMPTY^k(b_m)  ⊇  P_EMPTY^k(hull),

each term the inner approximation of :mod:`.map_kernel` (so the intersection is inner too). A
slice's box is narrower than the hull in heading, and a cone's free space eroded by a heading
interval shrinks with it: the cells the slices all prove free beyond the hull's are what the set
keeps and the hull loses. P_OBSTACLE^k and the old/new test stay the hull's (outer, sound).

Computed as: the cells of ``P_EMPTY^k(b_1)`` (one traversal) not yet free in the map, each then
tested against ``b_2 … b_m`` by the reference's leaf test (:func:`~.map_blocks._cell`, code 1 =
proven free): the cells the map lacks are a thin band, so the other boxes cost little.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.paving.tiles import EMPTY, cell_flags
from ivslam_cli.slam.lidar.map_blocks import _cell, _scan_angles
from ivslam_cli.slam.lidar.map_kernel import scan_cells
from ivslam_cli.slam.lidar.map_tables import _cos_gap, _fast_buffers, _fast_tables


@njit(cache=True, nogil=True)
def union_empty(keys, slots, cells, ranges, valid, a0, inc, boxes, r_abs, r_rel, r_alpha, eps, fill, smin):
    """The cells of ``∩_i P_EMPTY^k(boxes[i])`` (sensor boxes ``(m, 6)``, ``m ≥ 1``) that the map
    (``keys, slots, cells``, only read) does not hold as EMPTY yet: ``(ix, iy)``. Each is in
    :func:`~.map_kernel.scan_cells`' P_EMPTY^k of ``boxes[0]`` and passes the leaf test of every
    other box (no cell nearer than ``smin`` to a box: see :func:`~.map_kernel.traverse`)."""
    nb = ranges.shape[0]
    ex, ey, _, _ = scan_cells(ranges, valid, a0, inc, boxes[0], r_abs, r_rel, r_alpha, eps, False, fill, smin, False)
    lg, T = _fast_buffers(max(nb, 1))
    st = np.zeros(4, dtype=np.int64)
    rmax = _fast_tables(ranges, valid, r_abs, r_rel, _cos_gap(r_alpha, inc, fill), T)
    h = max(r_alpha, 0.5 * inc)
    m = boxes.shape[0]
    ang = np.empty((m, 4))
    for i in range(m):
        ang[i, 0], ang[i, 1], ang[i, 2], ang[i, 3] = _scan_angles(boxes[i], a0, inc, h, nb)
    n = 0
    for j in range(ex.shape[0]):
        if cell_flags(keys, slots, cells, ex[j], ey[j]) & EMPTY:
            continue
        ok = True
        for i in range(1, m):
            code, _, _, r_lo, _ = _cell(ex[j], ey[j], eps, boxes[i], a0, inc, h, nb, rmax, ang[i, 0], ang[i, 1],
                                        ang[i, 2], T, lg, st)
            if code != 1 or r_lo < smin:
                ok = False
                break
        if ok:
            ex[n] = ex[j]
            ey[n] = ey[j]
            n += 1
    return ex[:n].copy(), ey[:n].copy()
