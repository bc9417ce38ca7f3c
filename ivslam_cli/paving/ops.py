"""Set operations on pavings of the same grid, cell by cell (numba kernels).

Each docstring says what the result approximates. "Outer" means: every point of the exact
result set is in the result's outer approximation (union of boxes). "Inner" means: every
INNER cell of the result is inside the exact result set. Exact sets are those the operands
describe; operands are themselves outer/inner approximations, so e.g. the outer approximation
of ``A ∩ B`` holds every point of ``A_true ∩ B_true``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.paving.grid import (
    BOUNDARY,
    INNER,
    MAX_INDEX,
    Grid,
    GridPaving,
    PavingLimitError,
    cell_key,
    key_i,
    key_j,
    cell_of,
    prune_contained,
    coord,
    empty_paving,
)
from ivslam_cli.paving.sivia import DEFAULT_MAX_CELLS



MAX_PARTS = 256  # an operation's result cell with more parts keeps only their hull (sound)


# ----------------------------------------------------------------- kernels
@njit(cache=True)
def _set_hull(out, r, parts, lo, hi):
    """``out[r]`` = hull of ``parts[lo:hi]``."""
    out[r, 0, 0] = np.inf
    out[r, 0, 1] = -np.inf
    out[r, 1, 0] = np.inf
    out[r, 1, 1] = -np.inf
    for q in range(lo, hi):
        for d in range(2):
            out[r, d, 0] = min(out[r, d, 0], parts[q, d, 0])
            out[r, d, 1] = max(out[r, d, 1], parts[q, d, 1])


@njit(cache=True)
def _meet(P, p, Q, q):
    """``P[p] ∩ Q[q]`` as ``(xl, xh, yl, yh, non-empty)``."""
    xl = max(P[p, 0, 0], Q[q, 0, 0])
    xh = min(P[p, 0, 1], Q[q, 0, 1])
    yl = max(P[p, 1, 0], Q[q, 1, 0])
    yh = min(P[p, 1, 1], Q[q, 1, 1])
    return xl, xh, yl, yh, (xl <= xh and yl <= yh)


@njit(cache=True)
def _intersect(kA, lA, sA, pA, kB, lB, sB, pB):
    """Cells of both operands, each with the non-empty pairwise intersections of their parts
    (cells with none are dropped), INNER if INNER in both: rows for :func:`_reduce`."""
    # pass 1: matched cells and their part counts (exact, so memory is what is kept)
    n = min(kA.shape[0], kB.shape[0])
    ia = np.empty(n, np.int64)
    ib = np.empty(n, np.int64)
    cnt = np.empty(n, np.int64)
    m = 0
    a = 0
    b = 0
    while a < kA.shape[0] and b < kB.shape[0]:
        if kA[a] < kB[b]:
            a += 1
        elif kB[b] < kA[a]:
            b += 1
        else:
            c = 0
            for p in range(sA[a], sA[a + 1]):
                for q in range(sB[b], sB[b + 1]):
                    if _meet(pA, p, pB, q)[4]:
                        c += 1
            if c > 0:
                ia[m] = a
                ib[m] = b
                cnt[m] = c
                m += 1
            a += 1
            b += 1
    keys = np.empty(m, np.int64)
    label = np.empty(m, np.uint8)
    start = np.empty(m + 1, np.int64)
    start[0] = 0
    for r in range(m):
        start[r + 1] = start[r] + cnt[r]
    parts = np.empty((start[m], 2, 2))
    for r in range(m):
        a = ia[r]
        b = ib[r]
        keys[r] = kA[a]
        label[r] = INNER if (lA[a] == INNER and lB[b] == INNER) else BOUNDARY
        w = start[r]
        for p in range(sA[a], sA[a + 1]):
            for q in range(sB[b], sB[b + 1]):
                xl, xh, yl, yh, ok = _meet(pA, p, pB, q)
                if ok:
                    parts[w, 0, 0], parts[w, 0, 1], parts[w, 1, 0], parts[w, 1, 1] = xl, xh, yl, yh
                    w += 1
    return keys, label, start, parts


@njit(cache=True)
def _reduce(keys, label, start, parts, ox, oy, h, max_parts):
    """Merge rows with equal keys (``keys`` sorted; row ``r``'s parts ``parts[start[r]:start[r+1]]``):
    INNER wins (one part: the cell), else the parts are pooled, dropping those contained in
    another (over ``max_parts`` left: their hull)."""
    n = keys.shape[0]
    # pass 1: output cells, their first row, label and part count
    first = np.empty(n + 1, np.int64)
    ol = np.empty(n, np.uint8)
    m = -1
    for r in range(n):
        if m < 0 or keys[r] != keys[first[m]]:
            m += 1
            first[m] = r
            ol[m] = BOUNDARY
        if label[r] == INNER:
            ol[m] = INNER
    m += 1
    first[m] = n
    keep = np.zeros(parts.shape[0], np.bool_)
    ok = np.empty(m, np.int64)
    ostart = np.empty(m + 1, np.int64)
    ostart[0] = 0
    for c in range(m):
        ok[c] = keys[first[c]]
        lo = start[first[c]]
        hi = start[first[c + 1]]
        cnt = 1
        if ol[c] != INNER:
            prune_contained(parts, lo, hi, keep)
            cnt = 0
            for q in range(lo, hi):
                cnt += keep[q]
            if cnt > max_parts:
                cnt = 1
        ostart[c + 1] = ostart[c] + cnt
    op = np.empty((ostart[m], 2, 2))
    ob = np.empty((m, 2, 2))
    for c in range(m):
        lo = start[first[c]]
        hi = start[first[c + 1]]
        w = ostart[c]
        if ol[c] == INNER:
            i = key_i(ok[c])
            j = key_j(ok[c])
            op[w, 0, 0], op[w, 0, 1] = coord(ox, i, h), coord(ox, i + 1, h)
            op[w, 1, 0], op[w, 1, 1] = coord(oy, j, h), coord(oy, j + 1, h)
        elif ostart[c + 1] - w == 1:
            _set_hull(op, w, parts, lo, hi)
        else:
            for q in range(lo, hi):
                if keep[q]:
                    op[w] = parts[q]
                    w += 1
        _set_hull(ob, c, op, ostart[c], ostart[c + 1])
    return ok, ol[:m].copy(), ob, op, ostart


@njit(cache=True)
def _permute(order, start, parts):
    """Rows in the order ``order`` with their parts: ``(new start, new parts)``."""
    n = order.shape[0]
    ns = np.empty(n + 1, np.int64)
    ns[0] = 0
    for r in range(n):
        ns[r + 1] = ns[r] + start[order[r] + 1] - start[order[r]]
    np_ = np.empty((ns[n], 2, 2))
    for r in range(n):
        w = ns[r]
        for q in range(start[order[r]], start[order[r] + 1]):
            np_[w] = parts[q]
            w += 1
    return ns, np_


@njit(cache=True)
def _make_inner(keys, label, start, parts, mask, ox, oy, h):
    """Cells where ``mask`` is set become INNER, their parts replaced by the cell."""
    n = keys.shape[0]
    ns = np.empty(n + 1, np.int64)
    ns[0] = 0
    for r in range(n):
        ns[r + 1] = ns[r] + (1 if mask[r] else start[r + 1] - start[r])
    op = np.empty((ns[n], 2, 2))
    ob = np.empty((n, 2, 2))
    ol = label.copy()
    for r in range(n):
        w = ns[r]
        if mask[r]:
            ol[r] = INNER
            i = key_i(keys[r])
            j = key_j(keys[r])
            op[w, 0, 0], op[w, 0, 1] = coord(ox, i, h), coord(ox, i + 1, h)
            op[w, 1, 0], op[w, 1, 1] = coord(oy, j, h), coord(oy, j + 1, h)
        else:
            for q in range(start[r], start[r + 1]):
                op[w] = parts[q]
                w += 1
        _set_hull(ob, r, op, ns[r], ns[r + 1])
    return ol, ob, op, ns


@njit(cache=True)
def _span(o, h, lo, hi):
    """Every cell ``a..b`` whose closed interval meets ``[lo, hi]`` (``b < a``: none indexable)."""
    lim = float(MAX_INDEX - 2) * h
    if not (lo <= hi) or lo - o < -lim or hi - o > lim:
        return np.int64(1), np.int64(0)
    return cell_of(o, h, lo)[0], cell_of(o, h, hi)[1]


@njit(cache=True)
def _cover(o, h, lo, hi):
    """The fewest cells ``a..b`` covering ``[lo, hi]`` (no cell touching it only at an edge)."""
    lim = float(MAX_INDEX - 2) * h
    if not (lo <= hi) or lo - o < -lim or hi - o > lim:
        return np.int64(1), np.int64(0)
    a = cell_of(o, h, lo)[1]
    return a, max(a, cell_of(o, h, hi)[0])


@njit(cache=True)
def _spread(boxes, ox, oy, h, limit):
    """Each box cut by the grid: ``(key, box ∩ cell)`` for every cell it meets (BOUNDARY)."""
    total = 0
    for r in range(boxes.shape[0]):
        a, b = _cover(ox, h, boxes[r, 0, 0], boxes[r, 0, 1])
        c, d = _cover(oy, h, boxes[r, 1, 0], boxes[r, 1, 1])
        if b >= a and d >= c:
            total += (b - a + 1) * (d - c + 1)
    if total > limit:
        return np.empty(0, np.int64), np.empty((0, 2, 2)), total
    keys = np.empty(total, np.int64)
    out = np.empty((total, 2, 2))
    m = 0
    for r in range(boxes.shape[0]):
        a, b = _cover(ox, h, boxes[r, 0, 0], boxes[r, 0, 1])
        c, d = _cover(oy, h, boxes[r, 1, 0], boxes[r, 1, 1])
        for i in range(a, b + 1):
            xl = max(boxes[r, 0, 0], coord(ox, i, h))
            xh = min(boxes[r, 0, 1], coord(ox, i + 1, h))
            for j in range(c, d + 1):
                yl = max(boxes[r, 1, 0], coord(oy, j, h))
                yh = min(boxes[r, 1, 1], coord(oy, j + 1, h))
                if xl <= xh and yl <= yh:
                    keys[m] = cell_key(i, j)
                    out[m, 0, 0], out[m, 0, 1], out[m, 1, 0], out[m, 1, 1] = xl, xh, yl, yh
                    m += 1
    return keys[:m], out[:m], total


@njit(cache=True)
def _find(keys, k):
    p = np.searchsorted(keys, k)
    return p if (p < keys.shape[0] and keys[p] == k) else -1


@njit(cache=True)
def _contains(keys, label, start, parts, ox, oy, h, pts):
    n = pts.shape[0]
    outer = np.zeros(n, np.bool_)
    inner = np.zeros(n, np.bool_)
    for r in range(n):
        x, y = pts[r, 0], pts[r, 1]
        a, b = _span(ox, h, x, x)
        c, d = _span(oy, h, y, y)
        for i in range(a, b + 1):
            for j in range(c, d + 1):
                p = _find(keys, cell_key(i, j))
                if p < 0:
                    continue
                for q in range(start[p], start[p + 1]):
                    if (parts[q, 0, 0] <= x <= parts[q, 0, 1]
                            and parts[q, 1, 0] <= y <= parts[q, 1, 1]):
                        outer[r] = True
                if label[p] == INNER:
                    inner[r] = True
    return outer, inner


@njit(cache=True)
def _add_down(a, b):
    """The largest float <= a + b (exact real sum), via Knuth's TwoSum error term."""
    s = a + b
    bb = s - a
    e = (a - (s - bb)) + (b - bb)  # a + b = s + e exactly (finite s)
    if s != s:
        return -np.inf
    if s == np.inf:  # overflow of a finite sum: the largest float is below it
        return s if (a == np.inf or b == np.inf) else np.finfo(np.float64).max
    if s == -np.inf:
        return s
    return s if e >= 0.0 else np.nextafter(s, -np.inf)


@njit(cache=True)
def _add_up(a, b):
    """The smallest float >= a + b."""
    return -_add_down(-a, -b)


@njit(cache=True)
def _affine_boxes(box, sign, tl_x, th_x, tl_y, th_y):
    """``sign * b + [t]`` for every box, rounded outward."""
    n = box.shape[0]
    out = np.empty((n, 2, 2))
    for r in range(n):
        for d in range(2):
            tl = tl_x if d == 0 else tl_y
            th = th_x if d == 0 else th_y
            lo = box[r, d, 0] if sign > 0 else -box[r, d, 1]
            hi = box[r, d, 1] if sign > 0 else -box[r, d, 0]
            out[r, d, 0] = _add_down(lo, tl)
            out[r, d, 1] = _add_up(hi, th)
    return out


@njit(cache=True)
def _inner_affine(keys, src_keys, src_label, ox, oy, h, sign, t0x, t0y):
    """Cells ``g`` with ``g ⊂ sign * (inner cells of the source) + t0``: the outward box
    ``sign * (g - t0)`` must only meet INNER source cells."""
    n = keys.shape[0]
    res = np.zeros(n, np.bool_)
    for r in range(n):
        i = key_i(keys[r])
        j = key_j(keys[r])
        gl = _add_down(coord(ox, i, h), -t0x)
        gh = _add_up(coord(ox, i + 1, h), -t0x)
        ql = _add_down(coord(oy, j, h), -t0y)
        qh = _add_up(coord(oy, j + 1, h), -t0y)
        if sign < 0:
            gl, gh = -gh, -gl
            ql, qh = -qh, -ql
        a, b = _cover(ox, h, gl, gh)
        c, d = _cover(oy, h, ql, qh)
        if b < a or d < c:
            continue
        ok = True
        for si in range(a, b + 1):
            for sj in range(c, d + 1):
                p = _find(src_keys, cell_key(si, sj))
                if p < 0 or src_label[p] != INNER:
                    ok = False
                    break
            if not ok:
                break
        res[r] = ok
    return res


# ----------------------------------------------------------------- Python API
def _sorted(grid: Grid, keys, label, start, parts) -> GridPaving:
    """Rows ``(key, label, parts[start[r]:start[r+1]])`` in any order -> a paving (rows with
    equal keys merged by :func:`_reduce`)."""
    if keys.shape[0] == 0:
        return empty_paving(grid)
    order = np.argsort(keys, kind="stable")
    st, pt = _permute(order, start, parts)
    k, l, b, p, s = _reduce(keys[order], label[order], st, pt, grid.ox, grid.oy, grid.eps,
                            MAX_PARTS)
    return GridPaving(grid, k, l, b, p, s)


def intersection(a: GridPaving, b: GridPaving) -> GridPaving:
    """``A ∩ B``: outer (parts intersected pairwise, cell by cell) and inner (INNER ∩ INNER).

    Intersections contained in another are dropped; a cell with more than ``MAX_PARTS`` left
    keeps their hull."""
    a.same_grid(b)
    k, l, s, p = _intersect(a.key, a.label, a.start, a.parts, b.key, b.label, b.start, b.parts)
    if k.shape[0] == 0:
        return empty_paving(a.grid)
    g = a.grid
    k, l, bx, p, s = _reduce(k, l, s, p, g.ox, g.oy, g.eps, MAX_PARTS)
    return GridPaving(g, k, l, bx, p, s)


def union(a: GridPaving, b: GridPaving) -> GridPaving:
    """``A ∪ B``: outer (parts pooled cell by cell) and inner (INNER ∪ INNER).

    Parts contained in another are dropped; a cell with more than ``MAX_PARTS`` left keeps
    their hull."""
    a.same_grid(b)
    return _sorted(a.grid, np.concatenate([a.key, b.key]), np.concatenate([a.label, b.label]),
                   np.concatenate([a.start[:-1], b.start + a.start[-1]]),
                   np.concatenate([a.parts, b.parts]))


def from_boxes(grid: Grid, boxes, *, max_cells: int = DEFAULT_MAX_CELLS) -> GridPaving:
    """The union of arbitrary boxes ``(B, 2, 2)`` on ``grid``: an outer approximation
    (every cell a box meets, with the parts box ∩ cell; over ``MAX_PARTS`` in a cell: their
    hull); no INNER cells."""
    boxes = np.ascontiguousarray(boxes, dtype=np.float64).reshape(-1, 2, 2)
    keys, out, total = _spread(boxes, grid.ox, grid.oy, grid.eps, max_cells)
    if total > max_cells:
        raise PavingLimitError(f"boxes cover {total} cells > max_cells={max_cells}")
    return _sorted(grid, keys, np.full(keys.shape[0], BOUNDARY, np.uint8),
                   np.arange(keys.shape[0] + 1, dtype=np.int64), out)


def affine(s: GridPaving, sign: int, t, *, max_cells: int = DEFAULT_MAX_CELLS) -> GridPaving:
    """``{sign * p + t : p in S, t in [t]}`` for ``sign`` in {+1, -1} and a box ``[t]``
    ``[[txl, txh], [tyl, tyh]]`` (a point is a degenerate box), on the same grid.

    Outer: each part of S mapped with outward rounding, then cut by the grid. Inner: a cell is
    INNER when its preimage under ``p -> sign * p + t0`` (``t0`` the lower corner of [t]),
    rounded outward, only meets INNER cells of S (so the cell is in ``sign * inner(S) + t0``).
    """
    if sign not in (1, -1):
        raise ValueError(f"sign must be +1 or -1, got {sign}")
    t = np.asarray(t, dtype=np.float64)
    if t.shape == (2,):
        t = np.stack([t, t], axis=-1)
    t = t.reshape(2, 2)
    if not (t[0, 0] <= t[0, 1] and t[1, 0] <= t[1, 1]):
        raise ValueError(f"t must be a non-empty box, got {t.tolist()}")
    if len(s) == 0:
        return empty_paving(s.grid)
    moved = _affine_boxes(s.parts, sign, t[0, 0], t[0, 1], t[1, 0], t[1, 1])
    out = from_boxes(s.grid, moved, max_cells=max_cells)
    g = s.grid
    inner = _inner_affine(out.key, s.key, s.label, g.ox, g.oy, g.eps, sign, t[0, 0], t[1, 0])
    label, box, parts, start = _make_inner(out.key, out.label, out.start, out.parts, inner,
                                           g.ox, g.oy, g.eps)
    return GridPaving(g, out.key, label, box, parts, start)


def translate(s: GridPaving, t, **kw) -> GridPaving:
    """``S + [t]`` (outer and inner, see :func:`affine`)."""
    return affine(s, 1, t, **kw)


def negate(s: GridPaving, **kw) -> GridPaving:
    """``-S`` (outer and inner, see :func:`affine`)."""
    return affine(s, -1, np.zeros(2), **kw)


def minkowski_sub(m, s: GridPaving, **kw) -> GridPaving:
    """``[m] - S = {m - p : m in [m], p in S}``: ``m_j = m_i - S_dl`` (Mustafa et al., Eq. (6)).

    ``m`` is a point ``(x, y)`` or a box ``[[xl, xh], [yl, yh]]``. Outer and inner
    (see :func:`affine`).
    """
    return affine(s, -1, m, **kw)


def contains_points(s: GridPaving, points) -> tuple[np.ndarray, np.ndarray]:
    """For points ``(n, 2)``: ``(in_outer, in_inner)``. A point outside the outer
    approximation is proven outside the set; a point in the inner one is proven inside."""
    pts = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 2)
    g = s.grid
    return _contains(s.key, s.label, s.start, s.parts, g.ox, g.oy, g.eps, pts)
