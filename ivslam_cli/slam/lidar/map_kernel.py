"""Map-update kernels of the feature-less LiDAR SLAM, fast path (numba, outward rounding).

P_EMPTY^k (inner), P_OBSTACLE^k (outer), the old/new test and the map update of one scan from a
sensor pose box, as defined in :mod:`.map_reference` (after the "Guaranteed SLAM – practical
considerations" slides, University of Manchester). ``traverse`` / ``apply`` / ``update_log`` /
``scan_cells`` give the reference's cells, beams, flags, tiles (in the same order) and counts,
bit for bit (``tests/test_lidar_map.py``, ``bench/bench_lidar_map.py``), with fewer and cheaper
tests:

- one interleaved sparse table per scan (:mod:`.map_tables`: range lo, range hi, free range,
  its max, and the gap between consecutive valid beams): a window's summary costs two cache
  lines, and "does a beam of this window meet this range interval" is O(1) unless the window
  holds a jump larger than the interval (``_meets``; searched by halving then, ``_meets_g``);
- blocks away from the sensor box and from the back of the scan ("simple": one branch of the
  bearings, :mod:`.map_blocks`) are tested with an *outer* window of beam indices that holds
  the reference window of each of their cells whatever the roundings (fast bearings, ATAN_ERR
  and rounding margins): proven empty, or pruned when no beam of it meets the block's range
  interval and no cell can be proven free (``_inner``'s lower bound of every cell's largest
  range against the free ranges of beams in every cell's window), or proven all-P_OBSTACLE^k
  at once (``_inner``'s certificate) instead of being refined to single cells; blocks that are
  not simple (around the sensor box, the back of the scan) get the reference's block test;
- a cell's reference window is computed from fast bearings when every index is farther from a
  rounding boundary than the error allows (``_geom1``), else exactly as the reference;
- the tiles of a scan are visited together (chunks of :data:`_CHUNK`), level by level, a
  level in two stages: the geometry of all its blocks, or of all cells, in one vectorised pass
  (``_level_geom``, ``_cell_geom``: 8 blocks at a time with AVX-512), then the decisions block
  by block (:func:`_decide_blocks`, :func:`_decide_cells`), the blocks to refine listed for the
  next level. Records of a tile come in another order than the reference's; tiles in the same
  (:func:`_tiles_in_order`);
- the writes (:mod:`.map_write`) decide whole blocks where their window allows.

Hot helpers are inlined (``inline="always"``: a call with a dozen array arguments costs more
than their geometry) and take scalars where they can (an array made in the caller and passed to
an inlined helper gets its reference count changed, atomically, on every use: ~20 %). The
functions that stay calls (the stages of a level, the rare exact cell tests, the writes) never
allocate and are compiled with numba's private ``_nrt=False`` option: without it numba
increments and decrements the reference count of every array argument on each call, which made
the bench log ~25 % slower, and inside them inlined helpers count no references either. A numba
upgrade that drops the option breaks them at compile time.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.interval.rounding import INF, down, up
from ivslam_cli.paving.tiles import TILE, TILE_MASK, TILE_SHIFT, find
from ivslam_cli.slam.lidar.geometry import FIN_MAX, beam_window, box_bearings, dn, upf
from ivslam_cli.slam.lidar.map_blocks import (
    _axis_table,
    _cell,
    _cell_geom,
    _cell_window,
    _classify,
    _inner_consts,
    _level_consts,
    _level_geom,
    _scan_angles,
)
# the oracle, importable from here too (the tests and bench/bench_lidar_map.py compare the two)
from ivslam_cli.slam.lidar.map_reference import scan_cells_reference, update_log_reference  # noqa: F401
from ivslam_cli.slam.lidar.map_tables import (
    _LEVELS,
    _block_cells,
    _cos_gap,
    _fast_buffers,
    _fast_tables,
    _meets,
    _meets_g,
    _tile_range,
    _unmeasured,
    _win,
)
from ivslam_cli.slam.lidar.map_write import apply


@njit(cache=True, _nrt=False)
def _scan_new(T, o_lo, o_hi, r_lo, r_hi, new, st):
    """Mark every beam of ``[o_lo, o_hi]`` meeting ``[r_lo, r_hi]`` as new."""
    for i in range(o_lo, o_hi + 1):
        st[2] += 1
        if T[0, i, 0] <= r_hi and T[0, i, 1] >= r_lo:
            new[i] = True


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
             exact, lg, T, new, tl, blk, mblk, cand, cand_f, stats, WF, WI, fill=True, smin=0.0, obstacles=True):
    """P_EMPTY^k, P_OBSTACLE^k and the new beams of one scan (fast path; the same cells and
    beams as :func:`~.map_reference.traverse_reference`). ``T``: the scan's table
    (:func:`~.map_tables._fast_tables`); ``WF, WI``: work arrays (:func:`_level_buffers`). The
    cells' sides and offsets from the sensor box come from per-axis tables
    (:func:`~.map_blocks._axis_table`: the same roundings, once per column and row). The tiles
    are visited together (by chunks of :data:`_CHUNK`), level by level, each level in two
    stages: the geometry of all its blocks (or cells) in a vectorised pass
    (:func:`~.map_blocks._level_geom`, :func:`~.map_blocks._cell_geom`), then their decisions
    one by one (:func:`_decide_blocks`, :func:`_decide_cells`); the tiles' slots are put back in
    the order of a visit tile by tile at the end (:func:`_tiles_in_order`).

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

    ``smin``: no cell nearer than this to the sensor box is proven empty
    (:func:`~.free_cones.sweep_free_from`: the beams of a sweep are taken from poses apart).
    ``obstacles`` False: P_EMPTY^k alone (the same empty records; blocks are refined only where
    a cell may be proven empty, and nothing of P_OBSTACLE^k or ``new`` is recorded).

    Returns ``(ok, n_tl, n_blk, n_mblk, n_cand, need)``; ``ok`` False: a buffer was too small
    (``need`` > 0: the work arrays, which need that many columns; ``new`` and ``stats`` are then
    partial: grow the buffers, reset them, run again).
    """
    nb = ranges.shape[0]
    h = max(r_alpha, 0.5 * inc)
    rmax = _fast_tables(ranges, valid, r_abs, r_rel, _cos_gap(r_alpha, inc, fill), T)
    if rmax == -INF:
        return True, 0, 0, 0, 0, 0
    if not (abs(box[0]) + abs(box[1]) + abs(box[2]) + abs(box[3]) + 2.0 * rmax + 4.0 * TILE * eps < FIN_MAX):
        # the tile index (int32 tile coordinates) bounds a map far below this
        raise ValueError("lidar map: coordinates or ranges beyond 1e150")
    mid, lo_edge, hi_edge, err = _scan_angles(box, a0, inc, h, nb)
    pxl, pxh, pyl, pyh, thl, thh = box[0], box[1], box[2], box[3], box[4], box[5]
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
        return False, 0, 0, 0, 0, _CHUNK
    # the tiles in the reference's order (rank = column-major over the scan's tile range), by
    # chunks: the map index of the chunk's tiles and their slot in ``tl`` (-1: no record yet)
    nty = ty1 - ty0 + 1
    n_tiles = (tx1 - tx0 + 1) * nty
    TT = np.empty(_CHUNK, dtype=np.int64)
    TS = np.empty(_CHUNK, dtype=np.int64)
    sc = (eps, a0, inc, h, nb, rmax, mid, lo_edge, hi_edge, err, gmin_c, i0, j0, nty, smin, obstacles)
    rec = (tl, blk, mblk, cand, cand_f)
    G = (RL, RH, OL, OH, EL, EH, CV, SM, X0, X1, Y0, Y1, IL, IH, KL, KH)
    n_tl = 0
    n_blk = 0
    n_mblk = 0
    n_cand = 0
    nodes = 0
    n_empty = 0
    n_obst = 0
    for q0 in range(0, n_tiles, _CHUNK):  # a chunk of tiles, level by level
        n_lev = _chunk_roots(keys, slots, q0, min(q0 + _CHUNK, n_tiles), nty, tx0, ty0, LX, LY, TT, TS)
        lev = _LEVELS
        while lev > 0 and n_lev > 0:
            if 4 * n_lev > cap:
                return False, n_tl, n_blk, n_mblk, n_cand, 4 * n_lev
            inner = LC[lev, 2] < iw_min + 0.5 * eps  # else cells too far apart for a common bearing
            _level_geom(n_lev, 1 << lev, LX, LY, CX, CY, thl, thh, a0, inv_inc, h, nb, mid, lo_edge, hi_edge,
                        err, DXL, DXH, DYL, DYH, RL, RH, OL, OH, EL, EH, CV, SM, inner, X0, X1, Y0, Y1, IL, IH,
                        KL, KH, eps, pxl, pxh, pyl, pyh, icx, icy, iwx, iwy, irc, amg, LC[lev, 0], LC[lev, 1],
                        LC[lev, 2], LC[lev, 3])
            ok, n_next, n_tl, n_blk, n_mblk, d_nodes, d_empty, d_obst = _decide_blocks(
                lev, n_lev, q0, inner, exact, sc, LX, LY, NX, NY, G, T, lg, cells, box, TT, TS, rec,
                (n_tl, n_blk, n_mblk), new, stats)
            if not ok:
                return False, n_tl, n_blk, n_mblk, n_cand, 0
            nodes += d_nodes
            n_empty += d_empty
            n_obst += d_obst
            LX, NX = NX, LX
            LY, NY = NY, LY
            n_lev = n_next
            lev -= 1
        if lev > 0 or n_lev == 0:
            continue
        # the cells: geometry of all, then the reference's leaf decisions
        _cell_geom(n_lev, LX, LY, CX, CY, thl, thh, a0, h, nb, mid, lo_edge, hi_edge, err, inv_inc,
                   DXL, DXH, DYL, DYH, RL, RH, OL, OH, EL, EH, CV, SM)
        ok, n_tl, n_blk, n_cand, d_nodes, d_empty, d_obst = _decide_cells(
            n_lev, q0, exact, sc, LX, LY, G, T, lg, cells, box, TT, TS, rec, (n_tl, n_blk, n_cand), new, stats)
        if not ok:
            return False, n_tl, n_blk, n_mblk, n_cand, 0
        nodes += d_nodes
        n_empty += d_empty
        n_obst += d_obst
    _tiles_in_order(tl, n_tl, tx0, ty0, nty, blk, n_blk, mblk, n_mblk, cand, n_cand)
    stats[0] += nodes
    stats[1] += n_empty
    stats[3] += n_obst
    return True, n_tl, n_blk, n_mblk, n_cand, 0


@njit(cache=True, _nrt=False)
def _chunk_roots(keys, slots, q0, q1, nty, tx0, ty0, LX, LY, TT, TS):
    """The roots of tiles ``q0 .. q1 - 1`` (ranks in the scan's tile range) as the first level:
    their columns and rows in the axis tables into ``LX, LY``, their map index into ``TT``
    (-1: no tile), no slot yet in ``TS``. Returns their count."""
    n_lev = 0
    for q in range(q0, q1):
        LX[n_lev] = (q // nty) * TILE
        LY[n_lev] = (q % nty) * TILE
        TT[n_lev] = find(keys, slots, tx0 + q // nty, ty0 + q % nty)
        TS[n_lev] = -1
        n_lev += 1
    return n_lev


@njit(cache=True, _nrt=False)
def _decide_blocks(lev, n_lev, q0, inner, exact, sc, LX, LY, NX, NY, G, T, lg, cells, box, TT, TS, rec, n_rec,
                   new, stats):
    """The decisions on the ``n_lev`` blocks of ``2^lev`` cells of a level (their geometry in
    ``G``, from :func:`~.map_blocks._level_geom`): proven empty (into ``blk``), every cell in
    P_OBSTACLE^k (into ``mblk``, the beams of their unmeasured cells marked new), pruned, or
    refined (the four quarters listed in ``NX, NY``). ``sc``: the scan's constants (see
    :func:`traverse`), ``rec = (tl, blk, mblk, cand, cand_f)`` with ``n_rec = (n_tl, n_blk,
    n_mblk)`` records so far. Returns ``(ok, n_next, n_tl, n_blk, n_mblk, nodes, empty cells,
    obstacle cells)``; ``ok`` False: a record buffer is full."""
    eps, a0, inc, h, nb, rmax, mid, lo_edge, hi_edge, err, gmin_c, i0, j0, nty, smin, obstacles = sc
    RL, RH, OL, OH, EL, EH, CV, SM, X0, X1, Y0, Y1, IL, IH, KL, KH = G
    tl, blk, mblk, cand, cand_f = rec
    n_tl, n_blk, n_mblk = n_rec
    pxl, pxh, pyl, pyh, thl, thh = box[0], box[1], box[2], box[3], box[4], box[5]
    cap_blk = blk.shape[0]
    cap_mblk = mblk.shape[0]
    s = 1 << lev
    half = s >> 1
    nodes = 0
    n_empty = 0
    n_obst = 0
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
                o_lo, o_hi, e_lo, e_hi, cover = beam_window(down(bl - thh), up(bh - thl), a0, inc, h, nb)
        if o_lo > o_hi:
            continue
        lo_min, hi_max, f_min, f_max = _win(T, lg, o_lo, o_hi)
        if cover and (e_lo != o_lo or e_hi != o_hi):
            f_min = _win(T, lg, e_lo, e_hi)[2]
        if cover and r_hi < f_min and r_lo >= smin:
            slot = _tile_slot(tl, n_tl, TS[q], ix >> TILE_SHIFT, iy >> TILE_SHIFT, 1)
            if slot < 0 or n_blk >= cap_blk:
                return False, n_next, n_tl, n_blk, n_mblk, nodes, n_empty, n_obst
            TS[q] = slot
            n_tl = max(n_tl, slot + 1)
            blk[n_blk, 0], blk[n_blk, 1], blk[n_blk, 2], blk[n_blk, 3] = ix, iy, lev, slot
            n_blk += 1
            n_empty += s * s
            continue
        freep = r_lo < f_max
        obs = obstacles and r_hi >= lo_min and r_lo <= hi_max
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
                # no cell can be proven empty: its window reaches outside the scan, or its
                # largest range reaches the free range of a beam in every window
                if freep and (u_lo < 0 or u_hi > nb - 1 or k_hi >= if_min):
                    freep = False
                # every cell is in P_OBSTACLE^k when a beam of [i_lo, i_hi] meets the range
                # interval of each cell centre: one beam with lo <= k_hi and hi >= k_lo, or the
                # hull reaching them all with no jump wider than the narrowest, at least the
                # box's smaller side (see _inner_consts)
                if obs and i_lo <= i_hi and _meets_g(T, lg, i_lo, i_hi, k_hi, k_lo, ilo_min, ihi_max,
                                                     max(gmin_c, down(k_hi - k_lo)), stats):
                    slot = _tile_slot(tl, n_tl, TS[q], ix >> TILE_SHIFT, iy >> TILE_SHIFT, 2)
                    if slot < 0 or n_mblk >= cap_mblk:
                        return False, n_next, n_tl, n_blk, n_mblk, nodes, n_empty, n_obst
                    TS[q] = slot
                    n_tl = max(n_tl, slot + 1)
                    mblk[n_mblk, 0], mblk[n_mblk, 1], mblk[n_mblk, 2] = ix, iy, lev
                    mblk[n_mblk, 3], mblk[n_mblk, 4], mblk[n_mblk, 5] = o_lo, o_hi, slot
                    n_mblk += 1
                    n_obst += s * s
                    _block_new(cells, TT[q], ix, iy, s, eps, box, a0, inc, h, nb, rmax, mid, lo_edge, hi_edge, err,
                               T, new, stats)
                    continue
        if not obs and not freep:
            continue
        # refine: the four quarters at the next level (cells at level 0)
        NX[n_next], NY[n_next] = gx, gy
        NX[n_next + 1], NY[n_next + 1] = gx + half, gy
        NX[n_next + 2], NY[n_next + 2] = gx, gy + half
        NX[n_next + 3], NY[n_next + 3] = gx + half, gy + half
        n_next += 4
    return True, n_next, n_tl, n_blk, n_mblk, nodes, n_empty, n_obst


@njit(cache=True, inline="always")
def _block_new(cells, t, ix, iy, s, eps, box, a0, inc, h, nb, rmax, mid, lo_edge, hi_edge, err, T, new, stats):
    """The beams of the unmeasured cells of a block of P_OBSTACLE^k (``s x s`` cells from
    ``(ix, iy)``, map tile index ``t``) marked new: each such cell's reference window
    (:func:`~.map_blocks._cell_window`) and range interval, beam by beam."""
    lx = ix & TILE_MASK
    ly = iy & TILE_MASK
    for a in range(lx, lx + s):
        for b in range(ly, ly + s):
            if _unmeasured(cells, t, a, b):
                c_lo, c_hi, _, _, _, q_lo, q_hi = _cell_window(ix - lx + a, iy - ly + b, eps, box, a0, inc, h, nb,
                                                               rmax, mid, lo_edge, hi_edge, err)
                _scan_new(T, c_lo, c_hi, q_lo, q_hi, new, stats)


@njit(cache=True, _nrt=False)
def _decide_cells(n_lev, q0, exact, sc, LX, LY, G, T, lg, cells, box, TT, TS, rec, n_rec, new, stats):
    """The reference's leaf decisions on the ``n_lev`` cells of a chunk (their geometry in
    ``G``, from :func:`~.map_blocks._cell_geom`, or :func:`~.map_blocks._cell` where it left
    the window undecided): proven empty (into ``blk``), in P_OBSTACLE^k or only its hull test
    passed (into ``cand``, the beams of unmeasured marked cells set new). ``n_rec = (n_tl, n_blk,
    n_cand)``. Returns ``(ok, n_tl, n_blk, n_cand, nodes, empty cells, obstacle cells)``; ``ok``
    False: a record buffer is full."""
    eps, a0, inc, h, nb, rmax, mid, lo_edge, hi_edge, err, gmin_c, i0, j0, nty, smin, obstacles = sc
    RL, RH, OL, OH, EL, EH, CV, SM = G[0], G[1], G[2], G[3], G[4], G[5], G[6], G[7]
    tl, blk, mblk, cand, cand_f = rec
    n_tl, n_blk, n_cand = n_rec
    cap_blk = blk.shape[0]
    cap_cand = cand.shape[0]
    nodes = 0
    n_empty = 0
    n_obst = 0
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
            code, o_lo, o_hi, r_lo, r_hi = _cell(cx_, cy_, eps, box, a0, inc, h, nb, rmax, mid, lo_edge, hi_edge,
                                                 T, lg, stats)
        if code == 0 or (code == 2 and exact) or (code == 1 and r_lo < smin) or (code != 1 and not obstacles):
            continue
        if code == 1:
            slot = _tile_slot(tl, n_tl, TS[q], cx_ >> TILE_SHIFT, cy_ >> TILE_SHIFT, 1)
            if slot < 0 or n_blk >= cap_blk:
                return False, n_tl, n_blk, n_cand, nodes, n_empty, n_obst
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
            return False, n_tl, n_blk, n_cand, nodes, n_empty, n_obst
        TS[q] = slot
        n_tl = max(n_tl, slot + 1)
        cand[n_cand, 0], cand[n_cand, 1] = cx_, cy_
        cand[n_cand, 2], cand[n_cand, 3] = o_lo, o_hi
        cand[n_cand, 4], cand[n_cand, 5] = (1 if marked else 0), slot
        cand_f[n_cand, 0], cand_f[n_cand, 1] = r_lo, r_hi
        n_cand += 1
        n_obst += 1
    return True, n_tl, n_blk, n_cand, nodes, n_empty, n_obst


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
                    new, tl, blk, mblk, cand, cand_f, st, WF, WI, fill, smin, obstacles=True):
    """:func:`traverse` of one scan, its record buffers and work arrays grown (and ``new``,
    ``st`` reset) until they hold the scan: ``(n_tl, n_blk, n_mblk, n_cand, tl, blk, mblk, cand,
    cand_f, WF, WI)``."""
    nb = ranges.shape[0]
    while True:
        new[:nb] = False
        st[:] = 0
        ok, n_tl, n_blk, n_mblk, n_cand, need = traverse(keys, slots, cells, ranges, valid, a0, inc, box, r_abs,
                                                         r_rel, r_alpha, eps, exact, lg, T, new, tl, blk, mblk,
                                                         cand, cand_f, st, WF, WI, fill, smin, obstacles)
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


@njit(cache=True, nogil=True)
def update_log(keys, slots, cells, coords, n, ranges, valid, offsets, angle_min, angle_inc,
               boxes, order, r_abs, r_rel, r_alpha, eps, exact, write, is_old, scan_stats, fill, smin):
    """Process scans ``order`` (in that order) from sensor boxes ``boxes`` (S, 6), no cell of scan
    ``s`` nearer than ``smin[s]`` to its box proven empty (see :func:`traverse`): the same map,
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
            r_alpha, eps, exact, lg, T, new, tl, blk, mblk, cand, cand_f, st, WF, WI, fill, smin[s])
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
def scan_cells(ranges, valid, a0, inc, box, r_abs, r_rel, r_alpha, eps, exact, fill=True, smin=0.0, obstacles=True):
    """P_EMPTY^k and P_OBSTACLE^k of one scan as cell index arrays (for tests and plots):
    ``(empty_ix, empty_iy, obst_ix, obst_iy)`` (the cells of :func:`scan_cells_reference`,
    in another order; ``obstacles`` False: no P_OBSTACLE^k cells, the same P_EMPTY^k)."""
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
        mblk, cand, cand_f, st, WF, WI, fill, smin, obstacles)
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
