"""The SIMD unicycle kernel against the truth (mpmath) and against the scalar reference.

Truths are real points (mpmath, 120 bits) with float boxes built outward around them, so a truth
counted lost is lost; boxes go through the kernel in batches (blocks, rounds, packed lanes).

Relation to the scalar kernel (checked on the bench's mix): the same rows emptied, and no bound
outside the scalar result by more than ``2 RELATIVE_STOP`` of the input width (of the scalar
result's width where the input is unbounded) plus rounding: both iterate sound contractions and
stop when a pass or round shrinks no width by ``RELATIVE_STOP``, so either may stop a little
before the other (measured on 100,000 boxes: at most 0.92e-3 of the input width); on average
tighter.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.bench_kernels import _lost, unicycle_truths
from ivslam_cli.contractors import unicycle
from ivslam_cli.contractors.ctc_unicycle import RELATIVE_STOP, unicycle_kernel
from ivslam_cli.contractors import ctc_unicycle_simd as simd
from ivslam_cli.contractors.ctc_unicycle_simd import NB, unicycle_simd_kernel
from ivslam_cli.contractors.unicycle_heading import _heading, _headings
from tests.helpers.exact import around
from tests.helpers.hyp import examples

mpmath.mp.prec = 120
INF = math.inf
spread = st.one_of(st.just(0.0), st.floats(0.0, 1e-12), st.floats(0.0, 1e-6), st.floats(0.0, 0.3),
                   st.floats(0.0, 10.0))
point = st.tuples(
    st.floats(-50, 50), st.floats(-50, 50),  # x0, y0
    st.one_of(st.floats(-math.pi, math.pi), st.sampled_from([math.pi, -math.pi, 0.0, math.pi / 2])),
    st.one_of(st.floats(-2, 2), st.just(0.0)),  # v (reversing, standing still)
    st.floats(-1.5, 1.5), st.floats(0.01, 0.5),  # w, dt
    st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(-0.02, 0.02),  # qx, qy, qth
    st.integers(-2, 2), st.integers(-2, 2),  # branches of th0 and th1
    st.lists(spread, min_size=24, max_size=24),
)


def _truth_boxes(points):
    truths, rows = [], []
    for x0, y0, th0, v, w, dt, qx, qy, qth, k0, k1, m in points:
        X0, Y0, T0, Vv, Ww, D, QX, QY, QT = (mpmath.mpf(a) for a in (x0, y0, th0, v, w, dt, qx, qy, qth))
        X1 = X0 + Vv * D * mpmath.cos(T0) + QX
        Y1 = Y0 + Vv * D * mpmath.sin(T0) + QY
        T1 = T0 + Ww * D + QT + 2 * k1 * mpmath.pi
        t = (X0, Y0, T0 + 2 * k0 * mpmath.pi, X1, Y1, T1, Vv, Ww, D, QX, QY, QT)
        truths.append(t)
        rows.append([around(a, m[2 * j], m[2 * j + 1]) for j, a in enumerate(t)])
    b = np.array(rows)  # (n, 12, 2)
    return truths, [np.ascontiguousarray(b[:, j]) for j in range(12)]


@settings(max_examples=examples(ci=200))
@given(st.lists(point, min_size=1, max_size=40))
def test_simd_never_loses_the_truth(points):
    truths, arrays = _truth_boxes(points)
    before = [a.copy() for a in arrays]
    ok = unicycle_simd_kernel(*arrays)
    assert ok.all()
    for k, truth in enumerate(truths):
        for j in range(12):
            assert mpmath.mpf(arrays[j][k, 0]) <= truth[j] <= mpmath.mpf(arrays[j][k, 1]), (k, j)
            assert arrays[j][k, 0] >= before[j][k, 0] and arrays[j][k, 1] <= before[j][k, 1]


def test_simd_against_the_scalar_reference():
    _as_tight_as_the_scalar_kernel(*unicycle_truths(20_000, seed=21))


def test_half_unbounded_variables_are_contracted_as_by_the_scalar_kernel():
    """One bound of one variable a box made infinite (the way a missing stamp or an unknown
    duration enters): the SIMD kernel is still within the tolerance of the scalar result."""
    n = 20_000
    boxes, truth = unicycle_truths(n, seed=31)
    rng = np.random.default_rng(31)
    var, side = rng.integers(0, 12, n), rng.integers(0, 2, n)
    for j in range(12):
        boxes[j][(var == j) & (side == 0), 0] = -INF
        boxes[j][(var == j) & (side == 1), 1] = INF
    _as_tight_as_the_scalar_kernel(boxes, truth)


def _as_tight_as_the_scalar_kernel(boxes, truth):
    """Both kernels on copies of ``boxes``: the SIMD one keeps every truth, empties the same
    rows, puts no bound outside the scalar result by more than ``2 RELATIVE_STOP`` of the input
    width (of the scalar width where the input is unbounded) plus rounding, and is on average
    no wider."""
    s = [b.copy() for b in boxes]
    v = [b.copy() for b in boxes]
    ok_s = unicycle_kernel(*s)
    ok_v = unicycle_simd_kernel(*v)
    for b, (val, e) in zip(v, truth):
        assert not np.any(_lost(b, val, e))
    assert np.array_equal(ok_s, ok_v)
    with np.errstate(invalid="ignore"):
        for j in range(12):
            S, V, B = s[j][ok_s], v[j][ok_s], boxes[j][ok_s]
            ws, wv, wb = S[:, 1] - S[:, 0], V[:, 1] - V[:, 0], B[:, 1] - B[:, 0]
            scale = 1.0 + np.nan_to_num(np.abs(S), posinf=0.0, neginf=0.0).max(1)
            out = np.maximum(S[:, 0] - V[:, 0], V[:, 1] - S[:, 1])
            w_ref = np.where(np.isfinite(wb), wb, np.nan_to_num(ws, posinf=0.0))
            tol = 2 * RELATIVE_STOP * w_ref + 1e-12 * scale
            assert not np.any(out > tol), j
            fin = np.isfinite(ws) & np.isfinite(wv)
            assert wv[fin].sum() <= ws[fin].sum() * (1 + 1e-9)


NAMES = "x0 y0 th0 x1 y1 th1 v w dt qx qy qth".split()


def _rows(*dicts):
    base = {"x0": [0, 0], "y0": [0, 0], "th0": [-INF, INF], "x1": [-INF, INF], "y1": [-INF, INF],
            "th1": [-INF, INF], "v": [1, 1], "w": [0, 0], "dt": [1, 1], "qx": [0, 0],
            "qy": [0, 0], "qth": [0, 0]}
    b = np.array([[(base | d)[k] for k in NAMES] for d in dicts], dtype=float)
    return [np.ascontiguousarray(b[:, j]) for j in range(12)]


def test_empty_and_inconsistent_rows_are_emptied():
    """An empty input variable, a displacement longer than v dt, a heading that misses w dt:
    emptied (every variable ``[+inf, -inf]``); the other rows are untouched by them."""
    arrays = _rows({"x1": [1, 1], "y1": [0, 0], "th0": [-1, 1]}, {"v": [1, 0]}, {"x1": [3, 3], "y1": [0, 0]},
                   {"th0": [0, 0], "th1": [1, 1]}, {"x1": [1, 1], "y1": [0, 0], "v": [np.nan, 1]})
    ok = unicycle_simd_kernel(*arrays)
    assert ok.tolist() == [True, False, False, False, False]
    for a in arrays:
        assert np.all(a[~ok, 0] == INF) and np.all(a[~ok, 1] == -INF)
    lo, hi = arrays[2][0]
    assert lo <= 0.0 <= hi and hi - lo < 1e-9  # the heading of a unit step along +x


def test_across_the_cut_and_reversing():
    """A step along -x (heading ±pi, on the cut of atan2) and the same step reversing (v < 0,
    heading 0): the true heading is kept in the input's branch, both sides of the cut."""
    arrays = _rows({"x1": [-1, -1], "y1": [-1e-3, 1e-3], "th0": [-4, 4]},
                   {"x1": [-1, -1], "y1": [-1e-3, 1e-3], "th0": [2, 7]},
                   {"x1": [-1, -1], "y1": [0, 0], "th0": [-1, 1], "v": [-1, -1]},
                   {"x1": [-1, -1], "y1": [0, 0], "th0": [-4, 4], "v": [-1, 1]})
    assert unicycle_simd_kernel(*arrays).all()
    th0 = arrays[2]
    assert th0[0, 0] <= -math.pi and th0[0, 1] >= math.pi and th0[0, 1] - th0[0, 0] < 2 * math.pi + 0.01
    assert th0[1, 0] <= math.pi <= th0[1, 1] and th0[1, 1] - th0[1, 0] < 0.01
    assert th0[2, 0] <= 0.0 <= th0[2, 1] and th0[2, 1] - th0[2, 0] < 1e-9
    # v in [-1, 1]: forward (heading ±pi) or reversing (heading 0): every copy kept
    assert th0[3, 0] <= -math.pi and th0[3, 1] >= math.pi
    assert all(th0[3, 0] <= t <= th0[3, 1] for t in (-math.pi, 0.0, math.pi))


