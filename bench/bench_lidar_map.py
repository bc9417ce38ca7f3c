"""Benchmark: the LiDAR map update alone (P_OBSTACLE outer + P_EMPTY inner + old/new + write).

A simulated URG-04LX log (``ivslam simulate``'s ``urg-04lx`` profile: 682 beams over 239.4°,
10 Hz, 0.02-5.6 m) in the ``rooms`` world; every scan gets a robot pose box of half-widths
0.2 m, 0.2 m, 3° holding the true pose at a random place. Map at ε = 5 cm. Warm (numba
compiled on a short prefix first), one process, one core.

Target (issue #7): >= 400x real time, i.e. >= 400 * 6,800 = 2.72 M beams/s; the seed's own
budget (the sensor's rate, 6,800 beams/s) is printed beside it. Peak memory is the process's
peak RSS growth during the timed run and the map's own arrays.
"""

from __future__ import annotations

import math
import resource
import time

import numpy as np

EPS = 0.05
HALF_XY = 0.2
HALF_TH = math.radians(3.0)
SCANS = 1200  # 2 minutes of log
SEED_BUDGET = 6_800.0  # beams/s: the URG-04LX itself (680 beams at 10 Hz)
TARGET = 400.0 * SEED_BUDGET


def _boxes(rng: np.random.Generator, pose: np.ndarray) -> np.ndarray:
    f = rng.uniform(0.0, 1.0, pose.shape)
    hw = np.array([HALF_XY, HALF_XY, HALF_TH])
    lo = pose - 2.0 * hw * f
    hi = lo + 2.0 * hw
    return np.column_stack([lo[:, 0], hi[:, 0], lo[:, 1], hi[:, 1], lo[:, 2], hi[:, 2]])


def _segments_meet_cells(segs: np.ndarray, cells: np.ndarray, eps: float) -> np.ndarray:
    """Whether each closed cell (grown by 1e-9 m, the safe side) meets a segment (Liang-Barsky)."""
    lo = cells[:, None, :] * eps - 1e-9
    hi = (cells[:, None, :] + 1) * eps + 1e-9
    a, d = segs[None, :, :2], segs[None, :, 2:] - segs[None, :, :2]
    t0 = np.zeros((cells.shape[0], segs.shape[0]))
    t1 = np.ones_like(t0)
    ok = np.ones_like(t0, dtype=bool)
    for ax in range(2):
        dd, aa = np.broadcast_to(d[..., ax], t0.shape), np.broadcast_to(a[..., ax], t0.shape)
        par = dd == 0
        ok &= ~par | ((aa >= lo[..., ax]) & (aa <= hi[..., ax]))
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (lo[..., ax] - aa) / dd, (hi[..., ax] - aa) / dd
        t0 = np.where(par, t0, np.maximum(t0, np.minimum(ta, tb)))
        t1 = np.where(par, t1, np.minimum(t1, np.maximum(ta, tb)))
    return np.any(ok & (t0 <= t1), axis=1)


