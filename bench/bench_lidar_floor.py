"""Benchmark (issue #16): how tightly one scan fixes the heading when the world is known — the
localisation floor, from below, beside the tracker's relative boxes.

On a simulated URG-04LX log (cone beams: each return is the nearest wall point in the beam's
cone), for scans drawn every ``--every``: starting from the true sensor pose, the heading is
moved by 0.5 mrad … 50 mrad each way and a sensor position is searched (grids refined around
the best) where every valid beam's measured range is consistent with the nearest wall in its
cone, the true distance within the log's range bound (``range_abs + range_rel·z``), all but at
most ``q`` beams. Each pose found is a *witness*: with the world known exactly it agrees with
the scan, so no sound method can exclude it from that scan alone. The largest heading offsets
found each way, summed, are a lower bound of the heading width localisation against the exact
world allows (invalid beams are not used: fewer constraints, a wider set; a witness the search
does not find only makes the bound lower).

It is not the floor of SLAM: a tracker knows the world only through scans taken from poses it
must also estimate, so its floor lies above this one. It tells whether the bounds themselves
exclude a target: printed beside the tracker's relative heading (each scan in its submap's
frame, the narrowest of its submaps) at the same scans.

**Two scans, the world unknown** (``--pair GAP``): the same scans, each against the scan
``GAP`` before it, that one's pose exact (its robot frame is the frame), as our matcher sees a
pair: any world of surface points may explain them. A relative pose is a witness when all but
at most ``q`` beams of each scan have a point of their end region (cone × true-distance
bounds) outside the other scan's free cones (each cone free up to its lower distance bound):
those points are a world both scans agree with (a broken beam is one of the ``q``). Points
are sampled across each end region, so a witness found is one; one missed only lowers the
bound. The largest heading offsets with a witness on an x-y grid (±0.12 m, 2 mm) are printed
beside our matcher's heading width on the same pair (the earlier scan as its only
reference, every beam, the same ``q``, the default resolution and budget), and every
witness must lie in the matcher's union (a SOUNDNESS FAILURE otherwise). A pair's floor
bounds what one match can reach, not the tracker, which meets many scans.

    python -m bench lidar_floor
    python -m bench.bench_lidar_floor --duration 60 --every 60 --q 0,5
    python -m bench.bench_lidar_floor --duration 30 --every 30 --pair 10 --q 0,5
    python -m bench.bench_lidar_floor --log ../shared/datasets/breezyslam_mines/exp1.dat.xz \
        --config configs/exp1.toml --at-rest 0:3,0:7,0:12 --q 0,1,2,5

**A recorded log, pairs at rest** (``--log``): two scans between which the odometry shows no
motion have the identity as their true relative pose; the same two-scan witnesses are searched
around it (no truth needed), beside our matcher on the pair.

**A recorded log with benchmark relations** (``--log --relations FILE``, Kümmerle et al. 2009):
for every relation between two consecutive scans, (1) the fewest beams (of either scan, the
larger count) that break the bounds at any relative pose within 2 cm and 5 mrad of the relation
— the q the data need if the relation is right to that much; (2) the x, y and θ extents of the
witnesses (a grid, ``--grid``, default 2 cm and 5 mrad, over our matcher's hull grown by 2 cm and
10 mrad, within the prior; then each extreme witness pushed outward by a pattern search whose
steps are halved ``--push`` times, default 3) at each ``--q``: the floor of what one pair can
prove (a coarse search only lowers it); (3) our scan-pair match (:mod:`ivslam_cli.slam.lidar.scan_pairs`:
the motion model's step box as the prior, the config's ``pair_boxes``, ``pair_stride`` and
``pair_resolution``) on the
same pair, its widths and whether the relation is inside.

    python -m bench.bench_lidar_floor --log ../shared/datasets/intel_lab/intel_gfs.json.xz \
        --config configs/intel_lab.toml --relations ../shared/datasets/intel_lab/intel.relations.xz --q 5,10
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

ROOT = Path(__file__).resolve().parent.parent
#: heading offsets tried, each way [rad]
OFFSETS = (0.0005, 0.001, 0.002, 0.003, 0.005, 0.0075, 0.01, 0.015, 0.02, 0.03, 0.05)
#: heading offsets tried each way for a pair of scans [rad]
PAIR_OFFSETS = tuple(0.0025 * i for i in range(1, 41))
TARGET_HEADING = 0.03  # issue #16: median relative heading width


def sensor_pose(pose, mount) -> np.ndarray:
    """The sensor pose (x, y, yaw) of robot pose ``pose`` with the laser at ``mount``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array([pose[0] + c * mount[0] - s * mount[1], pose[1] + s * mount[0] + c * mount[1], pose[2] + mount[2]])


