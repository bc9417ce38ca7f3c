"""Witnesses of the landmark CSP: explicit solutions that meet every stated bound, pushed to the
extremes of a pose. They bound from below what any sound enclosure can reach (the floor).

A *witness* is a modelled path (the logged twist held between its stamps, the true speed and
turn rate within the twist bounds at every instant), a true pose at every observation frame
within the lag of that path (the pipeline's lag model, :func:`ivslam_cli.slam.motion.node_lags`),
a first pose within the initial box, and a map, such that every observation the ground truth
shows to be within its bounds (the log's inliers) meets its range and bearing bounds. Such a
world explains all the data under the assumption every run states, so a sound enclosure of a
pose (or landmark) holds the witness's; the spread of witnesses at a time is a lower bound of
the width of any sound enclosure there — the floor the bounds allow, measured from below (the
pipeline with the true map given measures it from above).

Witnesses are built from the truth: a modelled path is fitted to it (every true pose within the
lag of the path: :func:`fit_base`), then the path over a window of time, the true poses (and in
SLAM mode the landmarks seen there) are pushed towards an extreme of one pose by sequential
linear programming (HiGHS through highspy, a dev dependency), the path leaving the window where
the fitted one does so that everything outside is unchanged. Every accepted step is checked
exactly: the path integrated in closed form (arcs under held commands), every bound met with a
margin (``S_CTRL`` of each bound, ``S_OFF`` of each lag). Observations the truth shows to break
their bounds are left out: a witness may break exactly those, as the truth does.

Exact only up to the float arithmetic of the check (relative 1e-15): a floor, not a guarantee.
"""

from __future__ import annotations

import copy
from collections import Counter
from dataclasses import dataclass

import numpy as np

from bench.witness_lp import Breaks, linprog
from ivslam_cli.slam.motion import node_lags

S_CTRL = 0.97  # a witness uses this share of each control and observation bound
S_OFF = 0.95  # and of each lag
BLOCK = 0.5  # seconds of path per perturbed control (turn rate, speed scale, speed offset)
CHECK_EVERY = 1.0  # the fitted path holds the truth within the lag at every frame and every second
TRUTH_GAP = 0.5  # seconds: the truth is interpolated only across shorter gaps


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


@dataclass
class Bounds:
    """The bounds of a landmarks run, read from :class:`ivslam_cli.slam.landmarks.params.Params`."""

    range_abs: float
    range_rel: float
    bearing: float
    v_abs: float
    v_rel: float
    w_abs: float
    lag_xy: float
    lag_th: float
    lag_time: float
    lag_memory: float
    margin: np.ndarray
    w_rel: float = 0.0  # turn-rate bound per m/s (witnesses here keep within w_abs: a subset)

    @classmethod
    def from_params(cls, p) -> Bounds:
        o = p.odometry
        return cls(p.range_abs, p.range_rel, p.bearing, o.odom_v, o.odom_v_rel, o.odom_w, o.odom_lag_xy,
                   o.odom_lag_th, o.odom_lag_time, o.odom_lag_memory, np.asarray(p.initial.margin, float),
                   o.odom_w_rel)


