"""The motion model shared by the landmark and LiDAR pipelines: pose increments between the
nodes of a trajectory, from a log's odometry, with their bounds; and the initial pose box.

Motion, by the odometry the log has:

- **twist** ``(v, ω)`` (MRCLAM's commanded velocities, simulated logs): zero-order hold, so an
  event (observation, scan) between two odometry stamps splits the step exactly (a node at its
  stamp). The true speed ``v`` satisfies ``|z_v − v| ≤ odom_v + odom_v_rel·|v|`` and the true
  turn rate ``|z_ω − ω| ≤ odom_w + odom_w_rel·|v|`` at every instant of the step; each step is
  the pose increment enclosing every unicycle path within those bounds (:func:`chord_steps`:
  errors second order in ``dt``, steps cut at ``max_step``). The true pose stays within
  ``odom_lag_xy``/``odom_lag_th`` of such a path (commands the drive follows late);
- **pose increments** (``nav_msgs/Odometry``, CARMEN, Victoria Park): the increment between two
  odometry poses in the frame of the first, translation within ``odom_trans_abs +
  odom_trans_rel·|Δ|`` per axis and rotation within ``odom_rot_abs + odom_rot_rel·|Δθ|``. An
  event between two odometry stamps is attached to the nearer node, widened by the step's
  largest displacement and rotation (assumes the robot stays within its step's bound between
  two odometry poses).

The steps are contracted by :func:`ivslam_cli.slam.motion_kernel.step_contract` (the unicycle
motion constraint of the "Guaranteed SLAM – practical considerations" slides, written as a
range-bearing increment).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from ivslam_cli import interval as iv
from ivslam_cli.errors import IvslamError
from ivslam_cli.interval.vector import bound_up as _bound
from ivslam_cli.interval.vector import point as _col
from ivslam_cli.interval.vector import sym as _sym
from ivslam_cli.logs.model import LogData
from ivslam_cli.slam import motion_kernel as K

TWIST_BOUNDS = ("odom_v", "odom_v_rel", "odom_w", "odom_w_rel", "odom_lag_xy", "odom_lag_th", "odom_lag_time")
POSE_BOUNDS = ("odom_trans_abs", "odom_trans_rel", "odom_rot_abs", "odom_rot_rel")


@dataclass(frozen=True)
class MotionBounds:
    """The odometry bounds of ``[bounds]`` (decimal values; the kernels enclose each outward)."""

    odom_v: float = 0.0
    odom_v_rel: float = 0.0
    odom_w: float = 0.0
    odom_w_rel: float = 0.0
    odom_lag_xy: float = 0.0
    odom_lag_th: float = 0.0
    odom_lag_time: float = 0.0
    odom_lag_memory: float = 2.0
    odom_trans_abs: float = 0.0
    odom_trans_rel: float = 0.0
    odom_rot_abs: float = 0.0
    odom_rot_rel: float = 0.0
    speed_max: float = 0.0
    turn_rate_max: float = 0.0
    turn_accel_max: float = 0.0
    accel_max: float = 0.0

    @classmethod
    def from_config(cls, cfg) -> MotionBounds:
        return cls(**{f.name: float(cfg["bounds." + f.name]) for f in fields(cls)})

    @property
    def twist_set(self) -> bool:
        """Some twist bound is set."""
        return any(getattr(self, k) for k in TWIST_BOUNDS)

    @property
    def pose_set(self) -> bool:
        """Some pose-increment bound is set."""
        return any(getattr(self, k) for k in POSE_BOUNDS)


@dataclass(frozen=True)
class InitialPose:
    """Where the first pose box comes from: ``pose`` ± ``margin``, else the truth at the first
    stamp (``from_truth``), else the origin (the map frame is the first pose)."""

    pose: tuple[float, float, float] | None = None
    from_truth: bool = False
    margin: tuple[float, float, float] = (0.01, 0.01, 0.01)

    @classmethod
    def from_config(cls, cfg) -> InitialPose:
        p = cfg["landmarks.initial_pose"]
        return cls(pose=None if p is None else tuple(float(v) for v in p),
                   from_truth=bool(cfg["landmarks.initial_pose_from_truth"]),
                   margin=tuple(float(v) for v in cfg["landmarks.initial_margin"]))


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


def initial_box(log: LogData, initial: InitialPose, t0: float) -> tuple[np.ndarray, str]:
    """The initial pose box (3, 2) and where it comes from."""
    margin = [_bound(m) for m in initial.margin]
    if initial.pose is not None:
        centre, source = np.array(initial.pose, float), "landmarks.initial_pose"
    elif initial.from_truth:
        centre = _interp_truth(log, t0)
        if centre is None:
            raise IvslamError(f"--initial-pose-from-truth: the log has no ground-truth pose at t={t0:.6f}",
                              log.provenance.path)
        source = "ground truth interpolated at the first odometry stamp"
    else:
        centre, source = np.zeros(3), "origin (the map frame is the first pose)"
    box = iv.add(_col(centre), _sym(np.array(margin)))
    return box, source


def cumulative_up(step: np.ndarray) -> np.ndarray:
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


def _run_times(s, b, c, n_beams, runs: int):
    """Each scan (beam ``i`` at ``s + b + i c``) cut into at most ``runs`` runs of beams as
    :func:`~ivslam_cli.slam.lidar.sweep_map.chunk_scans` cuts it: ``(scan, run, beams, first
    time, last time)`` per run (arrays)."""
    nb = np.asarray(n_beams, np.int64)
    parts = np.minimum(runs, np.maximum(nb, 1))
    k, r = np.nonzero(np.arange(runs)[None, :] < parts[:, None])
    i0 = (r * nb[k]) // parts[k]
    i1 = np.maximum(((r + 1) * nb[k]) // parts[k] - 1, i0)
    ta, tb = s[k] + b[k] + c[k] * i0, s[k] + b[k] + c[k] * i1
    return k, r, i1 - i0 + 1, np.minimum(ta, tb), np.maximum(ta, tb)


@dataclass
class MotionSteps:
    """Dead-reckoning steps between nodes, and where each event (observation, scan) sits.

    ``node_stamp`` (N,); ``kind`` (N-1,) and ``U`` (N-1, 5, 2) as ``landmarks_kernel`` reads
    them; ``step_travel`` (N-1,) upper bounds of each step's displacement and ``step_dth``
    (N-1, 2) its heading change; ``lag`` (N, 2): true pose = modelled pose ± (lag_xy, lag_th)
    at each node (twist odometry; zero for pose increments); ``node`` (M,) the node of each
    event and ``reach`` (M, 2) the (position, heading) half-widths by which that node's box is
    widened to hold the pose at the event's own stamp; ``rate`` (N-1, 2) upper bounds of
    ``|v|`` and ``|ω|`` within each step (twist), NaN for pose increments (nothing is known
    within a step but that the robot stays within its bound); ``speed_max``, ``turn_max`` the
    robot's top speed and turn rate where the bounds state them, else inf."""

    motion: str
    node_stamp: np.ndarray
    kind: np.ndarray
    U: np.ndarray
    step_travel: np.ndarray
    step_dth: np.ndarray
    lag: np.ndarray
    node: np.ndarray
    reach: np.ndarray
    rate: np.ndarray | None = None
    speed_max: float = np.inf
    turn_max: float = np.inf
    turn_rate: np.ndarray | None = None  # (N-1, 2) the true turn rate's interval per step (twist)
    turn_accel: float = np.inf  # the stated top angular acceleration (pose increments), else inf
    speed: np.ndarray | None = None  # (N-1, 2) the true speed's interval per step (twist)
    step_xy: np.ndarray | None = None  # (N-1, 3) pose increments: (Δx, Δy) in the step's first frame, ± per axis
    accel: float = np.inf  # the stated top acceleration (pose increments), else inf

    def reach_between(self, t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
        """Upper bounds ``(d, a)`` (M, 2) of how far the robot moves and turns between the times
        ``t0`` and ``t1`` (each (M,), ``t0 <= t1``): with a twist, the largest speed and turn
        rate of each step met times the time spent in it, plus the lag at both ends; with pose
        increments, the whole bound of each step met, the first one's twice (two poses within
        one step's bound of its start may be twice that apart); at most the top speed and turn
        rate times the time where the bounds state them. Clipped to the odometry's span (the
        first and last steps go on)."""
        ns = self.node_stamp
        n1 = ns.shape[0] - 1
        out = np.zeros((t0.shape[0], 2))
        if n1 < 1:
            return out
        i0 = np.clip(np.searchsorted(ns, t0, side="right") - 1, 0, n1 - 1)
        i1 = np.clip(np.searchsorted(ns, t1, side="left") - 1, 0, n1 - 1)
        travel = self.step_travel
        turn = np.maximum(np.abs(self.step_dth[:, 0]), np.abs(self.step_dth[:, 1]))
        for e in range(t0.shape[0]):
            d = a = 0.0
            for k in range(int(i0[e]), int(max(i0[e], i1[e])) + 1):
                if self.rate is not None and np.isfinite(self.rate[k, 0]):
                    lo = t0[e] if k == i0[e] else ns[k]
                    hi = t1[e] if k == i1[e] or k == n1 - 1 else ns[k + 1]
                    # + ulps: stamps near 1.7e9 s are 2.4e-7 s apart
                    tau = max(hi - lo, 0.0) * (1.0 + 1e-12) + 4.0 * np.spacing(abs(hi) + abs(lo))
                    d += self.rate[k, 0] * tau
                    a += self.rate[k, 1] * tau
                else:
                    twice = 2.0 if k == i0[e] else 1.0
                    d += twice * travel[k]
                    a += twice * turn[k]
            # the true pose is within the lag of the driven path at both ends; within step k the
            # lag is at most its end nodes' (their windows hold the commands before and in it)
            k1 = int(max(i0[e], i1[e]))
            lag = self.lag[int(i0[e])] + np.maximum(self.lag[k1], self.lag[k1 + 1])
            out[e] = d + lag[0], a + lag[1]
        return self._capped(np.nextafter(out * (1.0 + 1e-12), np.inf), t1 - t0 + 4.0 * np.spacing(np.abs(t0) + np.abs(t1)))

    def _capped(self, out: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """``out`` (M, 2) at most ``(speed_max, turn_max) × tau`` (rounded up)."""
        top = np.array([self.speed_max, self.turn_max])
        stated = np.isfinite(top)
        cap = np.nextafter(np.maximum(tau, 0.0)[:, None] * np.where(stated, top, 0.0) * (1.0 + 1e-12), np.inf)
        return np.minimum(out, np.where(stated, cap, np.inf))

    def _chain(self, s: float, lo: float, hi: float):
        """The chain of the steps' chords from ``s`` over ``[lo, hi]`` (pose increments under a
        stated top angular acceleration: :mod:`ivslam_cli.slam.chord_chain`), or ``None``."""
        from ivslam_cli.slam.chord_chain import chain

        if self.step_xy is None or not np.isfinite(self.turn_accel):
            return None
        return chain(self.node_stamp, self.U[:, 2], self.step_xy, self.turn_accel, self.accel, s, lo, hi)

    def _steps_met(self, t0: np.ndarray, t1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The first and last steps ``[t0, t1]`` meets (clipped to the odometry's), and 4 ulps of
        its stamps (near 1.7e9 s they are 2.4e-7 s apart)."""
        n1 = self.node_stamp.shape[0] - 1
        i0 = np.clip(np.searchsorted(self.node_stamp, t0, side="right") - 1, 0, n1 - 1)
        i1 = np.clip(np.searchsorted(self.node_stamp, t1, side="left") - 1, 0, n1 - 1)
        return i0, i1, 4.0 * np.spacing(np.abs(t0) + np.abs(t1))

    def turn_between(self, s: np.ndarray, t0: np.ndarray, t1: np.ndarray, n_beams: np.ndarray,
                     slack: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A nominal turn rate ``ω̂`` (M,) and bounds ``e``, ``η`` (M,): for every time ``t`` in
        ``[t0, t1]`` (which holds ``s``), ``|θ(t) − θ(s) − ω̂ (t − s)| ≤ e``, and between two
        consecutive of ``n_beams`` times evenly over ``[t0, t1]`` the turn strays from ``ω̂``
        times their interval by at most ``η``. With a twist, ``ω̂`` is the
        middle of the turn rates the steps met allow and ``e`` the rest of them times the time,
        plus the lag at both; with pose increments and a stated top angular acceleration ``α``,
        within one step ``[t_k, t_k + h]`` of increment ``Δθ ± ε``: ``ω̂ = Δθ / h``, ``e = |t −
        s| ε / h + α h² / 8 + α (s − t_k)(t_k + h − s) / 2`` (a turn with ``|θ''| ≤ α`` strays
        from the chord of its step by at most ``α (t − t_k)(t_k + h − t) / 2``). Otherwise ``ω̂ =
        0``, ``e`` the reach (:meth:`reach_between`) and ``η`` the drift (:meth:`drift_between`).
        A rate straying at most ``ρ`` from ``ω̂`` (twist: the rest of the steps' rates; pose
        increments: ``ε / h + α h``) gives ``η = ρ × the interval`` (+ twice the lag).

        ``slack`` (M,): each of those times may be off by up to this (a scan taken up to
        ``slack`` from its nominal time, :mod:`~ivslam_cli.slam.lidar.scan_clock`): ``e`` then
        holds ``θ(t + δ) − θ(s) − ω̂ (t − s)`` for ``|δ| ≤ slack`` (the bound over the widened
        window plus ``|ω̂| slack``). Then, and whenever ``[t0, t1]`` leaves ``s`` or its step, with
        pose increments under ``α`` the heading is the chain of the steps' chords from ``s``
        (:meth:`_chain`): increments ``Δ_j ± ε_j`` weighted by the share ``λ_j`` of each step
        between ``s`` and ``t``, plus the chord error where the window is in each step and at
        ``s``; ``ω̂`` the rate
        (a step's, or the window's chord) that gives the least ``e``."""
        w = np.zeros(t0.shape[0])
        sl = np.zeros(t0.shape[0]) if slack is None else np.asarray(slack, float)
        lo_w, hi_w = np.minimum(t0 - sl, s), np.maximum(t1 + sl, s)
        e = self.reach_between(lo_w, hi_w)[:, 1]
        eta = self.drift_between(t0, t1, n_beams, sl)[:, 1]
        ns = self.node_stamp
        n1 = ns.shape[0] - 1
        if n1 < 1:
            return w, e, eta
        i0, i1, ulp = self._steps_met(lo_w, hi_w)
        dt = (t1 - t0 + ulp) / np.maximum(np.asarray(n_beams, float) - 1.0, 1.0)
        for k in range(t0.shape[0]):
            k0, k1 = int(i0[k]), int(max(i0[k], i1[k]))
            tau = max(t1[k] + sl[k] - s[k], s[k] - t0[k] + sl[k], 0.0) + ulp[k]
            if self.turn_rate is not None:
                W = self.turn_rate[k0:k1 + 1]
                lo, hi = float(W[:, 0].min()), float(W[:, 1].max())
                wc = 0.5 * (lo + hi)
                r = max(hi - wc, wc - lo)
                lag = 2.0 * float(np.max(self.lag[k0:k1 + 2, 1]))
                ek = np.nextafter((r * tau + lag) * (1.0 + 1e-12) + 1e-12, np.inf)
                rho, lag_eta = r, lag
            elif (np.isfinite(self.turn_accel) and sl[k] == 0.0 and k0 == k1 and ns[k0] <= t0[k] <= s[k] <= t1[k]
                  and t1[k] <= ns[k0 + 1]):
                h = float(ns[k0 + 1] - ns[k0])
                if not h > 0.0:
                    continue
                d = self.U[k0, 2]
                wc = 0.5 * (d[0] + d[1]) / h
                eps = 0.5 * (d[1] - d[0])
                a = self.turn_accel
                ek = np.nextafter((tau * eps / h + a * h * h / 8.0 + a * (s[k] - ns[k0]) * (ns[k0 + 1] - s[k]) / 2.0
                                   + 2.0 * abs(wc) * ulp[k]) * (1.0 + 1e-12) + 1e-12, np.inf)
                rho, lag_eta = eps / h + a * h, 0.0
            elif np.isfinite(self.turn_accel):
                ch = self._chain(float(s[k]), float(t0[k] - sl[k]), float(t1[k] + sl[k]))
                if ch is None:
                    continue
                wc, ek, rho = ch.turn(float(sl[k]), float(ulp[k]))
                lag_eta = 0.0
            else:
                continue
            if sl[k] > 0.0 and self.turn_rate is not None:
                ek = np.nextafter((ek + abs(wc) * sl[k]) * (1.0 + 1e-12) + 1e-12, np.inf)
            if ek < e[k]:
                w[k], e[k] = wc, ek
                eta[k] = np.nextafter((rho * dt[k] + lag_eta) * (1.0 + 1e-12) + 1e-15, np.inf)
        return w, e, eta

    def sweep_runs(self, s: np.ndarray, b: np.ndarray, c: np.ndarray, n_beams: np.ndarray, w: np.ndarray,
                   e: np.ndarray, V: np.ndarray, E: np.ndarray, slack: np.ndarray,
                   runs: int) -> tuple[np.ndarray, np.ndarray]:
        """``(turn, move)`` (M, runs) each: for each scan (beam ``i`` at ``s + b + i c``, within
        ``slack``) cut into ``runs`` runs of beams as
        :func:`~ivslam_cli.slam.lidar.sweep_map.chunk_scans` cuts it, bounds of ``|θ(t) − θ(s)
        − w (t − s)|`` and of ``|p(t) − p(s) − R(θ(s)) V (t − s)|`` over each run's times: with
        pose increments under a stated top angular acceleration the chain of chords over the run
        alone (its chord term where the run is in each step; the move under a stated top
        acceleration), with a twist each run's own bounds about ``w`` and ``V``
        (:meth:`_twist_runs`), at most ``e`` and ``E``; else ``e`` and ``E``."""
        out = np.repeat(np.asarray(e, float)[:, None], runs, axis=1)
        mv = np.repeat(np.asarray(E, float)[:, None], runs, axis=1)
        if self.turn_rate is not None and self.node_stamp.shape[0] >= 2:
            return self._twist_runs(s, b, c, n_beams, w, V, slack, runs, out, mv)
        if self.step_xy is None or not np.isfinite(self.turn_accel) or self.node_stamp.shape[0] < 2:
            return out, mv
        moves = np.isfinite(self.accel)
        K, R, _, lo, hi = _run_times(s, b, c, n_beams, runs)
        for k, r, lo_r, hi_r in zip(K.tolist(), R.tolist(), (lo - slack[K]).tolist(), (hi + slack[K]).tolist()):
            ch = self._chain(float(s[k]), lo_r, hi_r)
            if ch is not None:
                ulp = 4.0 * float(np.spacing(abs(lo_r) + abs(hi_r)))
                out[k, r] = min(out[k, r], ch.turn_at(float(w[k]), float(slack[k]), ulp))
                if moves:
                    mv[k, r] = min(mv[k, r], ch.move_at(V[k], float(slack[k]), ulp))
        return out, mv

    def _twist_runs(self, s, b, c, n_beams, w, V, slack, runs, out, mv):
        """:meth:`sweep_runs` with a twist: each run's own :meth:`turn_between` and
        :meth:`move_between` (rate ``ω̂_r``, velocity ``V_r``, bounds ``e_r``, ``E_r``) taken about
        the scan's ``ω̂`` and ``V``: ``e_r + |ω̂_r − ω̂| τ_r`` and ``E_r + |V_r − V| τ_r``, ``τ_r``
        the run's farthest time from ``s`` (plus the slack)."""
        k, r, n, lo, hi = _run_times(s, b, c, n_beams, runs)
        sl = np.asarray(slack, float)[k]
        wr, er, _ = self.turn_between(s[k], lo, hi, n, sl)
        Vr, Er = self.move_between(s[k], lo, hi, sl)
        tau = np.maximum(np.maximum(hi + sl - s[k], s[k] - lo + sl), 0.0) + 4.0 * np.spacing(np.abs(lo) + np.abs(hi))
        up = 1.0 + 1e-12
        turn = np.nextafter((er + np.abs(wr - np.asarray(w, float)[k]) * tau) * up + 1e-15, np.inf)
        dV = np.hypot(Vr[:, 0] - V[k, 0], Vr[:, 1] - V[k, 1])
        move = np.nextafter((Er + dV * up * tau) * up + 1e-15, np.inf)
        out[k, r] = np.minimum(out[k, r], turn)
        mv[k, r] = np.minimum(mv[k, r], move)
        return out, mv

    def move_between(self, s: np.ndarray, t0: np.ndarray, t1: np.ndarray,
                     slack: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """A nominal velocity ``V`` (M, 2) in the robot frame at ``s`` and a bound ``E`` (M,): for
        every ``t`` in ``[t0, t1]`` (which holds ``s``), ``|p(t) − p(s) − R(θ(s)) V (t − s)| ≤ E``.
        With a twist, ``V = (v̂, 0)``, ``v̂`` the middle of the speeds the steps met allow: ``E =
        Δv τ + |v̂| ω τ² / 2`` (the rest of the speeds, and the turn ``|φ| ≤ ω t`` of the
        direction, ``ω`` the largest turn rate) ``+ 2 lag_xy + 2 |v̂| τ lag_th``; with pose
        increments only under a stated top acceleration ``A``, for a scan stamped at an odometry
        stamp and swept within that step (``h``, increment ``Δp ± ε`` per axis): ``V = Δp / h``,
        ``E = τ √2 ε / h + A h² / 8`` (a path with ``|p''| ≤ A`` strays from its step's chord by
        at most ``A (t − t_k)(t_k + h − t) / 2``); with ``slack`` (as :meth:`turn_between`), or a
        window leaving ``s`` or its step, the chain of the steps' chords from ``s``
        (:meth:`_chain`). Otherwise ``V = 0`` and ``E`` the reach (:meth:`reach_between`)."""
        V = np.zeros((t0.shape[0], 2))
        sl = np.zeros(t0.shape[0]) if slack is None else np.asarray(slack, float)
        lo_w, hi_w = np.minimum(t0 - sl, s), np.maximum(t1 + sl, s)
        E = self.reach_between(lo_w, hi_w)[:, 0].copy()
        ns = self.node_stamp
        n1 = ns.shape[0] - 1
        if n1 < 1:
            return V, E
        i0, i1, ulp = self._steps_met(lo_w, hi_w)
        for k in range(t0.shape[0]):
            k0, k1 = int(i0[k]), int(max(i0[k], i1[k]))
            tau = max(t1[k] + sl[k] - s[k], s[k] - t0[k] + sl[k], 0.0) + ulp[k]
            if self.speed is not None:
                sp = self.speed[k0:k1 + 1]
                lo, hi = float(sp[:, 0].min()), float(sp[:, 1].max())
                vc = 0.5 * (lo + hi)
                dv = max(hi - vc, vc - lo)
                om = float(np.max(np.abs(self.turn_rate[k0:k1 + 1])))
                lag = self.lag[k0:k1 + 2]
                ek = (dv * tau + abs(vc) * om * tau * tau / 2.0 + 2.0 * float(np.max(lag[:, 0]))
                      + 2.0 * abs(vc) * tau * float(np.max(lag[:, 1])))
                v = (vc, 0.0)
                if sl[k] > 0.0:
                    ek += abs(vc) * sl[k]
            elif (np.isfinite(self.accel) and self.step_xy is not None and sl[k] == 0.0 and k0 == k1
                  and s[k] == ns[k0] and t1[k] <= ns[k0 + 1] and t0[k] >= ns[k0]):
                h = float(ns[k0 + 1] - ns[k0])
                if not h > 0.0:
                    continue
                dx, dy, eps = self.step_xy[k0]
                v = (dx / h, dy / h)
                ek = tau * math.sqrt(2.0) * eps / h + self.accel * h * h / 8.0 + math.hypot(*v) * ulp[k]
            elif np.isfinite(self.accel) and self.step_xy is not None and np.isfinite(self.turn_accel):
                ch = self._chain(float(s[k]), float(t0[k] - sl[k]), float(t1[k] + sl[k]))
                if ch is None:
                    continue
                v, ek = ch.move(float(sl[k]), float(ulp[k]))
            else:
                continue
            ek = float(np.nextafter(ek * (1.0 + 1e-12) + 1e-12, np.inf))
            if ek < E[k]:
                V[k], E[k] = v, ek
        return V, E

    def drift_between(self, t0: np.ndarray, t1: np.ndarray, n_beams: np.ndarray,
                      slack: np.ndarray | None = None) -> np.ndarray:
        """Upper bounds ``(δ, η)`` (M, 2) of how far the robot moves and turns between two
        consecutive beams of a scan taking its ``n_beams`` beams evenly over ``[t0, t1]``: with a
        twist, the largest speed and turn rate of the steps met times the time between two
        beams, plus the lag at both (the true pose is known only within the lag of the driven
        path); with pose increments, the whole motion over ``[t0, t1]`` (:meth:`reach_between`:
        nothing is known within a step). At most the top speed and turn rate times that time
        where the bounds state them. ``slack``: the beams may all be taken up to this later or
        earlier (the bound then holds over ``[t0 − slack, t1 + slack]``)."""
        # + ulps: ``t1`` is a stamp plus the sweep, rounded (2.4e-7 s near 1.7e9 s)
        tau = (t1 - t0 + 4.0 * np.spacing(np.abs(t0) + np.abs(t1))) / np.maximum(np.asarray(n_beams, float) - 1.0, 1.0)
        if slack is not None:
            t0, t1 = t0 - slack, t1 + slack
        out = self.reach_between(t0, t1)
        if self.rate is not None and self.node_stamp.shape[0] > 1:
            i0, i1, _ = self._steps_met(t0, t1)
            for e in range(t0.shape[0]):
                k0, k1 = int(i0[e]), int(max(i0[e], i1[e]))
                rate = self.rate[k0:k1 + 1]
                if np.all(np.isfinite(rate)):
                    lag = 2.0 * np.max(self.lag[k0:k1 + 2], axis=0)
                    out[e] = np.nextafter((np.max(rate, axis=0) * tau[e] + lag) * (1.0 + 1e-12), np.inf)
        return self._capped(out, tau)


def motion_steps(odo, bounds: MotionBounds, s: np.ndarray, prefer: str = "twist", max_step: float = 0.0,
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
        a_v, r_v = _bound(bounds.odom_v), _bound(bounds.odom_v_rel)
        V = np.column_stack([speed_interval(zlo[:, 0], a_v, r_v)[:, 0], speed_interval(zhi[:, 0], a_v, r_v)[:, 1]])
        vmax = np.maximum(np.abs(V[:, 0]), np.abs(V[:, 1]))
        w_half = iv.add(_col(np.full(n - 1, _bound(bounds.odom_w))),
                        iv.mul(_col(np.full(n - 1, _bound(bounds.odom_w_rel))), _col(vmax)))[:, 1]
        W = np.column_stack([iv.sub(_col(zlo[:, 1]), _sym(w_half))[:, 0], iv.add(_col(zhi[:, 1]), _sym(w_half))[:, 1]])
        dt = iv.sub(_col(node_stamp[1:]), _col(node_stamp[:-1]))
        dt[:, 0] = np.maximum(dt[:, 0], 0.0)
        lag = node_lags(t, tw_all, node_stamp, _bound(bounds.odom_lag_xy), _bound(bounds.odom_lag_th),
                        _bound(bounds.odom_lag_time), float(bounds.odom_lag_memory))
        U = np.zeros((n - 1, 5, 2))
        U[:, 0], U[:, 1], U[:, 2] = chord_steps(V, W, dt)
        kind = np.full(n - 1, K.INCREMENT, np.int8)
        step_travel = U[:, 0, 1].copy()
        step_dth = iv.mul(W, dt)
        rate = np.column_stack([vmax, np.maximum(np.abs(W[:, 0]), np.abs(W[:, 1]))])
        turn_rate = W
        speed = V
        step_xy = None
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
        half_t = _bound(bounds.odom_trans_abs) + _bound(bounds.odom_trans_rel) * norm * (1 + 1e-15)
        half_t = np.nextafter(half_t + eps_xy, np.inf)
        half_r = _bound(bounds.odom_rot_abs) + _bound(bounds.odom_rot_rel) * np.abs(dth) * (1 + 1e-15)
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
        rate = np.full((n - 1, 2), np.nan)
        turn_rate = None
        speed = None
        step_xy = np.column_stack([bx, by, half_t])
    else:
        raise IvslamError("the odometry has neither twist nor poses", path)

    return MotionSteps(motion=motion, node_stamp=node_stamp, kind=kind, U=np.ascontiguousarray(U),
                       step_travel=step_travel, step_dth=step_dth, lag=lag, node=node.astype(np.int64),
                       reach=np.ascontiguousarray(reach, dtype=np.float64), rate=rate,
                       speed_max=_top(bounds.speed_max), turn_max=_top(bounds.turn_rate_max),
                       turn_rate=turn_rate, turn_accel=_top(bounds.turn_accel_max), speed=speed, step_xy=step_xy,
                       accel=_top(bounds.accel_max))


def _top(v: float) -> float:
    """A stated top speed or turn rate (its decimal enclosed upward); 0: none stated (inf)."""
    return _bound(v) if v > 0.0 else np.inf


def choose_motion(log: LogData, want: str, bounds: MotionBounds) -> str:
    """``"twist"`` or ``"pose"``: the odometry stream to dead-reckon with. ``want`` is ``auto``
    (the stream whose bounds are set; twist if both or neither are), ``twist`` or ``pose``."""
    odo = log.odometry
    has_t, has_p = odo.twist is not None, odo.pose is not None
    if want == "twist" and not has_t:
        raise IvslamError("lidar.motion = twist, but the odometry has no twist", log.provenance.path)
    if want == "pose" and not has_p:
        raise IvslamError("lidar.motion = pose, but the odometry has no poses", log.provenance.path)
    if want != "auto":
        return want
    if has_t and has_p:
        return "pose" if bounds.pose_set and not bounds.twist_set else "twist"
    return "twist" if has_t else "pose"
