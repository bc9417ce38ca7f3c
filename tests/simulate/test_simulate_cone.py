"""Cone beams (``--beam-model cone``, the default): every simulated beam satisfies the bounds
its log states, against an independent oracle; the pipeline proves free space from such logs
without ``lidar.fill_gaps`` and stays sound; ``--beam-model ray`` reproduces the ray-cast logs.

The oracle of the nearest wall distance within a cone ``[a - h, a + h]``: ``R`` rays spread
evenly over the cone (its two edges included) and the wall end points inside the cone. Every
point it finds is a wall point of the cone, so its distance ``d_hi`` is an upper bound of the
nearest one, ``d``; and ``d_hi <= d / cos(delta / 2)`` with ``delta = 2 h / (R - 1)``: the
nearest point is a wall end point (found exactly), on an edge ray (found exactly) or the foot
of the perpendicular from the apex on its wall, and then the ray nearest to it in angle meets
that wall's line within ``d / cos(delta / 2)``, or the wall ends before, at an end point inside
the cone and no farther.
"""

from __future__ import annotations

import hashlib
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.config import resolve_config
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.simulate.conecast import cone_cast
from ivslam_cli.simulate.raycast import cast
from ivslam_cli.simulate.sensors import PROFILES, get_profile
from ivslam_cli.simulate.worlds import BUILTIN, load_world
from tests.helpers.hyp import examples, lanes
from tests.helpers.lidar_truth import true_pose_at

REL = 1e-12  # rounding allowance of the kernel and of the oracle (relative)


# ---------------------------------------------------------------- the oracle
def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def oracle(origin: np.ndarray, a: np.ndarray, h: float, segs: np.ndarray, rays: int):
    """``(d_hi, point, delta)`` for cones at ``origin`` ``(M, 2)``, bisector ``a`` ``(M,)``,
    half-width ``h``: the nearest wall point the oracle finds (``inf`` / NaN if none) and the
    angular spacing of its rays."""
    m = origin.shape[0]
    d_hi = np.full(m, np.inf)
    pt = np.full((m, 2), np.nan)
    u = np.linspace(-h, h, rays) if rays > 1 else np.zeros(1)
    phi = a[:, None] + u[None, :]  # (M, R)
    dx, dy = np.cos(phi)[..., None], np.sin(phi)[..., None]  # (M, R, 1)
    ax, ay = segs[:, 0], segs[:, 1]
    ex, ey = segs[:, 2] - ax, segs[:, 3] - ay
    wx, wy = ax[None, None, :] - origin[:, 0, None, None], ay[None, None, :] - origin[:, 1, None, None]
    den = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / den
        s = (wx * dy - wy * dx) / den
    t = np.where((den != 0) & (t > 0) & (s >= 0) & (s <= 1), t, np.inf).min(axis=2)  # (M, R)
    r = np.argmin(t, axis=1)
    d_hi = t[np.arange(m), r]
    hit = np.isfinite(d_hi)
    pt[hit] = origin[hit] + d_hi[hit, None] * np.column_stack([np.cos(phi[hit, r[hit]]), np.sin(phi[hit, r[hit]])])
    ends = np.concatenate([segs[:, :2], segs[:, 2:]])  # (2K, 2)
    v = ends[None, :, :] - origin[:, None, :]
    de = np.hypot(v[..., 0], v[..., 1])
    inside = np.abs(_wrap(np.arctan2(v[..., 1], v[..., 0]) - a[:, None])) <= h
    de = np.where(inside, de, np.inf)
    j = np.argmin(de, axis=1)
    dj = de[np.arange(m), j]
    better = dj < d_hi
    d_hi = np.where(better, dj, d_hi)
    pt[better] = ends[j[better]]
    return d_hi, pt, (2.0 * h / (rays - 1) if rays > 1 else 0.0)


