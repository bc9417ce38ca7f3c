"""The landmark CSP pipeline: pose enclosures and landmark boxes over a whole log.

Variables: the poses ``s_0 .. s_n`` at every node (odometry stamps, plus the stamps of
observations made between them) and the landmarks ``m_1 .. m_L``. Constraints: the motion
model between consecutive nodes and the range-bearing observation model, contracted to a
fixpoint by forward-backward sweeps over the whole trajectory (:func:`.kernel.solve`),
with q-relaxed intersections per landmark and per pose (outliers).

Motion: :mod:`ivslam_cli.slam.motion` (twist or pose increments, with their bounds).

Observations outside the odometry's time span, and of unknown landmarks, are not used.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ivslam_cli import interval as iv
from ivslam_cli.errors import IvslamError
from ivslam_cli.logs.model import Dropped, LogData
from ivslam_cli.results.model import (
    FRAME_FIRST_POSE,
    FRAME_WORLD,
    Consistency,
    Landmarks,
    Poses,
    Rejections,
    Result,
    WidthHistory,
)
from ivslam_cli.interval.pose import box_width
from ivslam_cli.interval.vector import bound_up, point, sym
from ivslam_cli.slam.landmarks import kernel as K
from ivslam_cli.slam.landmarks.params import Params
from ivslam_cli.slam.motion import cumulative_up, initial_box, motion_steps
from ivslam_cli.slam.pipeline import empty_events, make_result

REASONS = {
    K.OBS_REJECTED_LANDMARK: "misses the q-relaxed intersection of its landmark's observations",
    K.OBS_REJECTED_POSE: "misses the q-relaxed intersection of the observations at its pose",
}


@dataclass
class Problem:
    """The CSP in arrays (see ``landmarks_kernel``)."""

    node_stamp: np.ndarray  # (N,)
    kind: np.ndarray  # (N-1,) int8
    U: np.ndarray  # (N-1, 5, 2)
    travel: np.ndarray  # (N,) cumulative upper bound of the distance travelled
    turn: np.ndarray  # (N, 2) cumulative heading change [lo, hi] (float sums, error below turn_err)
    turn_err: float
    obs_index: np.ndarray  # (M,) index of each used observation in log.observations
    node: np.ndarray  # (M,)
    lm: np.ndarray  # (M,) landmark index
    rho: np.ndarray  # (M, 2)
    alpha: np.ndarray  # (M, 2)
    reach: np.ndarray  # (M, 2)
    ids: np.ndarray  # (L,) landmark ids
    q: np.ndarray  # (L,)
    initial: np.ndarray  # (3, 2) of the modelled pose
    lag: np.ndarray  # (N, 2): true pose = modelled pose ± (lag_xy, lag_xy, lag_th) at each node
    motion: str
    dropped: list[Dropped]
    initial_source: str


def observation_boxes(log: LogData, params: Params) -> tuple[np.ndarray, np.ndarray]:
    """``rho ∈ z ± (range_abs + range_rel·z)`` (``rho ≥ 0``), ``alpha ∈ z_α ± bearing``; outward."""
    obs = log.observations
    z = point(obs.range)
    n = z.shape[0]
    rel = iv.mul(z, np.tile(list(iv.enclose(params.range_rel)), (n, 1)))
    half = iv.add(rel, np.tile(list(iv.enclose(params.range_abs)), (n, 1)))[:, 1]
    rho = iv.add(z, sym(half))
    rho[:, 0] = np.maximum(rho[:, 0], 0.0)
    alpha = iv.add(point(obs.bearing), sym(np.full(n, bound_up(params.bearing))))
    return rho, alpha


def build_problem(log: LogData, params: Params) -> Problem:
    """Nodes, motion steps, observation intervals and landmark q's from a log and a config."""
    path = log.provenance.path
    odo, obs = log.odometry, log.observations
    if obs is None or len(obs) == 0:
        raise IvslamError("no landmark observations: --mode landmarks needs range-bearing observations", path)
    if odo is None or len(odo) < 2:
        raise IvslamError("no odometry (at least two samples): --mode landmarks needs a motion model", path)
    dropped: list[Dropped] = []
    t = np.asarray(odo.stamp, float)
    s = np.asarray(obs.stamp, float)
    inside = (s >= t[0]) & (s <= t[-1])
    if (~inside).any():
        dropped.append(Dropped("observations", int((~inside).sum()), "outside the odometry's time span (not used)"))
    used = np.flatnonzero(inside)
    if used.size == 0:
        raise IvslamError("no landmark observation falls within the odometry's time span", path)
    rho_all, alpha_all = observation_boxes(log, params)

    m = motion_steps(odo, params.odometry, s[used], prefer="twist", max_step=params.max_step, path=path)
    motion, node_stamp, kind, U, lag = m.motion, m.node_stamp, m.kind, m.U, m.lag
    step_travel, step_dth, node, reach = m.step_travel, m.step_dth, m.node, m.reach
    n = node_stamp.shape[0]

    lm_ids, lm_index = np.unique(obs.landmark_id[used], return_inverse=True)
    counts = np.bincount(lm_index, minlength=lm_ids.size)
    q = np.maximum(params.q_landmark,
                   np.floor(params.q_landmark_frac * counts).astype(np.int64)).astype(np.int64)
    initial, source = initial_box(log, params.initial, float(node_stamp[0]))
    initial = iv.add(initial, sym(lag[0, [0, 0, 1]]))
    return Problem(
        node_stamp=node_stamp, kind=kind, U=np.ascontiguousarray(U), travel=cumulative_up(step_travel),
        turn=np.column_stack([np.concatenate([[0.0], np.cumsum(step_dth[:, 0])]),
                             np.concatenate([[0.0], np.cumsum(step_dth[:, 1])])]),
        # recursive summation: |error| <= (n-1)·u·Σ|terms| (doubled, plus a tiny absolute term)
        turn_err=float((n + 4) * 2.0**-52 * np.abs(step_dth).sum() + 1e-300),
        obs_index=used, node=node.astype(np.int64), lm=lm_index.astype(np.int64),
        rho=np.ascontiguousarray(rho_all[used]), alpha=np.ascontiguousarray(alpha_all[used]),
        reach=np.ascontiguousarray(reach), ids=lm_ids.astype(np.int64), q=q, initial=initial, lag=lag, motion=motion,
        dropped=dropped, initial_source=source,
    )


