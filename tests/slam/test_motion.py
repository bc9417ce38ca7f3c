"""How far the robot may move between two times (:meth:`MotionSteps.reach_between`), against the
simulated truth: twist odometry (rates times the time spent in each step) and pose increments
(each step's whole bound)."""

from __future__ import annotations

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from ivslam_cli.config import resolve_config
from ivslam_cli.logs.model import Odometry
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.slam.motion import MotionBounds, motion_steps
from tests.helpers.hyp import examples
from tests.helpers.lidar_truth import true_pose_at


def _true_pose(tr, t: np.ndarray, t_ref: float = 0.0) -> np.ndarray:
    """The true poses at times ``t_ref + t``, on the simulated robot's arcs (as a swept scan's)."""
    return true_pose_at(tr, t, t_ref)


def _motion(seed: int, increments: bool, over: dict):
    """A short simulated log and its motion steps: the twist odometry, or the true poses as pose
    increments under the bounds ``over``."""
    log = simulate(SimConfig(scenario="lidar", world="rooms", seed=seed, steps=30))
    tr, odo = log.truth, log.odometry
    if increments:
        odo = Odometry(stamp=tr.pose_stamp.copy(), pose=tr.pose.copy(), twist=None)
    bounds = MotionBounds.from_config(resolve_config(None, over if increments else {}, log_bounds=log.bounds))
    return log, tr, motion_steps(odo, bounds, log.scans.stamp, prefer="pose" if increments else "twist")


@given(st.integers(0, 2**31 - 1), st.booleans(), st.lists(st.tuples(st.floats(0, 1), st.floats(0, 0.25)),
                                                          min_size=1, max_size=20))
@settings(max_examples=examples(ci=25))
def test_the_reach_between_two_times_holds_the_true_motion(seed, increments, spans):
    log = simulate(SimConfig(scenario="lidar", world="rooms", seed=seed, steps=30))
    tr, odo = log.truth, log.odometry
    if increments:  # the true poses as pose increments, within the default pose bounds
        odo = Odometry(stamp=tr.pose_stamp.copy(), pose=tr.pose.copy(), twist=None)
    bounds = MotionBounds.from_config(resolve_config(None, {}, log_bounds=log.bounds))
    m = motion_steps(odo, bounds, log.scans.stamp, prefer="pose" if increments else "twist")
    t_lo, t_hi = float(tr.pose_stamp[0]), float(tr.pose_stamp[-1])
    t0 = np.array([t_lo + f * (t_hi - t_lo) for f, _ in spans])
    t1 = np.minimum(t0 + np.array([tau for _, tau in spans]), t_hi)
    reach = m.reach_between(t0, t1)
    p0, p1 = _true_pose(tr, t0), _true_pose(tr, t1)
    assert np.all(np.hypot(p1[:, 0] - p0[:, 0], p1[:, 1] - p0[:, 1]) <= reach[:, 0])
    assert np.all(np.abs(p1[:, 2] - p0[:, 2]) <= reach[:, 1])
    assert np.all(reach >= 0.0)


@given(st.integers(0, 2**31 - 1), st.booleans(), st.lists(st.tuples(st.floats(0, 1), st.floats(0, 0.25)),
                                                          min_size=1, max_size=10), st.integers(2, 800))
