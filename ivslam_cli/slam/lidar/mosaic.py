"""Submap maps side by side: the :class:`~ivslam_cli.results.model.Submaps` record, the
per-submap log-odds baseline, and the global mosaic for display.

The mosaic places every submap's cells at its anchor's box centre (rotation and translation
in floating point, nearest cell): it is a picture of the run, **not** an enclosure — the
guarantees are per submap (P_EMPTY proven in the anchor's frame) and per global box.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.logs.model import Scans
from ivslam_cli.results.model import CELL_EMPTY, CELL_OBSTACLE, CELL_UNKNOWN, GRID_MOSAIC, LogOddsGrid, MapGrid, Submaps
from ivslam_cli.slam.lidar.logodds import build_logodds
from ivslam_cli.slam.lidar.map_update import grid_of


def submaps_record(subs, used: np.ndarray, eps: float) -> Submaps:
    """The result's :class:`Submaps` from the tracker's submaps (rows are used-scan rows)."""
    grids = [grid_of(s.tmap) for s in subs]
    shape = np.array([g.state.shape for g in grids], np.int64).reshape(-1, 2)
    counts = np.array([len(s.rows) for s in subs], np.int64)
    mapped_sets = [set(s.mapped) for s in subs]
    rows = np.array([r for s in subs for r in s.rows], np.int64)
    boxes = np.array([b for s in subs for b in s.rel], float).reshape(-1, 3, 2)
    mapped = np.array([r in ms for s, ms in zip(subs, mapped_sets) for r in s.rows], bool)
    return Submaps(
        anchor=np.array([s.anchor_row for s in subs], np.int64),
        anchor_box=np.array([s.G for s in subs], float).reshape(-1, 3, 2),
        resolution=float(eps),
        origin=np.array([g.origin for g in grids], float).reshape(-1, 2),
        shape=shape,
        state=np.concatenate([g.state.reshape(-1) for g in grids]) if grids else np.zeros(0, np.uint8),
        member_offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        member_row=rows, member_box=boxes, member_mapped=mapped,
    )


def submap_logodds(scans: Scans, used: np.ndarray, sm: Submaps) -> list[LogOddsGrid]:
    """Per submap, the log-odds baseline of its mapped members at their relative box centres, on
    its grid (the same scans and frame as its interval map)."""
    out = []
    for m in range(len(sm)):
        rows, boxes, mapped = sm.members(m)
        out.append(build_logodds(scans, used[rows[mapped]], boxes[mapped], sm.grid(m)))
    return out


def _centre_transform(box: np.ndarray) -> tuple[float, float, float, float]:
    c = 0.5 * (box[:, 0] + box[:, 1])
    return float(c[0]), float(c[1]), float(np.cos(c[2])), float(np.sin(c[2]))


@njit(cache=True, inline="always")
def _cell(st, v, use_values, unknown):
    return st != unknown or (use_values and v != 0)


@njit(cache=True)
def _extent(state, values, use_values, origin, centre, eps, unknown, ext):
    """``ext`` (i0, i1, j0, j1) grown by the cells of one submap (``state``, ``values``: its grids)
    that are not ``unknown`` (or, with ``use_values``, have a log-odds value), placed at its
    anchor's box centre ``centre`` (x, y, cos θ, sin θ; nearest cell)."""
    ax, ay, co, si = centre[0], centre[1], centre[2], centre[3]
    for r in range(state.shape[0]):
        y = origin[1] + (r + 0.5) * eps
        for c in range(state.shape[1]):
            if _cell(state[r, c], values[r, c] if use_values else 0.0, use_values, unknown):
                x = origin[0] + (c + 0.5) * eps
                i = np.int64(np.floor((ax + co * x - si * y) / eps))
                j = np.int64(np.floor((ay + si * x + co * y) / eps))
                ext[0], ext[1], ext[2], ext[3] = min(ext[0], i), max(ext[1], i), min(ext[2], j), max(ext[3], j)


