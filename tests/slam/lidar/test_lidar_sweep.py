"""A scan's beams taken one after another while the robot moves (``lidar.sweep``): every pose a
scan is matched or mapped with is widened by the motion its odometry allows in that time."""

from __future__ import annotations

import numpy as np
import pytest

from ivslam_cli.config import resolve_config
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.slam.lidar import Params as LidarParams
from ivslam_cli.slam.lidar.sweep_map import swept_box
from ivslam_cli.slam.lidar.pipeline import run
from ivslam_cli.slam.lidar.prediction import sweep_times
from tests.helpers.lidar_truth import containment, true_pose_at

SWEEP = 0.0667  # the URG-04LX: 683 of 1024 steps of a 100 ms turn


def test_a_swept_box_holds_the_box_and_rounds_outward():
    box = np.array([0.1, 0.3, -0.2, 0.2, 1.0, 1.1])
    w = swept_box(box, (0.05, 0.02))
    assert np.all(w[0::2] < box[0::2] - np.array([0.05, 0.05, 0.02]) + 1e-15)
    assert np.all(w[1::2] > box[1::2] + np.array([0.05, 0.05, 0.02]) - 1e-15)
    assert swept_box(box, (0.0, 0.0)) is box
    rows = swept_box(np.stack([box, box]), np.array([[0.05, 0.02], [0.0, 0.0]]))
    assert np.array_equal(rows[0], w) and np.array_equal(rows[1], box)


@pytest.mark.slow  # ~40 s
def test_a_swept_log_keeps_the_truth_with_its_sweep_and_loses_it_without():
    # the default cones of a swept log overlap by more than the turn between two beams (0.00343
    # rad against half a step, 0.00307): the free space they prove holds although each beam is
    # taken from its own pose
    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=5, steps=200, sweep=SWEEP))
    res = run(log, LidarParams.from_config(resolve_config(None, {}, log_bounds=log.bounds)))
    c = containment(res)
    for kind in ("pose", "pose_relative", "map_free", "global_free"):
        assert c[kind][0] == c[kind][1] > 0, (kind, c)
    assert "the log's time_increment" in res.consistency.assumption  # read from the log by default
    assert 0.0 < res.stats["sweep_free_from_median"] < 0.2 and res.stats["scans_no_free"] == 0
    # every beam at the stamp: the model is wrong by the robot's motion during the scan
    off = {"lidar.sweep_from_log": False}
    still = run(log, LidarParams.from_config(resolve_config(None, off, log_bounds=log.bounds)))
    c0 = containment(still)
    assert any(c0[kind][0] < c0[kind][1] for kind in ("pose", "pose_relative", "map_free")), c0
    assert "at the scan's stamp" in still.consistency.assumption
    # the same sweep given by hand
    by_hand = {"lidar.sweep_from_log": False, "lidar.sweep": SWEEP}
    sweep_times_source = sweep_times(log.scans, LidarParams.from_config(resolve_config(None, by_hand,
                                                                                      log_bounds=log.bounds)))
    assert sweep_times_source[1] == "lidar.sweep" and np.allclose(sweep_times_source[0], SWEEP)


def _beams_outside_their_runs(scans, tr, model, ch, ks, b, c, taken, plain=None):
    """Over scans ``ks``: how many beams' true sensors (the simulated robot's pose at the beam's
    own time ``taken[k] + b[k] + c[k] i``, the laser on its mount) fall outside their run's
    sensor box built around the true pose at the scan's stamp, or whose true direction (heading
    + mount + beam angle) is not the run's deskewed angle turned by a heading of its box; and
    the widest run box. ``plain``: ``ch`` holds the staggered runs of these chunks."""
    from ivslam_cli.slam.lidar.map_update import sensor_boxes
    from ivslam_cli.slam.lidar.sweep_map import chunk_boxes, staggered_errors

    ref = float(tr.pose_stamp[0])
    mx, my, myaw = scans.mount
    out, worst = 0, 0.0
    for k in ks:
        t_k = float(scans.stamp[k]) - ref
        p = true_pose_at(tr, t_k, ref)[0]
        box = np.array([p[0], p[0], p[1], p[1], p[2], p[2]])
        a, e = model.run_turn[k], model.run_err[k]
        if plain is not None:
            n = int(plain.first[k + 1] - plain.first[k])
            a, e = staggered_errors(a, n), staggered_errors(e, n)
        cb = chunk_boxes(ch, k, box, a, e, float(model.turn_lever[k]))
        sb = sensor_boxes(cb, scans.mount)
        for j in range(ch.first[k], ch.first[k + 1]):
            lo, hi = int(ch.scans.offsets[j]), int(ch.scans.offsets[j + 1])
            i = np.arange(lo, hi) - int(scans.offsets[k])
            t_i = (float(taken[k]) - ref) + b[k] + c[k] * i
            x, y, th = true_pose_at(tr, t_i, ref).T
            sx = x + np.cos(th) * mx - np.sin(th) * my
            sy = y + np.sin(th) * mx + np.cos(th) * my
            bj = sb[j - ch.first[k]]
            a_true = scans.angle_min[k] + i * scans.angle_increment[k]
            a_desk = ch.scans.angle_min[j] + np.arange(hi - lo) * ch.scans.angle_increment[j]
            head = th + myaw + a_true - a_desk
            inside = ((bj[0] <= sx) & (sx <= bj[1]) & (bj[2] <= sy) & (sy <= bj[3])
                      & (bj[4] - 1e-12 <= head) & (head <= bj[5] + 1e-12))
            out += int(np.count_nonzero(~inside))
            worst = max(worst, float(np.max(bj[[1, 3]] - bj[[0, 2]])))
    return out, worst


