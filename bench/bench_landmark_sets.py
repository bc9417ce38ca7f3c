"""Benchmark (issue #17): where the landmark CSP's width goes — our pose sets beside a set
filter on fine cells, on the demo log's outlier-free twin with the true map given.

Our pose sets keep one (x, y, θ) box per heading slice (:mod:`ivslam_cli.slam.landmarks.pose_sets`).
This benchmark runs, on the same log and under the same assumption, a forward-backward filter
whose sets are unions of small cells (``--cell`` metres × 0.5 mrad; a grid centred on the true
pose of each node, which places the grid and informs nothing else):

- a motion step moves every cell by the held twists of the step (speed and turn rate sampled
  on a 9 × 9 grid of their bounds, the unicycle arc exact, each image snapped to the nearest
  cell); the backward pass keeps the cells with an image in the next node's set;
- an observation keeps the cells where it holds at the cell's centre within its bounds widened
  by the cell's half-diagonal; under ``q_pose`` a cell may break that many of its node's
  observations (the landmarks' own caps are not modelled: a weaker assumption than our run's);
- the set is then kept as cells (``cells``), or, in each heading slice of our width (2π / 256),
  as the box (``box per slice``: our representation) or the octagon (bounds on x, y, x + y and
  x − y: ``octagon per slice``) of its cells.

The filter is an approximation, neither a floor nor an enclosure, and in practice it errs wide:
snapping each image to a cell moves it by up to half a cell in every direction at every step,
where the model allows almost no motion across the heading (a path read back from its cells and
integrated exactly drifts centimetres from them and breaks observations); the sampled twists
omit paths between the samples (it errs narrow there). It holds the truth at every node
(checked). In practice its widths lie above the exact set's, and the witnesses of
``bench_demo_floor`` below. What it measures: how much of our width comes from keeping one box per heading slice and
from how we contract, against sets that keep their shapes.

Printed: the median over the nodes of the largest x-y side and of the heading width, for our
runs (`pose_slices` 64, 256, 1024) and the filter's three representations, with q = 0 and with
`q_pose` = 1 at each node. About eight minutes.

    python -m bench landmark_sets
    python -m bench.bench_landmark_sets --cell 0.002
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from numba import njit

DEMO = {"scenario": "landmarks", "seed": 3, "steps": 300}
HEADING_CELL = 0.0005
TWIST_SAMPLES = 9
SLICE = 2.0 * math.pi / 256


@njit(cache=True)
def propagate(G, out, dx, dy, dp):
    """``out`` ∪= the image of every cell of ``G`` (NP, NX, NX) under each sampled twist ``a``:
    heading layer ``s`` → ``s + dp[a]``, position moved by ``(dx[s, a], dy[s, a])`` cells."""
    NP, NX = G.shape[0], G.shape[1]
    for s in range(NP):
        for a in range(dx.shape[1]):
            d = s + dp[a]
            if d < 0 or d >= NP:
                continue
            sx, sy = dx[s, a], dy[s, a]
            for i in range(max(0, -sx), min(NX, NX - sx)):
                for j in range(max(0, -sy), min(NX, NX - sy)):
                    if G[s, i, j]:
                        out[d, i + sx, j + sy] = True


@njit(cache=True)
def pullback(G, S, dx, dy, dp):
    """Keep the cells of ``G`` with an image (as in :func:`propagate`) in ``S``."""
    NP, NX = G.shape[0], G.shape[1]
    for s in range(NP):
        for i in range(NX):
            for j in range(NX):
                if not G[s, i, j]:
                    continue
                keep = False
                for a in range(dx.shape[1]):
                    d = s + dp[a]
                    ii, jj = i + dx[s, a], j + dy[s, a]
                    if 0 <= d < NP and 0 <= ii < NX and 0 <= jj < NX and S[d, ii, jj]:
                        keep = True
                        break
                G[s, i, j] = keep


class SetFilter:
    """The cell filter of one log (see the module docstring)."""

    def __init__(self, log, params, cell: float, span: float, heading_cell: float = HEADING_CELL,
                 heading_span: float = 0.08):
        self.C, self.P = cell, heading_cell
        self.NX = int(round(span / cell))
        self.NP = int(round(heading_span / heading_cell))
        self.xs = (np.arange(self.NX) - self.NX / 2 + 0.5) * cell
        self.ps = (np.arange(self.NP) - self.NP / 2 + 0.5) * self.P
        odo, obs = log.odometry, log.observations
        self.t = np.asarray(odo.stamp, float)
        self.h = np.diff(self.t)
        self.z = np.asarray(odo.twist, float)
        T = np.asarray(log.truth.pose, float).copy()
        T[:, 2] = np.unwrap(T[:, 2])
        self.T = T
        self.step = np.searchsorted(self.t, np.asarray(obs.stamp, float))
        lm = {int(i): np.asarray(xy, float) for i, xy in
              zip(log.truth.landmark_id, np.asarray(log.truth.landmark_xy).reshape(-1, 2))}
        self.m = np.array([lm[int(i)] for i in obs.landmark_id]).reshape(-1, 2)
        self.rng = np.asarray(obs.range, float)
        self.brg = np.asarray(obs.bearing, float)
        self.p = params
        self.N = self.t.size

    def _shifts(self, k):
        b, n = self.p.odometry, TWIST_SAMPLES
        zv, zw = self.z[k]
        vmin = max(0.0, (zv - b.odom_v) / (1 + b.odom_v_rel))
        vmax = (zv + b.odom_v) / (1 - b.odom_v_rel) if b.odom_v_rel < 1 else zv + b.odom_v
        dx = np.zeros((self.NP, n * n), np.int64)
        dy = np.zeros_like(dx)
        dp = np.zeros(n * n, np.int64)
        true_step = self.T[k + 1] - self.T[k]
        a = 0
        for v in np.linspace(vmin, vmax, n):
            bw = b.odom_w + b.odom_w_rel * v
            for w in np.linspace(zw - bw, zw + bw, n):
                half = 0.5 * w * self.h[k]
                L = v * self.h[k] * (math.sin(half) / half if abs(half) > 1e-12 else 1.0)
                th = self.T[k, 2] + self.ps + half
                dx[:, a] = np.round((L * np.cos(th) - true_step[0]) / self.C)
                dy[:, a] = np.round((L * np.sin(th) - true_step[1]) / self.C)
                dp[a] = round((w * self.h[k] - true_step[2]) / self.P)
                a += 1
        return dx, dy, dp

    def observed(self, G, k, q_pose):
        """``G`` ∩ the cells where at most ``q_pose`` of node ``k``'s observations fail."""
        pi, ii, jj = np.nonzero(G)
        if pi.size == 0:
            return G
        cp = slice(pi.min(), pi.max() + 1)
        ci = slice(ii.min(), ii.max() + 1)
        cj = slice(jj.min(), jj.max() + 1)
        X = self.T[k, 0] + self.xs[None, ci, None]
        Y = self.T[k, 1] + self.xs[None, None, cj]
        TH = self.T[k, 2] + self.ps[cp, None, None]
        bad = np.zeros((cp.stop - cp.start, ci.stop - ci.start, cj.stop - cj.start), np.int16)
        half = 0.71 * self.C
        for j in np.flatnonzero(self.step == k):
            dxm, dym = self.m[j, 0] - X, self.m[j, 1] - Y
            r = np.hypot(dxm, dym)
            a = (np.arctan2(dym, dxm) - TH - self.brg[j] + math.pi) % (2 * math.pi) - math.pi
            er = self.p.range_abs + self.p.range_rel * self.rng[j] + half
            bad += ~((np.abs(r - self.rng[j]) <= er) & (np.abs(a) <= self.p.bearing + half / r + self.P / 2))
        out = np.zeros_like(G)
        out[cp, ci, cj] = G[cp, ci, cj] & (bad <= q_pose)
        return out

    def represent(self, G, k, mode):
        """``G`` as cells, or as one box / octagon of its cells in each heading slice."""
        if mode == "cells":
            return G
        band = np.floor((self.T[k, 2] + self.ps) / SLICE).astype(np.int64)
        out = np.zeros_like(G)
        I, J = np.meshgrid(np.arange(self.NX), np.arange(self.NX), indexing="ij")
        for b in np.unique(band):
            rows = np.flatnonzero(band == b)
            pi, ii, jj = np.nonzero(G[rows])
            if pi.size == 0:
                continue
            lo, hi = rows[pi.min()], rows[pi.max()] + 1
            if mode == "box":
                out[lo:hi, ii.min():ii.max() + 1, jj.min():jj.max() + 1] = True
            else:  # octagon: x, y, x + y, x − y
                m2 = (I >= ii.min()) & (I <= ii.max()) & (J >= jj.min()) & (J <= jj.max())
                m2 &= (I + J >= (ii + jj).min()) & (I + J <= (ii + jj).max())
                m2 &= (I - J >= (ii - jj).min()) & (I - J <= (ii - jj).max())
                out[lo:hi] |= m2[None]
        return out

    def run(self, q_pose: int, mode: str) -> tuple[np.ndarray, bool, bool]:
        """Forward-backward over the whole log: (N, 3) widths (largest x-y side as x and y,
        heading), whether every set held the truth's cell, whether a set reached the grid's
        border (its width is then not valid)."""
        mg = self.p.initial.margin
        X = self.xs[None, :, None]
        Y = self.xs[None, None, :]
        TH = self.ps[:, None, None]
        G = (np.abs(X) <= mg[0] + self.C) & (np.abs(Y) <= mg[1] + self.C) & (np.abs(TH) <= mg[2] + self.P)
        G = self.represent(self.observed(G, 0, q_pose), 0, mode)
        F, steps = [G], []
        for k in range(self.N - 1):
            sh = self._shifts(k)
            out = np.zeros_like(G)
            propagate(G, out, *sh)
            G = self.represent(self.observed(out, k + 1, q_pose), k + 1, mode)
            F.append(G)
            steps.append(sh)
        S = F[-1]
        widths = np.zeros((self.N, 3))
        truth, clipped = True, False
        c, cp = self.NX // 2, self.NP // 2
        for k in range(self.N - 1, -1, -1):
            if k < self.N - 1:
                G = F[k].copy()
                pullback(G, S, *steps[k])
                S = self.represent(G, k, mode) & F[k]
            pi, ii, jj = np.nonzero(S)
            if pi.size == 0:
                return widths, False, clipped
            widths[k] = ((ii.max() - ii.min() + 1) * self.C, (jj.max() - jj.min() + 1) * self.C,
                         (pi.max() - pi.min() + 1) * self.P)
            truth = truth and bool(S[cp - 1:cp + 1, c - 1:c + 1, c - 1:c + 1].any())
            clipped = clipped or min(ii.min(), jj.min(), pi.min()) == 0 or ii.max() == self.NX - 1 \
                or jj.max() == self.NX - 1 or pi.max() == self.NP - 1
        return widths, truth, clipped


