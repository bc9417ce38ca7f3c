"""A GTSAM factor-graph baseline on a landmark log: time, error and 3σ containment of the truth.

The standard GTSAM recipe, on the same data and the same noise bounds as our pipeline, so
``make bench`` can put the two side by side (issue #6):

- **Variables.** A ``Pose2`` at ``t0`` (the first odometry stamp with truth), at every distinct
  observation stamp up to the last observation (``span="odometry"``: on to the last odometry
  stamp), and keyframes so that no two consecutive poses are more than ``pose_every`` seconds
  apart. A ``Point2`` per observed landmark.
- **Anchor.** A tight prior (``prior_sigma``) on the pose at ``t0``, at the truth interpolated
  there: the same anchor as our ``--initial-pose-from-truth``.
- **Odometry.** ``BetweenFactorPose2`` from integrating the commanded twist between
  consecutive pose stamps (zero-order hold: the twist at ``t_k`` holds over ``[t_k, t_{k+1})``,
  exact arcs). Noise from the bounds, ``σ = bound / 3`` per unit time, scaled with ``dt`` and
  summed over the hold segments (an error in ``v`` or ``ω`` held over the interval):
  along-track and lateral ``σ_t = Σ σ_v dt``, heading ``σ_θ = Σ σ_ω dt``, plus the first-order
  lateral drift of a heading error ``d σ_θ / 2`` (``d`` = distance), correlated with heading.
  ``σ_v = (odom_v + odom_v_rel |v|) / 3``, ``σ_ω = (odom_w + odom_w_rel |v|) / 3``.
- **Observations.** ``BearingRangeFactor2D`` with ``σ_β = bearing / 3`` and
  ``σ_ρ = (range_abs + range_rel z_ρ) / 3``; with ``robust`` a Huber kernel (``huber_k`` in
  whitened units, 1.345 = the usual 95 %-efficiency choice) on these factors.
- **Initial values.** Poses by dead reckoning from the anchor; each landmark from its first
  observation.
- **Solver.** Batch Levenberg–Marquardt (the GTSAM default for an offline problem), then
  ``Marginals`` (the Gaussian approximation at the optimum).

Evaluation against the truth interpolated at the pose stamps (headings unwrapped; stamps
outside the truth span, or in a truth gap longer than ``max_truth_gap``, are not scored):
position error (median, 95th percentile, RMSE, max), heading error, landmark position
error (also ``lm_err_aligned_rmse``: after the best rigid motion of the estimated map onto the
true one, i.e. the map's shape without the placement that only the anchor fixes), and the
fraction of poses/landmarks whose truth lies in the 3σ region of the marginal:

- ``*_xy_in_3sigma``: Mahalanobis d² of the x-y error ≤ 9 (the 2D "3σ ellipse"; a Gaussian
  puts 98.89 % inside it);
- ``pose_se2_in_3sigma``: d² of the full ``Logmap(est⁻¹ truth)`` ≤ 14.16 (χ²₃ at 99.73 %, the
  3-dof equivalent of 3σ).

GTSAM's ``Pose2`` covariance is in the pose's own frame (``retract = pose ∘ Exp(ξ)``); the x-y
error is rotated into that frame before the Mahalanobis distance.

Importing gtsam 4.3 leaves the FPU in round-to-nearest and does not disturb h5py or numba
(checked by ``tests/bench/test_gtsam_baseline.py``), so this runs in-process.

    python -m bench.gtsam_baseline --robot 1          # MRCLAM Dataset 6, robot 1
    python -m bench.gtsam_baseline --robot 1 --plain  # without the Huber kernel
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from ivslam_cli.logs.model import LogData

#: Thresholds of the "3σ" regions (see the module docstring).
D2_XY = 9.0
D2_SE2 = 14.16

#: Bounds used for MRCLAM by ``__main__`` when none are given (σ = bound / 3; pass the
#: pipeline's own with ``--bound KEY=VALUE``). From the residual statistics of
#: ``../shared/datasets/README.md`` §1 (range 1st/99th pct −0.6/+0.3 m, bearing within ±2–4°)
#: and of the commanded twist against the Vicon velocity over 0.5 s windows (all 5 robots:
#: v error 1st/99.9th pct −0.044/+0.042 m/s, ω error 99th pct ±0.17–0.26 rad/s).
MRCLAM_BOUNDS: dict[str, float] = {
    "range_abs": 0.6, "range_rel": 0.0, "bearing": 0.07,
    "odom_v": 0.05, "odom_v_rel": 0.0, "odom_w": 0.3, "odom_w_rel": 0.0,
}

MRCLAM_PATH = Path(__file__).resolve().parent.parent.parent / "shared" / "datasets" / "mrclam" / "MRCLAM_Dataset6"


# --- pure array helpers -------------------------------------------------------------------

def wrap(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-π, π)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def truth_at(pose_stamp: np.ndarray, pose: np.ndarray, t: np.ndarray,
             max_gap: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Truth poses linearly interpolated at ``t`` (heading unwrapped first) and a mask of the
    stamps that can be scored: inside the truth span and not inside a gap > ``max_gap`` s."""
    t = np.asarray(t, dtype=float)
    theta = np.unwrap(pose[:, 2])
    out = np.column_stack([np.interp(t, pose_stamp, pose[:, 0]), np.interp(t, pose_stamp, pose[:, 1]),
                           wrap(np.interp(t, pose_stamp, theta))])
    i = np.clip(np.searchsorted(pose_stamp, t, side="right"), 1, len(pose_stamp) - 1)
    ok = (t >= pose_stamp[0]) & (t <= pose_stamp[-1]) & (pose_stamp[i] - pose_stamp[i - 1] <= max_gap)
    return out, ok