@settings(max_examples=examples(ci=25))
def test_the_drift_between_two_beams_holds_the_true_motion(seed, increments, spans, n_beams):
    """Between any two consecutive beams of a scan taking ``n_beams`` evenly over ``[t0, t1]``, the
    true robot moves and turns within :meth:`MotionSteps.drift_between`; with pose increments
    that is the whole sweep's reach unless the top speed and turn rate are stated."""
    log = simulate(SimConfig(scenario="lidar", world="rooms", seed=seed, steps=30))
    tr, odo = log.truth, log.odometry
    if increments:
        odo = Odometry(stamp=tr.pose_stamp.copy(), pose=tr.pose.copy(), twist=None)
    cfg = resolve_config(None, {}, log_bounds=log.bounds)
    bounds = MotionBounds.from_config(cfg)
    m = motion_steps(odo, bounds, log.scans.stamp, prefer="pose" if increments else "twist")
    t_lo, t_hi = float(tr.pose_stamp[0]), min(float(tr.pose_stamp[-1]), float(m.node_stamp[-1]))  # the odometry's span
    t0 = np.array([t_lo + f * (t_hi - t_lo) for f, _ in spans])
    t1 = np.minimum(t0 + np.array([tau for _, tau in spans]), t_hi)
    n = np.full(t0.shape, n_beams)
    drift = m.drift_between(t0, t1, n)
    dt = (t1 - t0) / (n_beams - 1)
    ref = float(tr.pose_stamp[0])
    for e in range(t0.shape[0]):
        p = _true_pose(tr, (t0[e] - ref) + dt[e] * np.arange(n_beams), ref)
        assert np.all(np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1])) <= drift[e, 0])
        assert np.all(np.abs(np.diff(p[:, 2])) <= drift[e, 1])
    if increments:
        assert np.array_equal(drift, m.reach_between(t0, t1))
    # the robot's limits (the simulated robot's speed and turn rate are within these)
    v = np.hypot(np.diff(tr.pose[:, 0]), np.diff(tr.pose[:, 1])) / np.diff(tr.pose_stamp)
    w = np.abs(np.diff(np.unwrap(tr.pose[:, 2]))) / np.diff(tr.pose_stamp)
    top = MotionBounds.from_config(resolve_config(None, {"bounds.speed_max": 1.01 * v.max() + 1e-9,
                                                         "bounds.turn_rate_max": 1.01 * w.max() + 1e-9},
                                                  log_bounds=log.bounds))
    mt = motion_steps(odo, top, log.scans.stamp, prefer="pose" if increments else "twist")
    capped = mt.drift_between(t0, t1, n)
    assert np.all(capped <= drift)
    ulps = 4.0 * np.spacing(np.abs(t0) + np.abs(t1))  # the rounding of stamps near 1.7e9 s
    assert np.all(capped[:, 0] <= (dt + ulps / (n_beams - 1)) * mt.speed_max * (1 + 1e-9))
    assert np.all(mt.reach_between(t0, t1)[:, 1] <= (t1 - t0 + ulps) * mt.turn_max * (1 + 1e-9))
    for e in range(t0.shape[0]):
        p = _true_pose(tr, (t0[e] - ref) + dt[e] * np.arange(n_beams), ref)
        assert np.all(np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1])) <= capped[e, 0])
        assert np.all(np.abs(np.diff(p[:, 2])) <= capped[e, 1])


@given(st.integers(0, 2**31 - 1), st.booleans(), st.lists(st.tuples(st.floats(0, 1), st.floats(-0.2, 0.2)),
                                                          min_size=1, max_size=10))
@settings(max_examples=examples(ci=25))
def test_the_nominal_turn_holds_the_true_heading_within_its_error(seed, increments, spans):
    """A sweep from stamp ``s`` to ``s + T``: the true heading at every time of it is within ``e``
    of ``θ(s) + ω̂ (t − s)`` (:meth:`MotionSteps.turn_between`), the nominal turn that deskews the
    beams; with pose increments under a stated top angular acceleration (the simulated robot
    turns at a constant rate within a step: any ``α`` holds) and within one step."""
    log, tr, m = _motion(seed, increments, {"bounds.turn_accel_max": 3.0})
    t_lo, t_hi = float(tr.pose_stamp[0]), min(float(tr.pose_stamp[-1]), float(m.node_stamp[-1]))
    s = np.array([t_lo + f * (t_hi - t_lo) for f, _ in spans])
    T = np.array([tau for _, tau in spans])
    t0, t1 = np.maximum(s + np.minimum(T, 0.0), t_lo), np.minimum(s + np.maximum(T, 0.0), t_hi)
    w, e, eta = m.turn_between(s, t0, t1, np.full(s.shape, 100))
    ref = float(tr.pose_stamp[0])
    for k in range(s.shape[0]):
        ts = np.linspace(t0[k] - ref, t1[k] - ref, 100)
        th = _true_pose(tr, ts, ref)[:, 2]
        th_s = _true_pose(tr, np.array([s[k] - ref]), ref)[0, 2]
        assert np.all(np.abs(th - th_s - w[k] * (ts - (s[k] - ref))) <= e[k] + 1e-12), (k, w[k], e[k])
        assert np.all(np.abs(np.diff(th) - w[k] * np.diff(ts)) <= eta[k] + 1e-12)
    reach = m.reach_between(t0, t1)[:, 1]
    assert np.all(e <= reach)
    if not increments:  # within one step of a twist, the nominal turn is much tighter than the reach
        ns = m.node_stamp
        one = np.searchsorted(ns, t0, side="right") == np.searchsorted(ns, t1, side="left")
        turning = one & (np.abs(w) * (t1 - t0) > 0.01)
        assert np.all(e[turning] < 0.5 * reach[turning])


@given(st.integers(0, 2**31 - 1), st.booleans(), st.lists(st.tuples(st.integers(0, 28), st.floats(0.0, 1.0)),
                                                          min_size=1, max_size=10))
