"""Simulated logs carry their truth and bounds in /ivslam/meta: every reader recovers them."""

from __future__ import annotations

import numpy as np
import pytest

from ivslam_cli.logs import read_log
from ivslam_cli.logs.writers import write_log
from ivslam_cli.simulate import simulate
from ivslam_cli.simulate.config import SimConfig


@pytest.mark.parametrize("fmt,name", [("mcap", "log.mcap"), ("ros1", "log.bag"), ("ros2", "bagdir"),
                                      ("ros2-mcap", "bagdir2"), ("h5", "log.h5")])
def test_truth_bounds_and_outliers_survive_every_format(tmp_path, fmt, name):
    cfg = SimConfig(scenario="landmarks", seed=5, steps=60, landmarks=12, outlier_rate=0.05)
    log = simulate(cfg)
    path = write_log(tmp_path / name, log, fmt)
    back = read_log(path)
    assert back.bounds == log.bounds
    assert np.array_equal(back.truth.landmark_id, log.truth.landmark_id)
    assert np.array_equal(back.truth.landmark_xy, log.truth.landmark_xy)
    for stream, mask in log.truth.outliers.items():
        assert np.array_equal(back.truth.outliers[stream], mask), stream
    assert log.truth.outliers["observations"].any()  # the test would be empty otherwise