def test_slots_and_public_function_is_the_simd_kernel():
    boxes, _ = unicycle_truths(3 * NB + 7, seed=5)
    a = [b.copy() for b in boxes]
    c = [b.copy() for b in boxes]
    unicycle(*a)
    unicycle_simd_kernel(*c)
    for x, y in zip(a, c):
        assert np.array_equal(x, y)
    for i in range(0, 3 * NB + 7, 41):  # a row alone: the same bounds as in the batch
        r = [b[i:i + 1].copy() for b in boxes]
        unicycle_simd_kernel(*r)
        for x, y in zip(r, a):
            assert np.array_equal(x[0], y[i])


def test_vectorised_heading_step_is_the_scalar_one_bit_for_bit():
    """Where ``_headings`` says its selects apply (``HOK`` 0 or 1), it is ``_heading``: the
    same verdict and, where the box stays, the same 24 bounds."""
    boxes, _ = unicycle_truths(NB * 20, seed=13)
    rows = np.stack(boxes, axis=1).reshape(-1, 24)  # (n, 24) in unicycle_scalar's order
    applied = 0
    for s in range(0, rows.shape[0], NB):
        a = rows[s:s + NB]
        B = np.zeros(simd.BROWS * NB)
        B[:24 * NB] = a.T.reshape(-1)
        B[simd.LIVE * NB:(simd.LIVE + 1) * NB] = 1.0
        B[simd.NEED * NB:(simd.NEED + 1) * NB] = 1.0
        _headings(B)
        c = a.copy()
        for j in range(NB):
            hok = B[simd.HOK * NB + j]
            if hok < -0.5:
                continue
            applied += 1
            assert (hok > 0.5) == _heading(c, j)
            if hok > 0.5:
                assert np.array_equal(B[:24 * NB].reshape(24, NB)[:, j], c[j])
    assert applied > 0.9 * rows.shape[0]


