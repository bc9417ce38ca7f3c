"""Simulated logs satisfy every constraint they claim; outliers are exactly those that don't."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.errors import ConfigError
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.simulate.noise import INSIDE
from tests.helpers.hyp import examples


def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def obs_residuals(log):
    """Independent recomputation of g(truth) for every observation: (|e_rho|, b_rho, |e_alpha|)."""
    ob, tr = log.observations, log.truth
    k = np.searchsorted(tr.pose_stamp, ob.stamp)
    assert np.array_equal(tr.pose_stamp[k], ob.stamp)
    where = {int(i): j for j, i in enumerate(tr.landmark_id)}
    lm = tr.landmark_xy[[where[int(i)] for i in ob.landmark_id]]
    dx, dy = lm[:, 0] - tr.pose[k, 0], lm[:, 1] - tr.pose[k, 1]
    rho = np.array([math.hypot(a, b) for a, b in zip(dx, dy)])
    alpha = np.array([math.atan2(b, a) for a, b in zip(dx, dy)]) - tr.pose[k, 2]
    # the pipelines' convention: the relative part of the bound is of the measured range
    b_rho = log.bounds["range_abs"] + log.bounds["range_rel"] * ob.range
    return np.abs(ob.range - rho), b_rho, np.abs(wrap(ob.bearing - alpha)), rho, alpha


def check_observations(log):
    e_rho, b_rho, e_alpha, rho, alpha = obs_residuals(log)
    consistent = (e_rho <= b_rho) & (e_alpha <= log.bounds["bearing"])
    out = log.truth.outliers["observations"]
    assert out.shape == consistent.shape
    assert np.array_equal(consistent, ~out)
    return rho, alpha


def true_twist(log):
    """(v, w) between consecutive true poses, recovered from the exact-arc geometry."""
    p, t = log.truth.pose, log.truth.pose_stamp
    dt = np.diff(t)
    dth = wrap(np.diff(p[:, 2]))
    w = dth / dt
    chord = np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1]))
    half = 0.5 * dth
    sinc = np.where(half == 0, 1.0, np.sin(half) / np.where(half == 0, 1.0, half))
    return chord / (dt * sinc), w


def check_odometry(log):
    v, w = true_twist(log)
    z = log.odometry.twist[:-1]
    b = log.bounds
    ok = (np.abs(z[:, 0] - v) <= b["odom_v"] + b["odom_v_rel"] * np.abs(v)) & (
        np.abs(z[:, 1] - w) <= b["odom_w"] + b["odom_w_rel"] * np.abs(v))
    assert np.array_equal(ok, ~log.truth.outliers["odometry"][:-1])
    # the odometry pose is the dead reckoning of the measured twist from the true start
    pose = [log.truth.pose[0]]
    for k in range(len(log.odometry) - 1):
        x, y, th = pose[-1]
        vv, ww = log.odometry.twist[k]
        dt = log.odometry.stamp[k + 1] - log.odometry.stamp[k]
        h = 0.5 * ww * dt
        c = vv * dt * (math.sin(h) / h if h else 1.0)
        pose.append((x + c * math.cos(th + h), y + c * math.sin(th + h), th + 2 * h))
    pose = np.array(pose)
    assert np.allclose(log.odometry.pose[:, :2], pose[:, :2], rtol=0, atol=1e-9)
    assert np.allclose(wrap(log.odometry.pose[:, 2] - pose[:, 2]), 0, atol=1e-9)


@pytest.mark.parametrize("noise", ["uniform", "triangular", "edges"])
def test_pairs_truth_holds(noise):
    log = simulate(SimConfig(scenario="pairs", seed=3, steps=120, noise=noise, outlier_rate=0.05,
                             wrong_association_rate=0.05))
    check_observations(log)
    assert log.truth.outliers["observations"].any()
    assert np.all(log.truth.pose[:, 2] == 0) and log.bounds["heading"] == 0
    assert log.odometry is None
    wrong = np.asarray(log.meta["wrong_association"], dtype=int)
    assert wrong.size and log.truth.outliers["observations"][wrong].all()


def test_pairs_every_step_sees_an_old_landmark():
    log = simulate(SimConfig(scenario="pairs", seed=5, steps=200, landmarks=4))
    ob = log.observations
    steps = np.unique(ob.stamp)
    assert np.array_equal(steps, log.truth.pose_stamp)  # every step observes something
    seen: set[int] = set()
    for k, t in enumerate(steps):
        ids = set(ob.landmark_id[ob.stamp == t].tolist())
        assert len(ids) >= 2
        if k:
            assert ids & seen, f"step {k} sees no old landmark"
        seen |= ids
    assert log.meta["added_landmarks"] > 0  # 4 landmarks are too few: some were added


def test_landmarks_truth_holds_fov_and_range():
    cfg = SimConfig(scenario="landmarks", seed=7, steps=300, outlier_rate=0.03, wrong_association_rate=0.03)
    log = simulate(cfg)
    rho, alpha = check_observations(log)
    check_odometry(log)
    honest = ~np.isin(np.arange(len(log.observations)), log.meta["wrong_association"])
    lo, hi = cfg.range_limits()
    assert np.all((rho[honest] >= lo) & (rho[honest] <= hi))
    assert np.all(np.abs(wrap(alpha[honest])) <= cfg.half_fov())
    assert log.truth.outliers["odometry"].any()


def test_edges_noise_sits_at_the_bound():
    log = simulate(SimConfig(scenario="landmarks", seed=2, steps=100, noise="edges"))
    e_rho, b_rho, e_alpha, _, _ = obs_residuals(log)
    assert np.allclose(e_rho, INSIDE * b_rho, rtol=1e-9, atol=1e-12)
    assert np.allclose(e_alpha, INSIDE * log.bounds["bearing"], rtol=1e-9, atol=1e-12)


@settings(max_examples=examples(ci=15))
@given(seed=st.integers(0, 2**32 - 1), noise=st.sampled_from(["uniform", "triangular", "edges"]),
       rate=st.sampled_from([1.0, 7.0, 30.0]), out=st.sampled_from([0.0, 0.1]))
def test_landmarks_property(seed, noise, rate, out):
    log = simulate(SimConfig(scenario="landmarks", seed=seed, steps=40, rate=rate, noise=noise,
                             outlier_rate=out, wrong_association_rate=out, landmarks=40, world_size=10))
    check_observations(log)
    check_odometry(log)


def cast_numpy(origin, angles, segs):
    """Independent ray cast (numpy, beams x segments)."""
    d = np.stack([np.cos(angles), np.sin(angles)], axis=-1)[:, None, :]
    a, e = segs[None, :, :2], segs[None, :, 2:] - segs[None, :, :2]
    w = a - origin[None, None, :]
    den = d[..., 0] * e[..., 1] - d[..., 1] * e[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]) / den
        s = (w[..., 0] * d[..., 1] - w[..., 1] * d[..., 0]) / den
    t = np.where((den != 0) & (t > 0) & (s >= 0) & (s <= 1), t, np.inf)
    return t.min(axis=1)


@pytest.mark.parametrize("sensor,world", [("urg-04lx", "rooms"), ("sick", "open"), ("urg-04lx", "pillars")])
def test_lidar_beams_match_the_true_ray_cast(sensor, world):
    """``--beam-model ray``; the cone model (the default) is checked in test_simulate_cone.py."""
    log = simulate(SimConfig(scenario="lidar", sensor=sensor, world=world, seed=4, steps=60,
                             outlier_rate=0.01, beam_model="ray"))
    sc, tr, b = log.scans, log.truth, log.bounds
    out = tr.outliers["scans"]
    assert out.shape == sc.ranges.shape and out.any()
    mx, my, myaw = sc.mount
    for k in range(len(sc)):
        x, y, th = tr.pose[k]
        origin = np.array([x + math.cos(th) * mx - math.sin(th) * my, y + math.sin(th) * mx + math.cos(th) * my])
        n = sc.offsets[k + 1] - sc.offsets[k]
        ang = th + myaw + sc.angle_min[k] + np.arange(n) * sc.angle_increment[k]
        d = cast_numpy(origin, ang, tr.world)
        z = sc.ranges[sc.offsets[k]:sc.offsets[k + 1]].astype(np.float64)
        valid = sc.valid[sc.offsets[k]:sc.offsets[k + 1]]
        o = out[sc.offsets[k]:sc.offsets[k + 1]]
        e = b["range_abs"] + b["range_rel"] * np.where(np.isfinite(d), d, 0)
        ok_valid = valid & (np.abs(z - d) <= e)
        # a no-return beam claims d + e(d) > range_max (or a too-short return)
        ok_noreturn = ~valid & ((d + e > sc.range_max[k]) | (d - e < sc.range_min[k]))
        assert np.array_equal(ok_valid | ok_noreturn, ~o), f"scan {k}"
        assert np.all(valid == ((z >= sc.range_min[k]) & (z <= sc.range_max[k])))
        bad = z[~valid]
        if sensor == "urg-04lx":
            assert np.all(bad == 0.0)
        else:
            assert np.all(np.isinf(bad))
    assert (~sc.valid).any() and sc.valid.any()


@pytest.mark.parametrize("world", ["rooms", "corridor", "pillars", "open"])
def test_lidar_robot_never_touches_a_wall(world):
    from ivslam_cli.simulate.lidar import CLEARANCE
    log = simulate(SimConfig(scenario="lidar", world=world, seed=11, steps=400))
    p, segs = log.truth.pose[:, :2], log.truth.world
    a, ab = segs[:, :2], segs[:, 2:] - segs[:, :2]
    t = np.clip(((p[:, None, :] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0, 1)
    dist = np.linalg.norm(p[:, None, :] - (a + t[..., None] * ab), axis=-1).min(axis=1)
    assert dist.min() >= CLEARANCE
    assert np.ptp(p[:, 0]) + np.ptp(p[:, 1]) > 2.0  # it does move
    check_odometry(log)


@pytest.mark.parametrize("scenario", ["pairs", "landmarks", "lidar"])
def test_deterministic_under_seed(scenario):
    a = simulate(SimConfig(scenario=scenario, seed=9, steps=30, outlier_rate=0.05))
    b = simulate(SimConfig(scenario=scenario, seed=9, steps=30, outlier_rate=0.05))
    c = simulate(SimConfig(scenario=scenario, seed=10, steps=30, outlier_rate=0.05))
    assert np.array_equal(a.truth.pose, b.truth.pose) and not np.array_equal(a.truth.pose, c.truth.pose)
    for name in ("scans", "odometry", "observations"):
        sa, sb = getattr(a, name), getattr(b, name)
        if sa is not None:
            for f, v in vars(sa).items():
                if isinstance(v, np.ndarray):
                    assert np.array_equal(v, getattr(sb, f), equal_nan=True), f"{name}.{f}"
    assert a.meta == b.meta and a.bounds == b.bounds


def test_stamps_are_exact_in_nanoseconds():
    log = simulate(SimConfig(scenario="landmarks", seed=1, steps=50, rate=7.0))
    t = log.truth.pose_stamp
    assert np.all(t * 512 == np.round(t * 512)) and np.all(np.diff(t) > 0)
    assert abs((t[-1] - t[0]) - 49 / 7.0) < 2e-3


@pytest.mark.parametrize("kwargs,msg", [
    ({"scenario": "nope"}, "unknown scenario"),
    ({"noise": "gauss"}, "unknown noise"),
    ({"steps": 1}, "--steps"),
    ({"outlier_rate": 1.5}, "--outlier-rate"),
    ({"bounds": {"range_abs": -1.0}}, "range_abs"),
    ({"scenario": "pairs", "bounds": {"odom_v": 1.0}}, "does not apply"),
    ({"scenario": "lidar", "world": "/no/such/world.toml"}, "unknown world"),
    ({"scenario": "lidar", "sensor": "velodyne"}, "unknown sensor"),
    ({"min_range": 5.0, "max_range": 1.0}, "--min-range"),
])
def test_bad_config_is_a_config_error(kwargs, msg):
    with pytest.raises(ConfigError, match=msg):
        SimConfig(**kwargs).validate()


def test_world_file(tmp_path):
    f = tmp_path / "w.toml"
    f.write_text('start = [2.0, 2.0, 0.0]\npolygons = [[[0, 0], [6, 0], [6, 4], [0, 4]]]\n'
                 'polylines = [[[3, 0], [3, 2.5]]]\n')
    log = simulate(SimConfig(scenario="lidar", world=str(f), steps=40, seed=1))
    assert log.truth.world.shape == (5, 4) and log.meta["world"] == "w"
    f.write_text("start = [0.1, 0.1, 0]\npolygons = [[[0, 0], [6, 0], [6, 4]]]\n")
    with pytest.raises(ConfigError, match="from a wall"):
        SimConfig(scenario="lidar", world=str(f)).validate()
    f.write_text("start = [")
    with pytest.raises(ConfigError, match="cannot read world file"):
        SimConfig(scenario="lidar", world=str(f)).validate()
