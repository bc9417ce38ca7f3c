"""Loop closure over the submaps: interval loop constraints and the anchor graph as a CSP.

**Nodes** are the submaps' anchors: the robot pose of each anchor scan, ``G_i`` its box in the
result's frame. **Edges** are relative enclosures ``E_ab`` of anchor ``b`` in anchor ``a``'s frame:

- *chain / overlap*: a scan ``j`` tracked in two submaps ``a`` and ``b`` (the anchor of ``b`` is a
  scan of ``a``; the overlap scans are members of both) gives ``E_ab ∋ R_a(j) ⊕ R_b(j)⁻¹``;
- *loop*: a scan ``j`` matched against an older submap ``i`` it is not tracked in: the matcher's
  set inversion (:class:`~.matcher.Matcher`, rule A against the old submap's proven-free cells
  and its anchor scan's free cones, rule B against the anchor scan's beam ends, q-relaxed)
  over the prior ``L⁰ = (G_i⁻¹ ⊕ G_j) ∩ (E_{i,i+1} ⊕ … ⊕ E_{h−1,h} ⊕ R_h(j))`` (what the two
  global boxes allow, met with the chain of anchors up to the scan's home submap ``h``) gives
  ``L ∋`` the scan's pose in anchor ``i``'s frame, and ``E_ih ∋ L ⊕ R_h(j)⁻¹`` for every submap
  ``h`` tracking ``j``. An empty ``L`` (no pose of the prior agrees with the old submap) is a
  contradiction of the data with the model: it is recorded and nothing is contracted.

Every edge derived twice is met (both hold the same relative pose). :func:`contract_graph`
contracts the node boxes to a fixpoint by forward-backward passes over the edges
(``G_b ∩= G_a ⊕ E_ab``, ``G_a ∩= G_b ⊕ E_ab⁻¹``; :mod:`ivslam_cli.interval.pose`, outward
rounded); an empty meet (impossible when every enclosure holds the truth) is counted and the
node kept unchanged.

Guarantee: if every relative box holds its true relative pose and every global box its true
pose (the tracker's guarantee), every edge holds the true relative pose of its anchors, and the
contracted ``G_i`` hold the true anchor poses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ivslam_cli.interval.pose import compose, invert, meet, relative
from ivslam_cli.paving.tiles import EMPTY, TILE

SLICES = 16
KIND_CHAIN = 0
KIND_LOOP = 1


@njit(cache=True)
def _wsum(b):
    return (b[0, 1] - b[0, 0]) + (b[1, 1] - b[1, 0]) + (b[2, 1] - b[2, 0])


@njit(cache=True)
def contract_graph(G, ea, eb, E, max_sweeps, tol, slices):
    """Contract the node boxes ``G`` (n, 3, 2), in place, with the edges ``E[e]`` ∋ anchor
    ``eb[e]`` in the frame of anchor ``ea[e]``: forward (edges in order) then backward (reverse
    order) passes, each edge both ways, until a sweep narrows the summed widths by less than
    ``tol`` (relative) or after ``max_sweeps``. Returns ``(sweeps, empty meets)``."""
    ne = ea.shape[0]
    Einv = np.empty_like(E)
    for e in range(ne):
        invert(E[e], slices, Einv[e])
    tmp = np.empty((3, 2))
    met = np.empty((3, 2))
    bad = 0
    sweeps = 0
    for it in range(max_sweeps):
        sweeps += 1
        before = 0.0
        for i in range(G.shape[0]):
            before += _wsum(G[i])
        for p in range(2 * ne):
            e = p if p < ne else 2 * ne - 1 - p
            a = ea[e]
            b = eb[e]
            compose(G[a], E[e], slices, tmp)
            if meet(G[b], tmp, met):
                G[b] = met
            else:
                bad += 1
            compose(G[b], Einv[e], slices, tmp)
            if meet(G[a], tmp, met):
                G[a] = met
            else:
                bad += 1
        after = 0.0
        for i in range(G.shape[0]):
            after += _wsum(G[i])
        if not (before - after > tol * before):
            break
    return sweeps, bad


@njit(cache=True)
def chain_prior(E, i, h, r, slices, max_heading, out):
    """``out`` ⊇ ``E[i] ⊕ E[i+1] ⊕ … ⊕ E[h−1] ⊕ r``: a pose given in anchor ``h``'s frame, in
    anchor ``i``'s (``E[k]``: anchor ``k + 1`` in anchor ``k``'s frame). Returns False (out
    unbounded) as soon as the heading is wider than ``max_heading``."""
    acc = np.zeros((3, 2))
    tmp = np.empty((3, 2))
    for d in range(3):
        acc[d, 0] = 0.0
        acc[d, 1] = 0.0
    for k in range(i, h):
        compose(acc, E[k], slices, tmp)
        acc[:, :] = tmp
        if not (acc[2, 1] - acc[2, 0] <= max_heading):
            return False
    compose(acc, r, slices, out)
    return out[2, 1] - out[2, 0] <= max_heading


@njit(cache=True)
def loop_priors(G, gb, E, h, r, slices, max_heading, out, ok):
    """``out[i]`` (3, 2): a scan's pose in old anchor ``i``'s frame (``i < out.shape[0]``) as
    the two global boxes ``G[i]`` and ``gb`` allow, met with the chain from ``i`` to the scan's
    home ``h`` composed with its relative box ``r`` (where the chain's heading stays within
    ``max_heading``); ``ok[i]`` False where they miss (a contradiction: no search)."""
    pg = np.empty((3, 2))
    pc = np.empty((3, 2))
    # the chain's heading width from i on is the sum of its edges' (rounded outward, so no
    # less): where that sum is over max_heading, chain_prior returns False, not composed here
    tail = np.empty(out.shape[0] + 1)
    tail[out.shape[0]] = r[2, 1] - r[2, 0]
    for k in range(min(h, E.shape[0]) - 1, out.shape[0] - 1, -1):
        tail[out.shape[0]] += E[k, 2, 1] - E[k, 2, 0]
    for i in range(out.shape[0] - 1, -1, -1):
        tail[i] = tail[i + 1] + (E[i, 2, 1] - E[i, 2, 0] if i < h else 0.0)
    for i in range(out.shape[0]):
        relative(G[i], gb, slices, pg)
        ok[i] = True
        if h > i and not tail[i] > max_heading * (1.0 + 1e-9) + 1e-12 and chain_prior(E, i, h, r, slices,
                                                                                       max_heading, pc):
            if not meet(pg, pc, out[i]):
                ok[i] = False
        else:
            out[i] = pg


def free_extent(tmap) -> np.ndarray | None:
    """``(x0, x1, y0, y1)`` in the submap's frame of its proven-free cells (None: none)."""
    n = tmap.n
    if n == 0:
        return None
    f = (tmap.cells[:n] & EMPTY) != 0
    t, a, b = np.nonzero(f)
    if t.size == 0:
        return None
    ix = tmap.coords[t, 0].astype(np.int64) * TILE + a
    iy = tmap.coords[t, 1].astype(np.int64) * TILE + b
    e = tmap.eps
    return np.array([ix.min() * e, (ix.max() + 1) * e, iy.min() * e, (iy.max() + 1) * e])


