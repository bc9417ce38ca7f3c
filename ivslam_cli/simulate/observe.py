"""Range-bearing landmark observations with bounded noise, outliers, wrong associations."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ivslam_cli.logs.model import Observations
from ivslam_cli.simulate import noise
from ivslam_cli.simulate.motion import wrap


def predict(pose: np.ndarray, landmark_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``g``: true range and bearing of every landmark from every pose, ``(T, L)`` each."""
    dx = landmark_xy[None, :, 0] - pose[:, None, 0]
    dy = landmark_xy[None, :, 1] - pose[:, None, 1]
    return np.hypot(dx, dy), wrap(np.arctan2(dy, dx) - pose[:, None, 2])


def visibility(pose, landmark_xy, min_range, max_range, half_fov) -> np.ndarray:
    rho, alpha = predict(pose, landmark_xy)
    return (rho >= min_range) & (rho <= max_range) & (np.abs(alpha) <= half_fov)


@dataclass
class Observed:
    obs: Observations
    outlier: np.ndarray  # (M,) breaks the bounds (gross error or wrong association)
    wrong_association: np.ndarray  # (M,) subset of outlier


def observe(rng: np.random.Generator, stamp: np.ndarray, pose: np.ndarray, landmark_id: np.ndarray,
            landmark_xy: np.ndarray, min_range: float, max_range: float, half_fov: float,
            bounds: dict[str, float], kind: str, outlier_rate: float, outlier_magnitude: float,
            wrong_association_rate: float) -> Observed:
    """Observe every visible landmark at every step (rows sorted by step, then landmark)."""
    rho, alpha = predict(pose, landmark_xy)
    seen = (rho >= min_range) & (rho <= max_range) & (np.abs(alpha) <= half_fov)
    t_idx, l_idx = np.nonzero(seen)
    rho, alpha = rho[t_idx, l_idx], alpha[t_idx, l_idx]
    m = rho.shape[0]
    b_rho = bounds["range_abs"] + bounds["range_rel"] * rho
    b_alpha = bounds["bearing"]
    # the pipelines' convention: |z - rho| <= range_abs + range_rel * z (the measured range).
    # With u = e / b_rho in [-1, 1], z = (rho + u a) / (1 - u r) gives z - rho = u (a + r z).
    u = noise.bounded(rng, b_rho, kind, m) / np.where(b_rho > 0, b_rho, 1.0)
    e_rho = (rho + u * bounds["range_abs"]) / (1.0 - u * bounds["range_rel"]) - rho
    e_alpha = noise.bounded(rng, b_alpha, kind, m)

    # gross outliers: range, bearing or both
    out = noise.pick(rng, outlier_rate, m)
    which = rng.integers(0, 3, m)
    hit_r, hit_a = out & (which != 1), out & (which != 0)
    big_r = noise.outlier(rng, b_rho, outlier_magnitude, m)
    big_r = np.where(rho + big_r < 0, -big_r, big_r)  # a range is never negative
    big_a = np.clip(noise.outlier(rng, b_alpha, outlier_magnitude, m), -np.pi, np.pi)
    e_rho = np.where(hit_r, big_r, e_rho)
    e_alpha = np.where(hit_a, big_a, e_alpha)
    z_rho = rho + e_rho
    z_alpha = wrap(alpha + e_alpha)
    ids = landmark_id[l_idx].astype(np.int64)

    # wrong associations: relabel with a landmark whose prediction is out of bounds
    wrong = noise.pick(rng, wrong_association_rate, m) & ~out
    for i in np.flatnonzero(wrong):
        r_all, a_all = predict(pose[t_idx[i]][None, :], landmark_xy)
        r_all, a_all = r_all[0], a_all[0]
        far = (np.abs(z_rho[i] - r_all) > bounds["range_abs"] + bounds["range_rel"] * z_rho[i]) | (
            np.abs(wrap(z_alpha[i] - a_all)) > b_alpha)
        far[l_idx[i]] = False
        cand = np.flatnonzero(far)
        if cand.size == 0:
            wrong[i] = False
            continue
        ids[i] = landmark_id[rng.choice(cand)]

    inb = ~(out | wrong)
    ok = (np.abs(z_rho - rho) <= bounds["range_abs"] + bounds["range_rel"] * z_rho) & (
        np.abs(wrap(z_alpha - alpha)) <= b_alpha)
    if not np.all(ok[inb]):  # pragma: no cover - guaranteed by noise.INSIDE
        raise AssertionError("in-bound observation generated out of bounds")
    obs = Observations(stamp=stamp[t_idx].copy(), landmark_id=ids, range=z_rho, bearing=z_alpha)
    return Observed(obs, out | wrong, wrong)
