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
from ivslam_cli import limits
from ivslam_cli.errors import IvslamError
from ivslam_cli.logs.model import Dropped, GroundTruth, LogData
from ivslam_cli.results.model import (
    FRAME_FIRST_POSE,
    FRAME_WORLD,
    Consistency,
    Landmarks,
    Poses,
    PoseSets,
    Robots,
    Rejections,
    Result,
    WidthHistory,
)
from ivslam_cli.interval.pose import box_width
from ivslam_cli.interval.vector import bound_up, point, sym
from ivslam_cli.slam.landmarks import kernel as K
from ivslam_cli.slam.landmarks.params import Params
from ivslam_cli.slam.landmarks.skips import Skips, skip_edges
from ivslam_cli.slam.landmarks.steps import Steps, chain_steps
from ivslam_cli.slam.motion import cumulative_up, initial_box
from ivslam_cli.slam.pipeline import empty_events, make_result
from ivslam_cli.slam.progress import listening

REASONS = {
    K.OBS_REJECTED_LANDMARK: "misses the q-relaxed intersection of its landmark's observations",
    K.OBS_REJECTED_POSE: "misses the q-relaxed intersection of the observations at its pose",
}


@dataclass
class Chain:
    """One robot's part of the problem: its log, nodes and steps, and its first pose box
    (None: unknown, every pose of the plane)."""

    robot: int
    log: LogData
    steps: Steps
    initial: np.ndarray | None
    initial_source: str


@dataclass
class Problem:
    """The CSP in arrays (see :mod:`.kernel`): the nodes of every chain, one after the other."""

    chains: list[Chain]
    chain_nodes: np.ndarray  # (C+1,) node offsets of the chains
    node_stamp: np.ndarray  # (N,)
    chain_of: np.ndarray  # (N,) chain of each node
    kind: np.ndarray  # (N-1,) int8: INCREMENT, or STEP_NONE between two chains
    U: np.ndarray  # (N-1, 5, 2)
    travel: np.ndarray  # (N,) cumulative upper bound of the distance travelled (along each chain)
    turn: np.ndarray  # (N, 2) cumulative heading change [lo, hi] (float sums, error below turn_err)
    turn_err: float
    obs_stream: np.ndarray  # (M,) str: the stream of each used observation ("observations", ...)
    obs_index: np.ndarray  # (M,) its index in that stream
    node: np.ndarray  # (M,) the observer's node
    lm: np.ndarray  # (M,) landmark index, or -1: a robot seen at node tnode
    tnode: np.ndarray  # (M,) the observed robot's node (-1 for landmarks)
    treach: np.ndarray  # (M, 2) reach of the observed robot at its node
    rho: np.ndarray  # (M, 2)
    alpha: np.ndarray  # (M, 2)
    reach: np.ndarray  # (M, 2)
    ids: np.ndarray  # (L,) landmark ids
    q: np.ndarray  # (L,)
    lag: np.ndarray  # (N, 2): true pose = modelled pose ± (lag_xy, lag_xy, lag_th) at each node
    motion: str
    dropped: list[Dropped]

    @property
    def initial_source(self) -> str:
        return "; ".join(f"robot {c.robot}: {c.initial_source}" if len(self.chains) > 1 else c.initial_source
                         for c in self.chains)


def observation_boxes(log: LogData, params: Params, obs=None) -> tuple[np.ndarray, np.ndarray]:
    """``rho ∈ z ± (range_abs + range_rel·z)`` (``rho ≥ 0``), ``alpha ∈ z_α ± bearing``; outward.
    ``obs``: the observations (default: the log's landmark observations)."""
    obs = log.observations if obs is None else obs
    z = point(obs.range)
    n = z.shape[0]
    rel = iv.mul(z, np.tile(list(iv.enclose(params.range_rel)), (n, 1)))
    half = iv.add(rel, np.tile(list(iv.enclose(params.range_abs)), (n, 1)))[:, 1]
    rho = iv.add(z, sym(half))
    rho[:, 0] = np.maximum(rho[:, 0], 0.0)
    alpha = iv.add(point(obs.bearing), sym(np.full(n, bound_up(params.bearing))))
    return rho, alpha