def bracket(d_hi: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """``[lo, hi]`` holding the nearest distance, from the oracle's ``d_hi``."""
    return d_hi * math.cos(0.5 * delta) * (1 - REL) - 1e-15, d_hi * (1 + REL) + 1e-15


def random_world(rng, k: int) -> np.ndarray:
    """``k`` walls in a 10 m square: random segments, polyline chains sharing their end
    points, some axis-aligned."""
    segs = []
    while len(segs) < k:
        kind = rng.integers(3)
        if kind == 0:
            segs.append(rng.uniform(0, 10, 4))
        elif kind == 1:
            p = rng.uniform(0, 10, 2)
            for _ in range(rng.integers(2, 5)):
                q = p + rng.normal(0, 1.5, 2)
                segs.append(np.r_[p, q])
                p = q
        else:
            x, y, w = *rng.uniform(0, 10, 2), rng.uniform(0.1, 3)
            segs.append(np.array([x, y, x + w, y]) if rng.random() < 0.5 else np.array([x, y, x, y + w]))
    return np.asarray(segs[:k], dtype=np.float64)


# ---------------------------------------------------------------- the kernel against the oracle
@given(st.integers(0, 2**32 - 1), st.sampled_from([0.0, 1e-7, 0.0030679615757712823, 0.0087266, 0.05, 0.4, 1.2]))
@settings(max_examples=examples(ci=60))
def test_cone_kernel_equals_the_clipped_nearest_distance(seed, h):
    rng = np.random.default_rng(seed)
    segs = random_world(rng, int(rng.integers(1, 25)))
    n = 60
    origin = rng.uniform(-1, 11, (n, 2))
    a = rng.uniform(-4, 4, n)
    d = cone_cast(np.column_stack([origin, a]), [0.0], h, segs)[:, 0]
    d_hi, _, delta = oracle(origin, a, h, segs, 2000)
    assert np.array_equal(np.isinf(d), np.isinf(d_hi)), "a cone with walls the other misses"
    f = np.isfinite(d)
    lo, hi = bracket(d_hi[f], delta)
    assert np.all(d[f] <= hi), np.max(d[f] / d_hi[f] - 1)  # d_exact <= d_hi
    assert np.all(d[f] >= lo), np.max(lo / d[f] - 1)  # d_hi <= d_exact / cos(delta / 2)


@pytest.mark.parametrize("world", lanes(BUILTIN, fast=["rooms"]))
def test_cone_kernel_in_the_worlds_and_its_ray_limit(world):
    """Built-in worlds (walls meeting at corners), random sensor poses and URG/SICK cones; a
    cone is never farther than its own bisector ray, and at h = 0 it is that ray."""
    w = load_world(world)
    rng = np.random.default_rng(7)
    lo_xy, hi_xy = w.segments.reshape(-1, 2).min(axis=0), w.segments.reshape(-1, 2).max(axis=0)
    pose = np.column_stack([rng.uniform(lo_xy[0], hi_xy[0], 40), rng.uniform(lo_xy[1], hi_xy[1], 40),
                            rng.uniform(-math.pi, math.pi, 40)])
    for prof in PROFILES.values():
        ang = prof.beam_angles()
        h = prof.half_step()
        d = cone_cast(pose, ang, h, w.segments)
        ray = cast(pose, ang, w.segments)
        assert np.all(d <= ray * (1 + REL))
        d0 = cone_cast(pose, ang, 0.0, w.segments)
        f = np.isfinite(ray)
        assert np.array_equal(np.isfinite(d0), f) and np.allclose(d0[f], ray[f], rtol=1e-9, atol=0)
        for i in range(0, pose.shape[0], 8):  # the oracle on every beam of a few scans
            d_hi, _, delta = oracle(np.repeat(pose[i:i + 1, :2], ang.size, 0), pose[i, 2] + ang, h,
                                    w.segments, 400)
            assert np.array_equal(np.isinf(d[i]), np.isinf(d_hi))
            f = np.isfinite(d_hi)
            lo, hi = bracket(d_hi[f], delta)
            assert np.all((lo <= d[i, f]) & (d[i, f] <= hi))


def test_cone_kernel_refuses_a_half_width_of_a_quarter_turn():
    with pytest.raises(ValueError, match="half-width"):
        cone_cast(np.zeros((1, 3)), [0.0], 0.5 * math.pi, np.array([[1.0, -1.0, 1.0, 1.0]]))


# ---------------------------------------------------------------- the stated bounds of a log
def check_cone_log(log, rays: int = 64):
    """Every beam of ``log`` is in bounds for the nearest wall distance within its stated cone
    exactly when it is not marked an outlier (a no-return beam claims ``d + e(d) > range_max``
    or a too-short return); returns the oracle's nearest points ``(B, 2)``. With a sweep
    (``meta["sweep"]``), each beam is taken from the robot pose at its own time (on the arc
    through the true poses of two stamps)."""
    sc, tr, b = log.scans, log.truth, log.bounds
    h = b["beam_angle"]
    out = tr.outliers["scans"]
    mx, my, myaw = sc.mount
    points = np.full((sc.ranges.shape[0], 2), np.nan)
    sweep = float(log.meta.get("sweep", 0.0))
    ref = float(tr.pose_stamp[0])
    for k in range(len(sc)):
        b0, b1 = int(sc.offsets[k]), int(sc.offsets[k + 1])
        f = sweep * np.arange(b1 - b0) / max(b1 - b0 - 1, 1)
        x, y, th = true_pose_at(tr, (float(sc.stamp[k]) - ref) + f, ref).T
        origin = np.column_stack([x + np.cos(th) * mx - np.sin(th) * my, y + np.sin(th) * mx + np.cos(th) * my])
        ang = th + myaw + (sc.angle_min[k] + np.arange(b1 - b0) * sc.angle_increment[k])
        d_hi, pts, delta = oracle(origin, ang, h, tr.world, rays)
        points[b0:b1] = pts
        z = sc.ranges[b0:b1].astype(np.float64)
        valid = sc.valid[b0:b1]
        ok_valid, ok_noreturn = valid.copy(), ~valid
        for d in bracket(d_hi, delta):  # the claims are convex in d: both ends of the bracket
            e = b["range_abs"] + b["range_rel"] * np.where(np.isfinite(d), d, 0)
            ok_valid &= np.abs(z - d) <= e
            ok_noreturn &= (d + e > sc.range_max[k]) | (d - e < sc.range_min[k])
        assert np.array_equal(ok_valid | ok_noreturn, ~out[b0:b1]), f"scan {k}"
        assert np.all(valid == ((z >= sc.range_min[k]) & (z <= sc.range_max[k])))
    return points


def check_stated_cone(log):
    """The log states the cone it was made with, and its cones touch (no gap for the pipeline)."""
    prof = get_profile(log.meta["sensor"]["name"])
    h = log.bounds["beam_angle"]
    inc = log.scans.angle_increment
    assert log.meta["beam_model"] == "cone" and h == prof.half_step()
    assert np.all(inc == np.float32(inc)) and np.all(2.0 * h >= inc)
    assert not np.any(2.0 * float(np.nextafter(h, -np.inf)) >= inc)  # the smallest such double
    cfg = resolve_config(None, {}, log_bounds=log.bounds)
    assert cfg["bounds.bearing"] == h and not np.any(inc > 2.0 * cfg["bounds.bearing"])


@given(st.integers(0, 2**31 - 1), st.sampled_from(BUILTIN), st.sampled_from(sorted(PROFILES)),
       st.sampled_from(["uniform", "triangular", "edges"]), st.sampled_from([0.0, 0.02]))
@settings(max_examples=examples(ci=20))
def test_every_simulated_cone_beam_satisfies_its_stated_bounds(seed, world, sensor, noise, outliers):
    log = simulate(SimConfig(scenario="lidar", world=world, sensor=sensor, seed=seed, steps=12, noise=noise,
                             outlier_rate=outliers))
    check_stated_cone(log)
    check_cone_log(log)
    assert log.scans.valid.any()


@given(st.integers(0, 2**31 - 1), st.sampled_from(BUILTIN), st.floats(0.01, 0.1))
@settings(max_examples=examples(ci=10))
def test_swept_cone_beams_satisfy_their_bounds_from_their_own_poses(seed, world, sweep):
    """``--sweep``: beam ``i`` of a scan is taken ``sweep · i / (n − 1)`` seconds after its stamp,
    from the robot pose then; at 0.5 m/s and up to 0.1 s that is centimetres from the stamp's."""
    log = simulate(SimConfig(scenario="lidar", world=world, seed=seed, steps=12, sweep=sweep))
    assert log.meta["sweep"] == sweep
    check_cone_log(log)
    still = simulate(SimConfig(scenario="lidar", world=world, seed=seed, steps=12))
    assert not np.array_equal(log.scans.ranges, still.scans.ranges)


@pytest.mark.parametrize("sensor,sweep,speed", [("urg-04lx", 0.0667, 0.5), ("sick", 0.2, 1.0)])
def test_a_swept_logs_default_cones_overlap_by_its_turn_between_beams(sensor, sweep, speed):
    """By default a swept log's cones are wide enough that its true motion between two beams
    leaves free space proven from ``SWEEP_FREE_FROM`` on (half a step: nowhere)."""
    from ivslam_cli.simulate.config import SWEEP_FREE_FROM
    from ivslam_cli.slam.lidar.free_cones import sweep_free_from

    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor=sensor, seed=2, steps=80, sweep=sweep,
                             speed=speed))
    prof = get_profile(sensor)
    h, inc = log.bounds["beam_angle"], prof.angle_increment
    assert prof.half_step() < h < 2.0 * prof.half_step()
    check_cone_log(log)
    p, dt = log.truth.pose, np.diff(log.truth.pose_stamp)
    turn = np.abs(np.diff(np.unwrap(p[:, 2]))) / dt
    move = np.hypot(*np.diff(p[:, :2], axis=0).T) / dt + turn * math.hypot(*prof.mount[:2])
    c = sweep / (prof.beams - 1)
    drift = np.column_stack([move, turn]) * c
    assert turn.max() > 0.5 and move.max() > 0.5 * speed  # it turned and drove
    s = sweep_free_from(drift, np.full(len(dt), inc), h, False)
    assert np.all(s <= SWEEP_FREE_FROM), s.max()
    assert np.all(np.isinf(sweep_free_from(drift[turn > 0.5], inc, prof.half_step(), False)))


