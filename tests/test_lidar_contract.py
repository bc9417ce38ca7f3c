"""Pose contraction against the map (second seed): soundness and how much it contracts.

Worlds, the cone LiDAR and pose boxes come from ``test_lidar_map``: a map is built from scans
at known poses (tight boxes), then a new scan from a true pose inside a wide box is
contracted against it.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_lidar_map import SETTINGS, make_scans, random_box, random_pose, random_world

from ivslam_cli.paving.tiles import TileMap
from ivslam_cli.slam.lidar_contract import contract_pose
from ivslam_cli.slam.lidar_map import LidarBounds, update_map

EPS = 0.05
R_ABS, R_REL, HALF = 0.03, 0.01, 0.004


def _mapped_world(seed: int, n_map: int = 12):
    """A world, a map from ``n_map`` scans at known poses, and one more scan (the last) from a
    fresh true pose; returns (tmap, scans, truth pose of the last scan, bounds, rng)."""
    rng = np.random.default_rng(seed)
    segs, room = random_world(rng)
    poses = np.array([random_pose(rng, segs, room) for _ in range(n_map + 1)])
    scans, _, _ = make_scans(rng, segs, poses, (0.1, 0.0, 0.0), HALF, R_ABS, R_REL)
    bounds = LidarBounds(R_ABS, R_REL, HALF)
    tmap = TileMap(EPS)
    tight = np.array([random_box(rng, p, 0.005, 0.001) for p in poses[:n_map]])
    update_map(tmap, scans, np.vstack([tight, tight[:1]]), bounds, order=np.arange(n_map))
    return tmap, scans, poses[n_map], bounds, rng


def _inside(box, p) -> bool:
    return bool(box[0] <= p[0] <= box[1] and box[2] <= p[1] <= box[3] and box[4] <= p[2] <= box[5])


@given(st.integers(0, 2**32 - 1), st.sampled_from([0, 3]))
@settings(max_examples=100, **SETTINGS)
def test_contraction_keeps_the_true_pose(seed, q):
    tmap, scans, truth, bounds, rng = _mapped_world(seed)
    box = random_box(rng, truth, 0.3, 0.08)
    out, kept, tested = contract_pose(tmap, scans, len(scans) - 1, box, bounds, q=q, stride=2, max_boxes=512)
    assert kept > 0 and tested > 0
    assert _inside(out, truth), (box, out, truth)
    assert np.all(out[0::2] >= box[0::2]) and np.all(out[1::2] <= box[1::2])


def test_contraction_shrinks_wide_boxes():
    """Over 20 worlds, boxes of ±0.3 m / ±0.08 rad around the truth: the contracted boxes are
    much smaller in x-y (median area ratio below a quarter), somewhat in heading, and every one
    still holds the truth."""
    ratios, th_ratios = [], []
    for seed in range(20):
        tmap, scans, truth, bounds, rng = _mapped_world(1000 + seed)
        box = random_box(rng, truth, 0.3, 0.08, full=True)
        out, kept, _ = contract_pose(tmap, scans, len(scans) - 1, box, bounds, q=3, stride=2, max_boxes=512)
        assert kept > 0 and _inside(out, truth)
        ratios.append((out[1] - out[0]) * (out[3] - out[2]) / ((box[1] - box[0]) * (box[3] - box[2])))
        th_ratios.append((out[5] - out[4]) / (box[5] - box[4]))
    assert np.median(ratios) < 0.25, np.round(ratios, 3)
    assert np.median(th_ratios) < 0.9, np.round(th_ratios, 3)  # headings contract less: walls slide along themselves


def test_an_empty_map_contracts_nothing():
    rng = np.random.default_rng(3)
    segs, room = random_world(rng)
    pose = random_pose(rng, segs, room)
    scans, _, _ = make_scans(rng, segs, pose[None], (0.0, 0.0, 0.0), HALF, R_ABS, R_REL)
    box = random_box(rng, pose, 0.3, 0.08)
    out, kept, _ = contract_pose(TileMap(EPS), scans, 0, box, LidarBounds(R_ABS, R_REL, HALF), stride=4,
                                 max_boxes=256)
    assert kept > 0 and np.allclose(out, box)


def test_the_pipeline_contracts_its_pose_boxes_against_the_map():
    """``--mode lidar`` with contraction: every true pose still in its box, and the boxes
    narrower than dead reckoning alone (median width over a 20 s simulated log)."""
    from ivslam_cli.config import resolve_config
    from ivslam_cli.report.core import pose_containment
    from ivslam_cli.simulate import SimConfig, simulate
    from ivslam_cli.slam.lidar import run_lidar

    log = simulate(SimConfig(scenario="lidar", seed=5, steps=200))
    widths = {}
    for contract in (False, True):
        # the simulator ray-casts: state the gap assumption, or no free space is proven to contract with
        cfg = resolve_config(None, {"landmarks.initial_pose_from_truth": True, "lidar.contract": contract,
                                    "lidar.fill_gaps": True}, log_bounds=log.bounds)
        out = run_lidar(log, cfg)
        pc = pose_containment(out.poses, log.truth)
        assert pc.contained == pc.checked > 0
        widths[contract] = out.stats["median_pose_width"]
    assert out.stats["scans_contracted"] > 100 and out.stats["scans_contradicting_map"] == 0
    assert widths[True] < 0.8 * widths[False], widths