@settings(max_examples=examples(ci=25))
@example(5995, False, [(20, 0.0625)])  # a turning step: its chord strays from the heading, the arc does not
def test_the_nominal_move_holds_the_true_position_within_its_error(seed, increments, spans):
    """A sweep from stamp ``s`` (an odometry stamp) over part of the step after it: the true
    position at every time of it is within ``E`` of ``p(s) + R(θ(s)) V (t − s)``
    (:meth:`MotionSteps.move_between`), the nominal move the matcher takes each beam's sensor
    from; with pose increments under a stated top acceleration (the simulated robot drives arcs
    within a step: 0.5 m/s · its turn rate)."""
    log, tr, m = _motion(seed, increments, {"bounds.accel_max": 2.0})
    ps = tr.pose_stamp
    k = np.array([min(i, len(ps) - 2) for i, _ in spans])
    s = ps[k]
    t1 = s + np.array([f for _, f in spans]) * (ps[k + 1] - ps[k])
    V, E = m.move_between(s, s.copy(), t1)
    ref = float(ps[0])
    for j in range(s.shape[0]):
        ts = np.linspace(0.0, t1[j] - s[j], 50)
        p = _true_pose(tr, (s[j] - ref) + ts, ref)
        p0 = _true_pose(tr, np.array([s[j] - ref]), ref)[0]
        c, sn = np.cos(p0[2]), np.sin(p0[2])
        nom = np.column_stack([p0[0] + (c * V[j, 0] - sn * V[j, 1]) * ts, p0[1] + (sn * V[j, 0] + c * V[j, 1]) * ts])
        assert np.all(np.hypot(p[:, 0] - nom[:, 0], p[:, 1] - nom[:, 1]) <= E[j] + 1e-12), (j, V[j], E[j])
    reach = m.reach_between(s, t1)[:, 0]
    assert np.all(E <= reach)
    moving = (t1 - s > 0.02) & (np.hypot(V[:, 0], V[:, 1]) > 0.1)
    assert np.all(E[moving] < 0.5 * reach[moving])  # the nominal move is much tighter than the reach


@given(st.integers(0, 2**31 - 1), st.booleans(), st.lists(
    st.tuples(st.floats(0, 1), st.booleans(), st.floats(-0.3, 0.3), st.floats(0.0, 0.15), st.floats(0.0, 0.05)),
    min_size=1, max_size=8))
@settings(max_examples=examples(ci=40))
def test_a_scan_off_its_stamp_keeps_the_truth_within_the_nominal_turn_and_move(seed, increments, spans):
    """A scan paired with the odometry at ``s`` but taken over ``[s + d, s + d + T]`` (its own
    clock: :mod:`ivslam_cli.slam.lidar.scan_clock`), every time of it up to ``slack`` off: the
    true heading and position at each are within ``e``, ``E`` of ``θ(s) + ω̂ (t − s)``, ``p(s) +
    R(θ(s)) V (t − s)`` at its nominal time ``t`` (:meth:`MotionSteps.turn_between`,
    :meth:`~MotionSteps.move_between` with ``slack``; windows that leave ``s``'s step or do not
    hold ``s``: with pose increments the chain of the steps' chords), and within the reach."""
    log, tr, m = _motion(seed, increments, {"bounds.turn_accel_max": 3.0, "bounds.accel_max": 2.0})
    ns = m.node_stamp
    t_lo, t_hi = float(ns[0]), min(float(tr.pose_stamp[-1]), float(ns[-1]))
    ref = float(tr.pose_stamp[0])
    for f, at_node, d, T, sl in spans:
        s = t_lo + f * (t_hi - t_lo)
        if at_node:
            s = float(ns[np.searchsorted(ns, s) - (s > ns[0])])
        t0, t1 = s + d, s + d + T
        if not (t_lo <= min(t0 - sl, s) and max(t1 + sl, s) <= t_hi):
            continue
        S, T0, T1, SL = (np.array([v]) for v in (s, t0, t1, sl))
        w, e, _ = m.turn_between(S, T0, T1, np.array([60]), SL)
        V, E = m.move_between(S, T0, T1, SL)
        reach = m.reach_between(np.minimum(T0 - SL, S), np.maximum(T1 + SL, S))[0]
        assert e[0] <= reach[1] and E[0] <= reach[0]
        ts = np.linspace(t0 - ref, t1 - ref, 60)
        p0 = _true_pose(tr, np.array([s - ref]), ref)[0]
        c, sn = np.cos(p0[2]), np.sin(p0[2])
        u = ts - (s - ref)
        nom = np.column_stack([p0[0] + (c * V[0, 0] - sn * V[0, 1]) * u, p0[1] + (sn * V[0, 0] + c * V[0, 1]) * u])
        for delta in np.linspace(-sl, sl, 5):
            p = _true_pose(tr, ts + delta, ref)
            assert np.all(np.abs(p[:, 2] - p0[2] - w[0] * u) <= e[0] + 1e-12), (s, d, T, sl, w, e)
            assert np.all(np.hypot(p[:, 0] - nom[:, 0], p[:, 1] - nom[:, 1]) <= E[0] + 1e-12), (s, d, T, sl, V, E)


