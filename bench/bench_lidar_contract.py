"""Benchmark: pose contraction against the map (``slam.lidar.contract.contract_pose``), fast path
against the reference (hash lookups cell by cell), on three cases:

- ``sim``: a simulated URG-04LX log (``ivslam simulate``'s ``urg-04lx`` profile, 682 beams over
  239.4°, ``rooms`` world, ray-cast sensor with ``lidar.fill_gaps``); the map is built from the
  first ``--map-scans`` scans at known poses (boxes ±1 cm, ±0.1° around the truth), then every
  later scan is contracted from a box of half-widths 0.2 m, 0.2 m, 3° holding its true pose
  (checked: the truth stays in every contracted box).
- ``exp1``: ``../shared/datasets/breezyslam_mines/exp1.dat.xz`` with ``configs/exp1.toml``: the
  map from the first ``--map-scans`` scans at the odometry poses (boxes ±2 cm, ±0.3°), then the
  next scans contracted from boxes of half-widths 0.2 m, 0.2 m, 3° around the odometry pose
  (the odometry is not the truth: a box may miss it; this case measures time).
- ``pipeline``: ``ivslam run exp1 --mode lidar --config configs/exp1.toml``'s own calls (the
  dead-reckoned boxes of the track-and-map pass as they are, metres wide late in the log):
  every call of the run timed with the fast path; every ``--every``-th call replayed with both
  (a copy of the map at that call).

Settings as in the pipeline: ``lidar.contract_boxes`` = 1024, ``contract_stride`` = 2,
``q_beams`` = 5, ε = 5 cm. Warm (numba compiled first), one process, one core; each figure is
the smallest wall time of ``--repeat`` runs over the case's scans (the machine may be shared:
the load average is printed).

Reference: the cell-by-cell implementation on the same calls in the same process; kept count,
hull and tested count must be the same for every call (FAIL otherwise).

Target (issue #7): the whole LiDAR run at >= 100x real time, ~1 ms per scan in all, of which
the map update takes ~0.3 ms: the contraction should take well under 1 ms per scan when
boxes are a few decimetres wide (the ``sim`` and ``exp1`` cases).

    python -m bench lidar_contract    # as part of `make bench`
    python -m bench.bench_lidar_contract [--case sim|exp1|pipeline] [--no-reference]
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np

EPS = 0.05
HALF_XY = 0.2
HALF_TH = math.radians(3.0)
Q, STRIDE, BUDGET = 5, 2, 1024
TARGET_US = 1000.0  # per scan, the whole run's budget at 100x real time (10 Hz)
EXP1 = Path(__file__).resolve().parents[2] / "shared" / "datasets" / "breezyslam_mines" / "exp1.dat.xz"
CONFIG = Path(__file__).resolve().parents[1] / "configs" / "exp1.toml"


def _box_around(rng, pose, hxy, hth):
    """A box of half-widths (hxy, hxy, hth) holding ``pose`` at a random place."""
    hw = np.array([hxy, hxy, hth])
    lo = pose - 2.0 * hw * rng.uniform(0.0, 1.0, 3)
    return np.array([lo[0], lo[0] + 2 * hw[0], lo[1], lo[1] + 2 * hw[1], lo[2], lo[2] + 2 * hw[2]])


def _sim_case(n_map: int, n_test: int):
    from ivslam_cli.paving.tiles import TileMap
    from ivslam_cli.simulate import SimConfig, simulate
    from ivslam_cli.slam.lidar.map_update import LidarBounds, update_map

    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=7, steps=n_map + n_test))
    scans, truth = log.scans, log.truth.pose
    b = log.bounds
    bounds = LidarBounds(b["range_abs"], b["range_rel"], b.get("beam_angle", 0.0), fill_gaps=True)
    rng = np.random.default_rng(0)
    tmap = TileMap(EPS)
    tight = np.array([_box_around(rng, p, 0.01, math.radians(0.1)) for p in truth])
    update_map(tmap, scans, tight, bounds, order=np.arange(n_map))
    calls = [(tmap, int(k), _box_around(rng, truth[k], HALF_XY, HALF_TH)) for k in range(n_map, len(scans))]
    return scans, bounds, calls, truth


def _exp1_case(n_map: int, n_test: int):
    from ivslam_cli.config import resolve_config
    from ivslam_cli.logs import read_log
    from ivslam_cli.paving.tiles import TileMap
    from ivslam_cli.slam.lidar import Params
    from ivslam_cli.slam.lidar.map_update import update_map, usable_scans
    from ivslam_cli.slam.lidar.prediction import predict_poses

    log = read_log(EXP1)
    cfg = resolve_config(CONFIG, {"lidar.poses_known": True, "lidar.known_poses": "odometry",
                                  "lidar.pose_margin": (0.02, 0.02, math.radians(0.3))}, log_bounds=log.bounds)
    params = Params.from_config(cfg)
    bounds = params.beams
    scans, _ = usable_scans(log.scans, bounds, params.max_range, params.eps)
    pred = predict_poses(log, params, scans)
    used, boxes = pred.used, pred.boxes
    tmap = TileMap(EPS)
    all_boxes = np.zeros((len(scans), 6))
    all_boxes[used] = boxes
    update_map(tmap, scans, all_boxes, bounds, order=used[:n_map])
    rng = np.random.default_rng(0)
    centre = 0.5 * (boxes[:, 0::2] + boxes[:, 1::2])
    calls = [(tmap, int(used[j]), _box_around(rng, centre[j], HALF_XY, HALF_TH))
             for j in range(n_map, min(used.size, n_map + n_test))]
    return scans, bounds, calls


def _pipeline_case(every: int):
    """Run exp1's track-and-map pass; returns (scans, bounds, sampled calls, per-call fast times,
    per-call box widths)."""
    import ivslam_cli.slam.lidar.tracking as LC
    from ivslam_cli.config import resolve_config
    from ivslam_cli.logs import read_log
    from ivslam_cli.paving.tiles import TileMap
    from ivslam_cli.slam.lidar import Params as LidarParams
    from ivslam_cli.slam.lidar.map_update import usable_scans
    from ivslam_cli.slam.lidar.pipeline import solve

    log = read_log(EXP1)
    cfg = resolve_config(CONFIG, {}, log_bounds=log.bounds)
    params = LidarParams.from_config(cfg)
    bounds = params.beams
    scans, _ = usable_scans(log.scans, bounds, params.max_range, params.eps)
    orig = LC.contract_pose
    times, widths, calls = [], [], []

    def timed(tmap, scans_, k, box, bounds_, **kw):
        t0 = time.perf_counter()
        r = orig(tmap, scans_, k, box, bounds_, **kw)
        times.append(time.perf_counter() - t0)
        widths.append(max(box[1] - box[0], box[3] - box[2]))
        if len(times) % every == 1 or every == 1:
            snap = TileMap(tmap.eps)
            snap.set_arrays(*(a.copy() if isinstance(a, np.ndarray) else a for a in tmap.arrays()))
            calls.append((snap, int(k), np.array(box, float)))
        return r

    LC.contract_pose = timed
    try:
        solve(log, LidarParams.from_config(cfg))
    finally:
        LC.contract_pose = orig
    return scans, bounds, calls, np.array(times), np.array(widths)


def _time(calls, scans, bounds, reference: bool, repeat: int):
    from ivslam_cli.slam.lidar.contract import contract_pose

    best, outs = math.inf, None
    for _ in range(max(1, repeat)):
        res = []
        t0 = time.perf_counter()
        for tmap, k, box in calls:
            res.append(contract_pose(tmap, scans, k, box, bounds, q=Q, stride=STRIDE, max_boxes=BUDGET,
                                     reference=reference))
        best = min(best, time.perf_counter() - t0)
        outs = res
    return best, outs


def _report(name, calls, scans, bounds, repeat, no_reference, truth=None) -> bool:
    from ivslam_cli.slam.lidar.contract import contract_pose

    tm, k, box = calls[0]
    for ref in (False, True):  # compile / cache load
        contract_pose(tm, scans, k, box, bounds, q=Q, stride=STRIDE, max_boxes=BUDGET, reference=ref)
    dt, outs = _time(calls, scans, bounds, False, repeat)
    n = len(calls)
    tested = sum(o[2] for o in outs)
    kept = np.array([o[1] for o in outs])
    w0 = np.array([max(b[1] - b[0], b[3] - b[2]) for _, _, b in calls])
    w1 = np.array([max(o[0][1] - o[0][0], o[0][3] - o[0][2]) for o in outs])
    print(f"  {n} scans, {tested / n:.0f} boxes tested per scan, median box {np.median(w0):.2f} m -> "
          f"{np.median(w1[kept > 0]) if (kept > 0).any() else float('nan'):.2f} m, "
          f"{int((kept == 0).sum())} contradicting the map")
    print(f"  fast path: {1e6 * dt / n:,.0f} us/scan, {1e9 * dt / tested:,.0f} ns/box test; "
          f"load average {os.getloadavg()[0]:.2f}")
    ok = True
    if truth is not None:
        inside = sum(bool(np.all(o[0][0::2] <= truth[c[1]]) and np.all(truth[c[1]] <= o[0][1::2]))
                     for o, c in zip(outs, calls))
        print(f"  truth inside the contracted box: {inside} of {n}: {'OK' if inside == n else 'VIOLATED'}")
        ok = inside == n
    if not no_reference:
        rt, routs = _time(calls, scans, bounds, True, 1)
        same = all(a[1] == b[1] and a[2] == b[2] and np.array_equal(a[0], b[0]) for a, b in zip(outs, routs))
        print(f"  reference: {1e6 * rt / n:,.0f} us/scan, {1e9 * rt / tested:,.0f} ns/box test; fast path "
              f"{rt / dt:.1f}x faster; same kept, hull and tested for every scan: {'OK' if same else 'DIFFERENT'}")
        ok = ok and same
    return ok, 1e6 * dt / n


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.bench_lidar_contract", description=__doc__.split("\n")[0])
    ap.add_argument("--case", choices=["sim", "exp1", "pipeline"], action="append",
                    help="case(s) to run (default: all; pipeline and exp1 need the exp1 dataset)")
    ap.add_argument("--map-scans", type=int, default=50, help="scans in the map of sim / exp1 (default 50)")
    ap.add_argument("--scans", type=int, default=100, help="scans contracted in sim / exp1 (default 100)")
    ap.add_argument("--every", type=int, default=10,
                    help="pipeline: every n-th call replayed with both implementations (default 10)")
    ap.add_argument("--repeat", type=int, default=3, help="timed runs of the fast path, the smallest kept (default 3)")
    ap.add_argument("--no-reference", action="store_true", help="skip the reference (its time and the equality check)")
    args = ap.parse_args(argv)
    cases = args.case or ["sim", "exp1", "pipeline"]
    if not EXP1.exists() and ("exp1" in cases or "pipeline" in cases):
        print(f"{EXP1} not found: exp1 and pipeline cases skipped")
        cases = [c for c in cases if c == "sim"]

    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} CPUs, load average {load[0]:.2f} / {load[1]:.2f} (1 / 5 min) at start")
    print(f"contraction: q {Q}, stride {STRIDE}, budget {BUDGET} boxes, eps {EPS} m; time = min of {args.repeat} "
          f"run(s); target well under {TARGET_US:,.0f} us/scan with boxes a few decimetres wide")
    ok = True
    for case in cases:
        if case == "sim":
            scans, bounds, calls, truth = _sim_case(args.map_scans, args.scans)
            print(f"\nsim: URG-04LX rooms log, map of {args.map_scans} scans at known poses, boxes ±{HALF_XY} m "
                  f"±{math.degrees(HALF_TH):.0f}° holding the truth")
            good, us = _report(case, calls, scans, bounds, args.repeat, args.no_reference, truth)
            print(f"  target: {'PASS' if us < TARGET_US else 'FAIL'}")
            ok = ok and good and us < TARGET_US
        elif case == "exp1":
            scans, bounds, calls = _exp1_case(args.map_scans, args.scans)
            print(f"\nexp1: map of {args.map_scans} scans at odometry poses, boxes ±{HALF_XY} m "
                  f"±{math.degrees(HALF_TH):.0f}° around the odometry pose")
            good, us = _report(case, calls, scans, bounds, args.repeat, args.no_reference)
            print(f"  target: {'PASS' if us < TARGET_US else 'FAIL'}")
            ok = ok and good and us < TARGET_US
        else:
            scans, bounds, calls, times, widths = _pipeline_case(args.every)
            if times.size == 0:
                print("\npipeline: exp1's track-and-map pass made no contraction call")
                continue
            print(f"\npipeline: exp1's track-and-map pass, {times.size} calls in {times.sum():.3f} s "
                  f"({1e6 * times.mean():,.0f} us/call mean, {1e6 * np.median(times):,.0f} median, "
                  f"{1e6 * times.max():,.0f} max, the first loading the compiled kernels; boxes "
                  f"{np.median(widths):.2f} m median, {np.percentile(widths, 10):.2f}-{np.percentile(widths, 90):.2f}"
                  f" m 10-90 %); every {args.every}-th call replayed:")
            good, _ = _report(case, calls, scans, bounds, args.repeat, args.no_reference)
            ok = ok and good
    print(f"\nload average at the end {os.getloadavg()[0]:.2f}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
