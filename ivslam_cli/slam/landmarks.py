"""The landmark CSP pipeline (seed 001): pose enclosures and landmark boxes over a whole log.

Variables: the poses ``s_0 .. s_n`` at every node (odometry stamps, plus the stamps of
observations made between them) and the landmarks ``m_1 .. m_L``. Constraints: the motion
model between consecutive nodes and the range-bearing observation model, contracted to a
fixpoint by forward-backward sweeps over the whole trajectory (``landmarks_kernel.solve``),
with q-relaxed intersections per landmark and per pose (outliers).

Motion, by the odometry the log has:

- **twist** ``(v, ω)`` (MRCLAM's commanded velocities, simulated logs): zero-order hold, so an
  observation between two odometry stamps splits the step exactly (a node at its stamp). The
  true speed ``v`` satisfies ``|z_v − v| ≤ odom_v + odom_v_rel·|v|`` and the true turn rate
  ``|z_ω − ω| ≤ odom_w + odom_w_rel·|v|`` at every instant of the step; each step is the pose
  increment enclosing every unicycle path within those bounds (``chord_steps``: errors second
  order in ``dt``, steps cut at ``landmarks.max_step``). The true pose stays within
  ``odom_lag_xy``/``odom_lag_th`` of such a path (commands the drive follows late);
- **pose increments** (``nav_msgs/Odometry``, CARMEN, Victoria Park): the increment between two
  odometry poses in the frame of the first, translation within ``odom_trans_abs +
  odom_trans_rel·|Δ|`` per axis and rotation within ``odom_rot_abs + odom_rot_rel·|Δθ|``.
  An observation between two odometry stamps is attached to the nearer node, widened by the
  step's largest displacement and rotation (assumes the robot stays within its step's bound
  between two odometry poses).

Observations outside the odometry's time span, and of unknown landmarks, are not used.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ivslam_cli import interval as iv
from ivslam_cli.config import Config
from ivslam_cli.errors import IvslamError
from ivslam_cli.logs.model import Dropped, LogData
from ivslam_cli.results.model import (
    Consistency,
    EmptyEvents,
    Landmarks,
    Poses,
    Rejections,
    WidthHistory,
)
from ivslam_cli.slam import landmarks_kernel as K

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


def _sym(half: np.ndarray) -> np.ndarray:
    """``[-h, h]`` rows for non-negative upper bounds ``h``."""
    return np.column_stack([-half, half])


def _bound(value: float) -> float:
    """The upper end of the interval enclosing a decimal bound."""
    return iv.enclose(value)[1] if value else 0.0


def _col(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    return np.column_stack([a, a])


def speed_interval(z: np.ndarray, a: float, r: float) -> np.ndarray:
    """Every true ``v`` with ``|z − v| ≤ a + r·|v|`` (``r < 1``), rows ``(lo, hi)``, outward."""
    if r >= 1.0:
        raise IvslamError(f"bounds.odom_v_rel = {r} must be < 1 (a relative speed bound of 100 % bounds nothing)")
    z = np.asarray(z, dtype=np.float64)
    A = _col(np.full(z.shape, a))
    lo_num = iv.sub(_col(z), A)  # z - a
    hi_num = iv.add(_col(z), A)  # z + a
    one_p = _col(np.full(z.shape, 1.0 + 0.0))
    R = _col(np.full(z.shape, r))
    den_plus = iv.add(one_p, R)  # 1 + r
    den_minus = iv.sub(one_p, R)  # 1 - r
    # lo = (z - a)/(1 + r) if z - a >= 0 else (z - a)/(1 - r); hi symmetric
    lo_a = iv.div(lo_num, den_plus)[:, 0]
    lo_b = iv.div(lo_num, den_minus)[:, 0]
    hi_a = iv.div(hi_num, den_minus)[:, 1]
    hi_b = iv.div(hi_num, den_plus)[:, 1]
    lo = np.where(lo_num[:, 0] >= 0.0, lo_a, lo_b)
    hi = np.where(hi_num[:, 1] > 0.0, hi_a, hi_b)
    return np.column_stack([lo, hi])


def observation_boxes(log: LogData, cfg: Config) -> tuple[np.ndarray, np.ndarray]:
    """``rho ∈ z ± (range_abs + range_rel·z)`` (``rho ≥ 0``), ``alpha ∈ z_α ± bearing``; outward."""
    obs = log.observations
    z = _col(obs.range)
    n = z.shape[0]
    rel = iv.mul(z, np.tile(list(iv.enclose(cfg["bounds.range_rel"])), (n, 1)))
    half = iv.add(rel, np.tile(list(iv.enclose(cfg["bounds.range_abs"])), (n, 1)))[:, 1]
    rho = iv.add(z, _sym(half))
    rho[:, 0] = np.maximum(rho[:, 0], 0.0)
    alpha = iv.add(_col(obs.bearing), _sym(np.full(n, _bound(cfg["bounds.bearing"]))))
    return rho, alpha


def _interp_truth(log: LogData, t: float) -> np.ndarray | None:
    tr = log.truth
    if tr is None or tr.pose is None or tr.pose_stamp is None or len(tr.pose_stamp) < 1:
        return None
    ts = np.asarray(tr.pose_stamp, float)
    if t < ts[0] or t > ts[-1]:
        return None
    p = np.asarray(tr.pose, float)
    th = np.unwrap(p[:, 2])
    return np.array([np.interp(t, ts, p[:, 0]), np.interp(t, ts, p[:, 1]), np.interp(t, ts, th)])


def initial_box(log: LogData, cfg: Config, t0: float) -> tuple[np.ndarray, str]:
    """The initial pose box (3, 2) and where it comes from."""
    margin = [_bound(m) for m in cfg["landmarks.initial_margin"]]
    if cfg["landmarks.initial_pose"] is not None:
        centre, source = np.array(cfg["landmarks.initial_pose"], float), "landmarks.initial_pose"
    elif cfg["landmarks.initial_pose_from_truth"]:
        centre = _interp_truth(log, t0)
        if centre is None:
            raise IvslamError(f"--initial-pose-from-truth: the log has no ground-truth pose at t={t0:.6f}",
                              log.provenance.path)
        source = "ground truth interpolated at the first odometry stamp"
    else:
        centre, source = np.zeros(3), "origin (the map frame is the first pose)"
    box = iv.add(_col(centre), _sym(np.array(margin)))
    return box, source


def _cumulative(step: np.ndarray) -> np.ndarray:
    """Cumulative sums of non-negative step bounds, rounded up (relative float error ≤ n·2⁻⁵³)."""
    c = np.concatenate([[0.0], np.cumsum(step)])
    return np.nextafter(c * (1.0 + (len(c) + 2) * 2.0**-52), np.inf)


def subdivide(stamps: np.ndarray, max_step: float) -> np.ndarray:
    """``stamps`` (sorted) with evenly spaced stamps added so that no gap exceeds ``max_step``
    (up to rounding; 0 or less: unchanged)."""
    if max_step <= 0 or stamps.size < 2:
        return stamps
    gap = np.diff(stamps)
    m = np.ceil(gap / max_step).astype(np.int64)  # pieces per gap
    if np.all(m <= 1):
        return stamps
    k = np.repeat(np.arange(gap.size), np.maximum(m - 1, 0))
    j = np.arange(k.size) - np.repeat(np.cumsum(np.maximum(m - 1, 0)) - np.maximum(m - 1, 0), np.maximum(m - 1, 0)) + 1
    extra = stamps[k] + gap[k] * (j / m[k])
    return np.unique(np.concatenate([stamps, extra]))


def node_lags(t: np.ndarray, z: np.ndarray, node_stamp: np.ndarray, a_xy: float, a_th: float, tau: float,
              memory: float) -> np.ndarray:
    """Per node ``(position, heading)`` half-widths within which the true pose stays of the
    modelled one: ``a_xy + tau·max|v|`` and ``a_th + tau·max|ω|``, the largest commands (rows of
    ``z`` = ``(v, ω)``, held from each stamp of ``t`` to the next) over ``[stamp − memory,
    stamp]``; before the first command, zero. A drive that follows its commands ``tau`` late
    (or as a first-order lag of time constant ``tau``, ``memory`` a few ``tau``) trails the
    commanded path by at most the distance and turn those commands make in ``tau``. Rounded up."""
    n = node_stamp.shape[0]
    lag = np.empty((n, 2))
    lag[:, 0], lag[:, 1] = a_xy, a_th
    if tau <= 0.0:
        return lag
    if memory <= 0.0:
        raise IvslamError(f"bounds.odom_lag_memory = {memory} must be > 0 when bounds.odom_lag_time is set")
    first = np.searchsorted(t, node_stamp - memory, side="right") - 1
    last = np.searchsorted(t, node_stamp, side="right") - 1
    pad = np.vstack([np.abs(z), np.zeros((1, 2))])
    idx = np.ravel(np.column_stack([np.maximum(first, 0), np.maximum(last, 0) + 1]))
    top = np.maximum.reduceat(pad, idx, axis=0)[::2]
    top[last < 0] = 0.0  # the whole window before the first command
    for d in range(2):
        grow = iv.mul(_col(np.full(n, tau)), _col(top[:, d]))
        lag[:, d] = iv.add(_col(lag[:, d]), grow)[:, 1]
    return lag


def chord_steps(V: np.ndarray, W: np.ndarray, dt: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pose increments ``(ρ, α, δθ)`` (in the frame of the step's start) that enclose every path
    of the unicycle ``ẋ = v (cos θ, sin θ)``, ``θ̇ = ω`` over a step of duration ``dt`` with
    ``v(t) ∈ V`` and ``ω(t) ∈ W`` at every instant (any variation within the intervals). Rows
    ``(lo, hi)``, outward.

    With ``ω̄`` the midpoint of ``W``, ``r`` its radius and ``φ = θ_0 + ω̄ dt/2`` (the chord
    direction of the mean turn), ``|θ(t) − φ − ω̄ (t − dt/2)| ≤ r t``, so in the frame of ``φ``:
    along ``∈ [v_lo (dt·sinc(ω̄ dt/2) − r dt²/2), v_hi (dt·sinc(ω̄ dt/2) + r dt²/2)]`` (``1 − x²/6 ≤
    sinc x ≤ 1 − x²/6 + x⁴/120``; valid while
    ``|ω̄| dt/2 + r dt < π/2``, else ``± max|v| dt``) and lateral ``∈ ± (v_hi r dt²/2 + (v_hi −
    v_lo) |ω̄| dt²/8)``; when ``V`` holds negative speeds, along ``∈ ± max|v| dt`` and lateral
    ``∈ ± max|v| (|ω̄| dt²/4 + r dt²/2)``. The rotation is ``W·dt`` exactly. The errors are
    second order in ``dt`` (keep steps short: ``landmarks.max_step``)."""
    n = V.shape[0]
    wbar = np.ascontiguousarray(0.5 * (W[:, 0] + W[:, 1]))
    WB = _col(wbar)
    r = np.maximum(iv.sub(WB, _col(W[:, 0]))[:, 1], iv.sub(_col(W[:, 1]), WB)[:, 1])
    R_ = _col(r)
    half = iv.mul(iv.mul(WB, dt), _col(np.full(n, 0.5)))  # ω̄ dt / 2
    dt2 = iv.sqr(dt)
    vmaxabs = np.maximum(np.abs(V[:, 0]), np.abs(V[:, 1]))
    # |θ − φ| ≤ |ω̄| dt/2 + r dt
    delta = iv.add(iv.mul(_col(np.abs(wbar)), iv.mul(dt, _col(np.full(n, 0.5)))), iv.mul(R_, dt))[:, 1]
    forward = (V[:, 0] >= 0.0) & (delta < 1.5)
    # forward steps
    sinc_lo = iv.sub(_col(np.ones(n)), iv.div(iv.sqr(half), _col(np.full(n, 6.0))))
    along_lo = iv.sub(iv.mul(_col(V[:, 0]), iv.mul(dt, sinc_lo)),
                      iv.mul(_col(V[:, 0]), iv.mul(R_, iv.mul(dt2, _col(np.full(n, 0.5))))))[:, 0]
    x2 = iv.sqr(half)
    sinc_hi = iv.add(sinc_lo, iv.div(iv.sqr(x2), _col(np.full(n, 120.0))))  # sinc x ≤ 1 − x²/6 + x⁴/120
    along_hi = np.minimum(iv.mul(_col(V[:, 1]), dt)[:, 1],
                          iv.add(iv.mul(_col(V[:, 1]), iv.mul(dt, sinc_hi)),
                                 iv.mul(_col(V[:, 1]), iv.mul(R_, iv.mul(dt2, _col(np.full(n, 0.5))))))[:, 1])
    lat_f = iv.add(iv.mul(_col(V[:, 1]), iv.mul(R_, iv.mul(dt2, _col(np.full(n, 0.5))))),
                   iv.mul(iv.sub(_col(V[:, 1]), _col(V[:, 0])),
                          iv.mul(_col(np.abs(wbar)), iv.mul(dt2, _col(np.full(n, 0.125))))))[:, 1]
    # any other step
    m_dt = iv.mul(_col(vmaxabs), dt)[:, 1]
    lat_b = iv.mul(_col(vmaxabs), iv.add(iv.mul(_col(np.abs(wbar)), iv.mul(dt2, _col(np.full(n, 0.25)))),
                                         iv.mul(R_, iv.mul(dt2, _col(np.full(n, 0.5))))))[:, 1]
    along = np.where(forward[:, None], np.column_stack([along_lo, along_hi]), np.column_stack([-m_dt, m_dt]))
    lat = np.where(forward, lat_f, lat_b)
    LAT = np.column_stack([-lat, lat])
    rho = iv.sqrt(iv.add(iv.sqr(along), iv.sqr(LAT)))
    alpha = iv.add(half, iv.atan2(LAT, along))
    return rho, alpha, iv.mul(W, dt)