def test_packed_heading_step_is_the_scalar_one_bit_for_bit():
    """Where ``_meet1t`` does not apply (``_headings`` says ``HOK`` -1: a sum of widths of 6 or
    more), ``_headings_listed`` on those slots packed: the verdict and bounds of ``_heading``
    wherever it applies, and it applies to nearly all of them."""
    from ivslam_cli.contractors.unicycle_heading import (
        HOKP, HT0, HT1, HQT, HDT, HROWS, HW, _headings_listed)

    boxes, _ = unicycle_truths(NB * 60, seed=17)
    rows = np.stack(boxes, axis=1).reshape(-1, 24)
    applied = packed = 0
    hb = np.empty(HROWS * NB)
    for s in range(0, rows.shape[0], NB):
        a = rows[s:s + NB]
        B = np.zeros(simd.BROWS * NB)
        B[:24 * NB] = a.T.reshape(-1)
        B[simd.LIVE * NB:(simd.LIVE + 1) * NB] = 1.0
        B[simd.NEED * NB:(simd.NEED + 1) * NB] = 1.0
        _headings(B)
        sel = np.nonzero(B[simd.HOK * NB:(simd.HOK + 1) * NB] < -0.5)[0]
        for t, j in enumerate(sel):
            for r, v in enumerate((simd.W, simd.DT, simd.QT, simd.T1, simd.T0)):
                hb[2 * r * NB + t], hb[(2 * r + 1) * NB + t] = a[j, v], a[j, v + 1]
        _headings_listed(hb, len(sel))
        c = a.copy()
        for t, j in enumerate(sel):
            packed += 1
            hok = hb[HOKP * NB + t]
            if hok < -0.5:
                continue
            applied += 1
            assert (hok > 0.5) == _heading(c, j)
            if hok > 0.5:
                got = [hb[r * NB + t] for r in range(10)]
                want = [c[j, v + k] for v in (simd.W, simd.DT, simd.QT, simd.T1, simd.T0) for k in (0, 1)]
                assert _same(got, want)
    assert (HW, HDT, HQT, HT1, HT0) == (0, 2, 4, 6, 8)
    assert packed > 0.03 * rows.shape[0] and applied > 0.9 * packed


