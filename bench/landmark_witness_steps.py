"""Witnesses of the landmark CSP on twist logs without a lag (simulated logs): explicit worlds
that meet every stated bound, pushed to the extremes of one pose. Their spread at a node is a
lower bound of the width of any sound enclosure there: the floor the bounds allow.

The model is the pipeline's (:mod:`ivslam_cli.slam.motion`, twist odometry without a lag):
the twist ``z_k`` logged at stamp ``t_k`` is held over ``[t_k, t_{k+1})``; the true speed and
turn rate meet ``|z_v − v| ≤ odom_v + odom_v_rel·|v|`` and ``|z_ω − ω| ≤ odom_w +
odom_w_rel·|v|``; an observation at ``t_k`` is taken from the pose at ``t_k`` and meets
``|z_ρ − ρ| ≤ range_abs + range_rel·z_ρ`` and ``|z_α − α| ≤ bearing`` (α wrapped); the first
pose lies in the initial box (the truth ± ``initial_margin`` with ``--initial-pose-from-truth``).

A witness here holds one speed and one turn rate per step (a subset of the paths the bounds
allow), so its poses follow by exact arcs. It starts from the truth (whose twist is recovered
from its poses) and is pushed by sequential linear programming (HiGHS through highspy, a dev
dependency) over every step's twist, the first pose and, in SLAM mode, every landmark; the
twist constraints are linear (``v > 0``), the observations are linearised, and every step
taken is checked exactly on the integrated path. A witness keeps within ``S_CTRL`` of every
bound, or within the truth's own share of it where the truth uses more: observations the truth
breaks (its outliers) are left out, and an odometry step the truth breaks keeps the truth's
share there (such a witness breaks what the truth breaks, by no more).

Exact only up to the float arithmetic of the check (relative 1e-15): a floor, not a guarantee.
"""

from __future__ import annotations

from collections import Counter
import numpy as np

from bench.landmark_witness import S_CTRL, Bounds, wrap
from bench.witness_lp import Breaks, sparse_linprog


def _sinc(u):
    out = np.ones_like(u)
    nz = np.abs(u) > 1e-12
    out[nz] = np.sin(u[nz]) / u[nz]
    return out


def _dsinc(u):
    """d sinc(u) / du."""
    out = -u / 3.0
    nz = np.abs(u) > 1e-4
    out[nz] = (np.cos(u[nz]) - np.sin(u[nz]) / u[nz]) / u[nz]
    return out


BACKOFF = 1e-2  # the linear programs keep this share inside every bound (the check uses all of it)
TR0 = 0.5  # first trust region: share of each twist bound, metres of each landmark


def _share(used, bound):
    """The part of ``bound`` a witness may use: ``S_CTRL`` of it, or halfway from what the truth
    uses to the bound where the truth uses more (the truth keeps room to move)."""
    return np.minimum(np.maximum(S_CTRL * bound, used + 0.5 * (bound - used)), bound)


def integrate(P0, v, w, h):
    """Poses (N, 3) from ``P0`` under ``(v_k, w_k)`` held over ``h_k``: exact arcs (θ unwrapped)."""
    half = 0.5 * w * h
    th = P0[2] + np.concatenate([[0.0], np.cumsum(w * h)])
    L = v * h * _sinc(half)
    mid = th[:-1] + half
    x = P0[0] + np.concatenate([[0.0], np.cumsum(L * np.cos(mid))])
    y = P0[1] + np.concatenate([[0.0], np.cumsum(L * np.sin(mid))])
    return np.column_stack([x, y, th])


