"""The global map: every scan re-rendered in the result's frame with its global box, once the
anchor graph is contracted (loop closure), so that P_EMPTY is proven in that frame.

The submaps' maps are proven each in its anchor's frame (from tight relative boxes); the mosaic
that places them at their anchors' box centres is a picture. Here each scan whose global box is
at most ``lidar.max_pose_width`` wide (:data:`MAX_WIDTH_ANY` when that key is 0, "map every
scan" in the submaps: a box hundreds of metres wide proves nothing and would make the map span
kilometres) is mapped once more, into one map in the result's frame, with that box (the anchor's
box ⊕ the relative box, met with the dead reckoning and smoothed): the same old/new test and map
update (:mod:`.map_update`) as a run with given poses, the box's width eroding the free space it
proves. A log-odds grid from the same scans at their box
centres, on the same geometry, is the probabilistic comparison (not guaranteed).

Guarantee: if every global box holds its true pose (the tracker's and the anchor graph's
guarantee), every proven-free cell is free of obstacles in the result's frame, and every end
point of a valid beam of a mapped scan lies in a cell flagged obstacle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ivslam_cli.interval.pose import position_width
from ivslam_cli.paving.tiles import TileMap
from ivslam_cli.results.model import CELL_EMPTY, MapGrid
from ivslam_cli.slam.lidar.map_update import grid_of, map_scans


#: the width limit when ``lidar.max_pose_width`` is 0 [m] (that key's default)
MAX_WIDTH_ANY = 2.0


@dataclass
class GlobalMap:
    grid: MapGrid  # frame "proven": the result's frame
    scans_mapped: int
    empty_cells: int
    logodds_free_cells: int  # the log-odds grid from the same scans, on the same geometry


def render_global(scans, used: np.ndarray, boxes: np.ndarray, bounds, eps: float, max_width: float,
                  path=None, smin=None) -> GlobalMap:
    """Map the used scans ``used`` (log order) whose global boxes ``boxes`` (one (6,) row per used
    scan) are finite and at most ``max_width`` wide (0: :data:`MAX_WIDTH_ANY`) into one map in the
    result's frame (``smin``, one per used scan: see :func:`~.map_update.update_map`)."""
    from ivslam_cli.slam.lidar.logodds import build_logodds

    w = position_width(boxes)
    ok = np.isfinite(w) & np.all(np.isfinite(boxes), axis=1)
    ok &= w <= (max_width if max_width > 0 else MAX_WIDTH_ANY)
    rows = np.flatnonzero(ok)
    tmap = TileMap(eps)
    if rows.size:
        all_smin = np.zeros(len(scans))
        if smin is not None:
            all_smin[used] = smin
        map_scans(tmap, scans, used[rows], boxes[rows], bounds, path, smin=all_smin)
    grid = grid_of(tmap)
    lo = build_logodds(scans, used[rows], boxes[rows].reshape(-1, 3, 2), grid) if rows.size else None
    return GlobalMap(grid=grid, scans_mapped=int(rows.size), empty_cells=int(np.count_nonzero(grid.state == CELL_EMPTY)),
                     logodds_free_cells=int(np.count_nonzero(lo.value < 0)) if lo is not None else 0)