def dead_reckon(odo_stamp: np.ndarray, twist: np.ndarray, t: np.ndarray, start: np.ndarray,
                sigma_v: tuple[float, float], sigma_w: tuple[float, float]
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Integrate the twist (zero-order hold, exact arcs) from ``start`` at ``t[0]`` to the sorted
    stamps ``t``. Returns the poses ``(n, 3)`` at ``t`` and, per interval ``[t_j, t_{j+1}]``,
    ``Σ σ_v dt``, ``Σ σ_ω dt`` and the distance travelled (each ``(n-1,)``).

    ``sigma_v = (abs, rel)``: ``σ_v = abs + rel |v|``; ``sigma_w`` likewise (rel per m/s).
    The twist before ``odo_stamp[0]`` is taken as the first one.
    """
    lo, hi = t[0], t[-1]
    inner = odo_stamp[(odo_stamp > lo) & (odo_stamp < hi)]
    T = np.union1d(inner, t)  # segment breakpoints, sorted and unique
    k = np.clip(np.searchsorted(odo_stamp, T[:-1], side="right") - 1, 0, len(odo_stamp) - 1)
    v, w = twist[k, 0], twist[k, 1]
    dt = np.diff(T)
    dth = w * dt
    th0 = start[2] + np.concatenate([[0.0], np.cumsum(dth)])
    chord = v * dt * np.sinc(dth / (2.0 * np.pi))  # np.sinc(x) = sin(πx)/(πx)
    mid = th0[:-1] + 0.5 * dth
    x = start[0] + np.concatenate([[0.0], np.cumsum(chord * np.cos(mid))])
    y = start[1] + np.concatenate([[0.0], np.cumsum(chord * np.sin(mid))])
    j = np.searchsorted(T, t)  # t is a subset of T
    poses = np.column_stack([x[j], y[j], wrap(th0[j])])
    speed = np.abs(v)

    def per_interval(q: np.ndarray) -> np.ndarray:
        c = np.concatenate([[0.0], np.cumsum(q)])
        return np.diff(c[j])

    sv = per_interval((sigma_v[0] + sigma_v[1] * speed) * dt)
    sw = per_interval((sigma_w[0] + sigma_w[1] * speed) * dt)
    dist = per_interval(speed * dt)
    return poses, sv, sw, dist


def relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a⁻¹ b`` for rows of Pose2 ``(x, y, θ)``."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, wrap(b[:, 2] - a[:, 2])])


def pose_stamps(obs_stamp: np.ndarray, t0: float, pose_every: float, t_end: float | None = None) -> np.ndarray:
    """``t0``, the distinct observation stamps in ``[t0, t_end]`` (``t_end`` default: the last
    observation; never before ``t0``), ``t_end`` itself, and keyframes so that consecutive stamps
    are at most ``pose_every`` apart."""
    if t_end is None:
        t_end = float(obs_stamp.max()) if len(obs_stamp) else t0
    t_end = max(t_end, t0)
    obs = np.unique(obs_stamp[(obs_stamp >= t0) & (obs_stamp <= t_end)])
    t = np.union1d([t0, t_end], obs)
    if math.isfinite(pose_every) and len(t) > 1:
        gaps = np.diff(t)
        n_extra = np.ceil(gaps / pose_every).astype(np.int64) - 1
        extra = [t[i] + gaps[i] * np.arange(1, n + 1) / (n + 1) for i, n in enumerate(n_extra) if n > 0]
        if extra:
            t = np.union1d(t, np.concatenate(extra))
    return t


def _stats(prefix: str, e: np.ndarray) -> dict[str, float]:
    if len(e) == 0:
        return {f"{prefix}_median": math.nan, f"{prefix}_p95": math.nan, f"{prefix}_rmse": math.nan,
                f"{prefix}_max": math.nan}
    return {f"{prefix}_median": float(np.median(e)), f"{prefix}_p95": float(np.percentile(e, 95)),
            f"{prefix}_rmse": float(np.sqrt(np.mean(e**2))), f"{prefix}_max": float(np.max(e))}


def mahalanobis2(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """``eᵀ Σ⁻¹ e`` per row (``err (n, k)``, ``cov (n, k, k)``)."""
    return np.einsum("ni,ni->n", err, np.linalg.solve(cov, err[..., None])[..., 0])


# --- the baseline -------------------------------------------------------------------------

def run_gtsam(log: LogData, *, bounds: dict[str, float], robust: bool = True, huber_k: float = 1.345,
              robust_odometry: bool = False, pose_every: float = 1.0, span: str = "observations",
              prior_sigma: tuple[float, float, float] = (1e-4, 1e-4, 1e-4),
              max_iterations: int = 100, max_truth_gap: float = 0.5,
              return_estimate: bool = False) -> dict:
    """Build, optimise and score the GTSAM landmark-SLAM baseline (see the module docstring).

    ``bounds`` needs ``range_abs, range_rel, bearing, odom_v, odom_v_rel, odom_w, odom_w_rel``
    (half-widths, σ = bound / 3). ``span``: poses up to the last observation (default) or up to
    the last odometry stamp (dead reckoning past the last observation, like a pipeline whose
    poses are at every odometry stamp). The log needs twist odometry, landmark observations and
    truth (poses, and landmark positions for the landmark figures). Returns a flat dict of figures
    (times in s, errors in m and rad); with ``return_estimate`` also the arrays
    ``est_stamp, est_pose, est_pose_cov, est_landmark_id, est_landmark_xy, est_landmark_cov``.
    """
    try:
        import gtsam
        from gtsam.symbol_shorthand import L, X
    except ImportError as exc:  # an optional (dev extra) dependency
        raise ImportError("the GTSAM baseline needs gtsam (pip install 'ivslam[dev]' or pip install gtsam)") from exc

    odo, obs, truth = log.odometry, log.observations, log.truth
    if odo is None or odo.twist is None or obs is None or truth is None or truth.pose is None:
        raise ValueError("the GTSAM baseline needs twist odometry, observations and truth poses")
    b = {k: float(bounds[k]) for k in ("range_abs", "range_rel", "bearing", "odom_v", "odom_v_rel",
                                        "odom_w", "odom_w_rel")}
    t_start = time.perf_counter()

    # --- stamps, anchor, dead reckoning
    t0 = max(float(odo.stamp[0]), float(truth.pose_stamp[0]))
    if span not in ("observations", "odometry"):
        raise ValueError(f"span must be 'observations' or 'odometry', not {span!r}")
    stamps = pose_stamps(obs.stamp, t0, pose_every, float(odo.stamp[-1]) if span == "odometry" else None)
    in_obs = np.isin(stamps, obs.stamp)
    anchor, _ = truth_at(truth.pose_stamp, truth.pose, np.array([t0]), max_truth_gap)
    init, sv, sw, dist = dead_reckon(odo.stamp, odo.twist, stamps, anchor[0],
                                     (b["odom_v"] / 3, b["odom_v_rel"] / 3), (b["odom_w"] / 3, b["odom_w_rel"] / 3))
    rel = relative(init[:-1], init[1:])

    keep = (obs.stamp >= t0) & (obs.stamp <= stamps[-1])
    o_t, o_id, o_r, o_b = obs.stamp[keep], obs.landmark_id[keep], obs.range[keep], obs.bearing[keep]
    o_pose = np.searchsorted(stamps, o_t)

    # --- graph
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    graph.add(gtsam.PriorFactorPose2(X(0), gtsam.Pose2(*anchor[0]),
                                     gtsam.noiseModel.Diagonal.Sigmas(np.asarray(prior_sigma, float))))
    for i, p in enumerate(init):
        values.insert(X(i), gtsam.Pose2(*p))
    lateral = 0.5 * dist * sw  # first-order lateral drift of a heading error
    cov = np.zeros((len(rel), 3, 3))
    cov[:, 0, 0] = sv**2
    cov[:, 1, 1] = sv**2 + lateral**2
    cov[:, 2, 2] = sw**2
    cov[:, 1, 2] = cov[:, 2, 1] = lateral * sw
    cov += np.eye(3) * 1e-12  # a zero-length interval still gets a (tiny) positive definite model
    huber = gtsam.noiseModel.mEstimator.Huber.Create(huber_k) if robust else None
    for i in range(len(rel)):
        nm = gtsam.noiseModel.Gaussian.Covariance(cov[i])
        if huber is not None and robust_odometry:
            nm = gtsam.noiseModel.Robust.Create(huber, nm)
        graph.add(gtsam.BetweenFactorPose2(X(i), X(i + 1), gtsam.Pose2(*rel[i]), nm))
    s_r = (b["range_abs"] + b["range_rel"] * o_r) / 3.0
    s_b = b["bearing"] / 3.0
    for j in range(len(o_t)):
        nm = gtsam.noiseModel.Diagonal.Sigmas(np.array([s_b, s_r[j]]))
        if huber is not None:
            nm = gtsam.noiseModel.Robust.Create(huber, nm)
        graph.add(gtsam.BearingRangeFactor2D(X(int(o_pose[j])), L(int(o_id[j])), gtsam.Rot2(float(o_b[j])),
                                             float(o_r[j]), nm))
    lm_ids, first = np.unique(o_id, return_index=True)
    p0 = init[o_pose[first]]
    ang = p0[:, 2] + o_b[first]
    lm0 = p0[:, :2] + o_r[first, None] * np.column_stack([np.cos(ang), np.sin(ang)])
    for lid, xy in zip(lm_ids, lm0):
        values.insert(L(int(lid)), gtsam.Point2(*xy))
    t_build = time.perf_counter() - t_start

    # --- optimise
    t1 = time.perf_counter()
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    opt = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
    result = opt.optimize()
    t_opt = time.perf_counter() - t1
    err0, err1 = graph.error(values), graph.error(result)

    # --- marginals
    t2 = time.perf_counter()
    marg = gtsam.Marginals(graph, result)
    n = len(stamps)
    pose_cov = np.array([marg.marginalCovariance(X(i)) for i in range(n)])
    lm_cov = np.array([marg.marginalCovariance(L(int(lid))) for lid in lm_ids]).reshape(-1, 2, 2)
    t_marg = time.perf_counter() - t2

    est = np.array([[p.x(), p.y(), p.theta()] for p in (result.atPose2(X(i)) for i in range(n))])
    lm_est = np.array([result.atPoint2(L(int(lid))) for lid in lm_ids]).reshape(-1, 2)

    out: dict = {
        "robust": bool(robust), "robust_odometry": bool(robust and robust_odometry),
        "huber_k": float(huber_k) if robust else math.nan,
        "pose_every": float(pose_every), "span": span, "t0": t0, "t_end": float(stamps[-1]),
        "n_poses": int(n), "n_observation_poses": int(in_obs.sum()), "n_keyframes": int(n - in_obs.sum()),
        "n_observations": int(len(o_t)), "n_observations_dropped": int((~keep).sum()),
        "n_landmarks": int(len(lm_ids)), "n_factors": int(graph.size()),
        "t_build_s": t_build, "t_optimize_s": t_opt, "t_marginals_s": t_marg,
        "t_total_s": t_build + t_opt + t_marg, "iterations": int(opt.iterations()),
        "error_initial": float(err0), "error_final": float(err1),
    }
    out.update(_score_poses(stamps, est, pose_cov, truth, max_truth_gap))
    out.update(_score_landmarks(lm_ids, lm_est, lm_cov, truth))
    dr_true, dr_ok = truth_at(truth.pose_stamp, truth.pose, stamps, max_truth_gap)
    out.update(_stats("dead_reckoning_pos_err", np.hypot(*(init[dr_ok, :2] - dr_true[dr_ok, :2]).T)))
    if return_estimate:
        out.update(est_stamp=stamps, est_pose=est, est_pose_cov=pose_cov, est_landmark_id=lm_ids,
                   est_landmark_xy=lm_est, est_landmark_cov=lm_cov)
    return out


def _score_poses(stamps: np.ndarray, est: np.ndarray, cov: np.ndarray, truth, max_gap: float) -> dict:
    """Errors and 3σ containment of the poses against the interpolated truth."""
    true, ok = truth_at(truth.pose_stamp, truth.pose, stamps, max_gap)
    est, true, cov = est[ok], true[ok], cov[ok]
    e_xy = true[:, :2] - est[:, :2]
    c, s = np.cos(est[:, 2]), np.sin(est[:, 2])
    e_body = np.column_stack([c * e_xy[:, 0] + s * e_xy[:, 1], -s * e_xy[:, 0] + c * e_xy[:, 1]])
    e_th = wrap(true[:, 2] - est[:, 2])
    d2_xy = mahalanobis2(e_body, cov[:, :2, :2])
    d2_se2 = mahalanobis2(_logmap(relative(est, true)), cov)
    major = 3.0 * np.sqrt(np.linalg.eigvalsh(cov[:, :2, :2])[:, -1])
    out = {"n_scored_poses": int(ok.sum())}
    out.update(_stats("pos_err", np.hypot(e_xy[:, 0], e_xy[:, 1])))
    out.update(_stats("heading_err", np.abs(e_th)))
    out["pose_xy_in_3sigma"] = float(np.mean(d2_xy <= D2_XY)) if len(d2_xy) else math.nan
    out["pose_se2_in_3sigma"] = float(np.mean(d2_se2 <= D2_SE2)) if len(d2_se2) else math.nan
    out["heading_in_3sigma"] = float(np.mean(np.abs(e_th) <= 3.0 * np.sqrt(cov[:, 2, 2]))) if len(e_th) else math.nan
    out["pose_3sigma_major_median"] = float(np.median(major)) if len(major) else math.nan
    return out


def _score_landmarks(ids: np.ndarray, est: np.ndarray, cov: np.ndarray, truth) -> dict:
    """Errors and 3σ containment of the landmarks the log has a true position for."""
    if truth.landmark_id is None or truth.landmark_xy is None:
        return {"n_scored_landmarks": 0}
    known = np.isin(ids, truth.landmark_id)
    idx = np.searchsorted(truth.landmark_id, ids[known]) if np.all(np.diff(truth.landmark_id) > 0) else \
        np.array([int(np.flatnonzero(truth.landmark_id == i)[0]) for i in ids[known]], dtype=np.int64)
    e = truth.landmark_xy[idx] - est[known]
    d2 = mahalanobis2(e, cov[known])
    major = 3.0 * np.sqrt(np.linalg.eigvalsh(cov[known])[:, -1])
    out = {"n_scored_landmarks": int(known.sum())}
    out.update(_stats("lm_err", np.hypot(e[:, 0], e[:, 1])))
    out["lm_err_aligned_rmse"] = aligned_rmse(est[known], truth.landmark_xy[idx])
    out["lm_xy_in_3sigma"] = float(np.mean(d2 <= D2_XY)) if len(d2) else math.nan
    out["lm_3sigma_major_median"] = float(np.median(major)) if len(major) else math.nan
    return out


def aligned_rmse(a: np.ndarray, b: np.ndarray) -> float:
    """RMS distance between points ``a`` and ``b`` after the best rigid motion of ``a`` onto ``b``
    (Kabsch/Umeyama, no scale): the map's shape error without its placement (gauge) error."""
    if len(a) < 2:
        return math.nan
    ca, cb = a.mean(0), b.mean(0)
    u, _, vt = np.linalg.svd((a - ca).T @ (b - cb))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, d]) @ u.T
    return float(np.sqrt(np.mean(np.sum(((a - ca) @ r.T + cb - b) ** 2, axis=1))))


