"""The feature-less LiDAR pipeline (seed 001), end to end: pose enclosures at every scan, then
the map P_EMPTY (inner) / P_OBSTACLE (outer) with the seed's old/new test.

Stages of :func:`run_lidar` (one pass over the log, in this order):

1. **pose prediction** (:func:`predict_poses`): a box holding the robot pose at every scan
   stamp.

   - Dead reckoning from the log's odometry with the landmark CSP's motion model
     (:func:`ivslam_cli.slam.landmarks.motion_steps`, forward pass of
     :func:`ivslam_cli.slam.landmarks_kernel.step_contract`): twist ``(v, ω)`` with
     ``bounds.odom_v``/``odom_w`` (a node at every scan stamp, the held twist split there
     exactly; lags ``odom_lag_*``) or odometry pose increments with
     ``bounds.odom_trans_*``/``odom_rot_*`` (a scan between two odometry stamps is attached to
     the nearer one, widened by that step's largest displacement and turn). The first pose is
     ``landmarks.initial_pose`` (or the truth, or the origin) ± ``landmarks.initial_margin``.
   - ``lidar.poses_known``: the poses are given (ground truth, the poses recorded with each
     scan, or odometry poses: ``lidar.known_poses``) within ``lidar.pose_margin``; a scan
     between two given poses gets the hull of the two, widened by the margin.

2. **pose contraction against the map** (``lidar.contract``, :func:`track_and_map`): scan by
   scan, the box predicted from the previous one is contracted against the map built so far
   (:func:`ivslam_cli.slam.lidar_contract.contract_pose`: set inversion in pose space, q-relaxed
   over the beams), written back into the trajectory, then the scan is mapped; a backward pass
   over the motion steps at the end carries the contractions to the earlier scans.

3. **map update** (:func:`ivslam_cli.slam.lidar_map.update_map`, compiled kernels over the tiles): the
   laser mount (``Scans.mount``, from tf or the reader) is applied soundly to each box; beams
   are bounded by ``bounds.range_abs``/``range_rel``/``bearing`` (the bearing bound is the
   beam angle error); returns longer than ``lidar.max_range`` and every invalid beam (no
   return, error codes, beyond range_max) prove nothing.

Range bound convention: ``[bounds]`` states ``|ρ − z| ≤ range_abs + range_rel·z`` (measured
range) and simulated logs ``… + range_rel·ρ`` (true range); the map kernels take the second
form, with ``range_abs / (1 − range_rel)`` and ``range_rel / (1 − range_rel)``, which holds in
both conventions (rounded up).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ivslam_cli import interval as iv
from ivslam_cli.config import Config
from ivslam_cli.errors import ConfigError, IvslamError
from ivslam_cli.logs.model import Dropped, LogData, Scans
from ivslam_cli.results.model import (
    CELL_EMPTY,
    CELL_OBSTACLE,
    CELL_UNKNOWN,
    Consistency,
    EmptyEvents,
    MapGrid,
    Poses,
    WidthHistory,
)
from ivslam_cli.slam.lidar_poses import dead_reckon, widen_boxes
from ivslam_cli.slam.landmarks import _bound, _col, _sym, initial_box, motion_steps

MOTIONS = ("auto", "twist", "pose")
KNOWN_SOURCES = ("auto", "truth", "scan", "odometry")
TWIST_BOUNDS = ("odom_v", "odom_v_rel", "odom_w", "odom_w_rel", "odom_lag_xy", "odom_lag_th", "odom_lag_time")
POSE_BOUNDS = ("odom_trans_abs", "odom_trans_rel", "odom_rot_abs", "odom_rot_rel")


# ---------------------------------------------------------------- configuration
def lidar_bounds(cfg: Config):
    """The beam bounds of ``[bounds]`` in the map kernels' convention (see the module docstring)."""
    from ivslam_cli.slam.lidar_map import LidarBounds

    a = _bound(cfg["bounds.range_abs"])
    r = _bound(cfg["bounds.range_rel"])
    if not r < 1.0 / 3.0:
        raise ConfigError(f"[bounds] range_rel = {cfg['bounds.range_rel']} must be < 1/3 in lidar mode")
    den = float(np.nextafter(1.0 - r, -np.inf)) if r else 1.0
    a2 = float(np.nextafter(a / den, np.inf)) if r else a
    r2 = float(np.nextafter(r / den, np.inf)) if r else 0.0
    b = LidarBounds(a2, r2, _bound(cfg["bounds.bearing"]), fill_gaps=bool(cfg["lidar.fill_gaps"]))
    b.check()
    return b


