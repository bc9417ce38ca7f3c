"""Submap maps side by side: the :class:`~ivslam_cli.results.model.Submaps` record, the
per-submap log-odds baseline, and the global mosaic for display.

The mosaic places every submap's cells at its anchor's box centre (rotation and translation
in floating point, nearest cell): it is a picture of the run, **not** an enclosure — the
guarantees are per submap (P_EMPTY proven in the anchor's frame) and per global box.
"""

from __future__ import annotations

import numpy as np

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


def mosaic(sm: Submaps, logodds: list[LogOddsGrid] | None = None) -> tuple[MapGrid, LogOddsGrid | None]:
    """The mosaic of the submaps' states (and of their log-odds values, summed where submaps
    overlap) on one grid of the submaps' resolution; where submaps disagree on a cell, the state
    most of them give is drawn (obstacle on a tie)."""
    eps = float(sm.resolution)
    pts, states, vals = [], [], []
    for m in range(len(sm)):
        g = sm.grid(m)
        h, w = g.shape
        if h == 0 or w == 0:
            continue
        r, c = np.nonzero(g.state != CELL_UNKNOWN) if logodds is None else np.nonzero(
            (g.state != CELL_UNKNOWN) | (logodds[m].value != 0))
        x = g.origin[0] + (c + 0.5) * eps
        y = g.origin[1] + (r + 0.5) * eps
        ax, ay, co, si = _centre_transform(sm.anchor_box[m])
        pts.append(np.column_stack([ax + co * x - si * y, ay + si * x + co * y]))
        states.append(g.state[r, c])
        if logodds is not None:
            vals.append(logodds[m].value[r, c])
    if not pts:
        empty = MapGrid(origin=np.zeros(2), resolution=eps, state=np.zeros((0, 0), np.uint8), frame=GRID_MOSAIC)
        lo = None if logodds is None else LogOddsGrid(np.zeros((0, 0), np.float32), *_params(logodds))
        return empty, lo
    p = np.concatenate(pts)
    st = np.concatenate(states)
    ij = np.floor(p / eps).astype(np.int64)
    i0, j0 = ij.min(axis=0)
    i1, j1 = ij.max(axis=0)
    shape = (int(j1 - j0 + 1), int(i1 - i0 + 1))
    state = np.zeros(shape, np.uint8)
    flat = (ij[:, 1] - j0) * shape[1] + (ij[:, 0] - i0)
    n_cells = shape[0] * shape[1]
    n_free = np.bincount(flat[st == CELL_EMPTY], minlength=n_cells).reshape(shape)
    n_obst = np.bincount(flat[st == CELL_OBSTACLE], minlength=n_cells).reshape(shape)
    state[n_free > 0] = CELL_EMPTY  # where the submaps disagree, the majority is drawn
    state[(n_obst > 0) & (n_obst >= n_free)] = CELL_OBSTACLE
    grid = MapGrid(origin=np.array([i0 * eps, j0 * eps], float), resolution=eps, state=state, frame=GRID_MOSAIC)
    if logodds is None:
        return grid, None
    v = np.bincount(flat, weights=np.concatenate(vals).astype(np.float64), minlength=n_cells).reshape(shape)
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
