"""SIVIA on a regular grid: pave a set, level by level, down to the grid's cells.

The domain box is snapped outward to the grid; a quad-tree of aligned blocks of
``2^L x 2^L`` cells is refined one level per iteration (a Python loop over ~log2(extent/eps)
levels; every level is one batch through the classifier and numba kernels). A block is
dropped when its contraction is empty, kept whole (all its cells INNER) when proven inside,
else split into its four sub-blocks that meet its contracted box. At the cell level the
contracted box is stored; with ``sub > 0`` each boundary cell is bisected ``sub`` more times
and stores the hull of its contracted pieces (INNER if every piece is proven inside).

Guarantee: every point of ``set ∩ domain`` is in the outer approximation; every INNER cell
is inside the set (as far as the classifier's guarantees go).
"""

from __future__ import annotations

import math

import numpy as np

from ivslam_cli.interval.rounding import ensure_round_to_nearest
from numba import njit

from ivslam_cli.paving.grid import (
    BOUNDARY,
    INNER,
    Grid,
    GridPaving,
    PavingLimitError,
    cell_key,
    key_i,
    key_j,
    coord,
    empty_paving,
)

DEFAULT_MAX_CELLS = 20_000_000


@njit(cache=True)
def _node_boxes(I, J, size, ox, oy, h, ie, je):
    n = I.shape[0]
    b = np.empty((n, 2, 2))
    for k in range(n):
        b[k, 0, 0] = coord(ox, I[k], h)
        b[k, 0, 1] = coord(ox, min(I[k] + size, ie), h)
        b[k, 1, 0] = coord(oy, J[k], h)
        b[k, 1, 1] = coord(oy, min(J[k] + size, je), h)
    return b


@njit(cache=True)
def _split(I, J, size, out, inside, ie, je, ox, oy, h):
    """Sort the blocks of one level: children to refine, blocks proven inside, leaf cells."""
    n = I.shape[0]
    cI = np.empty(4 * n, np.int64)
    cJ = np.empty(4 * n, np.int64)
    iI = np.empty(n, np.int64)
    iJ = np.empty(n, np.int64)
    lI = np.empty(n, np.int64)
    lJ = np.empty(n, np.int64)
    lb = np.empty((n, 2, 2))
    nc = 0
    ni = 0
    nl = 0
    half = size // 2
    for k in range(n):
        oxl, oxh, oyl, oyh = out[k, 0, 0], out[k, 0, 1], out[k, 1, 0], out[k, 1, 1]
        if not (oxl <= oxh) or not (oyl <= oyh):
            continue
        if inside[k]:
            iI[ni] = I[k]
            iJ[ni] = J[k]
            ni += 1
            continue
        if size == 1:
            # the stored box: contraction ∩ cell (a classifier may return a slightly larger box)
            lI[nl] = I[k]
            lJ[nl] = J[k]
            lb[nl, 0, 0] = max(oxl, coord(ox, I[k], h))
            lb[nl, 0, 1] = min(oxh, coord(ox, I[k] + 1, h))
            lb[nl, 1, 0] = max(oyl, coord(oy, J[k], h))
            lb[nl, 1, 1] = min(oyh, coord(oy, J[k] + 1, h))
            if lb[nl, 0, 0] <= lb[nl, 0, 1] and lb[nl, 1, 0] <= lb[nl, 1, 1]:
                nl += 1
            continue
        for a in range(2):
            ci = I[k] + a * half
            if ci >= ie:
                continue
            if coord(ox, min(ci + half, ie), h) < oxl or coord(ox, ci, h) > oxh:
                continue
            for b in range(2):
                cj = J[k] + b * half
                if cj >= je:
                    continue
                if coord(oy, min(cj + half, je), h) < oyl or coord(oy, cj, h) > oyh:
                    continue
                cI[nc] = ci
                cJ[nc] = cj
                nc += 1
    return cI[:nc], cJ[:nc], iI[:ni], iJ[:ni], lI[:nl], lJ[:nl], lb[:nl]


@njit(cache=True)
def _count_cells(I, J, S, ie, je):
    total = 0
    for k in range(I.shape[0]):
        total += min(S[k], ie - I[k]) * min(S[k], je - J[k])
    return total