class Problem:
    """One robot's twist odometry, inlier observations, truth and the time grid of the witnesses."""

    def __init__(self, log, bounds: Bounds, extra_stamps=()):
        """``extra_stamps``: log stamps to put on the grid (the nodes whose poses are pushed)."""
        self.b = bounds
        odo, obs, tr = log.odometry, log.observations, log.truth
        self.t0 = float(odo.stamp[0])
        to = np.asarray(odo.stamp, float) - self.t0
        z = np.asarray(odo.twist, float)
        ts_t = np.asarray(tr.pose_stamp, float) - self.t0
        self._tt, self._tp = ts_t, np.asarray(tr.pose, float).copy()
        self._tp[:, 2] = np.unwrap(self._tp[:, 2])
        self.landmarks = {int(i): np.asarray(xy, float) for i, xy in zip(tr.landmark_id, np.asarray(tr.landmark_xy).reshape(-1, 2))}
        self.tend = float(min(to[-1], ts_t[-1]))
        t = np.asarray(obs.stamp, float) - self.t0
        lid = np.asarray(obs.landmark_id, np.int64)
        keep = (t > 0) & (t < self.tend) & np.isin(lid, list(self.landmarks)) & (self.truth_gap(t) < TRUTH_GAP)
        t, lid, rng, brg = t[keep], lid[keep], np.asarray(obs.range, float)[keep], np.asarray(obs.bearing, float)[keep]
        tp = self.truth(t)
        m = np.array([self.landmarks[i] for i in lid]).reshape(-1, 2)
        self.erange = bounds.range_abs + bounds.range_rel * rng
        er = np.abs(np.hypot(m[:, 0] - tp[:, 0], m[:, 1] - tp[:, 1]) - rng)
        eb = np.abs(wrap(np.arctan2(m[:, 1] - tp[:, 1], m[:, 0] - tp[:, 0]) - tp[:, 2] - brg))
        inl = (er <= self.erange) & (eb <= bounds.bearing)
        self.n_outliers = int((~inl).sum())
        self.out_t, self.out_lid = t[~inl], lid[~inl]  # the truth's outliers (they break their bounds)
        self.odo_t = to
        self.t, self.lid, self.rng, self.brg = t[inl], lid[inl], rng[inl], brg[inl]
        self.erange = self.erange[inl]
        # the margin the truth leaves (a witness keeps within S_CTRL of a bound, or the truth's own error)
        self.er_b = np.minimum(np.maximum(S_CTRL * self.erange, er[inl] + 1e-12), self.erange)
        self.eb_b = np.minimum(np.maximum(S_CTRL * bounds.bearing, eb[inl] + 1e-12), bounds.bearing)
        self.frame_t, self.frame = np.unique(self.t, return_inverse=True)
        # the grid: commands, frames, block boundaries
        self.nblk = int(np.ceil(self.tend / BLOCK))
        extra = np.asarray(extra_stamps, float) - self.t0
        g = np.unique(np.concatenate([to[(to > 0) & (to < self.tend)], self.frame_t, extra[(extra > 0) & (extra < self.tend)],
                                      np.arange(self.nblk) * BLOCK, [self.tend]]))
        self.ts, self.h = g, np.diff(g)
        self.N = g.size
        j = np.clip(np.searchsorted(to, g[:-1], side="right") - 1, 0, to.size - 1)
        self.vc, self.wc = z[j, 0], z[j, 1]
        self.blk = np.minimum(np.floor(g[:-1] / BLOCK + 1e-9).astype(np.int64), self.nblk - 1)
        self.bstart = np.searchsorted(self.blk, np.arange(self.nblk + 1))
        self.fstep = np.searchsorted(g, self.frame_t)
        lag = node_lags(to, z, g, bounds.lag_xy, bounds.lag_th, bounds.lag_time, bounds.lag_memory) if (
            bounds.lag_time > 0 or bounds.lag_xy > 0 or bounds.lag_th > 0) else np.zeros((g.size, 2))
        self.lag3 = np.column_stack([lag[:, 0], lag[:, 0], lag[:, 1]])
        if not (self.lag3 > 0).all():
            raise ValueError("witnesses need a lag model (odom_lag_xy, odom_lag_th > 0): the truth is not a "
                             "modelled path itself")
        sec = np.searchsorted(g, np.arange(0.0, self.tend, CHECK_EVERY))
        sec = sec[self.truth_gap(g[sec]) < TRUTH_GAP]
        self.ck = np.unique(np.concatenate([self.fstep, sec]))
        # control bounds: v = z + a|z| + c, w = z_w + d (a subset of the twist bounds)
        self.a_max = S_CTRL * bounds.v_rel / (1 + bounds.v_rel)
        self.c_max = S_CTRL * bounds.v_abs / (1 + bounds.v_rel)
        self.d_max = S_CTRL * bounds.w_abs

    def without(self, drop: np.ndarray) -> Problem:
        """The same problem with the inlier observations ``drop`` (a mask) left out as well: a
        witness may break them (the q a run states allows it). Frames and grid unchanged."""
        out = copy.copy(self)
        keep = ~np.asarray(drop, bool)
        for name in ("t", "lid", "rng", "brg", "erange", "er_b", "eb_b", "frame"):
            setattr(out, name, getattr(self, name)[keep])
        return out

    def breaks(self, q) -> Breaks:
        """What a witness may break under ``q`` = (q_pose, q_landmark, q_frac): an observation
        counts at both odometry stamps around it; ``m`` counts a landmark's observations here."""
        m = Counter(self.lid.tolist()) + Counter(self.out_lid.tolist())
        return Breaks(q, *self.odometry_bracket(self.t), self.lid, *self.odometry_bracket(self.out_t), self.out_lid, m)

    def odometry_bracket(self, t):
        """Per stamp: the indices of the odometry stamps at or before and at or after it (a
        run attaches an observation to a node between them)."""
        t = np.atleast_1d(np.asarray(t, float))
        hi = np.clip(np.searchsorted(self.odo_t, t, side="left"), 0, self.odo_t.size - 1)
        lo = np.clip(np.searchsorted(self.odo_t, t, side="right") - 1, 0, self.odo_t.size - 1)
        return lo, hi

    def truth(self, t):
        t = np.atleast_1d(np.asarray(t, float))
        return np.column_stack([np.interp(t, self._tt, self._tp[:, k]) for k in range(3)])

    def truth_gap(self, t):
        t = np.atleast_1d(np.asarray(t, float))
        i = np.clip(np.searchsorted(self._tt, t), 1, self._tt.size - 1)
        return self._tt[i] - self._tt[i - 1]

    def initial_box(self):
        """The modelled first pose's half-widths around the truth (margin + lag), times S_CTRL."""
        return S_CTRL * (self.b.margin + self.lag3[0])