def median_widths(w: np.ndarray) -> tuple[float, float]:
    """(median largest x-y side, median heading width) of (N, 3) widths or (N, 3, 2) boxes."""
    if w.ndim == 3:
        w = w[:, :, 1] - w[:, :, 0]
    return float(np.median(np.maximum(w[:, 0], w[:, 1]))), float(np.median(w[:, 2]))


def ours(log, run: dict, slices: int):
    from ivslam_cli.config import resolve_config
    from ivslam_cli.slam.landmarks import Params
    from ivslam_cli.slam.landmarks.pipeline import solve

    params = Params.from_config(resolve_config(None, {**run, "landmarks.pose_slices": slices},
                                               log_bounds=log.bounds))
    return params, solve(log, params).poses.box


ASSUMPTIONS = {  # the filter's assumption, and our run under it (the map given)
    "q = 0": (0, {"robust.q_landmark": 0, "robust.q_pose": 0}),
    "q_pose = 1 at each node": (1, {"robust.q_landmark": 1_000_000, "robust.q_pose": 1,
                                    "landmarks.pose_window": 0.0}),
}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cell", type=float, default=0.003, help="cell side of the filter (m)")
    ap.add_argument("--steps", type=int, default=DEMO["steps"])
    args = ap.parse_args(argv)
    from ivslam_cli.simulate import simulate
    from ivslam_cli.simulate.config import SimConfig

    log = simulate(SimConfig(**{**DEMO, "steps": args.steps}))
    base = {"landmarks.initial_pose_from_truth": True, "landmarks.map_known": True}
    print(f"ivslam simulate --scenario landmarks --seed 3 --steps {args.steps} (the demo log's outlier-free twin), "
          f"the true map given; "
          "filter slices of 2pi/256 for its box and octagon")
    print("median over the nodes: largest x-y side m / heading rad")
    bad = False
    for name, (q_pose, extra) in ASSUMPTIONS.items():
        run = {**base, **extra}
        t0 = time.perf_counter()
        row = {}
        for s in (64, 256, 1024):
            params, box = ours(log, run, s)
            row[f"ours, {s} slices"] = median_widths(box)
        t_ours = time.perf_counter() - t0
        if q_pose == 0:
            sf = SetFilter(log, params, args.cell, 0.36)
        else:  # wider sets: coarser cells over a wider grid
            sf = SetFilter(log, params, max(args.cell, 0.005), 0.8, 2 * HEADING_CELL, 0.16)
        t0 = time.perf_counter()
        for mode, label in (("box", "filter, box per slice"), ("octagon", "filter, octagon per slice"),
                            ("cells", "filter, cells")):
            w, truth, clipped = sf.run(q_pose, mode)
            row[label] = median_widths(w)
            if not truth:
                print(f"  {name}, {label}: a set lost the truth's cell (the filter's approximation)")
                bad = True
            if clipped:
                print(f"  {name}, {label}: a set reached the grid's border: its widths are not valid")
                bad = True
        print(f"{name} (ours {t_ours:.1f} s, filter {time.perf_counter() - t0:.0f} s, cells {sf.C * 1000:g} mm x "
              f"{sf.P * 1000:g} mrad):")
        for label, (wp, wt) in row.items():
            print(f"  {label:>28}: {wp:.3f} m / {wt:.4f} rad")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