def _soundness(log, tmap) -> tuple[int, int, int, int]:
    """(P_EMPTY cells meeting a true wall, of how many; true hit points of valid in-bound beams
    outside every cell ever marked P_OBSTACLE^k or P_OLD^k, of how many)."""
    from ivslam_cli.simulate.lidar import laser_poses
    from ivslam_cli.simulate.raycast import cast

    scans, segs = log.scans, log.truth.world
    d = tmap.dense(raw=True)
    empty = np.argwhere(d.data & 1) + [d.i0, d.j0]
    bad_empty = int(_segments_meet_cells(segs, empty, EPS).sum()) if empty.size else 0
    nb = int(scans.offsets[1] - scans.offsets[0])
    lp = laser_poses(log.truth.pose, scans.mount)
    ang = scans.angle_min[0] + scans.angle_increment[0] * np.arange(nb)
    dist = cast(lp, ang, segs)
    use = scans.valid.reshape(-1, nb) & ~log.truth.outliers["scans"].reshape(-1, nb) & np.isfinite(dist)
    world = lp[:, 2:3] + ang[None, :]
    px = lp[:, 0:1] + dist * np.cos(world)
    py = lp[:, 1:2] + dist * np.sin(world)
    px, py = px[use], py[use]
    missed = np.ones(px.shape[0], dtype=bool)
    for ox in (-1e-9, 0.0, 1e-9):  # a point on a cell border belongs to both cells
        for oy in (-1e-9, 0.0, 1e-9):
            f = tmap.get(np.floor(px / EPS + ox).astype(np.int64), np.floor(py / EPS + oy).astype(np.int64))
            missed &= (f & 6) == 0
    return bad_empty, int(empty.shape[0]), int(missed.sum()), int(px.shape[0])


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main() -> int:
    from ivslam_cli.paving.tiles import TileMap
    from ivslam_cli.simulate import SimConfig, simulate
    from ivslam_cli.slam.lidar_map import STAT_FIELDS, LidarBounds, update_map

    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=7, steps=SCANS))
    scans = log.scans
    rng = np.random.default_rng(0)
    boxes = _boxes(rng, log.truth.pose)
    b = log.bounds
    bounds = LidarBounds(b["range_abs"], b["range_rel"], b.get("beam_angle", 0.0))
    nb = int(scans.offsets[1] - scans.offsets[0])
    duration = float(scans.stamp[-1] - scans.stamp[0]) + 0.1
    print(f"log: {len(scans)} scans x {nb} beams ({scans.ranges.size:,} beams, "
          f"{100 * scans.valid.mean():.0f}% valid), {duration:.0f} s at 10 Hz; eps {EPS} m, "
          f"pose boxes ±{HALF_XY} m ±{math.degrees(HALF_TH):.0f}°")

    update_map(TileMap(EPS), scans, boxes, bounds, order=np.arange(5))  # compile / cache load
    rows = []
    for exact in (True, False):
        rss0 = _peak_rss_mb()
        tmap = TileMap(EPS)
        t0 = time.perf_counter()
        res = update_map(tmap, scans, boxes, bounds, exact=exact)
        dt = time.perf_counter() - t0
        rows.append((exact, dt, res, tmap, _peak_rss_mb() - rss0))
    ok = True
    for exact, dt, res, tmap, drss in rows:
        bps = scans.ranges.size / dt
        rt = duration / dt
        mean = res.stats.mean(axis=0)
        c = tmap.counts()
        print(f"\nleaf test: {'beam by beam (exact)' if exact else 'window hull'}")
        print(f"  time {dt:.2f} s = {1e6 * dt / len(scans):.0f} us/scan; {bps:,.0f} beams/s; "
              f"real-time factor {rt:.1f}x")
        print(f"  per scan: " + ", ".join(f"{k} {v:,.0f}" for k, v in zip(STAT_FIELDS, mean)))
        print(f"  map: {tmap.n_tiles} tiles, {tmap.nbytes / 1e6:.1f} MB; empty {c['empty'] * EPS**2:.1f} m², "
              f"obstacle {c['obstacle'] * EPS**2:.1f} m²; old beams {res.is_old.sum() / max(1, scans.valid.sum()):.1%}"
              f" of valid; peak RSS growth {drss:.1f} MB")
        print(f"  seed budget {SEED_BUDGET:,.0f} beams/s: {'PASS' if bps >= SEED_BUDGET else 'FAIL'} "
              f"({bps / SEED_BUDGET:.1f}x)")
        verdict = bps >= TARGET
        print(f"  target >= 400x real time ({TARGET / 1e6:.2f} M beams/s): {'PASS' if verdict else 'FAIL'}")
        if exact:
            ok = verdict
            be, ne, bh, nh = _soundness(log, tmap)
            print(f"  truth: {be} of {ne:,} P_EMPTY cells meet a wall (ray-cast sensor: the gap between "
                  f"beams is covered by interpolation, see lidar_geometry); {bh} of {nh:,} true hit points "
                  f"outside ∪P_OBSTACLE^k ∪ P_OLD^k: {'OK' if be == 0 and bh == 0 else 'VIOLATED'}")
            ok = ok and be == 0 and bh == 0
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