def test_a_wider_stated_cone_is_simulated_and_a_narrower_one_refused():
    from ivslam_cli.errors import ConfigError

    log = simulate(SimConfig(scenario="lidar", world="pillars", sensor="sick", seed=3, steps=10,
                             bounds={"beam_angle": 0.02}, noise="edges"))
    assert log.bounds["beam_angle"] == 0.02
    check_cone_log(log)
    with pytest.raises(ConfigError, match="below half the beam step of sick"):
        SimConfig(scenario="lidar", sensor="sick", bounds={"beam_angle": 0.0087}).validate()
    with pytest.raises(ConfigError, match="< 0.5 rad"):
        SimConfig(scenario="lidar", bounds={"beam_angle": 0.6}).validate()
    SimConfig(scenario="lidar", sensor="sick", bounds={"beam_angle": 0.0}, beam_model="ray").validate()
    with pytest.raises(ConfigError, match="unknown beam model"):
        SimConfig(scenario="lidar", beam_model="fan").validate()


@pytest.mark.parametrize("fmt,name", [("h5", "c.h5"), ("mcap", "c.mcap"), ("ros1", "c.bag")])
def test_the_stated_cone_survives_the_log_formats(tmp_path, fmt, name):
    from ivslam_cli.logs import read_log
    from ivslam_cli.logs.writers import write_log

    log = simulate(SimConfig(scenario="lidar", world="rooms", seed=2, steps=8))
    write_log(tmp_path / name, log, fmt, force=False)
    back = read_log(tmp_path / name)
    assert back.bounds == log.bounds and back.meta["beam_model"] == "cone"
    assert np.array_equal(back.scans.ranges, log.scans.ranges)
    check_stated_cone(back)


