"""LiDAR tracking and mapping in local frames: submaps anchored at keyframe scans.

Worst-case bounds add up along a path, so a pose box in one global frame grows without end
while the robot explores, and a map built from wide boxes proves little. Here every scan's
pose is tracked *relative to the robot pose of an anchor scan* (its submap's frame, where the
anchor pose is exact), the way Cartographer keeps submaps (Hess et al. 2016) and interval
LiDAR localisation keeps scans relative to keyframes:

1. **dead reckoning in the anchor frame**: the motion steps of :mod:`ivslam_cli.slam.motion`
   from the anchor's node (exact, up to the scan's reach of its node);
2. **contraction** of that relative box against the anchor scan (interval scan matching,
   both scans' continuous free space: :mod:`.scanmatch`) and against the submap's map built
   so far (a set inversion in pose space: :mod:`.contract`), q-relaxed over the beams;
3. **mapping** of the scan into its submap with its relative box (:mod:`.map_update`):
   P_EMPTY (inner) and P_OBSTACLE (outer) proven *in the anchor's frame*; with the match's
   pose set, also the cells every box of it proves free (:mod:`.map_union`).

A new submap starts at the current scan when the robot is ``submap_distance`` away from the
anchor, has turned ``submap_turn``, or the relative box is wider than ``submap_width``.
Consecutive submaps overlap: the previous submap keeps tracking and mapping the scans of the
next ``submap_overlap`` metres, so every place seen is mapped from tight relative boxes.

**The global tube.** The anchor of submap ``j + 1`` is a scan of submap ``j``: its global box is
``G_{j+1} = G_j ⊕ R`` (``R``: its relative box in submap ``j``, composed with outward rounding,
:mod:`ivslam_cli.interval.pose`), met with the global dead-reckoned box. A scan's global box is
its anchors' boxes ⊕ its relative boxes, met with the global dead reckoning, which each global
box then contracts (forward), and a backward pass over the motion steps smooths.

Guarantee: if the initial pose is in its box, the odometry within its bounds, every valid
return within the range and bearing bounds (the static world but for at most ``q_beams`` beams
per scan), then every relative box holds the true pose of its scan in its anchor's frame, every
global box the true pose, and each submap's P_EMPTY is free in its anchor's frame.
"""

from __future__ import annotations

import math
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np

from ivslam_cli.interval.pose import compose, meet
from ivslam_cli.slam.lidar import loops as L
from ivslam_cli.logs.model import LogData, Scans
from ivslam_cli.paving.tiles import TileMap
from ivslam_cli.slam.lidar.loopsearch import PAVE_BUDGET, PAVE_LEAF, PAVE_LEAVES, PAVE_STRIDE, pave
from ivslam_cli.slam.lidar.map_update import check_extent, extent_limits, map_union_free, update_map
from ivslam_cli.slam.lidar.matcher import Matcher, hull
from ivslam_cli.slam.lidar.params import Params
from ivslam_cli.slam.lidar.prediction import PosePrediction, trajectory
from ivslam_cli.slam.motion_kernel import (
    meet_node,
    propagate,
    propagate_boxes,
    smooth_backward,
    smooth_backward_range,
    widen_boxes,
)


@dataclass
class Submap:
    """One local frame: the robot pose of its anchor scan, and what is proven in it."""

    index: int
    anchor_row: int  # row of the anchor among the used scans
    anchor_scan: int  # scan index of the anchor
    k0: int  # trajectory node of the anchor
    G: np.ndarray  # (6,) global box of the anchor's robot pose
    tmap: TileMap  # the map in the anchor's frame
    P: np.ndarray  # (N - k0, 3, 2) node boxes relative to the anchor (row 0 = node k0)
    events: np.ndarray  # (N - k0 - 1,) motion steps with no solution in this frame
    k_prev: int  # last node propagated (absolute)
    rows: list = field(default_factory=list)  # member rows (used-scan rows tracked here)
    rel: list = field(default_factory=list)  # their relative boxes (6,), in step with ``rows``
    mapped: list = field(default_factory=list)  # rows mapped into this submap
    closes_at: float = math.inf  # travel at which the submap stops tracking (overlap end)
    last_row: int = -1  # last row mapped, not q-relaxed (the "previous scan" of the rules)
    last_box: np.ndarray | None = None  # its relative box
    union: np.ndarray | None = None  # (m, 6) the last tracked scan's pose set (one box per heading slice)
    union_row: int = -1  # ... of which row
    extent: np.ndarray | None = None  # (4,) its proven-free cells' extent once closed (loop candidates)
    closed: bool = False  # no longer tracking
    pending: object = None  # the anchor's map update, running (a future), until the next scan tracks here


