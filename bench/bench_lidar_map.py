"""Benchmark: the LiDAR map update alone (P_OBSTACLE outer + P_EMPTY inner + old/new + write).

A simulated URG-04LX log (``ivslam simulate``'s ``urg-04lx`` profile: 682 beams over 239.4°,
10 Hz, 0.02-5.6 m) in the ``rooms`` world; every scan gets a robot pose box of half-widths
0.2 m, 0.2 m, 3° holding the true pose at a random place. Map at ε = 5 cm. Warm (numba
compiled on a short prefix first), one process, one core; each figure is the smallest wall
time of ``--repeat`` runs, each from an empty map (the machine may be shared: the load average
is printed beside the rates). Peak memory is the process's peak RSS growth during the timed
runs and the map's own arrays.

Reference: the cell-by-cell implementation (``lidar_kernel.update_log_reference``) on the same
log in the same process: its time gives the speed-up, and its map, old/new beams and counts
must equal the fast path's bit for bit (FAIL otherwise), as must the truth check of the
simulated log. Real time is the sensor's own rate (the URG-04LX's 683 values at 10 Hz, the
real-time budget of the "Guaranteed SLAM – practical considerations" slides), printed beside
the rates. Compare the ratio to the reference of the same run: the speed of a shared machine
varies between runs.

Target (issue #7): >= 400x real time, i.e. >= 400 * 6,830 = 2.73 M beams/s.

Pose sets (``lidar.map_sets``, unless ``--no-truth``): a log of cone beams (the simulator's
default), each scan mapped with its box and then with a union of 8 heading slices of it whose
(x, y) boxes are random sub-boxes (the truth in one): the cells ``map_union_free`` adds, its
time, and every P_EMPTY cell of that map against the true walls (FAIL if one meets a wall).

    python -m bench lidar_map         # as part of `make bench`
    python -m bench.bench_lidar_map [--scans N] [--repeat N] [--no-reference] [--no-truth]

Figures measured so far, with the commit of each, and the profile of the update:
docs/results.md.
"""

from __future__ import annotations

import argparse
import math
import os
import resource
import time

import numpy as np

EPS = 0.05
HALF_XY = 0.2
HALF_TH = math.radians(3.0)
SCANS = 1200  # 2 minutes of log
SEED_BUDGET = 6_830.0  # beams/s: the URG-04LX itself (683 values at 10 Hz)
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


def _run(kernel, scans, sboxes, bounds, exact: bool):
    """One update over the whole log from an empty map: (wall s, cpu s, map, is_old, stats)."""
    from ivslam_cli.paving.tiles import TileMap

    tmap = TileMap(EPS)
    is_old = np.zeros(scans.ranges.shape[0], dtype=np.bool_)
    stats = np.zeros((len(scans), 6), dtype=np.int64)
    order = np.arange(len(scans), dtype=np.int64)
    args = (scans.ranges, scans.valid, scans.offsets, np.ascontiguousarray(scans.angle_min, dtype=np.float64),
            np.ascontiguousarray(scans.angle_increment, dtype=np.float64), sboxes, order, bounds.range_abs,
            bounds.range_rel, bounds.bearing, EPS, exact, True, is_old, stats, True,
            np.zeros(len(scans)))
    t0, c0 = time.perf_counter(), time.process_time()
    arrays = kernel(*tmap.arrays(), *args)
    dt, dc = time.perf_counter() - t0, time.process_time() - c0
    tmap.set_arrays(*arrays)
    return dt, dc, tmap, is_old, stats


