"""Each scan matched against the scan before it alone: one relative pose enclosure per
consecutive pair of scans (``lidar.pair_boxes``).

The tracker contracts a scan in its submaps' frames, and a relation between two consecutive
scans that share no anchor is read through the chain of anchors (wide: each link adds its
width and turns the next by its heading). Here the earlier scan's robot frame is the frame: its
pose is exact there, and the later scan's prior is the motion model's box over the steps
between the two stamps, from an exact start (dead reckoning, as for a submap's first member).
The matcher (:mod:`.matcher`: rule A against the earlier scan's free cells and cones, rule B
against its beam ends, every ``pair_stride``-th beam, ``pair_boxes`` pose sub-boxes at most) keeps every
pose at which both scans agree but for q beams of each; the enclosure is the hull of that set.
Only the hull is kept, so the search is not cut into heading slices: after the heading's two
bounds, the whole budget goes to the four sides of x and y, found to ``pair_resolution``.
This is the scan-to-scan relation of the benchmark of Kümmerle et al. (2009), enclosed.

The pairs are matched before the tracking, all at once on the tracker's threads (they need
nothing the tracking finds), and they serve it: a scan's prior in a submap that holds the scan
before it is met with that scan's box there ⊕ the pair (:meth:`.submap_track.Track.match`),
and in a submap that holds the scan before it alone (its anchor) the pair *is* the match.

Guarantee: if the motion bounds hold over the steps between the two scans and at most q of
the beams of each scan break the static world, the true relative pose (the later robot pose in
the earlier one's frame) is in the enclosure. q is ``q_beams``, or ``q_retry`` for a pair with
a scan the tracking found q-relaxed, or when no pose agrees with ``q_beams`` broken beams
(a pair matched with ``q_beams`` is matched again with ``q_retry`` once the tracking finds one
of its scans q-relaxed, before the tracking or the result uses it). A
pair with a relocalised scan (its motion step broke its bounds) or whose motion steps have no
solution, or where no pose agrees even with ``q_retry``, gets no enclosure.
"""

from __future__ import annotations

import numpy as np

from ivslam_cli.paving.tiles import TileMap
from ivslam_cli.slam.lidar.matcher import hull
from ivslam_cli.slam.motion_kernel import propagate, widen_boxes


def pair_prior(m, a: int, b: int) -> np.ndarray | None:
    """Row ``b``'s robot box (6,) in row ``a``'s robot frame from the motion model ``m`` alone
    (row ``a`` exact; each row's node within its reach of the scan's pose), or None when a
    motion step between them has no solution."""
    k0, k1 = int(m.node[a]), int(m.node[b])
    P = np.empty((k1 - k0 + 1, 3, 2))
    P[:, :, 0], P[:, :, 1] = -np.inf, np.inf
    rp, rt = float(m.reach[a, 0]), float(m.reach[a, 1])
    P[0] = [[-rp, rp], [-rp, rp], [-rt, rt]]
    events = np.zeros(max(k1 - k0, 1), np.int64)
    propagate(P, m.kind[k0:], m.U[k0:], events, 0, k1 - k0)
    if events.any():
        return None
    out = np.empty((1, 6))
    widen_boxes(P, np.array([k1 - k0], np.int64), m.reach[b:b + 1], out)
    return out[0]


def pair_match_args(p) -> dict:
    """The matcher's settings for a pair (``Matcher.match`` keywords): ``pair_boxes`` (or
    ``match_boxes`` when pairs are off), every ``pair_stride``-th beam, one slice (only the
    hull is kept), x and y to ``pair_resolution``."""
    return dict(budget=p.pair_boxes or p.match_boxes, stride=p.pair_stride, slices=1, resolution=p.pair_resolution)