def scan_bounds(log, k: int):
    """Scan ``k``'s valid beams: angles in the sensor frame and true-distance bounds ``lo, hi``."""
    sc, b = log.scans, log.bounds
    o0, o1 = int(sc.offsets[k]), int(sc.offsets[k + 1])
    v = np.asarray(sc.valid[o0:o1], bool)
    z = np.asarray(sc.ranges[o0:o1], float)[v]
    ang = (float(sc.angle_min[k]) + np.arange(o1 - o0) * float(sc.angle_increment[k]))[v]
    ra, rr = float(b["range_abs"]), float(b["range_rel"])
    return ang, np.maximum((z - ra) / (1 + rr), 0.0) - 1e-9, (z + ra) / (1 - rr) + 1e-9


def violations(poses: np.ndarray, ang, lo, hi, half_width: float, segments: np.ndarray) -> np.ndarray:
    """Per sensor pose (rows of ``poses``): the beams whose cone's nearest wall is outside
    their bounds."""
    from ivslam_cli.simulate.conecast import cone_scans

    d = cone_scans(np.ascontiguousarray(poses, float), ang, half_width, segments)
    return ((d < lo) | (d > hi)).sum(axis=1)


def find_position(p: np.ndarray, yaw: float, q: int, check, width: float = 0.12, levels: int = 5):
    """A sensor position near ``p`` with heading ``yaw`` breaking at most ``q`` beams (``check``:
    poses → violations), searched on 25 × 25 grids refined around the best; None if none found."""
    cx, cy, w = float(p[0]), float(p[1]), width
    for _ in range(levels):
        g = np.linspace(-w, w, 25)
        X, Y = np.meshgrid(cx + g, cy + g)
        P = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, yaw)])
        nv = check(P)
        i = int(np.argmin(nv))
        if nv[i] <= q:
            return P[i]
        cx, cy, w = P[i, 0], P[i, 1], w / 4
    return None


def heading_reach(log, k: int, q: int) -> tuple[float, float, list[np.ndarray]]:
    """The largest heading offsets (below, above the truth) with a witness for scan ``k``, and
    the witnesses (sensor poses)."""
    ang, lo, hi = scan_bounds(log, k)
    seg = np.asarray(log.truth.world, float)
    hw = float(log.bounds["beam_angle"])
    p = sensor_pose(np.asarray(log.truth.pose[k], float), log.scans.mount)

    def check(P):
        return violations(P, ang, lo, hi, hw, seg)

    reach, wit = [], []
    for sign in (-1.0, 1.0):
        best = 0.0
        for d in OFFSETS:
            w = find_position(p, p[2] + sign * d, q, check)
            if w is None:
                break
            best = d
            wit.append(w)
        reach.append(best)
    return reach[0], reach[1], wit


@njit(cache=True)
def _in_free(px, py, sx, sy, sth, f, a0, inc, ra):
    """Is the point in the free space of a scan from sensor ``(sx, sy, sth)``: within the cone
    (half-width ``ra``) of some beam nearer than its free range ``f`` (−1: invalid)?"""
    dx = px - sx
    dy = py - sy
    b = math.atan2(dy, dx) - sth
    b = (b + math.pi) % (2.0 * math.pi) - math.pi - a0  # the bearing in the scan's frame, from its first beam
    d = math.hypot(dx, dy)
    for j in range(max(math.ceil((b - ra) / inc), 0), min(math.floor((b + ra) / inc), f.shape[0] - 1) + 1):
        if f[j] > 0.0 and d < f[j]:
            return True
    return False