def _choose_motion(log: LogData, cfg: Config) -> str:
    odo = log.odometry
    want = cfg["lidar.motion"]
    if want not in MOTIONS:
        raise ConfigError(f"[lidar] motion must be one of {', '.join(MOTIONS)}, got {want!r}")
    has_t, has_p = odo.twist is not None, odo.pose is not None
    if want == "twist" and not has_t:
        raise IvslamError("lidar.motion = twist, but the odometry has no twist", log.provenance.path)
    if want == "pose" and not has_p:
        raise IvslamError("lidar.motion = pose, but the odometry has no poses", log.provenance.path)
    if want != "auto":
        return want
    if has_t and has_p:
        t_set = any(cfg[f"bounds.{k}"] for k in TWIST_BOUNDS)
        p_set = any(cfg[f"bounds.{k}"] for k in POSE_BOUNDS)
        return "pose" if p_set and not t_set else "twist"
    return "twist" if has_t else "pose"


# ---------------------------------------------------------------- stage 1: pose prediction
@dataclass
class PosePrediction:
    """Robot pose boxes at the used scans, and how they were obtained."""

    used: np.ndarray  # (S',) indices of the scans that get a box
    boxes: np.ndarray  # (S', 6) x_lo, x_hi, y_lo, y_hi, θ_lo, θ_hi
    source: str  # how (for the assumption)
    motion: str  # twist / pose increments / known poses
    step_events: np.ndarray  # (N-1,) skipped motion steps (dead reckoning)
    node_stamp: np.ndarray  # (N,)
    dropped: list[Dropped]
    interpolated: int = 0  # known poses: scans between two given poses


def _given_poses(log: LogData, scans: Scans, source: str) -> tuple[np.ndarray, np.ndarray, str]:
    """(stamps, poses (G, 3), what) of the given poses."""
    path = log.provenance.path
    tr = log.truth
    has_truth = tr is not None and tr.pose is not None and tr.pose_stamp is not None and len(tr.pose_stamp) > 0
    rows = log.meta.get("scan_odometry_pose") if isinstance(log.meta, dict) else None
    has_scan = rows is not None and len(rows) == len(scans) and len(rows) > 0
    odo = log.odometry
    has_odo = odo is not None and odo.pose is not None and len(odo) > 0
    if source not in KNOWN_SOURCES:
        raise ConfigError(f"[lidar] known_poses must be one of {', '.join(KNOWN_SOURCES)}, got {source!r}")
    if source == "auto":
        source = "truth" if has_truth else "scan" if has_scan else "odometry" if has_odo else ""
        if not source:
            raise IvslamError("--poses-known: the log has no ground truth, no poses with its scans and no "
                              "odometry poses", path)
    if source == "truth":
        if not has_truth:
            raise IvslamError("lidar.known_poses = truth, but the log has no ground-truth poses", path)
        return np.asarray(tr.pose_stamp, float), np.asarray(tr.pose, float), "the log's ground-truth poses"
    if source == "scan":
        if not has_scan:
            raise IvslamError("lidar.known_poses = scan, but the log records no pose with its scans", path)
        # (x, y, θ) per scan in file order: the scans' order unless the reader sorted them
        if any(d.stream == "scans" and "out-of-order" in d.reason for d in log.provenance.dropped):
            raise IvslamError("lidar.known_poses = scan: the reader reordered the scans, so the poses recorded "
                              "with them cannot be matched; use truth or odometry", path)
        return np.asarray(scans.stamp, float), np.asarray(rows, float)[:, :3], "the poses recorded with the scans"
    if not has_odo:
        raise IvslamError("lidar.known_poses = odometry, but the log has no odometry poses", path)
    return np.asarray(odo.stamp, float), np.asarray(odo.pose, float), "the odometry poses"