def _same(a, b) -> bool:
    """Bit-for-bit the same map (tiles in the same order, flags), old beams and counts."""
    ma, mb = a[2], b[2]
    return (ma.n == mb.n and np.array_equal(ma.coords[: ma.n], mb.coords[: mb.n])
            and np.array_equal(ma.cells[: ma.n], mb.cells[: mb.n]) and np.array_equal(a[3], b[3])
            and np.array_equal(a[4][:, 1:5], b[4][:, 1:5]))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.bench_lidar_map", description=__doc__.split("\n")[0])
    ap.add_argument("--scans", type=int, default=SCANS, help=f"scans of the simulated log (default {SCANS})")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of the fast path, the smallest kept (default 3)")
    ap.add_argument("--no-reference", action="store_true",
                    help="skip the cell-by-cell reference (its time and the equality check)")
    ap.add_argument("--no-truth", action="store_true", help="skip the truth check of the simulated log")
    args = ap.parse_args(argv)

    from ivslam_cli.simulate import SimConfig, simulate
    from ivslam_cli.slam.lidar import map_kernel as K
    from ivslam_cli.slam.lidar.map_update import STAT_FIELDS, LidarBounds, sensor_boxes, update_map
    from ivslam_cli.paving.tiles import TileMap

    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=7, steps=args.scans,
                             beam_model="ray"))
    scans = log.scans
    rng = np.random.default_rng(0)
    boxes = _boxes(rng, log.truth.pose)
    b = log.bounds
    # the simulator ray-casts: the gap assumption (lidar.fill_gaps) is stated so that free space
    # is computed, the heavier and usual path (URG-04LX steps of 0.35°)
    bounds = LidarBounds(b["range_abs"], b["range_rel"], b.get("beam_angle", 0.0), fill_gaps=True)
    sboxes = sensor_boxes(boxes, scans.mount)
    nb = int(scans.offsets[1] - scans.offsets[0])
    duration = float(scans.stamp[-1] - scans.stamp[0]) + 0.1
    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} CPUs, load average {load[0]:.2f} / {load[1]:.2f} (1 / 5 min) at start")
    print(f"log: {len(scans)} scans x {nb} beams ({scans.ranges.size:,} beams, "
          f"{100 * scans.valid.mean():.0f}% valid), {duration:.0f} s at 10 Hz; eps {EPS} m, "
          f"pose boxes ±{HALF_XY} m ±{math.degrees(HALF_TH):.0f}°; time = min of {args.repeat} run(s)")

    update_map(TileMap(EPS), scans, boxes, bounds, order=np.arange(min(5, len(scans))))  # compile / cache load
    ok = True
    for exact in (True, False):
        rss0 = _peak_rss_mb()
        runs = [_run(K.update_log, scans, sboxes, bounds, exact) for _ in range(max(1, args.repeat))]
        drss = _peak_rss_mb() - rss0
        best = min(runs, key=lambda r: r[0])
        dt, dc, tmap, is_old, stats = best
        bps = scans.ranges.size / dt
        rt = duration / dt
        mean = stats.mean(axis=0)
        c = tmap.counts()
        print(f"\nleaf test: {'beam by beam (exact)' if exact else 'window hull'}")
        print(f"  time {dt:.3f} s (cpu {dc:.3f} s) = {1e6 * dt / len(scans):.0f} us/scan; {bps:,.0f} beams/s; "
              f"real-time factor {rt:.1f}x; load average {os.getloadavg()[0]:.2f}")
        print("  per scan: " + ", ".join(f"{k} {v:,.0f}" for k, v in zip(STAT_FIELDS, mean)))
        print(f"  map: {tmap.n_tiles} tiles, {tmap.nbytes / 1e6:.1f} MB; empty {c['empty'] * EPS**2:.1f} m², "
              f"obstacle {c['obstacle'] * EPS**2:.1f} m²; old beams {is_old.sum() / max(1, scans.valid.sum()):.1%}"
              f" of valid; peak RSS growth {drss:.1f} MB")
        print(f"  seed budget {SEED_BUDGET:,.0f} beams/s: {'PASS' if bps >= SEED_BUDGET else 'FAIL'} "
              f"({bps / SEED_BUDGET:.1f}x)")
        verdict = bps >= TARGET
        print(f"  target >= 400x real time ({TARGET / 1e6:.2f} M beams/s): {'PASS' if verdict else 'FAIL'} "
              f"({rt / 400.0:.0%} of it)")
        if not args.no_reference:
            K.update_log_reference(*TileMap(EPS).arrays(), scans.ranges, scans.valid, scans.offsets,
                                   np.ascontiguousarray(scans.angle_min, dtype=np.float64),
                                   np.ascontiguousarray(scans.angle_increment, dtype=np.float64), sboxes[:3],
                                   np.arange(3, dtype=np.int64), bounds.range_abs, bounds.range_rel,
                                   bounds.bearing, EPS, exact, True, np.zeros(scans.ranges.shape[0], np.bool_),
                                   np.zeros((len(scans), 6), np.int64), True,
                                   np.zeros(len(scans)))  # compile / cache load
            ref = _run(K.update_log_reference, scans, sboxes, bounds, exact)
            same = _same(best, ref)
            print(f"  reference (cell by cell): {ref[0]:.3f} s = {scans.ranges.size / ref[0]:,.0f} beams/s "
                  f"({duration / ref[0]:.1f}x real time); fast path {ref[0] / dt:.1f}x faster; same map, old "
                  f"beams and counts: {'OK' if same else 'DIFFERENT'}")
            ok = ok and same
        if exact:
            ok = ok and verdict
            if not args.no_truth:
                be, ne, bh, nh = _soundness(log, tmap)
                print(f"  truth: {be} of {ne:,} P_EMPTY cells meet a wall (ray-cast sensor: the gap between "
                      f"beams taken as free under the stated lidar.fill_gaps assumption, see lidar_geometry); {bh} of {nh:,} true hit points "
                      f"outside ∪P_OBSTACLE^k ∪ P_OLD^k: {'OK' if be == 0 and bh == 0 else 'VIOLATED'}")
                ok = ok and be == 0 and bh == 0
    if not args.no_truth:
        ok = _pose_sets(args.scans) and ok
    print(f"\nload average at the end {os.getloadavg()[0]:.2f}")
    return 0 if ok else 1


