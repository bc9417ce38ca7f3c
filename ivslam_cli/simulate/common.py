"""Pieces shared by the scenarios: trajectories in a square world, metadata."""

from __future__ import annotations

import math

import numpy as np

from ivslam_cli import __version__
from ivslam_cli.simulate.config import SimConfig
from ivslam_cli.simulate.motion import step_scalar, wrap


def waypoint_path(rng: np.random.Generator, t: np.ndarray, speed: float, size: float) -> np.ndarray:
    """Holonomic path at constant ``speed`` through random waypoints in ``[1, size-1]^2``:
    positions ``(T, 2)`` at times ``t`` (seconds from the start)."""
    length = speed * float(t[-1]) + 1.0
    pts = [rng.uniform(1.0, size - 1.0, 2)]
    total = 0.0
    while total < length:
        nxt = rng.uniform(1.0, size - 1.0, 2)
        total += float(np.hypot(*(nxt - pts[-1])))
        pts.append(nxt)
    pts = np.asarray(pts)
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))))
    d = speed * t
    return np.column_stack([np.interp(d, s, pts[:, 0]), np.interp(d, s, pts[:, 1])])


def unicycle_waypoints(rng: np.random.Generator, stamp: np.ndarray, speed: float, size: float,
                       progress=None) -> tuple[np.ndarray, np.ndarray]:
    """A unicycle steering to random waypoints in ``[1, size-1]^2``.

    Returns the true poses ``(T, 3)`` and the true twists ``(T, 2)``; pose ``k+1`` is
    exactly ``h(pose_k, twist_k, dt_k)``. Starts at the centre, heading 0.
    """
    n = stamp.shape[0]
    pose = np.empty((n, 3))
    twist = np.empty((n, 2))
    x, y, th = 0.5 * size, 0.5 * size, 0.0
    goal = rng.uniform(1.0, size - 1.0, 2)
    w_max = 1.0
    for k in range(n):
        pose[k] = x, y, th
        if math.hypot(goal[0] - x, goal[1] - y) < 0.5:
            goal = rng.uniform(1.0, size - 1.0, 2)
        beta = float(wrap(math.atan2(goal[1] - y, goal[0] - x) - th))
        w = max(-w_max, min(w_max, 1.5 * beta))
        v = speed * max(0.1, math.cos(beta))
        twist[k] = v, w
        if k + 1 < n:
            x, y, th = step_scalar(x, y, th, v, w, stamp[k + 1] - stamp[k])
        if progress and k % 1000 == 999:
            progress(1000)
    return pose, twist


def base_meta(cfg: SimConfig, rate: float, steps: int) -> dict:
    """The metadata every simulated log carries (JSON-native values only)."""
    return {
        "generator": "ivslam simulate",
        "ivslam_version": __version__,
        "scenario": cfg.scenario,
        "seed": int(cfg.seed),
        "noise": cfg.noise,
        "steps": int(steps),
        "rate": float(rate),
        "outlier_rate": float(cfg.outlier_rate),
        "outlier_magnitude": float(cfg.outlier_magnitude),
        "wrong_association_rate": float(cfg.wrong_association_rate),
        "config": cfg.as_dict(),
    }