def _check_log(log: LogData) -> None:
    path = log.provenance.path
    odo, obs = log.odometry, log.observations
    if obs is None or len(obs) == 0:
        raise IvslamError("no landmark observations: --mode landmarks needs range-bearing observations", path)
    if odo is None or len(odo) < 2:
        raise IvslamError("no odometry (at least two samples): --mode landmarks needs a motion model", path)


def _robot_sightings(logs: list[tuple[int, LogData]]) -> list[tuple[int, int, np.ndarray]]:
    """Per observing chain: (chain, observed chain, indices into its other_observations) of the
    measurements of another robot of the run made within both robots' odometry spans."""
    chain_of_robot = {r: c for c, (r, _) in enumerate(logs)}
    out = []
    for c, (r, log) in enumerate(logs):
        oo = log.other_observations
        if oo is None or len(oo) == 0:
            continue
        t = log.odometry.stamp
        for target, tc in chain_of_robot.items():
            if target == r:
                continue
            tt = logs[tc][1].odometry.stamp
            s = oo.stamp
            sel = np.flatnonzero((oo.landmark_id == target) & (s >= max(t[0], tt[0])) & (s <= min(t[-1], tt[-1])))
            if sel.size:
                out.append((c, tc, sel))
    return out


def build_problem(logs: list[tuple[int, LogData]] | LogData, params: Params) -> Problem:
    """Nodes, motion steps, observation intervals and landmark q's from one log, or from the
    logs of several robots sharing their landmarks ``[(robot, log), ...]`` (their
    measurements of each other become observations between two chains)."""
    if isinstance(logs, LogData):
        logs = [(0, logs)]
    multi = len(logs) > 1
    for _, log in logs:
        _check_log(log)
    dropped: list[Dropped] = []
    sightings = _robot_sightings(logs) if multi else []
    # the event stamps of every chain: its landmark observations, its sightings of others, and
    # the stamps at which others saw it
    used, events = [], []
    for c, (r, log) in enumerate(logs):
        t = np.asarray(log.odometry.stamp, float)
        s = np.asarray(log.observations.stamp, float)
        inside = (s >= t[0]) & (s <= t[-1])
        if (~inside).any():
            dropped.append(Dropped(_stream(r, "observations", multi), int((~inside).sum()),
                                   "outside the odometry's time span (not used)"))
        u = np.flatnonzero(inside)
        if u.size == 0:
            raise IvslamError("no landmark observation falls within the odometry's time span", log.provenance.path)
        used.append(u)
        events.append([s[u]])
    for c, tc, sel in sightings:
        st = logs[c][1].other_observations.stamp[sel]
        events[c].append(st)
        events[tc].append(st)
    ev = [np.unique(np.concatenate(e)) for e in events]

    chains: list[Chain] = []
    for c, (r, log) in enumerate(logs):
        steps = chain_steps(log.odometry, params.odometry, ev[c], params.max_step, log.provenance.path)
        t0 = float(steps.node_stamp[0])
        located = params.map_known and params.initial.pose is None and not params.initial.from_truth
        if (c == 0 and not located) or params.initial.from_truth:
            box, source = initial_box(log, params.initial, t0)
            box = iv.add(box, sym(steps.lag[0, [0, 0, 1]]))
        else:
            box, source = None, ("unknown (located by the given map)" if located else
                                 "unknown (located by the shared landmarks and the other robots)")
        chains.append(Chain(robot=r, log=log, steps=steps, initial=box, initial_source=source))

    sizes = np.array([ch.steps.node_stamp.size for ch in chains])
    offs = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    n = int(offs[-1])
    node_stamp = np.concatenate([ch.steps.node_stamp for ch in chains])
    chain_of = np.repeat(np.arange(len(chains)), sizes).astype(np.int64)
    kind = np.full(n - 1, K.INCREMENT, np.int8)
    U = np.zeros((n - 1, 5, 2))
    step_travel = np.zeros(n - 1)
    step_dth = np.zeros((n - 1, 2))
    for c, ch in enumerate(chains):
        a, b = offs[c], offs[c + 1]
        U[a:b - 1] = ch.steps.U
        step_travel[a:b - 1] = ch.steps.step_travel
        step_dth[a:b - 1] = ch.steps.step_dth
        if c + 1 < len(chains):
            kind[b - 1] = K.STEP_NONE
    lag = np.concatenate([ch.steps.lag for ch in chains])

    # observations: landmarks of every chain, then robots seen by others
    parts = {k: [] for k in ("stream", "index", "node", "lmid", "tnode", "treach", "rho", "alpha", "reach")}
    for c, ch in enumerate(chains):
        log, u = ch.log, used[c]
        rho_all, alpha_all = observation_boxes(log, params)
        e = np.searchsorted(ev[c], log.observations.stamp[u])
        parts["stream"].append(np.full(u.size, _stream(ch.robot, "observations", multi)))
        parts["index"].append(u)
        parts["node"].append(offs[c] + ch.steps.node[e])
        parts["lmid"].append(log.observations.landmark_id[u])
        parts["tnode"].append(np.full(u.size, -1, np.int64))
        parts["treach"].append(np.zeros((u.size, 2)))
        parts["rho"].append(rho_all[u])
        parts["alpha"].append(alpha_all[u])
        parts["reach"].append(ch.steps.reach[e])
    for c, tc, sel in sightings:
        ch, tch = chains[c], chains[tc]
        oo = ch.log.other_observations
        rho_all, alpha_all = observation_boxes(ch.log, params, oo)
        st = oo.stamp[sel]
        e = np.searchsorted(ev[c], st)
        te = np.searchsorted(ev[tc], st)
        parts["stream"].append(np.full(sel.size, _stream(ch.robot, "other_observations", multi)))
        parts["index"].append(sel)
        parts["node"].append(offs[c] + ch.steps.node[e])
        parts["lmid"].append(np.full(sel.size, -1, np.int64))
        parts["tnode"].append(offs[tc] + tch.steps.node[te])
        parts["treach"].append(tch.steps.reach[te])
        parts["rho"].append(rho_all[sel])
        parts["alpha"].append(alpha_all[sel])
        parts["reach"].append(ch.steps.reach[e])
    cat = {k: np.concatenate(v) for k, v in parts.items()}
    is_lm = cat["tnode"] < 0
    lm_ids, inv = np.unique(cat["lmid"][is_lm], return_inverse=True)
    lm = np.full(cat["lmid"].size, -1, np.int64)
    lm[is_lm] = inv
    counts = np.bincount(inv, minlength=lm_ids.size)
    q = np.maximum(params.q_landmark,
                   np.floor(params.q_landmark_frac * counts).astype(np.int64)).astype(np.int64)
    travel = cumulative_up(step_travel)
    return Problem(
        chains=chains, chain_nodes=offs, node_stamp=node_stamp, chain_of=chain_of, kind=kind,
        U=np.ascontiguousarray(U), travel=travel,
        turn=np.column_stack([np.concatenate([[0.0], np.cumsum(step_dth[:, 0])]),
                             np.concatenate([[0.0], np.cumsum(step_dth[:, 1])])]),
        # recursive summation: |error| <= (n-1)·u·Σ|terms| (doubled, plus a tiny absolute term)
        turn_err=float((n + 4) * 2.0**-52 * np.abs(step_dth).sum() + 1e-300),
        obs_stream=cat["stream"].astype(str), obs_index=cat["index"].astype(np.int64),
        node=cat["node"].astype(np.int64), lm=lm, tnode=cat["tnode"].astype(np.int64),
        treach=np.ascontiguousarray(cat["treach"], dtype=np.float64),
        rho=np.ascontiguousarray(cat["rho"]), alpha=np.ascontiguousarray(cat["alpha"]),
        reach=np.ascontiguousarray(cat["reach"], dtype=np.float64), ids=lm_ids.astype(np.int64), q=q, lag=lag,
        motion=chains[0].steps.motion, dropped=dropped,
    )


