"""Pose contraction against the map: old beams end on obstacles, not in free space (after the
"Guaranteed SLAM – practical considerations" slides, University of Manchester).

The map's P_EMPTY cells are proven free of obstacles (closed squares). A beam's endpoint is a
surface point, so for a pose consistent with beam ``i`` the endpoint region

    E_i(b) = s + [z_i ± r_ρ] (cos, sin)(θ_s + α_i + [±r_α])      (s, θ_s: the sensor pose of b)

cannot lie inside P_EMPTY. Over the pose box of a scan, a set inversion in pose space keeps
the sub-boxes ``b`` for which at most ``q`` beams are *excluded* (``E_i(b)`` covered by P_EMPTY
cells only): q-relaxation for moving people, glass and other beams the static-world model does
not explain. The hull of the kept sub-boxes is the contracted pose box.

Why sub-boxes: on a whole pose box the endpoint regions are wide and meet obstacle or unknown
cells almost always, so nothing is excluded; on small sub-boxes the wrong poses put many
endpoints in proven-free space (measured on the URG-04LX log: for over 90 % of beams the
endpoint region of a whole box lies in P_OBSTACLE; the contraction comes from what the map
excludes).

Guarantee: if the true pose is in the box, the world is static but for at most ``q`` beams
of the scan, and the map's P_EMPTY is sound (built from pose boxes that held the truth), the
true pose stays in the result. Every bound is rounded outward; cells are enumerated
generously (a region's cells include every cell it may touch).

Two implementations: :func:`~.contract_reference.contract_kernel_reference` (each beam's
region of each sub-box looked up cell by cell in the tiles: the definition) and :func:`contract_kernel`, the fast path
:func:`contract_pose` runs (witness points, a summed-area table over a dense window, work
shared between sub-boxes: see the comment before it), with the same kept count, hull and
tested count. Their equality is tested on random maps and scans (``tests/test_lidar_contract``)
and checked by ``bench/bench_lidar_contract.py``.
"""

from __future__ import annotations

import math
import threading

import numpy as np
from numba import njit

from ivslam_cli.interval.arith import add
from ivslam_cli.interval.rounding import down, up
from ivslam_cli.paving.tiles import EMPTY, TILE
from ivslam_cli.slam.lidar.contract_reference import (
    MAX_REGION_CELLS,
    _empty_hull,
    _join,
    _region_free,
    contract_kernel_reference,
    excluded_beams,
)
from ivslam_cli.slam.lidar.geometry import beam_offset, range_bounds, sensor_box, sensor_offset


# ---------------------------------------------------------------- fast path
# Same answers as the reference (kept count, hull, tested count), by construction:
#
# - what does not depend on the sub-box is computed once: per beam the range bounds and angle;
#   per heading interval (a "node": boxes split along x or y share their parent's, and a node's
#   two halves are made once) the sensor offset of the mount and, on first use, each beam's
#   endpoint offset ``[r] (cos, sin)(θ_s + α_i ± r_α)``, with the reference's own operations;
# - witnesses: a beam is not free as soon as one real point of its endpoint region lies in a
#   cell not proven free, for that cell is among those the reference enumerates (its cell
#   range holds the cell of every point of the region). The region of a box holds
#   ``s + r (cos, sin)(φ)`` for every sensor position ``s`` of a pose of the box, ``r`` in
#   ``[r]`` and ``φ`` in the reference's angle interval, which holds ``σ + α_i`` (real sum)
#   for every float ``σ`` in the sensor heading interval, here ``σ = fl(mid θ + myaw)``. The
#   points tried: from the box's centre at ranges mid(r) and sup(r), then from the box's
#   corner farthest along the beam at sup(r). They are computed in floating point (a
#   rotation of ``(cos, sin)(α_i)`` by ``σ``) and used only when their cell is certain:
#   farther than ``mu`` cells from the cell's edges, far beyond the rounding error;
# - a box's centre lies in both its halves (on their common face), and in further descendants
#   as long as the splits stay on its faces: the beams witnessed from a pose (the "origin")
#   are witnessed for every box holding that pose, without a test. A box holding the origin
#   it was handed skips those beams and hands the same set down; any other box tests every
#   beam from its own centre and hands that set down (corner witnesses are not handed down);
# - otherwise the region's cells are tested in O(1) by a summed-area table of "not proven free"
#   over a dense window of the map (the extent of the endpoints from the root box, grown by
#   how far the box's poses, ranges and cone move them, within the tiles' bounding box),
#   built once per call when a first box needs it; a region not inside the window is looked
#   up in the tiles as the reference does (outside the tiles' bounding box: unknown, not free);
# - skips that cannot change a count: a beam whose endpoint offset alone spans more than
#   MAX_REGION_CELLS cells is never free for a box of its node, and a box whose sensor box alone
#   does is free for no beam (the one-cell margin of ``_cells_lb`` absorbs every rounding error
#   while coordinates stay below ``_SKIP_MAX`` and the cell side above ``_SKIP_EPS``);
# - beams are tested in any order: only "more than q free" is used.
#
# Speed: the arrays live in a per-thread workspace kept between calls (a call allocates nothing
# large: no page faults), and the loops over boxes and beams run in ``_level``, which allocates
# nothing and is compiled without reference counting (numba's private ``_nrt=False``): its
# per-box stages are inlined helpers taking arrays, which would otherwise change reference
# counts, atomically, on every use (15-25 % slower, measured on the bench's sim and exp1
# cases). Numba compiles a callee first reached from such a function with the same option:
# ``_region_free`` and the tile lookups it calls, shared with the reference, count no
# references either (a numba upgrade that drops the option breaks ``_level`` at compile time).