@dataclass
class LandmarksOutput:
    poses: Poses
    landmarks: Landmarks
    consistency: Consistency
    stats: dict
    dropped: list[Dropped]


def solve_problem(pb: Problem, params: Params):
    """Run the kernel; returns the arrays it fills."""
    n = pb.node_stamp.shape[0]
    P = np.empty((n, 3, 2))
    P[:, :, 0] = -np.inf
    P[:, :, 1] = np.inf
    P[0] = pb.initial
    L = np.empty((pb.ids.size, 2, 2))
    L[:, :, 0] = -np.inf
    L[:, :, 1] = np.inf
    by_node = np.argsort(pb.node, kind="stable").astype(np.int64)
    obs_node_stamp = np.ascontiguousarray(pb.node_stamp[pb.node[by_node]])
    node_first = np.full(n, -1, np.int64)
    node_first[pb.node[by_node][::-1]] = by_node[::-1]
    lm_order = np.argsort(pb.lm, kind="stable").astype(np.int64)
    lm_offsets = np.concatenate([[0], np.cumsum(np.bincount(pb.lm, minlength=pb.ids.size))]).astype(np.int64)
    status = np.zeros(pb.node.size, np.int8)
    step_events = np.zeros(n - 1, np.int64)
    pose_events = np.zeros(n, np.int64)
    lm_events = np.zeros(pb.ids.size, np.int64)
    max_it = params.max_iterations
    trace = np.full(max_it, np.nan)
    sweeps = K.solve(P, L, pb.kind, pb.U, pb.node_stamp, pb.travel, pb.turn, pb.turn_err, pb.node, pb.lm, pb.rho, pb.alpha,
                     pb.reach, obs_node_stamp, by_node, node_first, lm_offsets, lm_order, pb.q,
                     params.q_pose, params.pose_window, params.heading_slices, max_it, params.tolerance, status, step_events, pose_events, lm_events, trace)
    return P, L, status, step_events, pose_events, lm_events, trace[:sweeps], int(sweeps)