def _stream(robot: int, stream: str, multi: bool) -> str:
    return f"robot{robot}/{stream}" if multi else stream


@dataclass
class LandmarksOutput:
    poses: Poses
    landmarks: Landmarks
    consistency: Consistency
    stats: dict
    dropped: list[Dropped]
    pose_sets: PoseSets | None = None
    problem: Problem | None = None
    robots: Robots | None = None
    truth: GroundTruth | None = None  # several robots: their truths, one after the other (robots.truth_offsets)


@dataclass
class Solution:
    """What the kernel fills: the pose sets and their hulls (modelled poses), the landmark
    boxes, the observations' status and the event counters."""

    PS: np.ndarray
    H: np.ndarray
    L: np.ndarray
    status: np.ndarray
    step_events: np.ndarray
    pose_events: np.ndarray
    lm_events: np.ndarray
    trace: np.ndarray
    sweeps: int
    skips: Skips
    skip_events: np.ndarray


def solve_problem(pb: Problem, params: Params, known_landmarks: np.ndarray | None = None) -> Solution:
    """Run the kernel. ``known_landmarks`` (L, 2, 2): the landmark boxes to start from (the
    map given: localisation only); default unbounded."""
    n = pb.node_stamp.shape[0]
    S = params.pose_slices
    # a (3, 2) box per node and slice, an arc (2, 2) per observation and slice
    limits.check("POSE_SET_BYTES", S * (48 * n + 32 * pb.node.size),
                 f"pose sets of {n:,} nodes and {pb.node.size:,} observations in {S} heading slices "
                 "(landmarks.pose_slices: fewer need less), bytes")
    BINS = K.make_bins(S)
    PS = np.empty((n, S, 3, 2))
    PS[:, :, :2, 0] = -np.inf
    PS[:, :, :2, 1] = np.inf
    PS[:, :, 2] = BINS[None]
    for c, ch in enumerate(pb.chains):
        if ch.initial is not None:
            K.set_from_box(PS, int(pb.chain_nodes[c]), np.ascontiguousarray(ch.initial, dtype=np.float64), BINS)
    H = np.empty((n, 3, 2))
    if known_landmarks is not None:
        L = np.ascontiguousarray(known_landmarks, dtype=np.float64).copy()
    else:
        L = np.empty((pb.ids.size, 2, 2))
        L[:, :, 0] = -np.inf
        L[:, :, 1] = np.inf
    by_node = np.argsort(pb.node, kind="stable").astype(np.int64)
    obs_node_stamp = np.ascontiguousarray(pb.node_stamp[pb.node[by_node]])
    chain_obs = np.searchsorted(pb.chain_of[pb.node[by_node]], np.arange(len(pb.chains) + 1)).astype(np.int64)
    node_first = np.full(n, -1, np.int64)
    node_first[pb.node[by_node][::-1]] = by_node[::-1]
    robot_obs = np.flatnonzero(pb.tnode >= 0)
    by_target = robot_obs[np.argsort(pb.tnode[robot_obs], kind="stable")].astype(np.int64)
    target_first = np.full(n, -1, np.int64)
    target_first[pb.tnode[by_target][::-1]] = np.arange(by_target.size)[::-1]
    node_first[(node_first < 0) & (target_first >= 0)] = 0  # nodes seen by others are updated too
    lm_obs = np.flatnonzero(pb.lm >= 0)
    lm_order = lm_obs[np.argsort(pb.lm[lm_obs], kind="stable")].astype(np.int64)
    lm_offsets = np.concatenate([[0], np.cumsum(np.bincount(pb.lm[lm_obs], minlength=pb.ids.size))]).astype(np.int64)
    status = np.zeros(pb.node.size, np.int8)
    step_events = np.zeros(n - 1, np.int64)
    pose_events = np.zeros(n, np.int64)
    lm_events = np.zeros(pb.ids.size, np.int64)
    max_it = params.max_iterations
    trace = np.full(max_it, np.nan)
    skips = skip_edges(np.unique(pb.node), pb.chain_of, pb.U, params.skip_levels)
    skip_events = np.zeros(skips.count, np.int64)
    sweeps = K.solve(PS, H, L, BINS, pb.kind, pb.U, pb.node_stamp, pb.chain_of, pb.travel, pb.turn, pb.turn_err,
                     pb.node, pb.lm, pb.tnode, pb.treach, pb.rho, pb.alpha, pb.reach, obs_node_stamp, by_node,
                     node_first, chain_obs, by_target, target_first, lm_offsets, lm_order, pb.q, params.q_pose,
                     params.pose_window, params.pose_window_obs, params.pose_pieces, max_it, params.tolerance, status, step_events,
                     pose_events, lm_events, trace, skips.a, skips.b, skips.R, skips.in_off, skips.out, skips.out_off,
                     skip_events, params.q_pose_scope == "node")
    return Solution(PS, H, L, status, step_events, pose_events, lm_events, trace[:sweeps], int(sweeps), skips,
                    skip_events)