@njit(cache=True)
def _expand(I, J, S, ie, je, total):
    """Keys of every cell of the blocks ``(I, J, size S)`` clipped to the domain."""
    keys = np.empty(total, np.int64)
    m = 0
    for k in range(I.shape[0]):
        for i in range(I[k], min(I[k] + S[k], ie)):
            for j in range(J[k], min(J[k] + S[k], je)):
                keys[m] = cell_key(i, j)
                m += 1
    return keys


@njit(cache=True)
def _sub_boxes(I, J, box, depth, ox, oy, h):
    """The ``4^depth`` sub-boxes of each cell (tiling it exactly) and which meet its box."""
    n = I.shape[0]
    m = 1 << depth
    sb = np.empty((n * m * m, 2, 2))
    meet = np.empty(n * m * m, np.bool_)
    q = 0
    for k in range(n):
        x0 = coord(ox, I[k], h)
        x1 = coord(ox, I[k] + 1, h)
        y0 = coord(oy, J[k], h)
        y1 = coord(oy, J[k] + 1, h)
        for a in range(m):
            xa = x0 if a == 0 else x0 + (x1 - x0) * (a / m)
            xb = x1 if a == m - 1 else x0 + (x1 - x0) * ((a + 1) / m)
            for b in range(m):
                ya = y0 if b == 0 else y0 + (y1 - y0) * (b / m)
                yb = y1 if b == m - 1 else y0 + (y1 - y0) * ((b + 1) / m)
                sb[q, 0, 0], sb[q, 0, 1], sb[q, 1, 0], sb[q, 1, 1] = xa, xb, ya, yb
                meet[q] = not (xb < box[k, 0, 0] or xa > box[k, 0, 1]
                               or yb < box[k, 1, 0] or ya > box[k, 1, 1])
                q += 1
    return sb, meet


@njit(cache=True)
def _reduce_sub(n, per, sb, out, inside, meet):
    """Per cell: hull of the contracted pieces; all pieces inside -> INNER; none left -> dropped."""
    box = np.empty((n, 2, 2))
    label = np.zeros(n, np.uint8)  # 0 = dropped
    for k in range(n):
        xl = np.inf
        xh = -np.inf
        yl = np.inf
        yh = -np.inf
        all_in = True
        for q in range(k * per, (k + 1) * per):
            if not meet[q]:
                all_in = False
                continue
            if not inside[q]:
                all_in = False
            if out[q, 0, 0] <= out[q, 0, 1] and out[q, 1, 0] <= out[q, 1, 1]:
                xl = min(xl, max(out[q, 0, 0], sb[q, 0, 0]))
                xh = max(xh, min(out[q, 0, 1], sb[q, 0, 1]))
                yl = min(yl, max(out[q, 1, 0], sb[q, 1, 0]))
                yh = max(yh, min(out[q, 1, 1], sb[q, 1, 1]))
        if all_in:
            label[k] = INNER
            box[k, 0, 0], box[k, 0, 1] = sb[k * per, 0, 0], sb[(k + 1) * per - 1, 0, 1]
            box[k, 1, 0], box[k, 1, 1] = sb[k * per, 1, 0], sb[(k + 1) * per - 1, 1, 1]
        elif xl <= xh and yl <= yh:
            label[k] = BOUNDARY
            box[k, 0, 0], box[k, 0, 1], box[k, 1, 0], box[k, 1, 1] = xl, xh, yl, yh
    return box, label


@njit(cache=True)
def _inner_cells(keys, ox, oy, h):
    n = keys.shape[0]
    b = np.empty((n, 2, 2))
    for k in range(n):
        i = key_i(keys[k])
        j = key_j(keys[k])
        b[k, 0, 0] = coord(ox, i, h)
        b[k, 0, 1] = coord(ox, i + 1, h)
        b[k, 1, 0] = coord(oy, j, h)
        b[k, 1, 1] = coord(oy, j + 1, h)
    return b


@njit(cache=True)
def _leaf_keys(I, J):
    keys = np.empty(I.shape[0], np.int64)
    for k in range(I.shape[0]):
        keys[k] = cell_key(I[k], J[k])
    return keys


