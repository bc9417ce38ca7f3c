"""Benchmark (issue #17): the floor of the landmark CSP on MRCLAM, measured from below.

For each robot (``configs/mrclam.toml``): the SLAM run and the run with the true map given
(``landmarks.map_known``), then, at nodes drawn at random among those the truth covers,
*witnesses* (:mod:`bench.landmark_witness`): explicit worlds — a path within the twist bounds,
true poses within the lag, the surveyed map — that meet every bound at every observation the
truth shows to be an inlier, pushed to the extremes of the pose at the node. Every sound
enclosure holds them, so their spread is a lower bound of what any sound method can reach at
that node, SLAM or localisation alone (a witness keeps the true map). Printed per robot: the
median of those lower bounds (largest x-y side, heading), how many nodes are above the
issue's targets, and our two runs' widths at the same nodes.

With ``--q`` each node also gets witnesses that break observations the run's q allows to be
wrong (``q_pose`` at a node, ``q_landmark`` of a landmark's, the truth's outliers counted;
nearest the node first, :func:`bench.landmark_witness.q_drops`, and one after each linear
program as its duals pick, :class:`bench.witness_lp.Breaks`): the floor under the run's
whole assumption, which is what its boxes must hold.

It is also a soundness check beyond the truth: each witness must lie in our boxes (SLAM and
map given) at its node; a witness outside one is reported as a SOUNDNESS FAILURE (exit 1).

Needs highspy (HiGHS) from the dev extra. Slow (tens of seconds a node): the defaults take a
few nodes a robot.

    python -m bench landmark_floor
    python -m bench.bench_landmark_floor --robots 1,3 --samples 20 --windows 30,150
    python -m bench.bench_landmark_floor --samples 4 --windows 60 --q
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from bench.bench_landmarks import MRCLAM, MRCLAM_CONFIG, TARGET_HEADING_W, TARGET_POSE_W

TWO_PI = 2 * math.pi


def sample_nodes(stamps: np.ndarray, truth_stamps: np.ndarray, n: int, seed: int) -> np.ndarray:
    """``n`` node stamps drawn without replacement among those inside the truth's span (1 s in from
    its ends) and in no gap of the truth longer than 0.5 s."""
    s = np.asarray(stamps, float)
    tt = np.asarray(truth_stamps, float)
    i = np.clip(np.searchsorted(tt, s), 1, tt.size - 1)
    ok = (s > tt[0] + 1.0) & (s < tt[-1] - 1.0) & (tt[i] - tt[i - 1] < 0.5)
    cand = s[ok]
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(cand, min(n, cand.size), replace=False))


def inside(box: np.ndarray, k: int, value: float) -> bool:
    """``value`` in coordinate ``k`` of a (3, 2) box; headings modulo 2π."""
    lo, hi = box[k]
    if k < 2:
        return bool(lo <= value <= hi)
    from ivslam_cli.report.core import angle_in

    return bool(angle_in(np.array(lo), np.array(hi), np.array(value)))


def floor_robot(robot: int, samples: int, windows: tuple[float, ...], seed: int, slam_witnesses: bool,
                with_q: bool = False) -> dict:
    from bench.landmark_witness import Bounds, Problem, Witness, fit_base, q_drops
    from ivslam_cli.config import resolve_config
    from ivslam_cli.logs import read_log
    from ivslam_cli.slam.landmarks import Params
    from ivslam_cli.slam.landmarks.pipeline import solve

    log = read_log(MRCLAM, robot=robot)
    cfg = resolve_config(MRCLAM_CONFIG, {})
    params = Params.from_config(cfg)
    ours = solve(log, params)
    given = solve(log, Params.from_config(resolve_config(MRCLAM_CONFIG, {"landmarks.map_known": True})))
    nodes = sample_nodes(ours.poses.stamp, log.truth.pose_stamp, samples, seed)
    pb = Problem(log, Bounds.from_params(params), extra_stamps=nodes)
    t0 = time.perf_counter()
    base = fit_base(pb)
    wit = Witness(pb, base, slam=slam_witnesses)
    rows, failures = [], []
    for s in nodes:
        k = int(np.searchsorted(ours.poses.stamp, s))
        lo, hi = wit.pose_extremes(s, windows)
        row = {"t": s - pb.t0, "lb_pose": max(hi[0] - lo[0], hi[1] - lo[1]), "lb_heading": hi[2] - lo[2]}
        found = [("", lo, hi)]
        if with_q:  # witnesses that also break what the run's q allows: nearest the node first, and as the duals pick
            drop = q_drops(pb, s - pb.t0, max(windows), params.q_pose, params.q_landmark, params.q_landmark_frac)
            qlo, qhi = Witness(pb.without(drop), base, slam=slam_witnesses).pose_extremes(s, windows)
            q = (params.q_pose, params.q_landmark, params.q_landmark_frac)
            dlo, dhi = Witness(pb, base, slam=slam_witnesses, q=q).pose_extremes(s, windows)
            qlo, qhi = np.minimum(np.minimum(qlo, lo), dlo), np.maximum(np.maximum(qhi, hi), dhi)
            row.update(q_pose=max(qhi[0] - qlo[0], qhi[1] - qlo[1]), q_heading=qhi[2] - qlo[2], q_dropped=int(drop.sum()))
            found.append((f" (q: {int(drop.sum())} observations broken)", qlo, qhi))
        for name, out in (("slam", ours), ("given", given)):
            box = out.poses.box[k]
            row[f"{name}_pose"] = max(box[0, 1] - box[0, 0], box[1, 1] - box[1, 0])
            row[f"{name}_heading"] = box[2, 1] - box[2, 0]
            for what, wlo, whi in found:
                for c in range(3):
                    for v in (wlo[c], whi[c]):
                        if not inside(box, c, v):
                            failures.append(f"robot {robot}, node t={s - pb.t0:.3f} s: a witness's{what} {'xyθ'[c]} = "
                                            f"{v:.6f} lies outside the {name} box [{box[c, 0]:.6f}, {box[c, 1]:.6f}]")
        rows.append(row)
    return {"robot": robot, "rows": rows, "failures": failures, "fit_worst": base.worst, "outliers": pb.n_outliers,
            "witness_s": time.perf_counter() - t0}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", default="1,2,3,4,5")
    ap.add_argument("--samples", type=int, default=4, help="nodes per robot")
    ap.add_argument("--windows", default="30,120", help="seconds of path freed on each side of the node")
    ap.add_argument("--seed", type=int, default=17)
    ap.add_argument("--q", action="store_true",
                    help="also witnesses that break what the run's q allows (q_pose per node, q_landmark per "
                         "landmark; nearest the node first, and as the LP duals pick): the floor under the run's "
                         "whole assumption")
    ap.add_argument("--slam", action="store_true",
                    help="witnesses also move the landmarks (slower; the surveyed map is kept otherwise)")
    args = ap.parse_args(argv)
    try:
        import highspy  # noqa: F401
    except ImportError:
        print("bench_landmark_floor needs highspy (HiGHS; pip install -e '.[dev]')")
        return 2
    windows = tuple(float(w) for w in args.windows.split(","))
    failures: list[str] = []
    print(f"MRCLAM Dataset 6, {MRCLAM_CONFIG.name}; witnesses {'with' if args.slam else 'with the surveyed map'}, "
          f"path freed ±{', ±'.join(f'{w:g}' for w in windows)} s around each node")
    print(f"{'robot':>5} {'nodes':>5} {'floor pose m':>13} {'floor θ rad':>12} {'> targets':>10} "
          f"{'SLAM pose / θ':>15} {'map given pose / θ':>19} {'witness s':>9}")
    for r in (int(x) for x in args.robots.split(",")):
        res = floor_robot(r, args.samples, windows, args.seed, args.slam, args.q)
        rows = res["rows"]
        failures += res["failures"]

        def med(key):
            return float(np.median([row[key] for row in rows])) if rows else math.nan

        above = sum(row["lb_pose"] > TARGET_POSE_W for row in rows), sum(row["lb_heading"] > TARGET_HEADING_W for row in rows)
        print(f"{r:>5} {len(rows):>5} {med('lb_pose'):>13.3f} {med('lb_heading'):>12.3f} "
              f"{above[0]:>4}/{above[1]:<4} {med('slam_pose'):>7.2f} / {med('slam_heading'):<5.2f} "
              f"{med('given_pose'):>9.2f} / {med('given_heading'):<7.2f} {res['witness_s']:>9.0f}")
        if args.q and rows:
            aq = sum(row["q_pose"] > TARGET_POSE_W for row in rows), sum(row["q_heading"] > TARGET_HEADING_W for row in rows)
            print(f"{'':>5} {'q':>5} {med('q_pose'):>13.3f} {med('q_heading'):>12.3f} {aq[0]:>4}/{aq[1]:<4}"
                  f"   (witnesses that also break what q allows: {med('q_dropped'):.0f} observations, median)")
        for row in rows:
            qs = f"   under q {row['q_pose']:.3f} m {row['q_heading']:.3f} rad" if args.q else ""
            print(f"      t={row['t']:8.2f} s  floor {row['lb_pose']:.3f} m {row['lb_heading']:.3f} rad{qs}   "
                  f"SLAM {row['slam_pose']:.2f} m {row['slam_heading']:.2f} rad   map given {row['given_pose']:.2f} m "
                  f"{row['given_heading']:.2f} rad")
    print(f"targets (issue #17): median pose box ≤ {TARGET_POSE_W} m, heading ≤ {TARGET_HEADING_W} rad; "
          "'> targets' counts the nodes whose floor is already above them (pose/heading)")
    for f in failures:
        print("SOUNDNESS FAILURE:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
