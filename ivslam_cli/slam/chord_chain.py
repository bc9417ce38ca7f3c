"""The robot's pose between two times from pose-increment odometry under a stated top angular
acceleration ``α`` (``|θ''| ≤ α``) and top acceleration ``A`` (``|p''| ≤ A``): the chain of
the steps' chords.

Within a step ``[t_j, t_j + h_j]`` a path with ``|θ''| ≤ α`` strays from its chord by at most
``α (t − t_j)(t_j + h_j − t) / 2 ≤ α h_j² / 8``, and its rate from the chord's slope by at most
``α h_j``. So for any ``s`` and ``t``,

    θ(t) − θ(s) = Σ_j λ_j(t) D_j + c(t) − c(s),   D_j ∈ Δ_j ± ε_j,

``λ_j(t) = f_j(t) − f_j(s)`` the share of step ``j`` between ``s`` and ``t`` (``f_j(t)`` the
clipped fraction of step ``j`` before ``t``) and ``|c(t)| ≤ α (t − t_j)(t_j + h_j − t) / 2``:
the nominal ``N(t) = Σ λ_j Δ_j`` is within ``Σ |λ_j| ε_j + |c(t)| + |c(s)|`` of the truth (the
chord term taken at the window's point nearest each step's middle). Positions chain
the same way with the increments ``R(θ(t_j) − θ(s)) B_j`` in the frame at ``s`` (``B_j ± ε``
per axis; the heading's error at ``t_j`` turns ``B_j`` by at most that angle). Against a rate
``ω̂`` (velocity ``V``) the deviation is piecewise linear plus piecewise ``|linear|`` in ``t``:
its largest value over a window is at the window's ends, the nodes inside it, or ``s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class Chain:
    """The chain from ``s`` over the steps ``J`` that ``[min(lo, s), max(hi, s)]`` meets."""

    u: np.ndarray  # (U,) breakpoint times minus s: the window's ends, the nodes inside, s
    lam: np.ndarray  # (U, J) the share of each step between s and each breakpoint
    lam_node: np.ndarray  # (J, J) the same at each step's start
    D: np.ndarray  # (J,) nominal heading increments
    eps: np.ndarray  # (J,) their half-widths
    B: np.ndarray  # (J, 2) nominal translations in each step's first frame
    et: np.ndarray  # (J,) their half-width per axis
    h: np.ndarray  # (J,) step durations
    win: np.ndarray  # (J,) the step meets the window
    g: float  # max over the window of (t − t_j)(t_j + h_j − t) / 2, t in step j (the chord factor)
    alpha: float
    accel: float
    cs_th: float  # the heading's chord error at s
    cs_p: float  # the position's chord error at s

    def turn(self, slack: float, ulp: float) -> tuple[float, float, float]:
        """``(ω̂, e, ρ)``: ``|θ(t + δ) − θ(s) − ω̂ (t − s)| ≤ e`` for ``t + δ`` in the window and
        ``|δ| ≤ slack``; ``|θ'(t) − ω̂| ≤ ρ`` in the window. ``ω̂`` is the candidate rate (each
        step's in the window, the window's chord) with the least ``e``."""
        hw = self.h[self.win]
        rate = self.D[self.win] / hw
        cands = list(rate)
        if self.u[-1] > self.u[0]:
            N = self.lam @ self.D
            cands.append((N[-1] - N[0]) / (self.u[-1] - self.u[0]))
        w, e = min(((float(c), self.turn_at(float(c), slack, ulp)) for c in cands), key=lambda x: x[1])
        rho = float(np.max(np.abs(rate - w) + self.eps[self.win] / hw + self.alpha * hw))
        return w, e, _up(rho)

    def turn_at(self, w: float, slack: float, ulp: float) -> float:
        """``e`` of :meth:`turn` for the given rate ``w``."""
        N = self.lam @ self.D
        err = np.abs(self.lam) @ self.eps
        hw = self.h[self.win]
        top = float(np.max(np.abs(self.D[self.win] / hw) + self.eps[self.win] / hw + self.alpha * hw))
        e = float(np.max(np.abs(N - w * self.u) + err)) + self.alpha * self.g + self.cs_th + abs(w) * slack
        return _up(e + 2.0 * top * ulp)

    def _moves(self):
        """``(P, err, top)``: the nominal positions at the breakpoints in the frame at ``s``,
        their errors, and the fastest a step in the window may move."""
        phi = self.lam_node @ self.D
        ephi = np.abs(self.lam_node) @ self.eps + self.cs_th
        c, sn = np.cos(phi), np.sin(phi)
        Q = np.column_stack([c * self.B[:, 0] - sn * self.B[:, 1], sn * self.B[:, 0] + c * self.B[:, 1]])
        qerr = math.sqrt(2.0) * self.et + np.hypot(self.B[:, 0], self.B[:, 1]) * ephi
        hw = self.h[self.win]
        vel = Q[self.win] / hw[:, None]
        top = float(np.max(np.hypot(vel[:, 0], vel[:, 1]) + (math.sqrt(2.0) * self.et[self.win]) / hw
                           + self.accel * hw))
        return self.lam @ Q, np.abs(self.lam) @ qerr, top, vel

    def move_at(self, v, slack: float, ulp: float, moves=None) -> float:
        """``E`` of :meth:`move` for the given velocity ``v`` (in the frame at ``s``)."""
        P, err, top, _ = self._moves() if moves is None else moves
        d = np.hypot(P[:, 0] - v[0] * self.u, P[:, 1] - v[1] * self.u)
        e = float(np.max(d + err)) + self.accel * self.g + self.cs_p + math.hypot(*v) * slack
        return _up(e + 2.0 * top * ulp)

    def move(self, slack: float, ulp: float) -> tuple[tuple[float, float], float]:
        """``(V, E)``: ``|p(t + δ) − p(s) − R(θ(s)) V (t − s)| ≤ E`` for ``t + δ`` in the window
        and ``|δ| ≤ slack``, ``V`` the candidate velocity in the frame at ``s`` (each step's in
        the window, the window's chord) with the least ``E``."""
        moves = self._moves()
        P, vel = moves[0], moves[3]
        cands = [tuple(float(x) for x in v) for v in vel]
        if self.u[-1] > self.u[0]:
            cands.append(tuple(float(x) for x in (P[-1] - P[0]) / (self.u[-1] - self.u[0])))
        return min(((v, self.move_at(v, slack, ulp, moves)) for v in cands), key=lambda x: x[1])


def _up(x: float) -> float:
    """``x`` rounded up past the float error of the sums that made it."""
    return float(np.nextafter(x * (1.0 + 1e-12) + 1e-12, np.inf))


def chain(ns: np.ndarray, dth: np.ndarray, step_xy: np.ndarray | None, alpha: float, accel: float,
          s: float, lo: float, hi: float) -> Chain | None:
    """The :class:`Chain` from ``s`` over ``[lo, hi]`` with node stamps ``ns``, heading
    increments ``dth`` (N-1, 2) and translations ``step_xy`` (N-1, 3: Δx, Δy, ± per axis);
    ``None`` outside the odometry's span or over a step of no duration."""
    a, b = min(lo, s), max(hi, s)
    n1 = ns.shape[0] - 1
    if n1 < 1 or not (ns[0] <= a and b <= ns[-1]) or not lo <= hi:
        return None
    ka = int(np.clip(np.searchsorted(ns, a, side="right") - 1, 0, n1 - 1))
    kb = int(np.clip(np.searchsorted(ns, b, side="left") - 1, ka, n1 - 1))
    J = np.arange(ka, kb + 1)
    t_j = ns[J]
    h = ns[J + 1] - t_j
    if not np.all(h > 0.0):
        return None

    def frac(t):
        return np.clip((np.asarray(t, float)[..., None] - t_j) / h, 0.0, 1.0)

    inside = ns[(ns > lo) & (ns < hi)]
    u_abs = np.unique(np.concatenate([[lo, hi], inside, [s] if lo < s < hi else []]))
    fs = frac(s)
    lam = frac(u_abs) - fs
    lam_node = frac(t_j) - fs
    win = (ns[J + 1] >= lo) & (t_j <= hi)
    # (t − t_j)(t_j + h − t) / 2 peaks at the step's middle: the window's point nearest it
    mid = np.clip(t_j + 0.5 * h, np.maximum(lo, t_j), np.minimum(hi, t_j + h))
    gj = (mid - t_j) * (t_j + h - mid) / 2.0
    g = float(np.max(np.where(win, np.maximum(gj, 0.0), 0.0))) * (1.0 + 1e-12) if win.any() else float(np.max(h * h)) / 8.0
    ks = int(np.clip(np.searchsorted(ns, s, side="right") - 1, 0, n1 - 1))
    gs = (s - ns[ks]) * (ns[ks + 1] - s) / 2.0
    if not gs >= 0.0:
        gs = 0.0
    D = 0.5 * (dth[J, 0] + dth[J, 1])
    eps = np.nextafter(0.5 * (dth[J, 1] - dth[J, 0]), np.inf)
    if step_xy is None:
        B, et = np.zeros((J.size, 2)), np.zeros(J.size)
    else:
        B, et = step_xy[J, :2], step_xy[J, 2]
    return Chain(u=u_abs - s, lam=lam, lam_node=lam_node, D=D, eps=eps, B=B, et=et, h=h, win=win, g=g,
                 alpha=alpha, accel=accel, cs_th=alpha * gs, cs_p=(accel * gs if np.isfinite(accel) else np.inf))
