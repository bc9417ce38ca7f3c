"""The cell filter of ``bench/bench_landmark_sets.py``: its sets hold the truth, and the three
representations nest (cells ⊆ octagon per slice ⊆ box per slice), so their widths do too."""

from __future__ import annotations

import numpy as np
import pytest

from bench.bench_landmark_sets import SetFilter, median_widths
from ivslam_cli.config import resolve_config
from ivslam_cli.simulate import simulate
from ivslam_cli.simulate.config import SimConfig
from ivslam_cli.slam.landmarks import Params


@pytest.fixture(scope="module")
def sf():
    log = simulate(SimConfig(scenario="landmarks", seed=3, steps=30))
    run = {"landmarks.initial_pose_from_truth": True, "landmarks.map_known": True}
    params = Params.from_config(resolve_config(None, run, log_bounds=log.bounds))
    return SetFilter(log, params, cell=0.006, span=0.6, heading_cell=0.001, heading_span=0.16)


@pytest.mark.parametrize("q_pose", [0, 1])
def test_representations_nest_and_hold_the_truth(sf, q_pose):
    runs = {mode: sf.run(q_pose, mode) for mode in ("cells", "octagon", "box")}
    for mode, (w, truth, clipped) in runs.items():
        assert truth, mode
        assert not clipped, mode
        assert (w > 0).all(), mode
    assert (runs["cells"][0] <= runs["octagon"][0] + 1e-12).all()
    assert (runs["octagon"][0] <= runs["box"][0] + 1e-12).all()
    # the cells keep shapes a box per slice cannot: somewhere strictly narrower
    assert (runs["cells"][0] < runs["box"][0] - 1e-12).any()


def test_median_widths_of_boxes_and_widths():
    boxes = np.array([[[0.0, 2.0], [0.0, 1.0], [0.0, 0.1]], [[0.0, 1.0], [0.0, 3.0], [0.0, 0.3]]])
    assert median_widths(boxes) == (2.5, pytest.approx(0.2))
    assert median_widths(boxes[:, :, 1] - boxes[:, :, 0]) == (2.5, pytest.approx(0.2))
