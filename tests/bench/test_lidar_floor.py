"""The LiDAR localisation floor's witnesses (``bench/bench_lidar_floor.py``): each agrees with its
scan — checked by rays sampled across every cone, not by the cone kernel the search uses — and
the search excludes what the scan rules out."""

from __future__ import annotations

import numpy as np
import pytest

from bench.bench_lidar_floor import OFFSETS, find_position, heading_reach, scan_bounds, sensor_pose, violations
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.simulate.raycast import cast

RAYS = 401  # rays sampled across a cone


@pytest.fixture(scope="module")
def log():
    return simulate(SimConfig(scenario="lidar", seed=5, duration=2.0))


def _sampled_cone_min(pose, ang, half_width, segments):
    """Per beam: the nearest wall over ``RAYS`` rays spread across its cone."""
    offs = np.linspace(-half_width, half_width, RAYS)
    d = cast(pose, (ang[:, None] + offs[None, :]).ravel(), segments)
    return d.reshape(ang.size, RAYS).min(axis=1)


def _own_bounds(log, k):
    """Scan ``k``'s valid beam angles and true-distance bounds, from the log's stated bounds."""
    sc, b = log.scans, log.bounds
    o0, o1 = int(sc.offsets[k]), int(sc.offsets[k + 1])
    v = np.asarray(sc.valid[o0:o1], bool)
    z = np.asarray(sc.ranges[o0:o1], float)[v]
    ang = sc.angle_min[k] + np.arange(o1 - o0)[v] * sc.angle_increment[k]
    return ang, (z - b["range_abs"]) / (1 + b["range_rel"]), (z + b["range_abs"]) / (1 - b["range_rel"])


def test_the_true_pose_agrees_with_every_beam(log):
    seg = np.asarray(log.truth.world, float)
    hw = float(log.bounds["beam_angle"])
    for k in (0, 7, 15):
        ang, lo, hi = scan_bounds(log, k)
        p = sensor_pose(np.asarray(log.truth.pose[k], float), log.scans.mount)
        assert violations(p[None], ang, lo, hi, hw, seg)[0] == 0


def test_witnesses_agree_with_their_scan_by_sampled_rays(log):
    seg = np.asarray(log.truth.world, float)
    hw = float(log.bounds["beam_angle"])
    q = 5
    found = 0
    for k in (0, 7, 15):
        ang, lo, hi = _own_bounds(log, k)
        assert np.array_equal(ang, scan_bounds(log, k)[0])
        below, above, wit = heading_reach(log, k, q)
        truth = sensor_pose(np.asarray(log.truth.pose[k], float), log.scans.mount)
        assert len(wit) == sum(d <= below for d in OFFSETS) + sum(d <= above for d in OFFSETS)
        for w in wit:
            assert abs(w[2] - truth[2]) <= max(below, above) + 1e-12
            d = _sampled_cone_min(w, ang, hw, seg)
            bad = (d < lo - 1e-3) | (d > hi + 1e-3)
            assert int(bad.sum()) <= q
            found += 1
    assert found >= 3


def test_a_heading_far_off_has_no_witness(log):
    seg = np.asarray(log.truth.world, float)
    hw = float(log.bounds["beam_angle"])
    ang, lo, hi = scan_bounds(log, 7)
    p = sensor_pose(np.asarray(log.truth.pose[7], float), log.scans.mount)

    def check(P):
        return violations(P, ang, lo, hi, hw, seg)

    assert find_position(p, p[2], 0, check) is not None
    assert find_position(p, p[2] + 0.05, 0, check) is None
    assert find_position(p, p[2] - 0.05, 5, check) is None
