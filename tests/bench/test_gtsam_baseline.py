"""The GTSAM baseline of the benchmark (``bench/gtsam_baseline.py``): it runs, its figures are
what they claim to be, and importing gtsam leaves the process fit for our kernels."""

from __future__ import annotations

import copy
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

gtsam = pytest.importorskip("gtsam")

from bench.gtsam_baseline import (  # noqa: E402
    D2_SE2,
    D2_XY,
    _logmap,
    aligned_rmse,
    dead_reckon,
    pose_stamps,
    relative,
    run_gtsam,
    truth_at,
    wrap,
)
from ivslam_cli.simulate import SimConfig, simulate  # noqa: E402

from tests.helpers.hyp import examples  # noqa: E402
from tests.helpers.paths import REPO  # noqa: E402


@pytest.fixture(scope="module")
def sim_log():
    return simulate(SimConfig(scenario="landmarks", seed=3, steps=600, landmarks=15, world_size=10.0))


@pytest.fixture(scope="module")
def sim_fig(sim_log):
    return run_gtsam(sim_log, bounds=sim_log.bounds, return_estimate=True)


def test_importing_gtsam_keeps_round_to_nearest_and_h5py_numba_working(tmp_path):
    """Codac left the FPU rounding upward and a later h5py import crashed: gtsam must not."""
    code = textwrap.dedent(f"""
        import ctypes, ctypes.util
        libm = ctypes.CDLL(ctypes.util.find_library("m"))
        import gtsam
        assert libm.fegetround() == 0, "import"
        g = gtsam.NonlinearFactorGraph(); v = gtsam.Values(); v.insert(0, gtsam.Pose2())
        g.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(1, 2, 0.1), gtsam.noiseModel.Isotropic.Sigma(3, 0.1)))
        r = gtsam.LevenbergMarquardtOptimizer(g, v).optimize(); gtsam.Marginals(g, r).marginalCovariance(0)
        assert libm.fegetround() == 0, "optimise"
        import h5py
        with h5py.File({str(tmp_path / "x.h5")!r}, "w") as f:
            f["a"] = [1.0, 2.0]
        from ivslam_cli.interval.rounding import down, up
        assert down(1.0) < 1.0 < up(1.0) and down(0.1) < 0.1 < up(0.1)
        print("ok")
    """)
    res = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "ok"


# --- helpers ------------------------------------------------------------------------------

def test_dead_reckoning_of_noise_free_twist_is_the_simulated_truth():
    """Same zero-order hold and exact arcs as the simulator: noise-free twist gives the truth."""
    zero = {k: 0.0 for k in ("odom_v", "odom_v_rel", "odom_w", "odom_w_rel")}
    log = simulate(SimConfig(scenario="landmarks", seed=2, steps=400, landmarks=10, world_size=10.0, bounds=zero))
    odo, tr = log.odometry, log.truth
    assert np.array_equal(odo.stamp, tr.pose_stamp)
    p, sv, sw, dist = dead_reckon(odo.stamp, odo.twist, tr.pose_stamp, tr.pose[0], (0.1, 0.0), (0.2, 0.0))
    assert np.abs(p[:, :2] - tr.pose[:, :2]).max() < 1e-9
    assert np.abs(wrap(p[:, 2] - tr.pose[:, 2])).max() < 1e-9
    dt = np.diff(odo.stamp)
    np.testing.assert_allclose(sv, 0.1 * dt, rtol=1e-9)
    np.testing.assert_allclose(sw, 0.2 * dt, rtol=1e-9)
    np.testing.assert_allclose(dist, np.abs(odo.twist[:-1, 0]) * dt, rtol=1e-9)


def test_dead_reckoning_between_sparse_stamps_sums_the_segments():
    """Stamps between odometry samples split a hold segment; the sums add up across it."""
    stamp = np.array([0.0, 1.0, 2.0, 3.0])
    twist = np.array([[1.0, 0.0], [2.0, 0.0], [0.0, np.pi / 2], [5.0, 5.0]])
    t = np.array([0.0, 0.5, 2.0, 3.0])
    p, sv, sw, dist = dead_reckon(stamp, twist, t, np.zeros(3), (0.0, 1.0), (0.5, 0.0))
    np.testing.assert_allclose(p, [[0, 0, 0], [0.5, 0, 0], [3.0, 0, 0], [3.0, 0, np.pi / 2]], atol=1e-12)
    np.testing.assert_allclose(dist, [0.5, 2.5, 0.0])
    np.testing.assert_allclose(sv, [0.5, 2.5, 0.0])  # rel part only: σ_v = |v|
    np.testing.assert_allclose(sw, [0.25, 0.75, 0.5])