@pytest.mark.parametrize("seed", [1, 4])
def test_every_beam_is_taken_from_within_its_chunks_box(seed):
    """The sweep deskewed (prediction.sweep_motion) and mapped in runs of beams (sweep_map):
    from the true pose at a scan's stamp, every beam's true sensor (the simulated robot's pose at
    the beam's own time, the laser on its mount) lies in its chunk's sensor box, and its true
    direction is the chunk's deskewed beam angle turned by a heading of the chunk's box."""
    from ivslam_cli.slam.lidar.prediction import beam_times, sweep_motion, trajectory
    from ivslam_cli.slam.lidar.sweep_map import chunk_scans

    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=seed, steps=40, sweep=SWEEP))
    params = LidarParams.from_config(resolve_config(None, {}, log_bounds=log.bounds))
    scans, tr = log.scans, log.truth
    used, _, m, _, _, _ = trajectory(log, params, scans)
    model = sweep_motion(scans, params, m, used)
    ch = chunk_scans(model.beams, model.offset, model.smin)
    assert ch is not None and ch.moves[used].all()
    b, c = beam_times(scans, params)
    out, worst = _beams_outside_their_runs(scans, tr, model, ch, used[1:-2], b, c, scans.stamp)
    assert out == 0
    # the staggered runs (the cells between two runs): the same beams in the same order, one run
    # more, each within two adjacent runs of the plain cut, and the same guarantee
    st = chunk_scans(model.beams, model.offset, model.smin, staggered=True)
    for k in used:
        p0, p1, s0, s1 = ch.first[k], ch.first[k + 1], st.first[k], st.first[k + 1]
        assert s1 - s0 == p1 - p0 + 1
        po, so = ch.scans.offsets, st.scans.offsets
        assert so[s0] == po[p0] and so[s1] == po[p1] and np.all(np.diff(so[s0:s1 + 1]) >= 0)
        for i in range(1, s1 - s0):
            assert po[p0 + i - 1] <= so[s0 + i] and so[s0 + i + 1] <= po[min(p0 + i + 1, p1)]
    out_s, _ = _beams_outside_their_runs(scans, tr, model, st, used[1:-2], b, c, scans.stamp, plain=ch)
    assert out_s == 0
    # each run's own bounds (the twist's rates about the scan's, over the run's times alone)
    assert np.all(model.run_turn[used] <= model.reach[used, 1][:, None])
    assert np.all(model.run_err[used] <= model.err[used][:, None])
    assert np.median(model.run_turn[used].mean(axis=1) / model.reach[used, 1]) < 0.75
    assert np.median(model.run_err[used].mean(axis=1) / model.err[used]) < 0.75
    # the chunks' boxes are far narrower than the whole sweep's move (3.7 cm either side)
    assert worst < 0.5 * 2 * float(np.median(model.reach[used, 0]))


@pytest.mark.parametrize("seed,increments", [(2, False), (3, True)])
def test_scans_stamped_off_their_clock_are_taken_back_to_it(seed, increments):
    """A swept log whose stamps jitter (up to ±30 ms) around the scans' regular clock: with
    ``lidar.scan_clock = "fitted"`` and a ``bounds.scan_time`` covering the fit's error, every
    beam's true sensor at its true time lies in its chunk's box around the true pose at the
    stamp; taken at the stamps, some do not."""
    from dataclasses import replace

    from ivslam_cli.logs.model import Odometry
    from ivslam_cli.slam.lidar.prediction import beam_times, sweep_motion, trajectory
    from ivslam_cli.slam.lidar.scan_clock import scan_clock
    from ivslam_cli.slam.lidar.sweep_map import chunk_scans

    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=seed, steps=80, sweep=SWEEP))
    tr = log.truth
    true_stamp = np.asarray(log.scans.stamp, float)
    rng = np.random.default_rng(seed)
    jitter = rng.uniform(-0.03, 0.03, true_stamp.shape)
    scans = replace(log.scans, stamp=true_stamp + jitter)
    over = {"lidar.sweep_from_log": False, "lidar.sweep": SWEEP}
    if increments:  # the true poses as pose increments (the simulated robot turns at a constant rate between them)
        log = replace(log, odometry=Odometry(stamp=tr.pose_stamp.copy(), pose=tr.pose.copy(), twist=None))
        over.update({"lidar.motion": "pose", "bounds.turn_accel_max": 3.0, "bounds.accel_max": 2.0})
    log = replace(log, scans=scans)
    fit = scan_clock(scans, "fitted")
    miss = float(np.max(np.abs(scans.stamp + fit.offset - true_stamp)))
    assert miss < 0.5 * 0.03  # the fit takes the scans back, up to its error
    results = {}
    for clock, slack in (("fitted", miss * 1.01), ("stamps", 0.0)):
        params = LidarParams.from_config(resolve_config(None, {**over, "lidar.scan_clock": clock,
                                                               "bounds.scan_time": slack}, log_bounds=log.bounds))
        used, _, m, _, _, _ = trajectory(log, params, scans)
        model = sweep_motion(scans, params, m, used)
        # each run's own turn and move errors are at most the scan's, with the chain of chords below
        assert np.all(model.run_turn[used] <= model.reach[used, 1][:, None])
        assert np.all(model.run_err[used] <= model.err[used][:, None])
        if clock == "fitted":
            assert np.median(model.run_turn[used].mean(axis=1) / model.reach[used, 1]) < 0.95
        ch = chunk_scans(model.beams, model.offset, model.smin)
        b, c = beam_times(scans, params, scan_clock(scans, "stamps"))  # the sweep from the true time
        out, _ = _beams_outside_their_runs(scans, tr, model, ch, used[2:-3], b, c, true_stamp)
        results[clock] = out
    assert results["fitted"] == 0 and results["stamps"] > 0, results