@njit(cache=True)
def _accumulate(state, values, use_values, origin, centre, eps, unknown, empty, obstacle, i0, j0, n_free, n_obst,
                value):
    """The cells :func:`_extent` places, counted into the mosaic (origin cell ``i0``, ``j0``):
    free and obstacle states, and the sum of the log-odds values."""
    ax, ay, co, si = centre[0], centre[1], centre[2], centre[3]
    for r in range(state.shape[0]):
        y = origin[1] + (r + 0.5) * eps
        for c in range(state.shape[1]):
            st = state[r, c]
            if _cell(st, values[r, c] if use_values else 0.0, use_values, unknown):
                x = origin[0] + (c + 0.5) * eps
                i = np.int64(np.floor((ax + co * x - si * y) / eps)) - i0
                j = np.int64(np.floor((ay + si * x + co * y) / eps)) - j0
                if st == empty:
                    n_free[j, i] += 1
                elif st == obstacle:
                    n_obst[j, i] += 1
                if use_values:
                    value[j, i] += np.float64(values[r, c])


def mosaic(sm: Submaps, logodds: list[LogOddsGrid] | None = None) -> tuple[MapGrid, LogOddsGrid | None]:
    """The mosaic of the submaps' states (and of their log-odds values, summed where submaps
    overlap) on one grid of the submaps' resolution; where submaps disagree on a cell, the state
    most of them give is drawn (obstacle on a tie)."""
    eps = float(sm.resolution)
    use = logodds is not None
    none = np.zeros((1, 1), np.float32)
    subs = []
    ext = np.array([np.iinfo(np.int64).max, np.iinfo(np.int64).min] * 2, np.int64)
    for m in range(len(sm)):
        g = sm.grid(m)
        if g.state.size == 0:
            continue
        v = logodds[m].value if use else none
        c = np.array(_centre_transform(sm.anchor_box[m]), float)
        o = np.ascontiguousarray(g.origin, float)
        subs.append((g.state, v, o, c))
        _extent(g.state, v, use, o, c, eps, CELL_UNKNOWN, ext)
    i0, i1, j0, j1 = (int(x) for x in ext)
    if i0 > i1:
        empty = MapGrid(origin=np.zeros(2), resolution=eps, state=np.zeros((0, 0), np.uint8), frame=GRID_MOSAIC)
        lo = None if logodds is None else LogOddsGrid(np.zeros((0, 0), np.float32), *_params(logodds))
        return empty, lo
    shape = (j1 - j0 + 1, i1 - i0 + 1)
    n_free = np.zeros(shape, np.int64)
    n_obst = np.zeros(shape, np.int64)
    v = np.zeros(shape)
    for st, val, o, c in subs:
        _accumulate(st, val, use, o, c, eps, CELL_UNKNOWN, CELL_EMPTY, CELL_OBSTACLE, i0, j0, n_free, n_obst, v)
    state = np.zeros(shape, np.uint8)
    state[n_free > 0] = CELL_EMPTY  # where the submaps disagree, the majority is drawn
    state[(n_obst > 0) & (n_obst >= n_free)] = CELL_OBSTACLE
    grid = MapGrid(origin=np.array([i0 * eps, j0 * eps], float), resolution=eps, state=state, frame=GRID_MOSAIC)
    if logodds is None:
        return grid, None
    l_occ, l_free, l_min, l_max = _params(logodds)[:4]
    lo = LogOddsGrid(value=np.clip(v, l_min, l_max).astype(np.float32), l_occ=l_occ, l_free=l_free, l_min=l_min,
                     l_max=l_max, scans=int(sum(x.scans for x in logodds)), beams=int(sum(x.beams for x in logodds)))
    return grid, lo


def _params(logodds: list[LogOddsGrid]):
    from ivslam_cli.slam.lidar.logodds import L_FREE, L_MAX, L_MIN, L_OCC

    if logodds:
        a = logodds[0]
        return a.l_occ, a.l_free, a.l_min, a.l_max
    return L_OCC, L_FREE, L_MIN, L_MAX