def known_pose_boxes(log: LogData, cfg: Config, scans: Scans) -> PosePrediction:
    """Boxes from given poses ± ``lidar.pose_margin`` (hull of the two neighbours between them)."""
    t, p, what = _given_poses(log, scans, cfg["lidar.known_poses"])
    order = np.argsort(t, kind="stable")
    t, p = t[order], p[order]
    s = np.asarray(scans.stamp, float)
    inside = (s >= t[0]) & (s <= t[-1])
    dropped = []
    if (~inside).any():
        dropped.append(Dropped("scans", int((~inside).sum()), "outside the span of the given poses (not used)"))
    used = np.flatnonzero(inside)
    if used.size == 0:
        raise IvslamError("--poses-known: no scan falls within the span of the given poses", log.provenance.path)
    su = s[used]
    hi = np.clip(np.searchsorted(t, su, side="left"), 0, len(t) - 1)
    lo = np.where(t[hi] == su, hi, np.maximum(hi - 1, 0))
    exact = t[lo] == su
    a, b = p[lo], p[hi]
    # heading of b on the branch nearest to a's
    dth = b[:, 2] - a[:, 2]
    bth = a[:, 2] + (dth - np.round(dth / (2 * math.pi)) * 2 * math.pi)
    bth = np.where(exact, a[:, 2], np.nextafter(bth, np.where(bth > a[:, 2], np.inf, -np.inf)))
    box = np.empty((used.size, 3, 2))
    for d, (x, y) in enumerate(((a[:, 0], b[:, 0]), (a[:, 1], b[:, 1]), (a[:, 2], bth))):
        box[:, d, 0] = np.minimum(x, y)
        box[:, d, 1] = np.maximum(x, y)
    margin = np.array([_bound(m) for m in cfg["lidar.pose_margin"]])
    flat = iv.add(box.reshape(-1, 2), _sym(np.tile(margin, used.size))).reshape(-1, 3, 2)
    return PosePrediction(used=used, boxes=flat.reshape(-1, 6), source=what, motion="known poses",
                          step_events=np.zeros(0, np.int64), node_stamp=t, dropped=dropped,
                          interpolated=int((~exact).sum()))


def _trajectory(log: LogData, cfg: Config, scans: Scans):
    """The motion steps over the scans within the odometry's span and the node boxes with only
    the initial one bounded: ``(used, dropped, MotionSteps, P, initial source, step events)``."""
    path = log.provenance.path
    odo = log.odometry
    if odo is None or len(odo) < 2:
        raise IvslamError("no odometry (at least two samples): --mode lidar needs a motion model, "
                          "or --poses-known with given poses", path)
    t = np.asarray(odo.stamp, float)
    s = np.asarray(scans.stamp, float)
    inside = (s >= t[0]) & (s <= t[-1])
    dropped = []
    if (~inside).any():
        dropped.append(Dropped("scans", int((~inside).sum()), "outside the odometry's time span (not used)"))
    used = np.flatnonzero(inside)
    if used.size == 0:
        raise IvslamError("no scan falls within the odometry's time span", path)
    m = motion_steps(odo, cfg, s[used], prefer=_choose_motion(log, cfg), max_step=float(cfg["lidar.max_step"]),
                     path=path)
    n = m.node_stamp.shape[0]
    P = np.empty((n, 3, 2))
    P[:, :, 0] = -np.inf
    P[:, :, 1] = np.inf
    initial, source = initial_box(log, cfg, float(m.node_stamp[0]))
    P[0] = iv.add(initial, _sym(m.lag[0, [0, 0, 1]]))
    return used, dropped, m, P, source, np.zeros(max(n - 1, 0), np.int64)


def dead_reckoning_boxes(log: LogData, cfg: Config, scans: Scans) -> PosePrediction:
    """Boxes by dead reckoning from the odometry with its bounds (see the module docstring)."""
    used, dropped, m, P, source, events = _trajectory(log, cfg, scans)
    dead_reckon(P, m.kind, m.U, events)
    boxes = np.empty((used.size, 6))
    widen_boxes(P, m.node, m.reach, boxes)
    return PosePrediction(used=used, boxes=boxes, source=source, motion=m.motion, step_events=events,
                          node_stamp=m.node_stamp, dropped=dropped)


@dataclass
class Tracking:
    """What the track-and-map pass did: per used scan, whether it was contracted against the
    map, its box before contraction, and the scans that contradicted the map beyond q."""

    contracted: np.ndarray  # (S',) bool
    before: np.ndarray  # (S', 6) predicted boxes
    contradicted: np.ndarray  # (S',) bool: no pose of the box agrees with the map (box kept)
    tested: int  # sub-boxes tested in all
    forward: np.ndarray  # (S', 6) boxes after the forward pass (before the backward one)
    smoothed: int  # trajectory nodes the backward pass narrowed
    too_wide: int  # scans not contracted: box wider than lidar.contract_max_width
    relative: np.ndarray  # (S',) bool: box met with keyframe box ⊕ contracted relative box
    keyframes: int  # keyframes made
    unmatched: int  # keyframe matches where no relative pose agreed with both scans (box kept)
    rel_pairs: np.ndarray  # (R, 2) rows (keyframe scan, scan) among the used scans
    rel_boxes: np.ndarray  # (R, 6) robot pose of the second in the robot frame of the first
    kf_empty: list  # (row, kind, keyframe row) of keyframe matches that found no solution (box kept)