def _logmap(p: np.ndarray) -> np.ndarray:
    """Pose2 ``Logmap`` per row (GTSAM's convention: ``(v_x, v_y, ω)``)."""
    x, y, th = p[:, 0], p[:, 1], p[:, 2]
    half = 0.5 * th
    # V⁻¹ of SE(2): [[a, b], [-b, a]] with a = (θ/2) cot(θ/2), b = θ/2 (a → 1 as θ → 0)
    small = np.abs(th) < 1e-10
    a = np.where(small, 1.0, half * np.cos(half) / np.where(small, 1.0, np.sin(half)))
    return np.column_stack([a * x + half * y, -half * x + a * y, th])


# --- command line -------------------------------------------------------------------------

def _format(fig: dict) -> str:
    def f(k, v):
        if k in ("t0", "t_end"):
            return f"{v:.3f}"
        return f"{v:.4g}" if isinstance(v, float) else str(v)
    return "\n".join(f"  {k:30s} {f(k, v)}" for k, v in fig.items())


#: Columns of the summary table (figure, header, format).
_TABLE = (
    ("t_total_s", "time s", "{:.2f}"), ("iterations", "LM it", "{}"),
    ("pos_err_median", "pos med m", "{:.3f}"), ("pos_err_p95", "pos p95 m", "{:.3f}"),
    ("pos_err_rmse", "pos rmse m", "{:.3f}"), ("heading_err_median", "hdg med rad", "{:.3f}"),
    ("lm_err_median", "lm med m", "{:.3f}"), ("lm_err_max", "lm max m", "{:.3f}"),
    ("lm_err_aligned_rmse", "lm shape m", "{:.3f}"), ("pose_xy_in_3sigma", "pose xy 3σ", "{:.3f}"),
    ("pose_se2_in_3sigma", "pose se2 3σ", "{:.3f}"), ("lm_xy_in_3sigma", "lm xy 3σ", "{:.3f}"),
    ("pose_3sigma_major_median", "3σ major m", "{:.3f}"), ("dead_reckoning_pos_err_median", "DR med m", "{:.3f}"),
)


