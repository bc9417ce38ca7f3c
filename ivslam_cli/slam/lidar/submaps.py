"""LiDAR tracking and mapping in local frames: submaps anchored at keyframe scans.

Worst-case bounds add up along a path, so a pose box in one global frame grows without end
while the robot explores, and a map built from wide boxes proves little. Here every scan's
pose is tracked *relative to the robot pose of an anchor scan* (its submap's frame, where the
anchor pose is exact), the way Cartographer keeps submaps (Hess et al. 2016) and interval
LiDAR localisation keeps scans relative to keyframes:

1. **dead reckoning in the anchor frame**: the motion steps of :mod:`ivslam_cli.slam.motion`
   from the anchor's node (exact, up to the scan's reach of its node);
2. **contraction** of that relative box against the anchor scan and the previous scan (both
   scans' continuous free space) and against the submap's map built so far: a set inversion
   in pose space (:mod:`.matcher`), q-relaxed over the beams; one scan's matches in all its
   submaps first, then what they prove (:mod:`.submap_track`);
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
per scan, ``q_retry`` for the scans the run names q-relaxed), then every relative box holds the true pose of its scan in its anchor's frame, every
global box the true pose, and each submap's P_EMPTY is free in its anchor's frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ivslam_cli.interval.pose import compose, meet
from ivslam_cli.slam.lidar import loops as L
from ivslam_cli.logs.model import LogData, Scans
from ivslam_cli.paving.tiles import TileMap
from ivslam_cli.slam.lidar.loopsearch import PAVE_BUDGET, PAVE_LEAF, PAVE_LEAVES, PAVE_STRIDE, pave
from ivslam_cli.slam.lidar.map_update import extent_limits
from ivslam_cli.slam.lidar.matcher import hull
from ivslam_cli.slam.lidar.params import Params
from ivslam_cli.slam.lidar.prediction import PosePrediction, sweep_motion, trajectory
from ivslam_cli.slam.lidar.scan_pairs import Pairs
from ivslam_cli.slam.lidar.submap_track import Track, reset_node, threads, width
from ivslam_cli.slam.motion_kernel import (
    meet_node,
    propagate,
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
    q_rematched: list = field(default_factory=list)  # (row, submap) matched again with q_retry: relaxed elsewhere
    q_held: list = field(default_factory=list)  # rows matched with q_retry from the start (lidar.q_hold)
    sweep: np.ndarray | None = None  # (S', 2) per used row: motion bound (d, a) while its beams are taken
    smin: np.ndarray | None = None  # (S',) per used row: no cell nearer its sensor proven free (sweep_free_from)
    beams: Scans | None = None  # the scans as matched and mapped: each beam turned by the sweep's nominal turn
    pairs: tuple | None = None  # (rows (P, 2), boxes (P, 3, 2)): consecutive scans matched alone (scan_pairs)


def _centre(b: np.ndarray) -> tuple[float, float, float]:
    return 0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]), 0.5 * (b[4] + b[5])


def _new_submap(index: int, row: int, scan: int, k: int, G: np.ndarray, n_nodes: int, reach, eps: float) -> Submap:
    P = np.empty((n_nodes - k, 3, 2))
    P[:, :, 0] = -np.inf
    P[:, :, 1] = np.inf
    rp, rt = float(reach[0]), float(reach[1])  # node k holds the modelled pose, within reach of the scan's
    P[0] = [[-rp, rp], [-rp, rp], [-rt, rt]]
    return Submap(index, row, scan, k, G.copy(), TileMap(eps), P, np.zeros(max(n_nodes - k - 1, 0), np.int64), k)


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
    cands = cands[: params.loop_candidates]
    # a wide prior at least as wide as one whose paving ran out against that submap: not paved
    hopeless = [not c[4] and graph.pave_hopeless(c[2].index, L.width(c[3]), L.heading(c[3])) for c in cands]
    graph.pave_skipped += sum(hopeless)
    cands = [c for c, h in zip(cands, hopeless) if not h]
    added = False
    for (_, _, s, prior, narrow), (paved, pave_nt, roots, box, nb, nt) in zip(
            cands,
            track.map(lambda c: _loop_match(track.matcher(), scan, c[2], c[3], c[4], params, reach,
                                            track.q_for((scan, c[2].anchor_scan))), cands)):
        if paved:
            graph.paved += 1
            graph.pave_tests += pave_nt
        if roots is None:
            graph.pave_incomplete += 1
            if paved and pave_nt > 0:
                graph.pave_ran_out(s.index, L.width(prior), L.heading(prior))
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
    q_rematched: list = []
    q_held: list = []
    broken_global = False
    stats = np.zeros((len(scans), 6), np.int64)
    is_old = np.zeros(scans.ranges.shape[0], bool)
    # each beam turned by the nominal turn to its time (the sweep, deskewed)
    model = sweep_motion(scans, params, m, used)
    sweep, smin, beams = model.reach, model.smin, model.beams
    track = Track(params, beams, m, used, extent, path, threads(params), model)
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
        f0 = 0.0  # the share of the progress bar the pairs take
        if params.pair_boxes > 0 and params.contract:
            f0 = 0.4
            # matched first: they seed the tracking
            track.pairs = Pairs(track, m, used, None if progress is None else lambda f, t: progress(f0 * f, t))
        for j in range(S):
            if progress is not None:
                progress(f0 + (1.0 - f0) * j / S, f"scan {j}/{S}")
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
            results, held = track.track(list(active), j, k, scan, rp, rt)
            if held:
                q_held.append(j)
            for s, (r, out) in zip(active, results):
                tested += out.tested
                set_cells += out.set_cells
                if out.q_relaxed:
                    q_relaxed.append((j, s.index))
                if out.q_rematched:
                    q_rematched.append((j, s.index))
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
                reset_node(Pg, k, gb, rp, rt)
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
                    or width(r) >= params.submap_width):
                newest.closes_at = travel + params.submap_overlap
                s_new = _new_submap(len(submaps), j, scan, k, gb, n_nodes, m.reach[j], params.eps)
                # the new anchor is mapped into its own submap (exact pose in its frame) while the
                # next scan's other submaps are tracked
                s_new.pending = track.submit(track.map_anchor, s_new)
                s_new.rows.append(j)
                s_new.rel.append(np.zeros(6))
                s_new.mapped.append(j)
                mapped[j] = True  # at its own anchor, exactly
                s_new.last_row = j
                s_new.last_box = np.zeros(6)
                for t in active:
                    if t.rows and t.rows[-1] == j:
                        graph.add_member_pair(t.index, t.rel[-1], s_new.index, np.zeros(6))
                submaps.append(s_new)
                active.append(s_new)
                last = (0.0, 0.0, 0.0)
        pairs = None
        if track.pairs is not None:
            pairs = track.pairs.final({row for row, _ in relocalised})
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
                          anchor_before, set_cells, q_rematched, q_held, sweep[used], smin[used], beams, pairs)