def pair_enclosure(track, m, used: np.ndarray, j: int, q: int | None = None) -> tuple[np.ndarray | None, int]:
    """The enclosure (3, 2) of rows ``(j - 1, j)`` (see the module docstring), matched with
    ``track``'s matcher of the calling thread (the scans as tracked: deskewed, with their
    sweep), or None; with the q it holds under (``q``, or as :meth:`Track.q_for` says, or
    ``q_retry`` when no pose agrees with ``q_beams``)."""
    p = track.p
    a, b = int(used[j - 1]), int(used[j])
    if q is None:
        q = track.q_for((a, b))
    q_eff = p.q_beams if q is None else q
    prior = pair_prior(m, j - 1, j)
    if prior is None or not np.all(np.isfinite(prior)):
        return None, q_eff
    refs = [(a, np.zeros(6))]
    matcher = track.matcher()
    tmap = TileMap(p.eps)
    track.map_scan(tmap, a, np.zeros(6))  # for rule A where the cones cannot serve as references
    kw = pair_match_args(p)
    union, ok, _ = matcher.match(b, prior[None, :], tmap, refs, q=q, **kw)
    if not ok and q is None and p.q_retry > p.q_beams:
        q_eff = p.q_retry
        union, ok, _ = matcher.match(b, prior[None, :], tmap, refs, q=p.q_retry, **kw)
    if not ok:
        return None, q_eff
    h = hull(union)
    lo, hi = np.maximum(h[0::2], prior[0::2]), np.minimum(h[1::2], prior[1::2])
    return (np.column_stack([lo, hi]) if np.all(lo <= hi) else None), q_eff


BATCH = 64  # pairs matched between two progress reports


class Pairs:
    """Every consecutive pair's enclosure, matched before the tracking (in parallel on
    ``track``'s threads) with ``q_beams``, and again with ``q_retry`` when the tracking finds
    one of its scans q-relaxed: :meth:`get` gives a pair only under the q its scans need now."""

    def __init__(self, track, m, used: np.ndarray, progress=None) -> None:
        self.track, self.m, self.used = track, m, used
        rows = list(range(1, used.size))
        got = []
        for i in range(0, len(rows), BATCH):  # in batches, to tell ``progress(fraction, label)``
            if progress is not None:
                progress(i / max(len(rows), 1), f"scan pairs {i}/{len(rows)}")
            got += track.map(lambda j: pair_enclosure(track, m, used, j), rows[i:i + BATCH])
        self.box = {j: g for j, g in zip(rows, got)}  # j -> (box (3, 2) or None, q)

    def need(self, j: int) -> int:
        p, relaxed = self.track.p, self.track.relaxed
        if p.q_retry > p.q_beams and (relaxed[int(self.used[j - 1])] or relaxed[int(self.used[j])]):
            return p.q_retry
        return p.q_beams

    def get(self, j: int, q: int | None = None) -> tuple[np.ndarray | None, int]:
        """Rows ``(j - 1, j)``'s enclosure (3, 2) under at least ``q`` (and what the scans
        need), matched again when the one held was found with less (None when none), and the q
        it holds under."""
        if j not in self.box:
            return None, 0
        need = max(self.need(j), self.track.p.q_beams if q is None else q)
        box, q_had = self.box[j]
        if q_had < need:
            box, q_had = pair_enclosure(self.track, self.m, self.used, j, q=need)
            self.box[j] = (box, q_had)
        return box, q_had

    def final(self, skip: set) -> tuple[np.ndarray, np.ndarray]:
        """``(pairs (P, 2) rows, boxes (P, 3, 2))`` under the q the tracking ended with; rows in
        ``skip`` (relocalised) get none."""
        rows = [j for j in self.box if j not in skip and (j - 1) not in skip]
        redo = [j for j in rows if self.box[j][1] < self.need(j)]
        for j, g in zip(redo, self.track.map(lambda j: pair_enclosure(self.track, self.m, self.used, j,
                                                                       q=self.need(j)), redo)):
            self.box[j] = g
        keep = [j for j in rows if self.box[j][0] is not None]
        pairs = np.array([[j - 1, j] for j in keep], np.int64).reshape(-1, 2)
        return pairs, np.array([self.box[j][0] for j in keep], float).reshape(-1, 3, 2)