@settings(max_examples=examples(ci=500))
@given(st.one_of(st.floats(-40, 40), st.floats(-2e15, 2e15), st.just(-INF)),
       st.one_of(st.floats(0, 30), st.floats(5.5, 7.0), st.just(0.0), st.just(INF)),
       st.one_of(st.floats(-40, 40), st.floats(-2e15, 2e15)),
       st.one_of(st.floats(0, 7), st.floats(6.2, 6.3), st.just(0.0)))
def test_meet_scan_and_meet_wide_are_the_scalar_meets_where_they_apply(tl, tw, al, aw):
    """``_meet_scan`` gives ``angle_meet``'s bounds and ``_meet_wide`` those of ``_meet``
    (``_angle_difference``'s meet), bit for bit, where they say they apply."""
    from ivslam_cli.contractors.simd_quadrants import _meet
    from ivslam_cli.contractors.unicycle_heading import _meet_scan, _meet_wide
    from ivslam_cli.interval.angles import angle_meet

    th, ah = tl + tw, al + aw
    if not (th == th and tl <= th and al <= ah):
        return
    for fn, ref in ((_meet_scan, angle_meet), (_meet_wide, _meet)):
        lo, hi, ok = fn(tl, th, al, ah)
        if ok:
            r = ref(tl, th, al, ah)
            assert _same((lo, hi), r) or (not lo <= hi and not r[0] <= r[1]), (fn, tl, th, al, ah)


bound = st.one_of(st.floats(-1e6, 1e6), st.sampled_from([0.0, -0.0, 1.0, -1.0, INF, -INF, 5e-324]))


def _iv(draw_a, draw_b):
    lo, hi = sorted((draw_a, draw_b))
    return lo, hi


def _same(x, y):
    return all((a == b and math.copysign(1, a) == math.copysign(1, b)) or (a != a and b != b)
               for a, b in zip(x, y))


@settings(max_examples=examples(ci=500))
@given(bound, bound, bound, bound, bound, bound)
def test_select_forms_are_the_interval_operations_bit_for_bit(a, b, c, d, e, f):
    """``mul_s``, ``div_meet_s`` and ``bwd_mul_s`` (selects, SIMD loops) give the bounds of
    ``mul``, ``div_meet`` and ``bwd_mul`` on non-empty intervals, every case of the extended
    division included."""
    from ivslam_cli.interval.arith import bwd_mul, div_meet, mul
    from ivslam_cli.interval.arith_select import bwd_mul_s, div_meet_s, mul_s

    x, y, z = _iv(a, b), _iv(c, d), _iv(e, f)
    assert _same(mul_s(*x, *y), mul(*x, *y))
    assert _same(div_meet_s(*x, *y, *z), div_meet(*x, *y, *z))
    r, s = bwd_mul_s(*z, *x, *y), bwd_mul(*z, *x, *y)
    assert _same(r, s) or (not r[0] <= r[1] and not s[0] <= s[1])


