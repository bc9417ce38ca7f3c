"""Stages 1–3 of the LiDAR pipeline scan by scan (``lidar.contract`` or ``lidar.keyframes``):
predict each scan's pose box from the previous (contracted) one, contract it against the last
keyframe scan (interval scan matching) and against the map built so far (set inversion in pose
space), write it back into the trajectory, then add the scan to the map when its box is narrow
enough. A backward pass over the motion steps at the end carries the contractions to the
earlier scans (forward-backward).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ivslam_cli.interval.pose import compose, meet_or_keep
from ivslam_cli.logs.model import LogData, Scans
from ivslam_cli.slam.lidar.contract import contract_pose
from ivslam_cli.slam.lidar.map_update import UpdateResult, check_extent, extent_limits, update_map
from ivslam_cli.slam.lidar.params import Params
from ivslam_cli.slam.lidar.prediction import PosePrediction, trajectory
from ivslam_cli.slam.lidar.scanmatch import match_scan
from ivslam_cli.slam.motion_kernel import meet_node, propagate, smooth_backward, widen_boxes


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


def _far_from_keyframe(r: np.ndarray, params: Params) -> bool:
    cx, cy, ct = 0.5 * (r[0] + r[1]), 0.5 * (r[2] + r[3]), 0.5 * (r[4] + r[5])
    return bool(math.hypot(cx, cy) >= params.keyframe_distance or abs(ct) >= params.keyframe_turn)


def track_and_map(log: LogData, params: Params, scans: Scans, tmap):
    """Stages 1-3 scan by scan: predict the pose box from the previous (contracted) one,
    contract it against the last keyframe and against the map built so far
    (:func:`ivslam_cli.slam.lidar.contract.contract_pose`), write it back into the trajectory,
    then add the scan to the map when its box is narrow enough.

    Keyframes (``lidar.keyframes``): the pose of each scan *relative to the last keyframe
    scan* is dead-reckoned in that scan's frame (where the keyframe's pose is exact). When the
    robot has moved ``lidar.keyframe_distance`` or turned ``lidar.keyframe_turn`` from it, the
    relative box is contracted by interval scan matching against the keyframe scan
    (:func:`ivslam_cli.slam.lidar.scanmatch.match_scan`: continuous free space of both scans,
    eroded by neither cells nor global boxes), the global box meets keyframe box ⊕ relative
    box, and the scan becomes the next keyframe: global boxes then grow by the matched
    relative boxes' widths from keyframe to keyframe, not by the odometry's.

    After the last scan, a backward pass over the motion steps
    (:func:`ivslam_cli.slam.motion_kernel.smooth_backward`) carries every contraction back to the
    scans before it; a scan's final box is its forward box met with the smoothed one (the map
    keeps the forward boxes it was built with: wider, so still sound).
    Returns ``(PosePrediction, UpdateResult, narrow (S',), Tracking)``."""
    bounds = params.beams
    used, dropped, m, P, source, events = trajectory(log, params, scans)
    max_w = params.max_pose_width
    extent = extent_limits(scans, bounds, tmap.eps)  # for check_extent
    q = params.q_beams
    budget = params.contract_boxes
    stride = params.contract_stride
    max_cw = params.contract_max_width
    use_kf = params.keyframes
    do_map_contract = params.contract
    m_budget = params.match_boxes
    m_stride = params.match_stride
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
            if _far_from_keyframe(rel, params) or j == used.size - 1:
                switch = True
                if np.all(np.isfinite(rel)):
                    out, kept, nt = match_scan(scans, kf.scan, int(used[j]), rel, bounds, q=q, stride=m_stride,
                                               max_boxes=m_budget)
                    tested += nt
                    if kept > 0:
                        rel = out
                        compose(kf.box.reshape(3, 2), out.reshape(3, 2), 1, g.reshape(3, 2))
                        met = np.empty((1, 6))
                        if meet_or_keep(box.reshape(1, 3, 2), g.reshape(1, 3, 2), met.reshape(1, 3, 2)) == 0:
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
        meet_or_keep(forward.reshape(-1, 3, 2), back.reshape(-1, 3, 2), boxes.reshape(-1, 3, 2))
    pred = PosePrediction(used=used, boxes=boxes, source=source, motion=m.motion, step_events=events,
                          node_stamp=m.node_stamp, dropped=dropped)
    return pred, UpdateResult(is_old, stats), narrow, Tracking(contracted, before, contradicted, tested,
                                                               forward, smoothed, too_wide, relative, keyframes,
                                                               unmatched,
                                                               np.array(rel_pairs, np.int64).reshape(-1, 2),
                                                               np.array(rel_boxes, float).reshape(-1, 6), kf_empty)
