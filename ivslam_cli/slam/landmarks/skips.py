"""Skip edges of the landmark CSP: the motion between two observation frames as one increment.

The sweeps (:mod:`.kernel`) carry a contraction from node to node through the motion steps,
and each node's set keeps only one box per heading slice: the relation between two poses
several steps apart is the chain of those hulls. The composed increment between them
(:func:`.observations.compose_range`, outward rounding: it holds every composition of the
steps' increments) keeps it whole. Each observation frame (a node with observations) is
linked to the frames ``2, 4, …, 2^levels`` frames later on its chain, and to the next frame
when nodes without observations lie between them; in the sweeps each edge contracts its two
sets slice pair by slice pair like a motion step (:func:`skip_sets`). It holds under the
motion bounds every run already assumes: nothing new is assumed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ivslam_cli.slam.landmarks.observations import compose_range
from ivslam_cli.slam.landmarks.pose_sets import _commit, _set_empty_slices, increment_pairs, live_slices

LIVE_MAX = 0.125  # an edge waits while both its sets have live slices over more than this share of the circle


@dataclass
class Skips:
    """Edge ``e`` links nodes ``a[e] < b[e]`` of a chain (sorted by ``b``) by the increment
    ``R[e]`` (rows ``ρ, α, δθ``: node ``b`` in the frame of node ``a``); ``in_off`` (N + 1)
    the run of each node's edges from earlier nodes, ``out`` the edges sorted by ``a`` and
    ``out_off`` their runs."""

    a: np.ndarray
    b: np.ndarray
    R: np.ndarray
    in_off: np.ndarray
    out: np.ndarray
    out_off: np.ndarray

    @property
    def count(self) -> int:
        return int(self.a.size)


def skip_edges(frames: np.ndarray, chain_of: np.ndarray, U: np.ndarray, levels: int) -> Skips:
    """The skip edges between the observation ``frames`` (sorted node indices) of each chain
    (see the module docstring); ``levels = 0``: none."""
    n = chain_of.shape[0]
    frames = np.asarray(frames, np.int64)
    firsts, seconds = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    if levels > 0:
        for s in [1] + [2**i for i in range(1, levels + 1)]:
            a, b = frames[:-s], frames[s:]
            ok = chain_of[a] == chain_of[b]
            if s == 1:
                ok &= b - a > 1  # consecutive nodes: the motion step itself
            firsts.append(a[ok])
            seconds.append(b[ok])
    a, b = np.concatenate(firsts), np.concatenate(seconds)
    order = np.lexsort((a, b))
    a, b = a[order].astype(np.int64), b[order].astype(np.int64)
    R = np.empty((a.size, 3, 2))
    compose_edges(U, a, b, R)
    out = np.argsort(a, kind="stable").astype(np.int64)
    return Skips(a, b, R, np.searchsorted(b, np.arange(n + 1)).astype(np.int64), out,
                 np.searchsorted(a[out], np.arange(n + 1)).astype(np.int64))


@njit(cache=True)
def compose_edges(U, a, b, R):
    """``R[e]`` ⊇ the composition of the steps from node ``a[e]`` to node ``b[e]``."""
    for e in range(a.shape[0]):
        compose_range(U, a[e], b[e], R[e])


@njit(cache=True)
def skip_sets(PS, H, e, sa, sb, R, accA, accC, h_lo, h_hi, ver, done, clock):
    """Contract the sets of nodes ``sa[e]`` and ``sb[e]`` with edge ``e`` (as :func:`step_sets`
    does with a motion step); False (nothing written) if no slice pair has a solution. Skipped
    when neither set changed since the edge last ran (``done``), and while both sets have live
    slices over more than ``LIVE_MAX`` of the circle (a heading lost: every slice against many,
    slow, and little to gain)."""
    a = sa[e]
    b = sb[e]
    if ver[a] <= done[e] and ver[b] <= done[e]:
        return True
    most = LIVE_MAX * PS.shape[1] + 1  # + 1: a narrow heading across a slice border
    if live_slices(PS, a) > most and live_slices(PS, b) > most:
        done[e] = clock[0]
        return True
    _set_empty_slices(accA)
    _set_empty_slices(accC)
    if not increment_pairs(PS, a, b, (R[e, 0, 0], R[e, 0, 1], R[e, 1, 0], R[e, 1, 1], R[e, 2, 0], R[e, 2, 1]),
                           accA, accC):
        done[e] = clock[0]
        return False
    _commit(PS, H, a, accA, h_lo, h_hi, ver, clock)
    _commit(PS, H, b, accC, h_lo, h_hi, ver, clock)
    done[e] = clock[0]
    return True
