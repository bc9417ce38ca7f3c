"""What the witness modules' linear programs share: HiGHS through highspy (a dev dependency),
sparse and dense, with the rows' dual values on request, and :class:`Breaks`, the observations a
witness may still break under a run's q, picked by those duals."""

from __future__ import annotations

from collections import Counter

import numpy as np


class Breaks:
    """The observations a witness may still break under a run's q: at most ``q_pose`` broken at a
    node (an observation between two odometry stamps counts at both, ``a`` and ``b``) and
    ``max(q_landmark, ⌊q_frac·m⌋)`` of a landmark's ``m``, the truth's outliers (``out_*``)
    counted in both. ``active``: the inlier observations the witness still meets."""

    def __init__(self, q, a, b, lid, out_a, out_b, out_lid, m):
        self.q_pose, q_lm, q_frac = q
        self.a, self.b, self.lid = np.asarray(a), np.asarray(b), np.asarray(lid)
        self.node = Counter(np.asarray(out_a).tolist()) + Counter(np.asarray(out_b)[out_b != out_a].tolist())
        self.lm = Counter(np.asarray(out_lid).tolist())
        self.cap = {i: max(q_lm, int(q_frac * m[i])) for i in set(self.lid.tolist())}
        self.active = np.ones(self.lid.size, bool)

    def take(self, j: int) -> bool:
        """Break observation ``j`` if the caps allow it (and it is not broken yet)."""
        a, b, i = int(self.a[j]), int(self.b[j]), int(self.lid[j])
        if not (self.active[j] and self.node[a] < self.q_pose and self.node[b] < self.q_pose and self.lm[i] < self.cap[i]):
            return False
        self.active[j] = False
        self.node[a] += 1
        self.node[b] += b != a
        self.lm[i] += 1
        return True

    def pick(self, score) -> bool:
        """Break the observation of largest ``score`` (> 0) that the caps allow; False if none."""
        score = np.where(self.active, score, 0.0)
        for j in np.argsort(-score, kind="stable"):
            if not score[j] > 1e-9:
                return False
            if self.take(j):
                return True
        return False


def _quiet_highs():
    """A HiGHS instance (highspy, dev dependency) that prints nothing: its constructor writes
    a banner to the process's stdout, which is muted while it runs."""
    import os

    import highspy

    sys_stdout = os.dup(1)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 1)
            h = highspy.Highs()
    finally:
        os.dup2(sys_stdout, 1)
        os.close(sys_stdout)
    h.setOptionValue("output_flag", False)
    return h


def linprog(cost, A_ub=None, b_ub=None, A_eq=None, b_eq=None, bounds=None, duals=False):
    """min cost·x subject to A_ub x ≤ b_ub, A_eq x = b_eq, bounds[:, 0] ≤ x ≤ bounds[:, 1] (dense
    matrices), by HiGHS (:func:`sparse_linprog`): (solved, x, objective), and with ``duals`` the
    rows' dual values (A_ub's, then A_eq's)."""
    rows, lo_r, hi_r = [], [], []
    if A_ub is not None:
        rows.append(np.asarray(A_ub, float))
        lo_r.append(np.full(rows[-1].shape[0], -np.inf))
        hi_r.append(np.asarray(b_ub, float))
    if A_eq is not None:
        rows.append(np.asarray(A_eq, float))
        lo_r.append(np.asarray(b_eq, float))
        hi_r.append(np.asarray(b_eq, float))
    M = np.vstack(rows) if rows else np.zeros((0, cost.size))
    r, c = np.nonzero(M)
    return sparse_linprog(cost, r, c, M[r, c], np.concatenate(lo_r) if rows else np.zeros(0),
                          np.concatenate(hi_r) if rows else np.zeros(0), bounds[:, 0], bounds[:, 1], duals)


def sparse_linprog(cost, r, c, v, row_lo, row_hi, col_lo, col_hi, duals=False):
    """min cost·x subject to row_lo ≤ A x ≤ row_hi (A given as triplets, duplicates summed) and
    col_lo ≤ x ≤ col_hi, by HiGHS (highspy rather than SciPy: with SciPy installed numba imports
    scipy.linalg in every process that calls a kernel): (solved, x, objective), and with
    ``duals`` the rows' dual values after them. Infinite bounds are HiGHS's infinity."""
    import highspy

    n, m = cost.size, row_lo.size
    order = np.lexsort((c, r))
    r, c, v = r[order], c[order], v[order]
    if r.size:
        key = r * n + c
        first = np.concatenate([[True], key[1:] != key[:-1]])
        v = np.add.reduceat(v, np.flatnonzero(first))
        r, c = r[first], c[first]
    inf = highspy.kHighsInf
    lp = highspy.HighsLp()
    lp.num_col_, lp.num_row_ = n, m
    lp.col_cost_ = np.asarray(cost, float)
    lp.col_lower_ = np.where(np.isfinite(col_lo), col_lo, -inf)
    lp.col_upper_ = np.where(np.isfinite(col_hi), col_hi, inf)
    lp.row_lower_ = np.where(np.isfinite(row_lo), row_lo, -inf)
    lp.row_upper_ = np.where(np.isfinite(row_hi), row_hi, inf)
    lp.a_matrix_.format_ = highspy.MatrixFormat.kRowwise
    lp.a_matrix_.num_col_, lp.a_matrix_.num_row_ = n, m
    lp.a_matrix_.start_ = np.searchsorted(r, np.arange(m + 1))
    lp.a_matrix_.index_ = c
    lp.a_matrix_.value_ = v
    h = _quiet_highs()
    h.passModel(lp)
    h.run()
    ok = h.getModelStatus() == highspy.HighsModelStatus.kOptimal
    sol = h.getSolution()
    out = ok, np.array(sol.col_value), float(h.getInfo().objective_function_value)
    return (*out, np.array(sol.row_dual)) if duals else out
