"""Relative pose constraints (``slam/landmarks/relative.py``): the pieces of a pair of nodes
hold every relative pose the observations and the chain allow (brute force over sampled worlds),
with at most ``q`` of the common landmarks broken, and pin it when the observations are exact."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.slam.landmarks.relative import MAX_PIECES, observation_vectors, pair_pieces
from tests.helpers.hyp import examples


def _edge(rng, size=None):
    """±1, or (one time in four) uniform in between."""
    e = rng.choice([-1.0, 1.0], size)
    return np.where(rng.random(size) < 0.25, rng.uniform(-1, 1, size), e)


def _world(rng, n, bad, noise, lag=0.0):
    """Two true poses, ``n`` landmarks, their observations from both (``bad`` of them gross
    outliers at one node), the intervals, the reaches (``lag``: the modelled poses within
    ``lag`` m, ``lag / 2`` rad of the true ones) and the modelled relative pose. Errors and
    offsets at the ends of their bounds (the hardest case for an enclosure)."""
    pk = np.array([*rng.uniform(-5, 5, 2), rng.uniform(-math.pi, math.pi)])
    pl = np.array([*pk[:2] + rng.uniform(-3, 3, 2), pk[2] + rng.uniform(-1.5, 1.5)])
    m = pk[:2] + rng.uniform(-8, 8, (n, 2))
    rho = np.empty((2 * n, 2))
    alpha = np.empty((2 * n, 2))
    reach = np.zeros((2 * n, 2))
    reach[:, 0], reach[:, 1] = lag, lag / 2
    for s, p in enumerate((pk, pl)):
        for c in range(n):
            j = s * n + c
            r = float(np.hypot(*(m[c] - p[:2]))) + noise * 0.1 * _edge(rng)
            a = math.atan2(m[c, 1] - p[1], m[c, 0] - p[0]) - p[2] + noise * 0.02 * _edge(rng)
            rho[j] = [max(r - 0.1 * noise - 1e-9, 0.0), r + 0.1 * noise + 1e-9]
            alpha[j] = [a - 0.02 * noise - 1e-9, a + 0.02 * noise + 1e-9]
    for c in rng.choice(n, bad, replace=False):  # outliers: anywhere
        j = n + c if rng.random() < 0.5 else c
        rho[j] += rng.uniform(1, 5)
        alpha[j] += rng.uniform(-3, 3)
    pk = pk + lag * _edge(rng, 3) * [1, 1, 0.5]  # the modelled poses
    pl = pl + lag * _edge(rng, 3) * [1, 1, 0.5]
    ck, sk = math.cos(pk[2]), math.sin(pk[2])
    dx, dy = pl[:2] - pk[:2]
    d = np.array([ck * dx + sk * dy, -sk * dx + ck * dy])
    return rho, alpha, reach, d, pl[2] - pk[2]


def _pieces(rho, alpha, reach, n, q, chain):
    vi = np.empty((n, 2, 2))
    rj = np.empty((n, 2))
    aj = np.empty((n, 2))
    e = np.empty(n)
    observation_vectors(np.arange(n), np.arange(n, 2 * n), rho, alpha, reach, vi, rj, aj, e)
    out = np.empty((MAX_PIECES, 3, 2))
    g = pair_pieces(chain, vi, rj, aj, e, q, 1e-3, out)
    return out[:g]


def _inside(pieces, d, dth):
    for p in pieces:
        k = np.round((0.5 * (p[2, 0] + p[2, 1]) - dth) / (2 * math.pi))
        t = dth + 2 * math.pi * k
        if p[0, 0] <= d[0] <= p[0, 1] and p[1, 0] <= d[1] <= p[1, 1] and p[2, 0] <= t <= p[2, 1]:
            return True
    return False


@settings(max_examples=examples(ci=300))
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 5), q=st.integers(0, 2), circle=st.booleans(),
       lag=st.sampled_from([0.0, 0.05, 0.3]))
def test_the_true_relative_pose_is_in_a_piece(seed, n, q, circle, lag):
    rng = np.random.default_rng(seed)
    bad = int(rng.integers(0, min(q, n) + 1))
    rho, alpha, reach, d, dth = _world(rng, n, bad, 1.0, lag)
    if circle:
        chain = np.array([[-1e9, 1e9], [-1e9, 1e9], [-10.0, 10.0]])
    else:
        w = rng.uniform(0.01, 0.5, 3)
        chain = np.array([[d[0] - w[0], d[0] + w[0]], [d[1] - w[1], d[1] + w[1]], [dth - w[2], dth + w[2]]])
    pieces = _pieces(rho, alpha, reach, n, q, chain)
    assert pieces.shape[0] >= 1 and _inside(pieces, d, dth)


def test_exact_observations_of_three_landmarks_pin_the_relative_pose():
    rng = np.random.default_rng(5)
    for _ in range(20):
        rho, alpha, reach, d, dth = _world(rng, 3, 0, 0.0)
        chain = np.array([[-1e9, 1e9], [-1e9, 1e9], [-4.0, 4.0]])
        pieces = _pieces(rho, alpha, reach, 3, 0, chain)
        assert _inside(pieces, d, dth)
        assert pieces[:, 2, 1].max() - pieces[:, 2, 0].min() < 0.01
        assert max(pieces[:, 0, 1].max() - pieces[:, 0, 0].min(), pieces[:, 1, 1].max() - pieces[:, 1, 0].min()) < 0.1
