"""Kernels of the pairs pipeline (Mustafa, Codres & Stancu): displacement sets of landmark pairs.

At a step where landmarks i and j are both observed, with ranges ``rho_i, rho_j`` and
world-frame bearings ``beta_i, beta_j`` (bearing + heading, all intervals), the robot-to-
landmark vectors lie in annular sectors ``d_i ∈ A_i``, ``d_j ∈ A_j`` and the displacement
``dl = m_i − m_j = d_i − d_j`` lies in the *displacement set* ``S_t = A_i − A_j`` (Eq. 1–4).
The robot position cancels: nothing but the two observations and the heading is used.

A pair's subpaving is a list of boxes on the global grid of resolution ``eps`` (cell
``[a eps, (a+1) eps] x [b eps, (b+1) eps]``); each box is a union of whole cells or, once it
is a single cell, a box contracted inside its cell. Per box we count ``fails`` (sets proven
disjoint from it) and ``notin`` (sets it was not proven inside). With tolerance ``q`` the
q-relaxed intersection keeps a box while ``fails <= q`` and labels it inner when
``notin <= q``. A box is contracted by a set only when its ``fails`` already equals ``q``
(then every later set must hold its points).

Guarantee: if at most ``q`` of a pair's sets miss the true ``dl``, some kept box holds it.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_polar import polar_scalar
from ivslam_cli.interval.angles import arg_box
from ivslam_cli.interval.arith import add, cos, inter, mul, sin, sqr, sqrt, sub
from ivslam_cli.interval.rounding import INF, TWO_PI_HI, TWO_PI_LO, down, up

OUT = 0
BOUNDARY = 1
INSIDE = 2

# columns of a pair-observation row: rho_i lo/hi, beta_i lo/hi, rho_j lo/hi, beta_j lo/hi
N_OBS_COLS = 8
CSP_PASSES = 3


@njit(cache=True)
def sector_hull(rl, rh, bl, bh):
    """Bounding box of the annular sector ``{r (cos b, sin b)}`` (outer)."""
    cl, ch = cos(bl, bh)
    sl, sh = sin(bl, bh)
    xl, xh = mul(rl, rh, cl, ch)
    yl, yh = mul(rl, rh, sl, sh)
    return xl, xh, yl, yh


@njit(cache=True)
def _angle_inside(al, ah, bl, bh):
    """Is ``[a] ⊂ [b] + 2 k pi`` for some integer k? (False when unsure: an inner test)."""
    if not (al <= ah) or not (bl <= bh):
        return False
    if bh - bl >= TWO_PI_LO:
        return True
    k = float(math.floor((0.5 * (al + ah) - 0.5 * (bl + bh)) / (0.5 * (TWO_PI_LO + TWO_PI_HI)) + 0.5))
    for d in range(-1, 2):
        kk = k + d
        sl, sh = mul(kk, kk, TWO_PI_LO, TWO_PI_HI)
        lo_l, lo_h = add(bl, bl, sl, sh)  # encloses bl + 2 kk pi
        hi_l, hi_h = add(bh, bh, sl, sh)  # encloses bh + 2 kk pi
        if al >= lo_h and ah <= hi_l:
            return True
    return False


@njit(cache=True)
def box_inside_sector(xl, xh, yl, yh, rl, rh, bl, bh):
    """Is every point of the box in the sector ``rho ∈ [r], arg ∈ [b] mod 2 pi``? (sound inner test)."""
    ql, qh = add(*sqr(xl, xh), *sqr(yl, yh))
    nl, nh = sqrt(ql, qh)
    if not (nl >= rl and nh <= rh):
        return False
    al, ah = arg_box(xl, xh, yl, yh)
    if ah - al >= TWO_PI_LO:
        return False
    return _angle_inside(al, ah, bl, bh)


@njit(cache=True)
def _centre_point(rl, rh, bl, bh):
    """Enclosure of one real point of the sector: radius and angle at the (float) midpoints."""
    r = 0.5 * (rl + rh)
    b = 0.5 * (bl + bh)
    if not (rl <= r <= rh):
        r = rl
    if not (bl <= b <= bh):
        b = bl
    cl, ch = cos(b, b)
    sl, sh = sin(b, b)
    xl, xh = mul(r, r, cl, ch)
    yl, yh = mul(r, r, sl, sh)
    return xl, xh, yl, yh


@njit(cache=True)
def classify(xl, xh, yl, yh, obs, contract):
    """Classify the box ``[dl]`` against ``S = A_i − A_j``; optionally contract it.

    Returns ``(state, xl, xh, yl, yh)``: OUT (box ∩ S = ∅, proven), INSIDE (box ⊂ S, proven)
    or BOUNDARY; the box is contracted (outer: no point of S in the box is lost) only when
    ``contract`` is True.
    """
    ril, rih, bil, bih, rjl, rjh, bjl, bjh = (
        obs[0], obs[1], obs[2], obs[3], obs[4], obs[5], obs[6], obs[7],
    )
    # forward-backward on dl = d_i - d_j, d_i ∈ A_i, d_j ∈ A_j
    ixl, ixh, iyl, iyh = sector_hull(ril, rih, bil, bih)
    jxl, jxh, jyl, jyh = sector_hull(rjl, rjh, bjl, bjh)
    cxl, cxh, cyl, cyh = xl, xh, yl, yh
    for _ in range(CSP_PASSES):
        cxl, cxh = inter(cxl, cxh, *sub(ixl, ixh, jxl, jxh))
        cyl, cyh = inter(cyl, cyh, *sub(iyl, iyh, jyl, jyh))
        if not (cxl <= cxh) or not (cyl <= cyh):
            return OUT, xl, xh, yl, yh
        ixl, ixh = inter(ixl, ixh, *add(cxl, cxh, jxl, jxh))
        iyl, iyh = inter(iyl, iyh, *add(cyl, cyh, jyl, jyh))
        jxl, jxh = inter(jxl, jxh, *sub(ixl, ixh, cxl, cxh))
        jyl, jyh = inter(jyl, jyh, *sub(iyl, iyh, cyl, cyh))
        r = polar_scalar(ixl, ixh, iyl, iyh, ril, rih, bil, bih)
        ixl, ixh, iyl, iyh = r[0], r[1], r[2], r[3]
        r = polar_scalar(jxl, jxh, jyl, jyh, rjl, rjh, bjl, bjh)
        jxl, jxh, jyl, jyh = r[0], r[1], r[2], r[3]
        if not (ixl <= ixh) or not (jxl <= jxh):
            return OUT, xl, xh, yl, yh
    cxl, cxh = inter(cxl, cxh, *sub(ixl, ixh, jxl, jxh))
    cyl, cyh = inter(cyl, cyh, *sub(iyl, iyh, jyl, jyh))
    if not (cxl <= cxh) or not (cyl <= cyh):
        return OUT, xl, xh, yl, yh
    # inner tests: box + p_j ⊂ A_i for a point p_j of A_j, or p_i − box ⊂ A_j
    pxl, pxh, pyl, pyh = _centre_point(rjl, rjh, bjl, bjh)
    sxl, sxh = add(xl, xh, pxl, pxh)
    syl, syh = add(yl, yh, pyl, pyh)
    inside = box_inside_sector(sxl, sxh, syl, syh, ril, rih, bil, bih)
    if not inside:
        pxl, pxh, pyl, pyh = _centre_point(ril, rih, bil, bih)
        sxl, sxh = sub(pxl, pxh, xl, xh)
        syl, syh = sub(pyl, pyh, yl, yh)
        inside = box_inside_sector(sxl, sxh, syl, syh, rjl, rjh, bjl, bjh)
    if inside:
        return INSIDE, xl, xh, yl, yh
    if contract:
        return BOUNDARY, cxl, cxh, cyl, cyh
    return BOUNDARY, xl, xh, yl, yh


@njit(cache=True)
def set_hull(obs):
    """Bounding box of ``S = A_i − A_j`` (outer)."""
    ixl, ixh, iyl, iyh = sector_hull(obs[0], obs[1], obs[2], obs[3])
    jxl, jxh, jyl, jyh = sector_hull(obs[4], obs[5], obs[6], obs[7])
    xl, xh = sub(ixl, ixh, jxl, jxh)
    yl, yh = sub(iyl, iyh, jyl, jyh)
    return xl, xh, yl, yh


@njit(cache=True)
def _cells(lo, hi, eps):
    """Grid cell index range ``[a, b)`` whose cells cover ``[lo, hi]``."""
    return float(math.floor(lo / eps)), float(math.floor(hi / eps)) + 1.0


# A subpaving row: box xl, xh, yl, yh | grid cell range a0, a1, b0, b1 | fails | notin
ROW = 10
FAILS = 8
NOTIN = 9


@njit(cache=True)
def _push(buf, m, row):
    """Append one row to the growable ``buf`` holding ``m`` rows; returns (buf, m + 1)."""
    if m >= buf.shape[0]:
        grown = np.empty((2 * buf.shape[0] + 1, buf.shape[1]))
        grown[:m] = buf[:m]
        buf = grown
    buf[m] = row
    return buf, m + 1


@njit(cache=True)
def refine(paving, obs, q, eps, max_boxes, budget):
    """Intersect a pair's subpaving with one more displacement set (SIVIA on the grid).

    ``paving`` is (B, ROW): each row a box, the integer range ``[a0, a1) x [b0, b1)`` (as
    floats) of the grid cells it lies in, and its ``fails``/``notin`` counters. Returns the new
    paving, a flag that is True when ``max_boxes`` cut the refinement short (boundary boxes
    larger than a cell were then kept whole: still an outer approximation, less tight), and
    the number of box tests made. When ``budget`` box tests are not enough, it stops at once
    and returns ``budget + 1`` tests (the paving returned is then meaningless).
    """
    out = np.empty((max(16, 2 * paving.shape[0]), ROW))
    stack = np.empty((64, ROW))
    m = 0
    truncated = False
    work = 0
    for k in range(paving.shape[0]):
        stack[0] = paving[k]
        top = 1
        while top > 0:
            work += 1
            if work > budget:
                return out[:0].copy(), truncated, work
            top -= 1
            r = stack[top].copy()
            contract = r[FAILS] == q
            state, xl, xh, yl, yh = classify(r[0], r[1], r[2], r[3], obs, contract)
            if state == OUT:
                r[FAILS] += 1.0
                if r[FAILS] > q:
                    continue
                r[NOTIN] += 1.0
            elif state == BOUNDARY:
                single = (r[5] - r[4] <= 1.0) and (r[7] - r[6] <= 1.0)
                if not single and m + top < max_boxes:
                    # bisect along the longer side (in cells) at a grid line; children inherit the
                    # counters and are classified against the same set again
                    axis = 0 if r[5] - r[4] >= r[7] - r[6] else 1
                    mid = float(math.floor(0.5 * (r[4 + 2 * axis] + r[5 + 2 * axis])))
                    split = mid * eps
                    lo_child = r.copy()
                    hi_child = r.copy()
                    lo_child[2 * axis + 1] = min(r[2 * axis + 1], up(split))
                    hi_child[2 * axis] = max(r[2 * axis], down(split))
                    lo_child[5 + 2 * axis] = mid
                    hi_child[4 + 2 * axis] = mid
                    stack, top = _push(stack, top, lo_child)
                    stack, top = _push(stack, top, hi_child)
                    continue
                if not single:
                    truncated = True
                r[NOTIN] += 1.0
                if contract:
                    r[0], r[1], r[2], r[3] = xl, xh, yl, yh
            # INSIDE: counters unchanged
            out, m = _push(out, m, r)
    return out[:m].copy(), truncated, work


@njit(cache=True)
def initial_domain(obs_rows, eps):
    """A one-row paving: the hull of the given sets, snapped outward to the grid, counters 0."""
    xl = INF
    xh = -INF
    yl = INF
    yh = -INF
    for k in range(obs_rows.shape[0]):
        a, b, c, d = set_hull(obs_rows[k])
        xl = min(xl, a)
        xh = max(xh, b)
        yl = min(yl, c)
        yh = max(yh, d)
    a0, a1 = _cells(xl, xh, eps)
    b0, b1 = _cells(yl, yh, eps)
    row = np.zeros((1, ROW))
    # the grid-snapped box, never inside the hull even if xl / eps rounded up to an integer
    row[0, :8] = [min(down(a0 * eps), xl), max(up(a1 * eps), xh), min(down(b0 * eps), yl),
                  max(up(b1 * eps), yh), a0, a1, b0, b1]
    return row


@njit(cache=True)
def hull_width(boxes):
    """Largest side of the bounding box of the boxes (NaN when there is none)."""
    if boxes.shape[0] == 0:
        return math.nan
    xl = boxes[:, 0].min()
    xh = boxes[:, 1].max()
    yl = boxes[:, 2].min()
    yh = boxes[:, 3].max()
    return max(up(xh - xl), up(yh - yl))


@njit(cache=True)
def network_pass(m_box, pair_i, pair_j, offsets, boxes):
    """One sweep of ``m_j ∈ m_i − S_ij`` and ``m_i ∈ m_j + S_ij`` over every pair.

    ``m_box`` (L, 4) landmark boxes (indices, not ids), contracted in place; each pair's set is
    the union of its boxes ``boxes[offsets[p]:offsets[p+1]]``. Returns the largest relative
    width reduction (for the fixpoint loop) or -1 if some landmark box became empty.
    """
    best = 0.0
    for p in range(pair_i.shape[0]):
        i = pair_i[p]
        j = pair_j[p]
        s0 = offsets[p]
        s1 = offsets[p + 1]
        if s1 == s0:
            continue
        for target in range(2):
            a = j if target == 0 else i  # contracted
            b = i if target == 0 else j  # source
            nxl = INF
            nxh = -INF
            nyl = INF
            nyh = -INF
            for k in range(s0, s1):
                if target == 0:  # m_j = m_i - dl
                    cxl, cxh = sub(m_box[b, 0], m_box[b, 1], boxes[k, 0], boxes[k, 1])
                    cyl, cyh = sub(m_box[b, 2], m_box[b, 3], boxes[k, 2], boxes[k, 3])
                else:  # m_i = m_j + dl
                    cxl, cxh = add(m_box[b, 0], m_box[b, 1], boxes[k, 0], boxes[k, 1])
                    cyl, cyh = add(m_box[b, 2], m_box[b, 3], boxes[k, 2], boxes[k, 3])
                cxl, cxh = inter(cxl, cxh, m_box[a, 0], m_box[a, 1])
                cyl, cyh = inter(cyl, cyh, m_box[a, 2], m_box[a, 3])
                if cxl <= cxh and cyl <= cyh:
                    nxl = min(nxl, cxl)
                    nxh = max(nxh, cxh)
                    nyl = min(nyl, cyl)
                    nyh = max(nyh, cyh)
            if not (nxl <= nxh):
                return -1.0
            wx0 = m_box[a, 1] - m_box[a, 0]
            wy0 = m_box[a, 3] - m_box[a, 2]
            wx1 = nxh - nxl
            wy1 = nyh - nyl
            if wx0 == INF and wx1 < INF:
                best = 1.0
            elif wx0 > 0.0 and wx0 < INF:
                best = max(best, (wx0 - wx1) / wx0)
            if wy0 == INF and wy1 < INF:
                best = 1.0
            elif wy0 > 0.0 and wy0 < INF:
                best = max(best, (wy0 - wy1) / wy0)
            m_box[a, 0] = nxl
            m_box[a, 1] = nxh
            m_box[a, 2] = nyl
            m_box[a, 3] = nyh
    return best


@njit(cache=True)
def pair_rows(step_offsets, obs_id, rho, beta):
    """Every pair of observations made at the same step, as displacement-set rows.

    Rows are oriented so that ``i < j`` (``dl = m_i − m_j``); two observations of the same id
    at one step make no pair. Returns ``(i, j, a, b, rows)``: landmark ids, the indices of the
    two observations, and the (R, 8) row ``rho_i, beta_i, rho_j, beta_j`` (each lo, hi).
    """
    count = 0
    for s in range(step_offsets.shape[0] - 1):
        k = step_offsets[s + 1] - step_offsets[s]
        count += k * (k - 1) // 2
    pi = np.empty(count, dtype=np.int64)
    pj = np.empty(count, dtype=np.int64)
    pa = np.empty(count, dtype=np.int64)
    pb = np.empty(count, dtype=np.int64)
    rows = np.empty((count, N_OBS_COLS))
    r = 0
    for s in range(step_offsets.shape[0] - 1):
        for u in range(step_offsets[s], step_offsets[s + 1]):
            for v in range(u + 1, step_offsets[s + 1]):
                if obs_id[u] == obs_id[v]:
                    continue
                a, b = (u, v) if obs_id[u] < obs_id[v] else (v, u)
                pi[r] = obs_id[a]
                pj[r] = obs_id[b]
                pa[r] = a
                pb[r] = b
                rows[r, 0], rows[r, 1] = rho[a, 0], rho[a, 1]
                rows[r, 2], rows[r, 3] = beta[a, 0], beta[a, 1]
                rows[r, 4], rows[r, 5] = rho[b, 0], rho[b, 1]
                rows[r, 6], rows[r, 7] = beta[b, 0], beta[b, 1]
                r += 1
    return pi[:r], pj[:r], pa[:r], pb[:r], rows[:r]


@njit(cache=True)
def _append(buf, m, rows):
    """Append ``rows`` to the growable ``buf`` holding ``m`` rows; returns (buf, m)."""
    n = rows.shape[0]
    if m + n > buf.shape[0]:
        grown = np.empty((max(2 * buf.shape[0], m + n), buf.shape[1]))
        grown[:m] = buf[:m]
        buf = grown
    buf[m : m + n] = rows
    return buf, m + n


@njit(cache=True)
def process_pairs(rows, row_stamp, pair_offsets, q, eps, max_boxes, checkpoints, max_work):
    """Run every pair's history: the q-relaxed intersection of its displacement sets over time.

    ``rows`` are grouped by pair and time-ordered within a pair (``pair_offsets``). Returns
    flat boxes (B, 4), their ``inner`` flags, per-pair ``box_offsets``, the width of the pair's
    set after each row (the set never ends empty), a per-row ``rejected`` flag (the row would
    have emptied the set beyond q: an empty event, the row is left out), a per-pair
    ``truncated`` flag (``max_boxes`` stopped a bisection: still outer, less tight), and the
    pair sets at each of the ``checkpoints`` stamps: ``snap_boxes`` with ``snap_offsets`` indexed
    ``c * P + p`` (no box: the pair gives no bounded set yet at that time).
    A pair seen at most ``q`` times has no bounded enclosure: one box ``R^2``.
    The last two values are the box tests made and the pair being refined when they exceeded
    ``max_work`` (then the run stopped there and the other values are meaningless), else -1.
    """
    n_rows = rows.shape[0]
    n_pairs = pair_offsets.shape[0] - 1
    n_cp = checkpoints.shape[0]
    width = np.empty(n_rows)
    rejected = np.zeros(n_rows, dtype=np.bool_)
    truncated = np.zeros(n_pairs, dtype=np.bool_)
    out = np.empty((max(16, 4 * n_pairs), 5))
    box_offsets = np.zeros(n_pairs + 1, dtype=np.int64)
    snap = np.empty((max(16, 4 * n_pairs), 4))
    snap_count = np.zeros(n_cp * n_pairs, dtype=np.int64)
    snap_start = np.zeros(n_cp * n_pairs, dtype=np.int64)
    ns = 0
    m = 0
    work = 0
    none = np.empty((0, 4))
    for p in range(n_pairs):
        r0 = pair_offsets[p]
        r1 = pair_offsets[p + 1]
        c = 0
        if r1 - r0 <= q:
            bx = np.array([[-INF, INF, -INF, INF]])
            bi = np.zeros(1, dtype=np.bool_)
            for k in range(r0, r1):
                width[k] = INF
        else:
            paving = initial_domain(rows[r0 : r0 + q + 1], eps)
            for k in range(r0, r1):
                while c < n_cp and checkpoints[c] < row_stamp[k]:
                    cur = paving[:, :4] if k - r0 > q else none
                    snap_start[c * n_pairs + p] = ns
                    snap_count[c * n_pairs + p] = cur.shape[0]
                    snap, ns = _append(snap, ns, cur)
                    c += 1
                new, trunc, used = refine(paving, rows[k], q, eps, max_boxes, max_work - work)
                work += used
                if work > max_work:
                    return (out[:0, :4].copy(), np.zeros(0, dtype=np.bool_), box_offsets, width, rejected,
                            truncated, np.empty((0, 4)), np.zeros(1, dtype=np.int64), work, p)
                if trunc:
                    truncated[p] = True
                if new.shape[0] == 0:
                    rejected[k] = True
                else:
                    paving = new
                width[k] = hull_width(paving)
            bx = paving[:, :4].copy()
            bi = paving[:, NOTIN] <= q
        while c < n_cp:
            cur = bx if r1 - r0 > q else none
            snap_start[c * n_pairs + p] = ns
            snap_count[c * n_pairs + p] = cur.shape[0]
            snap, ns = _append(snap, ns, cur)
            c += 1
        tagged = np.empty((bx.shape[0], 5))
        tagged[:, :4] = bx
        for r in range(bx.shape[0]):
            tagged[r, 4] = 1.0 if bi[r] else 0.0
        out, m = _append(out, m, tagged)
        box_offsets[p + 1] = m
    # snapshots grouped by checkpoint then pair: contiguous per (c, p) already; build offsets
    snap_offsets = np.zeros(n_cp * n_pairs + 1, dtype=np.int64)
    snap_boxes = np.empty((ns, 4))
    w = 0
    for idx in range(n_cp * n_pairs):
        cnt = snap_count[idx]
        snap_boxes[w : w + cnt] = snap[snap_start[idx] : snap_start[idx] + cnt]
        w += cnt
        snap_offsets[idx + 1] = w
    inner = out[:m, 4] > 0.5
    return out[:m, :4].copy(), inner, box_offsets, width, rejected, truncated, snap_boxes, snap_offsets, work, -1