def test_pose_stamps_keyframes_fill_gaps():
    obs = np.array([0.5, 0.5, 1.0, 4.0, -1.0])
    t = pose_stamps(obs, 0.0, 1.0)
    np.testing.assert_allclose(t, [0.0, 0.5, 1.0, 2.0, 3.0, 4.0])
    assert np.all(np.diff(t) <= 1.0 + 1e-12)
    np.testing.assert_allclose(pose_stamps(obs, 0.0, np.inf), [0.0, 0.5, 1.0, 4.0])
    np.testing.assert_allclose(pose_stamps(obs, 0.0, np.inf, t_end=2.5), [0.0, 0.5, 1.0, 2.5])
    np.testing.assert_allclose(pose_stamps(obs, 0.0, 2.0, t_end=6.0), [0.0, 0.5, 1.0, 2.5, 4.0, 6.0])
    np.testing.assert_allclose(pose_stamps(obs, 0.0, 2.0, t_end=6.5), [0.0, 0.5, 1.0, 2.5, 4.0, 5.25, 6.5])


def test_truth_at_unwraps_heading_and_masks_gaps():
    ts = np.array([0.0, 1.0, 2.0, 5.0])
    pose = np.array([[0, 0, 3.0], [1, 0, -3.0], [2, 0, -3.0], [5, 0, -3.0]])
    p, ok = truth_at(ts, pose, np.array([0.5, 1.5, 3.0, 6.0]), max_gap=0.5 * 3 + 0.1)
    assert abs(wrap(p[0, 2] - np.pi)) < 1e-12  # halfway between 3 and -3 across ±π, not 0
    assert ok.tolist() == [True, True, False, False]  # 3.0 in the 3 s gap; 6.0 after the end


@settings(max_examples=examples(ci=50))
@given(st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-3.14, 3.14)), min_size=2, max_size=2))
def test_relative_and_logmap_match_gtsam(poses):
    a, b = (np.array([p]) for p in poses)
    ga, gb = gtsam.Pose2(*poses[0]), gtsam.Pose2(*poses[1])
    r = ga.between(gb)
    np.testing.assert_allclose(relative(a, b)[0, :2], [r.x(), r.y()], atol=1e-9)
    assert abs(wrap(relative(a, b)[0, 2] - r.theta())) < 1e-9
    # GTSAM's Logmap takes cos(θ) − 1 above |θ| = 1e-10: its error there is ~ε |t| / |θ|
    # (4.5e-7 at θ = 1e-10, |t| = 1.6), ours is a few ulps
    t, th = np.hypot(r.x(), r.y()), abs(r.theta())
    tol = 1e-8 + (4e-16 * t / th if th > 0.0 else 0.0)
    np.testing.assert_allclose(_logmap(relative(a, b))[0], gtsam.Pose2.Logmap(r), atol=tol)


@settings(max_examples=examples(ci=50))
@given(st.floats(-3.1, 3.1), st.floats(-10, 10), st.floats(-10, 10), st.integers(0, 2**32 - 1))
def test_aligned_rmse_removes_exactly_a_rigid_motion(th, tx, ty, seed):
    rng = np.random.default_rng(seed)
    a = rng.uniform(-5, 5, (8, 2))
    r = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    b = a @ r.T + [tx, ty]
    assert aligned_rmse(a, b) < 1e-9
    noise = rng.normal(0, 0.1, a.shape)
    moved = aligned_rmse(a + noise, b)
    assert moved == pytest.approx(aligned_rmse(a + noise, a), abs=1e-9)  # the motion does not matter
    assert moved <= np.sqrt(np.mean(np.sum(noise**2, axis=1))) + 1e-12  # the best fit beats the true one
    assert aligned_rmse(a, a[:, ::-1]) > 0.1  # a reflection is not a rigid motion


# --- the baseline on a simulated log ------------------------------------------------------

