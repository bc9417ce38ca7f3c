"""Reference scans in runs of beams (`slam/lidar/references.py`): the free space of a swept
reference as the matcher's rule A reads it, one row per run of beams, each from its own box.

Soundness: from the true pose at its stamp, no row of a swept reference certifies free a point
of a true wall. Tightness: a run's sensor is narrower than the whole sweep's, and the quick
selection of runs keeps every run the per-row quick test keeps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ivslam_cli.config import resolve_config
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.slam.lidar import Params as LidarParams
from ivslam_cli.slam.lidar.free_cones import _may_cover, _seg_free
from ivslam_cli.slam.lidar.matcher import Matcher
from ivslam_cli.slam.lidar.prediction import sweep_motion, trajectory
from ivslam_cli.slam.lidar.references import (C_AC, C_I0, C_II, C_MI, C_N, C_OK, C_RAD, C_RR, C_RUNS, C_SMIN, C_TH,
                                              C_X, C_Y, runs_may_cover)
from ivslam_cli.slam.lidar.sweep_map import chunk_scans
from tests.helpers.lidar_truth import true_pose_at

SWEEP = 0.0667


def _swept(seed: int, steps: int = 30, **kw):
    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=seed, steps=steps, sweep=SWEEP,
                             **kw))
    params = LidarParams.from_config(resolve_config(None, {}, log_bounds=log.bounds))
    used, _, m, _, _, _ = trajectory(log, params, log.scans)
    model = sweep_motion(log.scans, params, m, used)
    return log, params, used, model, chunk_scans(model.beams, model.offset, model.smin)


def _truth_at(log, t):
    ref = float(log.truth.pose_stamp[0])
    p = true_pose_at(log.truth, np.asarray(t, float) - ref, ref)
    if np.ndim(t) == 0:
        p = p[0]
    return p[..., 0], p[..., 1], p[..., 2]


def _true_box(log, k: int) -> np.ndarray:
    x, y, a = _truth_at(log, float(log.scans.stamp[k]))
    return np.array([x, x, y, y, a, a])


def _beam_walls(log, k: int, stride: int = 2) -> np.ndarray:
    """The wall points the beams of scan ``k`` point at, each from its true sensor at its own
    time along its nominal direction: true surface points inside the beams' cones."""
    from ivslam_cli.simulate.raycast import cast

    sc = log.scans
    i = np.arange(0, int(sc.offsets[k + 1] - sc.offsets[k]), stride)
    t = float(sc.stamp[k]) + SWEEP * i / (int(sc.offsets[k + 1] - sc.offsets[k]) - 1)
    x, y, th = _truth_at(log, t)
    mx, my, myaw = sc.mount
    sx, sy = x + np.cos(th) * mx - np.sin(th) * my, y + np.sin(th) * mx + np.cos(th) * my
    a = th + myaw + float(sc.angle_min[k]) + i * float(sc.angle_increment[k])
    d = np.array([cast(np.array([sx[j], sy[j], a[j]]), np.zeros(1), np.asarray(log.truth.world, float))[0, 0]
                  for j in range(i.shape[0])])
    ok = np.isfinite(d) & (d < 5.5)
    return np.column_stack([sx + d * np.cos(a), sy + d * np.sin(a)])[ok]


@pytest.mark.parametrize("seed", [3, 8])
def test_no_run_of_a_swept_reference_certifies_a_true_wall_free(seed):
    """At 1 m/s with errors at the bound (the worst case), the points the reference's own beams
    hit, each from its true pose, are never in a row's certified free space."""
    log, params, used, model, ch = _swept(seed, speed=1.0, noise="edges")
    assert ch is not None
    runs = Matcher(params, model.beams, model, ch)
    whole = Matcher(params, model.beams, model, None)
    r_alpha = float(params.beams.bearing)
    n_cert = 0
    for k in used[1:-2]:
        box = _true_box(log, k)
        for mt, rows in ((runs, 8), (whole, 1)):
            _, ref_f, ref_a0, ref_inc, ref_c, ref_th, R = mt.references([(int(k), box)])
            assert R == rows and ref_c[0, C_RUNS] == rows
            pts = _beam_walls(log, int(k))
            for t in range(R):
                c = ref_c[t]
                e = c[C_RAD] + 1e-9  # the point seen from every sensor of the run (as the matcher widens)
                for x, y in pts:
                    assert not _seg_free(x - c[C_X], y - c[C_Y], 1.0, 0.0, e, e, ref_th[t, 0], ref_th[t, 1],
                                         ref_f[t], ref_a0[t], ref_inc[t], r_alpha, c[C_SMIN]), (k, t, x, y)
                # the certified free space is not empty: points short of the walls are
                for x, y in pts[::10]:
                    v = np.array([x - c[C_X], y - c[C_Y]])
                    q = 0.7 * v
                    n_cert += _seg_free(q[0], q[1], 1.0, 0.0, e, e, ref_th[t, 0], ref_th[t, 1], ref_f[t],
                                        ref_a0[t], ref_inc[t], r_alpha, c[C_SMIN])
        # a run's sensor is much narrower than the whole sweep's
        rr = runs.references([(int(k), box)])[4][:, C_RAD]
        rw = whole.references([(int(k), box)])[4][0, C_RAD]
        assert np.all(rr < rw) and np.median(rr) < 0.5 * rw, (rr, rw)
    assert n_cert > 100