# ---------------------------------------------------------------- the pipeline on cone logs
def _cells_meeting_walls(grid, world) -> tuple[int, int]:
    """(EMPTY cells of a result grid meeting a wall, EMPTY cells)."""
    from ivslam_cli.results.model import CELL_EMPTY
    from tests.helpers.lidar_world import segments_meet_cells

    rc = np.argwhere(grid.state == CELL_EMPTY)
    if rc.size == 0:
        return 0, 0
    shifted = world - np.tile(grid.origin, 2)  # cells (c, r) of side res from the grid's origin
    return int(segments_meet_cells(shifted, rc[:, ::-1], grid.resolution).sum()), int(rc.shape[0])


@pytest.mark.parametrize("world,sensor,seed", [("rooms", "urg-04lx", 1), ("pillars", "sick", 6)])
def test_cli_known_poses_prove_free_space_from_cone_logs_only(cli_run, tmp_path, world, sensor, seed):
    """``ivslam run LOG --mode lidar --poses-known`` with the log's own bounds: a cone log proves
    free space by default (no lidar.fill_gaps), none of it on a wall; the ray log of the same
    seed proves none (its gaps could hide an obstacle) and says so."""
    from ivslam_cli.logs import read_log
    from ivslam_cli.results.hdf5 import read_result

    area = {}
    for model in ("cone", "ray"):
        log_path, res_path = tmp_path / f"{model}.h5", tmp_path / f"r_{model}.h5"
        r = cli_run("simulate", "--scenario", "lidar", "--world", world, "--sensor", sensor, "--seed", seed,
                    "--steps", 40, "--noise", "edges", "--beam-model", model, "-o", log_path)
        assert r.exit_code == 0, r.output
        r = cli_run("run", log_path, "--mode", "lidar", "--poses-known", "-o", res_path)
        assert r.exit_code == 0, r.output
        res = read_result(res_path)
        area[model] = res.stats["area_empty_m2"]
        bad, n_empty = _cells_meeting_walls(res.grid, read_log(log_path).truth.world)
        assert bad == 0, f"{model}: {bad} of {n_empty} EMPTY cells meet a wall"
        gaps = "no free space proven" in res.consistency.assumption
        assert gaps == (model == "ray"), res.consistency.assumption
    assert area["cone"] > 0 and area["ray"] == 0, area