def true_pose_sets(pb: Problem, sol: Solution) -> tuple[np.ndarray, PoseSets]:
    """The enclosures of the true poses: the hulls ``(N, 3, 2)`` and the pose sets, each box
    widened by its node's lag (the true pose within the lag of the modelled one)."""
    n = pb.node_stamp.shape[0]
    nb = K.count_boxes(sol.PS)
    offsets = np.empty(n + 1, np.int64)
    flat = np.empty((nb, 3, 2))
    K.flatten_sets(sol.PS, offsets, flat)
    P = sol.H.copy()
    # headings on the real line, each chain unwrapped: a node's set moved by the multiple of 2π
    # that brings its hull nearest the previous node's (the kernel keeps them in [−π, π])
    shift = np.zeros(n)
    ok = np.all(P[..., 0] <= P[..., 1], axis=-1) & np.isfinite(P[:, 2]).all(axis=-1)
    centre = np.where(ok, 0.5 * (P[:, 2, 0] + P[:, 2, 1]), np.nan)
    for c in range(len(pb.chains)):
        a, b = int(pb.chain_nodes[c]), int(pb.chain_nodes[c + 1])
        prev = np.nan
        for k in range(a, b):
            if not ok[k]:
                continue
            if np.isfinite(prev):
                shift[k] = 2 * np.pi * np.round((prev - centre[k]) / (2 * np.pi))
            prev = centre[k] + shift[k]
    if shift.any():
        owner = np.repeat(np.arange(n), np.diff(offsets))
        P[:, 2] = iv.add(P[:, 2], point(shift))
        flat[:, 2] = iv.add(flat[:, 2], point(shift[owner]))
    if pb.lag.any():
        ok = np.all(P[..., 0] <= P[..., 1], axis=-1)
        P = iv.add(P.reshape(-1, 2), sym(pb.lag[:, [0, 0, 1]].reshape(-1))).reshape(n, 3, 2)
        P[~ok] = [np.inf, -np.inf]
        owner = np.repeat(np.arange(n), np.diff(offsets))
        flat = iv.add(flat.reshape(-1, 2), sym(pb.lag[owner][:, [0, 0, 1]].reshape(-1))).reshape(-1, 3, 2)
    return P, PoseSets(offsets=offsets, boxes=flat)