class Path:
    """The modelled path over steps ``[s0, s1]`` from pose ``P`` (exact arcs under held commands)."""

    def __init__(self, pb: Problem, P, d, a, c, s0, s1):
        sl = slice(s0, s1)
        b = pb.blk[sl]
        h = pb.h[sl]
        w = pb.wc[sl] + d[b]
        v = pb.vc[sl] + a[b] * np.abs(pb.vc[sl]) + c[b]
        dth = w * h
        th = P[2] + np.concatenate([[0.0], np.cumsum(dth)])
        half = 0.5 * dth
        sinc = np.ones_like(half)
        nz = np.abs(half) > 1e-12
        sinc[nz] = np.sin(half[nz]) / half[nz]
        mid = th[:-1] + half
        L = v * h * sinc
        x = P[0] + np.concatenate([[0.0], np.cumsum(L * np.cos(mid))])
        y = P[1] + np.concatenate([[0.0], np.cumsum(L * np.sin(mid))])
        self.X = np.column_stack([x, y, th])
        self.s0, self.s1 = s0, s1
        self._parts = (L, mid, h, sinc)

    def jac(self, pb: Problem, rows, b0, nb):
        """Poses at absolute steps ``rows`` and their derivatives with respect to ``[P (3), d, a, c]``
        of blocks ``b0 .. b0 + nb`` (prefix sums; the derivative of the arc's sinc is left out)."""
        s0 = self.s0
        rows = np.asarray(rows, np.int64)
        n = rows - s0
        L, mid, h, sinc = self._parts
        tau = pb.ts[s0:self.s1] + 0.5 * h
        m, nv = n.size, 3 + 3 * nb
        J = np.zeros((m, 3, nv))
        J[:, 0, 0] = J[:, 1, 1] = J[:, 2, 2] = 1.0
        gx, gy = -L * np.sin(mid), L * np.cos(mid)
        z0 = np.zeros(1)
        Gx, Gy = np.concatenate([z0, np.cumsum(gx)]), np.concatenate([z0, np.cumsum(gy)])
        GxT, GyT = np.concatenate([z0, np.cumsum(gx * tau)]), np.concatenate([z0, np.cumsum(gy * tau)])
        J[:, 0, 2], J[:, 1, 2] = Gx[n], Gy[n]
        blocks = b0 + np.arange(nb)
        B = blocks * BLOCK
        e0 = np.clip(pb.bstart[blocks] - s0, 0, L.size)
        e1 = np.clip(pb.bstart[blocks + 1] - s0, 0, L.size)
        hi = np.minimum(e1[None, :], n[:, None])
        lo = np.broadcast_to(e0[None, :], hi.shape)
        inb = hi > lo
        e1b = np.broadcast_to(e1[None, :], hi.shape)
        for k, (G, GT) in enumerate(((Gx, GxT), (Gy, GyT))):
            inside = np.where(inb, (GT[hi] - GT[lo]) - B[None, :] * (G[hi] - G[lo]), 0.0)
            after = np.where(n[:, None] > e1b, BLOCK * (G[n][:, None] - G[e1b]), 0.0)
            J[:, k, 3:3 + nb] = inside + after
        J[:, 2, 3:3 + nb] = np.clip(pb.ts[rows][:, None] - B[None, :], 0.0, BLOCK)
        vabs = np.abs(pb.vc[s0:self.s1])
        for k, f in enumerate((np.cos(mid) * h * sinc, np.sin(mid) * h * sinc)):
            Ka = np.concatenate([z0, np.cumsum(f * vabs)])
            Kc = np.concatenate([z0, np.cumsum(f)])
            J[:, k, 3 + nb:3 + 2 * nb] = np.where(inb, Ka[hi] - Ka[lo], 0.0)
            J[:, k, 3 + 2 * nb:] = np.where(inb, Kc[hi] - Kc[lo], 0.0)
        return self.X[n], J