def test_the_chain_of_chords_is_the_one_step_bound_within_one_step():
    """Within one step from a stamp at its start, the chain of chords (taken when a slack is
    given) gives the nominal turn and move of the one-step bounds, within the stamps' ulps."""
    log, tr, m = _motion(3, True, {"bounds.turn_accel_max": 3.0, "bounds.accel_max": 2.0})
    ns = m.node_stamp
    k = np.arange(2, 20)
    s, t1 = ns[k], ns[k] + 0.6 * (ns[k + 1] - ns[k])
    n, tiny = np.full(k.shape, 100), np.full(k.shape, 1e-300)
    w0, e0, eta0 = m.turn_between(s, s.copy(), t1, n)
    w1, e1, eta1 = m.turn_between(s, s.copy(), t1, n, tiny)
    V0, E0 = m.move_between(s, s.copy(), t1)
    V1, E1 = m.move_between(s, s.copy(), t1, tiny)
    assert np.allclose(w0, w1, rtol=1e-9, atol=1e-12) and np.allclose(V0, V1, rtol=1e-9, atol=1e-12)
    assert np.all(e1 >= e0 * (1 - 1e-9)) and np.allclose(e0, e1, rtol=1e-3)
    assert np.all(E1 >= E0 * (1 - 1e-9)) and np.allclose(E0, E1, rtol=1e-3)
    assert np.allclose(eta0, eta1, rtol=1e-6)


@given(st.integers(0, 2**31 - 1), st.floats(0.2, 1.0), st.floats(2.0, 8.0), st.lists(
    st.tuples(st.floats(0.05, 0.95), st.booleans(), st.floats(-0.2, 0.2), st.floats(0.0, 0.1),
              st.floats(0.0, 0.02)), min_size=1, max_size=8))
@settings(max_examples=examples(ci=40))
def test_the_chain_holds_a_heading_that_bends_within_its_steps_at_the_stated_rate(seed, amp, omega, spans):
    """A heading ``θ(t) = a sin(Ω t) + 1.01 a Ω t`` (``|θ''| ≤ a Ω²``, stated as
    ``turn_accel_max``; monotone, so within a step it stays within the step's turn as pose
    increments assume, and under π a step) read as pose increments at irregular stamps: within
    a step it strays from the chord by up to the chord bound, which the chain of chords (and its
    chord term taken where the window is in each step) must hold, at every time of a window off
    the stamp and its slack. Half the chord term fails it."""
    rng = np.random.default_rng(seed)
    t = 100.0 + np.cumsum(np.r_[0.0, rng.uniform(0.05, 0.15, 40)])

    def theta(x):
        return amp * np.sin(omega * x) + 1.01 * amp * omega * (x - 100.0)

    th = theta(t)
    odo = Odometry(stamp=t, pose=np.column_stack([np.zeros_like(t), np.zeros_like(t), th]), twist=None)
    over = {"bounds.turn_accel_max": amp * omega * omega * (1 + 1e-9), "bounds.accel_max": 1.0,
            "bounds.odom_rot_abs": 1e-9, "bounds.odom_rot_rel": 1e-9, "bounds.odom_trans_abs": 1e-9}
    m = motion_steps(odo, MotionBounds.from_config(resolve_config(None, over)), t[:1], prefer="pose")
    for f, at_node, d, T, sl in spans:
        s = t[0] + f * (t[-1] - t[0])
        if at_node:
            s = float(t[np.searchsorted(t, s)])
        t0, t1 = s + d, s + d + T
        if not (t[0] <= min(t0 - sl, s) and max(t1 + sl, s) <= t[-1]):
            continue
        w, e, _ = m.turn_between(*(np.array([v]) for v in (s, t0, t1)), np.array([40]), np.array([sl]))
        u = np.linspace(t0, t1, 200)
        for delta in np.linspace(-sl, sl, 5):
            assert np.all(np.abs(theta(u + delta) - theta(s) - w[0] * (u - s)) <= e[0] + 1e-12), (s, d, T, sl, w, e)
