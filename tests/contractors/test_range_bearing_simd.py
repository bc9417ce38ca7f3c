"""The SIMD range-bearing kernel against the truth (mpmath) and against the scalar reference.

Truths are real points (mpmath, 120 bits) with float boxes built outward around them, so a truth
counted lost is lost; boxes go through the kernel in batches, so the chunked, packed lanes (and
the quadrant pieces of boxes on an axis) are what is tested.

Relation to the scalar kernel (checked on the bench's mix): the same rows emptied, and no bound
outside the scalar result by more than ``1e-9`` of its width plus ``1e-12 (1 + |bound|)``
(rounding); on average tighter (the pieces and the fused fixpoint).
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.bench_kernels import _lost, range_bearing_truths
from ivslam_cli.contractors import range_bearing
from ivslam_cli.contractors.ctc_range_bearing import range_bearing_kernel
from ivslam_cli.contractors.ctc_range_bearing_simd import CHUNK, range_bearing_simd_kernel
from ivslam_cli.contractors.simd_quadrants import _meet, _meet3
from ivslam_cli.interval.angles import angle_meet
from tests.helpers.exact import around
from tests.helpers.hyp import examples

mpmath.mp.prec = 120
INF = math.inf
spread = st.one_of(st.just(0.0), st.floats(0.0, 1e-12), st.floats(0.0, 1e-6), st.floats(0.0, 0.5),
                   st.floats(0.0, 20.0))
coord = st.one_of(st.floats(-100.0, 100.0), st.sampled_from([0.0, 1.0, -1.0]))
point = st.tuples(
    st.lists(coord, min_size=4, max_size=4),  # sx, sy, mx, my
    st.one_of(st.floats(-math.pi, math.pi), st.sampled_from([math.pi, -math.pi, 0.0, math.pi / 2])),
    st.integers(-2, 2), st.integers(-2, 2),  # branches of sth and alpha
    st.lists(spread, min_size=14, max_size=14),
)


def _truth_boxes(points):
    truths, rows = [], []
    for (sx, sy, mx, my), sth, ks, ka, m in points:
        if sx == mx and sy == my:
            mx += 1.0  # the landmark on the robot: no bearing to check
        SX, SY, MX, MY, ST = (mpmath.mpf(v) for v in (sx, sy, mx, my, sth))
        R = mpmath.sqrt((MX - SX) ** 2 + (MY - SY) ** 2)
        STb = ST + 2 * ks * mpmath.pi
        A = mpmath.atan2(MY - SY, MX - SX) - ST + 2 * ka * mpmath.pi
        t = (SX, SY, STb, MX, MY, R, A)
        truths.append(t)
        rows.append([around(v, m[2 * j], m[2 * j + 1]) for j, v in enumerate(t)])
    b = np.array(rows)  # (n, 7, 2)
    arrays = [np.ascontiguousarray(b[:, j]) for j in range(7)]
    arrays[5][:, 0] = np.maximum(arrays[5][:, 0], 0.0)
    return truths, arrays


@settings(max_examples=examples(ci=200))
@given(st.lists(point, min_size=1, max_size=60))
def test_simd_never_loses_the_truth(points):
    truths, arrays = _truth_boxes(points)
    before = [a.copy() for a in arrays]
    ok = range_bearing_simd_kernel(*arrays)
    assert ok.all()
    for k, truth in enumerate(truths):
        for j in range(7):
            assert mpmath.mpf(arrays[j][k, 0]) <= truth[j] <= mpmath.mpf(arrays[j][k, 1]), (k, j)
            assert arrays[j][k, 0] >= before[j][k, 0] and arrays[j][k, 1] <= before[j][k, 1]


def test_simd_against_the_scalar_reference():
    boxes, truth = range_bearing_truths(40_000, seed=21)
    s = [b.copy() for b in boxes]
    v = [b.copy() for b in boxes]
    ok_s = range_bearing_kernel(*s)
    ok_v = range_bearing_simd_kernel(*v)
    for b, (val, e) in zip(v, truth):
        assert not np.any(_lost(b, val, e))
    assert np.array_equal(ok_s, ok_v)
    with np.errstate(invalid="ignore"):
        for j in range(7):
            S, V = s[j][ok_s], v[j][ok_s]
            ws, wv = S[:, 1] - S[:, 0], V[:, 1] - V[:, 0]
            scale = 1.0 + np.nan_to_num(np.abs(S), posinf=0.0, neginf=0.0).max(1)
            out = np.maximum(S[:, 0] - V[:, 0], V[:, 1] - S[:, 1])
            assert not np.any(out > 1e-9 * np.nan_to_num(ws, posinf=0.0) + 1e-12 * scale), j
            fin = np.isfinite(ws) & np.isfinite(wv)
            assert wv[fin].sum() <= ws[fin].sum() * (1 + 1e-9)


@settings(max_examples=examples(ci=300))
@given(st.floats(-20, 20), st.floats(0, 8), st.floats(-20, 20), st.floats(0, 8))
def test_meet_is_angle_meet_bit_for_bit(tl, tw, al, aw):
    ref = angle_meet(tl, tl + tw, al, al + aw)
    assert _meet(tl, tl + tw, al, al + aw) == ref
    lo, hi, ok = _meet3(tl, tl + tw, al, al + aw)
    assert ok == (((tl + tw) - tl) + ((al + aw) - al) < 6.0)
    if ok:
        assert (lo, hi) == ref or (not lo <= hi and not ref[0] <= ref[1])


def _rows(*rows):
    b = np.array(rows, dtype=float)
    return [np.ascontiguousarray(b[:, j]) for j in range(7)]


def test_empty_and_inconsistent_rows_are_emptied():
    """An empty input variable, a range that misses |m - s|, a bearing that misses the
    landmark: emptied (every variable ``[+inf, -inf]``), the neighbours untouched by it."""
    good = [[0, 0], [0, 0], [0, 0], [3, 3], [4, 4], [4.9, 5.1], [0.9, 1.0]]
    rows = [good, [[1, 0]] + good[1:], good[:5] + [[6, 7], good[6]],
            good[:6] + [[-0.5, 0.5]], good, [[0, 0], [0, 0], [0, 0], [3, 3], [4, 4], [4.9, 5.1],
                                             [np.nan, 1.0]]]
    arrays = _rows(*rows)
    ok = range_bearing_simd_kernel(*arrays)
    assert ok.tolist() == [True, False, False, False, True, False]
    for a in arrays:
        assert np.all(a[~ok, 0] == INF) and np.all(a[~ok, 1] == -INF)
    assert arrays[5][0, 0] <= 5.0 <= arrays[5][0, 1]


def test_across_the_cut_both_sides_survive():
    """Landmark behind the robot on the ±pi cut (dy straddles 0, dx < 0): the bearings near
    -pi and near pi are both kept (the hull around pi in alpha's own branch)."""
    arrays = _rows([[0, 0], [0, 0], [0, 0], [-5, -5], [-0.1, 0.1], [0, INF], [-4, 4]],
                   [[0, 0], [0, 0], [0, 0], [-5, -5], [-0.1, 0.1], [0, INF], [2, 5]])
    assert range_bearing_simd_kernel(*arrays).all()
    a = math.atan2(0.1, -5.0)
    np.testing.assert_allclose(arrays[6][0], [a - 2 * math.pi, 2 * math.pi - a], rtol=1e-12)
    np.testing.assert_allclose(arrays[6][1], [a, 2 * math.pi - a], rtol=1e-12)
    assert arrays[6][1, 0] <= math.pi <= arrays[6][1, 1]


def test_on_the_axes_and_at_pi():
    """Landmark straight ahead, behind, left, right (dx or dy exactly 0): the true bearing kept."""
    for mx, my in ((5, 0), (-5, 0), (0, 5), (0, -5)):
        t = math.atan2(my, mx)
        arrays = _rows([[0, 0], [0, 0], [-10, 10], [mx, mx], [my, my], [5, 5], [0.29, 0.31]])
        assert range_bearing_simd_kernel(*arrays).all()
        lo, hi = arrays[2][0]
        ks = [k for k in range(-3, 4) if lo <= t - 0.3 + 2 * k * math.pi <= hi]
        assert ks and hi - lo < 2 * math.pi * (max(ks) - min(ks)) + 0.03


def test_chunks_pack_and_public_function_is_the_simd_kernel():
    boxes, truth = range_bearing_truths(3 * CHUNK + 17, seed=5)
    a = [b.copy() for b in boxes]
    c = [b.copy() for b in boxes]
    ok = range_bearing(*a)
    range_bearing_simd_kernel(*c)
    for x, y in zip(a, c):
        assert np.array_equal(x, y)
    # each row alone gives the same bounds as in the batch
    for i in range(0, len(ok), 97):
        r = [b[i:i + 1].copy() for b in boxes]
        range_bearing_simd_kernel(*r)
        for x, y in zip(r, a):
            assert np.array_equal(x[0], y[i])


def test_negative_zero_bounds_keep_the_piece():
    """``dx = mx - sx`` with an upper bound rounding to ``-0`` gives a quadrant piece whose
    ``|dx|`` has the lower bound ``-0``: the upper bound of ``t = v / |dx|`` must not turn into
    ``-inf`` there (a quotient by ``-0``), which would empty the piece and drop every solution
    with ``sx`` above the subnormal ``5e-324``."""
    row = [[5e-324, 2.5129887686083993e-15], [-35.08317093372674, -35.083170876490385],
           [12.57570811053139, 12.57570811053139], [-0.0, 0.0],
           [-56.177642786977565, -56.17764215795992], [21.094471847236132, 21.094471853755948],
           [-14.301793690544141, INF]]
    s = _rows(row)
    v = _rows(row)
    assert range_bearing_kernel(*s).all() and range_bearing_simd_kernel(*v).all()
    assert v[0][0, 1] >= s[0][0, 1] > 1e-15
