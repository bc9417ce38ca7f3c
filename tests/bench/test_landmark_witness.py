"""Witnesses of the landmark CSP (``bench/landmark_witness.py``): every witness is a world that
meets every stated bound (checked here by code that does not use the module's path or
constraints), and our enclosures hold every witness — a soundness check beyond the truth."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("highspy")

from bench.landmark_witness import Bounds, Problem, Witness, fit_base, q_drops, wrap  # noqa: E402
from ivslam_cli.config import resolve_config  # noqa: E402
from ivslam_cli.logs import read_log  # noqa: E402
from ivslam_cli.report.core import angle_in  # noqa: E402
from ivslam_cli.slam.landmarks import Params  # noqa: E402
from ivslam_cli.slam.landmarks.pipeline import solve  # noqa: E402
from ivslam_cli.slam.motion import node_lags  # noqa: E402

from tests.helpers.paths import CONFIGS  # noqa: E402

SPAN = 40.0  # seconds of robot 1's log
pytestmark = pytest.mark.datasets


def _cut(stream, t1):
    m = stream.stamp <= t1
    return dataclasses.replace(stream, **{f.name: getattr(stream, f.name)[m] for f in dataclasses.fields(stream)
                                          if isinstance(getattr(stream, f.name), np.ndarray)
                                          and getattr(stream, f.name).shape[:1] == m.shape})


@pytest.fixture(scope="module")
def case(datasets):
    log = read_log(datasets / "mrclam" / "MRCLAM_Dataset6", robot=1)
    t1 = log.odometry.stamp[0] + SPAN
    log = dataclasses.replace(log, odometry=_cut(log.odometry, t1), observations=_cut(log.observations, t1))
    params = Params.from_config(resolve_config(CONFIGS / "mrclam.toml", {}))
    out = solve(log, params)
    pb = Problem(log, Bounds.from_params(params))
    base = fit_base(pb)
    return log, params, out, pb, base


def check_world(log, params, pb, w):
    """Every bound of the model, on the whole log, by a separate integration (Simpson's rule on
    each held-command piece) — the witness is a world that explains the data."""
    b = Bounds.from_params(params)
    t0 = log.odometry.stamp[0]
    to = log.odometry.stamp - t0
    z = log.odometry.twist
    ts = pb.ts
    j = np.clip(np.searchsorted(to, ts[:-1], side="right") - 1, 0, to.size - 1)
    zv, zw = z[j, 0], z[j, 1]
    blk = np.minimum(np.floor(ts[:-1] / 0.5 + 1e-9).astype(int), w["d"].size - 1)
    v = zv + w["a"][blk] * np.abs(zv) + w["c"][blk]
    om = zw + w["d"][blk]
    assert (np.abs(zv - v) <= b.v_abs + b.v_rel * np.abs(v) + 1e-15).all()
    assert (np.abs(zw - om) <= b.w_abs + 1e-15).all()
    h = np.diff(ts)
    th = w["P0"][2] + np.concatenate([[0.0], np.cumsum(om * h)])
    s = np.linspace(0.0, 1.0, 17)
    wts = np.where(np.arange(17) % 2 == 1, 4.0, 2.0)
    wts[0] = wts[-1] = 1.0
    ang = th[:-1, None] + om[:, None] * h[:, None] * s[None, :]
    dx = (v * h)[:, None] * np.cos(ang) @ wts / 48.0
    dy = (v * h)[:, None] * np.sin(ang) @ wts / 48.0
    X = np.column_stack([w["P0"][0] + np.concatenate([[0.0], np.cumsum(dx)]),
                         w["P0"][1] + np.concatenate([[0.0], np.cumsum(dy)]), th])
    lag = node_lags(to, z, ts, b.lag_xy, b.lag_th, b.lag_time, b.lag_memory)
    truth0 = pb.truth(0.0)[0]
    assert (np.abs(w["P0"] - truth0) <= b.margin + lag[0, [0, 0, 1]] + 1e-12).all()
    f = np.searchsorted(ts, pb.frame_t)
    off = w["frames"] - X[f]
    assert (np.abs(off[:, :2]) <= lag[f, :1] + 1e-9).all() and (np.abs(off[:, 2]) <= lag[f, 1] + 1e-12).all()
    pose = w["frames"][pb.frame]
    m = np.array([w["landmarks"][i] for i in pb.lid])
    r = np.hypot(m[:, 0] - pose[:, 0], m[:, 1] - pose[:, 1])
    assert (np.abs(r - pb.rng) <= b.range_abs + b.range_rel * pb.rng + 1e-12).all()
    brg = wrap(np.arctan2(m[:, 1] - pose[:, 1], m[:, 0] - pose[:, 0]) - pose[:, 2] - pb.brg)
    assert (np.abs(brg) <= b.bearing + 1e-12).all()
    return X


def check_caps(log, params, pb, drop):
    """The broken observations keep to the run's q: never two next to one odometry stamp, at most
    q of a landmark's."""
    stamps = log.odometry.stamp - pb.t0
    after = np.searchsorted(stamps, pb.t[drop], side="left")  # the odometry stamps around each
    before = np.searchsorted(stamps, pb.t[drop], side="right") - 1
    around = np.concatenate([before, after[after != before]])
    assert np.unique(around).size == around.size
    m = {int(i): int(n) for i, n in zip(*np.unique(pb.lid, return_counts=True))}
    for lid, n in zip(*np.unique(pb.lid[drop], return_counts=True)):
        assert n <= max(params.q_landmark, int(params.q_landmark_frac * m[int(lid)]))


def test_the_fitted_path_explains_the_truth(case):
    log, params, out, pb, base = case
    assert pb.n_outliers == 0 and pb.frame_t.size > 20
    assert base.worst <= 0.95  # every true pose within 95 % of the lag of the fitted path


