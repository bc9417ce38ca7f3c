"""The SIMD polar kernel against the truth (mpmath) and against the scalar reference kernel.

Truths are real points (mpmath, 120 bits) with float boxes built outward around them, so a
truth counted lost is lost; batches of boxes go through the kernel together so the chunked,
packed SIMD path is what is tested (most boxes lie in one open quadrant: the fast path).

Relation to the scalar kernel: the same rows emptied; no bound outside the scalar result beyond
the rounding tolerance of the Codac crosscheck (``bench_kernels._looser``: ulps of the scale plus
the tan-conditioning and ``rho^2 - dy^2`` cancellation terms); on the regular boxes no bound
outside it by more than ``1e-9`` of its width plus ``1e-12 (1 + |bound|)``; widths on average no
larger. (Near an axis the cancellation term is needed: a few boxes in 10^5 of the soundness mix
differ by ~1e-11 from the scalar kernel, whose pass takes atan each time.)
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from bench.bench_kernels import _looser, polar_truths, regular_polar_truths
from ivslam_cli.contractors import polar
from ivslam_cli.contractors.ctc_polar import polar_kernel
from ivslam_cli.contractors.ctc_polar_simd import (
    CH,
    CHUNK,
    CL,
    KD,
    PSH,
    PSL,
    QD,
    WROWS,
    _entry,
    _setup,
    _tan_at_least,
    _tan_at_most,
    polar_simd_kernel,
)
from ivslam_cli.contractors.simd_polar_lanes import BIG, UH, UL, VH, VL, _cos_sin
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


def _strictly_within(S, V, ok):
    """No bound of ``V`` outside ``S`` by more than ``1e-9`` of its width plus ``1e-12 (1 +
    |bound|)`` (rows ``ok``), per variable."""
    with np.errstate(invalid="ignore"):
        for j in range(4):
            s, v = S[j][ok], V[j][ok]
            ws = s[:, 1] - s[:, 0]
            scale = 1.0 + np.nan_to_num(np.abs(s), posinf=0.0, neginf=0.0).max(1)
            out = np.maximum(s[:, 0] - v[:, 0], v[:, 1] - s[:, 1])
            assert not np.any(out > 1e-9 * np.nan_to_num(ws, posinf=0.0) + 1e-12 * scale), j


@settings(max_examples=examples(ci=300))
@given(st.lists(point, min_size=1, max_size=80))
@example([(1.7701284233172415e-157, 1.0, 0, [0.0, 0.0, 0.0, 0.0, 1.401298464324817e-45, 0.0, 0.0, 0.0])])
@example([(1e-160, 0.5, 0, [0.0] * 8), (3e-151, -2.0, 1, [1e-170] * 8)])
@example([(1.526431104409758e-148, 1.0, 0, [0.0, 0.0, 0.0, 0.0, 6.420280742079504e-13, 0.0, 0.0, 0.0])])
@example([(4.422436230716104e-242, 1.0, 0, [0.0, 0.0, 6.50809621507267e-13, 3.4833030734159337e-13,
                                            2.223390066047704e-13, 0.0, 9.493832106531228e-07, 9.098446451930451e-07])])
def test_simd_never_looser_than_the_scalar_kernel(points):
    """Random boxes around random true points: the same rows emptied as ``polar_scalar``, no
    bound outside its result beyond rounding."""
    _, arrays = _truth_boxes(points)
    s = [a.copy() for a in arrays]
    v = [a.copy() for a in arrays]
    ok_s = polar_kernel(*s)
    ok_v = polar_simd_kernel(*v)
    assert np.array_equal(ok_s, ok_v)
    _, beyond = _looser(np.stack(v)[:, ok_s], np.stack(s)[:, ok_s])
    assert beyond == 0


finite = st.floats(-1e7, 1e7)
edge = st.sampled_from([0.0, -0.0, 1e-300, -1e-300, 1e300, -1e300, 2e300, math.inf, -math.inf,
                        math.nan, math.pi, -math.pi, 4.7, 1e6, -1e6])
bound = st.one_of(finite, edge, st.floats(-10.0, 10.0))


@settings(max_examples=examples(ci=300))
@given(st.lists(st.lists(bound, min_size=8, max_size=8), min_size=1, max_size=40))
def test_entry_is_setup(rows):
    """:func:`_entry`'s selects take the boxes :func:`_setup` takes, with its quadrant, offset,
    ``u``, ``v`` and ``psi``, bit for bit."""
    b = np.array([[sorted(r[0:2]), sorted(r[2:4]), sorted(r[4:6]), r[6:8]] for r in rows])
    flat = [np.ascontiguousarray(b[:, j]).reshape(-1) for j in range(4)]
    W = np.empty(WROWS * CHUNK)
    _entry(0, len(rows), *flat, W)
    C = CHUNK
    for k in range(len(rows)):
        xl, xh, yl, yh, rl, rh, tl, th = b[k].reshape(-1)
        f = _setup(xl, xh, yl, yh, max(rl, 0.0), rh, tl, th)
        assert (W[KD * C + k] == 1.0) == f[0], k
        if f[0]:
            got = (W[QD * C + k], W[CL * C + k], W[CH * C + k], W[UL * C + k], W[UH * C + k],
                   W[VL * C + k], W[VH * C + k], W[PSL * C + k], W[PSH * C + k])
            assert got == (f[1], f[3], f[4], f[5], f[6], f[7], f[8], f[9], f[10]), k


@settings(max_examples=examples(ci=300))
@given(st.one_of(st.floats(0.0, 1.6), st.sampled_from([0.0, 5e-324, 1e-300, 1e-8, 1.5, 1.5705])),
       st.floats(1e-3, 1e3), st.floats(-1e-3, 1e-3))
def test_tan_comparisons_are_sure_and_close(p, x, rel):
    """The series comparisons that decide which tan calls to skip are never wrong (mpmath), and
    decide (True) once ``y / x`` is ``1e-6`` (relative) past ``tan(p)`` for ``p <= 1.2``."""
    t = mpmath.tan(mpmath.mpf(p))
    for y in (float(t * x * (1 + rel)), float(t * x * (1 + 1e-6)), float(t * x * (1 - 1e-6))):
        if y > 0.0:
            if _tan_at_most(p, y, x):
                assert t <= mpmath.mpf(y) / mpmath.mpf(x)
            if _tan_at_least(p, y, x):
                assert t >= mpmath.mpf(y) / mpmath.mpf(x)
    if 1e-8 <= p <= 1.2:
        assert _tan_at_most(p, float(t * x * (1 + 1e-6)), x)
        assert _tan_at_least(p, float(t * x * (1 - 1e-6)), x)


@settings(max_examples=examples(ci=500))
@given(st.one_of(st.floats(0.0, 10.0), st.floats(0.0, BIG), st.floats(0.0, 1e-150),
                 st.sampled_from([0.0, -0.0, 5e-324, 1e-160, 1.0, 1e8, 1e75, BIG])))
def test_cos_sin_of_a_tangent_bound_hold_the_real_values(t):
    """The lane's cos and sin of ``psi = atan(t)`` (one sqrt, one quotient, ``1 ∓ 2^-50``) are on
    their sides of the real values (mpmath), and within ~1e-15 of them."""
    cl, ch, sl, sh = _cos_sin(t)
    with mpmath.workprec(2300):  # sin = t (1 - t^2 / 2 + ...) told apart from t for t ~ 2^-1074
        T = mpmath.mpf(t)
        c, s = 1 / mpmath.sqrt(1 + T * T), T / mpmath.sqrt(1 + T * T)
        assert mpmath.mpf(cl) <= c <= mpmath.mpf(ch)
        assert mpmath.mpf(sl) <= s <= mpmath.mpf(sh)
        assert t == 0.0 or mpmath.mpf(sl) < s
    assert ch - cl <= 1e-14 * float(c) and sh - sl <= 1e-14 * float(s) + 1e-320


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
    if gen is regular_polar_truths:
        _strictly_within(s, v, ok_s)
    with np.errstate(invalid="ignore"):
        for j in range(4):
            ws, wv = S[j, :, 1] - S[j, :, 0], V[j, :, 1] - V[j, :, 0]
            fin = np.isfinite(ws) & np.isfinite(wv)
            assert wv[fin].sum() <= ws[fin].sum() * (1 + 1e-9)


def test_fallback_rows_are_the_scalar_result_bit_for_bit():
    """Boxes off the fast path and off the pieces route (the origin with rho reaching 0,
    unbounded, wide theta) go through polar_scalar."""
    inf = np.inf
    rows = [
        [[-1.0, 1.0], [-1.0, 1.0], [0.0, 2.0], [-4.0, 4.0]],  # the origin
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