def solve(log: LogData, params: Params) -> LandmarksOutput:
    """The landmark CSP over a log (see the module docstring)."""
    t0 = time.perf_counter()
    pb = build_problem(log, params)
    P, L, status, step_ev, pose_ev, lm_ev, trace, sweeps = solve_problem(pb, params)
    n = pb.node_stamp.shape[0]
    tol = params.tolerance
    if pb.lag.any():  # enclosures of the true poses
        ok = np.all(P[..., 0] <= P[..., 1], axis=-1)
        P = iv.add(P.reshape(-1, 2), sym(pb.lag[:, [0, 0, 1]].reshape(-1))).reshape(n, 3, 2)
        P[~ok] = [np.inf, -np.inf]
    converged = sweeps >= 2 and (trace[-2] - trace[-1]) <= tol * trace[-2] if sweeps >= 2 else False

    # consistency record
    rows = []  # (stamp, step, constraint, entity, measurement, text)
    for k in np.flatnonzero(step_ev):
        rows.append((pb.node_stamp[k], k, "motion", (int(k), -1), -1,
                     f"motion step {k} -> {k + 1} (t={pb.node_stamp[k]:.3f} s) contradicts the poses "
                     f"({step_ev[k]} sweep(s)); its contraction was skipped"))
    for k in np.flatnonzero(pose_ev):
        rows.append((pb.node_stamp[k], k, "pose_qinter", (int(k), -1), -1,
                     f"the observations at pose {k} (t={pb.node_stamp[k]:.3f} s) contradict it beyond "
                     f"q={params.q_pose} ({pose_ev[k]} sweep(s)); skipped"))
    for i in np.flatnonzero(lm_ev):
        rows.append((pb.node_stamp[-1], n - 1, "landmark_qinter", (int(pb.ids[i]), -1), -1,
                     f"landmark {pb.ids[i]}: its observations contradict each other beyond q={pb.q[i]} "
                     f"({lm_ev[i]} sweep(s)); its box kept"))
    rows.sort(key=lambda r: r[0])
    events = empty_events(rows)
    rej = np.flatnonzero(status != K.OBS_USED)
    rejections = Rejections(
        stream=np.array(["observations"] * rej.size, dtype=str).reshape(-1),
        index=pb.obs_index[rej].astype(np.int64),
        reason=np.array([REASONS[int(status[j])] for j in rej], dtype=str).reshape(-1),
    )
    pose_w = box_width(P[:, :2])
    pose_hist = WidthHistory(
        entity=np.column_stack([np.arange(n), np.full(n, -1)]).astype(np.int64),
        step=np.arange(n, dtype=np.int64), stamp=pb.node_stamp.astype(float), width=pose_w,
        definition="largest side (x, y) of the pose box at each node, metres",
    )
    lm_w = box_width(L)
    lm_hist = WidthHistory(
        entity=np.column_stack([pb.ids, np.full(pb.ids.size, -1)]).astype(np.int64),
        step=np.full(pb.ids.size, n - 1, np.int64), stamp=np.full(pb.ids.size, pb.node_stamp[-1]),
        width=lm_w, definition="largest side of the landmark box after the last sweep, metres",
    )
    motion_bounds = ("|z_v − v| ≤ odom_v + odom_v_rel·|v| and |z_ω − ω| ≤ odom_w + odom_w_rel·|v| at every "
                     "instant (commanded/measured twist held between odometry stamps) for a modelled pose the true "
                     f"one stays within ±(odom_lag_xy + odom_lag_time·max|v|) m, ±(odom_lag_th + odom_lag_time·max|ω|) "
                     f"rad of (largest commands over the last odom_lag_memory s; here up to ±{pb.lag[:, 0].max():.3g} m, "
                     f"±{pb.lag[:, 1].max():.3g} rad)" if pb.motion == "twist" else
                     "each odometry increment within ±(odom_trans_abs + odom_trans_rel·|Δ|) per axis and "
                     "±(odom_rot_abs + odom_rot_rel·|Δθ|), the robot staying within its step's bound between "
                     "two odometry poses")
    assumption = (
        f"the initial pose in its box ({pb.initial_source}); {motion_bounds}; every range error within "
        f"±(range_abs + range_rel·range) and bearing error within ±bearing, except for at most q observations "
        f"per landmark (q = max(q_landmark, ⌊q_landmark_frac·m⌋), here {int(pb.q.min())}..{int(pb.q.max())}) "
        f"and at most q_pose = {params.q_pose} among the observations within "
        f"{params.pose_window} s of each pose; observations proven to break it are rejected "
        f"({rej.size}) and listed"
    )
    if len(events):
        assumption += (f"; {len(events)} contraction(s) would have emptied a box and were skipped (empty events): "
                       "the data contradict the model there")
    consistency = Consistency(
        empty_events=events, q={"landmark": params.q_landmark, "pose": params.q_pose},
        rejected=rejections, widths={"pose": pose_hist, "landmark": lm_hist}, assumption=assumption,
    )
    runtime = time.perf_counter() - t0
    stats = {
        "motion": pb.motion, "nodes": int(n), "steps": int(n - 1), "observations": int(pb.node.size),
        "observations_rejected": int(rej.size), "landmarks": int(pb.ids.size), "sweeps": int(sweeps),
        "converged": int(bool(converged)), "final_width_sum": float(trace[-1]) if sweeps else float("nan"),
        "median_pose_width": float(np.nanmedian(pose_w)) if np.isfinite(pose_w).any() else float("nan"),
        "median_landmark_width": float(np.nanmedian(lm_w)) if np.isfinite(lm_w).any() else float("nan"),
        "solve_s": float(runtime),
    }
    return LandmarksOutput(
        poses=Poses(stamp=pb.node_stamp.astype(float), box=P,
                    **({"frame": FRAME_WORLD} if params.initial.pose is not None or params.initial.from_truth else
                       {"frame": FRAME_FIRST_POSE, "origin_stamp": float(pb.node_stamp[0])})),
        landmarks=Landmarks(id=pb.ids, box=L),
        consistency=consistency, stats=stats, dropped=pb.dropped,
    )


def run(log: LogData, params: Params, progress=None) -> Result:
    """The landmark CSP over ``log`` as a :class:`Result` (pose tube and landmark boxes)."""
    out = solve(log, params)
    return make_result("landmarks", log, dropped=out.dropped, poses=out.poses, landmarks=out.landmarks,
                       consistency=out.consistency, stats=out.stats)


def summary(result: Result) -> str:
    """The CLI line: poses, landmarks, observations used and rejected, sweeps, empty events."""
    s = result.stats
    return (f"landmarks: {s['nodes']} poses, {s['landmarks']} landmarks, {s['observations']} observations "
            f"({s['observations_rejected']} rejected), {s['sweeps']} sweep(s)"
            f"{'' if s['converged'] else ' (not converged)'}, {len(result.consistency.empty_events)} empty event(s)")
