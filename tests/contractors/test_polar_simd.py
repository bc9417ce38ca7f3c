"""The SIMD polar kernel against the truth (mpmath) and against the scalar reference kernel.

Truths are real points (mpmath, 120 bits) with float boxes built outward around them, so a
truth counted lost is lost; batches of boxes go through the kernel together so the chunked,
packed SIMD path is what is tested (most boxes lie in one open quadrant: the fast path).
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.bench_kernels import _looser, polar_truths, regular_polar_truths
from ivslam_cli.contractors import polar
from ivslam_cli.contractors.ctc_polar import polar_kernel
from ivslam_cli.contractors.ctc_polar_simd import CHUNK, _setup, polar_simd_kernel
from tests.helpers.hyp import examples
from tests.helpers.exact import around

mpmath.mp.prec = 120
spread = st.one_of(st.just(0.0), st.floats(0.0, 1e-12), st.floats(0.0, 1e-6), st.floats(0.0, 0.5),
                   st.floats(0.0, 20.0))
point = st.tuples(
    st.one_of(st.floats(1e-6, 1e-3), st.floats(0.0, 100.0), st.floats(1e4, 1e6)),
    st.one_of(st.floats(-math.pi, math.pi),
              st.sampled_from([math.pi, -math.pi, 0.0, math.pi / 2, -math.pi / 2, 1e-12, -1e-12])),
    st.integers(-3, 3),
    st.lists(spread, min_size=8, max_size=8),
)


def _truth_boxes(points):
    truths, rows = [], []
    for rho, theta, branch, m in points:
        R, T = mpmath.mpf(rho), mpmath.mpf(theta)
        X, Y = R * mpmath.cos(T), R * mpmath.sin(T)
        t_real = T + 2 * branch * mpmath.pi
        truths.append((X, Y, R, t_real))
        rows.append([around(X, m[0], m[1]), around(Y, m[2], m[3]), around(R, m[4], m[5]),
                     around(t_real, m[6], m[7])])
    b = np.array(rows)  # (n, 4, 2)
    return truths, [np.ascontiguousarray(b[:, j]) for j in range(4)]


@settings(max_examples=examples(ci=300))
@given(st.lists(point, min_size=1, max_size=80))
def test_simd_never_loses_the_truth(points):
    truths, arrays = _truth_boxes(points)
    before = [a.copy() for a in arrays]
    ok = polar_simd_kernel(*arrays)
    assert ok.all()
    for k, truth in enumerate(truths):
        for j in range(4):
            assert mpmath.mpf(arrays[j][k, 0]) <= truth[j] <= mpmath.mpf(arrays[j][k, 1]), (k, j)
            assert arrays[j][k, 0] >= before[j][k, 0] and arrays[j][k, 1] <= before[j][k, 1]


def test_most_boxes_take_the_fast_path():
    boxes, _ = regular_polar_truths(5000, seed=3)
    fast = sum(_setup(b[0][k, 0], b[0][k, 1], b[1][k, 0], b[1][k, 1], b[2][k, 0], b[2][k, 1],
                      b[3][k, 0], b[3][k, 1])[0]
               for b in [boxes] for k in range(5000))
    assert fast > 0.8 * 5000


@pytest.mark.parametrize("gen, n", [(regular_polar_truths, 200_000), (polar_truths, 200_000)])
def test_simd_against_the_scalar_reference(gen, n):
    """Over many boxes: no truth lost; same rows emptied; never looser than the scalar kernel
    beyond the rounding tolerance of the Codac crosscheck, and as tight on average."""
    boxes, truth = gen(n, seed=21)
    s = [b.copy() for b in boxes]
    v = [b.copy() for b in boxes]
    ok_s = polar_kernel(*s)
    ok_v = polar_simd_kernel(*v)
    for b, (val, e) in zip(v, truth):
        assert not np.any((b[:, 0] > val + e) | (b[:, 1] < val - e))
    assert np.array_equal(ok_s, ok_v)
    S, V = np.stack(s)[:, ok_s], np.stack(v)[:, ok_v]
    _, beyond = _looser(V, S)
    assert beyond == 0
    with np.errstate(invalid="ignore"):
        for j in range(4):
            ws, wv = S[j, :, 1] - S[j, :, 0], V[j, :, 1] - V[j, :, 0]
            fin = np.isfinite(ws) & np.isfinite(wv)
            assert wv[fin].sum() <= ws[fin].sum() * (1 + 1e-9)


def test_fallback_rows_are_the_scalar_result_bit_for_bit():
    """Boxes off the fast path (origin, axes, unbounded, wide theta) go through polar_scalar."""
    inf = np.inf
    rows = [
        [[-1.0, 1.0], [-1.0, 1.0], [0.0, 2.0], [-4.0, 4.0]],  # the origin
        [[0.0, 1.0], [0.5, 1.0], [0.0, 2.0], [0.0, 2.0]],  # on an axis
        [[-inf, inf], [1.0, 2.0], [0.0, 3.0], [0.0, 3.0]],  # unbounded
        [[1.0, 2.0], [1.0, 2.0], [0.0, 5.0], [-10.0, 10.0]],  # theta wider than 3 pi / 2
        [[1.0, 2.0], [1.0, 2.0], [0.0, 5.0], [1e7, 1e7 + 1]],  # theta far out
    ]
    b = np.array(rows)
    s = [np.ascontiguousarray(b[:, j]) for j in range(4)]
    v = [a.copy() for a in s]
    for k in range(len(rows)):
        assert not _setup(*[x for a in s for x in a[k]])[0]
    ok_s = polar_kernel(*s)
    ok_v = polar_simd_kernel(*v)
    assert np.array_equal(ok_s, ok_v)
    for a, c in zip(s, v):
        assert np.array_equal(a, c)


def test_inconsistent_boxes_are_emptied_and_chunks_pack():
    """More than a chunk of boxes, some without a solution (rho far from |(dx, dy)|): those are
    emptied, the others keep their truth whatever their neighbours in the chunk."""
    rng = np.random.default_rng(5)
    n = 3 * CHUNK + 17
    r = rng.uniform(1, 10, n)
    t = rng.uniform(-3, 3, n)
    x, y = r * np.cos(t), r * np.sin(t)
    bad = rng.random(n) < 0.3
    rr = np.where(bad, r + 1.0, r)  # a rho box that misses the point's norm
    e = 1e-9
    arrays = [np.c_[x - e, x + e], np.c_[y - e, y + e], np.c_[rr - e, rr + e], np.c_[t - e, t + e]]
    arrays = [np.ascontiguousarray(a) for a in arrays]
    ok = polar_simd_kernel(*arrays)
    assert np.array_equal(ok, ~bad)
    assert np.all(np.isinf(arrays[0][bad]))
    for a, val in zip(arrays, (x, y, r, t)):
        assert np.all((a[~bad, 0] <= val[~bad] + 1e-12) & (a[~bad, 1] >= val[~bad] - 1e-12))


def test_public_polar_is_the_simd_kernel():
    boxes, _ = regular_polar_truths(1000, seed=8)
    a = [b.copy() for b in boxes]
    c = [b.copy() for b in boxes]
    polar(*a)
    polar_simd_kernel(*c)
    for x, y in zip(a, c):
        assert np.array_equal(x, y)
