"""Stage 1 of the LiDAR pipeline: a box holding the robot pose at every scan stamp.

- **Dead reckoning** (:func:`dead_reckoning_boxes`) from the log's odometry with the motion
  model of :mod:`ivslam_cli.slam.motion`: twist ``(v, ω)`` with ``bounds.odom_v``/``odom_w`` (a
  node at every scan stamp, the held twist split there exactly; lags ``odom_lag_*``) or
  odometry pose increments with ``bounds.odom_trans_*``/``odom_rot_*`` (a scan between two
  odometry stamps is attached to the nearer one, widened by that step's largest displacement
  and turn). The first pose is ``landmarks.initial_pose`` (or the truth, or the origin) ±
  ``landmarks.initial_margin``.
- **Known poses** (:func:`known_pose_boxes`, ``lidar.poses_known``): the poses are given (ground
  truth, the poses recorded with each scan, or odometry poses: ``lidar.known_poses``) within
  ``lidar.pose_margin``; a scan between two given poses gets the hull of the two, widened by
  the margin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ivslam_cli import interval as iv
from ivslam_cli.errors import IvslamError
from ivslam_cli.interval.vector import bound_up, sym
from ivslam_cli.logs.model import Dropped, LogData, Scans
from ivslam_cli.slam.lidar.params import Params
from ivslam_cli.slam.lidar.scan_clock import scan_clock
from ivslam_cli.slam.motion import choose_motion, initial_box, motion_steps
from ivslam_cli.slam.motion_kernel import dead_reckon, widen_boxes


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


def known_pose_boxes(log: LogData, params: Params, scans: Scans) -> PosePrediction:
    """Boxes from given poses ± ``lidar.pose_margin`` (hull of the two neighbours between them)."""
    t, p, what = _given_poses(log, scans, params.known_poses)
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
    margin = np.array([bound_up(m) for m in params.pose_margin])
    flat = iv.add(box.reshape(-1, 2), sym(np.tile(margin, used.size))).reshape(-1, 3, 2)
    return PosePrediction(used=used, boxes=flat.reshape(-1, 6), source=what, motion="known poses",
                          step_events=np.zeros(0, np.int64), node_stamp=t, dropped=dropped,
                          interpolated=int((~exact).sum()))


def sweep_times(scans: Scans, params: Params) -> tuple[np.ndarray, str]:
    """Per scan, the time from its stamp to its last beam (negative: the stamp is the last
    beam's), and where it comes from: the log's ``time_increment`` × (beams − 1) where it has
    one and ``lidar.sweep_from_log``, else ``lidar.sweep``."""
    T = np.full(len(scans), float(params.sweep))
    ti = scans.time_increment
    if params.sweep_from_log and ti is not None:
        have = np.isfinite(ti) & (ti != 0.0)
        if have.any():
            n = np.diff(scans.offsets)
            T[have] = ti[have] * (n[have] - 1)
            return T, ("the log's time_increment × (beams − 1)" + ("" if have.all() else
                                                                  ", lidar.sweep where it has none"))
    return T, "lidar.sweep"


def beam_times(scans: Scans, params: Params, clock=None) -> tuple[np.ndarray, np.ndarray]:
    """Per scan ``(b, c)``: beam ``i`` is taken at its stamp ``+ b + i·c`` (see
    :func:`sweep_times`: the log's ``time_increment`` ``c`` from the stamp, or ``lidar.sweep`` T
    spread evenly after the stamp, before it when negative), ``b`` moved by the scan's clock
    (``clock``, else ``lidar.scan_clock``: :mod:`.scan_clock`); all within ``bounds.scan_time``
    of that."""
    if clock is None:
        clock = scan_clock(scans, params.scan_clock)
    b, c = _sweep_beams(scans, params)
    return b + clock.offset, c


def _sweep_beams(scans: Scans, params: Params) -> tuple[np.ndarray, np.ndarray]:
    T = sweep_times(scans, params)[0]
    n = np.diff(scans.offsets)
    c = np.where(n > 1, np.abs(T) / np.maximum(n - 1, 1), 0.0)
    b = np.minimum(T, 0.0)
    ti = scans.time_increment
    if params.sweep_from_log and ti is not None:
        have = np.isfinite(ti) & (ti != 0.0)
        c = np.where(have, ti, c)
        b = np.where(have, 0.0, b)
    return b, c


@dataclass
class SweepModel:
    """Each scan's sweep (its beams taken one after another while the robot moves), deskewed
    by the odometry's nominal motion (:func:`sweep_motion`)."""

    reach: np.ndarray  # (S, 2) (d, a): every pose the scan is mapped with, and its free cones, widened by this
    smin: np.ndarray  # (S,) its free cones prove nothing nearer its sensor (free_cones.sweep_free_from)
    beams: Scans  # the scans, each beam turned by the nominal turn to its time
    offset: np.ndarray  # (B, 2) each beam's sensor moved from the stamp's by the nominal motion (sensor frame)
    err: np.ndarray  # (S,) each beam's sensor within this of its nominal position (rule A's widening)
    turn_lever: np.ndarray  # (S,) the mount's lever turned by the nominal turn moves the sensor at most this
    run_turn: np.ndarray | None = None  # (S, CHUNKS) reach[:, 1] over each run of beams alone (sweep_map)
    run_err: np.ndarray | None = None  # (S, CHUNKS) err over each run of beams alone


def sweep_motion(scans: Scans, params: Params, m, used: np.ndarray) -> SweepModel:
    """The sweep of each scan from the motion steps ``m`` over the rows ``used``.

    ``beams``: the scans with each beam turned by the nominal turn from the stamp to its time
    (deskewed: :meth:`~ivslam_cli.slam.motion.MotionSteps.turn_between`; a constant turn rate
    keeps the beams evenly spaced: ``angle_min + ω̂ b``, ``angle_increment + ω̂ c``, see
    :func:`beam_times`). ``reach`` ``(d, a)``: how far the robot moves while the beams are
    taken (plus the mount's lever turned by the nominal turn) and how far its heading strays
    from the nominal turn. ``offset``: beam ``i``'s sensor moved by the nominal move ``V τ_i``
    (:meth:`~ivslam_cli.slam.motion.MotionSteps.move_between`) and the mount's lever turned by
    ``ω̂ τ_i``; ``err``: how far the move strays from ``V τ``. ``smin``: the distance from the
    sensor below which the scan's free cones prove nothing (:func:`~.free_cones.sweep_free_from`,
    with the deskewed step and what the turn and the sensor's move between two beams stray
    from it)."""
    from dataclasses import replace

    from ivslam_cli.slam.lidar.free_cones import sweep_free_from
    from ivslam_cli.slam.lidar.sweep_map import CHUNKS

    sweep = np.zeros((len(scans), 2))
    smin = np.zeros(len(scans))
    b, c = beam_times(scans, params)
    b, c = b[used], c[used]
    slack = np.full(used.size, float(params.scan_time))
    if not (np.any(c != 0.0) or np.any(b != 0.0) or params.scan_time > 0.0):
        return SweepModel(sweep, smin, scans, np.zeros((0, 2)), np.zeros(len(scans)), np.zeros(len(scans)))
    n = np.diff(scans.offsets)[used]
    s = np.asarray(scans.stamp, float)[used]
    last = b + (np.maximum(n, 1) - 1) * c
    t0, t1 = s + np.minimum(b, last), s + np.maximum(b, last)
    reach = m.reach_between(np.minimum(t0 - slack, s), np.maximum(t1 + slack, s))
    drift = m.drift_between(t0, t1, n, slack)
    w, e, eta = m.turn_between(s, t0, t1, n, slack)
    lever = math.hypot(float(scans.mount[0]), float(scans.mount[1]))
    tau = np.maximum(np.abs(b), np.abs(last)) + slack
    turn_lever = np.zeros(len(scans))
    turn_lever[used] = np.nextafter(np.minimum(np.abs(w) * tau, 2.0) * lever * (1.0 + 1e-12), np.inf)
    sweep[used, 0] = np.nextafter((reach[:, 0] + turn_lever[used]) * (1.0 + 1e-12), np.inf)
    sweep[used, 1] = e
    # the sensor's move between two beams: the robot's, plus its whole turn times the lever
    d_s = np.nextafter((drift[:, 0] + (np.abs(w * c) + eta) * lever) * (1.0 + 1e-12), np.inf)
    a0 = np.asarray(scans.angle_min, float).copy()
    inc = np.asarray(scans.angle_increment, float).copy()
    a0[used] = a0[used] + w * b
    inc[used] = inc[used] + w * c
    smin[used] = sweep_free_from(np.column_stack([d_s, eta]), inc[used], float(params.beams.bearing),
                                 bool(params.beams.fill_gaps))
    # the nominal move of each beam's sensor, in the sensor frame at the stamp
    V, E = m.move_between(s, t0, t1, slack)
    err = sweep[:, 0].copy()
    err[used] = np.minimum(E, sweep[used, 0])
    mx, my, myaw = (float(v) for v in scans.mount)
    offset = np.zeros((scans.ranges.shape[0], 2))
    ci, si = math.cos(-myaw), math.sin(-myaw)
    for j, k in enumerate(used):
        lo, hi = int(scans.offsets[k]), int(scans.offsets[k + 1])
        tau = b[j] + c[j] * np.arange(hi - lo)
        ox = V[j, 0] * tau + (np.cos(w[j] * tau) - 1.0) * mx - np.sin(w[j] * tau) * my
        oy = V[j, 1] * tau + np.sin(w[j] * tau) * mx + (np.cos(w[j] * tau) - 1.0) * my
        offset[lo:hi, 0] = ci * ox - si * oy
        offset[lo:hi, 1] = si * ox + ci * oy
    run_turn = np.repeat(sweep[:, 1:2], CHUNKS, axis=1)
    run_err = np.repeat(err[:, None], CHUNKS, axis=1)
    run_turn[used], run_err[used] = m.sweep_runs(s, b, c, n, w, e, V, err[used], slack, CHUNKS)
    return SweepModel(sweep, smin, replace(scans, angle_min=a0, angle_increment=inc), offset, err, turn_lever,
                      run_turn, run_err)


def trajectory(log: LogData, params: Params, scans: Scans):
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
    m = motion_steps(odo, params.odometry, s[used], prefer=choose_motion(log, params.motion, params.odometry),
                     max_step=params.max_step, path=path)
    n = m.node_stamp.shape[0]
    P = np.empty((n, 3, 2))
    P[:, :, 0] = -np.inf
    P[:, :, 1] = np.inf
    initial, source = initial_box(log, params.initial, float(m.node_stamp[0]))
    P[0] = iv.add(initial, sym(m.lag[0, [0, 0, 1]]))
    return used, dropped, m, P, source, np.zeros(max(n - 1, 0), np.int64)


def dead_reckoning_boxes(log: LogData, params: Params, scans: Scans) -> PosePrediction:
    """Boxes by dead reckoning from the odometry with its bounds (see the module docstring)."""
    used, dropped, m, P, source, events = trajectory(log, params, scans)
    dead_reckon(P, m.kind, m.U, events)
    boxes = np.empty((used.size, 6))
    widen_boxes(P, m.node, m.reach, boxes)
    return PosePrediction(used=used, boxes=boxes, source=source, motion=m.motion, step_events=events,
                          node_stamp=m.node_stamp, dropped=dropped)


def predict_poses(log: LogData, params: Params, scans: Scans) -> PosePrediction:
    """Known pose boxes with ``lidar.poses_known``, else dead reckoning."""
    if params.poses_known:
        return known_pose_boxes(log, params, scans)
    return dead_reckoning_boxes(log, params, scans)
