"""Benchmark (issue #17): the floor of the landmark CSP on the simulated demo log, measured from
below, beside our widths.

The demo log (``ivslam simulate --scenario landmarks --seed 3 --steps 300 --outlier-rate 0.01``)
and its outlier-free twin (the same without ``--outlier-rate``), each run as the README runs it
(``--initial-pose-from-truth --q-landmark 2 --q-pose 1``) and with the true map given. At nodes
drawn at random, *witnesses* (:mod:`bench.landmark_witness_steps`): worlds — a path of held
twists within the twist bounds, a first pose in the initial box, a map — that meet every bound,
pushed to the extremes of the node's pose (with the map given, witnesses keep the true map).
Every sound enclosure holds them, so their spread is a lower bound of what any sound method can
reach there:

- **floor, every bound**: the witnesses meet every observation the truth meets;
- **floor under q**: they may also break what the run's q allows (``q_pose`` at a step,
  ``q_landmark`` of a landmark's observations, the truth's outliers counted): the floor under
  the run's whole assumption, the one its boxes must hold. Two choices of what to break, both
  witnesses: the observations nearest the node, and those the linear programs' duals say hold
  the push most (one at a time, as the caps allow); the floor spans both.

Printed per log and run (SLAM, map given): the median over the nodes of the largest x-y side and
of the heading width (the two floors and ours), against the issue's target (median pose box
≤ 0.5 m).

It is also a soundness check beyond the truth: on the twin (every bound holds) a witness outside
one of our boxes at its node is a SOUNDNESS FAILURE (exit 1). On the demo log two odometry steps
break their bounds (outliers no q covers); witnesses keep the truth's error there, which the
run's assumption does not cover: one outside our box is listed, not a failure.

Needs highspy (HiGHS) from the dev extra; about three minutes a node.

    python -m bench demo_floor
    python -m bench.bench_demo_floor --nodes 12 --seed 5
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

TARGET_POSE_W = 0.5
DEMO = {"scenario": "landmarks", "seed": 3, "steps": 300}
RUN = {"landmarks.initial_pose_from_truth": True, "robust.q_landmark": 2, "robust.q_pose": 1}


def widths(lo, hi) -> tuple[float, float]:
    """(largest x-y side, heading width) of a (lo, hi) pair or a (3, 2) box."""
    return float(max(hi[0] - lo[0], hi[1] - lo[1])), float(hi[2] - lo[2])


def floor_log(name: str, log, nodes: int, seed: int, run: dict) -> dict:
    from bench.landmark_witness import Bounds
    from bench.landmark_witness_steps import StepProblem, StepWitness
    from ivslam_cli.config import resolve_config
    from ivslam_cli.report.core import angle_in
    from ivslam_cli.slam.landmarks import Params
    from ivslam_cli.slam.landmarks.pipeline import solve

    params = Params.from_config(resolve_config(None, run, log_bounds=log.bounds))
    t0 = time.perf_counter()
    runs = {"SLAM": solve(log, params),
            "map given": solve(log, Params.from_config(resolve_config(None, {**run, "landmarks.map_known": True},
                                                                          log_bounds=log.bounds)))}
    t_ours = time.perf_counter() - t0
    pb = StepProblem(log, Bounds.from_params(params))
    rng = np.random.default_rng(seed)
    picked = np.sort(rng.choice(np.arange(1, pb.N), min(nodes, pb.N - 1), replace=False))
    rows, outside = [], []
    t0 = time.perf_counter()
    for node in picked:
        row = {"node": int(node)}
        drop = pb.q_drops(int(node), params.q_pose, params.q_landmark, params.q_landmark_frac)
        stamp = log.odometry.stamp[node]
        for rname, out in runs.items():  # SLAM witnesses move the map; with the map given they keep it
            found = []
            slam = rname == "SLAM"
            q = (params.q_pose, params.q_landmark, params.q_landmark_frac)
            for what, wit in (("every bound", StepWitness(pb, slam)), ("under q", StepWitness(pb.without(drop), slam)),
                              ("under q", StepWitness(pb, slam, q=q))):
                lo, hi = wit.pose_extremes(int(node))
                if found:  # the q witnesses include those of every bound and each other
                    lo, hi = np.minimum(lo, found[-1][1]), np.maximum(hi, found[-1][2])
                found.append((what, lo, hi))
                row[rname, what] = widths(lo, hi)
            k = int(np.searchsorted(out.poses.stamp, stamp))
            box = out.poses.box[k]
            row[rname] = widths(box[:, 0], box[:, 1])
            for what, lo, hi in found:
                for c in range(3):
                    for v in (lo[c], hi[c]):
                        ok = box[c, 0] <= v <= box[c, 1] if c < 2 else bool(
                            angle_in(np.array(box[2, 0]), np.array(box[2, 1]), np.array(v)))
                        if not ok:
                            outside.append(f"{name}, step {node}: a witness ({what}) has {'xyθ'[c]} = {v:.6f} outside "
                                           f"the {rname} box [{box[c, 0]:.6f}, {box[c, 1]:.6f}]")
        rows.append(row)
    return {"name": name, "rows": rows, "outside": outside, "witness_s": time.perf_counter() - t0, "ours_s": t_ours,
            "outliers": (pb.n_outliers, pb.odometry_outliers.size), "median_all": {
                rname: float(np.median(np.maximum(out.poses.box[:, 0, 1] - out.poses.box[:, 0, 0],
                                                  out.poses.box[:, 1, 1] - out.poses.box[:, 1, 0])))
                for rname, out in runs.items()}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nodes", type=int, default=6, help="nodes per log")
    ap.add_argument("--seed", type=int, default=17)
    ap.add_argument("--logs", default="twin,demo")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a configuration override of our runs (e.g. landmarks.pose_window=2); repeatable")
    args = ap.parse_args(argv)
    import json

    run = dict(RUN)
    for kv in args.set:
        key, _, value = kv.partition("=")
        try:
            run[key] = json.loads(value)
        except json.JSONDecodeError:
            run[key] = value
    try:
        import highspy  # noqa: F401
    except ImportError:
        print("bench_demo_floor needs highspy (HiGHS; pip install -e '.[dev]')")
        return 2
    from ivslam_cli.simulate import simulate
    from ivslam_cli.simulate.config import SimConfig

    logs = {"twin": simulate(SimConfig(**DEMO)), "demo": simulate(SimConfig(**DEMO, outlier_rate=0.01))}
    failures = []
    print("demo log: ivslam simulate --scenario landmarks --seed 3 --steps 300 --outlier-rate 0.01; twin: without "
          "--outlier-rate; run --initial-pose-from-truth --q-landmark 2 --q-pose 1 (and with the map given)")
    if args.set:
        print("our runs also with: " + ", ".join(args.set))
    print(f"{'log':>5} {'run':>9} {'nodes':>5} {'floor, every bound':>19} {'floor under q':>14} {'ours':>14}   "
          "(median over the nodes: largest x-y side m / heading rad)")
    for name in args.logs.split(","):
        res = floor_log(name, logs[name], args.nodes, args.seed, run)
        rows = res["rows"]

        def med(key, i):
            return float(np.median([r[key][i] for r in rows])) if rows else math.nan

        for rname in ("SLAM", "map given"):
            cells = [f"{med(k, 0):.3f} / {med(k, 1):.3f}" for k in ((rname, "every bound"), (rname, "under q"), rname)]
            print(f"{name:>5} {rname:>9} {len(rows):>5} {cells[0]:>19} {cells[1]:>14} {cells[2]:>14}")
        for r in rows:
            print(f"      step {r['node']:>3}: " + "; ".join(
                f"{rn} floor {r[rn, 'every bound'][0]:.3f} m {r[rn, 'every bound'][1]:.3f} rad, under q "
                f"{r[rn, 'under q'][0]:.3f} m {r[rn, 'under q'][1]:.3f} rad, ours {r[rn][0]:.3f} m {r[rn][1]:.3f} rad"
                for rn in ("SLAM", "map given")))
        ma = res["median_all"]
        print(f"      every pose: ours SLAM median {ma['SLAM']:.3f} m, map given {ma['map given']:.3f} m; "
              f"truth outliers {res['outliers'][0]} observations, {res['outliers'][1]} odometry steps; "
              f"ours {res['ours_s']:.1f} s, witnesses {res['witness_s']:.0f} s")
        verdict = "reachable by a sound method" if med(("SLAM", "under q"), 0) <= TARGET_POSE_W else "below the floor"
        print(f"      target median pose box ≤ {TARGET_POSE_W} m: SLAM floor under q {med(('SLAM', 'under q'), 0):.3f} m ({verdict}); "
              f"ours {ma['SLAM']:.3f} m")
        for o in res["outside"]:
            if name == "twin" or res["outliers"][1] == 0:
                failures.append(o)
            else:
                print("      outside (the witness keeps the truth's odometry outliers, no q covers them):", o)
    for f in failures:
        print("SOUNDNESS FAILURE:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
