"""The motion steps of the landmark CSP: nodes where the CSP needs them, the odometry between
two nodes composed into one pose increment.

With twist odometry the held twist changes many times a second (MRCLAM logs a command at
60 Hz), and a node at every change is a node the sweeps visit for nothing. Nodes are put at
the events (observation stamps), the first and last odometry stamps and every ``max_step``
seconds in between; the exact steps between twist changes (:func:`motion.motion_steps`, each
enclosing every unicycle path within the twist bounds) are composed into the increment
between two nodes, in the frame of the first (:func:`compose_increments`, interval
arithmetic: the composed increment holds every composition of the pieces' increments).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ivslam_cli.interval.angles import arg_box
from ivslam_cli.interval.arith import add, cos, mul, sin, sqr, sqrt
from ivslam_cli.slam.motion import MotionBounds, motion_steps, subdivide


@njit(cache=True)
def compose_increments(U, starts, out):
    """``out[c]`` ⊇ the composition of the increments ``U[starts[c]:starts[c + 1]]`` (rows
    ``ρ, α, δθ`` of each, in the frame of its start): the displacement from the first piece's
    start to the last one's end, as ``(ρ, α)`` in the frame of the first, and the summed
    rotation. Outward rounding throughout."""
    for c in range(starts.shape[0] - 1):
        xl, xh, yl, yh, tl, th = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        for f in range(starts[c], starts[c + 1]):
            pl, ph = add(tl, th, U[f, 1, 0], U[f, 1, 1])
            cl, ch = cos(pl, ph)
            sl, sh = sin(pl, ph)
            xl, xh = add(xl, xh, *mul(U[f, 0, 0], U[f, 0, 1], cl, ch))
            yl, yh = add(yl, yh, *mul(U[f, 0, 0], U[f, 0, 1], sl, sh))
            tl, th = add(tl, th, U[f, 2, 0], U[f, 2, 1])
        rl, rh = sqrt(*add(*sqr(xl, xh), *sqr(yl, yh)))
        al, ah = arg_box(xl, xh, yl, yh)
        out[c, 0, 0], out[c, 0, 1] = rl, rh
        out[c, 1, 0], out[c, 1, 1] = al, ah
        out[c, 2, 0], out[c, 2, 1] = tl, th


@dataclass
class Steps:
    """Nodes and steps of one robot's chain (see :class:`motion.MotionSteps`): ``node_stamp``
    (N,), ``U`` (N−1, 5, 2), ``step_travel`` (N−1,) upper bounds of each step's displacement,
    ``step_dth`` (N−1, 2) its rotation, ``lag`` (N, 2), ``node`` and ``reach`` of each event."""

    motion: str
    node_stamp: np.ndarray
    U: np.ndarray
    step_travel: np.ndarray
    step_dth: np.ndarray
    lag: np.ndarray
    node: np.ndarray
    reach: np.ndarray


def chain_steps(odo, bounds: MotionBounds, events: np.ndarray, max_step: float, path: str = "") -> Steps:
    """The nodes and steps of one chain with events at stamps ``events`` (sorted, within the
    odometry's span). Twist odometry: nodes at the events, the ends and every ``max_step``
    seconds, the twist pieces in between composed; pose increments: the odometry's own
    stamps, events attached to the nearer one (:func:`motion.motion_steps`)."""
    t = np.asarray(odo.stamp, float)
    if odo.twist is None:
        m = motion_steps(odo, bounds, events, prefer="twist", max_step=max_step, path=path)
        return Steps(m.motion, m.node_stamp, m.U, m.step_travel, m.step_dth, m.lag, m.node, m.reach)
    coarse = subdivide(np.unique(np.concatenate([[t[0], t[-1]], events])), max_step)
    fine = motion_steps(odo, bounds, coarse, prefer="twist", max_step=max_step, path=path)
    starts = np.searchsorted(fine.node_stamp, coarse).astype(np.int64)
    if not np.array_equal(fine.node_stamp[starts], coarse):  # pragma: no cover - motion_steps keeps event stamps
        raise AssertionError("the fine nodes miss a coarse node")
    U = np.zeros((coarse.size - 1, 5, 2))
    compose_increments(fine.U, starts, U)
    node = np.searchsorted(coarse, events).astype(np.int64)
    lag = fine.lag[starts]
    return Steps("twist", coarse, U, U[:, 0, 1].copy(), U[:, 2].copy(), lag, node,
                 np.ascontiguousarray(lag[node]))