@dataclass
class SubmapTracking:
    """What the submap pass produced, per used scan row and per submap."""

    pred: PosePrediction  # global boxes (after forward-backward) and the trajectory's stamps
    submaps: list  # [Submap]
    home: np.ndarray  # (S',) index of the submap that holds each scan's relative box (the newest)
    relative: np.ndarray  # (S', 6) relative box in its home submap
    mapped: np.ndarray  # (S',) bool: mapped into at least one submap
    contracted: np.ndarray  # (S',) bool: some contraction narrowed the box
    contradicted: list  # (row, submap, kind) of matches where no pose agreed with the data (box kept)
    compose_empty: list  # (row, submap, what) where the anchor box ⊕ its relative (or loop) box missed the global box
    relocalised: list  # (row, submap) where the motion step broke its bounds and the scan was relocalised
    q_relaxed: list  # (row, submap) contracted with lidar.q_retry beams allowed (none agreed with q_beams)
    forward: np.ndarray  # (S', 6) global boxes before the backward pass
    predicted: np.ndarray  # (S', 6) global dead-reckoned boxes before any contraction reached them
    tested: int  # pose sub-boxes tested in all
    smoothed: int  # global trajectory nodes the backward pass narrowed
    stats: np.ndarray  # (S, 6) map update stats per scan (its home submap's update)
    is_old: np.ndarray  # (B,) per beam: old in its home submap
    graph: L.AnchorGraph | None = None  # the anchor graph (edges, loop constraints)
    open_loop: np.ndarray | None = None  # (S', 6) global boxes from the chain of anchors only (no loop edges)
    anchor_before: np.ndarray | None = None  # (n_submaps, 6) anchor boxes from the chain only
    set_cells: int = 0  # cells first proven free by a scan's pose set beyond its hull, over the submaps


def _met_rows(boxes: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The boxes (n, 6) met with ``r`` (6,), the empty meets left out: (n', 6)."""
    lo = np.maximum(boxes[:, 0::2], r[0::2])
    hi = np.minimum(boxes[:, 1::2], r[1::2])
    good = np.all(lo <= hi, axis=1)
    out = np.empty((int(good.sum()), 6))
    out[:, 0::2], out[:, 1::2] = lo[good], hi[good]
    return out


def _width(b: np.ndarray) -> float:
    return max(b[1] - b[0], b[3] - b[2])


def _centre(b: np.ndarray) -> tuple[float, float, float]:
    return 0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]), 0.5 * (b[4] + b[5])


def _new_submap(index: int, row: int, scan: int, k: int, G: np.ndarray, n_nodes: int, reach, eps: float) -> Submap:
    P = np.empty((n_nodes - k, 3, 2))
    P[:, :, 0] = -np.inf
    P[:, :, 1] = np.inf
    rp, rt = float(reach[0]), float(reach[1])  # node k holds the modelled pose, within reach of the scan's
    P[0] = [[-rp, rp], [-rp, rp], [-rt, rt]]
    return Submap(index, row, scan, k, G.copy(), TileMap(eps), P, np.zeros(max(n_nodes - k - 1, 0), np.int64), k)


def _reset_node(P, k: int, box: np.ndarray, rp: float, rt: float) -> None:
    """``P[k]`` = the robot box (6,) of an event at node ``k`` widened by its reach."""
    P[k, 0] = box[0] - rp, box[1] + rp
    P[k, 1] = box[2] - rp, box[3] + rp
    P[k, 2] = box[4] - rt, box[5] + rt
    P[k, :, 0] = np.nextafter(P[k, :, 0], -np.inf)
    P[k, :, 1] = np.nextafter(P[k, :, 1], np.inf)