@dataclass
class _Keyframe:
    """A scan whose frame anchors relative dead reckoning: the global box of its scan and the
    trajectory in its frame (``P``: node boxes relative to its robot pose; rows before its node
    unbounded)."""

    box: np.ndarray  # (6,) global robot box of the keyframe scan
    P: np.ndarray  # (N, 3, 2)
    k_prev: int  # last node propagated in ``P``
    scan: int  # index of the keyframe scan
    row: int  # its row among the used scans


def _new_keyframe(scan: int, row: int, box: np.ndarray, P_shape, k: int, reach) -> _Keyframe:
    P = np.empty(P_shape)
    P[:, :, 0] = -np.inf
    P[:, :, 1] = np.inf
    rp, rt = float(reach[0]), float(reach[1])  # node k holds the modelled pose, within reach of the scan's
    P[k] = [[-rp, rp], [-rp, rp], [-rt, rt]]
    return _Keyframe(box.copy(), P, k, scan, row)


def _far_from_keyframe(r: np.ndarray, cfg: Config) -> bool:
    cx, cy, ct = 0.5 * (r[0] + r[1]), 0.5 * (r[2] + r[3]), 0.5 * (r[4] + r[5])
    return bool(math.hypot(cx, cy) >= float(cfg["lidar.keyframe_distance"])
                or abs(ct) >= float(cfg["lidar.keyframe_turn"]))


