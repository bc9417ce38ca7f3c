"""Scenario ``landmarks``: unicycle with twist odometry, landmarks in a field of view (the
Guaranteed SLAM slides' setting)."""

from __future__ import annotations

import numpy as np

from ivslam_cli.logs.model import GroundTruth, LogData, Provenance
from ivslam_cli.simulate.common import base_meta, unicycle_waypoints
from ivslam_cli.simulate.config import SimConfig
from ivslam_cli.simulate.motion import T0, make_stamps
from ivslam_cli.simulate.observe import observe
from ivslam_cli.simulate.odometry import measure_twist


def simulate_landmarks(cfg: SimConfig, progress=None) -> LogData:
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(4)]
    rate = cfg.resolved_rate()
    n = cfg.resolved_steps(rate)
    stamp = make_stamps(T0, rate, n)
    lo, hi = cfg.range_limits()
    fov = cfg.half_fov()
    pose, twist = unicycle_waypoints(rngs[0], stamp, cfg.speed, cfg.world_size, progress)
    lm = rngs[1].uniform(0.0, cfg.world_size, (cfg.landmarks, 2))
    ids = np.arange(1, cfg.landmarks + 1, dtype=np.int64)
    bounds = cfg.resolved_bounds()
    odo, odo_out = measure_twist(rngs[3], stamp, pose[0], twist, bounds, cfg.noise,
                                 cfg.outlier_rate, cfg.outlier_magnitude)
    o = observe(rngs[2], stamp, pose, ids, lm, lo, hi, fov, bounds, cfg.noise,
                cfg.outlier_rate, cfg.outlier_magnitude, cfg.wrong_association_rate)
    meta = base_meta(cfg, rate, n) | {
        "landmark_sensor": {"min_range": lo, "max_range": hi, "half_fov": fov},
        "wrong_association": np.flatnonzero(o.wrong_association).tolist(),
    }
    truth = GroundTruth(pose_stamp=stamp.copy(), pose=pose, landmark_id=ids, landmark_xy=lm,
                        outliers={"observations": o.outlier, "odometry": odo_out})
    if progress:
        progress(n % 1000)
    return LogData(provenance=Provenance(path="<simulated>", format="simulated",
                                         topics={"observations": "/landmarks", "odometry": "/odom",
                                                 "truth": "/ground_truth"}),
                   odometry=odo, observations=o.obs, truth=truth, bounds=bounds, meta=meta)