def _relative_box(s: Submap, m, j: int, k: int) -> np.ndarray:
    """Propagate submap ``s``'s trajectory to node ``k`` and return scan row ``j``'s box in its frame."""
    propagate(s.P, m.kind[s.k0:], m.U[s.k0:], s.events, s.k_prev - s.k0, k - s.k0)
    s.k_prev = k
    out = np.empty((1, 6))
    widen_boxes(s.P, np.array([k - s.k0]), m.reach[j:j + 1], out)
    return out[0]


def _anchor_boxes(submaps) -> np.ndarray:
    return np.array([s.G for s in submaps], float).reshape(-1, 6)


def _set_anchor_boxes(submaps, G: np.ndarray) -> None:
    for s, g in zip(submaps, G):
        s.G = g.copy()


def _meet_loops(constraints, submaps, gb: np.ndarray, compose_empty: list) -> np.ndarray:
    """``gb`` (a scan's global box) met with ``G_i ⊕ L`` for each of its non-empty loop
    constraints ``L`` (its pose in old anchor ``i``'s frame); a miss is recorded, not met."""
    g = np.empty((3, 2))
    met = np.empty((3, 2))
    for lc in constraints:
        if lc.empty or not np.all(np.isfinite(lc.box)):
            continue
        compose(submaps[lc.submap].G.reshape(3, 2), np.ascontiguousarray(lc.box, float).reshape(3, 2), 1, g)
        if meet(gb.reshape(3, 2), g, met):
            gb = met.reshape(6).copy()
        else:
            compose_empty.append((lc.row, lc.submap, "loop"))
    return gb


def _open_chain(graph: L.AnchorGraph, submaps, predicted: np.ndarray) -> np.ndarray:
    """The anchor boxes the chain alone gives (no loop edge): ``G_{i+1} = (G_i ⊕ E_{i,i+1}) ∩``
    the dead-reckoned box of its anchor scan (dead reckoning alone, ``predicted``)."""
    n = len(submaps)
    out = np.empty((n, 6))
    C = graph.chain(n)
    tmp = np.empty((3, 2))
    met = np.empty((3, 2))
    for i, s in enumerate(submaps):
        b = predicted[s.anchor_row].copy()
        if i == 0:
            b = s.G.copy() if not np.all(np.isfinite(b)) else b
        else:
            compose(out[i - 1].reshape(3, 2), C[i - 1], 1, tmp)
            if meet(b.reshape(3, 2), tmp, met):
                b = met.reshape(6).copy()
        out[i] = b
    return out


def _search_loops(j: int, scan: int, gb: np.ndarray, submaps, active, graph: L.AnchorGraph, track, params,
                  reach: float) -> bool:
    """Match scan row ``j`` (global box ``gb``) against the older submaps it may be in (in
    parallel on ``track``'s threads); add the loop edges found, in the order of the candidates.
    Returns True when an edge was added."""
    newest = active[-1]
    h = newest.index
    r_h = newest.rel[-1]
    chain = graph.chain(h + 1)
    wx, wt = params.loop_window
    act = {s.index for s in active}
    n_old = max(h - 1, 0)
    priors = np.empty((n_old, 3, 2))
    met = np.zeros(n_old, bool)
    L.loop_priors(_anchor_boxes(submaps[:n_old]).reshape(-1, 3, 2), np.ascontiguousarray(gb, float).reshape(3, 2),
                  chain, h, np.ascontiguousarray(r_h, float).reshape(3, 2), L.SLICES, max(wt, 1e-9) * 4, priors, met)
    cands = []
    for s in submaps[:n_old]:
        if s.index in act or s.extent is None or not met[s.index]:
            continue
        prior = priors[s.index].reshape(6).copy()
        narrow = L.width(prior) <= wx and L.heading(prior) <= wt
        if not (narrow or L.width(prior) <= params.loop_wide) or not L.near_free(prior, s.extent, 0.0):
            continue
        cands.append((-(h - s.index), L.width(prior) + reach * L.heading(prior), s, prior, narrow))
    cands.sort(key=lambda c: (c[0], c[1]))  # the longest chain first: where a loop tells the most
    added = False
    for (_, _, s, prior, narrow), (paved, pave_nt, roots, box, nb, nt) in zip(
            cands[: params.loop_candidates],
            track.map(lambda c: _loop_match(track.matcher(), scan, c[2], c[3], c[4], params, reach,
                                            track.q_for((scan, c[2].anchor_scan))),
                      cands[: params.loop_candidates])):
        if paved:
            graph.paved += 1
            graph.pave_tests += pave_nt
        if roots is None:
            graph.pave_incomplete += 1
            continue
        empty = box is None
        graph.loops.append(L.LoopConstraint(j, s.index, h, prior, np.full(6, np.nan) if empty else box, nb, nt,
                                            empty))
        if empty:
            continue
        for t in active:
            if t.rows and t.rows[-1] == j:
                graph.add_member_pair(s.index, box, t.index, t.rel[-1], L.KIND_LOOP)
        added = True
    return added