def test_simulated_log_small_error_and_consistent_figures(sim_log, sim_fig):
    f, log = sim_fig, sim_log
    obs = log.observations
    assert f["n_observations"] == len(obs) and f["n_observations_dropped"] == 0
    assert f["n_observation_poses"] == len(np.unique(obs.stamp))
    assert f["n_poses"] == f["n_observation_poses"] + f["n_keyframes"] == len(f["est_stamp"])
    assert f["t_end"] == obs.stamp[-1] and f["span"] == "observations"
    assert np.all(np.diff(f["est_stamp"]) <= f["pose_every"] + 1e-9)
    assert f["n_landmarks"] == len(np.unique(obs.landmark_id)) == f["n_scored_landmarks"]
    assert f["n_factors"] == 1 + (f["n_poses"] - 1) + len(obs)
    assert f["error_final"] < f["error_initial"]
    for k in ("t_build_s", "t_optimize_s", "t_marginals_s"):
        assert f[k] > 0
    assert f["t_total_s"] == pytest.approx(f["t_build_s"] + f["t_optimize_s"] + f["t_marginals_s"])
    for p in ("pos_err", "heading_err", "lm_err"):
        assert 0 <= f[f"{p}_median"] <= f[f"{p}_p95"] <= f[f"{p}_max"]
        assert f[f"{p}_rmse"] <= f[f"{p}_max"]
    # small: centimetres with range bounds of 5 cm + 1 %, and well below dead reckoning
    b = log.bounds
    assert f["pos_err_rmse"] < b["range_abs"] / 2
    assert f["lm_err_max"] < b["range_abs"]
    assert f["lm_err_aligned_rmse"] <= f["lm_err_rmse"]
    assert f["pos_err_rmse"] < f["dead_reckoning_pos_err_rmse"] / 3
    # the anchor: the first pose is the truth at t0 (prior σ = 1e-4)
    assert f["t0"] == log.odometry.stamp[0]
    assert np.abs(f["est_pose"][0] - log.truth.pose[0]).max() < 5e-4
    # σ = bound/3 underestimates the spread of uniform noise (bound/√3), yet nearly all inside
    for k in ("pose_xy_in_3sigma", "pose_se2_in_3sigma", "heading_in_3sigma", "lm_xy_in_3sigma"):
        assert 0.9 <= f[k] <= 1.0


def test_simulated_figures_recomputed_independently(sim_log):
    """Recompute errors and containment from the returned estimate, by another route."""
    tr = sim_log.truth
    f = run_gtsam(sim_log, bounds=sim_log.bounds, pose_every=np.inf, return_estimate=True)
    assert f["n_keyframes"] == 0  # t0 is an observation stamp here; no keyframes: all on the truth grid
    k = np.searchsorted(tr.pose_stamp, f["est_stamp"])
    assert np.array_equal(tr.pose_stamp[k], f["est_stamp"])
    true = tr.pose[k]
    e = np.linalg.norm(true[:, :2] - f["est_pose"][:, :2], axis=1)
    assert f["pos_err_median"] == pytest.approx(np.median(e))
    assert f["pos_err_rmse"] == pytest.approx(np.sqrt(np.mean(e**2)))
    # 2D: truth - estimate in the estimate's frame against the x-y block of the covariance
    d2, d2_full = [], []
    for (x, y, th), est, cov in zip(true, f["est_pose"], f["est_pose_cov"]):
        assert np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) > 0)
        g_est, g_true = gtsam.Pose2(*est), gtsam.Pose2(x, y, th)
        local = g_est.transformTo(gtsam.Point2(x, y))
        d2.append(local @ np.linalg.inv(cov[:2, :2]) @ local)
        xi = gtsam.Pose2.Logmap(g_est.between(g_true))
        d2_full.append(xi @ np.linalg.inv(cov) @ xi)
    assert f["pose_xy_in_3sigma"] == pytest.approx(np.mean(np.array(d2) <= D2_XY))
    assert f["pose_se2_in_3sigma"] == pytest.approx(np.mean(np.array(d2_full) <= D2_SE2))
    lm = {int(i): xy for i, xy in zip(tr.landmark_id, tr.landmark_xy)}
    e_lm = np.array([lm[int(i)] - xy for i, xy in zip(f["est_landmark_id"], f["est_landmark_xy"])])
    d2_lm = [v @ np.linalg.inv(c) @ v for v, c in zip(e_lm, f["est_landmark_cov"])]
    assert f["lm_err_max"] == pytest.approx(np.linalg.norm(e_lm, axis=1).max())
    assert f["lm_xy_in_3sigma"] == pytest.approx(np.mean(np.array(d2_lm) <= D2_XY))