def pave(classify, domain, eps: float, *, origin=(0.0, 0.0), sub: int = 0,
         max_cells: int = DEFAULT_MAX_CELLS) -> GridPaving:
    """Pave ``set ∩ domain`` on the grid of resolution ``eps`` anchored at ``origin``.

    ``classify`` is a classifier (see :mod:`ivslam_cli.paving.classifiers`); ``domain`` a box
    ``[[xl, xh], [yl, yh]]``, snapped outward to the grid. ``sub`` extra bisections of the
    boundary cells tighten their boxes (cost ~4^sub per boundary cell). Raises
    :class:`PavingLimitError` beyond ``max_cells`` cells (blocks of a level, or stored cells).

    Returns a :class:`GridPaving` whose outer approximation holds every point of
    ``set ∩ domain`` and whose INNER cells are inside the set.
    """
    ensure_round_to_nearest()
    if sub < 0 or sub > 8:
        raise ValueError(f"sub must be in 0..8, got {sub}")
    grid = Grid(float(origin[0]), float(origin[1]), float(eps))
    d = np.asarray(domain, dtype=np.float64).reshape(2, 2)
    i0, i1 = grid.cell_range(d[0, 0], d[0, 1], 0)
    j0, j1 = grid.cell_range(d[1, 0], d[1, 1], 1)
    ie, je = i1 + 1, j1 + 1
    ox, oy, h = grid.ox, grid.oy, grid.eps
    size = 1 << max(0, math.ceil(math.log2(max(ie - i0, je - j0))))
    I = np.array([i0], np.int64)
    J = np.array([j0], np.int64)
    inner_I, inner_J, inner_S = [], [], []
    leaf_I = leaf_J = np.empty(0, np.int64)
    leaf_box = np.empty((0, 2, 2))
    while I.shape[0] > 0:
        if I.shape[0] > max_cells:
            raise PavingLimitError(f"paving needs more than max_cells={max_cells} blocks at one level")
        out, inside = classify(_node_boxes(I, J, size, ox, oy, h, ie, je))
        cI, cJ, iI, iJ, lI, lJ, lb = _split(I, J, size, out, inside, ie, je, ox, oy, h)
        inner_I.append(iI)
        inner_J.append(iJ)
        inner_S.append(np.full(iI.shape[0], size, np.int64))
        if size == 1:
            leaf_I, leaf_J, leaf_box = lI, lJ, lb
            break
        I, J = cI, cJ
        size //= 2
    iI = np.concatenate(inner_I)
    iJ = np.concatenate(inner_J)
    iS = np.concatenate(inner_S)
    total = int(_count_cells(iI, iJ, iS, ie, je))
    if total + leaf_I.shape[0] > max_cells:
        raise PavingLimitError(f"paving needs {total + leaf_I.shape[0]} cells > max_cells={max_cells}")
    inner_keys = _expand(iI, iJ, iS, ie, je, total)
    leaf_label = np.full(leaf_I.shape[0], BOUNDARY, np.uint8)
    if sub > 0 and leaf_I.shape[0] > 0:
        sb, meet = _sub_boxes(leaf_I, leaf_J, leaf_box, sub, ox, oy, h)
        out = np.empty_like(sb)
        out[:, :, 0] = np.inf
        out[:, :, 1] = -np.inf
        inside = np.zeros(sb.shape[0], np.bool_)
        idx = np.flatnonzero(meet)
        o, ins = classify(sb[idx])
        out[idx] = o
        inside[idx] = ins
        leaf_box, leaf_label = _reduce_sub(leaf_I.shape[0], 1 << (2 * sub), sb, out, inside, meet)
        keep = leaf_label != 0
        leaf_I, leaf_J, leaf_box, leaf_label = leaf_I[keep], leaf_J[keep], leaf_box[keep], leaf_label[keep]
    keys = np.concatenate([inner_keys, _leaf_keys(leaf_I, leaf_J)])
    if keys.shape[0] == 0:
        return empty_paving(grid)
    label = np.concatenate([np.full(inner_keys.shape[0], INNER, np.uint8), leaf_label])
    box = np.concatenate([_inner_cells(inner_keys, ox, oy, h), leaf_box])
    order = np.argsort(keys, kind="stable")
    return GridPaving(grid, keys[order], label[order], box[order])