#: the dense window holds at most this many cells (larger: regions are looked up in the tiles)
MAX_WINDOW_CELLS = 1 << 22
#: the skip rules and witnesses are used only when every coordinate and range is below this (m) ...
_SKIP_MAX = 1e6
#: ... and the cell side above this (m)
_SKIP_EPS = 1e-5
# node columns (float): tl, th, then _node_sensor's 8 values; (int): first child, pool row
_NF = 10
# trailing zeros of a power of two 2^i: _DEBRUIJN[(2^i * _DEBRUIJN_MUL mod 2^64) >> 58] = i
_DEBRUIJN_MUL = np.uint64(0x03F79D71B4CB0A89)
_DEBRUIJN = np.zeros(64, np.int64)
for _i in range(64):
    _DEBRUIJN[(((1 << _i) * int(_DEBRUIJN_MUL)) & (2**64 - 1)) >> 58] = _i


@njit(cache=True, inline="always")
def _cells_lb(w, eps):
    """A lower bound (>= 1) on the cells ``_region_free`` counts along an axis for an interval
    at least ``w`` wide (coordinates within the ``_SKIP_MAX`` / ``_SKIP_EPS`` guard)."""
    c = math.floor(w / eps) - 1
    return c if c > 1 else 1


@njit(cache=True)
def _build_window(cells, coords, n, wx0, wx1, wy0, wy1, F, S):
    """The cells ``[wx0, wx1] x [wy0, wy1]`` not proven free: flags ``F[a ny + b]`` (uint8) and
    their summed-area table ``S[a (ny + 1) + b]`` counting them over ``[wx0, wx0 + a) x
    [wy0, wy0 + b)`` modulo 2^16 (uint16: a rectangle's count, at most MAX_REGION_CELLS, is its
    four corners' alternating sum modulo 2^16) (``F``, ``S`` flat, large enough)."""
    nx = wx1 - wx0 + 1
    ny = wy1 - wy0 + 1
    F[: nx * ny] = 1  # not in a tile: unknown
    for t in range(n):
        ox = coords[t, 0] * TILE - wx0
        oy = coords[t, 1] * TILE - wy0
        a0 = max(0, -ox)
        a1 = min(TILE, nx - ox)
        b0 = max(0, -oy)
        b1 = min(TILE, ny - oy)
        for a in range(a0, a1):
            for b in range(b0, b1):
                F[(ox + a) * ny + oy + b] = np.uint8(1) - (cells[t, a, b] & EMPTY)
    m = ny + 1
    S[:m] = 0
    for a in range(nx):
        run = 0
        S[(a + 1) * m] = 0
        for b in range(ny):
            run += F[a * ny + b]
            S[(a + 1) * m + b + 1] = (S[a * m + b + 1] + run) & 0xFFFF


@njit(cache=True)
def _node_sensor(tl, th, mx, my, myaw):
    """The sensor offset and heading of the heading interval ``[tl, th]`` as :func:`sensor_box`
    computes them, ``(ox, oxh, oy, oyh, stl, sth)``, then the sensor offset of the heading
    ``mid(tl, th)`` in floating point (for witnesses)."""
    ox, oxh, oy, oyh, stl, sth = sensor_offset(tl, th, mx, my, myaw)
    tc = 0.5 * (tl + th)
    c, s = math.cos(tc), math.sin(tc)
    return ox, oxh, oy, oyh, stl, sth, c * mx - s * my, s * mx + c * my


@njit(cache=True)
def _set_node(nf, ni, i, tl, th, mx, my, myaw):
    """Node ``i``: heading interval ``[tl, th]``, no children, no pool row yet."""
    nf[i, 0] = tl
    nf[i, 1] = th
    o = _node_sensor(tl, th, mx, my, myaw)
    for d in range(8):
        nf[i, 2 + d] = o[d]
    ni[i, 0] = -1
    ni[i, 1] = -1