@dataclass
class Base:
    """A modelled path explaining the truth: first pose, per-block controls, and the largest
    share of the lag the truth needs at a check step."""

    P0: np.ndarray
    d: np.ndarray
    a: np.ndarray
    c: np.ndarray
    worst: float


def q_drops(pb: Problem, t_node: float, span: float, q_pose: int, q_landmark: int, q_frac: float) -> np.ndarray:
    """A mask of inlier observations a witness may break under a run's q assumption, nearest
    to ``t_node`` (seconds from the log's start) first, within ``span`` seconds of it: at most
    ``q_pose`` broken observations (the truth's outliers included) at any node — counted on
    both odometry stamps around each observation, so never two at one node whichever of them
    the run attaches it to — and at most ``max(q_landmark, ⌊q_frac·m⌋)`` of a landmark's ``m``
    observations (``m`` counted here, at most the run's count: a smaller q)."""
    br = pb.breaks((q_pose, q_landmark, q_frac))
    dt = np.abs(pb.t - t_node)
    for j in np.argsort(dt, kind="stable"):
        if dt[j] > span:
            break
        br.take(j)
    return ~br.active


def fit_base(pb: Problem, chunk: float = 40.0, keep: float = 25.0, iterations: int = 20) -> Base:
    """Controls of a modelled path whose distance to the truth, at every check step, is the
    smallest share of the lag (minimax by SLP, chunk after chunk)."""
    d, a, c = np.zeros(pb.nblk), np.zeros(pb.nblk), np.zeros(pb.nblk)
    T0 = pb.truth(0.0)[0]
    p0b = pb.initial_box()
    P = T0.copy()
    P0 = P.copy()
    s0, worst = 0, 0.0
    cb1 = np.array([pb.d_max, pb.a_max, pb.c_max])
    while True:
        s1 = min(pb.N - 1, int(np.searchsorted(pb.ts, pb.ts[s0] + chunk)))
        b0, nb = pb.blk[s0], pb.blk[s1 - 1] - pb.blk[s0] + 1
        ck = pb.ck[(pb.ck >= s0) & (pb.ck <= s1)]
        tt, LG = pb.truth(pb.ts[ck]), pb.lag3[ck]
        cb = np.repeat(cb1, nb)
        for _ in range(iterations):
            X, J = Path(pb, P, d, a, c, s0, s1).jac(pb, ck, b0, nb)
            E = tt - X
            nv = 4 + 3 * nb
            A = np.concatenate([np.concatenate([-J, -LG[:, :, None]], axis=2).reshape(-1, nv),
                                np.concatenate([J, -LG[:, :, None]], axis=2).reshape(-1, nv)])
            rhs = np.concatenate([-E.ravel(), E.ravel()])
            cur = np.concatenate([d[b0:b0 + nb], a[b0:b0 + nb], c[b0:b0 + nb]])
            plo, phi = (T0 - p0b - P, T0 + p0b - P) if s0 == 0 else (np.zeros(3), np.zeros(3))
            lo = np.concatenate([plo, np.maximum(-cb - cur, -0.5 * cb), [0.0]])
            hi = np.concatenate([phi, np.minimum(cb - cur, 0.5 * cb), [1e4]])
            cost = np.zeros(nv)
            cost[-1] = 1.0
            ok, dz, _ = linprog(cost, A_ub=A, b_ub=rhs, bounds=np.column_stack([lo, hi]))
            if not ok:
                raise RuntimeError("fitting a path to the truth: no solution of the linear program")
            if s0 == 0:
                P = P + dz[:3]
                P0 = P.copy()
            d[b0:b0 + nb] += dz[3:3 + nb]
            a[b0:b0 + nb] += dz[3 + nb:3 + 2 * nb]
            c[b0:b0 + nb] += dz[3 + 2 * nb:3 + 3 * nb]
            if np.abs(dz[:-1]).max() < 1e-10:
                break
        path = Path(pb, P, d, a, c, s0, s1)
        kend = s1 if s1 >= pb.N - 1 else int(np.searchsorted(pb.ts, pb.ts[s0] + keep))
        mk = ck <= kend
        ratio = np.abs(tt - path.X[ck - s0]) / LG
        worst = max(worst, float(ratio[mk].max(initial=0.0)))
        if s1 >= pb.N - 1:
            break
        P = path.X[kend - s0].copy()
        s0 = kend
    return Base(P0, d, a, c, worst)