@njit(cache=True)
def pair_breaks(sx, sy, sth, ang, lo, hi, ra, ox, oy, oth, f, a0, inc, ns, nr, cap):
    """Beams of a scan from sensor ``(sx, sy, sth)`` (angles ``ang``, true-distance bounds
    ``lo``, ``hi``, cones of half-width ``ra``) whose end region, sampled ``ns`` bearings by
    ``nr`` distances, lies wholly in the free space of the other scan (sensor ``(ox, oy,
    oth)``, free ranges ``f`` of beams at ``a0 + j·inc``); counting stops past ``cap``."""
    n = 0
    for i in range(ang.shape[0]):
        broken = True
        for a in range(nr):
            r = hi[i] - (hi[i] - lo[i]) * a / (nr - 1)
            for b in range(ns):
                t = ang[i] + sth + ra * 0.999 * (2.0 * b / (ns - 1) - 1.0)
                if not _in_free(sx + r * math.cos(t), sy + r * math.sin(t), ox, oy, oth, f, a0, inc, ra):
                    broken = False
                    break
            if not broken:
                break
        if broken:
            n += 1
            if n > cap:
                return n
    return n


@njit(cache=True)
def pair_witness(tx, ty, th, half, step, mount, S, A, ra, q, ns, nr):
    """A witness ``(x, y)`` of the relative robot pose at heading ``th`` (searched on a grid of
    ``step`` within ``half`` of ``(tx, ty)``), scan ``S`` against scan ``A`` at the frame's
    origin; ``S``, ``A``: (angles, lo, hi, free ranges, a0, inc) of the valid beams (free ranges
    over every beam). Returns ``(found, x, y)``."""
    n = int(round(half / step))
    for ii in range(-n, n + 1):
        for jj in range(-n, n + 1):
            x = tx + ii * step
            y = ty + jj * step
            if _both_broken(x, y, th, mount, S, A, ra, ns, nr, q) <= q:
                return True, x, y
    return False, 0.0, 0.0


def relative_pose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Robot pose ``b`` in the frame of robot pose ``a``."""
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, math.atan2(math.sin(b[2] - a[2]), math.cos(b[2] - a[2]))])


def pair_scan(log, k: int, r_abs: float, r_rel: float):
    """Scan ``k`` for :func:`pair_witness`, in the matcher's convention of the bounds."""
    from ivslam_cli.slam.lidar.free_cones import free_of

    sc = log.scans
    o0, o1 = int(sc.offsets[k]), int(sc.offsets[k + 1])
    r, v = np.asarray(sc.ranges[o0:o1], float), np.asarray(sc.valid[o0:o1], bool)
    a0, inc = float(sc.angle_min[k]), float(sc.angle_increment[k])
    # a witness must hold the real model: free ranges rounded up (the kernels' are rounded
    # down), end regions rounded inward, so a point found outside is outside
    f = free_of(r, v, r_abs, r_rel)
    f = np.where(f > 0.0, np.nextafter(f, np.inf), f)
    z = r[v]
    lo = np.nextafter(np.maximum((z - r_abs) / (1 + r_rel), 0.0), np.inf)
    hi = np.nextafter((z + r_abs) / (1 - r_rel), -np.inf)
    return (a0 + inc * np.flatnonzero(v), lo, hi, f, a0, inc)


def pair_floor(log, k: int, j: int, q: int, params, samples=(9, 7), t=None):
    """Scan ``k`` against scan ``j`` (exact): ``(below, above, witnesses, matcher union)`` — the
    largest heading offsets from the truth (or from ``t``, the relative pose searched around)
    with a witness, the witnesses (robot poses in ``j``'s frame) and our matcher's union on the
    same pair."""
    from ivslam_cli.paving.tiles import TileMap
    from ivslam_cli.slam.lidar.matcher import Matcher

    b = params.beams
    S, A = pair_scan(log, k, b.range_abs, b.range_rel), pair_scan(log, j, b.range_abs, b.range_rel)
    if t is None:
        t = relative_pose(np.asarray(log.truth.pose[j], float), np.asarray(log.truth.pose[k], float))
    mount = tuple(float(v) for v in log.scans.mount)
    reach, wit = [], []
    for sign in (-1.0, 1.0):
        best = 0.0
        for d in PAIR_OFFSETS:
            ok, x, y = pair_witness(t[0], t[1], t[2] + sign * d, 0.12, 0.002, mount, S, A, float(b.bearing), q,
                                    samples[0], samples[1])
            if not ok:
                break
            best = d
            wit.append(np.array([x, y, t[2] + sign * d]))
        reach.append(best)
    roots = np.array([[t[0] - 0.2, t[0] + 0.2, t[1] - 0.2, t[1] + 0.2, t[2] - 0.15, t[2] + 0.15]])
    union, _, _ = Matcher(params, log.scans).match(k, roots, TileMap(params.eps), [(j, np.zeros(6))], stride=1, q=q)
    return reach[0], reach[1], wit, union