@dataclass
class LoopConstraint:
    """One scan matched against an older submap (rows are used-scan rows)."""

    row: int
    submap: int  # the old submap
    home: int  # the scan's home submap when matched
    prior: np.ndarray  # (6,) the search region: the scan's pose in the old anchor's frame
    box: np.ndarray  # (6,) the kept poses' hull met with the prior (NaN rows when empty)
    beams: int  # beams of the scan tested (valid, every match_stride-th)
    tested: int  # pose sub-boxes tested
    empty: bool  # no pose of the prior agreed with the old submap


@dataclass
class AnchorGraph:
    """The anchor graph: edges met per (a, b) pair, loop constraints, contraction counters."""

    edges: dict = field(default_factory=dict)  # (a, b) -> [(6,) box, kind]
    loops: list = field(default_factory=list)  # [LoopConstraint]
    sweeps: int = 0
    empty_meets: int = 0
    contractions: int = 0
    paved: int = 0  # wide priors paved (loopsearch)
    pave_tests: int = 0
    pave_incomplete: int = 0
    pave_skipped: int = 0  # wide priors not paved: at least as wide as one that ran out against that submap
    # per old submap, the narrowest (x-y width, heading) of a prior whose paving ran out
    pave_failed: dict = field(default_factory=dict)

    def pave_hopeless(self, s: int, width: float, heading: float) -> bool:
        """True if a prior against submap ``s`` is at least as wide, in x-y and heading, as one
        whose paving ran out of budget (its paving would derive nothing either, as a rule)."""
        f = self.pave_failed.get(s)
        return f is not None and width >= f[0] and heading >= f[1]

    def pave_ran_out(self, s: int, width: float, heading: float) -> None:
        """Record that the paving of a prior against submap ``s`` ran out."""
        f = self.pave_failed.get(s)
        if f is None or (width <= f[0] and heading <= f[1]):
            self.pave_failed[s] = (width, heading)

    def add_edge(self, a: int, b: int, box: np.ndarray, kind: int) -> None:
        """Meet ``box`` (anchor ``b`` in ``a``'s frame) into the edge (a, b)."""
        if a == b or not np.all(np.isfinite(box)):
            return
        if a > b:
            inv = np.empty((3, 2))
            invert(np.ascontiguousarray(box, float).reshape(3, 2), SLICES, inv)
            a, b, box = b, a, inv.reshape(6)
        cur = self.edges.get((a, b))
        if cur is None:
            self.edges[(a, b)] = [np.asarray(box, float).reshape(6).copy(), kind]
            return
        out = np.empty((3, 2))
        if meet(cur[0].reshape(3, 2), np.asarray(box, float).reshape(3, 2), out):
            cur[0] = out.reshape(6)
        else:
            self.empty_meets += 1
        cur[1] = max(cur[1], kind)

    def add_member_pair(self, a: int, ra: np.ndarray, b: int, rb: np.ndarray, kind: int = KIND_CHAIN) -> None:
        """A pose ``ra`` in anchor ``a``'s frame and ``rb`` in ``b``'s: ``E_ab ∋ ra ⊕ rb⁻¹``."""
        inv = np.empty((3, 2))
        out = np.empty((3, 2))
        invert(np.ascontiguousarray(rb, float).reshape(3, 2), SLICES, inv)
        compose(np.ascontiguousarray(ra, float).reshape(3, 2), inv, SLICES, out)
        self.add_edge(a, b, out.reshape(6), kind)

    def arrays(self, n: int):
        keys = [k for k in self.edges if k[1] < n]
        ea = np.array([k[0] for k in keys], np.int64)
        eb = np.array([k[1] for k in keys], np.int64)
        E = np.array([self.edges[k][0] for k in keys], float).reshape(-1, 3, 2)
        kind = np.array([self.edges[k][1] for k in keys], np.int64)
        return ea, eb, E, kind

    def chain(self, n: int) -> np.ndarray:
        """(n − 1, 3, 2): ``E_{k,k+1}`` (unbounded where missing)."""
        C = np.empty((max(n - 1, 0), 3, 2))
        C[:, :, 0], C[:, :, 1] = -np.inf, np.inf
        for k in range(n - 1):
            e = self.edges.get((k, k + 1))
            if e is not None:
                C[k] = e[0].reshape(3, 2)
        return C

    def contract(self, G: np.ndarray, max_sweeps: int = 50, tol: float = 1e-6) -> None:
        """Contract the node boxes ``G`` (n, 6), in place."""
        n = G.shape[0]
        ea, eb, E, _ = self.arrays(n)
        if ea.size == 0:
            return
        G3 = np.ascontiguousarray(G.reshape(n, 3, 2))
        sweeps, bad = contract_graph(G3, ea, eb, np.ascontiguousarray(E), int(max_sweeps), float(tol), SLICES)
        G[:] = G3.reshape(n, 6)
        self.sweeps += int(sweeps)
        self.empty_meets += int(bad)
        self.contractions += 1