def solve(log, params: Params, known_landmarks: dict[int, tuple[float, float]] | None = None,
          known_margin: float = 0.0, progress=None) -> LandmarksOutput:
    """The landmark CSP over a log, or over ``[(robot, log), ...]`` (see the module
    docstring). ``known_landmarks`` ``{id: (x, y)}``: the map given, each landmark within
    ``known_margin`` (localisation only; landmarks not in it are unknown)."""
    t0 = time.perf_counter()
    pb = build_problem(log.robots if isinstance(log, LogData) and log.robots else log, params)
    if known_landmarks is None and params.map_known:
        known_landmarks, known_margin = true_map(log), params.map_margin
    L0 = None
    if known_landmarks is not None:
        L0 = np.empty((pb.ids.size, 2, 2))
        L0[..., 0], L0[..., 1] = -np.inf, np.inf
        for i, lid in enumerate(pb.ids):
            if int(lid) in known_landmarks:
                xy = iv.add(point(np.asarray(known_landmarks[int(lid)], float)), sym(np.full(2, bound_up(known_margin))))
                L0[i] = xy
    with listening(progress, "sweep"):
        sol = solve_problem(pb, params, L0)
    L, status, step_ev, pose_ev, lm_ev, trace, sweeps = (sol.L, sol.status, sol.step_events, sol.pose_events,
                                                         sol.lm_events, sol.trace, sol.sweeps)
    n = pb.node_stamp.shape[0]
    tol = params.tolerance
    P, sets = true_pose_sets(pb, sol)
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
    sk = sol.skips
    for e in np.flatnonzero(sol.skip_events):
        a, b = int(sk.a[e]), int(sk.b[e])
        rows.append((pb.node_stamp[a], a, "motion", (a, b), -1,
                     f"the motion from pose {a} to pose {b} (t={pb.node_stamp[a]:.3f} to {pb.node_stamp[b]:.3f} s, "
                     f"composed) contradicts the poses ({sol.skip_events[e]} sweep(s)); its contraction was skipped"))
    for i in np.flatnonzero(lm_ev):
        rows.append((pb.node_stamp[-1], n - 1, "landmark_qinter", (int(pb.ids[i]), -1), -1,
                     f"landmark {pb.ids[i]}: its observations contradict each other beyond q={pb.q[i]} "
                     f"({lm_ev[i]} sweep(s)); its box kept"))
    rows.sort(key=lambda r: r[0])
    events = empty_events(rows)
    rej = np.flatnonzero(status != K.OBS_USED)
    rejections = Rejections(
        stream=np.asarray(pb.obs_stream[rej], dtype=str).reshape(-1),
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
        + (f"and at most q_pose = {params.q_pose} at each pose (a pose's q-relaxed intersection over the "
           f"observations within {params.pose_window} s of it tolerates q_pose at each pose they come from, "
           f"at most q of a landmark's)" if params.q_pose_scope == "node" else
           f"and at most q_pose = {params.q_pose} among the observations within {params.pose_window} s of each pose")
        + f"; observations proven to break it are rejected "
        f"({rej.size}) and listed"
    )
    if known_landmarks is not None:
        assumption += (f"; localisation only: the landmarks given (map_known), each within ±{known_margin:g} m of "
                       "its position in the log's ground truth")
    if len(events):
        assumption += (f"; {len(events)} contraction(s) would have emptied a box and were skipped (empty events): "
                       "the data contradict the model there")
    consistency = Consistency(
        empty_events=events, q={"landmark": params.q_landmark, "pose": params.q_pose},
        rejected=rejections, widths={"pose": pose_hist, "landmark": lm_hist}, assumption=assumption,
    )
    robots, truth = None, None
    if len(pb.chains) > 1:
        robots, truth = _robots_and_truth(pb, log)
    runtime = time.perf_counter() - t0
    stats = {
        "motion": pb.motion, "nodes": int(n), "steps": int(n - 1), "observations": int(pb.node.size),
        "observations_rejected": int(rej.size), "landmarks": int(pb.ids.size), "sweeps": int(sweeps),
        "converged": int(bool(converged)), "final_width_sum": float(trace[-1]) if sweeps else float("nan"),
        "median_pose_width": float(np.nanmedian(pose_w)) if np.isfinite(pose_w).any() else float("nan"),
        "median_landmark_width": float(np.nanmedian(lm_w)) if np.isfinite(lm_w).any() else float("nan"),
        "median_heading_width": _median_finite(P[:, 2, 1] - P[:, 2, 0]),
        "pose_slices": int(params.pose_slices), "pose_set_boxes": int(sets.boxes.shape[0]),
        "pose_set_max_boxes": int(np.diff(sets.offsets).max()) if n else 0,
        "skip_edges": int(sol.skips.count),
        "solve_s": float(runtime),
    }
    return LandmarksOutput(
        poses=Poses(stamp=pb.node_stamp.astype(float), box=P,
                    **({"frame": FRAME_WORLD} if (params.initial.pose is not None or params.initial.from_truth
                                                   or known_landmarks is not None) else
                       {"frame": FRAME_FIRST_POSE, "origin_stamp": float(pb.node_stamp[0])})),
        landmarks=Landmarks(id=pb.ids, box=L),
        consistency=consistency, stats=stats, dropped=pb.dropped, pose_sets=sets, problem=pb,
        robots=robots, truth=truth,
    )