def in_union(union: np.ndarray, p: np.ndarray) -> bool:
    """Is the pose in one of the boxes (n, 6)?"""
    return bool(np.any((union[:, 0] <= p[0]) & (p[0] <= union[:, 1]) & (union[:, 2] <= p[1]) & (p[1] <= union[:, 3])
                       & (union[:, 4] <= p[2]) & (p[2] <= union[:, 5])))


def relative_heading(result, rows: np.ndarray) -> np.ndarray:
    """Per pose row: the narrowest heading width of its boxes in the submaps holding it."""
    sm = result.submaps
    out = np.full(rows.size, np.nan)
    for m in range(len(sm)):
        a, b = int(sm.member_offsets[m]), int(sm.member_offsets[m + 1])
        for r, box in zip(sm.member_row[a:b], sm.member_box[a:b]):
            i = np.searchsorted(rows, r)
            if i < rows.size and rows[i] == r:
                out[i] = np.nanmin([out[i], box[2, 1] - box[2, 0]])
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=60.0, help="seconds of simulated log")
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--every", type=int, default=60, help="every n-th scan is tested")
    ap.add_argument("--q", default="0,5", help="beams allowed to disagree (the pipeline's q_beams is 5)")
    ap.add_argument("--pair", type=int, default=0,
                    help="also each tested scan against the scan GAP before it, the world unknown (0: not)")
    ap.add_argument("--log", type=Path, help="a recorded log instead: scan pairs taken at rest (--at-rest)")
    ap.add_argument("--config", type=Path, help="with --log: its configuration (the bounds)")
    ap.add_argument("--at-rest", default="0:3,0:7,0:12",
                    help="with --log: pairs j:k of scans between which the odometry shows no motion")
    ap.add_argument("--relations", type=Path, help="with --log: benchmark relations (pairs of consecutive scans)")
    ap.add_argument("--grid", default="0.02,0.005",
                    help="with --relations: the witnesses' grid, metres and radians (finer: a higher floor, slower)")
    ap.add_argument("--push", type=int, default=3,
                    help="with --relations: each extreme witness pushed outward, the grid's steps halved this many times")
    args = ap.parse_args(argv)
    if args.log is not None and args.relations is not None:
        step, step_th = (float(v) for v in args.grid.split(","))
        return relations_floor(args.log, args.config, args.relations, [int(x) for x in args.q.split(",")], step,
                               step_th, args.push)
    if args.log is not None:
        return at_rest(args.log, args.config, [tuple(int(v) for v in p.split(":")) for p in args.at_rest.split(",")],
                       [int(x) for x in args.q.split(",")])
    from ivslam_cli.logs import read_log
    from ivslam_cli.results.hdf5 import read_result

    qs = [int(x) for x in args.q.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        log_path, res_path = Path(tmp) / "sim.h5", Path(tmp) / "res.h5"
        subprocess.run([sys.executable, "-m", "ivslam_cli", "simulate", "--scenario", "lidar", "--world", "rooms",
                        "--sensor", "urg-04lx", "--seed", str(args.seed), "--duration", f"{args.duration:g}",
                        "-o", str(log_path)], cwd=ROOT, check=True, capture_output=True)
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "ivslam_cli", "run", str(log_path), "--mode", "lidar", "-o",
                        str(res_path)], cwd=ROOT, check=True, capture_output=True)
        run_s = time.perf_counter() - t0
        log, result = read_log(log_path), read_result(res_path)
    rows = np.arange(0, len(log.scans), args.every)
    ours = relative_heading(result, rows)
    print(f"simulated rooms, URG-04LX, {args.duration:g} s, seed {args.seed}: {rows.size} scans "
          f"(every {args.every}); the tracker's run (defaults) {run_s:.0f} s")
    print(f"{'scan':>5} " + " ".join(f"{'floor q=' + str(q) + ' rad':>15}" for q in qs) + f" {'ours rad':>9}")
    floors = {q: [] for q in qs}
    t0 = time.perf_counter()
    for i, k in enumerate(rows):
        cells = []
        for q in qs:
            lo, hi, _ = heading_reach(log, int(k), q)
            floors[q].append(lo + hi)
            cells.append(f"{'>= ' if lo + hi == 0 else ''}{lo + hi:.4f}".rjust(15))
        print(f"{k:>5} " + " ".join(cells) + f" {ours[i]:>9.4f}", flush=True)
    print(f"{'median':>5} " + " ".join(f"{np.median(floors[q]):>15.4f}" for q in qs) + f" {np.nanmedian(ours):>9.4f}")
    print(f"witness search {time.perf_counter() - t0:.0f} s. A floor of 0 means no heading offset of "
          f"{OFFSETS[0] * 1e3:g} mrad or more had a witness. Target (issue #16): median relative heading "
          f"<= {TARGET_HEADING} rad — not excluded by the bounds when the floor is below it; the tracker's "
          "own floor (a world known only through its scans) lies between")
    if args.pair > 0:
        return pairs(log, rows, qs, args.pair)
    return 0


