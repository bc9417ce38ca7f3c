"""Witnesses of the landmark CSP on lag-free twist logs (``bench/landmark_witness_steps.py``):
each witness is a world that meets every stated bound (checked here by a separate integration
that does not use the module's arcs), and our enclosures hold it — a soundness check beyond the
truth on simulated logs."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("highspy")

from bench.landmark_witness import Bounds  # noqa: E402
from bench.landmark_witness_steps import StepProblem, StepWitness, _share  # noqa: E402
from ivslam_cli.config import resolve_config  # noqa: E402
from ivslam_cli.report.core import angle_in  # noqa: E402
from ivslam_cli.simulate import simulate  # noqa: E402
from ivslam_cli.simulate.config import SimConfig  # noqa: E402
from ivslam_cli.slam.landmarks import Params  # noqa: E402
from ivslam_cli.slam.landmarks.pipeline import solve  # noqa: E402

RUN = {"landmarks.initial_pose_from_truth": True, "robust.q_landmark": 2, "robust.q_pose": 1}


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


@pytest.fixture(scope="module")
def case():
    log = simulate(SimConfig(scenario="landmarks", seed=3, steps=90))
    params = Params.from_config(resolve_config(None, RUN, log_bounds=log.bounds))
    given = Params.from_config(resolve_config(None, {**RUN, "landmarks.map_known": True}, log_bounds=log.bounds))
    pb = StepProblem(log, Bounds.from_params(params))
    return log, params, pb, {True: solve(log, params), False: solve(log, given)}


def check_world(log, params, pb, w):
    """Every bound of the model on the whole log, by Simpson's rule on each held twist."""
    b = Bounds.from_params(params)
    z = np.asarray(log.odometry.twist, float)[:-1]
    v, om = w["v"], w["w"]
    assert (v > 0).all()
    assert (np.abs(z[:, 0] - v) <= b.v_abs + b.v_rel * v).all()
    assert (np.abs(z[:, 1] - om) <= b.w_abs + b.w_rel * v).all()
    h = np.diff(log.odometry.stamp)
    th = w["P0"][2] + np.concatenate([[0.0], np.cumsum(om * h)])
    s = np.linspace(0.0, 1.0, 33)
    wts = np.where(np.arange(33) % 2 == 1, 4.0, 2.0)
    wts[0] = wts[-1] = 1.0
    ang = th[:-1, None] + (om * h)[:, None] * s[None, :]
    dx = (v * h)[:, None] * np.cos(ang) @ wts / 96.0
    dy = (v * h)[:, None] * np.sin(ang) @ wts / 96.0
    X = np.column_stack([w["P0"][0] + np.concatenate([[0.0], np.cumsum(dx)]),
                         w["P0"][1] + np.concatenate([[0.0], np.cumsum(dy)]), th])
    assert np.abs(X - w["poses"]).max() < 1e-9  # the module's arcs are the path
    truth0 = np.asarray(log.truth.pose[0], float)
    assert (np.abs(w["P0"] - truth0) <= np.asarray(params.initial.margin)).all()
    obs = log.observations
    k = np.searchsorted(log.odometry.stamp, obs.stamp)
    pose = X[k]
    m = np.array([w["landmarks"][int(i)] for i in obs.landmark_id])
    r = np.hypot(m[:, 0] - pose[:, 0], m[:, 1] - pose[:, 1])
    brg = wrap(np.arctan2(m[:, 1] - pose[:, 1], m[:, 0] - pose[:, 0]) - pose[:, 2] - obs.bearing)
    ok = (np.abs(r - obs.range) <= b.range_abs + b.range_rel * obs.range) & (np.abs(brg) <= b.bearing)
    return X, ok


def test_the_truth_is_recovered_as_a_path_of_held_twists(case):
    log, params, pb, _ = case
    assert pb.n_outliers == 0 and pb.odometry_outliers.size == 0 and pb.step.size > 200
    assert (pb.sv <= 1).all() and (pb.sw <= 1).all()
    assert (pb.er_b <= params.range_abs + params.range_rel * pb.rng).all() and (pb.eb_b <= params.bearing).all()
    assert _share(np.array([0.0, 0.99]), np.array([1.0, 1.0])).tolist() == [0.97, 0.995]


