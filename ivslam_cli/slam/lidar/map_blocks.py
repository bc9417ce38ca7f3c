"""Geometry of the fast path's blocks and cells (LiDAR map update, :mod:`.map_kernel`).

Per level of a tile's quadtree, the geometry of every block (or cell) in one pass written with
selects only, which the compiler vectorises (:func:`_level_geom`, :func:`_cell_geom`): range
interval, fast bearings (:func:`~.geometry.box_bearings_fast`, error below ``ATAN_ERR``) and the
window of beam indices they give, with margins:

- a block is *simple* when its fast bearings minus ``[θ]`` lie in one branch near the scan's
  middle and no other branch meets the scan's cones; its *outer* window then holds the
  reference's window of each of its cells whatever the roundings (the reference:
  :mod:`.map_reference`);
- :func:`_inner`: a window of beams in *every* cell's window and a range interval inside every
  cell's, from real geometry with margins far above every rounding (a certificate that every
  cell of the block is in P_OBSTACLE^k, or that none can be proven empty);
- a cell's window from fast bearings is the reference's when every index is farther from a
  rounding boundary than the error allows (:func:`_geom1`); else :func:`_cell_window` computes
  it as the reference does, and :func:`_classify` makes the reference's leaf decision.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval.rounding import down, up
from ivslam_cli.slam.lidar.geometry import (
    ATAN_ERR,
    atan2_fast,
    beam_window,
    box_bearings,
    box_bearings_fast,
    box_ranges,
    box_ranges_fin,
    dn,
    upf,
    window_in_branch,
)
from ivslam_cli.slam.lidar.map_tables import _LEVELS, _meets, _win


@njit(cache=True, inline="always")
def _scan_angles(box, a0, inc, h, nb):
    """A scan's constants for windows from fast bearings: ``(mid, lo_edge, hi_edge, err)``, the
    middle of its beam angles, the outer edges of its cones ``a0 - h`` and ``a_end + h`` rounded
    outward, and a bound on the error of a fast bearing minus ``[θ]`` (sensor box ``box``)
    against the reference's (ATAN_ERR and the roundings)."""
    a_end = a0 + (nb - 1) * inc
    mid = 0.5 * (a0 + a_end)
    lo_edge = down(a0 - h)
    hi_edge = up(up(a_end + h))
    err = ATAN_ERR + 1e-12 * (8.0 + abs(box[4]) + abs(box[5]))
    return mid, lo_edge, hi_edge, err


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

    The bearings come from :func:`box_bearings_fast`; the reference's window is ``ceil /
    floor`` of ``(bearing -/+ theta -/+ h - a0) / inc`` after a shift by ``2 pi m`` (the beams
    whose cones meet the bearings): when the approximate value is farther than ``err / inc``
    (``err``: ATAN_ERR plus every rounding of the reference's chain) from an integer, the
    ceil / floor are those of the exact value, and so are the branch and the "other branch"
    test when farther than ``err`` from their limits.
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
    f_lo = math.ceil(u_lo - d)
    f_hi = math.floor(u_hi + d)
    und = bad or f_lo != math.ceil(u_lo + d) or f_hi != math.floor(u_hi - d)
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
        e_lo = int(math.ceil(u_lo if ok else 0.0))
        e_hi = int(math.floor(u_hi if ok else -1.0))
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