@njit(cache=True)
def _node_witness(tl, th, myaw, rmid, rh, uc, us, wit, row):
    """Witness offsets from the sensor, ``wit[row]`` (B, 4): ``r (cos, sin)(σ + α_i)`` for
    ``r`` = ``rmid`` and ``rh``, ``σ = fl(mid(tl, th) + myaw)`` (``uc, us``: cos, sin of
    ``α_i``), floating point."""
    sg = 0.5 * (tl + th) + myaw
    c, s = math.cos(sg), math.sin(sg)
    for j in range(uc.shape[0]):
        ex = c * uc[j] - s * us[j]
        ey = s * uc[j] + c * us[j]
        wit[row, j, 0] = rmid[j] * ex
        wit[row, j, 1] = rmid[j] * ey
        wit[row, j, 2] = rh[j] * ex
        wit[row, j, 3] = rh[j] * ey


@njit(cache=True, inline="always")
def _witness_cell(ux, uy, mu, cx0, cx1, cy0, cy1):
    """The cell surely holding the point ``(ux, uy)`` (in cells): ``(0, ix, iy)``; ``(1, ., .)``
    if that cell is in no tile (unknown); ``(-1, ., .)`` if no cell is certain (near an edge,
    or NaN)."""
    fx = math.floor(ux)
    fy = math.floor(uy)
    dx = ux - fx
    dy = uy - fy
    if not (dx > mu and dx < 1.0 - mu and dy > mu and dy < 1.0 - mu):
        return -1, 0, 0
    ix = int(fx)
    iy = int(fy)
    if ix < cx0 or ix > cx1 or iy < cy0 or iy > cy1:
        return 1, ix, iy
    return 0, ix, iy


@njit(cache=True, _nrt=False)
def _level(cur, cur_n, cur_b, cur_o, nxt, nxt_n, nxt_b, nxt_o, n_cur, cap, hull, nf, ni, n_nodes, wit, dof, dst,
           n_rows, keys, slots, cells, eps, F, S, built, wx0, wx1, wy0, wy1, cx0, cx1, cy0, cy1, rl, rh, rmid, ang,
           uc, us, r_alpha, mx, my, myaw, q, min_xy, min_th, reach, skip, witness, mu):
    """One level of the breadth-first set inversion of :func:`contract_kernel_reference`: tests
    the ``n_cur`` boxes of ``cur`` (their nodes in ``cur_n``), writes the halves of those to
    split into ``nxt`` / ``nxt_n``, the kept ones into ``hull``. Returns ``(n_nxt, kept,
    n_nodes, n_rows)``. The caller has made room for ``2 n_cur`` more nodes and ``n_cur`` more
    pool rows. Witnessed beams handed down: ``cur_b[j, 0]`` says whether box ``j`` has a set
    (bits ``cur_b[j, 1:]``) witnessed from the pose ``cur_o[j]``; the sets for the halves go to
    ``nxt_b`` / ``nxt_o``.

    Per box, three stages (inlined; this function counts no references, see the comment
    before the fast path): the witnessed set handed down (:func:`_hand_down`), the count of
    free regions (:func:`_free_count`), then kept or split (:func:`_split`)."""
    nb = rl.shape[0]
    nw = (nb + 63) >> 6
    win = (F, S, built, wx0, wx1, wy0, wy1, cx0, cx1, cy0, cy1)
    beams = (rl, rh, rmid, ang, uc, us)
    n_nxt = 0
    kept = 0
    for j in range(n_cur):
        nd = cur_n[j]
        has = _hand_down(cur, cur_b, cur_o, j, nxt_b, nxt_o, n_nxt, nw)
        n, n_rows = _free_count(cur, cur_b, j, nd, has, nxt_b, n_nxt, nf, ni, wit, dof, dst, n_rows, keys, slots,
                                cells, eps, win, beams, r_alpha, myaw, q, skip, witness, mu)
        if n > q:
            continue
        n_nxt, k, n_nodes = _split(cur, j, nd, nxt, nxt_n, nxt_b, nxt_o, n_nxt, cap, hull, nf, ni, n_nodes, nw, mx,
                                   my, myaw, min_xy, min_th, reach)
        kept += k
    return n_nxt, kept, n_nodes, n_rows


@njit(cache=True, inline="always")
def _hand_down(cur, cur_b, cur_o, j, nxt_b, nxt_o, n_nxt, nw):
    """The witnessed set box ``j`` hands down, into row ``n_nxt`` of ``nxt_b`` / ``nxt_o``: the
    origin's if the box holds it (returns True: the box skips those beams), else an empty one
    from the box's centre."""
    b0, b1, b2, b3, b4, b5 = cur[j, 0], cur[j, 1], cur[j, 2], cur[j, 3], cur[j, 4], cur[j, 5]
    has = (cur_b[j, 0] != 0 and b0 <= cur_o[j, 0] <= b1 and b2 <= cur_o[j, 1] <= b3
           and b4 <= cur_o[j, 2] <= b5)
    if has:
        for w in range(nw + 1):
            nxt_b[n_nxt, w] = cur_b[j, w]
        for w in range(3):
            nxt_o[n_nxt, w] = cur_o[j, w]
    else:
        for w in range(nw + 1):
            nxt_b[n_nxt, w] = 0
        nxt_o[n_nxt, 0] = 0.5 * (b0 + b1)
        nxt_o[n_nxt, 1] = 0.5 * (b2 + b3)
        nxt_o[n_nxt, 2] = 0.5 * (b4 + b5)
    return has