def test_select_division_is_div_meet_bit_for_bit_on_every_special_case():
    """``div_meet_s`` and ``bwd_mul_s`` (two quotients, their operands picked by the case) on
    every ordered triple of intervals with bounds from a grid of special values (infinities,
    ±0, the least subnormal, huge and plain numbers): the bounds of ``div_meet`` and
    ``bwd_mul``, signs of zeros included (``inf / inf`` corners, ``[b] = [inf, inf]``, zeros
    at either end of ``[b]``)."""
    from numba import njit

    from ivslam_cli.interval.arith import bwd_mul, div_meet
    from ivslam_cli.interval.arith_select import bwd_mul_s, div_meet_s

    grid = np.array([-INF, -1e300, -3.0, -1.0, -5e-324, -0.0, 0.0, 5e-324, 1.0, 2.0, 7.0, 1e300, INF])

    @njit(error_model="numpy")
    def same(x, y):
        for i in range(len(x)):
            if not ((x[i] == y[i] and np.copysign(1.0, x[i]) == np.copysign(1.0, y[i]))
                    or (x[i] != x[i] and y[i] != y[i])):
                return False
        return True

    @njit(error_model="numpy")
    def mismatches(g):
        n, bad, cases = len(g), 0, 0
        for i in range(n):
            for j in range(i, n):
                for k in range(n):
                    for m in range(k, n):
                        for p in range(n):
                            for q in range(p, n):
                                t0, t1, a0, a1, b0, b1 = g[i], g[j], g[k], g[m], g[p], g[q]
                                cases += 1
                                if not same(div_meet_s(t0, t1, a0, a1, b0, b1),
                                            div_meet(t0, t1, a0, a1, b0, b1)):
                                    bad += 1
                                r = bwd_mul_s(t0, t1, a0, a1, b0, b1)
                                s = bwd_mul(t0, t1, a0, a1, b0, b1)
                                if not (same(r, s) or (not r[0] <= r[1] and not s[0] <= s[1])):
                                    bad += 1
        return bad, cases

    bad, cases = mismatches(grid)
    assert cases == (13 * 14 // 2) ** 3 and bad == 0


@settings(max_examples=examples(ci=300))
@given(st.one_of(st.floats(-20, 20), st.just(-INF)), st.one_of(st.floats(0, 8), st.just(INF)),
       st.floats(-20, 20), st.one_of(st.floats(0, 8), st.floats(6.2, 7.0)))
def test_meet3t_is_angle_meet_where_it_applies(tl, tw, al, aw):
    from ivslam_cli.contractors.simd_quadrants import _meet3t
    from ivslam_cli.interval.angles import angle_meet

    th = tl + tw
    if not th == th:
        return
    lo, hi, ok = _meet3t(tl, th, al, al + aw)
    ref = angle_meet(tl, th, al, al + aw)
    if ok:
        assert (lo, hi) == ref or (not lo <= hi and not ref[0] <= ref[1])


@settings(max_examples=examples(ci=500))
@given(st.one_of(st.floats(-20, 20), st.floats(-2e6, 2e6), st.just(-INF)),
       st.one_of(st.floats(0, 8), st.floats(2.5, 3.5), st.just(INF)),
       st.one_of(st.floats(-20, 20), st.floats(-2e6, 2e6)),
       st.one_of(st.floats(0, 8), st.floats(2.5, 3.5), st.floats(6.2, 7.0)))
def test_meet1t_is_meet3t_where_it_applies(tl, tw, al, aw):
    """The one-copy meet of the heading step gives ``_meet3t``'s bounds, bit for bit, where it
    says it applies (``_meet3t`` applies there too)."""
    from ivslam_cli.contractors.simd_quadrants import _meet3t
    from ivslam_cli.contractors.simd_quadrants import _meet1t

    th = tl + tw
    if not th == th:
        return
    lo, hi, ok = _meet1t(tl, th, al, al + aw)
    lo3, hi3, ok3 = _meet3t(tl, th, al, al + aw)
    if ok:
        assert ok3
        assert _same((lo, hi), (lo3, hi3)) or (not lo <= hi and not lo3 <= hi3)


def test_unbounded_duration_is_contracted_as_by_the_scalar_kernel():
    row = {"x0": [-26.93018624694655, -26.010071434205454], "y0": [-33.359369420730566, -33.27728664873216],
           "th0": [3.3085461959501052, 7.46286036226577], "x1": [-26.966222263666197, -26.966221456204313],
           "y1": [-33.25063178721349, -33.25061441883605], "th1": [1.6864998553321926, 3.4028461622537134],
           "v": [0.335904508255959, 0.43801568838488275], "w": [0.9230592396663965, 0.9230616122486612],
           "dt": [-INF, 0.14425682824594693], "qx": [0.004845309725533927, 0.004926400697089364],
           "qy": [0.0407061028624971, 0.04467157119807745],
           "qth": [-0.16196706548851456, -0.018090874278587396]}
    s, v = _rows(row), _rows(row)
    assert unicycle_kernel(*s).tolist() == unicycle_simd_kernel(*v).tolist() == [True]
    for j, name in enumerate(NAMES):  # the scalar result: th0 <= 3.478, dt >= 0.0946
        tol = 2 * RELATIVE_STOP * (s[j][0, 1] - s[j][0, 0]) + 1e-12 * (1 + np.abs(s[j][0]).max())
        assert max(s[j][0, 0] - v[j][0, 0], v[j][0, 1] - s[j][0, 1]) <= tol, name
