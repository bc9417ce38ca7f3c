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


def _free_by_cones(pts, sensor, ang_all, free, ra):
    """Per point: inside the free space of a scan from ``sensor`` (x, y, yaw): within ``ra`` of a
    beam's angle and nearer than its free range (an independent, vectorised form)."""
    d = np.hypot(pts[:, 0] - sensor[0], pts[:, 1] - sensor[1])
    b = np.arctan2(pts[:, 1] - sensor[1], pts[:, 0] - sensor[0]) - sensor[2]
    b = np.angle(np.exp(1j * b))
    off = np.abs(np.angle(np.exp(1j * (b[:, None] - ang_all[None, :]))))
    return ((off <= ra) & (d[:, None] < free[None, :]) & (free[None, :] > 0)).any(axis=1)


def _region_points(sensor, ang, lo, hi, ra, n=9):
    """Points across each beam's end region: (beams, n * n, 2)."""
    t = ang[:, None] + sensor[2] + ra * 0.999 * np.linspace(-1.0, 1.0, n)[None, :]
    r = lo[:, None] + (hi - lo)[:, None] * np.linspace(0.0, 1.0, n)[None, :]
    R, T = r[:, :, None], t[:, None, :]
    return np.stack([sensor[0] + R * np.cos(T), sensor[1] + R * np.sin(T)], -1).reshape(ang.size, n * n, 2)


def _assert_witness_in(w, S, A, mount, ra, q, union):
    """Pose ``w`` of scan ``S`` in scan ``A``'s frame leaves at most ``q`` beams of each scan
    whose whole end region (sampled densely) is in the other's free cones, and lies in ``union``."""
    all_s = S[4] + S[5] * np.arange(S[3].size)
    all_a = A[4] + A[5] * np.arange(A[3].size)
    a_sensor, s_sensor = sensor_pose(np.zeros(3), mount), sensor_pose(w, mount)
    inside_a = _free_by_cones(_region_points(s_sensor, S[0], S[1], S[2], ra).reshape(-1, 2), a_sensor, all_a, A[3], ra)
    inside_s = _free_by_cones(_region_points(a_sensor, A[0], A[1], A[2], ra).reshape(-1, 2), s_sensor, all_s, S[3], ra)
    assert inside_a.reshape(S[0].size, -1).all(axis=1).sum() <= q
    assert inside_s.reshape(A[0].size, -1).all(axis=1).sum() <= q
    assert np.any((union[:, 0] <= w[0]) & (w[0] <= union[:, 1]) & (union[:, 2] <= w[1]) & (w[1] <= union[:, 3])
                  & (union[:, 4] <= w[2]) & (w[2] <= union[:, 5]))


def test_pair_witnesses_hold_a_world_and_lie_in_our_matchers_union():
    """Each two-scan witness leaves at most q beams of each scan whose whole end region is in the
    other's free cones (checked by an independent vectorised form); every other beam has a point
    outside: a world of points both scans agree with. Our matcher, sound, keeps every witness;
    a heading far off has none."""
    from bench.bench_lidar_floor import pair_floor, pair_scan, pair_witness, relative_pose
    from ivslam_cli.config import resolve_config
    from ivslam_cli.slam.lidar.params import Params

    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=5, duration=3.0))
    params = Params.from_config(resolve_config(None, {}, log_bounds=log.bounds))
    b, mount, q = params.beams, log.scans.mount, 5
    ra = float(b.bearing)
    k, j = 25, 15
    below, above, wit, union = pair_floor(log, k, j, q, params)
    assert len(wit) >= 3 and below + above > 0
    S, A = pair_scan(log, k, b.range_abs, b.range_rel), pair_scan(log, j, b.range_abs, b.range_rel)
    for w in wit:
        _assert_witness_in(w, S, A, mount, ra, q, union)
    t = relative_pose(np.asarray(log.truth.pose[j], float), np.asarray(log.truth.pose[k], float))
    assert not pair_witness(t[0], t[1], t[2] + 0.3, 0.12, 0.002, tuple(float(v) for v in mount), S, A, ra, q, 9, 7)[0]


def test_pushed_witness_extents_are_witnesses_beyond_the_grid():
    """The relations' floor: every extreme the pattern search reaches is a witness (at most q
    broken beams of each scan, the same check :func:`_both_broken` makes, and by the
    independent vectorised form) inside the limits, at or beyond the grid's extent; our
    matcher's union keeps each one."""
    from bench.bench_lidar_floor import _both_broken, pair_floor, pair_scan, push_witnesses, witness_extents
    from ivslam_cli.config import resolve_config
    from ivslam_cli.slam.lidar.params import Params

    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=5, duration=3.0))
    params = Params.from_config(resolve_config(None, {}, log_bounds=log.bounds))
    b, mount, q = params.beams, tuple(float(v) for v in log.scans.mount), 5
    ra = float(b.bearing)
    k, j = 25, 15
    union = pair_floor(log, k, j, q, params)[3]
    S, A = pair_scan(log, k, b.range_abs, b.range_rel), pair_scan(log, j, b.range_abs, b.range_rel)
    h = np.array([union[:, 0].min(), union[:, 1].max(), union[:, 2].min(), union[:, 3].max(), union[:, 4].min(),
                  union[:, 5].max()])
    lim = h + np.array([-0.05, 0.05, -0.05, 0.05, -0.02, 0.02])
    out = np.array([np.inf, -np.inf, np.inf, -np.inf, np.inf, -np.inf])
    at = np.zeros((6, 3))
    assert witness_extents(lim, 0.02, 0.005, mount, S, A, ra, q, 9, 7, out, at) > 0
    grid = out.copy()
    push_witnesses(out, at, lim, 0.02, 0.005, 3, mount, S, A, ra, q, 9, 7)
    assert np.all(out[0::2] <= grid[0::2]) and np.all(out[1::2] >= grid[1::2]) and np.any(out != grid)
    for side in range(6):
        w = at[side]
        assert out[side] == w[side // 2]
        assert np.all(lim[0::2] <= w) and np.all(w <= lim[1::2])
        assert _both_broken(w[0], w[1], w[2], mount, S, A, ra, 9, 7, q) <= q
        _assert_witness_in(w, S, A, mount, ra, q, union)