def pairs(log, rows: np.ndarray, qs: list[int], gap: int) -> int:
    """The two-scan table (see the module docstring); 1 if a witness lies outside our union."""
    from ivslam_cli.config import resolve_config
    from ivslam_cli.slam.lidar.params import Params

    params = Params.from_config(resolve_config(None, {}, log_bounds=log.bounds))
    print(f"\ntwo scans, the world unknown: scan k against scan k - {gap} (exact), every beam; heading width "
          "with a witness (floor) and our matcher's on the same pair")
    print(f"{'scan':>5} " + " ".join(f"{'floor q=' + str(q):>11} {'ours q=' + str(q):>10}" for q in qs))
    floors, ours, failures = {q: [] for q in qs}, {q: [] for q in qs}, []
    t0 = time.perf_counter()
    for k in (int(r) for r in rows if r >= gap):
        cells = []
        for q in qs:
            lo, hi, wit, union = pair_floor(log, k, k - gap, q, params)
            w = float(union[:, 5].max() - union[:, 4].min())
            floors[q].append(lo + hi)
            ours[q].append(w)
            failures += [f"scan {k}, q = {q}: witness {np.round(p, 5).tolist()} outside our union" for p in wit
                         if not in_union(union, p)]
            cells.append(f"{lo + hi:>11.4f} {w:>10.4f}")
        print(f"{k:>5} " + " ".join(cells), flush=True)
    if floors[qs[0]]:
        print(f"{'median':>5} " + " ".join(f"{np.median(floors[q]):>11.4f} {np.median(ours[q]):>10.4f}" for q in qs))
    print(f"pair witnesses {time.perf_counter() - t0:.0f} s (offsets searched in steps of {PAIR_OFFSETS[0]:g} rad)")
    for f in failures:
        print("SOUNDNESS FAILURE:", f)
    return 1 if failures else 0


