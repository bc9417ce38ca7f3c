"""The LiDAR pipeline's trajectory kernels: dead reckoning, the backward pass, box meets."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.slam.landmarks.kernel import INCREMENT
from ivslam_cli.interval.pose import meet_or_keep
from ivslam_cli.slam.motion_kernel import dead_reckon, meet_node, smooth_backward
from tests.helpers.hyp import examples


def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def _inside(P, truth) -> np.ndarray:
    xy = np.all((P[:, :2, 0] <= truth[:, :2]) & (truth[:, :2] <= P[:, :2, 1]), axis=1)
    th = P[:, 2, 0] + np.mod(truth[:, 2] - P[:, 2, 0], 2 * math.pi)
    return xy & (th <= P[:, 2, 1])


def _trajectory(seed: int, n: int, err: float):
    """True poses, measured increments U (range, bearing, turn) within ±err (±err/4 rad), P with
    only the first node bounded."""
    rng = np.random.default_rng(seed)
    truth = np.zeros((n, 3))
    for k in range(1, n):
        v, w = rng.uniform(0.1, 0.5), rng.uniform(-0.4, 0.4)
        th = truth[k - 1, 2]
        truth[k] = truth[k - 1] + [v * math.cos(th), v * math.sin(th), w]
    d = np.diff(truth, axis=0)
    rho = np.hypot(d[:, 0], d[:, 1])
    alpha = _wrap(np.arctan2(d[:, 1], d[:, 0]) - truth[:-1, 2])
    U = np.empty((n - 1, 3, 2))
    for j, (val, e) in enumerate(((rho, err), (alpha, err / 4), (d[:, 2], err / 4))):
        c = val + rng.uniform(-e, e, val.shape)  # measured within the bound
        U[:, j, 0], U[:, j, 1] = c - e - 1e-12, c + e + 1e-12
    P = np.empty((n, 3, 2))
    P[:, :, 0], P[:, :, 1] = -np.inf, np.inf
    P[0, :, 0], P[0, :, 1] = truth[0] - 1e-3, truth[0] + 1e-3
    return truth, np.full(n - 1, INCREMENT, np.int64), U, P


@given(st.integers(0, 2**31 - 1), st.integers(4, 40), st.floats(0.005, 0.05))
@settings(max_examples=examples(ci=300))
def test_backward_pass_keeps_the_truth_and_carries_a_contraction_back(seed, n, err):
    truth, kind, U, P = _trajectory(seed, n, err)
    events = np.zeros(n - 1, np.int64)
    dead_reckon(P, kind, U, events)
    assert events.sum() == 0 and _inside(P, truth).all()
    fwd = P.copy()
    # a contraction at the last node (as the map gives): the truth within ±1 cm / 0.005 rad
    t = truth[-1]
    box = np.array([t[0] - 0.01, t[0] + 0.01, t[1] - 0.01, t[1] + 0.01, t[2] - 0.005, t[2] + 0.005])
    assert meet_node(P, n - 1, box, 0.0, 0.0)
    smooth_backward(P, kind, U, events, n - 1)
    assert events.sum() == 0
    assert _inside(P, truth).all()
    w = lambda B: (B[:, 0, 1] - B[:, 0, 0]) + (B[:, 1, 1] - B[:, 1, 0])  # noqa: E731
    assert np.all(w(P) <= w(fwd) + 1e-9)
    # the node before the contracted one is narrower than dead reckoning left it
    if w(fwd)[n - 2] > 0.2:
        assert w(P)[n - 2] < w(fwd)[n - 2]


def test_meet_or_keep_meets_headings_as_angles_and_keeps_a_on_empty():
    a = np.array([[0.0, 1.0, 0.0, 1.0, 3.0, 3.4], [0.0, 1.0, 0.0, 1.0, 0.0, 0.1]])
    b = np.array([[0.5, 2.0, -1.0, 0.5, 3.2 - 2 * math.pi, 3.3 - 2 * math.pi], [2.0, 3.0, 0.0, 1.0, 0.0, 0.1]])
    out = np.empty_like(a)
    assert meet_or_keep(a.reshape(-1, 3, 2), b.reshape(-1, 3, 2), out.reshape(-1, 3, 2)) == 1
    assert out[0, :4].tolist() == [0.5, 1.0, 0.0, 0.5]
    lo, hi = out[0, 4:]
    assert hi - lo <= 0.1 + 1e-9 and (lo <= 3.2 <= hi or lo <= 3.2 - 2 * math.pi <= hi)
    assert out[1].tolist() == a[1].tolist()