@njit(cache=True, inline="always")
def _free_count(cur, cur_b, j, nd, has, nxt_b, n_nxt, nf, ni, wit, dof, dst, n_rows, keys, slots, cells, eps, win,
                beams, r_alpha, myaw, q, skip, witness, mu):
    """How many beams of box ``j`` (heading node ``nd``) have an endpoint region in proven-free
    cells, as :func:`excluded_beams` counts them (stops past ``q``); beams witnessed from the
    origin are skipped when the box holds it (``has``), the box's own witnesses go into row
    ``n_nxt`` of ``nxt_b`` when it does not. Returns ``(count, n_rows)`` (the node's pool row
    made on first use)."""
    F, S, built, wx0, wx1, wy0, wy1, cx0, cx1, cy0, cy1 = win
    rl, rh, rmid, ang, uc, us = beams
    nb = rl.shape[0]
    ny = wy1 - wy0 + 1
    m = ny + 1
    inv_eps = 1.0 / eps
    b0, b1, b2, b3 = cur[j, 0], cur[j, 1], cur[j, 2], cur[j, 3]
    store = not has
    sxl, sxh = add(b0, b1, nf[nd, 2], nf[nd, 3])
    syl, syh = add(b2, b3, nf[nd, 4], nf[nd, 5])
    n = 0
    if nb == 0 or (skip and _cells_lb(sxh - sxl, eps) * _cells_lb(syh - syl, eps) > MAX_REGION_CELLS):
        return n, n_rows  # every region of this box spans too many cells: none is free
    row = ni[nd, 1]
    if row < 0:
        row = n_rows
        ni[nd, 1] = row
        n_rows += 1
        for k in range(nb):
            dst[row, k] = 0
        if witness:
            _node_witness(nf[nd, 0], nf[nd, 1], myaw, rmid, rh, uc, us, wit, row)
    if store and witness:
        nxt_b[n_nxt, 0] = 1
    stl = nf[nd, 6]
    sth = nf[nd, 7]
    scx = 0.5 * (b0 + b1) + nf[nd, 8]
    scy = 0.5 * (b2 + b3) + nf[nd, 9]
    hx = b1 - 0.5 * (b0 + b1)  # the corners: centre ± (hx, hy), floats of the box
    hy = b3 - 0.5 * (b2 + b3)
    k = -1
    while True:
        k += 1
        if has:  # to the next beam not witnessed from the origin
            while k < nb:
                word = ~cur_b[j, 1 + (k >> 6)] >> np.uint64(k & 63)
                if word != 0:
                    k += _DEBRUIJN[((word & (~word + np.uint64(1))) * _DEBRUIJN_MUL) >> np.uint64(58)]
                    break
                k = ((k >> 6) + 1) << 6
        if k >= nb:
            break
        st = dst[row, k]
        if st == 2:
            continue
        if witness:
            c, ix, iy = _witness_cell((scx + wit[row, k, 0]) * inv_eps, (scy + wit[row, k, 1]) * inv_eps, mu, cx0,
                                      cx1, cy0, cy1)
            if not (c == 1 or (c == 0 and built and ix >= wx0 and ix <= wx1 and iy >= wy0 and iy <= wy1
                               and F[(ix - wx0) * ny + iy - wy0] != 0)):
                c, ix, iy = _witness_cell((scx + wit[row, k, 2]) * inv_eps, (scy + wit[row, k, 3]) * inv_eps, mu,
                                          cx0, cx1, cy0, cy1)
            if c == 1 or (c == 0 and built and ix >= wx0 and ix <= wx1 and iy >= wy0 and iy <= wy1
                          and F[(ix - wx0) * ny + iy - wy0] != 0):
                if store:
                    nxt_b[n_nxt, 1 + (k >> 6)] |= np.uint64(1) << np.uint64(k & 63)
                continue
            # the far end seen from the box's corner farthest along the beam (a pose of the box,
            # not its centre: not handed down)
            ex = wit[row, k, 2]
            ey = wit[row, k, 3]
            c, ix, iy = _witness_cell((scx + (hx if ex >= 0.0 else -hx) + ex) * inv_eps,
                                      (scy + (hy if ey >= 0.0 else -hy) + ey) * inv_eps, mu, cx0, cx1, cy0, cy1)
            if c == 1 or (c == 0 and built and ix >= wx0 and ix <= wx1 and iy >= wy0 and iy <= wy1
                          and F[(ix - wx0) * ny + iy - wy0] != 0):
                continue
        if st == 0:
            dxl, dxh, dyl, dyh = beam_offset(stl, sth, rl[k], rh[k], ang[k], r_alpha)
            dof[row, k, 0] = dxl
            dof[row, k, 1] = dxh
            dof[row, k, 2] = dyl
            dof[row, k, 3] = dyh
            if skip and _cells_lb(dxh - dxl, eps) * _cells_lb(dyh - dyl, eps) > MAX_REGION_CELLS:
                dst[row, k] = 2  # never free for a box of this heading interval
                continue
            dst[row, k] = 1
        xl, xh = add(sxl, sxh, dof[row, k, 0], dof[row, k, 1])
        yl, yh = add(syl, syh, dof[row, k, 2], dof[row, k, 3])
        if not (abs(xl) < math.inf and abs(xh) < math.inf and abs(yl) < math.inf and abs(yh) < math.inf):
            free = _region_free(keys, slots, cells, eps, xl, xh, yl, yh)
        else:
            ix0 = math.floor(down(xl / eps))
            ix1 = math.floor(up(xh / eps))
            iy0 = math.floor(down(yl / eps))
            iy1 = math.floor(up(yh / eps))
            if (ix1 - ix0 + 1) * (iy1 - iy0 + 1) > MAX_REGION_CELLS:
                free = False
            elif built and ix0 >= wx0 and ix1 <= wx1 and iy0 >= wy0 and iy1 <= wy1:
                ax0 = (ix0 - wx0) * m
                ax1 = (ix1 - wx0 + 1) * m
                ay0 = iy0 - wy0
                ay1 = iy1 - wy0 + 1
                free = (S[ax1 + ay1] - S[ax0 + ay1] - S[ax1 + ay0] + S[ax0 + ay0]) & 0xFFFF == 0
            elif ix0 < cx0 or ix1 > cx1 or iy0 < cy0 or iy1 > cy1:
                free = False  # a cell in no tile: unknown
            else:
                free = _region_free(keys, slots, cells, eps, xl, xh, yl, yh)
        if free:
            n += 1
            if n > q:
                break
    return n, n_rows


