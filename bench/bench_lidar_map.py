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
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