def summary_table(rows: list[tuple[str, dict]]) -> str:
    """A fixed-width table of the main figures, one row per (label, figures)."""
    head = f"{'run':18s}" + "".join(f"{h:>12s}" for _, h, _ in _TABLE)
    lines = [head]
    for label, fig in rows:
        lines.append(f"{label:18s}" + "".join(f"{fmt.format(fig[k]):>12s}" for k, _, fmt in _TABLE))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    import json

    from ivslam_cli.logs import read_log

    ap = argparse.ArgumentParser(prog="python -m bench.gtsam_baseline", description=__doc__.split("\n")[0])
    ap.add_argument("--robot", type=int, action="append", help="MRCLAM robot 1..5 (repeatable; default all)")
    ap.add_argument("--log", default=str(MRCLAM_PATH), help="log path (default MRCLAM Dataset 6)")
    ap.add_argument("--plain", action="store_true", help="only without the Huber kernel")
    ap.add_argument("--both", action="store_true", help="robust and plain")
    ap.add_argument("--robust-odometry", action="store_true", help="Huber on the odometry factors too")
    ap.add_argument("--pose-every", type=float, default=1.0, help="largest gap between poses [s] (default 1)")
    ap.add_argument("--span", choices=("observations", "odometry"), default="observations",
                    help="poses up to the last observation (default) or the last odometry stamp")
    ap.add_argument("--bound", action="append", default=[], metavar="KEY=VALUE",
                    help=f"override a bound (defaults: {MRCLAM_BOUNDS})")
    ap.add_argument("--json", action="store_true", help="print one JSON list of {robot, figures...}")
    args = ap.parse_args(argv)
    bounds = dict(MRCLAM_BOUNDS)
    for kv in args.bound:
        k, _, v = kv.partition("=")
        if k not in bounds:
            ap.error(f"unknown bound {k!r}")
        bounds[k] = float(v)
    modes = [False] if args.plain else [True, False] if args.both else [True]
    if not args.json:
        print(f"bounds (σ = bound/3): {bounds}")
    rows, docs = [], []
    for robot in args.robot or [1, 2, 3, 4, 5]:
        log = read_log(args.log, robot=robot)
        for robust in modes:
            fig = run_gtsam(log, bounds=bounds, robust=robust, robust_odometry=args.robust_odometry,
                            pose_every=args.pose_every, span=args.span)
            label = f"robot {robot} {'Huber' if robust else 'plain'}"
            rows.append((label, fig))
            docs.append({"robot": robot, "bounds": bounds, **fig})
            if not args.json:
                print(f"\n{label}:\n{_format(fig)}", flush=True)
    if args.json:
        print(json.dumps(docs, indent=1))
    else:
        print("\n" + summary_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