def at_rest(path: Path, config: Path | None, pairs_: list[tuple[int, int]], qs: list[int]) -> int:
    """Pairs of a recorded log's scans taken while the robot stands still (the odometry moves by
    under 1 mm and 1 mrad between them): the true relative pose is the identity, so the witness
    search runs around it, beside our matcher on the same pair (every beam, the config's bounds,
    no sweep: the robot does not move). 1 if a witness lies outside our union."""
    from ivslam_cli.config import resolve_config
    from ivslam_cli.logs import read_log
    from ivslam_cli.slam.lidar.params import Params

    log = read_log(path)
    params = Params.from_config(resolve_config(config, {}, log_bounds=log.bounds))
    odo_t, odo_p = np.asarray(log.odometry.stamp, float), np.asarray(log.odometry.pose, float)
    stamp = np.asarray(log.scans.stamp, float)
    print(f"{path.name}: scan pairs at rest, every beam, no sweep; heading width with a witness (floor) and our "
          "matcher's on the same pair (prior ±0.2 m, ±0.15 rad)")
    print(f"{'pair':>7} " + " ".join(f"{'floor q=' + str(q):>11} {'ours q=' + str(q):>10}" for q in qs))
    failures = []
    for j, k in pairs_:
        a, b = (np.clip(np.searchsorted(odo_t, stamp[i]), 0, len(odo_t) - 1) for i in (j, k))
        d = relative_pose(odo_p[a], odo_p[b])
        if not (math.hypot(d[0], d[1]) < 1e-3 and abs(d[2]) < 1e-3):
            print(f"{j}:{k}: the odometry moves {np.round(d, 4).tolist()} between them: not at rest, skipped")
            continue
        cells = []
        for q in qs:
            lo, hi, wit, union = pair_floor(log, k, j, q, params, t=np.zeros(3))
            failures += [f"pair {j}:{k}, q = {q}: witness {np.round(p, 5).tolist()} outside our union" for p in wit
                         if not in_union(union, p)]
            cells.append(f"{lo + hi:>11.4f} {float(union[:, 5].max() - union[:, 4].min()):>10.4f}")
        print(f"{j:>3}:{k:<3} " + " ".join(cells), flush=True)
    for f in failures:
        print("SOUNDNESS FAILURE:", f)
    return 1 if failures else 0


@njit(cache=True)
def _both_broken(x, y, th, mount, S, A, ra, ns, nr, cap):
    """The larger count of broken beams of the two scans at relative robot pose ``(x, y, th)``."""
    mx, my, myaw = mount
    c, s = math.cos(th), math.sin(th)
    sx, sy = x + c * mx - s * my, y + s * mx + c * my
    a = pair_breaks(sx, sy, th + myaw, S[0], S[1], S[2], ra, mx, my, myaw, A[3], A[4], A[5], ns, nr, cap)
    if a > cap:
        return a
    return max(a, pair_breaks(mx, my, myaw, A[0], A[1], A[2], ra, sx, sy, th + myaw, S[3], S[4], S[5], ns, nr, cap))


@njit(cache=True)
def fewest_broken(t, half, step, half_th, step_th, mount, S, A, ra, ns, nr):
    """The fewest broken beams (:func:`_both_broken`) on a grid within ``half`` (``step``) and
    ``half_th`` (``step_th``) of the relative pose ``t``."""
    n, m = int(round(half / step)), int(round(half_th / step_th))
    best = 1 << 30
    for kk in range(-m, m + 1):
        for ii in range(-n, n + 1):
            for jj in range(-n, n + 1):
                v = _both_broken(t[0] + ii * step, t[1] + jj * step, t[2] + kk * step_th, mount, S, A, ra, ns, nr,
                                 best - 1)
                best = min(best, v)
    return best


@njit(cache=True)
def _first_witness(x0, y0, th, step, outer, inner, by_x, rev, mount, S, A, ra, q, ns, nr):
    """The first grid line (of ``outer`` lines, from the low end or, ``rev``, the high end;
    columns of constant x when ``by_x``, else rows) holding a witness at heading ``th``, and the
    witness's place on it: ``(line, place)``, ``(-1, -1)`` if none."""
    for a in range(outer):
        u = outer - 1 - a if rev else a
        for v in range(inner):
            i, j = (u, v) if by_x else (v, u)
            if _both_broken(x0 + i * step, y0 + j * step, th, mount, S, A, ra, ns, nr, q) <= q:
                return u, v
    return -1, -1


