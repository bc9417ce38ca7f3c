"""The feature-less LiDAR pipeline (the "Guaranteed SLAM – practical considerations" slides,
University of Manchester), end to end: pose enclosures at every scan, then the map P_EMPTY
(inner) / P_OBSTACLE (outer) with the old/new inclusion test.

Stages of :func:`solve` (one pass over the log, in this order):

1. **pose prediction** (:mod:`.prediction`): a box holding the robot pose at every scan stamp,
   by dead reckoning or from given poses;
2. **pose contraction** (``lidar.contract`` / ``lidar.keyframes``, :mod:`.tracking`): scan by
   scan, the box predicted from the previous one is contracted against the last keyframe scan
   (:mod:`.scanmatch`) and the map built so far (:mod:`.contract`: set inversion in pose
   space, q-relaxed over the beams), written back into the trajectory, then the scan is
   mapped; a backward pass over the motion steps carries the contractions to earlier scans;
3. **map update** (:mod:`.map_update`, compiled kernels over the tiles): the laser mount
   (``Scans.mount``, from tf or the reader) is applied soundly to each box; beams are bounded by
   ``bounds.range_abs``/``range_rel``/``bearing`` (the bearing bound is the beam angle error);
   returns longer than ``lidar.max_range`` and every invalid beam (no return, error codes,
   beyond range_max) prove nothing.

Beside the interval map the result holds a log-odds occupancy grid from the same scans at their
box centres (:mod:`.logodds`): a probabilistic baseline for comparison, not guaranteed.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ivslam_cli.errors import IvslamError
from ivslam_cli.interval.pose import position_width
from ivslam_cli.logs.model import Dropped, LogData, Scans
from ivslam_cli.paving.tiles import TileMap
from ivslam_cli.results.model import (
    Consistency,
    MapGrid,
    Poses,
    RelativePoses,
    Result,
    WidthHistory,
)
from ivslam_cli.slam.lidar.map_update import grid_of, map_scans, usable_scans
from ivslam_cli.slam.lidar.params import Params
from ivslam_cli.slam.lidar.prediction import predict_poses
from ivslam_cli.slam.lidar.tracking import track_and_map
from ivslam_cli.slam.pipeline import empty_events, make_result


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


def solve(log: LogData, params: Params) -> LidarOutput:
    """The LiDAR pipeline over a log (see the module docstring)."""
    path = log.provenance.path
    scans = log.scans
    if scans is None or len(scans) == 0:
        raise IvslamError("no LiDAR scans: --mode lidar needs laser scans (sensor_msgs/LaserScan, FLASER, ...)", path)
    t0 = time.perf_counter()
    bounds = params.beams
    scans, far = usable_scans(scans, bounds, params.max_range, params.eps, path)
    tmap = TileMap(params.eps)
    max_w = params.max_pose_width
    tracking = None
    if params.tracking:
        pred, res, narrow, tracking = track_and_map(log, params, scans, tmap)
        t1 = time.perf_counter()
        widths = position_width(pred.boxes)
    else:
        pred = predict_poses(log, params, scans)
        t1 = time.perf_counter()
        widths = position_width(pred.boxes)
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
                  f"q = {params.q_beams} beam ends in proven-free cells; its box kept uncontracted")
                 for j in np.flatnonzero(tracking.contradicted)]
        rows += [(float(stamp[j]), int(used[j]), kind, (int(used[j]), int(used[r])), -1,
                  f"scan {int(used[j])} (t={float(stamp[j]):.3f} s) vs keyframe scan {int(used[r])}: "
                  + ("no relative pose puts at most q beam ends of either scan in the other's free space"
                     if kind == "keyframe_match" else
                     "the keyframe's box composed with the matched relative box misses the predicted box")
                  + "; its box kept unmatched")
                 for j, kind, r in tracking.kf_empty]
        rows.sort(key=lambda r: r[0])
    events = empty_events(rows)
    if pred.motion == "known poses":
        pose_text = (f"every robot pose within ±{list(params.pose_margin)} (x, y, θ) of {pred.source}"
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
        + ("scans whose beam step exceeds twice the bearing bound (gaps between cones): "
           + ("nothing pokes between two adjacent beams (lidar.fill_gaps); " if bounds.fill_gaps else
              "no free space proven from them (an obstacle can hide between beams; see lidar.fill_gaps); ")
           if np.any(np.asarray(scans.angle_increment, float) > 2.0 * bounds.bearing) else "")
        + ("no pose contraction (the boxes are the prediction)" if tracking is None else
           f"the world static but for at most q = {params.q_beams} beams per scan ("
           + "; ".join(([] if not params.contract else
                        ["pose boxes contracted against the map: a pose is excluded when more than q beam ends of "
                         "its scan fall in proven-free cells"])
                       + ([] if not params.keyframes else
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
        bw = position_width(tracking.before)
        fw = position_width(tracking.forward)
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
        relative=None if tracking is None or not params.keyframes else (tracking.rel_pairs, tracking.rel_boxes),
    )


def run(log: LogData, params: Params, progress=None) -> Result:
    """The LiDAR pipeline over ``log`` as a :class:`Result`: pose boxes, the interval map, the
    log-odds baseline from the same scans, and the relative enclosures of a keyframes run."""
    from ivslam_cli.slam.lidar.logodds import logodds_of

    out = solve(log, params)
    rel = None
    if out.relative is not None:
        pairs, boxes = out.relative
        rel = RelativePoses(pairs=np.ascontiguousarray(pairs, np.int64).reshape(-1, 2),
                            box=np.ascontiguousarray(boxes, np.float64).reshape(-1, 3, 2))
    return make_result("lidar", log, dropped=out.dropped, poses=out.poses, grid=out.grid, logodds=logodds_of(out),
                       relative=rel, consistency=out.consistency, stats=out.stats)


def summary(result: Result) -> str:
    """The CLI line: scans used and mapped, beams, old/new, the map's areas, empty events."""
    s = result.stats
    return (f"lidar: {s['scans_used']}/{s['scans']} scans ({s['scans_mapped']} mapped), {s['beams']} beams "
            f"({s['valid_beams_mapped']} valid mapped: {s['old_beams']} old, {s['new_beams']} new), {s['motion']}; "
            f"map {s['area_empty_m2']:.4g} m² empty, {s['area_obstacle_m2']:.4g} m² obstacle, "
            f"{s['area_explored_m2']:.4g} m² explored; {len(result.consistency.empty_events)} empty event(s)")
