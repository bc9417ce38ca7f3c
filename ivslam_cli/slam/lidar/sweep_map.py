"""A swept scan mapped in chunks of beams, each from its own nominal sensor position.

A 2D LiDAR takes its beams one after another while the robot moves (the sweep:
:class:`~.prediction.SweepModel`). Mapped from one box, every beam needs the robot box widened
by the whole sweep's move (3.7 cm at 0.5 m/s over the URG-04LX's 0.067 s, twice an odometry
step with pose increments), and every proven-free cell stops that much short of the walls.
The map kernels take one sensor box per scan, so the scan is cut into :data:`CHUNKS` runs of
consecutive beams, each mapped as a scan of its own from the robot box moved by its beams'
nominal move (the odometry's, :meth:`~ivslam_cli.slam.motion.MotionSteps.move_between`, turned
with the box's heading) and widened by their spread about it and the move's error. A chunk
proves free only the bearings its own cones cover and, like the whole scan, nothing nearer its
sensor than the sweep's ``smin`` (:func:`~.free_cones.sweep_free_from`). The scan is also
mapped in *staggered* runs, cut at the chunks' middles (P_EMPTY only: their P_OBSTACLE would
only add to the outer set), so a cell whose bearings span the boundary of two chunks, but not
more than half a chunk, lies within one of them. The guarantee is the map's: every proven-free cell
free, every end point in P_OBSTACLE, for every pose of the robot box at the stamp.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ivslam_cli.logs.model import Scans

#: runs of beams a swept scan is mapped in (the URG-04LX: 86 beams, 4.6 mm of a 3.7 cm move each)
CHUNKS = 8


@dataclass
class Chunks:
    """The scans cut into runs of beams (the same beams, in the same order)."""

    scans: Scans  # one row per chunk
    of: np.ndarray  # (C,) the scan of each chunk
    first: np.ndarray  # (S + 1,) the chunks of scan k: first[k] .. first[k + 1] − 1
    centre: np.ndarray  # (C, 2) the chunk's nominal move (robot frame at the stamp)
    spread: np.ndarray  # (C,) every beam's nominal move within this of the centre
    smin: np.ndarray  # (C,) as its scan's
    moves: np.ndarray  # (S,) some beam of the scan moves (else it is mapped whole)


def chunk_scans(scans: Scans, offset: np.ndarray, smin: np.ndarray, n: int = CHUNKS,
                staggered: bool = False) -> Chunks | None:
    """``scans`` cut into ``n`` runs of beams each, with the nominal moves ``offset`` (B, 2, in
    the sensor frame) of their beams' sensors; None when no beam moves. ``staggered``: cut at
    the middles of those runs instead (``n + 1`` runs, half a run at each end), so that run
    ``i`` lies within runs ``i − 1`` and ``i`` of the plain cut (:func:`staggered_errors`)."""
    if offset.shape[0] != scans.ranges.shape[0] or not np.any(offset != 0.0):
        return None
    myaw = float(scans.mount[2])
    c, s = math.cos(myaw), math.sin(myaw)
    o = np.column_stack([c * offset[:, 0] - s * offset[:, 1], s * offset[:, 0] + c * offset[:, 1]])  # robot frame
    nb = np.diff(scans.offsets)
    base = np.minimum(n, np.maximum(nb, 1))
    parts = base + 1 if staggered else base
    first = np.concatenate([[0], np.cumsum(parts)]).astype(np.int64)
    C = int(first[-1])
    of = np.repeat(np.arange(len(scans)), parts)
    starts = np.empty(C, np.int64)
    for k in range(len(scans)):
        if staggered:
            cut = scans.offsets[k] + np.concatenate([[0], ((2 * np.arange(base[k]) + 1) * nb[k]) // (2 * base[k])])
        else:
            cut = scans.offsets[k] + (np.arange(parts[k]) * nb[k]) // parts[k]
        starts[first[k]:first[k + 1]] = cut
    offs = np.concatenate([starts, [scans.offsets[-1]]]).astype(np.int64)
    lead = starts - scans.offsets[of]  # beams before the chunk in its scan
    a0 = np.asarray(scans.angle_min, float)[of] + lead * np.asarray(scans.angle_increment, float)[of]
    centre = np.zeros((C, 2))
    spread = np.zeros(C)
    for j in range(C):
        seg = o[offs[j]:offs[j + 1]]
        if seg.shape[0]:
            centre[j] = 0.5 * (seg.min(axis=0) + seg.max(axis=0))
            spread[j] = float(np.max(np.hypot(seg[:, 0] - centre[j, 0], seg[:, 1] - centre[j, 1])))
    spread = np.nextafter(spread * (1.0 + 1e-12) + 1e-15, np.inf)
    ti = None if scans.time_increment is None else np.asarray(scans.time_increment)[of]
    cs = replace(scans, stamp=np.asarray(scans.stamp, float)[of], angle_min=a0,
                 angle_increment=np.asarray(scans.angle_increment, float)[of],
                 range_min=np.asarray(scans.range_min, float)[of], range_max=np.asarray(scans.range_max, float)[of],
                 offsets=offs, time_increment=ti)
    moves = np.array([bool(np.any(o[scans.offsets[k]:scans.offsets[k + 1]] != 0.0)) for k in range(len(scans))])
    return Chunks(scans=cs, of=of, first=first, centre=centre, spread=spread, smin=np.asarray(smin, float)[of],
                  moves=moves)


def staggered_errors(x, n: int) -> np.ndarray:
    """Per-run bounds (``n`` runs, or one for the scan) as bounds of the ``n + 1`` staggered
    runs: run ``i`` lies within plain runs ``i − 1`` and ``i``, so it takes the larger."""
    x = np.broadcast_to(np.asarray(x, float), (n,)) if np.ndim(x) == 0 else np.asarray(x, float)[:n]
    return np.concatenate([x[:1], np.maximum(x[:-1], x[1:]), x[-1:]])


def chunk_boxes(ch: Chunks, k: int, box: np.ndarray, a, err, lever: float) -> np.ndarray:
    """The robot boxes (m, 6) of scan ``k``'s chunks from its robot box ``box`` at the stamp:
    moved by each chunk's nominal move turned by the box's heading (its lever over the heading
    interval widened by ``a``, the turn's error: one for the scan, or one per chunk), widened by
    the chunk's spread, ``err`` (the move's error, likewise) and ``a`` times ``lever`` (the mount's lever
    turned by the nominal turn, whose move turns with the true heading); the heading widened by
    ``a``."""
    j0, j1 = int(ch.first[k]), int(ch.first[k + 1])
    cen = ch.centre[j0:j1]
    a = np.broadcast_to(np.asarray(a, float), (j1 - j0,)) if np.ndim(a) == 0 else np.asarray(a, float)[:j1 - j0]
    err = np.asarray(err, float) if np.ndim(err) == 0 else np.asarray(err, float)[:j1 - j0]
    tl, th = box[4] - a, box[5] + a
    tc = 0.5 * (tl + th)
    hw = 0.5 * (th - tl) * (1.0 + 1e-12) + 1e-15 * (1.0 + np.abs(tc))
    c, s = np.cos(tc), np.sin(tc)
    mx = c * cen[:, 0] - s * cen[:, 1]
    my = s * cen[:, 0] + c * cen[:, 1]
    grow = np.nextafter((np.hypot(cen[:, 0], cen[:, 1]) * np.minimum(hw, 2.0) + ch.spread[j0:j1] + err + a * lever)
                        * (1.0 + 1e-12)
                        + 1e-12 * (1.0 + abs(box[0]) + abs(box[1]) + abs(box[2]) + abs(box[3])), np.inf)
    out = np.empty((j1 - j0, 6))
    out[:, 0] = np.nextafter(box[0] + mx - grow, -np.inf)
    out[:, 1] = np.nextafter(box[1] + mx + grow, np.inf)
    out[:, 2] = np.nextafter(box[2] + my - grow, -np.inf)
    out[:, 3] = np.nextafter(box[3] + my + grow, np.inf)
    out[:, 4] = np.nextafter(tl, -np.inf)
    out[:, 5] = np.nextafter(th, np.inf)
    return out


def swept_box(box: np.ndarray, sweep) -> np.ndarray:
    """Robot boxes (..., 6) widened by ``sweep`` (..., 2) ``= (d, a)`` (how far the robot moves
    and turns while a scan's beams are taken), rounded outward; ``box`` itself when there is
    no sweep."""
    sw = np.asarray(sweep, float)
    if not np.any(sw > 0.0):
        return box
    d, a = sw[..., 0], sw[..., 1]
    w = np.stack([-d, d, -d, d, -a, a], axis=-1)
    out = np.asarray(box, float) + w
    out[..., 0::2] = np.where(w[..., 0::2] != 0.0, np.nextafter(out[..., 0::2], -np.inf), out[..., 0::2])
    out[..., 1::2] = np.where(w[..., 1::2] != 0.0, np.nextafter(out[..., 1::2], np.inf), out[..., 1::2])
    return out