class StepProblem:
    """A twist log whose observations are at odometry stamps, its truth at the same stamps, and
    the share of each bound a witness may use."""

    def __init__(self, log, bounds: Bounds):
        """``bounds``: :meth:`bench.landmark_witness.Bounds.from_params` of the run (no lag)."""
        if bounds.lag_xy > 0 or bounds.lag_th > 0 or bounds.lag_time > 0:
            raise ValueError("landmark_witness_steps models no lag: use bench.landmark_witness for this log")
        self.b = bounds
        odo, obs, tr = log.odometry, log.observations, log.truth
        t = np.asarray(odo.stamp, float)
        if tr is None or tr.pose is None or not np.array_equal(np.asarray(tr.pose_stamp, float), t):
            raise ValueError("needs the true pose at every odometry stamp (a simulated log)")
        self.t0 = float(t[0])
        self.h = np.diff(t)
        self.N = t.size
        self.z = np.asarray(odo.twist, float)[:-1]
        T = np.asarray(tr.pose, float).copy()
        T[:, 2] = np.unwrap(T[:, 2])
        self.truth = T
        # the truth's twist, recovered from its poses (exact arcs)
        w = np.diff(T[:, 2]) / self.h
        half = 0.5 * w * self.h
        chord = np.hypot(np.diff(T[:, 0]), np.diff(T[:, 1]))
        self.v_true = chord / (self.h * _sinc(half))
        self.w_true = w
        if np.abs(integrate(T[0], self.v_true, self.w_true, self.h) - T).max() > 1e-6:
            raise ValueError("the truth is not a path of held twists between the odometry stamps")
        if (self.v_true <= 0).any():
            raise ValueError("witnesses need a positive speed at every step")
        b = bounds
        # share of each twist bound a witness may use: S_CTRL, or the truth's (beyond 1 where it breaks it)
        Bv = b.v_abs + b.v_rel * self.v_true
        Bw = b.w_abs + b.w_rel * self.v_true
        uv, uw = np.abs(self.z[:, 0] - self.v_true) / Bv, np.abs(self.z[:, 1] - self.w_true) / Bw
        self.sv = np.where(uv > 1, uv * (1 + 1e-9), _share(uv, 1.0))
        self.sw = np.where(uw > 1, uw * (1 + 1e-9), _share(uw, 1.0))
        self.odometry_outliers = np.flatnonzero((self.sv > 1) | (self.sw > 1))
        # observations
        s = np.asarray(obs.stamp, float)
        self.step = np.searchsorted(t, s)
        if (self.step >= self.N).any() or not np.array_equal(t[self.step], s):
            raise ValueError("witnesses need every observation at an odometry stamp")
        lid = np.asarray(obs.landmark_id, np.int64)
        self.landmarks = {int(i): np.asarray(xy, float) for i, xy in
                          zip(tr.landmark_id, np.asarray(tr.landmark_xy).reshape(-1, 2))}
        known = np.isin(lid, list(self.landmarks))
        rng, brg = np.asarray(obs.range, float), np.asarray(obs.bearing, float)
        er_bound = b.range_abs + b.range_rel * rng
        p = T[self.step]
        m = np.array([self.landmarks.get(int(i), (np.nan, np.nan)) for i in lid]).reshape(-1, 2)
        er = np.abs(np.hypot(m[:, 0] - p[:, 0], m[:, 1] - p[:, 1]) - rng)
        eb = np.abs(wrap(np.arctan2(m[:, 1] - p[:, 1], m[:, 0] - p[:, 0]) - p[:, 2] - brg))
        inl = known & (er <= er_bound) & (eb <= b.bearing)
        self.n_outliers = int((~inl).sum())
        self.out_step, self.out_lid = self.step[~inl], lid[~inl]
        self.step, self.lid, self.rng, self.brg = self.step[inl], lid[inl], rng[inl], brg[inl]
        self.er_b = _share(er[inl], er_bound[inl])
        self.eb_b = _share(eb[inl], b.bearing)
        self.ids = sorted(set(self.lid.tolist()))
        self.n_all = Counter(lid[known].tolist())  # a landmark's observations, outliers included

    def without(self, drop: np.ndarray) -> StepProblem:
        """The same problem with the inlier observations ``drop`` (a mask) left out: a witness
        may break them (the q a run states allows it)."""
        import copy

        out = copy.copy(self)
        keep = ~np.asarray(drop, bool)
        for name in ("step", "lid", "rng", "brg", "er_b", "eb_b"):
            setattr(out, name, getattr(self, name)[keep])
        out.ids = sorted(set(out.lid.tolist()))
        return out

    def breaks(self, q) -> Breaks:
        """What a witness may break under ``q`` = (q_pose, q_landmark, q_frac), by step."""
        return Breaks(q, self.step, self.step, self.lid, self.out_step, self.out_step, self.out_lid, self.n_all)

    def q_drops(self, node: int, q_pose: int, q_landmark: int, q_frac: float) -> np.ndarray:
        """A mask of inlier observations a witness may break under a run's q, nearest to step
        ``node`` first: at most ``q_pose`` broken at any step and ``max(q_landmark, ⌊q_frac·m⌋)``
        of a landmark's ``m``, the truth's outliers counted in both."""
        br = self.breaks((q_pose, q_landmark, q_frac))
        for j in np.argsort(np.abs(self.step - node), kind="stable"):
            br.take(j)
        return ~br.active