SLICES = 8


def slices_around(rng: np.random.Generator, box: np.ndarray, pose: np.ndarray, m: int = SLICES) -> np.ndarray:
    """``box`` cut into ``m`` heading slices, each with a random (x, y) sub-box of it; the slice
    holding the true heading keeps the true position (a union that holds the truth)."""
    edges = np.linspace(box[4], box[5], m + 1)
    u = np.tile(box, (m, 1))
    u[:, 4], u[:, 5] = edges[:-1], edges[1:]
    for i in range(m):
        for a in range(2):
            lo, hi = np.sort(rng.uniform(box[2 * a], box[2 * a + 1], 2))
            if u[i, 4] <= pose[2] <= u[i, 5]:
                lo, hi = min(lo, pose[a]), max(hi, pose[a])
            u[i, 2 * a], u[i, 2 * a + 1] = lo, hi
    return u


def _pose_sets(n_scans: int) -> bool:
    """``lidar.map_sets`` on a log of cone beams (the simulator's default: every beam the nearest
    surface in its cone, so no gap assumption): each scan mapped with its box, then with a union
    of slices of it (:func:`slices_around`) by ``map_union_free``; the cells it adds, its time, and
    every P_EMPTY cell of the map against the true walls."""
    from ivslam_cli.paving.tiles import TileMap
    from ivslam_cli.simulate import SimConfig, simulate
    from ivslam_cli.slam.lidar.map_update import LidarBounds, map_union_free, update_map

    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=7, steps=n_scans))
    scans, b = log.scans, log.bounds
    bounds = LidarBounds(b["range_abs"], b["range_rel"], b["beam_angle"])
    boxes = _boxes(np.random.default_rng(0), log.truth.pose)
    rng = np.random.default_rng(1)
    unions = [slices_around(rng, boxes[k], log.truth.pose[k]) for k in range(len(scans))]
    map_union_free(TileMap(EPS), scans, 0, unions[0], bounds)  # compile / cache load
    tmap = TileMap(EPS)
    one = np.zeros(1, np.int64)
    t_hull = t_sets = 0.0
    added = 0
    for k in range(len(scans)):
        one[0] = k
        t0 = time.perf_counter()
        update_map(tmap, scans, boxes, bounds, order=one)
        t1 = time.perf_counter()
        added += map_union_free(tmap, scans, k, unions[k], bounds)
        t_sets += time.perf_counter() - t1
        t_hull += t1 - t0
    c = tmap.counts()["empty"]
    d = tmap.dense(raw=True)
    empty = np.argwhere(d.data & 1) + [d.i0, d.j0]
    bad = int(_segments_meet_cells(log.truth.world, empty, EPS).sum()) if empty.size else 0
    print(f"\npose sets (lidar.map_sets), a log of cone beams: each box cut into {SLICES} heading slices with "
          f"random (x, y) sub-boxes, the truth in one")
    print(f"  map_union_free added {added:,} cells to the boxes' {c - added:,} (+{added / max(1, c - added):.1%}) in "
          f"{t_sets:.3f} s, beside {t_hull:.3f} s for the boxes' own updates (scan by scan)")
    print(f"  truth: {bad} of {empty.shape[0]:,} P_EMPTY cells meet a wall: {'OK' if bad == 0 else 'VIOLATED'}")
    return bad == 0


if __name__ == "__main__":
    raise SystemExit(main())
