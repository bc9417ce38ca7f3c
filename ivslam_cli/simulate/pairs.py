"""Scenario ``pairs``: holonomic robot without rotation among point landmarks (the setting of
Mustafa, Codres & Stancu)."""

from __future__ import annotations

import numpy as np

from ivslam_cli.errors import ConfigError
from ivslam_cli.logs.model import GroundTruth, LogData, Provenance
from ivslam_cli.simulate.common import base_meta, waypoint_path
from ivslam_cli.simulate.config import SimConfig
from ivslam_cli.simulate.motion import T0, make_stamps
from ivslam_cli.simulate.observe import observe, visibility


def coverage_defects(vis: np.ndarray) -> np.ndarray:
    """Steps that see fewer than two landmarks, or (after step 0) no landmark seen before."""
    seen_before = np.zeros_like(vis)
    seen_before[1:] = np.logical_or.accumulate(vis, axis=0)[:-1]
    count = vis.sum(axis=1)
    old = (vis & seen_before).sum(axis=1)
    bad = count < 2
    bad[1:] |= old[1:] < 1
    return np.flatnonzero(bad)


def simulate_pairs(cfg: SimConfig, progress=None) -> LogData:
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(4)]
    rate = cfg.resolved_rate()
    n = cfg.resolved_steps(rate)
    stamp = make_stamps(T0, rate, n)
    lo, hi = cfg.range_limits()
    w = cfg.world_size
    xy = waypoint_path(rngs[0], stamp - stamp[0], cfg.speed, w)
    pose = np.column_stack([xy, np.zeros(n)])  # heading known: 0
    lm = rngs[1].uniform(0.0, w, (cfg.landmarks, 2))

    # by construction: add landmarks where a step would see < 2, or no old one
    radius = 0.5 * (lo + hi)
    for _ in range(4 * n + 10):
        bad = coverage_defects(visibility(pose, lm, lo, hi, np.pi))
        if bad.size == 0:
            break
        k = int(bad[0])
        centre = pose[k] if k == 0 else 0.5 * (pose[k] + pose[k - 1])
        phi = rngs[1].uniform(-np.pi, np.pi)
        lm = np.vstack([lm, centre[:2] + radius * np.array([np.cos(phi), np.sin(phi)])])
    else:  # pragma: no cover - each addition fixes a step
        raise ConfigError("cannot place landmarks so that every step sees an old one; widen --max-range")
    if progress:
        progress(n // 2)
    ids = np.arange(1, lm.shape[0] + 1, dtype=np.int64)
    bounds = cfg.resolved_bounds()
    o = observe(rngs[2], stamp, pose, ids, lm, lo, hi, np.pi, bounds, cfg.noise,
                cfg.outlier_rate, cfg.outlier_magnitude, cfg.wrong_association_rate)
    meta = base_meta(cfg, rate, n) | {
        "landmark_sensor": {"min_range": lo, "max_range": hi, "half_fov": float(np.pi)},
        "added_landmarks": int(lm.shape[0] - cfg.landmarks),
        "wrong_association": np.flatnonzero(o.wrong_association).tolist(),
    }
    truth = GroundTruth(pose_stamp=stamp.copy(), pose=pose, landmark_id=ids, landmark_xy=lm,
                        outliers={"observations": o.outlier})
    if progress:
        progress(n - n // 2)
    return LogData(provenance=Provenance(path="<simulated>", format="simulated",
                                         topics={"observations": "/landmarks", "truth": "/ground_truth"}),
                   observations=o.obs, truth=truth, bounds=bounds, meta=meta)
