"""The landmark boxes' grid refinement (``observations._grid_refine``): the q-relaxed
intersection of the candidates' unions of slice images keeps every point that at least
``m − q`` of them hold, and it narrows what the hulls alone give."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.slam.landmarks.observations import OBS_USED, _grid_refine
from tests.helpers.hyp import examples

G = 32


def _refine(box, cimg, q, status=None):
    m = cimg.shape[0]
    status = np.full(m, OBS_USED, np.int8) if status is None else status
    out = np.array(box, float)
    _grid_refine(out, 0, m, np.arange(m, dtype=np.int64), status, cimg, q, np.zeros((G, G), np.int64),
                 np.zeros((G, G), np.int64))
    return out


def _union_count(cimg, p):
    inside = ((cimg[..., 0, 0] <= p[0]) & (p[0] <= cimg[..., 0, 1]) & (cimg[..., 1, 0] <= p[1]) &
              (p[1] <= cimg[..., 1, 1]))
    return int(inside.any(axis=1).sum())


@settings(max_examples=examples(ci=200))
@given(seed=st.integers(0, 2**31 - 1), m=st.integers(1, 12), s=st.integers(1, 6), q=st.integers(0, 3),
       scale=st.sampled_from([1e-3, 1.0, 1e3]), off=st.sampled_from([0.0, 7.3, -1e4]))
def test_points_in_m_minus_q_unions_are_kept(seed, m, s, q, scale, off):
    rng = np.random.default_rng(seed)
    p = off + scale * rng.uniform(-1, 1, 2)  # the "true landmark"
    lo = p - scale * rng.uniform(0, 2, (m, s, 2))
    hi = p + scale * rng.uniform(0, 2, (m, s, 2))
    # most slices of an honest candidate miss the point: all but the first shifted away
    shift = scale * rng.uniform(-3, 3, (m, s, 2))
    shift[:, 0] = 0.0
    cimg = np.stack([lo + shift, hi + shift], axis=-1)  # (m, s, 2, 2)
    bad = rng.random(m) < 0.3  # outliers: their whole union away from the point
    cimg[bad] += 5 * scale
    box = np.array([[cimg[..., 0, 0].min(), cimg[..., 0, 1].max()], [cimg[..., 1, 0].min(), cimg[..., 1, 1].max()]])
    out = _refine(box, cimg, q)
    assert np.all(out[:, 0] >= box[:, 0]) and np.all(out[:, 1] <= box[:, 1])  # never wider
    in_box = box[0, 0] <= p[0] <= box[0, 1] and box[1, 0] <= p[1] <= box[1, 1]
    if in_box and _union_count(cimg, p) >= m - q:
        assert out[0, 0] <= p[0] <= out[0, 1] and out[1, 0] <= p[1] <= out[1, 1]
    # every sampled point that m − q unions hold is kept
    for x in rng.uniform(box[:, 0], box[:, 1], (40, 2)):
        if _union_count(cimg, x) >= m - q:
            assert out[0, 0] <= x[0] <= out[0, 1] and out[1, 0] <= x[1] <= out[1, 1]


def test_unions_meet_where_their_hulls_do_not_tell():
    """Two candidates whose hulls are the same square: an L of two slice images (bottom and
    left edges) and a band (the left third); their unions meet in the band only."""
    a = np.array([[[0.0, 1.0], [0.0, 0.1]], [[0.0, 0.1], [0.0, 1.0]]])  # bottom and left edges
    c = np.array([[[0.0, 0.3], [0.0, 1.0]], [[0.0, 0.3], [0.0, 1.0]]])  # left third
    out = _refine([[0.0, 1.0], [0.0, 1.0]], np.stack([a, c]), 0)
    assert out[0, 1] < 0.4 and out[0, 0] == 0.0
    # with q = 1 one candidate may be the outlier: nothing is cut
    out = _refine([[0.0, 1.0], [0.0, 1.0]], np.stack([a, c]), 1)
    assert np.array_equal(out, [[0.0, 1.0], [0.0, 1.0]])


def test_rejected_observations_are_left_out():
    a = np.array([[[0.0, 0.3], [0.0, 1.0]]])
    far = np.array([[[0.7, 1.0], [0.0, 1.0]]])
    cimg = np.stack([a, far])
    status = np.array([OBS_USED, 1], np.int8)
    out = _refine([[0.0, 1.0], [0.0, 1.0]], cimg, 0, status)
    assert out[0, 1] < 0.4
