"""Twist odometry with bounded noise and outliers, and its dead-reckoned pose."""

from __future__ import annotations

import numpy as np

from ivslam_cli.logs.model import Odometry
from ivslam_cli.simulate import noise
from ivslam_cli.simulate.motion import dead_reckon


def measure_twist(rng: np.random.Generator, stamp: np.ndarray, true_pose0: np.ndarray,
                  true_twist: np.ndarray, bounds: dict[str, float], kind: str,
                  outlier_rate: float, outlier_magnitude: float) -> tuple[Odometry, np.ndarray]:
    """Measured twist ``u + e`` with ``|e_v| <= odom_v + odom_v_rel |v|`` and
    ``|e_w| <= odom_w + odom_w_rel |v|``; returns the odometry (pose dead-reckoned from
    the true initial pose) and the outlier mask."""
    n = stamp.shape[0]
    speed = np.abs(true_twist[:, 0])
    b_v = bounds["odom_v"] + bounds["odom_v_rel"] * speed
    b_w = bounds["odom_w"] + bounds["odom_w_rel"] * speed
    e_v = noise.bounded(rng, b_v, kind, n)
    e_w = noise.bounded(rng, b_w, kind, n)
    out = noise.pick(rng, outlier_rate, n)
    which = rng.integers(0, 3, n)
    e_v = np.where(out & (which != 1), noise.outlier(rng, b_v, outlier_magnitude, n), e_v)
    e_w = np.where(out & (which != 0), noise.outlier(rng, b_w, outlier_magnitude, n), e_w)
    twist = true_twist + np.column_stack([e_v, e_w])
    pose = dead_reckon(true_pose0, stamp, twist)
    return Odometry(stamp=stamp.copy(), pose=pose, twist=twist), out
