"""The map update of the feature-less LiDAR SLAM: P_EMPTY, P_OBSTACLE, old/new (after the
"Guaranteed SLAM – practical considerations" slides, University of Manchester).

    >>> tmap = TileMap(0.05)
    >>> res = update_map(tmap, scans, robot_boxes, LidarBounds(0.03, 0.01, 0.0))
    >>> res.is_old          # per beam: old (cheap form, against the map before its scan)
    >>> tmap.dense().data   # unknown / empty / obstacle per cell

Guarantees (for every robot pose in its box, given the sensor model of
:mod:`~ivslam_cli.slam.lidar.geometry` and the stated bounds):

- every cell of P_EMPTY^k is free of obstacles (inner approximation; cells are closed squares
  enclosed outward, so a wall touching a cell's border keeps it out of P_EMPTY);
- every endpoint of a valid beam lies in a cell of P_OBSTACLE^k (outer approximation);
- the map accumulates them as in the slides (flags in :mod:`ivslam_cli.paving.tiles`):
  P_EMPTY = ∪ P_EMPTY^k, P_OBSTACLE = (∪ P_OBSTACLE^k) ∩ (∪ P_OLD^k).

Old/new: the slides' inclusion test ``P_EMPTY^{i,k} ⊂ P_EMPTY ∪ P_OBSTACLE`` would never call a
beam old with P_OBSTACLE defined through P_OLD (no old beam -> P_OLD empty -> P_OBSTACLE empty),
so "included in the map" is read as *measured* (any flag: proven free, or in some
P_OBSTACLE^k / P_OLD^k). The cheap form ``P_OBSTACLE^{i,k} ∩ P_UNKNOWN = ∅`` takes P_UNKNOWN =
the unmeasured cells (a dilation by one cell would make every beam new forever: the cells just
behind a wall are never measured).

The work is done by the fast path of :mod:`~ivslam_cli.slam.lidar.map_kernel` (one compiled call per
``update_map``, whatever the number of scans), whose cells, beams, flags and counts are those of
its cell-by-cell reference, :mod:`~ivslam_cli.slam.lidar.map_reference`, bit for bit
(``tests/test_lidar_map.py``, ``bench/bench_lidar_map.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ivslam_cli.errors import ConfigError, IvslamError
from ivslam_cli.interval.rounding import ensure_round_to_nearest
from ivslam_cli.logs.model import Scans
from ivslam_cli.paving.tiles import TileMap
from ivslam_cli.results.model import CELL_EMPTY, CELL_OBSTACLE, CELL_UNKNOWN, MapGrid
from ivslam_cli.slam.lidar import map_kernel as K
from ivslam_cli.slam.lidar import map_reference as R
from ivslam_cli.slam.lidar.geometry import sensor_boxes_of

STAT_FIELDS = ("nodes", "empty_cells", "obstacle_cells", "new_beams", "old_beams", "leaf_beam_tests")


@dataclass(frozen=True)
class LidarBounds:
    """Measurement bounds: ``|z - d| <= range_abs + range_rel d``; bearing error ``<= bearing``
    (the beam cone's half-width, rad); ``fill_gaps`` (see below)."""

    range_abs: float
    range_rel: float = 0.0
    bearing: float = 0.0
    #: cones narrower than the beam step (``bearing`` < step/2) leave gaps between beams where an
    #: obstacle can hide; with ``fill_gaps`` the gap is taken as free up to the nearer free range
    #: (an assumption: nothing pokes between two adjacent beams); without it, such scans prove
    #: no free space
    fill_gaps: bool = False

    def check(self) -> None:
        for name in ("range_abs", "range_rel", "bearing"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ConfigError(f"lidar bound '{name}' must be finite and >= 0, got {v}")
        if self.range_rel >= 0.5:
            raise ConfigError(f"lidar bound 'range_rel' must be < 0.5, got {self.range_rel}")
        if self.bearing >= 0.5:
            raise ConfigError(f"lidar bound 'bearing' must be < 0.5 rad, got {self.bearing}")


@dataclass
class UpdateResult:
    """``is_old`` (B,) per beam of the log (False for invalid or unprocessed beams);
    ``stats`` (S, 6) per scan, columns :data:`STAT_FIELDS` (zeros for unprocessed scans):
    ``empty_cells`` = |P_EMPTY^k|, ``obstacle_cells`` = |P_OBSTACLE^k| (with ``exact=False``: the
    cells passing the window-hull test), new and old beams; ``nodes`` (quadtree nodes and cells
    tested) and ``leaf_beam_tests`` (beams scanned one by one) measure the kernel's work."""

    is_old: np.ndarray
    stats: np.ndarray


def _boxes(robot_boxes, mount, rows=None) -> np.ndarray:
    """Sensor boxes of the robot boxes (all rows, or only ``rows``: the others stay zero)."""
    b = np.ascontiguousarray(np.atleast_2d(robot_boxes), dtype=np.float64)
    if b.ndim != 2 or b.shape[1] != 6:
        raise ValueError(f"pose boxes must be (S, 6) = x_lo, x_hi, y_lo, y_hi, th_lo, th_hi; got {b.shape}")
    if not np.all(np.isfinite(b)) or np.any(b[:, 0::2] > b[:, 1::2]):
        raise ValueError("pose boxes must be finite with lo <= hi")
    mx, my, myaw = (float(v) for v in mount)
    rows = np.arange(b.shape[0], dtype=np.int64) if rows is None else rows
    return sensor_boxes_of(b, rows, mx, my, myaw)


def sensor_boxes(robot_boxes, mount=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Sensor pose boxes (S, 6) enclosing ``pose (+) mount`` for every pose of each robot box."""
    return _boxes(robot_boxes, mount)


def _check_scans(scans: Scans) -> None:
    if np.any(~(scans.angle_increment > 0.0)):
        raise ConfigError("scans with angle_increment <= 0 are not supported")


def update_map(tmap: TileMap, scans: Scans, robot_boxes, bounds: LidarBounds, order=None,
               exact: bool = True, write: bool = True, smin=None) -> UpdateResult:
    """Old/new test and map update for scans ``order`` (default: all, in log order).

    ``robot_boxes`` (S, 6): robot pose box of every scan (the laser mount of ``scans`` is
    applied soundly). ``exact``: cell-level P_OBSTACLE test beam by beam (else the window's
    hull, looser but still outer). ``write=False`` only classifies beams. ``smin`` (S,): no
    cell nearer than this to a scan's sensor box is proven empty (its beams taken from poses
    apart: :func:`~.free_cones.sweep_free_from`; default 0, inf: none).
    """
    ensure_round_to_nearest()
    bounds.check()
    _check_scans(scans)
    order = np.arange(len(scans), dtype=np.int64) if order is None else np.asarray(order, np.int64).ravel()
    if order.size and (order.min() < 0 or order.max() >= len(scans)):
        raise ValueError(f"scan indices must be in [0, {len(scans)}), got {order.min()}..{order.max()}")
    b = np.atleast_2d(robot_boxes)
    if b.ndim == 2 and b.shape[0] != len(scans):
        raise ValueError(f"{b.shape[0]} pose boxes for {len(scans)} scans")
    boxes = _boxes(b, scans.mount, order)  # only the boxes of the scans processed
    is_old = np.zeros(scans.ranges.shape[0], dtype=np.bool_)
    stats = np.zeros((len(scans), len(STAT_FIELDS)), dtype=np.int64)
    smin = np.zeros(len(scans)) if smin is None else np.ascontiguousarray(smin, dtype=np.float64)
    arrays = K.update_log(*tmap.arrays(), scans.ranges, scans.valid, scans.offsets,
                          np.ascontiguousarray(scans.angle_min, dtype=np.float64),
                          np.ascontiguousarray(scans.angle_increment, dtype=np.float64),
                          boxes, order, float(bounds.range_abs), float(bounds.range_rel),
                          float(bounds.bearing), tmap.eps, exact, write, is_old, stats, bool(bounds.fill_gaps),
                          smin)
    tmap.set_arrays(*arrays)
    _check_cells(tmap)
    return UpdateResult(is_old, stats)


def _check_cells(tmap: TileMap) -> None:
    """Refuse a map grown past the ``MAP_CELLS`` limit (an ``eps`` far finer than the area mapped)."""
    from ivslam_cli import limits
    from ivslam_cli.paving.tiles import TILE

    limits.check("MAP_CELLS", tmap.n_tiles * TILE * TILE, f"cells of the map at lidar.eps = {tmap.eps:g} m (coarsen lidar.eps)")


def _scan(scans: Scans, k: int):
    b0, b1 = int(scans.offsets[k]), int(scans.offsets[k + 1])
    return scans.ranges[b0:b1], scans.valid[b0:b1], float(scans.angle_min[k]), float(scans.angle_increment[k])


def scan_sets(scans: Scans, k: int, robot_box, bounds: LidarBounds, eps: float,
              exact: bool = True, smin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """P_EMPTY^k (inner) and P_OBSTACLE^k (outer) of scan ``k`` as cell indices ``(n, 2)``
    (``smin``: see :func:`update_map`)."""
    ensure_round_to_nearest()
    bounds.check()
    _check_scans(scans)
    box = _boxes(robot_box, scans.mount)[0]
    r, v, a0, inc = _scan(scans, k)
    ex, ey, ox, oy = K.scan_cells(r, v, a0, inc, box, float(bounds.range_abs),
                                  float(bounds.range_rel), float(bounds.bearing), float(eps), exact,
                                  bool(bounds.fill_gaps), float(smin))
    return np.column_stack([ex, ey]), np.column_stack([ox, oy])


def map_union_free(tmap: TileMap, scans: Scans, k: int, robot_boxes, bounds: LidarBounds,
                   smin: float = 0.0) -> int:
    """Scan ``k``'s pose lies in the union of ``robot_boxes`` (m, 6): mark as EMPTY the cells its
    P_EMPTY proves free from every box (:mod:`.map_union`); returns how many were not EMPTY
    before. Meant after :func:`update_map` with their hull, which wrote P_OBSTACLE^k and the
    cells the hull proves free (``smin``: see :func:`update_map`)."""
    from ivslam_cli.paving.tiles import EMPTY
    from ivslam_cli.slam.lidar.map_union import union_empty

    ensure_round_to_nearest()
    bounds.check()
    boxes = _boxes(robot_boxes, scans.mount)
    r, v, a0, inc = _scan(scans, k)
    ix, iy = union_empty(tmap.keys, tmap.slots, tmap.cells, r, v, a0, inc, boxes, float(bounds.range_abs),
                         float(bounds.range_rel), float(bounds.bearing), float(tmap.eps), bool(bounds.fill_gaps),
                         float(smin))
    if ix.size:
        tmap.set(ix, iy, EMPTY)
        _check_cells(tmap)
    return int(ix.size)


def inclusion_new(tmap: TileMap, scans: Scans, k: int, robot_box, bounds: LidarBounds) -> np.ndarray:
    """The slides' full old/new test for scan ``k`` against ``tmap``: ``new`` per beam (see
    :func:`ivslam_cli.slam.lidar.map_reference.inclusion_new`)."""
    ensure_round_to_nearest()
    bounds.check()
    box = _boxes(robot_box, scans.mount)[0]
    r, v, a0, inc = _scan(scans, k)
    return R.inclusion_new(tmap.keys, tmap.slots, tmap.cells, r, v, a0, inc, box,
                           float(bounds.range_abs), float(bounds.range_rel), float(bounds.bearing),
                           tmap.eps)


# a scan's map update visits the tiles within its reach: (2 reach / (64 eps))^2 tiles, and
# per-column / per-row tables of 2 reach / eps rows (lidar_kernel). 2^16 cells (3.3 km at
# 5 cm) is far beyond any 2D LiDAR; a return beyond it is a unit or encoding error.
MAX_REACH_CELLS = 1 << 16


def usable_scans(scans: Scans, bounds: LidarBounds, max_range: float, eps: float, path=None) -> tuple[Scans, int]:
    """``scans`` with returns beyond ``max_range`` (``lidar.max_range``; 0: none) marked invalid;
    how many were. Raises :class:`IvslamError` when a valid return reaches more than
    ``MAX_REACH_CELLS`` cells of ``eps`` (``lidar.eps``)."""
    cap = float(max_range)
    far = scans.valid & (scans.ranges.astype(np.float64) > cap) if cap > 0.0 else None
    k = 0 if far is None else int(far.sum())
    if k:
        from dataclasses import replace

        scans = replace(scans, valid=scans.valid & ~far)
    reach, i = scan_reach(scans, bounds)
    eps = float(eps)
    if i >= 0 and not reach <= MAX_REACH_CELLS * eps:
        s = int(np.searchsorted(scans.offsets, i, side="right")) - 1
        raise IvslamError(f"a valid return of {float(scans.ranges[i]):g} m (scan {s}, beam "
                          f"{i - int(scans.offsets[s])}) reaches {reach / eps:,.0f} cells of lidar.eps = {eps:g} m, "
                          f"beyond the {MAX_REACH_CELLS:,} one scan's map update may cover: set lidar.max_range to "
                          "the sensor's reach (or a coarser lidar.eps)", path)
    return scans, k


def scan_reach(scans: Scans, bounds) -> tuple[float, int]:
    """The largest range the map kernels give a valid beam (their ``range_bounds``) and that
    beam's index; ``(0.0, -1)`` without valid beams."""
    from ivslam_cli.slam.lidar.geometry import range_bounds

    if not scans.valid.any():
        return 0.0, -1
    z = np.where(scans.valid, scans.ranges.astype(np.float64), 0.0)
    i = int(np.argmax(z))
    return float(range_bounds(float(z[i]), float(bounds.range_abs), float(bounds.range_rel))[1]), i


def extent_limits(scans: Scans, bounds, eps: float) -> tuple[float, float, float, float, float]:
    """What :func:`check_extent` compares with: ``(reach, pad, span_max, origin_max, eps)``."""
    from ivslam_cli.paving.tiles import TILE
    from ivslam_cli.slam.lidar.map_tables import MAX_SPAN_TILES

    reach = scan_reach(scans, bounds)[0]
    side = TILE * eps
    pad = math.hypot(float(scans.mount[0]), float(scans.mount[1])) + side + reach
    return reach, pad, (MAX_SPAN_TILES - 16) * side, 2.0**29 * side, eps


def check_extent(boxes: np.ndarray, rows: np.ndarray, limits, path=None) -> None:
    """:class:`IvslamError` naming the first scan (``rows``) whose robot pose box (``boxes``,
    (N, 6)) the map update cannot take (``limits``: :func:`extent_limits`): so wide that,
    with its returns, one scan spans over the kernels' ``MAX_SPAN_TILES`` tiles a side, or so
    far from the origin that its tiles leave the tile index (corrupt odometry). Margins cover
    the laser mount. Rows with NaN / inf are left to update_map's own check."""
    reach, pad, span_max, origin_max, eps = limits
    b = np.atleast_2d(boxes)
    for j in range(b.shape[0]) if b.shape[0] <= 1 else _extent_suspects(b, pad, span_max, origin_max):
        x0, x1, y0, y1 = b[j, :4].tolist()
        w = max(x1 - x0, y1 - y0)
        far = max(abs(x0), abs(x1), abs(y0), abs(y1))
        if not math.isfinite(w + far):
            continue
        if not w + 2.0 * pad < span_max:
            raise IvslamError(f"scan {int(rows[j])}: its pose box is {w:.4g} m wide, and with returns up to "
                              f"{reach:.4g} m one scan's map update cannot cover it (at most {span_max:.4g} m a side "
                              f"at lidar.eps = {eps:g} m): set lidar.max_pose_width (0 maps every scan)", path)
        if not far + pad < origin_max:
            raise IvslamError(f"scan {int(rows[j])}: its pose box lies {far:.4g} m from the origin, beyond the map's "
                              f"tile index ({origin_max:.4g} m at lidar.eps = {eps:g} m): corrupt odometry or poses?",
                              path)


def _extent_suspects(b: np.ndarray, pad: float, span_max: float, origin_max: float) -> np.ndarray:
    """Rows of ``b`` that :func:`check_extent` must look at (numpy over all rows)."""
    with np.errstate(invalid="ignore"):
        w = np.maximum(b[:, 1] - b[:, 0], b[:, 3] - b[:, 2])
        far = np.max(np.abs(b[:, :4]), axis=1)
        return np.flatnonzero(~(w + 2.0 * pad < span_max) | ~(far + pad < origin_max))


def map_scans(tmap, scans: Scans, used: np.ndarray, boxes: np.ndarray, bounds, path=None, smin=None):
    """Old/new test and map update for scans ``used`` (in that order) with robot boxes
    ``boxes`` (one row per used scan; ``smin`` one per scan: see :func:`update_map`)."""
    from ivslam_cli.slam.lidar.map_update import update_map

    check_extent(boxes, used, extent_limits(scans, bounds, tmap.eps), path)
    all_boxes = np.zeros((len(scans), 6))
    all_boxes[used] = boxes
    return update_map(tmap, scans, all_boxes, bounds, order=used, smin=smin)


def grid_of(tmap) -> MapGrid:
    """The map as a :class:`MapGrid` (row = y index) over the bounding box of its tiles."""
    from ivslam_cli import limits
    from ivslam_cli.paving import tiles as T

    if tmap.n_tiles:
        co = tmap.coords[: tmap.n_tiles]
        nx, ny = (co.max(axis=0) - co.min(axis=0) + 1) * T.TILE
        limits.check("MAP_CELLS", float(nx) * float(ny),
                     f"the map spans {nx * tmap.eps:.4g} m x {ny * tmap.eps:.4g} m (a pose far from the others: "
                     f"an odometry jump, a unit error?); cells of its dense grid at lidar.eps = {tmap.eps:g} m")
    d = tmap.dense()
    state = np.zeros(d.data.shape[::-1], np.uint8)
    data = d.data.T
    state[data == T.EMPTY_STATE] = CELL_EMPTY
    state[data == T.OBSTACLE] = CELL_OBSTACLE
    state[data == T.UNKNOWN] = CELL_UNKNOWN
    return MapGrid(origin=np.array([d.i0 * d.eps, d.j0 * d.eps], float), resolution=float(d.eps),
                   state=np.ascontiguousarray(state))