def test_marginals_are_gtsams(sim_log):
    """The returned covariances are GTSAM's marginals (a looser odometry bound widens them)."""
    loose = dict(sim_log.bounds, odom_v=10 * sim_log.bounds["odom_v"], odom_w=10 * sim_log.bounds["odom_w"])
    tight = run_gtsam(sim_log, bounds=sim_log.bounds)
    wide = run_gtsam(sim_log, bounds=loose)
    assert wide["pose_3sigma_major_median"] > tight["pose_3sigma_major_median"]


def test_huber_beats_plain_least_squares_on_gross_outliers():
    log = simulate(SimConfig(scenario="landmarks", seed=4, steps=600, landmarks=15, world_size=10.0,
                             outlier_rate=0.05, outlier_magnitude=30))
    assert log.truth.outliers["observations"].sum() > 10
    robust = run_gtsam(log, bounds=log.bounds, robust=True, robust_odometry=True)
    plain = run_gtsam(log, bounds=log.bounds, robust=False)
    assert robust["robust"] and robust["robust_odometry"] and not plain["robust"]
    assert robust["pos_err_rmse"] < plain["pos_err_rmse"]
    assert robust["lm_err_max"] < plain["lm_err_max"]


def test_observations_before_t0_are_dropped_and_counted(sim_log):
    log = copy.deepcopy(sim_log)
    log.odometry.stamp = log.odometry.stamp[20:]
    log.odometry.twist = log.odometry.twist[20:]
    f = run_gtsam(log, bounds=log.bounds)
    early = int((sim_log.observations.stamp < log.odometry.stamp[0]).sum())
    assert early > 0
    assert f["n_observations_dropped"] == early
    assert f["n_observations"] == len(sim_log.observations) - early
    assert f["t0"] == log.odometry.stamp[0]


def test_span_odometry_continues_to_the_last_odometry_stamp(sim_log):
    log = copy.deepcopy(sim_log)
    last_obs = log.observations.stamp[-1]
    keep = log.observations.stamp < last_obs - 5.0  # 5 s of odometry after the last observation
    for name in ("stamp", "landmark_id", "range", "bearing"):
        setattr(log.observations, name, getattr(log.observations, name)[keep])
    short = run_gtsam(log, bounds=log.bounds)
    full = run_gtsam(log, bounds=log.bounds, span="odometry")
    assert short["t_end"] == log.observations.stamp[-1]
    assert full["t_end"] == log.odometry.stamp[-1]
    assert full["n_poses"] >= short["n_poses"] + 5  # keyframes every second over the tail
    assert full["n_observations"] == short["n_observations"] == int(keep.sum())
    with pytest.raises(ValueError, match="span"):
        run_gtsam(log, bounds=log.bounds, span="scans")


def test_missing_streams_are_refused(sim_log):
    log = copy.copy(sim_log)
    log.truth = None
    with pytest.raises(ValueError, match="truth"):
        run_gtsam(log, bounds=sim_log.bounds)


# --- one MRCLAM robot (about a second) ----------------------------------------------------

@pytest.mark.datasets
def test_mrclam_robot4_beats_dead_reckoning(datasets):
    from bench.gtsam_baseline import MRCLAM_BOUNDS
    from ivslam_cli.logs import read_log

    log = read_log(datasets / "mrclam" / "MRCLAM_Dataset6", robot=4)
    f = run_gtsam(log, bounds=MRCLAM_BOUNDS)
    assert f["n_observations"] == len(log.observations)
    assert f["n_scored_landmarks"] == 15
    assert f["n_scored_poses"] <= f["n_poses"]
    assert f["pos_err_median"] < f["dead_reckoning_pos_err_median"] / 2
    assert f["pos_err_p95"] < f["dead_reckoning_pos_err_p95"] / 2
    for k in ("pose_xy_in_3sigma", "pose_se2_in_3sigma", "lm_xy_in_3sigma"):
        assert 0.0 <= f[k] <= 1.0