def width(b: np.ndarray) -> float:
    return max(b[1] - b[0], b[3] - b[2])


def near_free(prior: np.ndarray, ext: np.ndarray | None, margin: float) -> bool:
    """The prior's positions within ``margin`` of the free extent ``ext`` of a submap."""
    if ext is None:
        return False
    return (prior[0] <= ext[1] + margin and ext[0] - margin <= prior[1] and prior[2] <= ext[3] + margin
            and ext[2] - margin <= prior[3])


def heading(b: np.ndarray) -> float:
    return b[5] - b[4]


def loops_record(graph: AnchorGraph, anchor_open: np.ndarray, n: int):
    """The result's :class:`~ivslam_cli.results.model.Loops` from the graph."""
    from ivslam_cli.results.model import Loops

    lc = graph.loops
    ea, eb, E, kind = graph.arrays(n)
    return Loops(
        row=np.array([x.row for x in lc], np.int64), submap=np.array([x.submap for x in lc], np.int64),
        home=np.array([x.home for x in lc], np.int64),
        prior=np.array([x.prior for x in lc], float).reshape(-1, 3, 2),
        box=np.array([x.box for x in lc], float).reshape(-1, 3, 2),
        beams=np.array([x.beams for x in lc], np.int64), empty=np.array([x.empty for x in lc], bool),
        edge_a=ea, edge_b=eb, edge_box=np.asarray(E, float).reshape(-1, 3, 2), edge_kind=kind,
        anchor_box_open=np.asarray(anchor_open, float).reshape(-1, 3, 2), sweeps=int(graph.sweeps))


__all__ = ["AnchorGraph", "LoopConstraint", "contract_graph", "chain_prior", "free_extent",
           "loop_priors", "near_free", "width", "heading", "loops_record", "KIND_CHAIN", "KIND_LOOP", "math"]