@njit(cache=True)
def witness_extents(box, step, step_th, mount, S, A, ra, q, ns, nr, out, at):
    """``out`` (6,) = the x, y, θ extents of the witnesses (at most ``q`` broken beams of each
    scan) on a grid over ``box`` (6,), each heading searched from the four sides inward;
    ``at[s]`` the witness (x, y, θ) at extent ``s``. Returns the headings with a witness."""
    found = 0
    nx, ny = int((box[1] - box[0]) / step) + 1, int((box[3] - box[2]) / step) + 1
    nt = int((box[5] - box[4]) / step_th) + 1
    for kk in range(nt):
        th = box[4] + kk * step_th
        lo_x, v0 = _first_witness(box[0], box[2], th, step, nx, ny, True, False, mount, S, A, ra, q, ns, nr)
        if lo_x < 0:
            continue
        hi_x, v1 = _first_witness(box[0], box[2], th, step, nx, ny, True, True, mount, S, A, ra, q, ns, nr)
        lo_y, u2 = _first_witness(box[0], box[2], th, step, ny, nx, False, False, mount, S, A, ra, q, ns, nr)
        hi_y, u3 = _first_witness(box[0], box[2], th, step, ny, nx, False, True, mount, S, A, ra, q, ns, nr)
        pts = ((lo_x, v0), (hi_x, v1), (u2, lo_y), (u3, hi_y))
        for e in range(4):
            x, y = box[0] + pts[e][0] * step, box[2] + pts[e][1] * step
            v = x if e < 2 else y
            if (e % 2 == 0 and v < out[e]) or (e % 2 == 1 and v > out[e]):
                out[e] = v
                at[e, 0], at[e, 1], at[e, 2] = x, y, th
        if th < out[4]:
            out[4] = th
            at[4, 0], at[4, 1], at[4, 2] = box[0] + lo_x * step, box[2] + v0 * step, th
        if th > out[5]:
            out[5] = th
            at[5, 0], at[5, 1], at[5, 2] = box[0] + lo_x * step, box[2] + v0 * step, th
        found += 1
    return found


@njit(cache=True)
def push_witnesses(out, at, lim, step, step_th, levels, mount, S, A, ra, q, ns, nr):
    """Each extent ``out[s]`` of the grid's witnesses pushed outward: from its witness ``at[s]``,
    a move of one step along that side's axis (with lateral offsets of up to two steps in the
    other two) is kept when it lands on a witness within ``lim`` (the prior), the steps halved
    ``levels`` times when none does. Every pose kept is a witness, so the extents stay a floor
    (higher than the grid's)."""
    for side in range(6):
        if not np.isfinite(out[side]):
            continue
        d = side // 2
        sgn = -1.0 if side % 2 == 0 else 1.0
        p = at[side].copy()
        f = 1.0
        for _ in range(levels + 1):
            moved = True
            while moved:
                moved = False
                st = np.array([step * f, step * f, step_th * f])
                for a in range(-2, 3):
                    for b in range(-2, 3):
                        c = p.copy()
                        c[d] += sgn * st[d]
                        o1, o2 = (d + 1) % 3, (d + 2) % 3
                        c[o1] += a * st[o1]
                        c[o2] += b * st[o2]
                        if not (lim[0] <= c[0] <= lim[1] and lim[2] <= c[1] <= lim[3] and lim[4] <= c[2] <= lim[5]):
                            continue
                        if _both_broken(c[0], c[1], c[2], mount, S, A, ra, ns, nr, q) <= q:
                            p = c
                            moved = True
                            break
                    if moved:
                        break
            f *= 0.5
        out[side] = p[d]
        at[side] = p


