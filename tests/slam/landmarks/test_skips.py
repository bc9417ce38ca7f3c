"""Skip edges (``slam/landmarks/skips.py``): the composed motion between two observation frames
keeps every pose the chain of steps allows, and on simulated logs it narrows the pose sets
while the truth stays inside."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ivslam_cli.config import resolve_config
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.slam.landmarks import Params as LandmarksParams
from ivslam_cli.slam.landmarks.pipeline import solve
from ivslam_cli.slam.landmarks.pose_sets import make_bins, set_from_box
from ivslam_cli.slam.landmarks.skips import skip_edges, skip_sets
from tests.helpers.hyp import seeds
from tests.slam.landmarks.test_landmarks import _check_sound


def _in_set(PS, k, pose):
    for b in range(PS.shape[1]):
        B = PS[k, b]
        if not B[0, 0] <= B[0, 1]:
            continue
        t = pose[2] + 2 * math.pi * np.round((0.5 * (B[2, 0] + B[2, 1]) - pose[2]) / (2 * math.pi))
        if B[0, 0] <= pose[0] <= B[0, 1] and B[1, 0] <= pose[1] <= B[1, 1] and B[2, 0] <= t <= B[2, 1]:
            return True
    return False


def _size(PS, k):
    """Summed x and y widths of the set's boxes."""
    live = PS[k, :, 0, 0] <= PS[k, :, 0, 1]
    return float((PS[k, live, :2, 1] - PS[k, live, :2, 0]).sum())


@pytest.mark.parametrize("seed", seeds(ci=60))
def test_an_edge_keeps_the_true_poses_and_contracts(seed):
    """A random path of ``n`` steps, each step's increment an interval around the true one
    (often an end at the true value at every step: the hardest case), the sets of its two ends set from
    boxes around their true poses (the far one wide): after the skip edge both true poses are
    still in their sets, and the far set is less than half what it was."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 20))
    poses = np.zeros((n + 1, 3))
    poses[0] = [*rng.uniform(-5, 5, 2), rng.uniform(-math.pi, math.pi)]
    U = np.zeros((n, 5, 2))
    tight = rng.integers(0, 3, (3, 2)) == 0  # per row and end: the truth at that end at every step
    for i in range(n):
        rho, alpha, dth = rng.uniform(0.0, 0.3), rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3)
        th = poses[i, 2]
        poses[i + 1] = [poses[i, 0] + rho * math.cos(th + alpha), poses[i, 1] + rho * math.sin(th + alpha), th + dth]
        for r, v in enumerate((rho, alpha, dth)):
            w = rng.uniform(0, 0.01, 2) * ~tight[r]
            U[i, r] = [v - w[0], v + w[1]]
        U[i, 0, 0] = max(U[i, 0, 0], 0.0)
    S = int(rng.choice([8, 64]))
    BINS = make_bins(S)
    PS = np.empty((2 * n + 2, S, 3, 2))  # nodes 0 and n are the edge's, the rest unused
    near = rng.uniform(0.0, 0.05, 3)
    set_from_box(PS, 0, np.column_stack([poses[0] - near, poses[0] + near]), BINS)
    far = np.array([5.0, 5.0, rng.choice([0.5, 7.0])])
    set_from_box(PS, n, np.column_stack([poses[n] - rng.uniform(0.5, 1, 3) * far,
                                         poses[n] + rng.uniform(0.5, 1, 3) * far]), BINS)
    sk = skip_edges(np.array([0, n]), np.zeros(2 * n + 2, np.int64), U, 1)
    assert sk.count == (1 if n > 1 else 0)
    before = _size(PS, n)
    H = np.empty((2 * n + 2, 3, 2))
    ok = skip_sets(PS, H, 0, sk.a, sk.b, sk.R, np.empty((S, 3, 2)), np.empty((S, 3, 2)), np.empty(S), np.empty(S),
                   np.ones(2 * n + 2, np.int64), np.full(1, -1, np.int64), np.zeros(1, np.int64))
    assert ok
    assert _in_set(PS, 0, poses[0]) and _in_set(PS, n, poses[n])
    assert _size(PS, n) < 0.5 * before


def test_edges_link_frames_two_four_and_more_apart_on_one_chain():
    frames = np.array([0, 1, 2, 5, 6, 7, 9, 10, 11])  # nodes with observations; 3, 4, 8 without
    chain_of = np.array([0] * 8 + [1] * 4)  # a second robot's chain from node 8
    U = np.zeros((11, 5, 2))
    sk = skip_edges(frames, chain_of, U, 2)
    pairs = set(zip(sk.a.tolist(), sk.b.tolist()))
    # next frame past nodes without observations; 2 frames on; 4 frames on; never across chains
    assert pairs == {(2, 5), (0, 2), (1, 5), (2, 6), (5, 7), (9, 11), (0, 6), (1, 7)}
    assert np.all(np.diff(sk.b) >= 0)
    assert skip_edges(frames, chain_of, U, 0).count == 0


def _sim(seed):
    return simulate(SimConfig(scenario="landmarks", seed=seed, steps=200, landmarks=18, world_size=20.0,
                              outlier_rate=0.01))


@pytest.mark.parametrize("seed", [1, 3, 5])
def test_skip_edges_narrow_the_pose_sets_and_keep_the_truth(seed):
    """Simulated logs like the demo's (outliers, q_landmark = 2, q_pose = 1): with skip edges the
    median pose box is narrower than without, and the truth stays inside."""
    log = _sim(seed)
    widths = []
    for levels in (0, 6):
        cfg = resolve_config(None, {"landmarks.initial_pose_from_truth": True, "robust.q_landmark": 2,
                                    "robust.q_pose": 1, "landmarks.skip_levels": levels}, log_bounds=log.bounds)
        out = solve(log, LandmarksParams.from_config(cfg))
        _check_sound(log, out)
        assert out.stats["skip_edges"] > (0 if levels else -1)
        widths.append(out.stats["median_pose_width"])
    assert widths[1] < widths[0]
