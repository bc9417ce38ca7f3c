"""Scan pairs (``lidar.pair_boxes``): each scan matched against the scan before it alone, its
relative pose enclosed in that scan's robot frame (:mod:`ivslam_cli.slam.lidar.scan_pairs`)."""

from __future__ import annotations

import numpy as np
import pytest

from ivslam_cli.report.core import angle_in, in_box, relative_pose, scan_pair_mask, truth_at
from ivslam_cli.slam.lidar.pipeline import run
from ivslam_cli.slam.lidar.prediction import trajectory
from ivslam_cli.slam.lidar.scan_pairs import pair_prior
from tests.helpers.hyp import seeds
from tests.helpers.lidar_truth import assert_contained
from tests.slam.lidar.test_lidar_pipeline import run_sim

WIDE = {"bounds.odom_v": 1.0, "bounds.odom_w": 2.0}  # sound (wider than the simulated noise), a wide prior


def _inside(box, t):
    """Is the pose ``t`` (3,) in the box (3, 2), the heading modulo 2π?"""
    return bool(in_box(box[:2], t[:2]) and angle_in(box[2, 0], box[2, 1], t[2]))


@pytest.mark.parametrize("seed", seeds(ci=6, dev=2))
def test_scan_pairs_hold_the_true_relative_pose_within_their_prior(seed):
    """Every consecutive pair gets an enclosure inside its dead-reckoned prior that holds the true
    relative pose; with wide odometry bounds the match narrows the prior: the heading several
    times, the position across the walls (seed 0: ×1.45 / ×1.39 / ×8.1 in x / y / θ; along a
    corridor one axis is the odometry's)."""
    world = ("rooms", "corridor", "pillars")[seed % 3]
    log, params, out = run_sim(seed, world, steps=30, overrides={**WIDE, "lidar.pair_boxes": 4000})
    pairs, boxes = out.tracking.pairs
    used = out.used
    assert pairs.shape[0] >= used.size - 3 and np.all(pairs[:, 1] == pairs[:, 0] + 1)
    m = trajectory(log, params, log.scans)[2]
    st = np.asarray(log.scans.stamp, float)[used]
    truth = relative_pose(truth_at(log.truth, st[pairs[:, 0]]), truth_at(log.truth, st[pairs[:, 1]]))
    ratio = []
    for (a, b), box, t in zip(pairs, boxes, truth):
        prior = pair_prior(m, int(a), int(b)).reshape(3, 2)
        assert _inside(prior, t), (a, b)
        assert _inside(box, t), (a, b, box, t)
        assert np.all(box[:, 0] >= prior[:, 0]) and np.all(box[:, 1] <= prior[:, 1])
        ratio.append((prior[:, 1] - prior[:, 0]) / (box[:, 1] - box[:, 0]))
    r = np.median(ratio, axis=0)  # prior width / enclosure width: x, y, θ
    assert max(r[0], r[1]) > 1.2 and r[2] > 3, r  # walls along one axis (a corridor) leave the other
    # the report checks them against the truth as their own kind
    res = run(log, params)
    c = assert_contained(res, ("pose", "pose_scan_pair"))
    assert c["pose_scan_pair"][1] == int(scan_pair_mask(res).sum()) > 0


def test_no_pairs_by_default():
    log, params, out = run_sim(1, "rooms", steps=10)
    assert params.pair_boxes == 0 and out.tracking.pairs is None
    assert scan_pair_mask(run(log, params)) is None


@pytest.mark.parametrize("seed", seeds(ci=3, dev=1))
def test_scan_pairs_seed_the_tracking(seed):
    """With pairs, a scan's box in the submap its predecessor anchors lies in the pair's
    enclosure (the pair stands for that match), and the tracking's relative boxes are narrower
    than without pairs (wide odometry bounds: the tracker's budget runs out on every fourth beam
    where the pair tests every beam). The truth is checked in the test above."""
    world = ("rooms", "corridor", "pillars")[seed % 3]
    _, _, out = run_sim(seed, world, steps=30, overrides={**WIDE, "lidar.pair_boxes": 4000})
    _, _, plain = run_sim(seed, world, steps=30, overrides=WIDE)
    pairs, boxes = out.tracking.pairs
    pair_of = {int(b): box for (a, b), box in zip(pairs, boxes)}
    seen = 0
    for s in out.tracking.submaps:
        for row, rel in zip(s.rows, s.rel):
            if row == s.anchor_row + 1 and row in pair_of:
                box = pair_of[row]
                assert np.all(rel[0::2] >= box[:, 0] - 1e-9) and np.all(rel[1::2] <= box[:, 1] + 1e-9), (row, rel, box)
                seen += 1
    assert seen >= 2
    w, w0 = out.stats["median_relative_width"], plain.stats["median_relative_width"]
    h, h0 = out.stats["median_relative_heading"], plain.stats["median_relative_heading"]
    assert w <= w0 and h < h0, (w, w0, h, h0)
