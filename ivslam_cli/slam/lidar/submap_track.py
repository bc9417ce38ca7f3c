"""One scan tracked in the submaps that hold it: dead reckoning in each anchor's frame, the
match against each submap, then the contraction and the map update.

The two steps are apart because the q of a scan is one assumption over all its submaps. Each
match first allows ``q_beams`` wrong beams; when no pose of some submap's prediction agrees
with that many, the scan is matched there again allowing ``q_retry`` (it is *q-relaxed*). From
then on only ``q_retry`` is assumed for that scan, so its matches in its other submaps are made
again with ``q_retry`` before any of them contracts a pose or maps a cell. Whatever broke the
static world (people, glass) is likely still there a moment later, and a scan with more than
``q_beams`` such beams may still agree with some wrong pose: the scans of the next ``q_hold``
seconds are *held*, matched with ``q_retry`` from the start. A q-relaxed or held scan is no
reference (the "previous scan") for later scans, and every match against it allows ``q_retry``.

With scan pairs (``lidar.pair_boxes``, :mod:`.scan_pairs`), a scan's dead-reckoned box in a
submap that holds the scan before it is met with that scan's box there ⊕ the pair's
enclosure; where that submap holds nothing but the scan before it (its anchor), the pair,
every beam matched against that same scan, stands for the match.

Guarantee: if the scan's true pose is in its dead-reckoned box in a submap's frame, the
submap's map is sound, and at most the q it was matched with of its beams (and of its
references', and of the scan before it with a pair) break the static world, the box :meth:`Track.commit` returns holds the true pose
in that frame, and the cells it maps are free (P_EMPTY) or may hold a surface (P_OBSTACLE) in
that frame.
"""

from __future__ import annotations

import math
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ivslam_cli.interval.pose import compose, meet
from ivslam_cli.logs.model import Scans
from ivslam_cli.slam.lidar.map_update import UpdateResult, check_extent, map_union_free, update_map
from ivslam_cli.slam.lidar.matcher import Matcher, hull
from ivslam_cli.slam.lidar.params import Params
from ivslam_cli.slam.lidar.sweep_map import chunk_boxes, chunk_scans, staggered_errors, swept_box
from ivslam_cli.slam.motion_kernel import meet_node, propagate, propagate_boxes, widen_boxes


def met_rows(boxes: np.ndarray, r: np.ndarray) -> np.ndarray:
    """The boxes (n, 6) met with ``r`` (6,), the empty meets left out: (n', 6)."""
    lo = np.maximum(boxes[:, 0::2], r[0::2])
    hi = np.minimum(boxes[:, 1::2], r[1::2])
    good = np.all(lo <= hi, axis=1)
    out = np.empty((int(good.sum()), 6))
    out[:, 0::2], out[:, 1::2] = lo[good], hi[good]
    return out


def width(b: np.ndarray) -> float:
    """The larger x-y side of a pose box (6,)."""
    return max(b[1] - b[0], b[3] - b[2])


def reset_node(P, k: int, box: np.ndarray, rp: float, rt: float) -> None:
    """``P[k]`` = the robot box (6,) of an event at node ``k`` widened by its reach."""
    P[k, 0] = box[0] - rp, box[1] + rp
    P[k, 1] = box[2] - rp, box[3] + rp
    P[k, 2] = box[4] - rt, box[5] + rt
    P[k, :, 0] = np.nextafter(P[k, :, 0], -np.inf)
    P[k, :, 1] = np.nextafter(P[k, :, 1], np.inf)


def relative_box(s, m, j: int, k: int) -> np.ndarray:
    """Propagate submap ``s``'s trajectory to node ``k`` and return scan row ``j``'s box in its frame."""
    propagate(s.P, m.kind[s.k0:], m.U[s.k0:], s.events, s.k_prev - s.k0, k - s.k0)
    s.k_prev = k
    out = np.empty((1, 6))
    widen_boxes(s.P, np.array([k - s.k0]), m.reach[j:j + 1], out)
    return out[0]