def track_and_map(log: LogData, cfg: Config, scans: Scans, bounds, tmap):
    """Stages 1-3 scan by scan: predict the pose box from the previous (contracted) one,
    contract it against the last keyframe and against the map built so far
    (:func:`ivslam_cli.slam.lidar_contract.contract_pose`), write it back into the trajectory,
    then add the scan to the map when its box is narrow enough.

    Keyframes (``lidar.keyframes``): the pose of each scan *relative to the last keyframe
    scan* is dead-reckoned in that scan's frame (where the keyframe's pose is exact). When the
    robot has moved ``lidar.keyframe_distance`` or turned ``lidar.keyframe_turn`` from it, the
    relative box is contracted by interval scan matching against the keyframe scan
    (:func:`ivslam_cli.slam.lidar_scanmatch.match_scan`: continuous free space of both scans,
    eroded by neither cells nor global boxes), the global box meets keyframe box ⊕ relative
    box, and the scan becomes the next keyframe: global boxes then grow by the matched
    relative boxes' widths from keyframe to keyframe, not by the odometry's.

    After the last scan, a backward pass over the motion steps
    (:func:`ivslam_cli.slam.lidar_poses.smooth_backward`) carries every contraction back to the
    scans before it; a scan's final box is its forward box met with the smoothed one (the map
    keeps the forward boxes it was built with: wider, so still sound).
    Returns ``(PosePrediction, UpdateResult, narrow (S',), Tracking)``."""
    from ivslam_cli.slam.lidar_contract import contract_pose
    from ivslam_cli.slam.lidar_map import UpdateResult, update_map
    from ivslam_cli.slam.lidar_poses import compose, meet_boxes, meet_node, propagate, smooth_backward
    from ivslam_cli.slam.lidar_scanmatch import match_scan

    used, dropped, m, P, source, events = _trajectory(log, cfg, scans)
    max_w = float(cfg["lidar.max_pose_width"])
    extent = extent_limits(scans, bounds, tmap.eps)  # for check_extent
    q = int(cfg["lidar.q_beams"])
    budget = int(cfg["lidar.contract_boxes"])
    stride = int(cfg["lidar.contract_stride"])
    max_cw = float(cfg["lidar.contract_max_width"])
    use_kf = bool(cfg["lidar.keyframes"])
    do_map_contract = bool(cfg["lidar.contract"])
    m_budget = int(cfg["lidar.match_boxes"])
    m_stride = int(cfg["lidar.match_stride"])
    unmatched = 0
    rel_pairs: list = []
    kf_empty: list = []  # (row, kind, keyframe row): empty intersections of keyframe matching
    rel_boxes: list = []
    boxes = np.empty((used.size, 6))
    before = np.empty((used.size, 6))
    contracted = np.zeros(used.size, bool)
    contradicted = np.zeros(used.size, bool)
    relative = np.zeros(used.size, bool)
    narrow = np.zeros(used.size, bool)
    all_boxes = np.zeros((len(scans), 6))
    is_old = np.zeros(scans.ranges.shape[0], bool)
    stats = np.zeros((len(scans), 6), np.int64)
    tested = 0
    too_wide = 0
    keyframes = 0
    kf_events = np.zeros(max(P.shape[0] - 1, 0), np.int64)
    one = np.zeros(1, np.int64)
    g = np.empty(6)
    k_prev = 0
    kf = None
    for j in range(used.size):
        k = int(m.node[j])
        propagate(P, m.kind, m.U, events, k_prev, k)
        k_prev = k
        rp, rt = float(m.reach[j, 0]), float(m.reach[j, 1])
        box = np.empty((1, 6))
        widen_boxes(P, m.node[j:j + 1], m.reach[j:j + 1], box)
        box = box[0]
        before[j] = box
        switch = use_kf and kf is None
        if kf is not None:  # this scan in the keyframe's frame
            propagate(kf.P, m.kind, m.U, kf_events, kf.k_prev, k)
            kf.k_prev = k
            rel = np.empty((1, 6))
            widen_boxes(kf.P, m.node[j:j + 1], m.reach[j:j + 1], rel)
            rel = rel[0]
            if _far_from_keyframe(rel, cfg) or j == used.size - 1:
                switch = True
                if np.all(np.isfinite(rel)):
                    out, kept, nt = match_scan(scans, kf.scan, int(used[j]), rel, bounds, q=q, stride=m_stride,
                                               max_boxes=m_budget)
                    tested += nt
                    if kept > 0:
                        rel = out
                        compose(kf.box, out, g)
                        met = np.empty((1, 6))
                        if meet_boxes(box[None, :], g[None, :], met) == 0:
                            box = met[0]
                            relative[j] = True
                            meet_node(P, k, box, rp, rt)
                        else:  # keyframe box (+) relative box misses the predicted box: a contradiction
                            kf_empty.append((j, "keyframe_meet", kf.row))
                    else:
                        unmatched += 1
                        kf_empty.append((j, "keyframe_match", kf.row))
            if np.all(np.isfinite(rel)):
                rel_pairs.append((kf.row, j))
                rel_boxes.append(rel.copy())
        wide = max_cw > 0 and max(box[1] - box[0], box[3] - box[2]) > max_cw
        too_wide += int(wide)
        if do_map_contract and tmap.n_tiles > 0 and np.all(np.isfinite(box)) and not wide:
            out, kept, nt = contract_pose(tmap, scans, int(used[j]), box, bounds, q=q, stride=stride,
                                          max_boxes=budget)
            tested += nt
            if kept == 0:
                contradicted[j] = True
            else:
                contracted[j] = True
                box = out
                meet_node(P, k, box, rp, rt)
        boxes[j] = box
        w = max(box[1] - box[0], box[3] - box[2])
        narrow[j] = (w <= max_w) if max_w > 0 else True
        if narrow[j]:
            check_extent(box, used[j:j + 1], extent, log.provenance.path)
            all_boxes[used[j]] = box
            one[0] = used[j]
            r = update_map(tmap, scans, all_boxes, bounds, order=one)
            is_old |= r.is_old
            stats[used[j]] = r.stats[used[j]]
        if switch and np.all(np.isfinite(box)):
            kf = _new_keyframe(int(used[j]), j, box, P.shape, k, m.reach[j])
            keyframes += 1
    forward = boxes.copy()
    smoothed = 0
    if contracted.any() or relative.any():
        smoothed = int(smooth_backward(P, m.kind, m.U, events, k_prev))
        back = np.empty((used.size, 6))
        widen_boxes(P, m.node, m.reach, back)
        meet_boxes(forward, back, boxes)
    pred = PosePrediction(used=used, boxes=boxes, source=source, motion=m.motion, step_events=events,
                          node_stamp=m.node_stamp, dropped=dropped)
    return pred, UpdateResult(is_old, stats), narrow, Tracking(contracted, before, contradicted, tested,
                                                               forward, smoothed, too_wide, relative, keyframes,
                                                               unmatched,
                                                               np.array(rel_pairs, np.int64).reshape(-1, 2),
                                                               np.array(rel_boxes, float).reshape(-1, 6), kf_empty)


def predict_poses(log: LogData, cfg: Config, scans: Scans) -> PosePrediction:
    if cfg["lidar.poses_known"]:
        return known_pose_boxes(log, cfg, scans)
    return dead_reckoning_boxes(log, cfg, scans)


# ---------------------------------------------------------------- stage 3: the map
# a scan's map update visits the tiles within its reach: (2 reach / (64 eps))^2 tiles, and
# per-column / per-row tables of 2 reach / eps rows (lidar_kernel). 2^16 cells (3.3 km at
# 5 cm) is far beyond any 2D LiDAR; a return beyond it is a unit or encoding error.
MAX_REACH_CELLS = 1 << 16