def _loop_match(matcher, scan: int, s: Submap, prior: np.ndarray, narrow: bool, params: Params, reach: float,
                q: int | None = None):
    """Scan ``scan`` matched against old submap ``s`` over ``prior`` (a wide prior paved first),
    ``q`` beams allowed (default ``q_beams``): ``(paved, paving_tests, roots, box, beams,
    tested)`` — ``roots`` None when the paving ran out of budget (no constraint), ``box`` None
    when no pose of the prior agrees (an empty constraint); ``tested`` counts the paving's tests
    too."""
    refs = [(s.anchor_scan, np.zeros(6))]
    roots = prior[None, :]
    nt = 0
    if not narrow:  # a wide prior: pave it on every n-th beam first, the kept leaves are the roots
        roots, nt = pave(matcher, scan, prior, s.tmap, refs, PAVE_STRIDE, PAVE_LEAF, PAVE_BUDGET, PAVE_LEAVES, q)
        if roots is None or roots.shape[0] == 0:
            return True, nt, roots, None, matcher.last_beams, nt
    pave_nt = nt
    union, ok, nt2 = matcher.match(scan, roots, s.tmap, refs, budget=params.loop_boxes, stride=params.loop_stride, q=q)
    nt += nt2
    nb = matcher.last_beams
    # the kept set is a sound prior for the same search: repeat while it shrinks
    for _ in range(3):
        if not ok:
            break
        w0 = L.width(hull(union)) + reach * L.heading(hull(union))
        u2, ok2, nt2 = matcher.match(scan, union, s.tmap, refs, budget=params.loop_boxes, stride=params.loop_stride,
                                     q=q)
        nt += nt2
        if not ok2:
            ok = False
            break
        w1 = L.width(hull(u2)) + reach * L.heading(hull(u2))
        union = u2
        if not w1 < 0.8 * w0:
            break
    if not ok:
        return not narrow, pave_nt, roots, None, nb, nt
    hl = hull(union)
    lo = np.maximum(hl[0::2], prior[0::2])
    hi = np.minimum(hl[1::2], prior[1::2])
    if not np.all(lo <= hi):
        return not narrow, pave_nt, roots, None, nb, nt
    return not narrow, pave_nt, roots, np.column_stack([lo, hi]).reshape(6), nb, nt


@dataclass
class _Tracked:
    """What tracking one scan in one submap found (the caller records it, in submap order)."""

    tested: int = 0
    q_relaxed: bool = False
    relocalised: bool = False
    contradicted: bool = False
    contracted: bool = False
    res: object = None  # the map update's result when the scan was mapped into the submap
    set_cells: int = 0  # cells its pose set proved free that the submap did not hold yet (lidar.map_sets)
    last: tuple = ()  # the submap's reference scan before this one became it (row, box)