def threads(params: Params) -> int:
    """The tracking threads: ``lidar.threads``, or the CPUs this process may use when 0."""
    if params.threads > 0:
        return params.threads
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


@dataclass
class Tracked:
    """What tracking one scan in one submap found (the caller records it, in submap order)."""

    dead_reckoned: np.ndarray | None = None  # (6,) the scan's box in the frame before any match
    r: np.ndarray | None = None  # (6,) its box: the match's hull met with the prior (the anchor: 0)
    matched: bool = False  # a match ran
    ok: bool = False  # ... and some pose agreed with the submap
    union: np.ndarray | None = None  # (m, 6) the kept pose set
    q: int | None = None  # the q the match began with (None: q_beams)
    tested: int = 0
    q_relaxed: bool = False  # no pose agreed with q_beams beams; matched with q_retry
    q_rematched: bool = False  # matched again with q_retry: the scan was q-relaxed in another submap
    relocalised: bool = False
    contradicted: bool = False
    contracted: bool = False
    res: object = None  # the map update's result when the scan was mapped into the submap
    set_cells: int = 0  # cells its pose set proved free that the submap did not hold yet (lidar.map_sets)


class Track:
    """The per-scan work in each active submap, which touches nothing but that submap: the
    submaps of a scan are matched, then committed, in parallel threads (the kernels release
    the GIL), with the same results as one after the other. Each thread keeps its own matcher
    and buffers."""

    def __init__(self, params: Params, scans: Scans, m, used: np.ndarray, extent, path, n_threads: int,
                 model=None) -> None:
        self.p, self.scans, self.m, self.used, self.extent, self.path = params, scans, m, used, extent, path
        # the sweep (prediction.SweepModel): per scan (d, a), how far the robot moves and turns
        # while its beams are taken, and the distance from its sensor below which its free cones
        # prove nothing (its beams taken from poses apart: free_cones.sweep_free_from)
        self.model = model
        self.sweep = np.zeros((len(scans), 2)) if model is None else model.reach
        self.smin = np.zeros(len(scans)) if model is None else model.smin
        # swept scans mapped in runs of beams, each from its nominal sensor position (sweep_map)
        self.chunks = None if model is None else chunk_scans(scans, model.offset, model.smin)
        # ... and, for the cells between two runs, P_EMPTY in runs cut at the runs' middles
        self.stagger = None if self.chunks is None else chunk_scans(scans, model.offset, model.smin, staggered=True)
        # scans q-relaxed somewhere: up to q_retry of their beams may be wrong, so every match of
        # one, or against one, allows as many
        self.relaxed = np.zeros(len(scans), bool)
        self.hold_until = -math.inf  # scans up to this stamp are matched with q_retry from the start
        self.local = threading.local()
        self.pairs = None  # scan_pairs.Pairs: each scan's prior also met with the previous one's box ⊕ their pair
        self.pool = ThreadPoolExecutor(max_workers=n_threads) if n_threads > 1 else None

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown()

    def _buffers(self):
        b = getattr(self.local, "b", None)
        if b is None:
            nc = 1 if self.chunks is None else len(self.chunks.scans)
            b = self.local.b = (Matcher(self.p, self.scans, self.model, self.chunks), np.zeros((len(self.scans), 6)),
                                np.zeros(1, np.int64), np.zeros((nc, 6)))
        return b

    def _run_boxes(self, scan: int, r: np.ndarray, staggered: bool = False) -> np.ndarray:
        """The robot boxes (runs, 6) of a moving swept scan's runs of beams (the plain or the
        staggered ones) from its robot box ``r`` (6,) at its stamp (:mod:`.sweep_map`)."""
        ch, md = (self.stagger if staggered else self.chunks), self.model
        a = float(self.sweep[scan, 1]) if md.run_turn is None else md.run_turn[scan]
        e = float(md.err[scan]) if md.run_err is None else md.run_err[scan]
        if staggered:
            n = int(self.chunks.first[scan + 1] - self.chunks.first[scan])
            a, e = staggered_errors(a, n), staggered_errors(e, n)
        return chunk_boxes(ch, scan, r, a, e, float(md.turn_lever[scan]))

    def map_scan(self, tmap, scan: int, r: np.ndarray) -> UpdateResult:
        """Scan ``scan`` mapped into ``tmap`` from robot box ``r`` (6,) at its stamp: widened by
        its sweep, or, when it moves, in runs of beams each from its nominal sensor position,
        then in the staggered runs (P_EMPTY only) (:mod:`.sweep_map`). The result is indexed by
        scan."""
        _, all_boxes, one, cboxes = self._buffers()
        ch = self.chunks
        if ch is None or not ch.moves[scan]:
            all_boxes[scan] = swept_box(r, self.sweep[scan])
            check_extent(all_boxes[scan], np.array([scan]), self.extent, self.path)
            one[0] = scan
            return update_map(tmap, self.scans, all_boxes, self.p.beams, order=one, smin=self.smin)
        j0, j1 = int(ch.first[scan]), int(ch.first[scan + 1])
        cb = self._run_boxes(scan, r)
        cboxes[j0:j1] = cb
        check_extent(cb, np.full(j1 - j0, scan), self.extent, self.path)
        res = update_map(tmap, ch.scans, cboxes, self.p.beams, order=np.arange(j0, j1), smin=ch.smin)
        stats = np.zeros((len(self.scans), res.stats.shape[1]), res.stats.dtype)
        stats[scan] = res.stats[j0:j1].sum(axis=0)
        self._runs_empty(tmap, self.stagger, scan, self._run_boxes(scan, r, staggered=True)[:, None, :])
        return UpdateResult(res.is_old, stats)

    def _runs_empty(self, tmap, ch, scan: int, boxes: np.ndarray) -> int:
        """Run by run of ``ch``, the cells run ``i`` proves free from every box ``boxes[i]``
        (runs, n, 6) marked EMPTY (:func:`.map_update.map_union_free`); how many were not."""
        j0 = int(ch.first[scan])
        n = 0
        for i in range(boxes.shape[0]):
            j = j0 + i
            if ch.scans.offsets[j + 1] > ch.scans.offsets[j]:
                n += map_union_free(tmap, ch.scans, j, boxes[i], self.p.beams, float(ch.smin[j]))
        return n

    def map_set(self, tmap, scan: int, u: np.ndarray) -> int:
        """The cells scan ``scan`` proves free from every box of its pose set ``u`` (n, 6) at its
        stamp marked EMPTY in ``tmap`` (after :meth:`map_scan` with their hull); how many were
        not before. A moving swept scan, run by run: a cell a run proves free from each box's
        run box is free whichever box holds the pose."""
        ch = self.chunks
        if ch is None or not ch.moves[scan]:
            return map_union_free(tmap, self.scans, scan, swept_box(u, self.sweep[scan]), self.p.beams,
                                  self.smin[scan])
        return self._runs_empty(tmap, ch, scan, np.stack([self._run_boxes(scan, b) for b in u], axis=1))

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

    def map_anchor(self, s) -> None:
        """The anchor scan mapped into its own submap, at the frame's origin."""
        self.map_scan(s.tmap, s.anchor_scan, np.zeros(6))

    @staticmethod
    def settle(s) -> None:
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

    def track(self, active: list, j: int, k: int, scan: int, rp: float, rt: float) -> tuple[list, bool]:
        """Scan row ``j`` (node ``k``) in each of the ``active`` submaps: ``([(box, Tracked)],
        held)``, ``held`` when the scan was matched with ``q_retry`` from the start (within
        ``q_hold`` seconds of a q-relaxed scan)."""
        p = self.p
        t = float(self.scans.stamp[scan])
        held = p.q_retry > p.q_beams and t <= self.hold_until
        if held:
            self.relaxed[scan] = True
        newest = active[-1]
        outs = self.map(lambda s: self.match(s, j, k, scan, q=p.q_retry if held else None, older=s is not newest),
                        active)
        if any(o.q_relaxed for o in outs):
            self.relaxed[scan] = True
            self.hold_until = t + p.q_hold if p.q_hold > 0 else -math.inf
            for i, o in enumerate(outs):  # a box met with a q_beams pair but not matched: met anew
                if not o.matched and o.dead_reckoned is not None and o.r is not o.dead_reckoned:
                    o.r = self.pair_met(active[i], j, o.dead_reckoned, p.q_retry)
            again = [i for i, o in enumerate(outs) if o.matched and o.q is None and not o.q_relaxed]
            if p.q_retry > p.q_beams and again:
                redo = self.map(lambda i: self.match(active[i], j, k, scan, q=p.q_retry, older=active[i] is not newest,
                                                     prior=outs[i].dead_reckoned), again)
                for i, o in zip(again, redo):
                    o.tested += outs[i].tested
                    o.q_rematched = True
                    outs[i] = o
        relaxed = bool(self.relaxed[scan])
        return self.map(lambda so: self.commit(so[0], j, k, scan, rp, rt, so[1], relaxed), list(zip(active, outs))), held

    def match(self, s, j: int, k: int, scan: int, q: int | None = None, prior: np.ndarray | None = None,
              older: bool = False) -> Tracked:
        """Scan row ``j`` matched against submap ``s`` (nothing in ``s`` but its dead reckoning
        changes): ``q`` beams allowed (default: as :meth:`q_for` says, with a ``q_retry`` retry);
        ``prior`` the dead-reckoned box when it is known."""
        params, m, used = self.p, self.m, self.used
        self.settle(s)
        matcher = self.matcher()
        out = Tracked()
        if s.anchor_row == j:
            out.r = np.zeros(6)  # the frame is the anchor's pose
            return out
        r0 = relative_box(s, m, j, k) if prior is None else prior
        out.dead_reckoned = out.r = r0
        if not (params.contract and np.all(np.isfinite(r0))):
            return out
        r = out.r = self.pair_met(s, j, r0, q)
        if older and 0 < params.max_pose_width < width(r):
            return out  # an overlap's scan too wide there to be mapped: the newest submap tracks it
        if self.pairs is not None and s.anchor_row == j - 1 and len(s.rows) == 1 and r is not r0:
            # the submap holds the previous scan alone: its match is the pair's (every beam)
            _, q_had = self.pairs.get(j, q)
            out.matched, out.q, out.ok, out.union = True, q, True, r[None, :].copy()
            out.q_relaxed = q is None and q_had > params.q_beams
            return out
        roots = self._roots(s, j, k, r)
        refs = [(s.anchor_scan, np.zeros(6))]
        if s.last_row >= 0 and s.last_row != s.anchor_row:
            refs.append((int(used[s.last_row]), s.last_box))
        if q is None:
            q = self.q_for(i for i, _ in refs)
        out.matched, out.q = True, q
        union, ok, nt = matcher.match(scan, roots, s.tmap, refs, q=q)
        out.tested += nt
        if not ok and params.q_retry > params.q_beams and q is None:
            # more than q beams contradict every predicted pose: people, glass, mixed
            # returns? match again allowing q_retry beams before doubting the motion
            if r is not r0:  # the prior met with the pair under q_retry, the roots from it anew
                r = out.r = self.pair_met(s, j, r0, params.q_retry)
                roots = self._roots(s, j, k, r)
            union, ok, nt = matcher.match(scan, roots, s.tmap, refs, q=params.q_retry)
            out.tested += nt
            out.q_relaxed = bool(ok)
        if not ok and params.relocalise[0] > 0:
            # no pose of the prediction agrees with the submap: the motion step broke its
            # bounds (an odometry jump)? search the relocalisation window around it
            wx, wt = params.relocalise
            wide = r0 + np.array([-wx, wx, -wx, wx, -wt, wt])
            union, ok, nt = matcher.match(scan, wide[None, :], s.tmap, refs, q=q)
            out.tested += nt
            if ok:
                out.relocalised = True
                out.r = wide
        out.ok, out.union = bool(ok), union
        return out

    def _roots(self, s, j: int, k: int, r: np.ndarray) -> np.ndarray:
        """The match's roots for row ``j`` (node ``k``) in submap ``s`` from its prior ``r``
        (6,): the submap's last pose set propagated to node ``k`` and met with ``r``, or ``r``."""
        m = self.m
        if s.union is not None and s.union_row >= 0:
            jp = s.union_row
            kp = int(m.node[jp])
            prop = np.empty_like(s.union)
            ok = propagate_boxes(s.P[kp - s.k0], s.union, m.reach[jp], m.kind[s.k0:], m.U[s.k0:],
                                 kp - s.k0, k - s.k0, m.reach[j], prop)
            met = met_rows(prop[ok], r)
            if met.shape[0]:
                return met
        return r[None, :]

    def pair_met(self, s, j: int, r: np.ndarray, q: int | None) -> np.ndarray:
        """Row ``j``'s box ``r`` (6,) in submap ``s``'s frame met with the previous row's box
        there ⊕ the pair's enclosure (held under ``q``), when ``s`` holds row ``j - 1``; ``r``
        itself otherwise, or when they do not meet."""
        if self.pairs is None or not s.rows or s.rows[-1] != j - 1:
            return r
        box, _ = self.pairs.get(j, q)
        if box is None:
            return r
        g = np.empty((3, 2))
        compose(np.ascontiguousarray(s.rel[-1], float).reshape(3, 2), np.ascontiguousarray(box, float), 1, g)
        met = np.empty((3, 2))
        if not meet(np.ascontiguousarray(r, float).reshape(3, 2), g, met):
            return r
        return met.reshape(6)

    def commit(self, s, j: int, k: int, scan: int, rp: float, rt: float, out: Tracked,
               relaxed: bool) -> tuple[np.ndarray, Tracked]:
        """What the match ``out`` of row ``j`` proved, into submap ``s``: its pose set and node
        box contracted, the scan mapped with its box; it becomes the submap's reference scan
        unless ``relaxed``. Returns ``(box, out)``."""
        params = self.p
        r = out.r
        if out.matched:
            if not out.ok:
                out.contradicted = True
                s.union = r[None, :].copy()
            else:
                s.union = out.union
                h = hull(out.union)
                lo = np.maximum(h[0::2], r[0::2])
                hi = np.minimum(h[1::2], r[1::2])
                if np.all(lo <= hi) and not np.array_equal(np.column_stack([lo, hi]).reshape(6), r):
                    r = np.column_stack([lo, hi]).reshape(6)
                    out.contracted = True
                    if out.relocalised:  # the trajectory restarts from the relocalised box
                        reset_node(s.P, k - s.k0, r, rp, rt)
                    else:
                        meet_node(s.P, k - s.k0, r, rp, rt)
            s.union_row = j
        if params.max_pose_width <= 0 or width(r) <= params.max_pose_width:
            out.res = self.map_scan(s.tmap, scan, r)
            if params.map_sets and s.union is not None and s.union_row == j and s.union.shape[0] > 1:
                # the cells every box of its pose set proves free, beyond the hull's
                u = met_rows(s.union, r)
                if u.shape[0] > 1:
                    out.set_cells = self.map_set(s.tmap, scan, u)
            s.mapped.append(j)
            if not relaxed:
                # up to q_retry of a relaxed scan's beams may break the model: no reference
                s.last_row = j
                s.last_box = r.copy()
        return r, out