class StepWitness:
    """Witnesses of a :class:`StepProblem`: :meth:`push` one coordinate of one pose."""

    def __init__(self, pb: StepProblem, slam: bool, q: tuple[int, int, float] | None = None):
        """``q`` = (q_pose, q_landmark, q_landmark_frac) of a run: each push may also break
        observations as the run's q allows (:meth:`push`)."""
        self.pb, self.slam, self.q = pb, slam, q
        self.last = None
        self.active = np.ones(pb.step.size, bool)  # the observations the witness meets

    def state0(self) -> dict:
        pb = self.pb
        return {"P0": pb.truth[0].copy(), "v": pb.v_true.copy(), "w": pb.w_true.copy(),
                "m": np.array([pb.landmarks[i] for i in pb.ids]).reshape(-1, 2)}

    def poses(self, s: dict) -> np.ndarray:
        return integrate(s["P0"], s["v"], s["w"], self.pb.h)

    def feasible(self, s: dict) -> bool:
        """Every bound the witness must meet, on its integrated path."""
        pb, b = self.pb, self.pb.b
        tol = 1 + 1e-12
        v, w = s["v"], s["w"]
        if (v <= 0).any():
            return False
        if (np.abs(pb.z[:, 0] - v) > pb.sv * (b.v_abs + b.v_rel * v) * tol).any():
            return False
        if (np.abs(pb.z[:, 1] - w) > pb.sw * (b.w_abs + b.w_rel * v) * tol).any():
            return False
        if (np.abs(s["P0"] - pb.truth[0]) > S_CTRL * b.margin).any():
            return False
        X = self.poses(s)
        vr, vb = self.residuals(X, s["m"])[3:]
        off = ~self.active
        return bool(((np.abs(vr) <= pb.er_b) | off).all() and ((np.abs(vb) <= pb.eb_b) | off).all())

    def residuals(self, X, m):
        pb = self.pb
        col = np.searchsorted(pb.ids, pb.lid)
        p = X[pb.step]
        mm = m[col]
        dx, dy = mm[:, 0] - p[:, 0], mm[:, 1] - p[:, 1]
        rr = np.hypot(dx, dy)
        return dx, dy, rr, rr - pb.rng, wrap(np.arctan2(dy, dx) - p[:, 2] - pb.brg)

    def push(self, node: int, k: int, sign: int, iterations: int = 60) -> float:
        """The extreme of coordinate ``k`` of the pose at step ``node`` reached towards ``sign``
        (a value returned is that of a witness: :meth:`feasible` holds for it).

        Each linear program has the poses as variables beside the twists, the first pose and
        the landmarks, and the linearised arcs as equalities: every row is sparse.

        With ``q``, after each linear program the witness stops meeting the observation whose
        rows hold its objective most (the largest dual values), while the caps allow: at most
        ``q_pose`` broken at a step and ``max(q_landmark, ⌊q_frac·m⌋)`` of a landmark's ``m``,
        the truth's outliers counted in both (:attr:`active`: the ones it still meets)."""
        pb, b = self.pb, self.pb.b
        N, n1, nl = pb.N, pb.N - 1, len(pb.ids) if self.slam else 0
        cP, cv, cw, cm = 0, 3 * N, 3 * N + n1, 3 * N + 2 * n1
        NV = cm + 2 * nl
        st = self.state0()
        if not self.feasible(st):
            raise AssertionError("the truth is not a witness")
        Bv0 = b.v_abs + b.v_rel * pb.v_true
        Bw0 = b.w_abs + b.w_rel * pb.v_true
        col = np.searchsorted(pb.ids, pb.lid)
        I = np.arange(n1)
        no = pb.step.size
        breaks = pb.breaks(self.q or (0, 0, 0.0))
        self.active = active = breaks.active

        def value(s):
            return float(self.poses(s)[node, k])

        tr, trl = TR0, TR0
        left = iterations
        while left > 0:
            left -= 1
            X = self.poses(st)
            v, w, h = st["v"], st["w"], pb.h
            half = 0.5 * w * h
            sc = _sinc(half)
            L = v * h * sc
            mid = X[:-1, 2] + half
            c, sn = np.cos(mid), np.sin(mid)
            dL_dw = v * h * _dsinc(half) * 0.5 * h
            R, C, V, lo_r, hi_r = [], [], [], [], []
            r0 = 0

            def rows(n, cols_vals, lo, hi):
                nonlocal r0
                rr = r0 + np.arange(n)
                for cc, vv in cols_vals:
                    R.append(rr)
                    C.append(np.broadcast_to(cc, (n,)))
                    V.append(np.broadcast_to(vv, (n,)).astype(float))
                lo_r.append(np.broadcast_to(lo, (n,)).astype(float))
                hi_r.append(np.broadcast_to(hi, (n,)).astype(float))
                r0 += n

            # linearised arcs: dP_{k+1} − dP_k − ∂step·(dθ_k, dv_k, dw_k) = 0
            px, py, pt = cP + 3 * I, cP + 3 * I + 1, cP + 3 * I + 2
            rows(n1, [(px + 3, 1.0), (px, -1.0), (pt, L * sn), (cv + I, -h * sc * c),
                      (cw + I, 0.5 * h * L * sn - dL_dw * c)], 0.0, 0.0)
            rows(n1, [(py + 3, 1.0), (py, -1.0), (pt, -L * c), (cv + I, -h * sc * sn),
                      (cw + I, -0.5 * h * L * c - dL_dw * sn)], 0.0, 0.0)
            rows(n1, [(pt + 3, 1.0), (pt, -1.0), (cw + I, -h)], 0.0, 0.0)
            # twists (exact): v − z ≤ s(a + r v), z − v ≤ s(a + r v), |ω − z_ω| ≤ s(a_ω + r_ω v)
            sv, sw = pb.sv * (1 - BACKOFF), pb.sw * (1 - BACKOFF)
            rows(n1, [(cv + I, 1 - sv * b.v_rel)], -np.inf, pb.z[:, 0] + sv * b.v_abs - (1 - sv * b.v_rel) * v)
            rows(n1, [(cv + I, -(1 + sv * b.v_rel))], -np.inf, -pb.z[:, 0] + sv * b.v_abs + (1 + sv * b.v_rel) * v)
            for sgn in (1.0, -1.0):
                rows(n1, [(cw + I, sgn), (cv + I, -sw * b.w_rel)], -np.inf,
                     sgn * pb.z[:, 1] + sw * b.w_abs + sw * b.w_rel * v - sgn * w)
            # observations, linearised
            dx, dy, rr, vr, vb = self.residuals(X, st["m"])
            ps = cP + 3 * pb.step
            cr = [(ps, -dx / rr), (ps + 1, -dy / rr)]
            cb = [(ps, dy / rr ** 2), (ps + 1, -dx / rr ** 2), (ps + 2, -1.0)]
            if nl:
                cr += [(cm + 2 * col, dx / rr), (cm + 2 * col + 1, dy / rr)]
                cb += [(cm + 2 * col, -dy / rr ** 2), (cm + 2 * col + 1, dx / rr ** 2)]
            er = np.where(active, pb.er_b * (1 - BACKOFF), np.inf)
            eb = np.where(active, pb.eb_b * (1 - BACKOFF), np.inf)
            r_obs = r0
            rows(no, cr, -er - vr, er - vr)
            rows(no, cb, -eb - vb, eb - vb)
            lo, hi = np.full(NV, -np.inf), np.full(NV, np.inf)
            m0 = S_CTRL * b.margin * (1 - BACKOFF)
            lo[:3], hi[:3] = pb.truth[0] - m0 - st["P0"], pb.truth[0] + m0 - st["P0"]
            lo[cv:cw], hi[cv:cw] = -tr * Bv0, tr * Bv0
            lo[cw:cm], hi[cw:cm] = -tr * Bw0, tr * Bw0
            lo[cm:], hi[cm:] = -trl, trl
            lo, hi = np.minimum(lo, 0.0), np.maximum(hi, 0.0)
            cost = np.zeros(NV)
            cost[cP + 3 * node + k] = -sign
            ok, x, fun, y = sparse_linprog(cost, np.concatenate(R), np.concatenate(C), np.concatenate(V),
                                           np.concatenate(lo_r), np.concatenate(hi_r), lo, hi, duals=True)
            if not ok:
                tr, trl = 0.5 * tr, 0.5 * trl
                if tr < 1e-4:
                    break
                continue
            held = np.abs(y[r_obs:r_obs + no]) + np.abs(y[r_obs + no:r_obs + 2 * no])  # each observation's rows
            dropped = self.q is not None and breaks.pick(held)
            if dropped:
                left = min(left + 1, 4 * iterations)
            if -fun < 1e-6:
                if dropped:
                    continue
                break
            for frac in (1.0, 0.5, 0.25, 0.12, 0.06, 0.03):
                dz = frac * x
                cand = {"P0": st["P0"] + dz[:3], "v": st["v"] + dz[cv:cw], "w": st["w"] + dz[cw:cm],
                        "m": st["m"] + dz[cm:].reshape(-1, 2) if nl else st["m"]}
                if self.feasible(cand) and sign * (value(cand) - value(st)) > 0:
                    st = cand
                    tr, trl = min(1.5 * tr, 2.0), min(1.5 * trl, 2.0)
                    break
            else:
                tr, trl = 0.3 * tr, 0.3 * trl
                if tr < 1e-4:
                    break
        self.last = st
        return value(st)

    def pose_extremes(self, node: int) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of x, y, θ (θ unwrapped) over the witnesses found: a witness reaches each bound."""
        lo, hi = self.pb.truth[node].copy(), self.pb.truth[node].copy()
        for k in range(3):
            hi[k] = max(hi[k], self.push(node, k, +1))
            lo[k] = min(lo[k], self.push(node, k, -1))
        return lo, hi

    def world(self) -> dict:
        """The last witness :meth:`push` reached: first pose, twists, poses at every stamp, map."""
        s = self.last
        lm = dict(self.pb.landmarks)
        lm.update({i: s["m"][j] for j, i in enumerate(self.pb.ids)} if self.slam else {})
        return {"P0": s["P0"], "v": s["v"], "w": s["w"], "poses": self.poses(s), "landmarks": lm}