@dataclass
class MotionSteps:
    """Dead-reckoning steps between nodes, and where each event (observation, scan) sits.

    ``node_stamp`` (N,); ``kind`` (N-1,) and ``U`` (N-1, 5, 2) as ``landmarks_kernel`` reads
    them; ``step_travel`` (N-1,) upper bounds of each step's displacement and ``step_dth``
    (N-1, 2) its heading change; ``lag`` (N, 2): true pose = modelled pose ± (lag_xy, lag_th)
    at each node (twist odometry; zero for pose increments); ``node`` (M,) the node of each
    event and ``reach`` (M, 2) the (position, heading) half-widths by which that node's box is
    widened to hold the pose at the event's own stamp."""

    motion: str
    node_stamp: np.ndarray
    kind: np.ndarray
    U: np.ndarray
    step_travel: np.ndarray
    step_dth: np.ndarray
    lag: np.ndarray
    node: np.ndarray
    reach: np.ndarray


def motion_steps(odo, cfg: Config, s: np.ndarray, prefer: str = "twist", max_step: float = 0.0,
                 path: str = "") -> MotionSteps:
    """The motion model of ``odo`` (see the module docstring) with events at stamps ``s``
    (sorted, within the odometry's span).

    ``prefer``: ``"twist"`` uses the twist when the odometry has one, else the poses;
    ``"pose"`` the reverse. Twist steps get a node at every event stamp (exact split of the
    held twist) and are cut at ``max_step`` seconds; with pose increments an event between two
    odometry stamps is attached to the nearer node, widened by its step's motion.
    """
    if prefer not in ("twist", "pose"):
        raise ValueError(prefer)
    t = np.asarray(odo.stamp, float)
    use_twist = odo.twist is not None and (prefer == "twist" or odo.pose is None)
    if use_twist:
        motion = "twist"
        # nodes: where the held twist changes (a run of equal twists is one exact step), the
        # observation stamps, and the last odometry stamp
        tw_all = np.asarray(odo.twist, float)
        change = np.concatenate([[True], np.any(tw_all[1:] != tw_all[:-1], axis=1)])
        change[-1] = True
        node_stamp = subdivide(np.unique(np.concatenate([t[change], s])), max_step)
        n = node_stamp.shape[0]
        j = np.clip(np.searchsorted(t, node_stamp[:-1], side="right") - 1, 0, len(t) - 1)
        zlo = zhi = tw_all[j]
        a_v, r_v = _bound(cfg["bounds.odom_v"]), _bound(cfg["bounds.odom_v_rel"])
        V = np.column_stack([speed_interval(zlo[:, 0], a_v, r_v)[:, 0], speed_interval(zhi[:, 0], a_v, r_v)[:, 1]])
        vmax = np.maximum(np.abs(V[:, 0]), np.abs(V[:, 1]))
        w_half = iv.add(_col(np.full(n - 1, _bound(cfg["bounds.odom_w"]))),
                        iv.mul(_col(np.full(n - 1, _bound(cfg["bounds.odom_w_rel"]))), _col(vmax)))[:, 1]
        W = np.column_stack([iv.sub(_col(zlo[:, 1]), _sym(w_half))[:, 0], iv.add(_col(zhi[:, 1]), _sym(w_half))[:, 1]])
        wmax = np.maximum(np.abs(W[:, 0]), np.abs(W[:, 1]))
        dt = iv.sub(_col(node_stamp[1:]), _col(node_stamp[:-1]))
        dt[:, 0] = np.maximum(dt[:, 0], 0.0)
        lag = node_lags(t, tw_all, node_stamp, _bound(cfg["bounds.odom_lag_xy"]), _bound(cfg["bounds.odom_lag_th"]),
                        _bound(cfg["bounds.odom_lag_time"]), float(cfg["bounds.odom_lag_memory"]))
        U = np.zeros((n - 1, 5, 2))
        U[:, 0], U[:, 1], U[:, 2] = chord_steps(V, W, dt)
        kind = np.full(n - 1, K.INCREMENT, np.int8)
        step_travel = U[:, 0, 1].copy()
        step_dth = iv.mul(W, dt)
        node = np.searchsorted(node_stamp, s)
        # the true pose at an observation is within the lag of the modelled one
        reach = lag[node]
    elif odo.pose is not None:
        motion = "pose increments"
        node_stamp = t.copy()
        if np.any(np.diff(node_stamp) <= 0):
            raise IvslamError("odometry stamps are not strictly increasing", path)
        n = node_stamp.shape[0]
        p = np.asarray(odo.pose, float)
        d = p[1:, :2] - p[:-1, :2]
        c, sn = np.cos(p[:-1, 2]), np.sin(p[:-1, 2])
        bx, by = c * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + c * d[:, 1]
        raw = p[1:, 2] - p[:-1, 2]
        dth = raw - np.round(raw / (2 * np.pi)) * (2 * np.pi)
        # float error of the increments: a few ulps of the coordinates involved
        eps_xy = 8.0 * np.spacing(np.abs(p[1:, :2]).max(axis=1) + np.abs(p[:-1, :2]).max(axis=1) + 1.0)
        eps_th = 8.0 * np.spacing(np.abs(p[1:, 2]) + np.abs(p[:-1, 2]) + 2 * np.pi)
        norm = np.hypot(bx, by)
        half_t = _bound(cfg["bounds.odom_trans_abs"]) + _bound(cfg["bounds.odom_trans_rel"]) * norm * (1 + 1e-15)
        half_t = np.nextafter(half_t + eps_xy, np.inf)
        half_r = _bound(cfg["bounds.odom_rot_abs"]) + _bound(cfg["bounds.odom_rot_rel"]) * np.abs(dth) * (1 + 1e-15)
        half_r = np.nextafter(half_r + eps_th, np.inf)
        BX, BY = iv.add(_col(bx), _sym(half_t)), iv.add(_col(by), _sym(half_t))
        R = iv.sqrt(iv.add(iv.sqr(BX), iv.sqr(BY)))
        A = iv.atan2(BY, BX)
        U = np.zeros((n - 1, 5, 2))
        U[:, 0], U[:, 1], U[:, 2] = R, A, iv.add(_col(dth), _sym(half_r))
        kind = np.full(n - 1, K.INCREMENT, np.int8)
        step_travel = R[:, 1]
        step_dth = U[:, 2].copy()
        step_turn = np.maximum(np.abs(U[:, 2, 0]), np.abs(U[:, 2, 1]))
        # attach each observation to the nearer odometry node, widened by its step's motion
        su = s
        k = np.clip(np.searchsorted(t, su, side="right") - 1, 0, n - 2)
        nearer_next = (t[k + 1] - su) < (su - t[k])
        node = np.where(nearer_next, k + 1, k)
        exact = t[node] == su
        reach = np.column_stack([np.where(exact, 0.0, step_travel[k]), np.where(exact, 0.0, step_turn[k])])
        lag = np.zeros((n, 2))
    else:
        raise IvslamError("the odometry has neither twist nor poses", path)

    return MotionSteps(motion=motion, node_stamp=node_stamp, kind=kind, U=np.ascontiguousarray(U),
                       step_travel=step_travel, step_dth=step_dth, lag=lag, node=node.astype(np.int64),
                       reach=np.ascontiguousarray(reach, dtype=np.float64))