@pytest.mark.parametrize("slam", [False, True])
def test_witnesses_are_worlds_and_lie_in_our_enclosures(case, slam):
    log, params, out, pb, base = case
    wit = Witness(pb, base, slam=slam)
    f = int(np.argmin(np.abs(pb.frame_t - 20.0)))  # a frame near the middle
    k = int(pb.fstep[f])
    node = int(np.searchsorted(out.poses.stamp, pb.t0 + pb.ts[k] - 1e-9))
    assert abs(out.poses.stamp[node] - pb.t0 - pb.ts[k]) < 1e-9
    truth = pb.truth(pb.ts[k])[0]
    spread = []
    for c, sign in ((2, +1), (2, -1), (0, +1), (1, -1)):
        value = wit.push(pb.ts[k] - 15.0, pb.ts[k] + 15.0, ("pose", k, c), sign)
        w = wit.world()
        check_world(log, params, pb, w)
        assert w["frames"][f, c] == pytest.approx(value, abs=1e-12)
        assert sign * (value - truth[c]) >= 0.0
        spread.append(abs(value - truth[c]))
        # our enclosures hold the witness: its true pose at every frame of the log
        stamps = pb.t0 + pb.frame_t
        nodes = np.searchsorted(out.poses.stamp, stamps - 1e-9)
        box = out.poses.box[nodes]
        P = w["frames"]
        assert (box[:, 0, 0] <= P[:, 0]).all() and (P[:, 0] <= box[:, 0, 1]).all()
        assert (box[:, 1, 0] <= P[:, 1]).all() and (P[:, 1] <= box[:, 1, 1]).all()
        assert angle_in(box[:, 2, 0], box[:, 2, 1], P[:, 2]).all()
        if slam:
            for i, lid in enumerate(out.landmarks.id):
                x, y = w["landmarks"][int(lid)]
                L = out.landmarks.box[i]
                assert L[0, 0] <= x <= L[0, 1] and L[1, 0] <= y <= L[1, 1]
    assert max(spread) > 0.05  # the witnesses moved (a check that could not fail would not)


def test_broken_observations_keep_to_the_runs_q_and_their_witnesses_lie_in_our_enclosures(case):
    """Witnesses that also break observations (as many as the run's q allows, nearest the node
    first): never two at one node, at most q of a landmark's, and our boxes still hold them."""
    log, params, out, pb, base = case
    t = 20.0
    drop = q_drops(pb, t, 15.0, params.q_pose, params.q_landmark, params.q_landmark_frac)
    assert drop.sum() >= 10
    check_caps(log, params, pb, drop)
    assert abs(pb.t[drop] - t).max() <= 15.0
    pq = pb.without(drop)
    wit = Witness(pq, base, slam=False)
    f = int(np.argmin(np.abs(pb.frame_t - t)))
    k = int(pb.fstep[f])
    # the same assumption counted at each pose over 2 s windows (robust.q_pose_scope = node)
    windowed = solve(log, Params.from_config(resolve_config(CONFIGS / "mrclam.toml", {
        "robust.q_pose_scope": "node", "landmarks.pose_window": 2.0, "landmarks.pose_window_obs": 12})))
    for c, sign in ((2, +1), (0, -1)):
        wit.push(pb.ts[k] - 15.0, pb.ts[k] + 15.0, ("pose", k, c), sign)
        w = wit.world()
        check_world(log, params, pq, w)  # every bound at every observation not broken
        for run in (out, windowed):
            nodes = np.searchsorted(run.poses.stamp, pb.t0 + pb.frame_t - 1e-9)
            box, P = run.poses.box[nodes], w["frames"]
            assert (box[:, 0, 0] <= P[:, 0]).all() and (P[:, 0] <= box[:, 0, 1]).all()
            assert (box[:, 1, 0] <= P[:, 1]).all() and (P[:, 1] <= box[:, 1, 1]).all()
            assert angle_in(box[:, 2, 0], box[:, 2, 1], P[:, 2]).all()


def test_witnesses_that_break_what_the_duals_pick_keep_to_the_runs_q(case):
    """Witnesses that break, one after each linear program, the observation whose rows hold the
    push most: the same caps, every other bound met, inside our boxes."""
    log, params, out, pb, base = case
    f = int(np.argmin(np.abs(pb.frame_t - 20.0)))
    k = int(pb.fstep[f])
    q = (params.q_pose, params.q_landmark, params.q_landmark_frac)
    gained = []
    for c, sign in ((2, +1), (0, -1)):
        plain = Witness(pb, base, slam=False).push(pb.ts[k] - 15.0, pb.ts[k] + 15.0, ("pose", k, c), sign)
        wit = Witness(pb, base, slam=False, q=q)
        value = wit.push(pb.ts[k] - 15.0, pb.ts[k] + 15.0, ("pose", k, c), sign)
        drop = ~wit.breaks.active
        assert drop.any()
        check_caps(log, params, pb, drop)
        w = wit.world()
        check_world(log, params, pb.without(drop), w)  # every bound at every observation not broken
        assert w["frames"][f, c] == pytest.approx(value, abs=1e-12)
        nodes = np.searchsorted(out.poses.stamp, pb.t0 + pb.frame_t - 1e-9)
        box, P = out.poses.box[nodes], w["frames"]
        assert (box[:, 0, 0] <= P[:, 0]).all() and (P[:, 0] <= box[:, 0, 1]).all()
        assert (box[:, 1, 0] <= P[:, 1]).all() and (P[:, 1] <= box[:, 1, 1]).all()
        assert angle_in(box[:, 2, 0], box[:, 2, 1], P[:, 2]).all()
        gained.append(sign * (value - plain))
    assert max(gained) > 0.001  # breaking observations took the witness further than meeting them all
