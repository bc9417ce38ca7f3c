"""Scenario ``lidar``: unicycle with twist odometry and a 2D LiDAR in a wall world.

The true distance of a beam is that of the nearest wall point within its cone (``cone``,
:mod:`.conecast`, half-width the stated ``beam_angle``) or along its nominal ray (``ray``,
:mod:`.raycast`); both draw the same random numbers in the same order.
"""

from __future__ import annotations

import math

import numpy as np

from ivslam_cli.errors import ConfigError
from ivslam_cli.logs.model import GroundTruth, LogData, Provenance, Scans
from ivslam_cli.simulate import noise
from ivslam_cli.simulate.common import base_meta
from ivslam_cli.simulate.conecast import cone_cast, swept_cone_scans
from ivslam_cli.simulate.config import TURN_RATE_MAX, SimConfig
from ivslam_cli.simulate.motion import T0, make_stamps, step_scalar
from ivslam_cli.simulate.odometry import measure_twist
from ivslam_cli.simulate.raycast import cast
from ivslam_cli.simulate.sensors import LidarProfile, get_profile
from ivslam_cli.simulate.worlds import World, load_world, point_segments_distance, segments_cross

CLEARANCE = 0.3  # the robot keeps this far from every wall [m]
_PROBES = np.linspace(-math.pi / 2, math.pi / 2, 13)


def wander(rng: np.random.Generator, world: World, stamp: np.ndarray, speed: float,
           progress=None) -> tuple[np.ndarray, np.ndarray]:
    """Wander without touching walls: true poses ``(T, 3)`` and twists ``(T, 2)``.

    Random-walk turn rate; when a wall is ahead it slows and turns towards the clearer
    side; a step that would come closer than ``CLEARANCE`` to a wall (or cross one)
    becomes a turn on the spot, which is always safe.
    """
    n = stamp.shape[0]
    pose, twist = np.empty((n, 3)), np.empty((n, 2))
    segs = world.segments
    x, y, th = world.start
    w_rand, turn, w_max = 0.0, 0, TURN_RATE_MAX
    for k in range(n):
        pose[k] = x, y, th
        probe = cast(np.array([x, y, th]), _PROBES, segs)[0]
        front = probe[np.abs(_PROBES) <= 0.6].min()
        if front < 1.2:
            if turn == 0:
                turn = 1 if probe[_PROBES > 0].mean() >= probe[_PROBES < 0].mean() else -1
            v = speed * min(1.0, max(0.0, (front - 0.6) / 0.6))
            w = turn * w_max
        else:
            turn = 0
            w_rand = 0.9 * w_rand + rng.normal(0.0, 0.1)
            w_rand = max(-0.6, min(0.6, w_rand))
            v, w = speed, w_rand
        if k + 1 < n:
            dt = stamp[k + 1] - stamp[k]
            nxt = step_scalar(x, y, th, v, w, dt)
            if v > 0 and (point_segments_distance(np.array(nxt[:2]), segs).min() < CLEARANCE
                          or segments_cross(np.array([x, y]), np.array(nxt[:2]), segs)[0]):
                turn = turn or 1
                v, w = 0.0, turn * w_max
                nxt = step_scalar(x, y, th, v, w, dt)
            x, y, th = nxt
        twist[k] = v, w
        if progress and k % 1000 == 999:
            progress(1000)
    return pose, twist


def laser_poses(pose: np.ndarray, mount: tuple[float, float, float]) -> np.ndarray:
    """Sensor poses ``pose (+) mount``."""
    c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
    return np.column_stack([pose[:, 0] + c * mount[0] - s * mount[1],
                            pose[:, 1] + s * mount[0] + c * mount[1], pose[:, 2] + mount[2]])


