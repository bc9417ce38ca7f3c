"""Several robots in one landmark CSP (``--robot all``): shared landmarks, the robots'
measurements of each other, per-robot tubes; soundness on simulated fleets, the result file,
the report and the CLI's refusals."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from ivslam_cli.config import resolve_config
from ivslam_cli.logs.model import GroundTruth, LogData, Observations, Provenance
from ivslam_cli.report.core import compute_report, landmark_containment, robot_pose_containment
from ivslam_cli.results.hdf5 import read_result, write_result
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.simulate.observe import observe
from ivslam_cli.slam.landmarks import Params as LandmarksParams
from ivslam_cli.slam.landmarks import pipeline as PL
from tests.helpers.hyp import seeds


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def fleet(seed: int, robots: int = 3, steps: int = 150, outlier_rate: float = 0.0, sightings: bool = True) -> LogData:
    """``robots`` simulated robots in one world: robot 1's landmarks, every robot observing them
    (the simulator's sensor and bounds), and each robot measuring the others in its field of
    view (same range/bearing bounds); gross outliers at ``outlier_rate`` on both kinds of
    measurement (in the truth's masks), none on the odometry."""
    # odometry within its bounds (outliers only on the measurements, as q covers them)
    logs = [simulate(SimConfig(scenario="landmarks", seed=seed * 10 + r, steps=steps, landmarks=10, world_size=10.0))
            for r in range(robots)]
    base = logs[0]
    ids, lm = base.truth.landmark_id, base.truth.landmark_xy
    sensor = base.meta["landmark_sensor"]
    rng = np.random.default_rng(seed)
    out = []
    for r, log in enumerate(logs):
        tr = log.truth
        b = log.bounds
        o = observe(rng, tr.pose_stamp, tr.pose, ids, lm, sensor["min_range"], sensor["max_range"],
                    sensor["half_fov"], b, "uniform", outlier_rate, 20.0, 0.0)
        other = None
        rows = []
        if sightings:
            for t, other_log in enumerate(logs):
                if t == r:
                    continue
                d = other_log.truth.pose[:, :2] - tr.pose[:, :2]
                rho = np.hypot(d[:, 0], d[:, 1])
                alpha = _wrap(np.arctan2(d[:, 1], d[:, 0]) - tr.pose[:, 2])
                seen = np.flatnonzero((rho >= sensor["min_range"]) & (rho <= sensor["max_range"])
                                      & (np.abs(alpha) <= sensor["half_fov"]))
                u = rng.uniform(-0.95, 0.95, seen.size)
                z = (rho[seen] + u * b["range_abs"]) / (1 - u * b["range_rel"])
                za = _wrap(alpha[seen] + rng.uniform(-0.95, 0.95, seen.size) * b["bearing"])
                bad = rng.random(seen.size) < outlier_rate
                za = np.where(bad, _wrap(za + 2.0), za)
                rows.append(np.column_stack([tr.pose_stamp[seen], np.full(seen.size, t + 1), z, za, bad]))
        if rows:
            a = np.concatenate(rows)
            a = a[np.argsort(a[:, 0], kind="stable")]
            other = Observations(stamp=a[:, 0], landmark_id=a[:, 1].astype(np.int64), range=a[:, 2], bearing=a[:, 3])
            bad_other = a[:, 4].astype(bool)
        truth = GroundTruth(pose_stamp=tr.pose_stamp, pose=tr.pose, landmark_id=ids, landmark_xy=lm,
                            outliers={"observations": o.outlier,
                                      **({"other_observations": bad_other} if rows else {})})
        out.append((r + 1, replace(log, observations=o.obs, other_observations=other, truth=truth)))
    return LogData(provenance=Provenance(path="<simulated fleet>", format="simulated"),
                   truth=GroundTruth(landmark_id=ids, landmark_xy=lm), bounds=dict(base.bounds), robots=out)


def _cfg(log, **over):
    base = {"landmarks.initial_pose_from_truth": True}
    base.update(over)
    return resolve_config(None, base, log_bounds=log.bounds)


def _sound(res):
    per = robot_pose_containment(res)
    assert len(per) == len(res.robots) and all(c.checked > 0 for c in per.values())
    for rid, c in per.items():
        assert c.contained == c.checked, (rid, c.failures[:3])
    lc = landmark_containment(res.landmarks, res.truth)
    assert lc.contained == lc.checked > 0, lc.failures
    return per


@pytest.mark.parametrize("seed", seeds(ci=12))
def test_fleets_keep_the_truth(seed):
    log = fleet(seed)
    res = PL.run(log, LandmarksParams.from_config(_cfg(log)))
    _sound(res)
    assert len(res.consistency.empty_events) == 0 and len(res.consistency.rejected) == 0
    assert res.stats["observations"] > sum(len(lg.observations) for _, lg in log.robots) * 0.9


@pytest.mark.parametrize("seed", range(12, 20))
def test_fleets_with_outliers_keep_the_truth_and_reject_only_outliers(seed):
    log = fleet(seed, outlier_rate=0.02)
    masks = {}
    for rid, lg in log.robots:
        for stream, m in lg.truth.outliers.items():
            masks[f"robot{rid}/{stream}"] = m
    # the stated assumption: q_pose within one frame (all robots observe at the same stamps)
    per_frame = max(int(np.bincount(np.unique(lg.observations.stamp[m], return_inverse=True)[1]).max())
                    if m.any() else 0 for (rid, lg), m in ((x, x[1].truth.outliers["observations"]) for x in log.robots))
    q_lm = max(int(np.bincount(lg.observations.landmark_id[lg.truth.outliers["observations"]]).max())
               if lg.truth.outliers["observations"].any() else 0 for _, lg in log.robots) * len(log.robots)
    res = PL.run(log, LandmarksParams.from_config(_cfg(log, **{"robust.q_landmark": q_lm,
                                                               "robust.q_pose": max(per_frame, 1) + 1})))
    _sound(res)
    rej = res.consistency.rejected
    for stream, i in zip(rej.stream, rej.index):  # an honest measurement is never proven wrong
        assert masks[str(stream)][int(i)], (stream, i)


def test_sightings_tie_the_robots_together():
    """A robot whose first pose is unknown is located by the shared landmarks and the others'
    measurements of it; without the sightings, by the landmarks alone (no tighter)."""
    log = fleet(3)
    # an explicit first pose anchors robot 1 only; the others start anywhere
    p0 = log.robots[0][1].truth.pose[0]
    cfg = _cfg(log, **{"landmarks.initial_pose_from_truth": False,
                       "landmarks.initial_pose": tuple(float(v) for v in p0)})
    with_s = PL.run(log, LandmarksParams.from_config(cfg))
    without = PL.run(fleet(3, sightings=False), LandmarksParams.from_config(cfg))
    _sound(with_s)
    _sound(without)
    w_with = np.nanmedian(np.max(with_s.poses.box[:, :2, 1] - with_s.poses.box[:, :2, 0], axis=-1))
    w_without = np.nanmedian(np.max(without.poses.box[:, :2, 1] - without.poses.box[:, :2, 0], axis=-1))
    assert w_with <= w_without * 1.0001
    n1 = int(with_s.robots.pose_offsets[1])
    assert np.all(np.isfinite(with_s.poses.box[n1:, :2])), "the robots of unknown start were located"


def test_result_file_report_and_tum(tmp_path):
    from ivslam_cli.report.jsonout import render_json
    from ivslam_cli.results.export import tum_paths, write_tum

    log = fleet(5, robots=2, steps=80)
    res = PL.run(log, LandmarksParams.from_config(_cfg(log)))
    write_result(tmp_path / "f.h5", res)
    back = read_result(tmp_path / "f.h5")
    assert back.robots.id.tolist() == [1, 2]
    assert np.array_equal(back.pose_sets.offsets, res.pose_sets.offsets)
    rep = compute_report(back)
    assert set(rep.robot_containment) == {1, 2} and rep.sound
    assert rep.containment["pose"].checked == sum(c.checked for c in rep.robot_containment.values())
    doc = json.loads(render_json(rep))
    assert doc["robot_containment"]["1"]["fraction"] == 1.0
    write_tum(tmp_path / "f.tum", back.poses, robots=back.robots)
    paths = tum_paths(tmp_path / "f.tum", back.robots.id)
    assert [p.name for p in paths] == ["f.robot1.tum", "f.robot2.tum"]
    rows = [np.loadtxt(p) for p in paths]
    assert [len(r) for r in rows] == np.diff(back.robots.pose_offsets).tolist()
    assert all(np.all(np.diff(r[:, 0]) > 0) for r in rows)


def test_pose_sets_are_inside_their_hull_and_hold_the_truth():
    log = fleet(7, robots=2, steps=100)
    res = PL.run(log, LandmarksParams.from_config(_cfg(log)))
    ps, P = res.pose_sets, res.poses.box
    owner = np.repeat(np.arange(len(P)), np.diff(ps.offsets))
    assert np.all(ps.boxes[:, :2, 0] >= P[owner, :2, 0]) and np.all(ps.boxes[:, :2, 1] <= P[owner, :2, 1])
    # at node stamps the truth lies in one of the node's boxes (not only in the hull)
    for r, (rid, lg) in enumerate(log.robots):
        a, b = res.robots.pose_offsets[r], res.robots.pose_offsets[r + 1]
        ts = lg.truth.pose_stamp
        for k in range(a, b):
            i = np.searchsorted(ts, res.poses.stamp[k])
            if i >= len(ts) or ts[i] != res.poses.stamp[k]:
                continue
            p = lg.truth.pose[i]
            bx = ps.node_boxes(k)
            th = bx[:, 2]
            n = np.ceil((th[:, 0] - p[2]) / (2 * np.pi))
            inside = ((bx[:, 0, 0] <= p[0]) & (p[0] <= bx[:, 0, 1]) & (bx[:, 1, 0] <= p[1]) & (p[1] <= bx[:, 1, 1])
                      & ((th[:, 0] <= p[2] + 2 * np.pi * n) & (p[2] + 2 * np.pi * n <= th[:, 1])
                         | (th[:, 0] <= p[2] + 2 * np.pi * (n - 1)) & (p[2] + 2 * np.pi * (n - 1) <= th[:, 1])))
            assert inside.any(), (rid, k)


def test_other_modes_refuse_several_robots():
    from ivslam_cli.errors import IvslamError
    from ivslam_cli.slam import run_pipeline

    log = fleet(1, robots=2, steps=30)
    with pytest.raises(IvslamError, match="--mode landmarks"):
        run_pipeline(log, _cfg(log), "pairs")


def test_cli_robot_all_needs_landmarks_mode(cli_run, tmp_path):
    r = cli_run("run", str(tmp_path), "--robot", "all", "--mode", "pairs", "-o", str(tmp_path / "x.h5"))
    assert r.exit_code == 2 and "--robot all needs --mode landmarks" in r.output
    r = cli_run("run", str(tmp_path), "--robot", "seven", "--mode", "landmarks")
    assert r.exit_code == 2 and "neither a robot number nor 'all'" in r.output