def relations_floor(path: Path, config: Path | None, relations: Path, qs: list[int], step: float = 0.02,
                    step_th: float = 0.005, push: int = 3) -> int:
    """The table of ``--relations`` (see the module docstring); 1 if a witness lies outside our
    pair enclosure at the config's q."""
    from ivslam_cli.config import resolve_config
    from ivslam_cli.logs import read_log
    from ivslam_cli.paving.tiles import TileMap
    from ivslam_cli.report.relations import match_stamps, read_relations
    from ivslam_cli.slam.lidar.matcher import Matcher, hull
    from ivslam_cli.slam.lidar.params import Params
    from ivslam_cli.slam.lidar.prediction import trajectory
    from ivslam_cli.slam.lidar.scan_pairs import pair_match_args, pair_prior

    log = read_log(path)
    params = Params.from_config(resolve_config(config, {}, log_bounds=log.bounds))
    b = params.beams
    rel = read_relations(relations)
    st = np.asarray(log.scans.stamp, float)
    a_, _ = match_stamps(st, rel.t1, 1e-4)
    b_, _ = match_stamps(st, rel.t2, 1e-4)
    rows = np.flatnonzero((a_ >= 0) & (b_ >= 0) & (b_ - a_ == 1))
    used, _, m = trajectory(log, params, log.scans)[:3]
    mount = tuple(float(v) for v in log.scans.mount)
    matcher = Matcher(params, log.scans)
    kw = pair_match_args(params)
    pushed = f", pushed outward to steps of 1/{2 ** push:g} of it" if push else ""
    print(f"{path.name}: {rows.size} relations between consecutive scans; our pair match: {kw['budget']} boxes, "
          f"every {kw['stride']} beam(s), {kw['resolution']} m, q = {params.q_beams}; witnesses on a grid of "
          f"{step:g} m and {step_th:g} rad{pushed}")
    print(f"{'pair':>9} {'fewest':>6} " + " ".join(f"{'floor q=' + str(q) + ' x/y/θ':>22}" for q in qs)
          + f" {'ours x/y/θ':>22} inside")
    fewest, floors, ours, failures, outside = [], {q: [] for q in qs}, [], [], 0
    t0 = time.perf_counter()
    for r in rows:
        j, k = int(a_[r]), int(b_[r])
        S, A = pair_scan(log, k, b.range_abs, b.range_rel), pair_scan(log, j, b.range_abs, b.range_rel)
        t = np.asarray(rel.rel[r], float)
        n = fewest_broken(t, 0.02, 0.002, 0.005, 0.001, mount, S, A, float(b.bearing), 9, 7)
        fewest.append(n)
        rj, rk = (int(np.searchsorted(used, i)) for i in (j, k))
        if rk >= used.size or used[rj] != j or used[rk] != k or (prior := pair_prior(m, rj, rk)) is None:
            print(f"{j:>4}:{k:<4} no prior (a scan not used, or a motion step without solution)")
            continue
        tm = TileMap(params.eps)
        union, ok, _ = matcher.match(k, prior[None, :], tm, [(j, np.zeros(6))], **kw)
        h = hull(union)
        inside = in_union(union, t)
        outside += not inside
        ours.append(h[1::2] - h[0::2])
        cells = []
        for q in qs:
            box = h + np.array([-0.02, 0.02, -0.02, 0.02, -0.01, 0.01])  # beyond it: witnesses our union misses
            box[0::2], box[1::2] = np.maximum(box[0::2], prior[0::2]), np.minimum(box[1::2], prior[1::2])
            out = np.array([np.inf, -np.inf, np.inf, -np.inf, np.inf, -np.inf])
            at = np.zeros((6, 3))
            witness_extents(box, step, step_th, mount, S, A, float(b.bearing), q, 9, 7, out, at)
            if push:
                push_witnesses(out, at, prior, step, step_th, push, mount, S, A, float(b.bearing), q, 9, 7)
            w = np.where(np.isfinite(out[1::2] - out[0::2]), out[1::2] - out[0::2], 0.0)
            floors[q].append(w)
            if q == params.q_beams and np.isfinite(out).all() and not (
                    np.all(h[0::2] <= out[0::2]) and np.all(out[1::2] <= h[1::2])):
                failures.append(f"pair {j}:{k}: witnesses {np.round(out, 4).tolist()} beyond our hull")
            cells.append(f"{w[0]:>7.3f}{w[1]:>7.3f}{w[2]:>8.4f}")
        cells.append(f"{ours[-1][0]:>7.3f}{ours[-1][1]:>7.3f}{ours[-1][2]:>8.4f}")
        print(f"{j:>4}:{k:<4} {n:>6} " + " ".join(cells) + f" {'yes' if inside else 'NO'}", flush=True)
    print(f"{'median':>9} {np.median(fewest):>6.0f} " + " ".join(
        "".join(f"{v:>7.3f}" for v in np.median(floors[q], axis=0)[:2]) + f"{np.median(floors[q], axis=0)[2]:>8.4f}"
        for q in qs) + "".join(f"{v:>7.3f}" for v in np.median(ours, axis=0)[:2])
          + f"{np.median(ours, axis=0)[2]:>8.4f}")
    need = np.array(fewest)
    print(f"fewest broken beams near the relations: {np.bincount(need).tolist()} (count by number); "
          f"{int((need > params.q_beams).sum())} relations need more than q = {params.q_beams}; "
          f"{outside} relations outside our pair enclosure; {time.perf_counter() - t0:.0f} s")
    for f in failures:
        print("SOUNDNESS FAILURE:", f)
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