@njit(cache=True, inline="always")
def _split(cur, j, nd, nxt, nxt_n, nxt_b, nxt_o, n_nxt, cap, hull, nf, ni, n_nodes, nw, mx, my, myaw, min_xy,
           min_th, reach):
    """Box ``j`` (not excluded) kept into ``hull`` when small enough or out of room, else bisected
    along the widest of x, y and ``reach·θ``: its halves into rows ``n_nxt, n_nxt + 1`` of
    ``nxt`` (the witnessed set of row ``n_nxt`` copied to both; a split heading gets the node's
    two children, made once). Returns ``(n_nxt, kept, n_nodes)``."""
    b0, b1, b2, b3, b4, b5 = cur[j, 0], cur[j, 1], cur[j, 2], cur[j, 3], cur[j, 4], cur[j, 5]
    wx = b1 - b0
    wy = b3 - b2
    wt = (b5 - b4) * reach
    if (wx <= min_xy and wy <= min_xy and b5 - b4 <= min_th) or n_nxt + 2 > cap:
        _join(hull, cur[j])
        return n_nxt, 1, n_nodes
    d = 0 if (wx >= wy and wx >= wt) else (1 if wy >= wt else 2)
    mid = 0.5 * (cur[j, 2 * d] + cur[j, 2 * d + 1])
    for e in range(6):
        nxt[n_nxt, e] = cur[j, e]
        nxt[n_nxt + 1, e] = cur[j, e]
    nxt[n_nxt, 2 * d + 1] = mid
    nxt[n_nxt + 1, 2 * d] = mid
    for w in range(nw + 1):
        nxt_b[n_nxt + 1, w] = nxt_b[n_nxt, w]
    for w in range(3):
        nxt_o[n_nxt + 1, w] = nxt_o[n_nxt, w]
    if d == 2:  # the two halves of the heading interval, made once per node
        if ni[nd, 0] < 0:
            _set_node(nf, ni, n_nodes, b4, mid, mx, my, myaw)
            _set_node(nf, ni, n_nodes + 1, mid, b5, mx, my, myaw)
            ni[nd, 0] = n_nodes
            n_nodes += 2
        nxt_n[n_nxt] = ni[nd, 0]
        nxt_n[n_nxt + 1] = ni[nd, 0] + 1
    else:
        nxt_n[n_nxt] = nd
        nxt_n[n_nxt + 1] = nd
    return n_nxt + 2, 0, n_nodes


@njit(cache=True)
def _box_free_possible(cur, cur_n, n_cur, nf, eps, skip):
    """Whether some box of the level escapes the box-level skip (its beams get tested)."""
    if not skip:
        return True
    for j in range(n_cur):
        nd = cur_n[j]
        sxl, sxh = add(cur[j, 0], cur[j, 1], nf[nd, 2], nf[nd, 3])
        syl, syh = add(cur[j, 2], cur[j, 3], nf[nd, 4], nf[nd, 5])
        if _cells_lb(sxh - sxl, eps) * _cells_lb(syh - syl, eps) <= MAX_REGION_CELLS:
            return True
    return False