def test_the_selection_of_runs_keeps_every_run_the_quick_test_keeps():
    """:func:`runs_may_cover` (one arctangent per reference scan) against :func:`_may_cover` run
    by run: every run the latter may let prove a point free lies in the selected range."""
    log, params, used, model, ch = _swept(5, 20)
    rng = np.random.default_rng(5)
    mt = Matcher(params, model.beams, model, ch)
    n_kept = 0
    for k in used[1:-2]:
        box = _true_box(log, k)
        _, ref_f, ref_a0, _, ref_c, _, R = mt.references([(int(k), box)])
        assert R == 8
        c0 = ref_c[0]
        for _ in range(400):
            d = rng.uniform(0.05, 6.0)
            b = rng.uniform(-2.3, 2.3) + c0[C_TH]
            cx, cy = c0[C_X] + d * math.cos(b), c0[C_Y] + d * math.sin(b)
            phi = rng.uniform(-math.pi, math.pi)
            ux, uy = math.cos(phi), math.sin(phi)
            base = rng.uniform(0.0, 0.1)
            t0, t1 = runs_may_cover(cx, cy, ux, uy, base, ref_c, 0)
            for t in range(R):
                c = ref_c[t]
                e = base + c[C_RAD]
                if _may_cover(cx + e * ux, cy + e * uy, c[C_X], c[C_Y], c[C_TH], ref_f[t], ref_a0[t], c[C_II], c[C_AC],
                              c[C_MI], c[C_OK] > 0.0, c[C_RR], not c[C_SMIN] > 0.0):
                    n_kept += 1
                    assert t0 <= t <= t1, (k, t, t0, t1)
        # runs partition the scan's beams
        assert ref_c[0, C_I0] == 0 and np.all(ref_c[1:R, C_I0] == ref_c[:R - 1, C_I0] + ref_c[:R - 1, C_N])
    assert n_kept > 100


@pytest.mark.parametrize("seed", [2, 6])
def test_every_beams_true_sensor_lies_in_its_own_runs_circle(seed):
    """Rule B in runs (:func:`own_runs`, :func:`own_runs_at`): from the sensor region of the
    true pose at the stamp (widened as the matcher widens it: the move's error, the turn's), each
    beam's true sensor at its own time lies in its run's circle."""
    from ivslam_cli.slam.lidar.free_cones import free_of
    from ivslam_cli.slam.lidar.geometry import sensor_box
    from ivslam_cli.slam.lidar.references import C_RAD, own_runs, own_runs_at

    log, params, used, model, ch = _swept(seed, speed=1.0)
    sc, beams = log.scans, model.beams
    mx, my, myaw = sc.mount
    worst = 0.0
    for k in used[1:-2]:
        b0, b1 = int(sc.offsets[k]), int(sc.offsets[k + 1])
        f = free_of(beams.ranges[b0:b1], beams.valid[b0:b1], 0.03, 0.01)
        own_c, _ = own_runs(f, np.ascontiguousarray(model.offset[b0:b1]), float(beams.angle_min[k]),
                            float(beams.angle_increment[k]), 0.0034, 0.0, 8)
        assert own_c.shape[0] == 8
        box = _true_box(log, k)
        e, a = float(model.err[k]), float(model.reach[k, 1])
        sb = sensor_box(box[0] - e, box[1] + e, box[2] - e, box[3] + e, box[4] - a, box[5] + a, mx, my, myaw)
        ccx, ccy, c = 0.5 * (sb[0] + sb[1]), 0.5 * (sb[2] + sb[3]), 0.5 * (sb[4] + sb[5])
        rs = math.hypot(0.5 * (sb[1] - sb[0]), 0.5 * (sb[3] - sb[2])) * (1 + 1e-12) + 1e-9
        own_runs_at(own_c, ccx, ccy, math.cos(c), math.sin(c), c, rs, 0.5 * (sb[5] - sb[4]) * (1 + 1e-12))
        i = np.arange(b1 - b0)
        x, y, th = _truth_at(log, float(sc.stamp[k]) + SWEEP * i / (b1 - b0 - 1))
        sx, sy = x + np.cos(th) * mx - np.sin(th) * my, y + np.sin(th) * mx + np.cos(th) * my
        for p in range(8):
            j = slice(int(own_c[p, C_I0]), int(own_c[p, C_I0] + own_c[p, C_N]))
            d = np.hypot(sx[j] - own_c[p, C_X], sy[j] - own_c[p, C_Y])
            assert np.all(d <= own_c[p, C_RAD]), (k, p, d.max(), own_c[p, C_RAD])
            worst = max(worst, float(np.max(d / own_c[p, C_RAD])))
        # much narrower than the whole sweep's region
        assert np.median(own_c[:, C_RAD]) < 0.5 * (rs + float(model.reach[k, 0]))
    assert worst > 0.05  # the circles are not loose everywhere
