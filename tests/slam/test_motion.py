"""How far the robot may move between two times (:meth:`MotionSteps.reach_between`), against the
simulated truth: twist odometry (rates times the time spent in each step) and pose increments
(each step's whole bound)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.config import resolve_config
from ivslam_cli.logs.model import Odometry
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.slam.motion import MotionBounds, motion_steps
from tests.helpers.hyp import examples


def _true_pose(tr, t: np.ndarray) -> np.ndarray:
    """The true poses at times ``t``: the poses of the stamps interpolated (as a swept scan's)."""
    th = np.unwrap(tr.pose[:, 2])
    return np.column_stack([np.interp(t, tr.pose_stamp, tr.pose[:, 0]), np.interp(t, tr.pose_stamp, tr.pose[:, 1]),
                            np.interp(t, tr.pose_stamp, th)])


@given(st.integers(0, 2**31 - 1), st.booleans(), st.lists(st.tuples(st.floats(0, 1), st.floats(0, 0.25)),
                                                          min_size=1, max_size=20))
@settings(max_examples=examples(ci=25))
def test_the_reach_between_two_times_holds_the_true_motion(seed, increments, spans):
    log = simulate(SimConfig(scenario="lidar", world="rooms", seed=seed, steps=30))
    tr, odo = log.truth, log.odometry
    if increments:  # the true poses as pose increments, within the default pose bounds
        odo = Odometry(stamp=tr.pose_stamp.copy(), pose=tr.pose.copy(), twist=None)
    bounds = MotionBounds.from_config(resolve_config(None, {}, log_bounds=log.bounds))
    m = motion_steps(odo, bounds, log.scans.stamp, prefer="pose" if increments else "twist")
    t_lo, t_hi = float(tr.pose_stamp[0]), float(tr.pose_stamp[-1])
    t0 = np.array([t_lo + f * (t_hi - t_lo) for f, _ in spans])
    t1 = np.minimum(t0 + np.array([tau for _, tau in spans]), t_hi)
    reach = m.reach_between(t0, t1)
    p0, p1 = _true_pose(tr, t0), _true_pose(tr, t1)
    assert np.all(np.hypot(p1[:, 0] - p0[:, 0], p1[:, 1] - p0[:, 1]) <= reach[:, 0])
    assert np.all(np.abs(p1[:, 2] - p0[:, 2]) <= reach[:, 1])
    assert np.all(reach >= 0.0)