class _Track:
    """The per-scan work in each active submap — dead reckoning in its frame, the match against
    it, the map update — which touches nothing but that submap: the submaps of a scan are
    tracked in parallel threads (the kernels release the GIL), with the same results as one
    after the other. Each thread keeps its own matcher and buffers."""

    def __init__(self, params: Params, scans: Scans, m, used: np.ndarray, extent, path, threads: int) -> None:
        self.p, self.scans, self.m, self.used, self.extent, self.path = params, scans, m, used, extent, path
        # scans matched with q_retry somewhere: up to q_retry of their beams may be wrong, so a
        # match that uses one as a reference allows as many
        self.relaxed = np.zeros(len(scans), bool)
        self.local = threading.local()
        self.pool = ThreadPoolExecutor(max_workers=threads) if threads > 1 else None

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown()

    def _buffers(self):
        b = getattr(self.local, "b", None)
        if b is None:
            b = self.local.b = (Matcher(self.p, self.scans), np.zeros((len(self.scans), 6)), np.zeros(1, np.int64))
        return b

    def matcher(self) -> Matcher:
        """This thread's matcher."""
        return self._buffers()[0]

    def map(self, f, items: list) -> list:
        """``[f(x) for x in items]``, in parallel when it can."""
        if self.pool is None or len(items) < 2:
            return [f(x) for x in items]
        return list(self.pool.map(f, items))

    def submit(self, f, *args):
        """``f(*args)`` on the pool (a future), or at once (None) without one."""
        if self.pool is None:
            f(*args)
            return None
        return self.pool.submit(f, *args)

    def map_anchor(self, s: Submap) -> None:
        """The anchor scan mapped into its own submap, at the frame's origin."""
        _, all_boxes, one = self._buffers()
        all_boxes[s.anchor_scan] = 0.0
        one[0] = s.anchor_scan
        update_map(s.tmap, self.scans, all_boxes, self.p.beams, order=one)

    @staticmethod
    def settle(s: Submap) -> None:
        """Wait for ``s``'s pending map update (its errors are raised here)."""
        if s.pending is not None:
            s.pending.result()
            s.pending = None

    def q_for(self, scans) -> int | None:
        """The q of a match among ``scans`` (indices): q_retry when one of them was q-relaxed,
        else the default (None)."""
        p = self.p
        if p.q_retry > p.q_beams and any(self.relaxed[i] for i in scans):
            return p.q_retry
        return None

    def one(self, s: Submap, j: int, k: int, scan: int, rp: float, rt: float) -> tuple[np.ndarray, _Tracked]:
        """Scan row ``j`` (node ``k``) in submap ``s``: its relative box and what was found."""
        params, m, used = self.p, self.m, self.used
        self.settle(s)
        matcher, all_boxes, one = self._buffers()
        out = _Tracked()
        if s.anchor_row == j:
            r = np.zeros(6)  # the frame is the anchor's pose
        else:
            r = _relative_box(s, m, j, k)
            if params.contract and np.all(np.isfinite(r)):
                roots = r[None, :]
                if s.union is not None and s.union_row >= 0:
                    jp = s.union_row
                    kp = int(m.node[jp])
                    prop = np.empty_like(s.union)
                    ok = propagate_boxes(s.P[kp - s.k0], s.union, m.reach[jp], m.kind[s.k0:], m.U[s.k0:],
                                         kp - s.k0, k - s.k0, m.reach[j], prop)
                    met = _met_rows(prop[ok], r)
                    if met.shape[0]:
                        roots = met
                refs = [(s.anchor_scan, np.zeros(6))]
                if s.last_row >= 0 and s.last_row != s.anchor_row:
                    refs.append((int(used[s.last_row]), s.last_box))
                q = self.q_for(i for i, _ in refs)
                union, ok, nt = matcher.match(scan, roots, s.tmap, refs, q=q)
                out.tested += nt
                reloc = False
                if not ok and params.q_retry > params.q_beams and q is None:
                    # more than q beams contradict every predicted pose: people, glass, mixed
                    # returns? match again allowing q_retry beams before doubting the motion
                    union, ok, nt = matcher.match(scan, roots, s.tmap, refs, q=params.q_retry)
                    out.tested += nt
                    out.q_relaxed = bool(ok)
                if not ok and params.relocalise[0] > 0:
                    # no pose of the prediction agrees with the submap: the motion step broke
                    # its bounds (an odometry jump)? search the relocalisation window around it
                    wx, wt = params.relocalise
                    wide = r + np.array([-wx, wx, -wx, wx, -wt, wt])
                    union, ok, nt = matcher.match(scan, wide[None, :], s.tmap, refs, q=q)
                    out.tested += nt
                    if ok:
                        reloc = out.relocalised = True
                        r = wide
                if not ok:
                    out.contradicted = True
                    s.union = r[None, :].copy()
                else:
                    s.union = union
                    h = hull(union)
                    lo = np.maximum(h[0::2], r[0::2])
                    hi = np.minimum(h[1::2], r[1::2])
                    if np.all(lo <= hi) and not np.array_equal(np.column_stack([lo, hi]).reshape(6), r):
                        r = np.column_stack([lo, hi]).reshape(6)
                        out.contracted = True
                        if reloc:  # the trajectory restarts from the relocalised box
                            _reset_node(s.P, k - s.k0, r, rp, rt)
                        else:
                            meet_node(s.P, k - s.k0, r, rp, rt)
                s.union_row = j
        # map the scan into the submap
        if params.max_pose_width <= 0 or _width(r) <= params.max_pose_width:
            check_extent(r, used[j:j + 1], self.extent, self.path)
            all_boxes[scan] = r
            one[0] = scan
            out.res = update_map(s.tmap, self.scans, all_boxes, params.beams, order=one)
            if params.map_sets and s.union is not None and s.union_row == j and s.union.shape[0] > 1:
                # the cells every box of its pose set proves free, beyond the hull's
                u = _met_rows(s.union, r)
                if u.shape[0] > 1:
                    out.set_cells = map_union_free(s.tmap, self.scans, scan, u, params.beams)
            s.mapped.append(j)
            out.last = (s.last_row, s.last_box)
            s.last_row = j
            s.last_box = r.copy()
        return r, out