def usable_scans(scans: Scans, cfg: Config, path=None) -> tuple[Scans, int]:
    """``scans`` with returns beyond ``lidar.max_range`` marked invalid; how many were.
    Raises :class:`IvslamError` when a valid return reaches more than ``MAX_REACH_CELLS``
    cells of ``lidar.eps``."""
    cap = float(cfg["lidar.max_range"])
    far = scans.valid & (scans.ranges.astype(np.float64) > cap) if cap > 0.0 else None
    k = 0 if far is None else int(far.sum())
    if k:
        from dataclasses import replace

        scans = replace(scans, valid=scans.valid & ~far)
    reach, i = scan_reach(scans, lidar_bounds(cfg))
    eps = float(cfg["lidar.eps"])
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
    from ivslam_cli.slam.lidar_geometry import range_bounds

    if not scans.valid.any():
        return 0.0, -1
    z = np.where(scans.valid, scans.ranges.astype(np.float64), 0.0)
    i = int(np.argmax(z))
    return float(range_bounds(float(z[i]), float(bounds.range_abs), float(bounds.range_rel))[1]), i


def extent_limits(scans: Scans, bounds, eps: float) -> tuple[float, float, float, float, float]:
    """What :func:`check_extent` compares with: ``(reach, pad, span_max, origin_max, eps)``."""
    from ivslam_cli.paving.tiles import TILE
    from ivslam_cli.slam.lidar_kernel import MAX_SPAN_TILES

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


def map_scans(tmap, scans: Scans, used: np.ndarray, boxes: np.ndarray, bounds, path=None):
    """Old/new test and map update for scans ``used`` (in that order) with robot boxes
    ``boxes`` (one row per used scan)."""
    from ivslam_cli.slam.lidar_map import update_map

    check_extent(boxes, used, extent_limits(scans, bounds, tmap.eps), path)
    all_boxes = np.zeros((len(scans), 6))
    all_boxes[used] = boxes
    return update_map(tmap, scans, all_boxes, bounds, order=used)


def grid_of(tmap) -> MapGrid:
    """The map as a :class:`MapGrid` (row = y index) over the bounding box of its tiles."""
    from ivslam_cli.paving import tiles as T

    d = tmap.dense()
    state = np.zeros(d.data.shape[::-1], np.uint8)
    data = d.data.T
    state[data == T.EMPTY_STATE] = CELL_EMPTY
    state[data == T.OBSTACLE] = CELL_OBSTACLE
    state[data == T.UNKNOWN] = CELL_UNKNOWN
    return MapGrid(origin=np.array([d.i0 * d.eps, d.j0 * d.eps], float), resolution=float(d.eps),
                   state=np.ascontiguousarray(state))


# ---------------------------------------------------------------- the pipeline
@dataclass
class LidarOutput:
    poses: Poses
    grid: MapGrid
    consistency: Consistency
    stats: dict
    dropped: list[Dropped]
    is_old: np.ndarray  # (B,) per beam of the log
    tmap: object  # the TileMap (flags per cell: EMPTY, OBST_NEW, OBST_OLD)
    mapped: np.ndarray  # indices of the scans that went into the map
    used: np.ndarray  # indices of the scans that got a pose box (rows of ``poses``)
    scans: Scans  # the scans as used (returns beyond lidar.max_range marked invalid)
    #: with lidar.keyframes: ``(pairs (R, 2), boxes (R, 6))``: the robot pose at pose row
    #: ``pairs[r, 1]`` in the robot frame at pose row ``pairs[r, 0]`` (a keyframe), within ``boxes[r]``
    #: (dead-reckoned in the keyframe's frame, matched where the scan was matched); else None
    relative: tuple | None = None


def _box_width(b: np.ndarray) -> np.ndarray:
    w = np.maximum(b[:, 1] - b[:, 0], b[:, 3] - b[:, 2])
    return np.where(np.all(b[:, 0::2] <= b[:, 1::2], axis=1), w, np.nan)