@njit(cache=True)
def contract_kernel(keys, slots, cells, coords, n_tiles, eps, ranges, valid, a0, inc, box, mx, my, myaw, r_abs,
                    r_rel, r_alpha, q, stride, min_xy, min_th, reach, max_boxes, out, max_window, ws_box, ws_n,
                    ws_o, ws_nf, ws_ni, wit, dof, dst, F, S, bits):
    """:func:`contract_kernel_reference` (same arguments plus the tiles' ``coords`` and count),
    same results, faster (see the comment above). ``max_window``: cells of the dense window at
    most (0: none, every region looked up in the tiles; for tests). Workspace (see
    :func:`_workspace`): ``ws_box`` (2, max_boxes + 2, 6), ``ws_n`` (2, max_boxes + 2) int64,
    ``ws_o`` (2, max_boxes + 3, 3), ``ws_nf`` (2 max_boxes + 3, _NF), ``ws_ni`` (2 max_boxes + 3,
    2) int64; pools ``wit``, ``dof`` (R, B', 4), ``dst`` (R, B') int8, window ``F`` (uint8),
    ``S`` (uint16) and witness bits (2, C, W) uint64 of any sizes (regrown here).

    Stages: the beams and what does not depend on the sub-box (:func:`_beams`), the tiles'
    bounding box and the dense window's extent (:func:`_tiles_bbox`, :func:`_window_extent`),
    then the set inversion level by level (:func:`_level`), the window built
    (:func:`_build_window`) before the first level that may test a region.

    Returns ``(kept, tested, wit, dof, dst, F, S, bits)`` (the last six possibly regrown)."""
    rl, rh, rmid, ang, uc, us, rmax = _beams(ranges, valid, stride, a0, inc, r_abs, r_rel)
    nb = rl.shape[0]
    # the guard of the skip rules and witnesses
    ext = max(abs(box[0]), abs(box[1]), abs(box[2]), abs(box[3])) + abs(mx) + abs(my) + rmax
    skip = ext < _SKIP_MAX and eps > _SKIP_EPS
    mu = 1e-9 * (ext + 1.0) / eps
    witness = skip and mu < 1e-3
    cx0, cx1, cy0, cy1 = _tiles_bbox(coords, n_tiles)
    wx0, wx1, wy0, wy1 = 0, -1, 0, -1
    if skip and n_tiles > 0 and nb > 0:
        wx0, wx1, wy0, wy1 = _window_extent(box, mx, my, myaw, r_alpha, eps, rl, rh, uc, us, rmax, cx0, cx1, cy0,
                                            cy1, max_window)
    has_window = wx1 >= wx0
    built = False

    nf, ni = ws_nf, ws_ni  # heading nodes
    _set_node(nf, ni, 0, box[4], box[5], mx, my, myaw)
    n_nodes = 1
    n_rows = 0
    if dst.shape[1] < nb:  # pool rows too short for this scan: new pools
        wit = np.empty((wit.shape[0], nb, 4))
        dof = np.empty((wit.shape[0], nb, 4))
        dst = np.empty((wit.shape[0], nb), np.int8)

    cap = max_boxes + 2
    cur, nxt = ws_box[0], ws_box[1]
    cur_n, nxt_n = ws_n[0], ws_n[1]
    if bits.shape[1] < cap + 1 or bits.shape[2] < ((nb + 63) >> 6) + 1:
        bits = np.empty((2, cap + 1, ((nb + 63) >> 6) + 1), np.uint64)
    cur_b, nxt_b = bits[0], bits[1]
    cur_o, nxt_o = ws_o[0], ws_o[1]
    for d in range(6):
        cur[0, d] = box[d]
    cur_n[0] = 0
    cur_b[0, 0] = 0
    n_cur = 1
    tested = 0
    kept = 0
    hull = _empty_hull()
    while n_cur > 0:
        if tested + n_cur > max_boxes:  # out of budget: keep this level as it is
            for j in range(n_cur):
                _join(hull, cur[j])
            kept += n_cur
            break
        if n_rows + n_cur > wit.shape[0]:  # room for this level's new pool rows
            wit, dof, dst = _grown_pools(wit, dof, dst, n_rows, max(2 * wit.shape[0], n_rows + n_cur))
        if has_window and not built and _box_free_possible(cur, cur_n, n_cur, nf, eps, skip):
            nx, ny = wx1 - wx0 + 1, wy1 - wy0 + 1
            if F.shape[0] < nx * ny:
                F = np.empty(nx * ny, np.uint8)
            if S.shape[0] < (nx + 1) * (ny + 1):
                S = np.empty((nx + 1) * (ny + 1), np.uint16)
            _build_window(cells, coords, n_tiles, wx0, wx1, wy0, wy1, F, S)
            built = True
        n_nxt, k, n_nodes, n_rows = _level(cur, cur_n, cur_b, cur_o, nxt, nxt_n, nxt_b, nxt_o, n_cur, cap, hull, nf,
                                           ni, n_nodes, wit, dof, dst, n_rows, keys, slots, cells, eps, F, S, built,
                                           wx0, wx1, wy0, wy1, cx0, cx1, cy0, cy1, rl, rh, rmid, ang, uc, us,
                                           r_alpha, mx, my, myaw, q, min_xy, min_th, reach, skip, witness, mu)
        tested += n_cur
        kept += k
        cur, nxt = nxt, cur
        cur_n, nxt_n = nxt_n, cur_n
        cur_b, nxt_b = nxt_b, cur_b
        cur_o, nxt_o = nxt_o, cur_o
        n_cur = n_nxt
    if kept > 0:
        for d in range(6):
            out[d] = hull[d]
    return kept, tested, wit, dof, dst, F, S, bits


