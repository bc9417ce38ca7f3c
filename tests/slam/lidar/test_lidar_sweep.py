"""A scan's beams taken one after another while the robot moves (``lidar.sweep``): every pose a
scan is matched or mapped with is widened by the motion its odometry allows in that time."""

from __future__ import annotations

import numpy as np
import pytest

from ivslam_cli.config import resolve_config
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.slam.lidar import Params as LidarParams
from ivslam_cli.slam.lidar.matcher import swept_box
from ivslam_cli.slam.lidar.pipeline import run
from ivslam_cli.slam.lidar.prediction import sweep_times
from tests.helpers.lidar_truth import containment

SWEEP = 0.0667  # the URG-04LX: 683 of 1024 steps of a 100 ms turn


def test_a_swept_box_holds_the_box_and_rounds_outward():
    box = np.array([0.1, 0.3, -0.2, 0.2, 1.0, 1.1])
    w = swept_box(box, (0.05, 0.02))
    assert np.all(w[0::2] < box[0::2] - np.array([0.05, 0.05, 0.02]) + 1e-15)
    assert np.all(w[1::2] > box[1::2] + np.array([0.05, 0.05, 0.02]) - 1e-15)
    assert swept_box(box, (0.0, 0.0)) is box
    rows = swept_box(np.stack([box, box]), np.array([[0.05, 0.02], [0.0, 0.0]]))
    assert np.array_equal(rows[0], w) and np.array_equal(rows[1], box)


@pytest.mark.slow  # ~40 s
def test_a_swept_log_keeps_the_truth_with_its_sweep_and_loses_it_without():
    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=5, steps=200, sweep=SWEEP))
    res = run(log, LidarParams.from_config(resolve_config(None, {}, log_bounds=log.bounds)))
    c = containment(res)
    for kind in ("pose", "pose_relative", "map_free", "global_free"):
        assert c[kind][0] == c[kind][1] > 0, (kind, c)
    assert "the log's time_increment" in res.consistency.assumption  # read from the log by default
    # every beam at the stamp: the model is wrong by the robot's motion during the scan
    off = {"lidar.sweep_from_log": False}
    still = run(log, LidarParams.from_config(resolve_config(None, off, log_bounds=log.bounds)))
    c0 = containment(still)
    assert any(c0[kind][0] < c0[kind][1] for kind in ("pose", "pose_relative", "map_free")), c0
    assert "at the scan's stamp" in still.consistency.assumption
    # the same sweep given by hand
    by_hand = {"lidar.sweep_from_log": False, "lidar.sweep": SWEEP}
    sweep_times_source = sweep_times(log.scans, LidarParams.from_config(resolve_config(None, by_hand,
                                                                                      log_bounds=log.bounds)))
    assert sweep_times_source[1] == "lidar.sweep" and np.allclose(sweep_times_source[0], SWEEP)