def true_map(log) -> dict[int, tuple[float, float]]:
    """``{id: (x, y)}`` of the landmarks in the ground truth of ``log`` (a log, or ``[(robot,
    log), ...]``: the first that has them), for ``landmarks.map_known``."""
    logs = [log] if isinstance(log, LogData) else [lg for _, lg in log]
    for lg in logs:
        tr = lg.truth
        if tr is not None and tr.landmark_id is not None and tr.landmark_xy is not None and len(tr.landmark_id):
            xy = np.asarray(tr.landmark_xy, float).reshape(-1, 2)
            return {int(i): (float(x), float(y)) for i, (x, y) in zip(np.asarray(tr.landmark_id), xy)}
    raise IvslamError("landmarks.map_known needs the landmark positions in the log's ground truth; this log has none",
                      logs[0].provenance.path if logs else "")


def _robots_and_truth(pb: Problem, log: LogData) -> tuple[Robots, GroundTruth]:
    """Which pose rows are whose, and the robots' truths one after the other."""
    stamps, poses, counts = [], [], []
    for ch in pb.chains:
        tr = ch.log.truth
        ok = tr is not None and tr.pose is not None and tr.pose_stamp is not None
        stamps.append(np.asarray(tr.pose_stamp, float) if ok else np.zeros(0))
        poses.append(np.asarray(tr.pose, float).reshape(-1, 3) if ok else np.zeros((0, 3)))
        counts.append(stamps[-1].size)
    top = log.truth if log.truth is not None else GroundTruth()
    truth = GroundTruth(pose_stamp=np.concatenate(stamps), pose=np.concatenate(poses),
                        landmark_id=top.landmark_id, landmark_xy=top.landmark_xy)
    robots = Robots(id=np.array([ch.robot for ch in pb.chains], np.int64), pose_offsets=pb.chain_nodes.astype(np.int64),
                    truth_offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64))
    return robots, truth


def _median_finite(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if a.size else float("nan")


def run(log: LogData, params: Params, progress=None) -> Result:
    """The landmark CSP over ``log`` as a :class:`Result` (pose tube and landmark boxes)."""
    out = solve(log, params, progress=progress)
    res = make_result("landmarks", log, dropped=out.dropped, poses=out.poses, landmarks=out.landmarks,
                      consistency=out.consistency, stats=out.stats, pose_sets=out.pose_sets, robots=out.robots)
    if out.truth is not None:
        res.truth = out.truth
    return res


def summary(result: Result) -> str:
    """The CLI line: poses, landmarks, observations used and rejected, sweeps, empty events."""
    s = result.stats
    return (f"landmarks: {s['nodes']} poses, {s['landmarks']} landmarks, {s['observations']} observations "
            f"({s['observations_rejected']} rejected), {s['sweeps']} sweep(s)"
            f"{'' if s['converged'] else ' (not converged)'}, {len(result.consistency.empty_events)} empty event(s)")