@njit(cache=True)
def _beams(ranges, valid, stride, a0, inc, r_abs, r_rel):
    """The beams tested (every ``stride``-th, those valid) and what does not depend on the
    sub-box: ``(rl, rh, rmid, ang, uc, us, rmax)``, their range bounds (as
    :func:`excluded_beams`), mid-range (NaN for an empty range), angle ``α_i`` and its cos and
    sin, and the largest ``rh`` (``inf`` if one is NaN; 0 with no beam)."""
    nb = 0
    for i in range(0, ranges.shape[0], stride):
        if valid[i]:
            nb += 1
    rl = np.empty(nb)
    rh = np.empty(nb)
    rmid = np.empty(nb)
    ang = np.empty(nb)
    uc = np.empty(nb)
    us = np.empty(nb)
    j = 0
    rmax = 0.0
    for i in range(0, ranges.shape[0], stride):
        if valid[i]:
            rl[j], rh[j] = range_bounds(float(ranges[i]), r_abs, r_rel)
            rmid[j] = 0.5 * (rl[j] + rh[j]) if rl[j] <= rh[j] else math.nan
            ang[j] = a0 + i * inc
            uc[j] = math.cos(ang[j])
            us[j] = math.sin(ang[j])
            rmax = max(rmax, rh[j]) if rh[j] == rh[j] else math.inf
            j += 1
    return rl, rh, rmid, ang, uc, us, rmax


@njit(cache=True)
def _tiles_bbox(coords, n_tiles):
    """The bounding box of the map's ``n_tiles`` tiles in cells, ``(cx0, cx1, cy0, cy1)``
    (empty, ``(0, -1, 0, -1)``, with no tile): a cell outside it is in no tile (unknown)."""
    if n_tiles == 0:
        return 0, -1, 0, -1
    cx0, cx1, cy0, cy1 = coords[0, 0], coords[0, 0], coords[0, 1], coords[0, 1]
    for t in range(1, n_tiles):
        cx0 = min(cx0, coords[t, 0])
        cx1 = max(cx1, coords[t, 0])
        cy0 = min(cy0, coords[t, 1])
        cy1 = max(cy1, coords[t, 1])
    return cx0 * TILE, cx1 * TILE + TILE - 1, cy0 * TILE, cy1 * TILE + TILE - 1


@njit(cache=True)
def _window_extent(box, mx, my, myaw, r_alpha, eps, rl, rh, uc, us, rmax, cx0, cx1, cy0, cy1, max_window):
    """The dense window's cells ``(wx0, wx1, wy0, wy1)`` (empty, ``(0, -1, 0, -1)``, beyond
    ``max_window`` cells): the endpoints from the root box's centre, grown by how far a pose of
    the box, a range of ``[r]`` and a direction of the cone can move them, within the tiles'
    bounding box. An estimate suffices: a region outside the window is looked up in the tiles."""
    tc = 0.5 * (box[4] + box[5])
    sg = tc + myaw
    cs, sn = math.cos(sg), math.sin(sg)
    sx = 0.5 * (box[0] + box[1]) + math.cos(tc) * mx - math.sin(tc) * my
    sy = 0.5 * (box[2] + box[3]) + math.sin(tc) * mx + math.cos(tc) * my
    ex0, ex1, ey0, ey1 = sx, sx, sy, sy
    dr = 0.0
    for j in range(rl.shape[0]):
        px = sx + rh[j] * (cs * uc[j] - sn * us[j])
        py = sy + rh[j] * (sn * uc[j] + cs * us[j])
        ex0, ex1, ey0, ey1 = min(ex0, px), max(ex1, px), min(ey0, py), max(ey1, py)
        dr = max(dr, rh[j] - rl[j])
    grow = (0.5 * (box[1] - box[0]) + 0.5 * (box[3] - box[2]) + dr
            + (abs(mx) + abs(my) + rmax) * (0.5 * (box[5] - box[4]) + r_alpha) + 2.0 * eps)
    if grow < rmax:
        wx0 = max(cx0, math.floor((ex0 - grow) / eps))
        wx1 = min(cx1, math.floor((ex1 + grow) / eps))
        wy0 = max(cy0, math.floor((ey0 - grow) / eps))
        wy1 = min(cy1, math.floor((ey1 + grow) / eps))
    else:
        rsb = sensor_box(box[0], box[1], box[2], box[3], box[4], box[5], mx, my, myaw)
        wx0 = max(cx0, math.floor((rsb[0] - rmax) / eps) - 2)
        wx1 = min(cx1, math.floor((rsb[1] + rmax) / eps) + 2)
        wy0 = max(cy0, math.floor((rsb[2] - rmax) / eps) - 2)
        wy1 = min(cy1, math.floor((rsb[3] + rmax) / eps) + 2)
    if wx1 < wx0 or wy1 < wy0 or (wx1 - wx0 + 1) * (wy1 - wy0 + 1) > max_window:
        return 0, -1, 0, -1
    return wx0, wx1, wy0, wy1


