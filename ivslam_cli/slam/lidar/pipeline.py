"""The feature-less LiDAR pipeline (the "Guaranteed SLAM – practical considerations" slides,
University of Manchester), end to end: pose enclosures at every scan, then the map P_EMPTY
(inner) / P_OBSTACLE (outer) with the old/new inclusion test.

Stages of :func:`solve` (one pass over the log, in this order):

1. **pose prediction** (:mod:`.prediction`): a box holding the robot pose at every scan stamp,
   by dead reckoning or from given poses;
2. **tracking in submaps** (dead reckoning, :mod:`.submaps`): every scan's pose is tracked in
   the frame of its submap's anchor scan, contracted there against the anchor scan
   (:mod:`.scanmatch`) and the submap's map (:mod:`.contract`: set inversion in pose space,
   q-relaxed over the beams), and mapped into the submap; global boxes are the anchors' boxes
   composed with the relative ones, met with the global dead reckoning; with given poses
   (``lidar.poses_known``) every scan is mapped in the result's frame;
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
    CELL_EMPTY,
    CELL_OBSTACLE,
    CELL_UNKNOWN,
    FRAME_FIRST_POSE,
    FRAME_WORLD,
    Consistency,
    LogOddsGrid,
    MapGrid,
    Poses,
    RelativePoses,
    Result,
    Submaps,
    WidthHistory,
)
from ivslam_cli.slam.lidar.map_update import grid_of, map_scans, usable_scans
from ivslam_cli.slam.lidar.params import Params
from ivslam_cli.slam.lidar.prediction import predict_poses, sweep_times
from ivslam_cli.slam.lidar.scan_clock import scan_clock
from ivslam_cli.slam.pipeline import empty_events, make_result


# ---------------------------------------------------------------- the pipeline
@dataclass
class LidarOutput:
    poses: Poses
    grid: MapGrid  # proven (given poses) or the submaps' mosaic (display)
    consistency: Consistency
    stats: dict
    dropped: list[Dropped]
    is_old: np.ndarray  # (B,) per beam of the log
    mapped: np.ndarray  # indices of the scans that went into the map (a submap)
    used: np.ndarray  # indices of the scans that got a pose box (rows of ``poses``)
    scans: Scans  # the scans as used (returns beyond lidar.max_range marked invalid)
    logodds: LogOddsGrid | None = None
    submaps: Submaps | None = None
    relative: RelativePoses | None = None  # (anchor row, member row) for every submap membership, then the scan pairs
    tracking: object | None = None  # the submap pass (its submaps' maps and trajectories), dead reckoning
    tmap: object | None = None  # the one map, given poses
    loops: object | None = None  # Loops record (loop closure)
    global_map: MapGrid | None = None  # every scan at its global box after loop closure (proven)


def _median(w: np.ndarray) -> float:
    w = np.asarray(w, float)
    return float(np.nanmedian(w)) if np.isfinite(w).any() else float("nan")


def _heading_width(b: np.ndarray) -> np.ndarray:
    b = np.asarray(b, float).reshape(-1, 6)
    return np.where(np.all(b[:, 0::2] <= b[:, 1::2], axis=1), b[:, 5] - b[:, 4], np.nan)


def _sweep_text(scans: Scans, params: Params, submaps: bool) -> str:
    T, source = sweep_times(scans, params)
    if not submaps:
        return "at the scan's stamp; "
    clock = scan_clock(scans, params.scan_clock, "")
    when = "the scan's stamp" if params.scan_clock == "stamps" else "the scan's tick"
    pre = f"{clock.text()}; " if clock.text() else ""
    if params.scan_time > 0.0:
        pre += f"every beam within bounds.scan_time = {params.scan_time:g} s of its nominal time (from {when}); "
    if not np.any(T != 0.0):
        return f"at {when}; " + pre
    lo, hi = float(np.min(T)), float(np.max(T))
    span = f"{abs(lo):.4g} s" if lo == hi else f"{abs(lo):.4g}–{abs(hi):.4g} s"
    return (f"at its own time, within {span} {'after' if hi > 0 else 'before'} {when} ({source}), "
            "each beam turned by the odometry's nominal turn to its time (twist; pose increments under "
            "bounds.turn_accel_max), every pose widened by how far the robot moves and how far its turn may "
            "stray from that in that time; ") + pre


def _sweep_free_text(tracking, params: Params) -> str:
    """What the sweep leaves of the free cones (:func:`~.free_cones.sweep_free_from`)."""
    smin = None if tracking is None else tracking.smin
    if smin is None or params.beams.fill_gaps or not np.any(smin > 0.0):
        return ""
    none = int(np.count_nonzero(~np.isfinite(smin)))
    fin = smin[np.isfinite(smin)]
    text = ("; a scan's beams taken from poses apart, its free cones prove free space only where adjacent "
            "cones overlap by the sensor's turn and shift from one beam to the next (bearing bound above half "
            "the beam step plus half the turn)")
    if fin.size:
        text += f": from {float(np.median(fin)):.3g} m of the sensor on (median over scans)"
    if none:
        text += (f"; {none} scan(s) prove no free space: the turn between two beams the motion bounds allow "
                 "exceeds the cones' overlap" + ("" if params.odometry.turn_rate_max > 0 else
                                                 " (bounds.speed_max, turn_rate_max state the robot's limits)"))
    return text


def _assumption(params: Params, scans: Scans, pred, submaps: bool, not_mapped: int, n_events: int) -> str:
    bounds = params.beams
    max_w = params.max_pose_width
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
    text = (
        f"{pose_text}; the laser at mount {tuple(round(float(v), 6) for v in scans.mount)} (x, y, yaw) on the robot; "
        f"every valid return within ±(range_abs + range_rel·range) of the true distance to the nearest surface "
        f"in its beam's cone, within ±bearing of its nominal angle (bounds used: range_abs {bounds.range_abs:.6g}, "
        f"range_rel {bounds.range_rel:.6g}, bearing {bounds.bearing:.6g}) from the robot pose "
        + _sweep_text(scans, params, submaps)
        + "invalid beams prove nothing; "
        + ("scans whose beam step exceeds twice the bearing bound (gaps between cones): "
           + ("nothing pokes between two adjacent beams (lidar.fill_gaps); " if bounds.fill_gaps else
              "no free space proven from them (an obstacle can hide between beams; see lidar.fill_gaps); ")
           if np.any(np.asarray(scans.angle_increment, float) > 2.0 * bounds.bearing) else "")
        + ("no pose contraction (the boxes are the given ones)" if not submaps else
           "every scan tracked in the frame of its submap's anchor scan, where each submap's map is proven"
           + ("" if not params.contract else
              f"; the world static but for at most q = {params.q_beams} beams per scan (a relative pose is "
              "excluded when more than q beam ends fall in the anchor scan's or the submap's proven free space, "
              "or the anchor scan's beam ends in the scan's)"))
        + (f"; {not_mapped} scan(s) with pose boxes wider than {max_w:g} m not mapped" if not_mapped else "")
    )
    if n_events:
        text += f"; {n_events} contradiction(s) of the data with the model were recorded as empty events (skipped)"
    return text


def solve(log: LogData, params: Params, progress=None) -> LidarOutput:
    """The LiDAR pipeline over a log (see the module docstring)."""
    path = log.provenance.path
    scans = log.scans
    if scans is None or len(scans) == 0:
        raise IvslamError("no LiDAR scans: --mode lidar needs laser scans (sensor_msgs/LaserScan, FLASER, ...)", path)
    t0 = time.perf_counter()
    bounds = params.beams
    scans, far = usable_scans(scans, bounds, params.max_range, params.eps, path)
    max_w = params.max_pose_width
    tracking = None
    tmap = None
    submaps = None
    relative = None
    rel_boxes = None
    if params.tracking:
        from ivslam_cli.slam.lidar.submaps import track_submaps

        tracking = track_submaps(log, params, scans, progress)
        pred = tracking.pred
        t1 = time.perf_counter()
        narrow = tracking.mapped
        is_old, st_all = tracking.is_old, tracking.stats
        rel_boxes = tracking.relative
    else:
        pred = predict_poses(log, params, scans)
        t1 = time.perf_counter()
        widths = position_width(pred.boxes)
        narrow = widths <= max_w if max_w > 0 else np.ones(widths.shape, bool)
        tmap = TileMap(params.eps)
        res = map_scans(tmap, scans, pred.used[narrow], pred.boxes[narrow], bounds, path)
        is_old, st_all = res.is_old, res.stats
    used = pred.used
    widths = position_width(pred.boxes)
    dropped = list(pred.dropped)
    if (~narrow).any():
        dropped.append(Dropped("scans", int((~narrow).sum()),
                               f"robot pose box wider than lidar.max_pose_width = {max_w:g} m (not mapped)"))
    if tracking is not None:
        from ivslam_cli.slam.lidar.mosaic import mosaic, submap_logodds, submaps_record

        submaps = submaps_record(tracking.submaps, used, params.eps)
        lo_sub = submap_logodds(scans, used, submaps)
        grid, logodds = mosaic(submaps, lo_sub)
        keep = submaps.member_row != submaps.anchor[np.repeat(np.arange(len(submaps)), np.diff(submaps.member_offsets))]
        rel_pairs = np.column_stack([np.repeat(submaps.anchor, np.diff(submaps.member_offsets)),
                                     submaps.member_row])[keep].astype(np.int64).reshape(-1, 2)
        rel_box = np.ascontiguousarray(submaps.member_box[keep]).reshape(-1, 3, 2)
        if tracking.pairs is not None:  # consecutive scans matched alone
            rel_pairs = np.concatenate([rel_pairs, tracking.pairs[0]])
            rel_box = np.concatenate([rel_box, tracking.pairs[1]])
        relative = RelativePoses(pairs=rel_pairs, box=np.ascontiguousarray(rel_box))
        cells = [submaps.grid(m).state for m in range(len(submaps))]
        empty_cells = int(sum(int(np.count_nonzero(c == CELL_EMPTY)) for c in cells))
        obstacle_cells = int(sum(int(np.count_nonzero(c == CELL_OBSTACLE)) for c in cells))
        measured_cells = int(sum(int(np.count_nonzero(c != CELL_UNKNOWN)) for c in cells))
        lo_free = int(sum(int(np.count_nonzero(x.value < 0)) for x in lo_sub))
        lo_occ = int(sum(int(np.count_nonzero(x.value > 0)) for x in lo_sub))
        tiles = int(sum(s.tmap.n_tiles for s in tracking.submaps))
        nbytes = int(sum(s.tmap.nbytes for s in tracking.submaps))
    else:
        grid = grid_of(tmap)
        from ivslam_cli.slam.lidar.logodds import build_logodds

        mapped_rows = np.flatnonzero(narrow)
        logodds = build_logodds(scans, used[mapped_rows], pred.boxes.reshape(-1, 3, 2)[mapped_rows], grid)
        counts = tmap.counts()
        empty_cells, obstacle_cells = int(counts["empty"]), int(counts["obstacle"])
        measured_cells = int(np.count_nonzero(tmap.cells[: tmap.n]))
        lo_free = int(np.count_nonzero(logodds.value < 0))
        lo_occ = int(np.count_nonzero(logodds.value > 0))
        tiles, nbytes = int(tmap.n_tiles), int(tmap.nbytes)
    t2 = time.perf_counter()
    eps = params.eps
    stamp = np.asarray(scans.stamp, float)[used]
    box3 = pred.boxes.reshape(-1, 3, 2)
    n_beams = int(np.sum(np.diff(scans.offsets)[used]))
    beam_scan = np.repeat(np.arange(len(scans)), np.diff(scans.offsets))
    in_used = np.zeros(len(scans), bool)
    in_used[used] = True
    valid_used = int(np.count_nonzero(scans.valid & in_used[beam_scan]))
    mapped = used[narrow]
    valid_mapped = int(np.count_nonzero(scans.valid & np.isin(beam_scan, mapped)))
    st = st_all[mapped]
    new_beams, old_beams = int(st[:, 3].sum()), int(st[:, 4].sum())
    area = eps * eps
    area_empty = float(max(0.0, np.nextafter(np.nextafter(empty_cells * area, 0.0), 0.0))) if empty_cells else 0.0
    area_obst = float(np.nextafter(np.nextafter(obstacle_cells * area, np.inf), np.inf)) if obstacle_cells else 0.0
    explored = float(np.nextafter(measured_cells * area, np.inf))

    pose_hist = WidthHistory(
        entity=np.column_stack([used, np.full(used.size, -1)]).astype(np.int64),
        step=np.arange(used.size, dtype=np.int64), stamp=stamp, width=widths,
        definition="largest side (x, y) of the robot pose box at each scan (the result's frame), metres",
    )
    rows = [(pred.node_stamp[k], int(k), "motion", (int(k), -1), -1,
             f"motion step {k} -> {k + 1} (t={pred.node_stamp[k]:.3f} s) has no solution from the previous "
             "box; skipped") for k in np.flatnonzero(pred.step_events)]
    if tracking is not None:
        for j, sidx, kind in tracking.contradicted:
            what = ("no relative pose puts at most q beam ends of the scan and of the anchor scan in the other's "
                    "free space" if kind == "anchor_match" else
                    "every relative pose puts more than q beam ends in the submap's proven-free cells")
            rows.append((float(stamp[j]), int(used[j]), kind, (int(used[j]), int(sidx)), -1,
                         f"scan {int(used[j])} (t={float(stamp[j]):.3f} s) in submap {sidx}: {what}; its box kept "
                         "uncontracted"))
        for j, sidx, what in tracking.compose_empty:
            rows.append((float(stamp[j]), int(used[j]), "submap_compose", (int(used[j]), int(sidx)), -1,
                         f"scan {int(used[j])} (t={float(stamp[j]):.3f} s): submap {sidx}'s anchor box composed with "
                         f"the scan's {'loop constraint' if what == 'loop' else 'relative box'} misses its global box; "
                         "not met"))
        for lc in (tracking.graph.loops if tracking.graph is not None else []):
            if lc.empty:
                j = lc.row
                rows.append((float(stamp[j]), int(used[j]), "loop_match", (int(used[j]), int(lc.submap)), -1,
                             f"scan {int(used[j])} (t={float(stamp[j]):.3f} s) against older submap {lc.submap}: no "
                             "pose its global box and the chain of anchors allow agrees with that submap beyond q "
                             "beams; no loop constraint (nothing contracted)"))
        for j, sidx in tracking.q_relaxed:
            rows.append((float(stamp[j]), int(used[j]), "q_relaxed", (int(used[j]), int(sidx)), -1,
                         f"scan {int(used[j])} (t={float(stamp[j]):.3f} s) in submap {sidx}: every pose of its "
                         f"predicted box puts more than q_beams = {params.q_beams} beams against the submap; "
                         f"contracted with q = {params.q_retry} instead"))
        for j, sidx in tracking.relocalised:
            rows.append((float(stamp[j]), int(used[j]), "motion_outlier", (int(used[j]), int(sidx)), -1,
                         f"scan {int(used[j])} (t={float(stamp[j]):.3f} s) in submap {sidx}: no pose of its predicted "
                         f"box agrees with the submap (the motion step broke its bounds, or more than q_beams = {params.q_beams} "
                         "beams did); relocalised within "
                         f"±{params.relocalise[0]:g} m, ±{params.relocalise[1]:g} rad of it"))
        rows.sort(key=lambda r: r[0])
    events = empty_events(rows)
    assumption = _assumption(params, scans, pred, tracking is not None, int((~narrow).sum()), len(events))
    if tracking is not None and tracking.q_relaxed:
        assumption += (f"; {len(tracking.q_relaxed)} scan(s) contradicted the static world beyond q_beams beams "
                       f"(empty events q_relaxed): their poses hold if at most q = {params.q_retry} of their "
                       "beams (and of their references') break it")
        if tracking.q_held:
            assumption += (f", and so do those of the {len(tracking.q_held)} scan(s) within q_hold = "
                           f"{params.q_hold:g} s after one (matched with q = {params.q_retry} from the start)")
    if tracking is not None and tracking.relocalised:
        assumption += (f"; {len(tracking.relocalised)} motion step(s) broke their bounds, or more than "
                       f"q_beams beams of their scans did (empty events motion_outlier): their scans were relocalised, assuming the true pose within "
                       f"±{params.relocalise[0]:g} m, ±{params.relocalise[1]:g} rad of the predicted box there")
    assumption += _sweep_free_text(tracking, params)
    q = {"beams": int(params.q_beams)} if tracking is not None else {}
    consistency = Consistency(empty_events=events, q=q, widths={"pose": pose_hist}, assumption=assumption)
    duration = float(stamp[-1] - stamp[0]) if stamp.size > 1 else 0.0
    total = t2 - t0
    hw = _heading_width(pred.boxes)
    stats = {
        "motion": pred.motion, "scans": int(len(scans)), "scans_used": int(used.size),
        "scans_mapped": int(mapped.size), "mapped_fraction": float(mapped.size / max(used.size, 1)),
        "beams": n_beams, "valid_beams": valid_used,
        "beams_mapped": int(np.sum(np.diff(scans.offsets)[mapped])), "valid_beams_mapped": valid_mapped,
        "beyond_max_range": int(far), "new_beams": new_beams, "old_beams": old_beams,
        "eps": float(eps), "tiles": tiles, "map_bytes": nbytes,
        "empty_cells": empty_cells, "obstacle_cells": obstacle_cells, "measured_cells": measured_cells,
        "logodds_free_cells": lo_free, "logodds_occupied_cells": lo_occ,
        "area_empty_m2": area_empty, "area_obstacle_m2": area_obst, "area_explored_m2": explored,
        "median_pose_width": _median(widths), "max_pose_width": float(np.nanmax(widths)) if np.isfinite(widths).any()
        else float("nan"), "median_pose_heading": _median(hw),
        "log_duration_s": duration, "predict_s": float(t1 - t0), "map_update_s": float(t2 - t1),
        "beams_per_s": float(n_beams / total) if total > 0 else float("nan"),
        "interpolated_poses": int(pred.interpolated),
    }
    if tracking is not None:
        stats.update({
            "submaps": int(len(submaps)),
            "median_relative_width": _median(position_width(rel_boxes)),
            "median_relative_heading": _median(_heading_width(rel_boxes)),
            "max_relative_width": float(np.nanmax(position_width(rel_boxes))),
            "scans_contracted": int(tracking.contracted.sum()),
            "scans_relocalised": int(len(tracking.relocalised)),
            "scans_q_relaxed": int(len(tracking.q_relaxed)),
            "scans_q_held": int(len(tracking.q_held)),
            "sweep_free_from_median": _median(np.where(np.isfinite(tracking.smin), tracking.smin, np.nan))
            if tracking.smin is not None else 0.0,
            "scans_no_free": int(np.count_nonzero(~np.isfinite(tracking.smin))) if tracking.smin is not None else 0,
            "scans_contradicting": int(len({j for j, _, _ in tracking.contradicted})),
            "contraction_boxes_tested": int(tracking.tested),
            "pose_set_cells": int(tracking.set_cells),
            "median_predicted_width": _median(position_width(tracking.predicted)),
            "median_forward_width": _median(position_width(tracking.forward)),
            "nodes_smoothed": int(tracking.smoothed),
        })
    loops_rec = None
    global_grid = None
    if tracking is not None and tracking.graph is not None and params.loop_closure and params.contract:
        from ivslam_cli.slam.lidar.loops import loops_record

        loops_rec = loops_record(tracking.graph, tracking.anchor_before, len(tracking.submaps))
        found = int(np.count_nonzero(~loops_rec.empty))
        w_open = position_width(tracking.open_loop)
        stats.update({
            "loops_found": found, "loops_empty": int(np.count_nonzero(loops_rec.empty)),
            "loop_submaps": int(len({int(v) for v in loops_rec.submap[~loops_rec.empty]})),
            "median_open_loop_width": _median(w_open),
            "max_open_loop_width": float(np.nanmax(w_open)) if np.isfinite(w_open).any() else float("nan"),
            "median_loop_width": _median(position_width(loops_rec.box[~loops_rec.empty])) if found else float("nan"),
            "median_loop_heading": _median(loops_rec.box[~loops_rec.empty, 2, 1] - loops_rec.box[~loops_rec.empty, 2, 0])
            if found else float("nan"),
            "graph_sweeps": int(tracking.graph.sweeps), "graph_empty_meets": int(tracking.graph.empty_meets),
            "loop_priors_paved": int(tracking.graph.paved), "loop_pave_tests": int(tracking.graph.pave_tests),
            "loop_pave_incomplete": int(tracking.graph.pave_incomplete),
            "loop_pave_skipped": int(tracking.graph.pave_skipped),
        })
        from ivslam_cli.slam.lidar.global_map import render_global
        from ivslam_cli.slam.lidar.sweep_map import swept_box

        t3 = time.perf_counter()
        gm = render_global(tracking.beams if tracking.beams is not None else scans, used,
                           swept_box(pred.boxes, tracking.sweep), bounds, eps, max_w, path, tracking.smin)
        global_grid = gm.grid
        stats.update({
            "global_scans_mapped": gm.scans_mapped, "global_empty_cells": gm.empty_cells,
            "global_logodds_free_cells": gm.logodds_free_cells,
            "global_area_empty_m2": float(np.nextafter(gm.empty_cells * area, 0.0)) if gm.empty_cells else 0.0,
            "global_map_s": float(time.perf_counter() - t3),
        })
    poses = Poses(stamp=stamp, box=np.ascontiguousarray(box3))
    if tracking is not None:
        poses.submap = tracking.home.astype(np.int64)
        poses.relative = np.ascontiguousarray(rel_boxes.reshape(-1, 3, 2))
    poses.frame, poses.origin_stamp = pose_frame(params, pred)
    return LidarOutput(poses=poses, grid=grid, consistency=consistency, stats=stats, dropped=dropped, is_old=is_old,
                       mapped=mapped, used=used, scans=scans, logodds=logodds, submaps=submaps, relative=relative,
                       tracking=tracking, tmap=tmap, loops=loops_rec, global_map=global_grid)


def pose_frame(params: Params, pred) -> tuple[str, float]:
    """``(frame, origin stamp)`` of the pose boxes: the world when poses or an initial pose are
    given or taken from the truth, else the robot pose at the first trajectory node."""
    if pred.motion == "known poses" or params.initial.pose is not None or params.initial.from_truth:
        return FRAME_WORLD, float("nan")
    return FRAME_FIRST_POSE, float(pred.node_stamp[0])


def run(log: LogData, params: Params, progress=None) -> Result:
    """The LiDAR pipeline over ``log`` as a :class:`Result`: pose boxes (global and, per submap,
    relative), the submaps and their mosaic (or, with given poses, one proven map), and the
    log-odds baseline from the same scans."""
    out = solve(log, params, progress)
    return make_result("lidar", log, dropped=out.dropped, poses=out.poses, grid=out.grid, logodds=out.logodds,
                       relative=out.relative, submaps=out.submaps, loops=out.loops, global_map=out.global_map, consistency=out.consistency,
                       stats=out.stats)


def _from_sets(s: dict) -> str:
    n = s.get("pose_set_cells", 0)
    return f", {n} first proven by the scans' pose sets beyond their hulls" if n else ""


def summary(result: Result) -> str:
    """The CLI line: scans used and mapped, submaps, widths, the map's areas, empty events."""
    s = result.stats
    sub = (f"{s['submaps']} submaps, relative box median {s['median_relative_width']:.3g} m / "
           f"{s['median_relative_heading']:.3g} rad, " if "submaps" in s else "")
    if "loops_found" in s:
        sub += (f"{s['loops_found']} loop constraints ({s['loops_empty']} empty; " if s["loops_found"] else
                "no loop found (") + f"open-loop global box median {s['median_open_loop_width']:.3g} m), "
    return (f"lidar: {s['scans_used']}/{s['scans']} scans ({s['scans_mapped']} mapped), {sub}global box median "
            f"{s['median_pose_width']:.3g} m, {s['motion']}; map {s['area_empty_m2']:.4g} m² proven free"
            f"{' (sum over the submaps, each in its frame)' if 'submaps' in s else ''} "
            f"({s['empty_cells']} cells{_from_sets(s)}; log-odds free {s['logodds_free_cells']}), "
            f"{s['area_obstacle_m2']:.4g} m² "
            f"obstacle; {len(result.consistency.empty_events)} empty event(s)")
