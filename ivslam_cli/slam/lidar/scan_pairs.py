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

Guarantee: if the motion bounds hold over the steps between the two scans and at most q of
the beams of each scan break the static world, the true relative pose (the later robot pose in
the earlier one's frame) is in the enclosure. q is ``q_beams``, or ``q_retry`` for a pair with
a scan the tracking found q-relaxed, or when no pose agrees with ``q_beams`` broken beams. A
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


def pair_enclosure(track, m, used: np.ndarray, j: int) -> np.ndarray | None:
    """The enclosure (3, 2) of rows ``(j - 1, j)`` (see the module docstring), matched with
    ``track``'s matcher of the calling thread (the scans as tracked: deskewed, with their
    sweep), or None."""
    p = track.p
    prior = pair_prior(m, j - 1, j)
    if prior is None or not np.all(np.isfinite(prior)):
        return None
    a, b = int(used[j - 1]), int(used[j])
    q = track.q_for((a, b))
    refs = [(a, np.zeros(6))]
    matcher = track.matcher()
    tmap = TileMap(p.eps)
    track.map_scan(tmap, a, np.zeros(6))  # for rule A where the cones cannot serve as references
    kw = pair_match_args(p)
    union, ok, _ = matcher.match(b, prior[None, :], tmap, refs, q=q, **kw)
    if not ok and q is None and p.q_retry > p.q_beams:
        union, ok, _ = matcher.match(b, prior[None, :], tmap, refs, q=p.q_retry, **kw)
    if not ok:
        return None
    h = hull(union)
    lo, hi = np.maximum(h[0::2], prior[0::2]), np.minimum(h[1::2], prior[1::2])
    return np.column_stack([lo, hi]) if np.all(lo <= hi) else None


def scan_pairs(track, m, used: np.ndarray, skip: set) -> tuple[np.ndarray, np.ndarray]:
    """The enclosures of every consecutive pair of used rows ``(j - 1, j)``, matched on
    ``track``'s threads; rows in ``skip`` (relocalised) get none. Returns ``(pairs (P, 2) rows,
    boxes (P, 3, 2))``."""
    rows = [j for j in range(1, used.size) if j not in skip and (j - 1) not in skip]
    boxes = track.map(lambda j: pair_enclosure(track, m, used, j), rows)
    keep = [i for i, b in enumerate(boxes) if b is not None]
    pairs = np.array([[rows[i] - 1, rows[i]] for i in keep], np.int64).reshape(-1, 2)
    return pairs, np.array([boxes[i] for i in keep], float).reshape(-1, 3, 2)
