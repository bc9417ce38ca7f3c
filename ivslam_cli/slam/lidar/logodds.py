"""The probabilistic baseline of the LiDAR pipeline: a log-odds occupancy grid, and where it
disagrees with the interval map (the slides' "comparison between an interval map and a probabilistic map").

**Nothing here is guaranteed.** This is the map a standard occupancy-grid mapper builds from the
same scans, for comparison only: every scan is placed at the *centre* of its robot pose box (⊕
the laser mount), each beam is a ray with no width and no range error, and cells get the usual
inverse-sensor-model update:

- every cell the ray from the laser to the return crosses gets ``l_free`` (exact cell traversal,
  Amanatides & Woo 1987), the cell holding the return gets ``l_occ``; each value is clamped to
  ``[l_min, l_max]`` after every update, beams and scans in order;
- invalid beams (no return, error codes, beyond ``range_max`` or ``lidar.max_range``) are
  skipped: they add nothing, not even free space;
- the grid is the interval map's (same origin, resolution and shape); a ray is clipped to it
  (cells outside are not stored; a return outside the grid adds no ``l_occ``).

A cell is *occupied* when p > 0.5 (log-odds > 0), *free* when p < 0.5, *unknown* at exactly 0
(never updated, or updates that cancel). Plain float64 arithmetic (no outward rounding: there is
no enclosure to keep), stored as float32.

:func:`compare` lists the cells where the two maps disagree:

- (a) ``DIS_EMPTY_OCCUPIED``: the interval map proves the cell free (EMPTY: inner approximation
  of free space) and log-odds calls it occupied — the probabilistic map contradicts a proof
  (a return placed off its true position by the centre pose, a moving person seen at one time
  in a cell proven free at another, ...);
- (b) log-odds occupied outside the interval P_OBSTACLE (an outer approximation of every
  surface hit): (a) plus ``DIS_UNKNOWN_OCCUPIED`` (interval state UNKNOWN);
- (c) ``DIS_OBSTACLE_FREE``: interval OBSTACLE cells log-odds calls free. Not a contradiction
  (the interval obstacle set is outer, thickened by the pose boxes and the range bounds, and
  rays pass through the thickening), shown for the size of that margin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from ivslam_cli.logs.model import Scans
from ivslam_cli.results.model import CELL_EMPTY, CELL_OBSTACLE, CELL_UNKNOWN, LogOddsGrid, MapGrid, box_is_empty

# Inverse sensor model (log-odds units): p(occ | hit) ≈ 0.70, p(occ | crossed) ≈ 0.40; clamped
# at ±5 (p ∈ [0.0067, 0.9933]) so that the map can still change.
L_OCC = 0.85
L_FREE = -0.4
L_MIN = -5.0
L_MAX = 5.0

# Per-cell disagreement codes of :func:`compare`.
DIS_NONE = 0
DIS_EMPTY_OCCUPIED = 1  # (a) interval EMPTY (proven free), log-odds occupied
DIS_UNKNOWN_OCCUPIED = 2  # interval UNKNOWN, log-odds occupied; (b) = (a) + these
DIS_OBSTACLE_FREE = 3  # (c) interval OBSTACLE, log-odds free


# ---------------------------------------------------------------- kernel
@njit(cache=True)
def _add(lo, iy, ix, dl, l_min, l_max):
    v = lo[iy, ix] + dl
    lo[iy, ix] = l_min if v < l_min else (l_max if v > l_max else v)


@njit(cache=True)
def _clip(p, q, t0, t1):
    """Liang–Barsky step for ``p·t ≤ q``; returns the narrowed (t0, t1) (t0 > t1: empty)."""
    if p == 0.0:
        if q < 0.0:
            return 1.0, 0.0
        return t0, t1
    r = q / p
    if p < 0.0:
        if r > t0:
            t0 = r
    elif r < t1:
        t1 = r
    return t0, t1


@njit(cache=True)
def logodds_kernel(lo, ox, oy, res, pose, scan, offsets, ranges, valid, angle_min, angle_inc,
                   l_occ, l_free, l_min, l_max):
    """Add the beams of scans ``scan[k]`` (in order) from laser poses ``pose[k]`` = (x, y, θ) to
    ``lo`` (H, W) in place; returns (beams used, cells updated). Poses with a non-finite value
    are skipped."""
    h, w = lo.shape
    n_beams = 0
    n_upd = 0
    if h == 0 or w == 0:
        return n_beams, n_upd
    for k in range(scan.shape[0]):
        px, py, pth = pose[k, 0], pose[k, 1], pose[k, 2]
        if not (math.isfinite(px) and math.isfinite(py) and math.isfinite(pth)):
            continue
        s = scan[k]
        gx0 = (px - ox) / res
        gy0 = (py - oy) / res
        for b in range(offsets[s], offsets[s + 1]):
            if not valid[b]:
                continue
            r = float(ranges[b])
            if not (r >= 0.0 and math.isfinite(r)):
                continue
            n_beams += 1
            a = pth + angle_min[s] + (b - offsets[s]) * angle_inc[s]
            gx1 = gx0 + r * math.cos(a) / res
            gy1 = gy0 + r * math.sin(a) / res
            dx = gx1 - gx0
            dy = gy1 - gy0
            # clip the segment p(t) = g0 + t·d, t ∈ [0, 1], to [0, w] × [0, h]
            t0, t1 = 0.0, 1.0
            t0, t1 = _clip(-dx, gx0, t0, t1)
            t0, t1 = _clip(dx, w - gx0, t0, t1)
            t0, t1 = _clip(-dy, gy0, t0, t1)
            t0, t1 = _clip(dy, h - gy0, t0, t1)
            if t0 > t1:
                continue
            jx = int(math.floor(gx1))
            jy = int(math.floor(gy1))
            end_in = 0 <= jx < w and 0 <= jy < h  # the return's cell is in the grid
            ix = min(max(int(math.floor(gx0 + t0 * dx)), 0), w - 1)
            iy = min(max(int(math.floor(gy0 + t0 * dy)), 0), h - 1)
            if not end_in:  # the cell where the ray leaves the grid
                jx = min(max(int(math.floor(gx0 + t1 * dx)), 0), w - 1)
                jy = min(max(int(math.floor(gy0 + t1 * dy)), 0), h - 1)
            n = abs(jx - ix) + abs(jy - iy)
            # Amanatides–Woo over the full segment's parameter (exact in exact arithmetic; the
            # step count n bounds the walk whatever the rounding)
            if dx > 0.0:
                sx, tmx, tdx = 1, (ix + 1 - gx0) / dx, 1.0 / dx
            elif dx < 0.0:
                sx, tmx, tdx = -1, (ix - gx0) / dx, -1.0 / dx
            else:
                sx, tmx, tdx = 0, math.inf, math.inf
            if dy > 0.0:
                sy, tmy, tdy = 1, (iy + 1 - gy0) / dy, 1.0 / dy
            elif dy < 0.0:
                sy, tmy, tdy = -1, (iy - gy0) / dy, -1.0 / dy
            else:
                sy, tmy, tdy = 0, math.inf, math.inf
            for _ in range(n):
                if not (end_in and ix == jx and iy == jy):
                    _add(lo, iy, ix, l_free, l_min, l_max)
                    n_upd += 1
                if tmx < tmy:
                    ix += sx
                    tmx += tdx
                else:
                    iy += sy
                    tmy += tdy
                if ix < 0 or ix >= w or iy < 0 or iy >= h:
                    break
            if end_in:
                _add(lo, jy, jx, l_occ, l_min, l_max)
                n_upd += 1
            elif 0 <= ix < w and 0 <= iy < h:
                _add(lo, iy, ix, l_free, l_min, l_max)  # the exit cell: crossed, no return in it
                n_upd += 1
    return n_beams, n_upd


# ---------------------------------------------------------------- building the grid
def laser_centres(robot_boxes: np.ndarray, mount) -> np.ndarray:
    """(n, 3) laser poses: the centre of each robot box (n, 3, 2) ⊕ ``mount``; NaN rows for
    empty or unbounded boxes."""
    b = np.asarray(robot_boxes, float).reshape(-1, 3, 2)
    with np.errstate(invalid="ignore"):
        c = 0.5 * (b[..., 0] + b[..., 1])
    c[box_is_empty(b) | ~np.all(np.isfinite(b), axis=(1, 2))] = np.nan
    mx, my, myaw = (float(v) for v in mount)
    cos, sin = np.cos(c[:, 2]), np.sin(c[:, 2])
    return np.column_stack([c[:, 0] + cos * mx - sin * my, c[:, 1] + sin * mx + cos * my, c[:, 2] + myaw])


def build_logodds(scans: Scans, scan_idx: np.ndarray, robot_boxes: np.ndarray, grid: MapGrid, *,
                  l_occ: float = L_OCC, l_free: float = L_FREE, l_min: float = L_MIN,
                  l_max: float = L_MAX) -> LogOddsGrid:
    """The log-odds grid (geometry of ``grid``) from scans ``scan_idx`` (in that order), each at
    the centre of its robot box ``robot_boxes[k]`` (n, 3, 2) ⊕ ``scans.mount``. Not guaranteed
    (see the module docstring)."""
    idx = np.ascontiguousarray(scan_idx, dtype=np.int64).reshape(-1)
    boxes = np.asarray(robot_boxes, float).reshape(-1, 3, 2)
    if boxes.shape[0] != idx.shape[0]:
        raise ValueError(f"build_logodds: {idx.shape[0]} scans but {boxes.shape[0]} pose boxes")
    if idx.size and (idx.min() < 0 or idx.max() >= len(scans)):
        raise ValueError("build_logodds: scan index out of range")
    if not (l_min < 0.0 < l_max and l_free < 0.0 < l_occ):
        raise ValueError("build_logodds: needs l_free < 0 < l_occ and l_min < 0 < l_max")
    lo = np.zeros(grid.shape, np.float64)
    pose = np.ascontiguousarray(laser_centres(boxes, scans.mount))
    beams, _ = logodds_kernel(
        lo, float(grid.origin[0]), float(grid.origin[1]), float(grid.resolution), pose, idx,
        np.ascontiguousarray(scans.offsets, np.int64), np.ascontiguousarray(scans.ranges, np.float32),
        np.ascontiguousarray(scans.valid, np.bool_), np.ascontiguousarray(scans.angle_min, np.float64),
        np.ascontiguousarray(scans.angle_increment, np.float64), float(l_occ), float(l_free),
        float(l_min), float(l_max))
    used = int(np.count_nonzero(np.all(np.isfinite(pose), axis=1))) if pose.size else 0
    return LogOddsGrid(value=lo.astype(np.float32), l_occ=float(l_occ), l_free=float(l_free),
                       l_min=float(l_min), l_max=float(l_max), scans=used, beams=int(beams))


# ---------------------------------------------------------------- comparison
@dataclass
class Disagreement:
    """Cells where the log-odds map and the interval map disagree (see the module docstring).

    ``code`` (H, W) uint8: DIS_NONE, DIS_EMPTY_OCCUPIED, DIS_UNKNOWN_OCCUPIED or DIS_OBSTACLE_FREE.
    """

    code: np.ndarray
    empty_occupied: int  # (a)
    occupied_outside_obstacle: int  # (b) ⊇ (a)
    obstacle_free: int  # (c)
    logodds_cells: dict[str, int]  # occupied / free / unknown (log-odds 0)
    interval_cells: dict[str, int]  # empty / obstacle / unknown

    def counts(self) -> dict[str, int]:
        return {"empty_occupied": self.empty_occupied,
                "unknown_occupied": self.occupied_outside_obstacle - self.empty_occupied,
                "occupied_outside_obstacle": self.occupied_outside_obstacle,
                "obstacle_free": self.obstacle_free}


def logodds_classes(lo: LogOddsGrid) -> dict[str, int]:
    v = lo.value
    return {"occupied": int(np.count_nonzero(v > 0)), "free": int(np.count_nonzero(v < 0)),
            "unknown": int(np.count_nonzero(v == 0))}


def compare(grid: MapGrid, lo: LogOddsGrid) -> Disagreement:
    """Per-cell disagreement between the interval map ``grid`` and ``lo`` (same shape)."""
    if lo.value.shape != grid.state.shape:
        raise ValueError(f"compare: log-odds grid {lo.value.shape} and interval map {grid.state.shape} differ")
    st, v = grid.state, lo.value
    occ, free = v > 0, v < 0
    code = np.zeros(st.shape, np.uint8)
    code[occ & (st == CELL_EMPTY)] = DIS_EMPTY_OCCUPIED
    code[occ & (st == CELL_UNKNOWN)] = DIS_UNKNOWN_OCCUPIED
    code[free & (st == CELL_OBSTACLE)] = DIS_OBSTACLE_FREE
    a = int(np.count_nonzero(code == DIS_EMPTY_OCCUPIED))
    b = int(np.count_nonzero(occ & (st != CELL_OBSTACLE)))
    c = int(np.count_nonzero(code == DIS_OBSTACLE_FREE))
    cells = {name: int(np.count_nonzero(st == k))
             for name, k in (("empty", CELL_EMPTY), ("obstacle", CELL_OBSTACLE), ("unknown", CELL_UNKNOWN))}
    return Disagreement(code=code, empty_occupied=a, occupied_outside_obstacle=b, obstacle_free=c,
                        logodds_cells=logodds_classes(lo), interval_cells=cells)