class Witness:
    """Witnesses around a fitted path: :meth:`push` one coordinate of a pose or a landmark,
    :meth:`pose_extremes` every coordinate of a pose."""

    def __init__(self, pb: Problem, base: Base, slam: bool, q: tuple[int, int, float] | None = None):
        """``q`` = (q_pose, q_landmark, q_landmark_frac) of a run: each push may also break
        observations as the run's q allows, the one whose rows hold the push most (largest dual
        values) after each linear program (:class:`Breaks`)."""
        self.pb, self.base, self.slam, self.q = pb, base, slam, q
        self.breaks = None
        self.X = Path(pb, base.P0, base.d, base.a, base.c, 0, pb.N - 1).X
        self.off0 = pb.truth(pb.frame_t) - self.X[pb.fstep]  # each frame's true pose, from the path
        self.offb = S_OFF * pb.lag3[pb.fstep]
        if not (np.abs(self.off0) <= self.offb).all():
            raise ValueError(f"the fitted path leaves the truth beyond {S_OFF} of the lag (worst {base.worst:.3f})")
        d = np.abs(pb.truth(pb.ts[pb.ck]) - self.X[pb.ck])[:, :2]
        self.slack = (S_OFF * pb.lag3[pb.ck, :2] - d).min(axis=1)
        self.by_frame = [np.flatnonzero(pb.frame == f) for f in range(pb.frame_t.size)]

    def push(self, t_lo: float, t_hi: float, target: tuple, sign: int, iterations: int = 40) -> float:
        """The extreme of ``target`` — ``("pose", step, k)`` (coordinate ``k`` of the true pose at
        grid step ``step``) or ``("lm", id, k)`` — reached towards ``sign`` by witnesses whose path
        differs from the fitted one over ``[t_lo, t_hi]`` only (a value the witness returned holds
        every bound: see the module docstring)."""
        pb = self.pb
        b0 = max(int(np.floor(t_lo / BLOCK)), 0)
        b1 = min(int(np.ceil(t_hi / BLOCK)), pb.nblk)
        if target[0] == "pose":
            ns = int(target[1])
            b0, b1 = min(b0, pb.blk[min(ns, pb.N - 2)]), max(b1, pb.blk[min(ns, pb.N - 2)] + 1)
        nb = b1 - b0
        w0 = int(pb.bstart[b0])
        w1 = int(pb.bstart[b1]) if b1 < pb.nblk else pb.N - 1
        first, has_end = w0 == 0, w1 < pb.N - 1
        fw = np.flatnonzero((pb.fstep >= w0) & (pb.fstep <= w1))
        lids = set(pb.lid[np.concatenate([self.by_frame[f] for f in fw])].tolist()) if (self.slam and fw.size) else set()
        if target[0] == "lm":
            lids.add(int(target[1]))
        lids = sorted(lids)
        inwin = np.zeros(pb.frame_t.size, bool)
        inwin[fw] = True
        fo = np.flatnonzero(~inwin & np.isin(np.arange(pb.frame_t.size), pb.frame[np.isin(pb.lid, lids)]))
        star_frame = -1
        if target[0] == "pose":
            hit = np.flatnonzero(pb.fstep[fw] == ns)
            star_frame = int(hit[0]) if hit.size else -1
        nvp, nfw, nfo, nl = 3 + 3 * nb, fw.size, fo.size, len(lids)
        c_fw = nvp
        c_star = c_fw + 3 * nfw
        c_lm = c_star + 3
        c_fo = c_lm + 2 * nl
        NV = c_fo + 3 * nfo
        lmcol = {l: c_lm + 2 * i for i, l in enumerate(lids)}
        ow = np.concatenate([self.by_frame[f] for f in fw]) if nfw else np.zeros(0, np.int64)
        ow_f = np.searchsorted(fw, pb.frame[ow])  # window frame of each window observation
        oo = np.concatenate([self.by_frame[f] for f in fo]) if nfo else np.zeros(0, np.int64)
        oo_f = np.searchsorted(fo, pb.frame[oo])
        endslack = min(self.slack[pb.ck > w1].min(initial=1.0), (1 - S_OFF) * pb.lag3[:, :2].min()) if has_end else 1.0
        Xend = self.X[w1]
        rows = np.concatenate([pb.fstep[fw], [ns if target[0] == "pose" else w0, w1]]).astype(np.int64)
        cb = np.repeat([pb.d_max, pb.a_max, pb.c_max], nb)
        sb = S_OFF * pb.lag3[ns] if target[0] == "pose" else np.zeros(3)
        st = {"P": (self.base.P0 if first else self.X[w0]).copy(), "d": self.base.d.copy(), "a": self.base.a.copy(),
              "c": self.base.c.copy(), "fw": self.off0[fw].copy(), "star": np.zeros(3),
              "lm": {l: pb.landmarks[l].copy() for l in lids}, "fo": self.off0[fo].copy()}

        def lm_xy(s, ids):
            return np.array([s["lm"][i] if i in s["lm"] else pb.landmarks[i] for i in ids]).reshape(-1, 2)

        def residuals(pose, m, k):
            dx, dy = m[:, 0] - pose[:, 0], m[:, 1] - pose[:, 1]
            rr = np.hypot(dx, dy)
            return dx, dy, rr, rr - pb.rng[k], wrap(np.arctan2(dy, dx) - pose[:, 2] - pb.brg[k])

        def obs_block(dx, dy, rr, Jp, k, cols):
            """Rows of range and bearing in the columns of the pose (Jp: (n, 3, NV)) and landmark."""
            Jr = (-dx[:, None] * Jp[:, 0] - dy[:, None] * Jp[:, 1]) / rr[:, None]
            Jb = (dy[:, None] * Jp[:, 0] - dx[:, None] * Jp[:, 1]) / rr[:, None] ** 2 - Jp[:, 2]
            i = np.flatnonzero(cols >= 0)
            Jr[i, cols[i]] += dx[i] / rr[i]
            Jr[i, cols[i] + 1] += dy[i] / rr[i]
            Jb[i, cols[i]] -= dy[i] / rr[i] ** 2
            Jb[i, cols[i] + 1] += dx[i] / rr[i] ** 2
            return Jr, Jb

        def lmcols(ids):
            return np.array([lmcol.get(int(i), -1) for i in ids], np.int64)

        if self.q is not None:
            self.breaks = pb.breaks(self.q)
        active = self.breaks.active if self.q is not None else np.ones(pb.t.size, bool)
        layout = []  # (observations, first row) of each block of four

        def linearise(s):
            X, J = Path(pb, s["P"], s["d"], s["a"], s["c"], w0, w1).jac(pb, rows, b0, nb)
            blocks, rhs = [], []
            layout.clear()
            r0 = 0
            for k, pose, Jp in self._obs_parts(X, J, s, ow, ow_f, oo, oo_f, nfw, NV, nvp, c_fw, c_fo):
                on = active[k]
                k, pose, Jp = k[on], pose[on], Jp[on]
                if not k.size:
                    continue
                layout.append((k, r0))
                r0 += 4 * k.size
                dx, dy, rr, vr, vb = residuals(pose, lm_xy(s, pb.lid[k]), k)
                Jr, Jb = obs_block(dx, dy, rr, Jp, k, lmcols(pb.lid[k]))
                blocks += [Jr, -Jr, Jb, -Jb]
                rhs += [pb.er_b[k] - vr, pb.er_b[k] + vr, pb.eb_b[k] - vb, pb.eb_b[k] + vb]
            Aeq = beq = None
            if has_end:
                e = np.zeros((3, NV))
                e[:, :nvp] = J[-1]
                Aeq, beq = e[2:3], np.array([Xend[2] - X[-1, 2]])
                blocks += [e[:2], -e[:2]]
                rhs += [0.5 * endslack - (X[-1, :2] - Xend[:2]), 0.5 * endslack + (X[-1, :2] - Xend[:2])]
            A = np.vstack(blocks) if blocks else None
            return X, J, A, (np.concatenate(rhs) if rhs else None), Aeq, beq

        def bounds(s, tr, trl):
            lo, hi = np.full(NV, -np.inf), np.full(NV, np.inf)
            if first:
                T0, p0b = pb.truth(0.0)[0], pb.initial_box()
                lo[:3], hi[:3] = T0 - p0b - s["P"], T0 + p0b - s["P"]
            else:
                lo[:3] = hi[:3] = 0.0
            cur = np.concatenate([s["d"][b0:b1], s["a"][b0:b1], s["c"][b0:b1]])
            lo[3:nvp], hi[3:nvp] = np.maximum(-cb - cur, -tr * cb), np.minimum(cb - cur, tr * cb)
            lo[c_fw:c_star], hi[c_fw:c_star] = (-self.offb[fw] - s["fw"]).ravel(), (self.offb[fw] - s["fw"]).ravel()
            lo[c_star:c_lm], hi[c_star:c_lm] = -sb - s["star"], sb - s["star"]
            lo[c_lm:c_fo], hi[c_lm:c_fo] = -trl, trl
            lo[c_fo:], hi[c_fo:] = (-self.offb[fo] - s["fo"]).ravel(), (self.offb[fo] - s["fo"]).ravel()
            return np.minimum(lo, 0.0), np.maximum(hi, 0.0)

        def apply(s, dz):
            t = dict(s)
            if first:
                t["P"] = s["P"] + dz[:3]
            for key, off in (("d", 3), ("a", 3 + nb), ("c", 3 + 2 * nb)):
                t[key] = s[key].copy()
                t[key][b0:b1] += dz[off:off + nb]
            t["fw"] = s["fw"] + dz[c_fw:c_star].reshape(-1, 3)
            t["star"] = s["star"] + dz[c_star:c_lm]
            t["lm"] = {l: s["lm"][l] + dz[lmcol[l]:lmcol[l] + 2] for l in lids}
            t["fo"] = s["fo"] + dz[c_fo:].reshape(-1, 3)
            return t

        def restore(s):
            """Newton steps on the speed controls so that the path ends where the fitted one does."""
            if not has_end:
                return s
            s = dict(s, a=s["a"].copy(), c=s["c"].copy())
            sc = np.concatenate([np.full(nb, pb.a_max), np.full(nb, pb.c_max)])
            for _ in range(8):
                X, J = Path(pb, s["P"], s["d"], s["a"], s["c"], w0, w1).jac(pb, [w1], b0, nb)
                res = X[0, :2] - Xend[:2]
                if np.abs(res).max() < 0.2 * endslack:
                    break
                step = np.linalg.lstsq(J[0][:2, 3 + nb:] * sc, -res, rcond=None)[0] * sc
                s["a"][b0:b1] = np.clip(s["a"][b0:b1] + step[:nb], -pb.a_max, pb.a_max)
                s["c"][b0:b1] = np.clip(s["c"][b0:b1] + step[nb:], -pb.c_max, pb.c_max)
            return s

        def feasible(s):
            tol = 1 + 1e-9
            if (np.abs(s["d"][b0:b1]) > pb.d_max * tol).any() or (np.abs(s["a"][b0:b1]) > pb.a_max * tol).any() \
                    or (np.abs(s["c"][b0:b1]) > pb.c_max * tol).any():
                return False
            if first and (np.abs(s["P"] - pb.truth(0.0)[0]) > pb.initial_box() * tol).any():
                return False
            X = Path(pb, s["P"], s["d"], s["a"], s["c"], w0, w1).X
            if has_end:
                de = X[-1] - Xend
                if abs(de[2]) > 1e-9 or np.abs(de[:2]).max() > endslack:
                    return False
            if (np.abs(s["fw"]) > self.offb[fw] * tol).any() or (np.abs(s["fo"]) > self.offb[fo] * tol).any() \
                    or (np.abs(s["star"]) > sb * tol + 1e-300).any():
                return False
            for k, pose in ((ow, X[pb.fstep[fw][ow_f] - w0] + s["fw"][ow_f]), (oo, self.X[pb.fstep[fo][oo_f]] + s["fo"][oo_f])):
                k, pose = k[active[k]], pose[active[k]]
                if k.size:
                    _, _, _, vr, vb = residuals(pose, lm_xy(s, pb.lid[k]), k)
                    if (np.abs(vr) > pb.er_b[k]).any() or (np.abs(vb) > pb.eb_b[k]).any():
                        return False
            return True

        def value(s):
            if target[0] == "lm":
                return float(s["lm"][int(target[1])][target[2]])
            X = Path(pb, s["P"], s["d"], s["a"], s["c"], w0, w1).X
            off = s["fw"][star_frame] if star_frame >= 0 else s["star"]
            return float(X[ns - w0][target[2]] + off[target[2]])

        if not feasible(st):
            raise AssertionError("the fitted path is not a witness")
        ctx = {"first": first, "w0": w0, "w1": w1, "fw": fw, "fo": fo, "star_frame": star_frame}
        tr, trl = 0.3, 0.3
        for _ in range(iterations):
            X, J, A, rhs, Aeq, beq = linearise(st)
            lo, hi = bounds(st, tr, trl)
            cost = np.zeros(NV)
            if target[0] == "pose":
                cost[:nvp] = -sign * J[nfw][target[2]]
                col = (c_fw + 3 * star_frame) if star_frame >= 0 else c_star
                cost[col + target[2]] -= sign
            else:
                cost[lmcol[int(target[1])] + target[2]] = -sign
            ok, x, fun, y = linprog(cost, A_ub=A, b_ub=rhs, A_eq=Aeq, b_eq=beq, bounds=np.column_stack([lo, hi]),
                                    duals=True)
            if not ok:
                tr, trl = 0.5 * tr, 0.5 * trl
                if tr < 1e-4:
                    break
                continue
            broke = False
            if self.q is not None and layout:
                score = np.zeros(pb.t.size)
                for k, r0 in layout:
                    n = k.size
                    score[k] += np.abs(y[r0:r0 + 4 * n]).reshape(4, n).sum(axis=0)
                broke = self.breaks.pick(score)
            if -fun < 1e-5:
                if broke:
                    continue
                break
            for frac in (1.0, 0.5, 0.25, 0.12):
                cand = restore(apply(st, frac * x))
                if feasible(cand) and sign * (value(cand) - value(st)) > 0:
                    st = cand
                    tr, trl = min(1.5 * tr, 1.0), min(1.5 * trl, 2.0)
                    break
            else:
                tr, trl = 0.3 * tr, 0.3 * trl
                if tr < 1e-4:
                    break
        self._last = (st, ctx)
        return value(st)

    def world(self) -> dict:
        """The last witness :meth:`push` reached, whole: ``P0`` (first modelled pose), the per-block
        controls ``d``, ``a``, ``c``, the true pose of every frame ``frames`` (F, 3) and the map
        ``landmarks`` {id: (x, y)} — for a check that does not trust this module."""
        st, ctx = self._last
        pb = self.pb
        frames = pb.truth(pb.frame_t)
        X = Path(pb, st["P"], st["d"], st["a"], st["c"], ctx["w0"], ctx["w1"]).X
        frames[ctx["fw"]] = X[pb.fstep[ctx["fw"]] - ctx["w0"]] + st["fw"]
        frames[ctx["fo"]] = self.X[pb.fstep[ctx["fo"]]] + st["fo"]
        lm = dict(pb.landmarks)
        lm.update(st["lm"])
        return {"P0": st["P"] if ctx["first"] else self.base.P0.copy(), "d": st["d"], "a": st["a"], "c": st["c"],
                "frames": frames, "landmarks": lm}

    def step(self, stamp: float) -> int:
        """The grid step of a log stamp (put on the grid with ``extra_stamps``)."""
        t = float(stamp) - self.pb.t0
        k = int(np.searchsorted(self.pb.ts, t))
        if k >= self.pb.N or abs(self.pb.ts[k] - t) > 1e-9:
            raise ValueError(f"t = {t:.6f} s is not on the grid (pass it in extra_stamps)")
        return k

    def pose_extremes(self, stamp: float, windows=(30.0, 120.0)) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of x, y, θ over the witnesses found (every window tried, both ways): the true
        pose at ``stamp`` of some witness reaches each bound."""
        k = self.step(stamp)
        t = self.pb.ts[k]
        lo, hi = self.pb.truth(t)[0], self.pb.truth(t)[0]
        for c in range(3):
            for w in windows:
                hi[c] = max(hi[c], self.push(t - w, t + w, ("pose", k, c), +1))
                lo[c] = min(lo[c], self.push(t - w, t + w, ("pose", k, c), -1))
        return lo, hi

    def _obs_parts(self, X, J, s, ow, ow_f, oo, oo_f, nfw, NV, nvp, c_fw, c_fo):
        """(observation indices, true poses, pose Jacobians (n, 3, NV)) of the window's frames and
        of the frames outside it whose offsets are free."""
        out = []
        if ow.size:
            Jp = np.zeros((ow.size, 3, NV))
            Jp[:, :, :nvp] = J[:nfw][ow_f]
            for k in range(3):
                Jp[np.arange(ow.size), k, c_fw + 3 * ow_f + k] = 1.0
            out.append((ow, X[:nfw][ow_f] + s["fw"][ow_f], Jp))
        if oo.size:
            Jp = np.zeros((oo.size, 3, NV))
            for k in range(3):
                Jp[np.arange(oo.size), k, c_fo + 3 * oo_f + k] = 1.0
            out.append((oo, self.X[self.pb.fstep[self.pb.frame[oo]]] + s["fo"][oo_f], Jp))
        return out
