"""Reference scans for the matcher (:mod:`.matcher`): rows of free cones (rule A) and witness
rectangles (rule B).

A reference scan (the submap's anchor, the last scan mapped into it) proves free space with its
cones, and a surface point in the end-point region of each of its beams. A swept reference (its
beams taken one after another while the robot moves, :class:`~.prediction.SweepModel`) is cut
into the runs of beams :mod:`.sweep_map` maps it in, each from its own robot box (moved by its
beams' nominal move, widened by their spread and the move's error; not by the whole sweep's
move): one row per run, free ranges for its own beams only (a run proves free only the bearings
its own cones cover), and witnesses from the run's box.

A beam of the matched scan is tested against every reference scan; its runs share the bearing
of a point but for their sensors' offsets, so :func:`runs_may_cover` takes one arctangent per
scan and keeps the runs whose beams that bearing may fall among; each is then tested alone.
The matched scan's own cones (rule B) come in runs the same way (:func:`own_runs`). Dropping a
run only drops evidence against a pose (fewer beams break a rule): it can widen the kept set,
never lose the truth.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.slam.lidar.free_cones import _QUICK_COORD, _cover_setup, free_of
from ivslam_cli.slam.lidar.geometry import MARGIN_ABS, atan2_fast, beam_region, range_bounds, sensor_box, upf
from ivslam_cli.slam.lidar.sweep_map import chunk_boxes, swept_box

#: columns of a row (``ref_c``, and ``own_c`` of :func:`own_runs`): the sensor's centre, its
#: radius, where its cones start proving (``smin``), the row's first beam in its scan and its
#: beams, :func:`~.free_cones._cover_setup`'s constants (1/inc, centre angle, index margin,
#: usable, cone half-width / inc), the heading's centre; in a scan's first row also its runs,
#: its beams, its centre angle, whether it spans less than a turn, and how far (the slack) its
#: runs' sensors (and radii) and headings' centres are from its middle run's; the row's first
#: beam's angle; for the matched scan's own runs, their nominal move (sensor frame), its length
#: and the spread of their beams' moves about it
(C_X, C_Y, C_RAD, C_SMIN, C_I0, C_N, C_II, C_AC, C_MI, C_OK, C_RR, C_TH, C_RUNS, C_NB, C_SAC, C_SOK, C_SLACK,
 C_DTH, C_A0, C_OX, C_OY, C_OL, C_SPREAD) = range(23)
N_COLS = 23


@njit(cache=True, nogil=True)
def witness_segments(ranges, valid, a0, inc, box, mx, my, myaw, r_abs, r_rel, r_alpha, stride, out):
    """Rectangles ``out`` (k, 6: centre x, y, axis x, y, half-length, half-width) holding the end
    points of the valid beams (every ``stride``-th) of a scan taken from robot box ``box`` (6,)
    in the frame: each holds a surface point. Returns k."""
    sxl, sxh, syl, syh, stl, sth = sensor_box(box[0], box[1], box[2], box[3], box[4], box[5], mx, my, myaw)
    c = 0.5 * (stl + sth)
    d = upf(upf(upf(0.5 * (sth - stl)) + 1e-15 * abs(c) + 1e-300) + r_alpha)
    if not d < 1.0:
        return 0
    cc, sc = math.cos(c), math.sin(c)
    ccx, ccy = 0.5 * (sxl + sxh), 0.5 * (syl + syh)
    rs = upf(0.5 * upf(math.hypot(sxh - sxl, syh - syl))) + MARGIN_ABS
    k = 0
    for i in range(0, ranges.shape[0], stride):
        if not valid[i]:
            continue
        rl, rh = range_bounds(float(ranges[i]), r_abs, r_rel)
        ang = a0 + i * inc
        cx, cy, ux, uy, ah, ac, _, _ = beam_region(ccx, ccy, cc, sc, math.cos(ang), math.sin(ang), rl, rh, d)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = cx, cy, ux, uy
        out[k, 4], out[k, 5] = upf(ah + rs), upf(ac + rs)
        k += 1
    return k


@njit(cache=True, inline="always")
def runs_may_cover(cx, cy, ux, uy, base, ref_c, g):
    """The rows ``g + t0 .. g + t1`` of reference scan ``g``'s runs whose beams the point ``(cx,
    cy) + (base + radius) u`` (``radius`` the run's sensor radius) may fall among, from one
    arctangent for the scan: its runs' sensors are within the scan's slack of its middle run's.
    ``(0, −1)`` when none; every run when there is no shortcut. The caller then tests each with
    :func:`~.free_cones._may_cover` and :func:`~.free_cones._seg_free`."""
    c = ref_c[g]
    P = int(c[C_RUNS])
    o = ref_c[g + P // 2]  # the bearings from the middle run's sensor
    e = base + o[C_RAD]
    px, py = cx + e * ux, cy + e * uy
    if not (c[C_SOK] > 0.0 and abs(px) + abs(py) + abs(o[C_X]) + abs(o[C_Y]) < _QUICK_COORD):
        return 0, P - 1
    dx = px - o[C_X]
    dy = py - o[C_Y]
    rho = math.hypot(dx, dy)
    shift = c[C_SLACK]
    if not (rho > 1e-3 and shift < 0.5 * rho):
        return 0, P - 1
    b = atan2_fast(dy, dx) - o[C_TH]
    sac = c[C_SAC]
    if not abs(b - sac) < 64.0:
        return 0, P - 1
    while b - sac >= math.pi:
        b -= 2.0 * math.pi
    while b - sac < -math.pi:
        b += 2.0 * math.pi
    j = (b - c[C_A0]) * c[C_II]
    m = (0.5 * math.pi * shift / rho + c[C_DTH]) * c[C_II] + c[C_MI] + c[C_RR] + 1.0
    i_lo = max(math.ceil(j - m), 0)
    i_hi = min(math.floor(j + m), int(c[C_NB]) - 1)
    if i_lo > i_hi:
        return 0, -1
    t0 = 0
    while t0 < P - 1 and i_lo >= ref_c[g + t0, C_I0] + ref_c[g + t0, C_N]:
        t0 += 1
    t1 = t0
    while t1 < P - 1 and i_hi >= ref_c[g + t1 + 1, C_I0]:
        t1 += 1
    return t0, t1


@njit(cache=True)
def own_runs(free, off, a0, inc, r_alpha, smin, n_runs):
    """The matched scan's own free cones (rule B) in ``n_runs`` runs of beams (as
    :mod:`.sweep_map` cuts them), each beam's sensor moved by ``off`` (B, 2, sensor frame):
    rows (``own_c`` of :data:`N_COLS` columns, ``own_f`` their free ranges), each run's nominal
    move the middle of its beams' and its spread their farthest from it (rounded up). No rows
    when no beam moves (the scan's cones from its box widened by the whole sweep)."""
    nb = free.shape[0]
    moves = off.shape[0] == nb and nb > 0
    if moves:
        moves = False
        for i in range(nb):
            if off[i, 0] != 0.0 or off[i, 1] != 0.0:
                moves = True
    P = min(n_runs, nb) if moves else 0
    width = 1
    for p in range(P):
        width = max(width, (p + 1) * nb // P - p * nb // P)
    own_c = np.zeros((P, N_COLS))
    own_f = np.full((max(P, 1), width), -1.0)
    for p in range(P):
        i0, i1 = p * nb // P, (p + 1) * nb // P
        c = own_c[p]
        lx, hx, ly, hy = off[i0, 0], off[i0, 0], off[i0, 1], off[i0, 1]
        for i in range(i0, i1):
            lx, hx, ly, hy = min(lx, off[i, 0]), max(hx, off[i, 0]), min(ly, off[i, 1]), max(hy, off[i, 1])
            own_f[p, i - i0] = free[i]
        c[C_OX], c[C_OY] = 0.5 * (lx + hx), 0.5 * (ly + hy)
        c[C_OL] = upf(math.hypot(c[C_OX], c[C_OY]) * (1.0 + 1e-12))
        sp = 0.0
        for i in range(i0, i1):
            sp = max(sp, math.hypot(off[i, 0] - c[C_OX], off[i, 1] - c[C_OY]))
        c[C_SPREAD] = upf(sp * (1.0 + 1e-12) + 1e-15)
        c[C_I0], c[C_N], c[C_A0], c[C_SMIN] = i0, i1 - i0, a0 + i0 * inc, smin
        c[C_II], c[C_AC], c[C_MI], ok, c[C_RR] = _cover_setup(width, a0 + i0 * inc, inc, r_alpha)
        c[C_OK] = 1.0 if ok else 0.0
    if P > 0:
        g = own_c[0]
        g[C_RUNS], g[C_NB], g[C_SAC] = P, nb, a0 + 0.5 * (nb - 1) * inc
        g[C_SOK] = 1.0 if inc >= 1e-5 and (nb - 1) * inc < 2.0 * math.pi - 1e-3 else 0.0
    return own_c, own_f


@njit(cache=True, inline="always")
def own_runs_at(own_c, ccx, ccy, cc, sc, c, rs, hw):
    """The own runs' sensors for a sub-box whose sensor (at the scan's pose) is within ``rs`` of
    ``(ccx, ccy)``, its heading within ``hw`` of ``c`` (``cc``, ``sc`` its cosine and sine): each
    run's moved by its nominal move turned with the heading, widened by the move's lever over
    ``hw`` and the run's spread; and the runs' slack about the middle one."""
    P = own_c.shape[0]
    for p in range(P):
        o = own_c[p]
        ox = cc * o[C_OX] - sc * o[C_OY]
        oy = sc * o[C_OX] + cc * o[C_OY]
        o[C_X], o[C_Y], o[C_TH] = ccx + ox, ccy + oy, c
        o[C_RAD] = upf(upf(rs + upf(o[C_OL] * (hw + 1e-15))) + o[C_SPREAD]) + 1e-15 * (abs(ox) + abs(oy))
    m = own_c[P // 2]
    sl = 0.0
    for p in range(P):
        o = own_c[p]
        sl = max(sl, math.hypot(o[C_X] - m[C_X], o[C_Y] - m[C_Y]) + abs(o[C_RAD] - m[C_RAD]))
    own_c[0, C_SLACK] = sl


def scan_runs(k: int, box: np.ndarray, nb: int, chunks, sweep, err, lever: float, run_turn=None):
    """Scan ``k`` (``nb`` beams) from robot box ``box`` as runs of beams: ``(robot boxes (m, 6),
    beam bounds (m + 1,))``, the runs of :mod:`.sweep_map` when it moves (``chunks``; each run's
    heading widened by its own ``run_turn``, else the scan's; ``err`` the move's error, the
    scan's or one per run), else the whole scan from its box widened by ``sweep`` ``(d, a)``."""
    box = np.ascontiguousarray(box, float)
    if chunks is None or not chunks.moves[k]:
        return swept_box(box, sweep)[None, :], np.array([0, nb])
    j0, j1 = int(chunks.first[k]), int(chunks.first[k + 1])
    boxes = chunk_boxes(chunks, k, box, float(sweep[1]) if run_turn is None else run_turn, err, lever)
    return boxes, chunks.scans.offsets[j0:j1 + 1] - chunks.scans.offsets[j0]


def reference_rows(scans, refs, runs, mount, r_abs: float, r_rel: float, r_alpha: float, smin, stride: int, W):
    """The rows of the reference scans ``refs`` ((scan, robot box) pairs) cut into ``runs``
    (:func:`scan_runs` of each): ``(n_w, ref_f, ref_a0, ref_inc, ref_c, ref_th, R, W)`` with the
    witnesses written to ``W`` (grown as needed) and ``ref_c`` of :data:`N_COLS` columns."""
    n = 0
    mx, my, myaw = mount
    nb = max((int(np.max(np.diff(cut))) for _, cut in runs), default=1)
    R = sum(b.shape[0] for b, _ in runs)
    ref_f = np.full((max(R, 1), nb), -1.0)
    ref_a0 = np.zeros(max(R, 1))
    ref_inc = np.ones(max(R, 1))
    ref_c = np.zeros((max(R, 1), N_COLS))
    ref_th = np.zeros((max(R, 1), 2))
    t = 0
    for (k, _), (boxes, cut) in zip(refs, runs):
        b0, b1 = int(scans.offsets[k]), int(scans.offsets[k + 1])
        r, v = scans.ranges[b0:b1], scans.valid[b0:b1]
        a0, inc = float(scans.angle_min[k]), float(scans.angle_increment[k])
        if r.shape[0] + n > W.shape[0]:
            W = np.concatenate([W, np.empty((r.shape[0] + n, 6))])
        f = free_of(r, v, r_abs, r_rel) if smin[k] < math.inf else None
        first = t
        for j in range(boxes.shape[0]):
            i0, i1 = int(cut[j]), int(cut[j + 1])
            a0j = a0 + i0 * inc
            n += witness_segments(r[i0:i1], v[i0:i1], a0j, inc, boxes[j], mx, my, myaw, r_abs, r_rel, r_alpha, stride,
                                  W[n:])
            if f is not None:
                ref_f[t, : i1 - i0] = f[i0:i1]
            ref_a0[t], ref_inc[t] = a0j, inc
            ref_c[t, C_A0] = a0j
            sb = sensor_box(*(float(x) for x in boxes[j]), mx, my, myaw)
            c = ref_c[t]
            c[C_X], c[C_Y] = 0.5 * (sb[0] + sb[1]), 0.5 * (sb[2] + sb[3])
            c[C_RAD] = np.nextafter(0.5 * math.hypot(sb[1] - sb[0], sb[3] - sb[2]), np.inf) + 1e-12
            c[C_SMIN] = smin[k]
            c[C_II], c[C_AC], c[C_MI], ok, c[C_RR] = _cover_setup(nb, a0j, inc, r_alpha)
            c[C_OK] = 1.0 if ok else 0.0
            c[C_TH] = 0.5 * (sb[4] + sb[5])
            ref_th[t] = sb[4], sb[5]
            c[C_I0], c[C_N] = i0, i1 - i0
            t += 1
        g, o = ref_c[first], ref_c[first + boxes.shape[0] // 2]
        rows = ref_c[first:t]
        g[C_SLACK] = np.max(np.hypot(rows[:, C_X] - o[C_X], rows[:, C_Y] - o[C_Y]) + np.abs(rows[:, C_RAD] - o[C_RAD]))
        g[C_DTH] = np.max(np.abs(rows[:, C_TH] - o[C_TH]))
        g[C_RUNS], g[C_NB], g[C_SAC] = boxes.shape[0], r.shape[0], a0 + 0.5 * (r.shape[0] - 1) * inc
        g[C_SOK] = 1.0 if inc >= 1e-5 and (r.shape[0] - 1) * inc < 2.0 * math.pi - 1e-3 else 0.0
    return n, ref_f, ref_a0, ref_inc, ref_c, ref_th, R, W