@pytest.mark.parametrize("world,sensor,seed,known", lanes([
    ("rooms", "urg-04lx", 3, False), ("corridor", "urg-04lx", 4, True), ("pillars", "sick", 6, False),
    ("open", "sick", 8, True), ("pillars", "urg-04lx", 9, True)], fast=[("corridor", "urg-04lx", 4, True)]))
def test_the_pipeline_keeps_the_truth_on_cone_logs(world, sensor, seed, known):
    """Dead reckoning from the true start, or known poses, without lidar.fill_gaps: every true
    pose in its box, no P_EMPTY cell on a wall, and every wall point the oracle finds at the
    nearest distance within an in-bound valid beam's cone in a P_OBSTACLE^k / P_OLD^k cell."""
    from ivslam_cli.slam.lidar import Params as LidarParams
    from ivslam_cli.slam.lidar.pipeline import run, solve
    from tests.helpers.lidar_truth import assert_contained, hits_outside_obstacle

    log = simulate(SimConfig(scenario="lidar", world=world, sensor=sensor, seed=seed, steps=50, noise="edges"))
    over = {"lidar.poses_known": True, "lidar.pose_margin": (0.02, 0.02, 0.005)} if known else {}
    cfg = resolve_config(None, {"landmarks.initial_pose_from_truth": True, **over}, log_bounds=log.bounds)
    assert cfg["lidar.fill_gaps"] is False
    params = LidarParams.from_config(cfg)
    out = solve(log, params)
    c = assert_contained(run(log, params), ("pose", "map_free"))
    assert c["map_free"][1] > 0
    pts = check_cone_log(log)
    missed, n = hits_outside_obstacle(log, out, pts)
    assert n > 0 and missed == 0, f"{missed} of {n} wall points outside P_OBSTACLE"


# ---------------------------------------------------------------- ray logs: reproducible
#: sha256 of the data of ray-cast logs (scans, odometry, truth, bounds: everything but meta) as
#: ivslam 6b98a5a generated them (x86-64, numpy 2.4): ``--beam-model ray`` must keep them
RAY_LOGS = {
    "97ffc2f039bcb6bbf04c13848836b520b2a85474272162b1910e90ffef8fb018":
        dict(world="rooms", sensor="urg-04lx", seed=3, steps=60),
    "5b5b83682c98490ab2f90182d68258e804f0e3272bd27745dfa4dba8e051ede5":
        dict(world="corridor", sensor="sick", seed=4, steps=100),
    "0fddafe2eef437cdd56cb617652a2eae115bdb72d5fa1d84486fce3f022aa839":
        dict(world="pillars", sensor="urg-04lx", seed=7, steps=80, noise="edges", outlier_rate=0.05),
    "824f772706a4b2d8a8039a86034fd6f66a2e18cacf12669471872e468b1e1c68":
        dict(world="open", sensor="sick", seed=2, steps=50, noise="triangular", outlier_rate=0.02,
             bounds={"beam_angle": 0.004}),
}


def log_digest(log) -> str:
    h = hashlib.sha256()
    for name in ("scans", "odometry", "truth"):
        for f, v in sorted(vars(getattr(log, name)).items()):
            if isinstance(v, np.ndarray):
                h.update(f"{name}.{f}".encode())
                h.update(np.ascontiguousarray(v).tobytes())
            elif isinstance(v, dict):
                for k in sorted(v):
                    h.update(f"{name}.{f}.{k}".encode())
                    h.update(np.ascontiguousarray(v[k]).tobytes())
    h.update(json.dumps(log.bounds, sort_keys=True).encode())
    return h.hexdigest()


@pytest.mark.parametrize("digest", sorted(RAY_LOGS))
def test_ray_model_reproduces_the_ray_cast_logs(digest):
    log = simulate(SimConfig(scenario="lidar", beam_model="ray", **RAY_LOGS[digest]))
    assert log.meta["beam_model"] == "ray" and log.meta["config"]["beam_model"] == "ray"
    assert log_digest(log) == digest
    kw = {k: v for k, v in RAY_LOGS[digest].items() if k != "bounds"}  # (0.004 rad is too narrow a cone)
    cone = simulate(SimConfig(scenario="lidar", **kw))  # the same draws, other distances
    assert np.array_equal(cone.truth.pose, log.truth.pose) and np.array_equal(cone.odometry.twist, log.odometry.twist)
    assert not np.array_equal(cone.scans.ranges, log.scans.ranges)