def _threads(params: Params) -> int:
    if params.threads > 0:
        return params.threads
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def track_submaps(log: LogData, params: Params, scans: Scans, progress=None) -> SubmapTracking:
    """Track and map every scan in submaps (see the module docstring); ``progress(fraction,
    label)``, if given, hears of every scan."""
    bounds = params.beams
    path = log.provenance.path
    used, dropped, m, Pg, source, events = trajectory(log, params, scans)
    n_nodes = m.node_stamp.shape[0]
    extent = extent_limits(scans, bounds, params.eps)
    S = used.size
    glob = np.empty((S, 6))
    predicted = np.empty((S, 6))
    home = np.full(S, -1, np.int64)
    relative = np.full((S, 6), np.nan)
    mapped = np.zeros(S, bool)
    contracted = np.zeros(S, bool)
    contradicted: list = []
    compose_empty: list = []
    relocalised: list = []
    q_relaxed: list = []
    broken_global = False
    stats = np.zeros((len(scans), 6), np.int64)
    is_old = np.zeros(scans.ranges.shape[0], bool)
    track = _Track(params, scans, m, used, extent, path, _threads(params))
    g = np.empty(6)
    met = np.empty(6)
    tested = 0
    set_cells = 0
    submaps: list[Submap] = []
    active: list[Submap] = []
    kg_prev = 0
    travel = 0.0
    last = None  # (x, y) of the previous relative centre in the newest submap, for the travel
    graph = L.AnchorGraph()
    Pdr = Pg.copy()  # the dead reckoning alone (no contraction reaches it): the open-loop reference
    loops_on = bool(params.loop_closure and params.contract)
    try:
        for j in range(S):
            if progress is not None:
                progress(j / S, f"scan {j}/{S}")
            k = int(m.node[j])
            scan = int(used[j])
            rp, rt = float(m.reach[j, 0]), float(m.reach[j, 1])
            # the global dead-reckoned box
            propagate(Pg, m.kind, m.U, events, kg_prev, k)
            kg_prev = k
            gb = np.empty((1, 6))
            widen_boxes(Pg, m.node[j:j + 1], m.reach[j:j + 1], gb)
            gb = gb[0]
            predicted[j] = gb
            if not submaps:  # the first scan anchors the first submap: its frame is the first pose's
                s0 = _new_submap(0, j, scan, k, gb, n_nodes, m.reach[j], params.eps)
                submaps.append(s0)
                active.append(s0)
            results = track.map(lambda s: track.one(s, j, k, scan, rp, rt), list(active))
            if any(out.q_relaxed for _, out in results):
                # up to q_retry of its beams may break the model: no reference for later scans
                track.relaxed[scan] = True
                for s, (_, out) in zip(active, results):
                    if out.last:
                        s.last_row, s.last_box = out.last
            for s, (r, out) in zip(active, results):
                tested += out.tested
                set_cells += out.set_cells
                if out.q_relaxed:
                    q_relaxed.append((j, s.index))
                if out.relocalised:
                    relocalised.append((j, s.index))
                if out.contradicted:
                    contradicted.append((j, s.index, "submap_match"))
                if out.contracted:
                    contracted[j] = True
                s.rows.append(j)
                s.rel.append(r.copy())
                # global: anchor box ⊕ relative box, met with the global box
                compose(s.G.reshape(3, 2), r.reshape(3, 2), 1, g.reshape(3, 2))
                if meet(gb.reshape(3, 2), g.reshape(3, 2), met.reshape(3, 2)):
                    gb = met.copy()
                elif relocalised and relocalised[-1][0] == j:
                    gb = g.copy()  # the global dead reckoning broke with the relocalised motion step
                    broken_global = True
                else:
                    compose_empty.append((j, s.index, "relative"))
                if out.res is not None:
                    mapped[j] = True
                    if s is active[-1]:
                        is_old[scans.offsets[scan]:scans.offsets[scan + 1]] = out.res.is_old[scans.offsets[scan]:
                                                                                            scans.offsets[scan + 1]]
                        stats[scan] = out.res.stats[scan]
            newest = active[-1]
            home[j] = newest.index
            relative[j] = newest.rel[-1]
            # the scan in two submaps: an edge between their anchors
            both = [t for t in active if t.rows and t.rows[-1] == j]
            for a in range(len(both) - 1):
                for b in range(a + 1, len(both)):
                    graph.add_member_pair(both[a].index, both[a].rel[-1], both[b].index, both[b].rel[-1])
            if loops_on and j % params.loop_every == 0 and len(submaps) > 2 and np.all(np.isfinite(gb)):
                reach_j = float(np.median(scans.ranges[scans.offsets[scan]:scans.offsets[scan + 1]]))
                n_loops = len(graph.loops)
                if _search_loops(j, scan, gb, submaps, active, graph, track, params, reach_j):
                    G = _anchor_boxes(submaps)
                    graph.contract(G)
                    _set_anchor_boxes(submaps, G)
                    for t in both:
                        compose(t.G.reshape(3, 2), t.rel[-1].reshape(3, 2), 1, g.reshape(3, 2))
                        if meet(gb.reshape(3, 2), g.reshape(3, 2), met.reshape(3, 2)):
                            gb = met.copy()
                        else:
                            compose_empty.append((j, t.index, "relative"))
                    # the scan's own loop constraints, from the old anchors directly (not through the
                    # anchor edge, which composes its relative box twice)
                    gb = _meet_loops(graph.loops[n_loops:], submaps, gb, compose_empty)
            if broken_global:
                _reset_node(Pg, k, gb, rp, rt)
                broken_global = False
            else:
                meet_node(Pg, k, gb, rp, rt)
            glob[j] = gb
            # travel along the newest submap's relative centres (for the overlap)
            c = _centre(relative[j])
            if last is not None and np.all(np.isfinite(c)):
                travel += math.hypot(c[0] - last[0], c[1] - last[1])
            last = c if newest.anchor_row != j else (0.0, 0.0, 0.0)
            # overlap ends
            for s in list(active[:-1]):
                if travel >= s.closes_at:
                    active.remove(s)
                    s.closed = True
                    if loops_on:
                        s.extent = L.free_extent(s.tmap)
            # a new submap?
            r = relative[j]
            if j + 1 < S and newest.anchor_row != j and np.all(np.isfinite(r)) and np.all(np.isfinite(gb)) and (
                    math.hypot(c[0], c[1]) >= params.submap_distance or abs(c[2]) >= params.submap_turn
                    or _width(r) >= params.submap_width):
                newest.closes_at = travel + params.submap_overlap
                s_new = _new_submap(len(submaps), j, scan, k, gb, n_nodes, m.reach[j], params.eps)
                # the new anchor is mapped into its own submap (exact pose in its frame) while the
                # next scan's other submaps are tracked
                s_new.pending = track.submit(track.map_anchor, s_new)
                s_new.rows.append(j)
                s_new.rel.append(np.zeros(6))
                s_new.mapped.append(j)
                s_new.last_row = j
                s_new.last_box = np.zeros(6)
                for t in active:
                    if t.rows and t.rows[-1] == j:
                        graph.add_member_pair(t.index, t.rel[-1], s_new.index, np.zeros(6))
                submaps.append(s_new)
                active.append(s_new)
                last = (0.0, 0.0, 0.0)
    finally:
        for s in submaps:
            track.settle(s)
        track.close()
    forward = glob.copy()
    # backward passes: in every submap's frame, then globally
    for s in submaps:
        k1 = int(m.node[s.rows[-1]])
        if k1 > s.k0 and contracted[s.rows].any():
            smooth_backward_range(s.P, m.kind[s.k0:], m.U[s.k0:], s.events, 0, k1 - s.k0)
            back = np.empty((len(s.rows), 6))
            widen_boxes(s.P, np.asarray(m.node[s.rows], np.int64) - s.k0, m.reach[s.rows], back)
            for i, row in enumerate(s.rows):
                if row != s.anchor_row and meet(s.rel[i].reshape(3, 2), back[i].reshape(3, 2), met.reshape(3, 2)):
                    s.rel[i] = met.copy()
    for s in submaps:
        for i, row in enumerate(s.rows):
            if s.index == home[row]:
                relative[row] = s.rel[i]
    # the anchor graph with the smoothed relative boxes, contracted; every scan's global box
    # is then its anchors' boxes ⊕ its relative boxes, met with what it was
    members: dict = {}
    for s in submaps:
        for i, row in enumerate(s.rows):
            members.setdefault(row, []).append((s.index, s.rel[i]))
    for row, lst in members.items():
        for a in range(len(lst) - 1):
            for b in range(a + 1, len(lst)):
                graph.add_member_pair(lst[a][0], lst[a][1], lst[b][0], lst[b][1])
    G = _anchor_boxes(submaps)
    propagate(Pdr, m.kind, m.U, np.zeros_like(events), 0, kg_prev)
    dr = np.empty((S, 6))
    widen_boxes(Pdr, m.node, m.reach, dr)
    anchor_before = _open_chain(graph, submaps, dr)
    open_loop = np.full((S, 6), np.nan)
    if graph.loops:
        graph.contract(G)
        _set_anchor_boxes(submaps, G)
    for row, lst in members.items():
        ob = dr[row].copy()
        for si, rb in lst:
            for Gs, target in ((submaps[si].G, glob), (anchor_before[si], None)):
                compose(Gs.reshape(3, 2), np.ascontiguousarray(rb).reshape(3, 2), 1, g.reshape(3, 2))
                dst = glob[row] if target is not None else ob
                if meet(dst.reshape(3, 2), g.reshape(3, 2), met.reshape(3, 2)):
                    dst[:] = met
        open_loop[row] = ob
    by_row: dict = {}
    for lc in graph.loops:
        by_row.setdefault(lc.row, []).append(lc)
    for row, lst in by_row.items():
        glob[row] = _meet_loops(lst, submaps, glob[row], compose_empty)
    if graph.loops:
        scratch = np.zeros_like(events)
        for j in range(S):
            meet_node(Pg, int(m.node[j]), glob[j], float(m.reach[j, 0]), float(m.reach[j, 1]))
        propagate(Pg, m.kind, m.U, scratch, 0, kg_prev)
    smoothed = int(smooth_backward(Pg, m.kind, m.U, events, kg_prev))
    back = np.empty((S, 6))
    widen_boxes(Pg, m.node, m.reach, back)
    for j in range(S):
        if meet(glob[j].reshape(3, 2), back[j].reshape(3, 2), met.reshape(3, 2)):
            glob[j] = met
    pred = PosePrediction(used=used, boxes=glob, source=source, motion=m.motion, step_events=events,
                          node_stamp=m.node_stamp, dropped=dropped)
    return SubmapTracking(pred, submaps, home, relative, mapped, contracted, contradicted, compose_empty,
                          relocalised, q_relaxed, forward, predicted, tested, smoothed, stats, is_old, graph, open_loop,
                          anchor_before, set_cells)