@njit(cache=True)
def _grown_pools(wit, dof, dst, n_rows, rows):
    """The pools with ``rows`` rows, their first ``n_rows`` kept."""
    w2 = np.empty((rows, dst.shape[1], 4))
    w2[:n_rows] = wit[:n_rows]
    o2 = np.empty((rows, dst.shape[1], 4))
    o2[:n_rows] = dof[:n_rows]
    s2 = np.empty((rows, dst.shape[1]), np.int8)
    s2[:n_rows] = dst[:n_rows]
    return w2, o2, s2


_WS = threading.local()


def _workspace(max_boxes: int):
    """This thread's workspace for :func:`contract_kernel` (box and node arrays sized for
    ``max_boxes``; pools and window as the last call left them)."""
    ws = getattr(_WS, "ws", None)
    cap = max_boxes + 2
    if ws is None or ws["box"].shape[1] < cap:
        ws = {"box": np.empty((2, cap, 6)), "n": np.empty((2, cap), np.int64), "o": np.empty((2, cap + 1, 3)),
              "nf": np.empty((2 * max_boxes + 3, _NF)), "ni": np.empty((2 * max_boxes + 3, 2), np.int64),
              "wit": np.empty((8, 1, 4)), "dof": np.empty((8, 1, 4)), "dst": np.empty((8, 1), np.int8),
              "F": np.empty(1, np.uint8), "S": np.empty(1, np.uint16), "bits": np.empty((2, 1, 1), np.uint64)}
        _WS.ws = ws
    return ws


def contract_pose(tmap, scans, k: int, robot_box, bounds, *, q: int = 0, stride: int = 1, min_xy: float = 0.02,
                  min_th: float = 0.005, reach: float = 4.0, max_boxes: int = 4096, reference: bool = False,
                  window_cells: int = MAX_WINDOW_CELLS):
    """Contract the robot pose box (6,) of scan ``k`` against ``tmap`` (see the module docstring).

    Returns ``(box, kept, tested)``: the contracted box (the input box when no sub-box is kept,
    ``kept == 0``: the scan contradicts the map beyond ``q``). ``reference``: run
    :func:`contract_kernel_reference` (hash lookups cell by cell) instead of
    :func:`contract_kernel`; the results are the same. ``window_cells``: the fast path's dense
    window at most (0: none; the results are the same)."""
    from ivslam_cli.interval.rounding import ensure_round_to_nearest

    ensure_round_to_nearest()
    bounds.check()
    b0, b1 = int(scans.offsets[k]), int(scans.offsets[k + 1])
    box = np.ascontiguousarray(robot_box, dtype=np.float64).reshape(6)
    out = box.copy()
    mx, my, myaw = (float(v) for v in scans.mount)
    keys, slots, cells, coords, n = tmap.arrays()
    args = (float(tmap.eps), scans.ranges[b0:b1], scans.valid[b0:b1], float(scans.angle_min[k]),
            float(scans.angle_increment[k]), box, mx, my, myaw, float(bounds.range_abs), float(bounds.range_rel),
            float(bounds.bearing), int(q), int(stride), float(min_xy), float(min_th), float(reach), int(max_boxes),
            out)
    if reference:
        kept, tested = contract_kernel_reference(keys, slots, cells, *args)
    else:
        ws = _workspace(int(max_boxes))
        kept, tested, *pools = contract_kernel(keys, slots, cells, coords, int(n), *args, int(window_cells),
                                               ws["box"], ws["n"], ws["o"], ws["nf"], ws["ni"], ws["wit"], ws["dof"],
                                               ws["dst"], ws["F"], ws["S"], ws["bits"])
        ws["wit"], ws["dof"], ws["dst"], ws["F"], ws["S"], ws["bits"] = pools
    return out, int(kept), int(tested)


__all__ = ["MAX_REGION_CELLS", "contract_kernel", "contract_kernel_reference", "contract_pose", "excluded_beams"]