@pytest.mark.parametrize("slam", [True, False])
def test_witnesses_are_worlds_and_lie_in_our_enclosures(case, slam):
    log, params, pb, outs = case
    out = outs[slam]
    node = 60
    wit = StepWitness(pb, slam=slam)
    spread = []
    for c, sign in ((2, +1), (0, -1), (1, +1)):
        value = wit.push(node, c, sign)
        w = wit.world()
        X, ok = check_world(log, params, pb, w)
        assert ok.all()  # every observation within its bounds (the log has no outlier)
        assert X[node, c] == pytest.approx(value, abs=1e-9)
        assert sign * (value - pb.truth[node, c]) >= 0.0
        spread.append(abs(value - pb.truth[node, c]))
        if not slam:
            assert all(np.array_equal(w["landmarks"][i], pb.landmarks[i]) for i in pb.landmarks)
        # our enclosures hold the witness: its pose at every stamp and (SLAM) its map
        box = out.poses.box[np.searchsorted(out.poses.stamp, log.odometry.stamp)]
        assert (box[:, 0, 0] <= X[:, 0]).all() and (X[:, 0] <= box[:, 0, 1]).all()
        assert (box[:, 1, 0] <= X[:, 1]).all() and (X[:, 1] <= box[:, 1, 1]).all()
        assert angle_in(box[:, 2, 0], box[:, 2, 1], X[:, 2]).all()
        if slam:
            for i, lid in enumerate(out.landmarks.id):
                x, y = w["landmarks"][int(lid)]
                L = out.landmarks.box[i]
                assert L[0, 0] <= x <= L[0, 1] and L[1, 0] <= y <= L[1, 1]
    assert min(spread) > 0.001 and max(spread) > 0.005  # the witnesses moved (a check that could not fail would not)


def test_broken_observations_keep_to_the_runs_q(case):
    log, params, pb, outs = case
    node = 60
    drop = pb.q_drops(node, params.q_pose, params.q_landmark, params.q_landmark_frac)
    assert drop.sum() >= 10
    steps, counts = np.unique(pb.step[drop], return_counts=True)
    assert counts.max() <= params.q_pose
    for lid, n in zip(*np.unique(pb.lid[drop], return_counts=True)):
        assert n <= max(params.q_landmark, int(params.q_landmark_frac * pb.n_all[int(lid)]))
    wit = StepWitness(pb.without(drop), slam=True)
    value = wit.push(node, 0, +1)
    _, ok = check_world(log, params, pb, wit.world())
    assert ok.size == drop.size and ok[~drop].all()  # only the broken observations may miss their bounds
    box = outs[True].poses.box[int(np.searchsorted(outs[True].poses.stamp, log.odometry.stamp[node]))]
    assert box[0, 0] <= value <= box[0, 1]


def test_witnesses_that_break_what_the_duals_pick_keep_to_q_and_lie_in_our_enclosures(case):
    log, params, pb, outs = case
    node = 60
    q = (params.q_pose, params.q_landmark, params.q_landmark_frac)
    box = outs[True].poses.box[int(np.searchsorted(outs[True].poses.stamp, log.odometry.stamp[node]))]
    gained = []
    for c, sign in ((0, +1), (1, -1)):
        plain = StepWitness(pb, slam=True).push(node, c, sign)
        wit = StepWitness(pb, slam=True, q=q)
        value = wit.push(node, c, sign)
        drop = ~wit.active
        assert drop.any()
        assert np.unique(pb.step[drop], return_counts=True)[1].max() <= params.q_pose
        for lid, n in zip(*np.unique(pb.lid[drop], return_counts=True)):
            assert n <= max(params.q_landmark, int(params.q_landmark_frac * pb.n_all[int(lid)]))
        X, ok = check_world(log, params, pb, wit.world())
        assert ok[~drop].all() and X[node, c] == pytest.approx(value, abs=1e-9)
        assert box[c, 0] <= value <= box[c, 1]
        gained.append(sign * (value - plain))
    assert max(gained) > 0.001  # breaking observations took the witness further than meeting them all