def run_lidar(log: LogData, cfg: Config) -> LidarOutput:
    """The LiDAR pipeline over a log (see the module docstring)."""
    from ivslam_cli.paving.tiles import TileMap

    path = log.provenance.path
    scans = log.scans
    if scans is None or len(scans) == 0:
        raise IvslamError("no LiDAR scans: --mode lidar needs laser scans (sensor_msgs/LaserScan, FLASER, ...)", path)
    t0 = time.perf_counter()
    bounds = lidar_bounds(cfg)
    scans, far = usable_scans(scans, cfg, path)
    tmap = TileMap(float(cfg["lidar.eps"]))
    max_w = float(cfg["lidar.max_pose_width"])
    tracking = None
    if not cfg["lidar.poses_known"] and (cfg["lidar.contract"] or cfg["lidar.keyframes"]):
        pred, res, narrow, tracking = track_and_map(log, cfg, scans, bounds, tmap)
        t1 = time.perf_counter()
        widths = _box_width(pred.boxes)
    else:
        pred = predict_poses(log, cfg, scans)
        t1 = time.perf_counter()
        widths = _box_width(pred.boxes)
        narrow = widths <= max_w if max_w > 0 else np.ones(widths.shape, bool)
        res = map_scans(tmap, scans, pred.used[narrow], pred.boxes[narrow], bounds, path)
    dropped = list(pred.dropped)
    if (~narrow).any():
        dropped.append(Dropped("scans", int((~narrow).sum()),
                               f"robot pose box wider than lidar.max_pose_width = {max_w:g} m (not mapped)"))
    t2 = time.perf_counter()
    grid = grid_of(tmap)
    counts = tmap.counts()
    eps = tmap.eps

    used = pred.used
    stamp = np.asarray(scans.stamp, float)[used]
    box3 = pred.boxes.reshape(-1, 3, 2)
    n_beams = int(np.sum(np.diff(scans.offsets)[used]))
    beam_scan = np.repeat(np.arange(len(scans)), np.diff(scans.offsets))
    in_used = np.zeros(len(scans), bool)
    in_used[used] = True
    valid_used = int(np.count_nonzero(scans.valid & in_used[beam_scan]))
    mapped = used[narrow]
    valid_mapped = int(np.count_nonzero(scans.valid & np.isin(beam_scan, mapped)))
    st = res.stats[mapped]
    new_beams, old_beams = int(st[:, 3].sum()), int(st[:, 4].sum())
    # areas: inner (empty) rounded down, outer (obstacle, unknown-or-worse) rounded up
    area_empty = tmap.area("empty", upward=False)
    area_obst = tmap.area("obstacle", upward=True)
    measured_cells = int(np.count_nonzero(tmap.cells[: tmap.n]))
    explored = float(np.nextafter(measured_cells * eps * eps, np.inf))

    pose_hist = WidthHistory(
        entity=np.column_stack([used, np.full(used.size, -1)]).astype(np.int64),
        step=np.arange(used.size, dtype=np.int64), stamp=stamp, width=widths,
        definition="largest side (x, y) of the robot pose box at each scan, metres",
    )
    rows = [(pred.node_stamp[k], int(k), "motion", (int(k), -1), -1,
             f"motion step {k} -> {k + 1} (t={pred.node_stamp[k]:.3f} s) has no solution from the previous "
             "box; skipped") for k in np.flatnonzero(pred.step_events)]
    if tracking is not None:
        rows += [(float(stamp[j]), int(used[j]), "scan_qinter", (int(used[j]), -1), -1,
                  f"scan {int(used[j])} (t={float(stamp[j]):.3f} s): every pose of its box puts more than "
                  f"q = {cfg['lidar.q_beams']} beam ends in proven-free cells; its box kept uncontracted")
                 for j in np.flatnonzero(tracking.contradicted)]
        rows += [(float(stamp[j]), int(used[j]), kind, (int(used[j]), int(used[r])), -1,
                  f"scan {int(used[j])} (t={float(stamp[j]):.3f} s) vs keyframe scan {int(used[r])}: "
                  + ("no relative pose puts at most q beam ends of either scan in the other's free space"
                     if kind == "keyframe_match" else
                     "the keyframe's box composed with the matched relative box misses the predicted box")
                  + "; its box kept unmatched")
                 for j, kind, r in tracking.kf_empty]
        rows.sort(key=lambda r: r[0])
    events = EmptyEvents(
        stamp=np.array([r[0] for r in rows], float), step=np.array([r[1] for r in rows], np.int64),
        constraint=np.array([r[2] for r in rows], dtype=str).reshape(-1),
        entity=np.array([r[3] for r in rows], np.int64).reshape(-1, 2),
        measurement=np.array([r[4] for r in rows], np.int64),
        text=np.array([r[5] for r in rows], dtype=str).reshape(-1),
    )
    if pred.motion == "known poses":
        pose_text = (f"every robot pose within ±{list(cfg['lidar.pose_margin'])} (x, y, θ) of {pred.source}"
                     + (f"; at the {pred.interpolated} scan(s) between two given poses, within that margin of "
                        "the hull of the two" if pred.interpolated else ""))
    elif pred.motion == "twist":
        pose_text = (f"the initial pose in its box ({pred.source}); the twist odometry within "
                     "|z_v − v| ≤ odom_v + odom_v_rel·|v|, |z_ω − ω| ≤ odom_w + odom_w_rel·|v| at every instant, "
                     "the true pose within the odom_lag_* bounds of such a path")
    else:
        pose_text = (f"the initial pose in its box ({pred.source}); each odometry increment within "
                     "±(odom_trans_abs + odom_trans_rel·|Δ|) per axis and ±(odom_rot_abs + odom_rot_rel·|Δθ|), "
                     "the robot staying within its step's bound between two odometry poses")
    assumption = (
        f"{pose_text}; the laser at mount {tuple(round(float(v), 6) for v in scans.mount)} (x, y, yaw) on the robot; "
        f"every valid return within ±(range_abs + range_rel·range) of the true distance along its beam, whose "
        f"direction is within ±bearing of its nominal angle (bounds used: range_abs {bounds.range_abs:.6g}, "
        f"range_rel {bounds.range_rel:.6g}, bearing {bounds.bearing:.6g}); invalid beams prove nothing; "
        + (f"scans whose beam step exceeds twice the bearing bound (gaps between cones): "
           + ("nothing pokes between two adjacent beams (lidar.fill_gaps); " if bounds.fill_gaps else
              "no free space proven from them (an obstacle can hide between beams; see lidar.fill_gaps); ")
           if np.any(np.asarray(scans.angle_increment, float) > 2.0 * bounds.bearing) else "")
        + ("no pose contraction (the boxes are the prediction)" if tracking is None else
           f"the world static but for at most q = {cfg['lidar.q_beams']} beams per scan ("
           + "; ".join(([] if not cfg["lidar.contract"] else
                        ["pose boxes contracted against the map: a pose is excluded when more than q beam ends of "
                         "its scan fall in proven-free cells"])
                       + ([] if not cfg["lidar.keyframes"] else
                          ["relative poses matched against keyframe scans: one is excluded when more than q beam "
                           "ends of either scan fall in the other's proven free space"]))
           + ")")
        + (f"; {int((~narrow).sum())} scan(s) with pose boxes wider than {max_w:g} m not mapped" if (~narrow).any() else "")
    )
    if len(events):
        assumption += f"; {len(events)} motion step(s) had no solution and were skipped (empty events)"
    consistency = Consistency(empty_events=events, q={}, widths={"pose": pose_hist}, assumption=assumption)
    duration = float(stamp[-1] - stamp[0]) if stamp.size > 1 else 0.0
    total = t2 - t0
    stats = {
        "motion": pred.motion, "scans": int(len(scans)), "scans_used": int(used.size),
        "scans_mapped": int(mapped.size), "beams": n_beams, "valid_beams": valid_used,
        "beams_mapped": int(np.sum(np.diff(scans.offsets)[mapped])), "valid_beams_mapped": valid_mapped, "beyond_max_range": int(far),
        "new_beams": new_beams, "old_beams": old_beams,
        "eps": float(eps), "tiles": int(tmap.n_tiles), "map_bytes": int(tmap.nbytes),
        "empty_cells": int(counts["empty"]), "obstacle_cells": int(counts["obstacle"]),
        "measured_cells": measured_cells,
        "area_empty_m2": float(area_empty), "area_obstacle_m2": float(area_obst), "area_explored_m2": explored,
        "median_pose_width": float(np.nanmedian(widths)) if np.isfinite(widths).any() else float("nan"),
        "max_pose_width": float(np.nanmax(widths)) if np.isfinite(widths).any() else float("nan"),
        "log_duration_s": duration, "predict_s": float(t1 - t0), "map_update_s": float(t2 - t1),
        "beams_per_s": float(n_beams / total) if total > 0 else float("nan"),
        "interpolated_poses": int(pred.interpolated),
    }
    if tracking is not None:
        bw = _box_width(tracking.before)
        fw = _box_width(tracking.forward)
        stats.update({
            "scans_contracted": int(tracking.contracted.sum()),
            "scans_contradicting_map": int(tracking.contradicted.sum()),
            "contraction_boxes_tested": int(tracking.tested),
            "median_predicted_width": float(np.nanmedian(bw)) if np.isfinite(bw).any() else float("nan"),
            "median_forward_width": float(np.nanmedian(fw)) if np.isfinite(fw).any() else float("nan"),
            "nodes_smoothed": int(tracking.smoothed),
            "scans_too_wide_to_contract": int(tracking.too_wide),
            "keyframes": int(tracking.keyframes),
            "keyframes_matched": int(tracking.relative.sum()),
            "keyframes_unmatched": int(tracking.unmatched),
        })
    return LidarOutput(
        poses=Poses(stamp=stamp, box=np.ascontiguousarray(box3)), grid=grid, consistency=consistency,
        stats=stats, dropped=dropped, is_old=res.is_old, tmap=tmap, mapped=mapped, used=used, scans=scans,
        relative=None if tracking is None or not cfg["lidar.keyframes"] else (tracking.rel_pairs, tracking.rel_boxes),
    )
