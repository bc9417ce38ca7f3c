"""SIVIA on a regular grid: pave a set, level by level, down to the grid's cells.

The domain box is snapped outward to the grid; a quad-tree of aligned blocks of
``2^L x 2^L`` cells is refined one level per iteration (a Python loop over ~log2(extent/eps)
levels; every level is one batch through the classifier and numba kernels). A block is
dropped when its contraction is empty, kept whole (all its cells INNER) when proven inside,
else split into its four sub-blocks that meet its contracted box. At the cell level the
contracted box is stored; with ``sub > 0`` each boundary cell is cut into a ``2^sub x 2^sub``
sub-grid of pieces, each piece (∩ the cell's contracted box) is classified once more, and the
cell keeps as its parts the contracted pieces that may hold points (a piece proven inside is
kept whole); the cell is INNER if every piece is proven inside, dropped if none is left.

With ``refine > 0`` each boundary cell is instead refined as a separator paving (Codac's
``pave``) does: contracted by the classifier and by its complementary contraction, what lies
outside the latter is proven inside (kept as ``inner_parts``), the boundary box between the
two is bisected down to sides of ``eps / 2^refine``.

Guarantee: every point of ``set ∩ domain`` is in the outer approximation; every INNER cell
and every inner part is inside the set (as far as the classifier's guarantees go).
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
    prune_contained,
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
    """The ``4^depth`` pieces of each cell (tiling it exactly), which of them meet the cell's
    contracted ``box``, and ``piece ∩ box`` (what is classified: the set's points in the cell
    are all in ``box``)."""
    n = I.shape[0]
    m = 1 << depth
    sb = np.empty((n * m * m, 2, 2))
    inp = np.empty((n * m * m, 2, 2))
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
                inp[q, 0, 0] = max(xa, box[k, 0, 0])
                inp[q, 0, 1] = min(xb, box[k, 0, 1])
                inp[q, 1, 0] = max(ya, box[k, 1, 0])
                inp[q, 1, 1] = min(yb, box[k, 1, 1])
                meet[q] = inp[q, 0, 0] <= inp[q, 0, 1] and inp[q, 1, 0] <= inp[q, 1, 1]
                q += 1
    return sb, inp, meet


@njit(cache=True)
def _compact(parts, lo, hi, keep):
    """Drops the parts in ``lo..hi`` contained in another (duplicates: all but the first), moving
    the kept ones to the front; returns how many are kept. The union is unchanged. The parts'
    interiors are disjoint (pieces of distinct sub-cells or bisection halves), so only a
    segment or a point can lie in another."""
    prune_contained(parts, lo, hi, keep, True)
    w = lo
    for q in range(lo, hi):
        if keep[q]:
            parts[w] = parts[q]
            w += 1
    return w - lo


@njit(cache=True)
def _reduce_sub(n, per, sb, inp, out, inside, meet):
    """Per cell: its parts, the contracted pieces (a piece proven inside is kept whole); every
    piece proven inside -> INNER (one part, the cell); no piece left -> dropped (label 0).

    Returns ``(label (n,), box (n, 2, 2) hull of the parts, count (n,), parts (n * per, 2, 2))``
    with cell ``k``'s parts at ``parts[k * per : k * per + count[k]]``, none contained in another.
    """
    box = np.empty((n, 2, 2))
    label = np.zeros(n, np.uint8)  # 0 = dropped
    count = np.zeros(n, np.int64)
    parts = np.empty((n * per, 2, 2))
    keep = np.empty(n * per, np.bool_)
    for k in range(n):
        base = k * per
        all_in = True
        c = 0
        for q in range(base, base + per):
            if not meet[q]:
                all_in = False
                continue
            whole = (inp[q, 0, 0] == sb[q, 0, 0] and inp[q, 0, 1] == sb[q, 0, 1]
                     and inp[q, 1, 0] == sb[q, 1, 0] and inp[q, 1, 1] == sb[q, 1, 1])
            if not (inside[q] and whole):
                all_in = False
            if inside[q]:
                parts[base + c] = inp[q]
                c += 1
                continue
            xl = max(out[q, 0, 0], inp[q, 0, 0])
            xh = min(out[q, 0, 1], inp[q, 0, 1])
            yl = max(out[q, 1, 0], inp[q, 1, 0])
            yh = min(out[q, 1, 1], inp[q, 1, 1])
            if xl <= xh and yl <= yh:
                parts[base + c, 0, 0], parts[base + c, 0, 1] = xl, xh
                parts[base + c, 1, 0], parts[base + c, 1, 1] = yl, yh
                c += 1
        if all_in:
            label[k] = INNER
            parts[base, 0, 0], parts[base, 0, 1] = sb[base, 0, 0], sb[base + per - 1, 0, 1]
            parts[base, 1, 0], parts[base, 1, 1] = sb[base, 1, 0], sb[base + per - 1, 1, 1]
            c = 1
        elif c > 0:
            label[k] = BOUNDARY
            c = _compact(parts, base, base + c, keep)
        count[k] = c
        box[k, 0, 0] = np.inf
        box[k, 0, 1] = -np.inf
        box[k, 1, 0] = np.inf
        box[k, 1, 1] = -np.inf
        for q in range(base, base + c):
            for d in range(2):
                box[k, d, 0] = min(box[k, d, 0], parts[q, d, 0])
                box[k, d, 1] = max(box[k, d, 1], parts[q, d, 1])
    return label, box, count, parts


@njit(cache=True)
def _gather_parts(order, per, count, parts, n_inner, inner_box):
    """Flat ``(start, parts)`` of the sorted cells: ``order[r] < n_inner`` is inner cell
    ``order[r]`` (one part), else leaf ``order[r] - n_inner`` (its ``count`` parts)."""
    n = order.shape[0]
    start = np.empty(n + 1, np.int64)
    start[0] = 0
    for r in range(n):
        o = order[r]
        start[r + 1] = start[r] + (1 if o < n_inner else count[o - n_inner])
    out = np.empty((start[n], 2, 2))
    for r in range(n):
        o = order[r]
        if o < n_inner:
            out[start[r]] = inner_box[o]
        else:
            base = (o - n_inner) * per
            for c in range(count[o - n_inner]):
                out[start[r] + c] = parts[base + c]
    return start, out


@njit(cache=True)
def _separate(box, out, cin):
    """One separator step on each row: ``out`` (outer contraction of ``box``) and ``cin``
    (complementary contraction of ``out``) give the parts of ``out`` outside ``cin`` (proven
    inside the set: up to four strips, interiors disjoint) and the boundary box ``out ∩ cin``.

    Returns ``(strips (S, 2, 2), strip_row (S,), bnd (n, 2, 2), has_bnd (n,))``; rows whose
    ``out`` is empty give nothing.
    """
    n = box.shape[0]
    strips = np.empty((4 * n, 2, 2))
    row = np.empty(4 * n, np.int64)
    bnd = np.empty((n, 2, 2))
    has = np.zeros(n, np.bool_)
    s = 0
    for k in range(n):
        a = max(out[k, 0, 0], box[k, 0, 0])
        b = min(out[k, 0, 1], box[k, 0, 1])
        c = max(out[k, 1, 0], box[k, 1, 0])
        d = min(out[k, 1, 1], box[k, 1, 1])
        if not (a <= b) or not (c <= d):
            continue
        a2 = max(cin[k, 0, 0], a)
        b2 = min(cin[k, 0, 1], b)
        c2 = max(cin[k, 1, 0], c)
        d2 = min(cin[k, 1, 1], d)
        if not (a2 <= b2) or not (c2 <= d2):  # no point outside the set: all of out is inside
            strips[s, 0, 0], strips[s, 0, 1], strips[s, 1, 0], strips[s, 1, 1] = a, b, c, d
            row[s] = k
            s += 1
            continue
        if a < a2:
            strips[s, 0, 0], strips[s, 0, 1], strips[s, 1, 0], strips[s, 1, 1] = a, a2, c, d
            row[s] = k
            s += 1
        if b2 < b:
            strips[s, 0, 0], strips[s, 0, 1], strips[s, 1, 0], strips[s, 1, 1] = b2, b, c, d
            row[s] = k
            s += 1
        if c < c2:
            strips[s, 0, 0], strips[s, 0, 1], strips[s, 1, 0], strips[s, 1, 1] = a2, b2, c, c2
            row[s] = k
            s += 1
        if d2 < d:
            strips[s, 0, 0], strips[s, 0, 1], strips[s, 1, 0], strips[s, 1, 1] = a2, b2, d2, d
            row[s] = k
            s += 1
        bnd[k, 0, 0], bnd[k, 0, 1], bnd[k, 1, 0], bnd[k, 1, 1] = a2, b2, c2, d2
        has[k] = True
    return strips[:s], row[:s], bnd, has


@njit(cache=True)
def _bisect(b):
    """Each box cut in two at the middle of its wider side (the halves share the cut line)."""
    n = b.shape[0]
    out = np.empty((2 * n, 2, 2))
    for k in range(n):
        d = 0 if b[k, 0, 1] - b[k, 0, 0] >= b[k, 1, 1] - b[k, 1, 0] else 1
        m = 0.5 * (b[k, d, 0] + b[k, d, 1])
        out[2 * k] = b[k]
        out[2 * k + 1] = b[k]
        out[2 * k, d, 1] = m
        out[2 * k + 1, d, 0] = m
    return out


@njit(cache=True)
def _pack(cell, parts, n):
    """Parts grouped by cell (``cell`` sorted), those contained in another dropped: ``(count (n,),
    per, padded (n * per, 2, 2), hull (n, 2, 2))`` in the layout of :func:`_reduce_sub`."""
    count = np.zeros(n, np.int64)
    for q in range(cell.shape[0]):
        count[cell[q]] += 1
    per = 1
    for k in range(n):
        per = max(per, count[k])
    padded = np.empty((n * per, 2, 2))
    box = np.empty((n, 2, 2))
    box[:, :, 0] = np.inf
    box[:, :, 1] = -np.inf
    fill = np.zeros(n, np.int64)
    for q in range(cell.shape[0]):
        k = cell[q]
        padded[k * per + fill[k]] = parts[q]
        fill[k] += 1
        for d in range(2):
            box[k, d, 0] = min(box[k, d, 0], parts[q, d, 0])
            box[k, d, 1] = max(box[k, d, 1], parts[q, d, 1])
    keep = np.empty(n * per, np.bool_)
    for k in range(n):
        if count[k] > 1:
            count[k] = _compact(padded, k * per, k * per + count[k], keep)
    return count, per, padded, box


def _refine(classify, leaf_box, depth: int, h: float, max_cells: int):
    """Separator-style refinement of the boundary cells (as Codac's ``pave`` does with a
    separator, inside each cell): a box is contracted by the classifier (outer) and by its
    complement; what lies outside the complementary contraction is kept as inner strips, the
    boundary box left between the two is bisected until both its sides are at most
    ``h / 2^depth``. Returns per cell ``(count, per, parts, hull)`` of its outer parts (inner
    strips and boundary boxes) and the inner strips ``(K, 2, 2)``."""
    from ivslam_cli.paving.classifiers import complement

    n = leaf_box.shape[0]
    stop = h / (1 << depth)
    boxes = leaf_box
    cell = np.arange(n, dtype=np.int64)
    outer, outer_cell, inner = [], [], []
    while boxes.shape[0] > 0:
        if boxes.shape[0] > max_cells:
            raise PavingLimitError(f"refinement needs more than max_cells={max_cells} boxes")
        out, _ = classify(boxes)
        cin = complement(classify, np.ascontiguousarray(out))
        strips, srow, bnd, has = _separate(boxes, out, cin)
        inner.append(strips)
        outer.append(strips)
        outer_cell.append(cell[srow])
        bnd = bnd[has]
        bcell = cell[has]
        w = np.maximum(bnd[:, 0, 1] - bnd[:, 0, 0], bnd[:, 1, 1] - bnd[:, 1, 0])
        done = w <= stop
        outer.append(bnd[done])
        outer_cell.append(bcell[done])
        boxes = _bisect(np.ascontiguousarray(bnd[~done]))
        cell = np.repeat(bcell[~done], 2)
    parts = np.concatenate(outer)
    pc = np.concatenate(outer_cell)
    order = np.argsort(pc, kind="stable")
    count, per, padded, hull = _pack(pc[order], parts[order], n)
    return count, per, padded, hull, np.concatenate(inner)


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


def pave(classify, domain, eps: float, *, origin=(0.0, 0.0), sub: int = 0, refine: int = 0,
         max_cells: int = DEFAULT_MAX_CELLS) -> GridPaving:
    """Pave ``set ∩ domain`` on the grid of resolution ``eps`` anchored at ``origin``.

    ``classify`` is a classifier (see :mod:`ivslam_cli.paving.classifiers`); ``domain`` a box
    ``[[xl, xh], [yl, yh]]``, snapped outward to the grid. ``sub > 0`` cuts each boundary cell
    into ``2^sub x 2^sub`` pieces and keeps their contractions as the cell's parts (cost and
    storage ~4^sub per boundary cell; the cell's ``box`` is their hull, never larger than
    with ``sub = 0``; the inner approximation may gain cells, never loses any).
    ``refine > 0`` (instead of ``sub``) refines each boundary cell as a separator paving does:
    the parts outside the classifier's complementary contraction are proven inside and kept
    as the paving's ``inner_parts`` (and as outer parts), the boundary boxes between the two
    contractions are bisected down to sides of ``eps / 2^refine`` (cost ~2^refine per
    boundary cell: the boundary is a curve). Raises
    :class:`PavingLimitError` beyond ``max_cells`` cells (blocks of a level, or stored cells).

    Returns a :class:`GridPaving` whose outer approximation holds every point of
    ``set ∩ domain`` and whose INNER cells are inside the set.
    """
    ensure_round_to_nearest()
    if sub < 0 or sub > 8:
        raise ValueError(f"sub must be in 0..8, got {sub}")
    if refine < 0 or refine > 16:
        raise ValueError(f"refine must be in 0..16, got {refine}")
    if refine and sub:
        raise ValueError("give sub or refine, not both")
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
    inner_box = _inner_cells(inner_keys, ox, oy, h)
    leaf_label = np.full(leaf_I.shape[0], BOUNDARY, np.uint8)
    per = 1
    count = np.ones(leaf_I.shape[0], np.int64)
    leaf_parts = leaf_box
    if sub > 0 and leaf_I.shape[0] > 0:
        per = 1 << (2 * sub)
        sb, inp, meet = _sub_boxes(leaf_I, leaf_J, leaf_box, sub, ox, oy, h)
        out = np.empty_like(sb)
        out[:, :, 0] = np.inf
        out[:, :, 1] = -np.inf
        inside = np.zeros(sb.shape[0], np.bool_)
        idx = np.flatnonzero(meet)
        o, ins = classify(inp[idx])
        out[idx] = o
        inside[idx] = ins
        leaf_label, leaf_box, count, leaf_parts = _reduce_sub(leaf_I.shape[0], per, sb, inp, out,
                                                              inside, meet)
        keep = np.flatnonzero(leaf_label != 0)
        leaf_I, leaf_J, leaf_box, leaf_label, count = (leaf_I[keep], leaf_J[keep], leaf_box[keep],
                                                       leaf_label[keep], count[keep])
        leaf_parts = leaf_parts.reshape(-1, per, 2, 2)[keep].reshape(-1, 2, 2)
    inner_parts = None
    if refine > 0 and leaf_I.shape[0] > 0:
        count, per, leaf_parts, leaf_box, inner_parts = _refine(classify, leaf_box, refine, h,
                                                                 max_cells)
        keep = np.flatnonzero(count > 0)
        leaf_I, leaf_J, leaf_box, count = leaf_I[keep], leaf_J[keep], leaf_box[keep], count[keep]
        leaf_label = np.full(leaf_I.shape[0], BOUNDARY, np.uint8)
        leaf_parts = leaf_parts.reshape(-1, per, 2, 2)[keep].reshape(-1, 2, 2)
    keys = np.concatenate([inner_keys, _leaf_keys(leaf_I, leaf_J)])
    if keys.shape[0] == 0:
        return empty_paving(grid)
    label = np.concatenate([np.full(inner_keys.shape[0], INNER, np.uint8), leaf_label])
    box = np.concatenate([inner_box, leaf_box])
    order = np.argsort(keys, kind="stable")
    start, parts = _gather_parts(order, per, count, leaf_parts, inner_keys.shape[0], inner_box)
    return GridPaving(grid, keys[order], label[order], box[order], parts, start,
                      inner_parts=inner_parts)