def build_problem(log: LogData, cfg: Config) -> Problem:
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
    rho_all, alpha_all = observation_boxes(log, cfg)

    m = motion_steps(odo, cfg, s[used], prefer="twist", max_step=float(cfg["landmarks.max_step"]), path=path)
    motion, node_stamp, kind, U, lag = m.motion, m.node_stamp, m.kind, m.U, m.lag
    step_travel, step_dth, node, reach = m.step_travel, m.step_dth, m.node, m.reach
    n = node_stamp.shape[0]

    lm_ids, lm_index = np.unique(obs.landmark_id[used], return_inverse=True)
    counts = np.bincount(lm_index, minlength=lm_ids.size)
    q = np.maximum(int(cfg["robust.q_landmark"]),
                   np.floor(float(cfg["robust.q_landmark_frac"]) * counts).astype(np.int64)).astype(np.int64)
    initial, source = initial_box(log, cfg, float(node_stamp[0]))
    initial = iv.add(initial, _sym(lag[0, [0, 0, 1]]))
    return Problem(
        node_stamp=node_stamp, kind=kind, U=np.ascontiguousarray(U), travel=_cumulative(step_travel),
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


def solve_problem(pb: Problem, cfg: Config):
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
    max_it = int(cfg["landmarks.max_iterations"])
    trace = np.full(max_it, np.nan)
    sweeps = K.solve(P, L, pb.kind, pb.U, pb.node_stamp, pb.travel, pb.turn, pb.turn_err, pb.node, pb.lm, pb.rho, pb.alpha,
                     pb.reach, obs_node_stamp, by_node, node_first, lm_offsets, lm_order, pb.q,
                     int(cfg["robust.q_pose"]), float(cfg["landmarks.pose_window"]),
                     int(cfg["landmarks.heading_slices"]), max_it,
                     float(cfg["landmarks.tolerance"]), status, step_events, pose_events, lm_events, trace)
    return P, L, status, step_events, pose_events, lm_events, trace[:sweeps], int(sweeps)


def _box_width(box: np.ndarray) -> np.ndarray:
    w = box[..., 1] - box[..., 0]
    return np.where(np.all(box[..., 0] <= box[..., 1], axis=-1), np.max(w, axis=-1), np.nan)


def run_landmarks(log: LogData, cfg: Config) -> LandmarksOutput:
    """The landmark CSP over a log (see the module docstring)."""
    t0 = time.perf_counter()
    pb = build_problem(log, cfg)
    P, L, status, step_ev, pose_ev, lm_ev, trace, sweeps = solve_problem(pb, cfg)
    n = pb.node_stamp.shape[0]
    tol = float(cfg["landmarks.tolerance"])
    if pb.lag.any():  # enclosures of the true poses
        ok = np.all(P[..., 0] <= P[..., 1], axis=-1)
        P = iv.add(P.reshape(-1, 2), _sym(pb.lag[:, [0, 0, 1]].reshape(-1))).reshape(n, 3, 2)
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
                     f"q={cfg['robust.q_pose']} ({pose_ev[k]} sweep(s)); skipped"))
    for i in np.flatnonzero(lm_ev):
        rows.append((pb.node_stamp[-1], n - 1, "landmark_qinter", (int(pb.ids[i]), -1), -1,
                     f"landmark {pb.ids[i]}: its observations contradict each other beyond q={pb.q[i]} "
                     f"({lm_ev[i]} sweep(s)); its box kept"))
    rows.sort(key=lambda r: r[0])
    events = EmptyEvents(
        stamp=np.array([r[0] for r in rows], float),
        step=np.array([r[1] for r in rows], np.int64),
        constraint=np.array([r[2] for r in rows], dtype=str).reshape(-1),
        entity=np.array([r[3] for r in rows], np.int64).reshape(-1, 2),
        measurement=np.array([r[4] for r in rows], np.int64),
        text=np.array([r[5] for r in rows], dtype=str).reshape(-1),
    )
    rej = np.flatnonzero(status != K.OBS_USED)
    rejections = Rejections(
        stream=np.array(["observations"] * rej.size, dtype=str).reshape(-1),
        index=pb.obs_index[rej].astype(np.int64),
        reason=np.array([REASONS[int(status[j])] for j in rej], dtype=str).reshape(-1),
    )
    pose_w = _box_width(P[:, :2])
    pose_hist = WidthHistory(
        entity=np.column_stack([np.arange(n), np.full(n, -1)]).astype(np.int64),
        step=np.arange(n, dtype=np.int64), stamp=pb.node_stamp.astype(float), width=pose_w,
        definition="largest side (x, y) of the pose box at each node, metres",
    )
    lm_w = _box_width(L)
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
        f"and at most q_pose = {cfg['robust.q_pose']} among the observations within "
        f"{cfg['landmarks.pose_window']} s of each pose; observations proven to break it are rejected "
        f"({rej.size}) and listed"
    )
    if len(events):
        assumption += (f"; {len(events)} contraction(s) would have emptied a box and were skipped (empty events): "
                       "the data contradict the model there")
    consistency = Consistency(
        empty_events=events, q={"landmark": int(cfg["robust.q_landmark"]), "pose": int(cfg["robust.q_pose"])},
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
        poses=Poses(stamp=pb.node_stamp.astype(float), box=P),
        landmarks=Landmarks(id=pb.ids, box=L),
        consistency=consistency, stats=stats, dropped=pb.dropped,
    )