def scan(rng: np.random.Generator, d: np.ndarray, prof: LidarProfile, bounds: dict[str, float],
         kind: str, outlier_rate: float, outlier_magnitude: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noisy float32 ranges from true distances ``d`` (flat): ``(ranges, valid, outlier)``."""
    m = d.shape[0]
    hit = d <= prof.range_max
    dd = np.where(hit, d, 0.0)
    b = bounds["range_abs"] + bounds["range_rel"] * dd
    z = dd + noise.bounded(rng, b, kind, m)
    # outliers: phantom returns, short of the true range or where there is nothing
    out = noise.pick(rng, outlier_rate, m)
    short = dd + noise.outlier(rng, b, outlier_magnitude, m, sign=-np.ones(m))
    b_max = bounds["range_abs"] + bounds["range_rel"] * prof.range_max
    phantom = rng.uniform(prof.range_min, max(prof.range_min, prof.range_max - 2.0 * b_max), m)
    out &= ~hit | (short >= prof.range_min)
    z = np.where(out, np.where(hit, short, phantom), z)
    z32 = z.astype(np.float32)
    inb = hit & ~out
    if not np.all(np.abs(z32[inb].astype(np.float64) - d[inb]) <= b[inb]):
        raise ConfigError("range bound too small for float32 LaserScan ranges (use >= 1e-3 m)")
    valid = (hit | out) & (z32 >= np.float32(prof.range_min)) & (z32 <= np.float32(prof.range_max))
    if prof.no_return == "zero":
        bad = np.float32(0.0)
    else:  # REP 117
        bad = np.where(z32 < np.float32(prof.range_min), np.float32(-np.inf), np.float32(np.inf))
    return np.where(valid, z32, bad).astype(np.float32), valid, out


def simulate_lidar(cfg: SimConfig, progress=None) -> LogData:
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(cfg.seed).spawn(4)]
    prof = get_profile(cfg.sensor)
    world = load_world(cfg.world)
    rate = cfg.resolved_rate(prof.rate)
    n = cfg.resolved_steps(rate)
    stamp = make_stamps(T0, rate, n)
    bounds = cfg.resolved_bounds()
    pose, twist = wander(rngs[0], world, stamp, cfg.speed, progress)
    odo, odo_out = measure_twist(rngs[3], stamp, pose[0], twist, bounds, cfg.noise,
                                 cfg.outlier_rate, cfg.outlier_magnitude)
    sensor_pose = laser_poses(pose, prof.mount)
    if cfg.sweep > 0.0:
        # each beam from the robot pose at its own time, on the arc the robot drives (after the
        # last stamp, the last step's)
        beam_time = np.linspace(0.0, cfg.sweep, prof.beams)
        held = twist.copy()
        if n > 1:
            held[-1] = twist[-2]
        d = swept_cone_scans(pose, held, stamp - stamp[0], np.asarray(prof.mount, float), prof.beam_angles(),
                             beam_time, float(bounds["beam_angle"]),
                             np.ascontiguousarray(world.segments, float)).ravel()
    elif cfg.beam_model == "cone":
        d = cone_cast(sensor_pose, prof.beam_angles(), bounds["beam_angle"], world.segments).ravel()
    else:
        d = cast(sensor_pose, prof.beam_angles(), world.segments).ravel()
    ranges, valid, out = scan(rngs[2], d, prof, bounds, cfg.noise, cfg.outlier_rate, cfg.outlier_magnitude)
    full = np.ones(n)
    scans = Scans(stamp=stamp.copy(), angle_min=full * prof.angle_min,
                  angle_increment=full * prof.angle_increment, range_min=full * prof.range_min,
                  range_max=full * prof.range_max,
                  offsets=np.arange(n + 1, dtype=np.int64) * prof.beams, ranges=ranges, valid=valid,
                  mount=prof.mount, frame_id="laser",
                  time_increment=full * (cfg.sweep / (prof.beams - 1)) if cfg.sweep > 0.0 else None)
    meta = base_meta(cfg, rate, n) | {"sensor": prof.as_dict(), "beam_model": cfg.beam_model, "sweep": cfg.sweep,
                                      "world": world.name, "clearance": CLEARANCE}
    truth = GroundTruth(pose_stamp=stamp.copy(), pose=pose, world=world.segments.copy(),
                        outliers={"scans": out, "odometry": odo_out})
    if progress:
        progress(n % 1000)
    return LogData(provenance=Provenance(path="<simulated>", format="simulated",
                                         topics={"scans": "/scan", "odometry": "/odom",
                                                 "truth": "/ground_truth"}),
                   scans=scans, odometry=odo, truth=truth, bounds=bounds, meta=meta)
