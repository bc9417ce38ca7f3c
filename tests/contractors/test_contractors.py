"""Linear difference and q-relaxed intersection: soundness, tightness, brute force, API.

The difference ``a = b - c`` is checked against exact rationals (``fractions.Fraction``): the
truth is kept and the result is within a few ulps of the exact hull, so a contractor that
silently widened (or did nothing) fails. Its periodic form is checked with mpmath reals.
The q-relaxed intersection is compared with a brute force on small random sets.
"""

from __future__ import annotations

import math
from fractions import Fraction

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.contractors import difference, qinter, qinter_batch
from ivslam_cli.interval.angles import angle_meet
from tests.helpers.hyp import examples

mpmath.mp.prec = 120
SETTINGS = settings(max_examples=examples(ci=1500))
INF = math.inf

value = st.one_of(st.floats(-1e6, 1e6), st.just(0.0), st.floats(-1e-300, 1e-300))
spread = st.one_of(st.just(0.0), st.floats(0.0, 1e-9), st.floats(0.0, 10.0), st.floats(0.0, 1e5),
                   st.just(INF))


def box(x: float, below: float, above: float) -> np.ndarray:
    """A ``(1, 2)`` box holding the float ``x`` (degenerate when both spreads are 0)."""
    lo = x if below == 0.0 else float(np.nextafter(x - below, -INF))
    hi = x if above == 0.0 else float(np.nextafter(x + above, INF))
    return np.array([[lo, hi]])


def F(x: float) -> Fraction | float:
    return x if math.isinf(x) else Fraction(x)


def ulps_away(x: float, n: int, direction: float) -> float:
    for _ in range(n):
        x = float(np.nextafter(x, direction))
    return x


# ---------------------------------------------------------------- difference
@SETTINGS
@given(b=value, c=value, s=st.lists(spread, min_size=6, max_size=6))
def test_difference_keeps_the_truth_and_is_tight(b, c, s):
    a_true = Fraction(b) - Fraction(c)  # exact, not necessarily a float
    A = np.array([[ulps_away(float(a_true), 1, -INF) - s[0], ulps_away(float(a_true), 1, INF) + s[1]]])
    B, C = box(b, s[2], s[3]), box(c, s[4], s[5])
    a0, b0, c0 = A.copy(), B.copy(), C.copy()
    assert difference(A, B, C)[0]
    assert F(A[0, 0]) <= a_true <= F(A[0, 1])
    assert B[0, 0] <= b <= B[0, 1] and C[0, 0] <= c <= C[0, 1]
    # tight: a's bounds within 2 ulps of the exact projection of the solution set
    lo = max(F(a0[0, 0]), F(b0[0, 0]) - F(c0[0, 1]))
    hi = min(F(a0[0, 1]), F(b0[0, 1]) - F(c0[0, 0]))
    if not math.isinf(lo):
        assert A[0, 0] >= ulps_away(float(lo), 2, -INF)
    if not math.isinf(hi):
        assert A[0, 1] <= ulps_away(float(hi), 2, INF)


def test_difference_contracts_every_variable():
    a = np.array([[-10.0, 10.0], [0.0, 0.5], [0.0, 1.0]])
    b = np.array([[1.0, 2.0], [-5.0, 5.0], [0.0, 1.0]])
    c = np.array([[0.5, 0.7], [1.0, 1.25], [-5.0, 5.0]])
    assert difference(a, b, c).all()
    np.testing.assert_allclose(a[0], [0.3, 1.5], rtol=1e-15)   # forward
    np.testing.assert_allclose(b[1], [1.0, 1.75], rtol=1e-15)  # b = a + c
    np.testing.assert_allclose(c[2], [-1.0, 1.0], rtol=1e-15)  # c = b - a


def test_difference_detects_inconsistency_row_by_row():
    a = np.array([[0.0, 1.0], [0.0, 1.0]])
    b = np.array([[5.0, 6.0], [1.0, 2.0]])
    c = np.array([[0.0, 1.0], [0.0, 1.0]])
    ok = difference(a, b, c)
    assert ok.tolist() == [False, True]
    for arr in (a, b, c):
        assert arr[0, 0] == INF and arr[0, 1] == -INF
    assert b[1].tolist() == [1.0, 2.0]


@SETTINGS
@given(b=st.floats(-7.0, 7.0), c=st.floats(-7.0, 7.0), k=st.integers(-3, 3),
       s=st.lists(st.one_of(st.just(0.0), st.floats(0.0, 0.5), st.floats(0.0, 8.0)),
                  min_size=6, max_size=6))
def test_periodic_difference_keeps_the_truth_in_every_branch(b, c, k, s):
    a_true = mpmath.mpf(b) - mpmath.mpf(c) + 2 * k * mpmath.pi
    v = float(a_true)
    A = np.array([[float(np.nextafter(v - s[0], -INF)), float(np.nextafter(v + s[1], INF))]])
    B, C = box(b, s[2], s[3]), box(c, s[4], s[5])
    assert difference(A, B, C, periodic=True)[0]
    assert mpmath.mpf(A[0, 0]) <= a_true <= mpmath.mpf(A[0, 1])
    assert B[0, 0] <= b <= B[0, 1] and C[0, 0] <= c <= C[0, 1]


def test_periodic_difference_wraps_and_contracts():
    # heading change across the cut: b = 3.1, c = -3.1 -> a = 6.2 = -0.083 (mod 2 pi)
    a = np.array([[-0.5, 0.5]])
    b = np.array([[3.1, 3.1]])
    c = np.array([[-3.1, -3.1]])
    assert difference(a, b, c, periodic=True)[0]
    np.testing.assert_allclose(a[0], [6.2 - 2 * math.pi] * 2, atol=1e-14)
    # the plain difference sees no solution there
    a = np.array([[-0.5, 0.5]])
    assert not difference(a, np.array([[3.1, 3.1]]), np.array([[-3.1, -3.1]]))[0]


def test_angle_meet_with_a_huge_interval_keeps_it():
    # regression: numba's math.floor of a huge quotient overflowed int64 and emptied the result
    assert angle_meet(0.1, 1e24, 0.1, 0.1) == (0.1, 1e24)
    assert angle_meet(1e20, 1e20 + 1e5, 0.0, 1.0) == (1e20, 1e20 + 1e5)


# ---------------------------------------------------------------- q-relaxed intersection
def brute_interval(iv: np.ndarray, q: int) -> tuple[float, float]:
    """Hull of the points in >= m - q intervals: its ends are endpoints of the inputs."""
    k = len(iv) - q
    if k <= 0:
        return -INF, INF
    pts = [x for x in iv.ravel() if not math.isnan(x)]
    good = [x for x in pts if sum(lo <= x <= hi for lo, hi in iv) >= k]
    return (min(good), max(good)) if good else (INF, -INF)


ends = st.integers(-6, 6).map(float)


@st.composite
def interval_sets(draw, max_m=9):
    m = draw(st.integers(0, max_m))
    rows = []
    for _ in range(m):
        kind = draw(st.sampled_from(["normal", "normal", "normal", "point", "empty", "inf"]))
        a, b = sorted((draw(ends), draw(ends)))
        if kind == "point":
            b = a
        elif kind == "empty":
            a, b = draw(st.sampled_from([(INF, -INF), (3.0, 1.0), (math.nan, math.nan)]))
        elif kind == "inf":
            a, b = draw(st.sampled_from([(-INF, b), (a, INF), (-INF, INF)]))
        rows.append((a, b))
    return np.array(rows, dtype=float).reshape(m, 2)


@settings(max_examples=examples(ci=1000))
@given(iv=interval_sets(), q=st.integers(0, 10))
def test_qinter_intervals_matches_brute_force(iv, q):
    res, rejected = qinter(iv, q)
    expected = brute_interval(iv, q)
    assert tuple(res) == expected
    for i, (lo, hi) in enumerate(iv):
        disjoint = not (lo <= hi) or not (res[0] <= res[1]) or hi < res[0] or lo > res[1]
        assert rejected[i] == disjoint


@settings(max_examples=examples(ci=300))
@given(iv=interval_sets(max_m=80), q=st.integers(0, 40))
def test_qinter_interval_counted_and_sorted_agree_with_brute_force(iv, q):
    """Up to ``SMALL_M`` inputs the kernel counts per candidate, beyond it sorts: both exact."""
    from ivslam_cli.contractors.ctc_qinter import _qinter_counted, qinter_interval, qinter_prefix

    lo, hi = np.ascontiguousarray(iv[:, 0]), np.ascontiguousarray(iv[:, 1])
    expected = brute_interval(iv, q)
    assert qinter_interval(lo, hi, q) == expected
    if 0 < len(iv) - q:
        assert _qinter_counted(lo, hi, len(iv), len(iv) - q) == expected
    # the first m entries of longer buffers, the rest ignored (as the pose update passes them)
    pad = np.array([-INF, 0.0, 5.0, math.nan])
    assert qinter_prefix(np.concatenate([lo, pad]), np.concatenate([hi, pad[::-1]]), len(iv), q) == expected


@settings(max_examples=examples(ci=400))
@given(d=st.integers(1, 3), m=st.integers(1, 7), q=st.integers(0, 4), data=st.data())
def test_qinter_boxes_is_an_outer_approximation(d, m, q, data):
    bx = np.array(data.draw(st.lists(st.lists(st.tuples(ends, ends).map(sorted), min_size=d,
                                              max_size=d), min_size=m, max_size=m)), dtype=float)
    res, rejected = qinter(bx, q)
    # per dimension it is exactly the interval q-intersection (or empty everywhere)
    per_dim = [brute_interval(bx[:, j], q) for j in range(d)]
    if all(lo <= hi for lo, hi in per_dim):
        assert [tuple(r) for r in res] == per_dim
    else:
        assert (res[:, 0] == INF).all() and (res[:, 1] == -INF).all()
    # every grid point (half-integers too) in >= m - q boxes lies in the result
    grid = np.arange(-6.0, 6.5, 0.5)
    pts = np.stack(np.meshgrid(*[grid] * d, indexing="ij"), -1).reshape(-1, d)
    inside = ((bx[None, :, :, 0] <= pts[:, None, :]) & (pts[:, None, :] <= bx[None, :, :, 1])).all(-1)
    agreed = pts[inside.sum(1) >= m - q]
    assert ((res[:, 0] <= agreed) & (agreed <= res[:, 1])).all()
    disjoint = (~(bx[:, :, 0] <= bx[:, :, 1]) | (bx[:, :, 1] < res[:, 0]) | (bx[:, :, 0] > res[:, 1])).any(1)
    assert (rejected == disjoint).all()


def brute_capped(iv, ga, ca, gb, cb):
    """The hull of the reals whose failing intervals keep to the caps, over every endpoint."""
    from ivslam_cli.contractors.ctc_qinter import droppable

    lo, hi = iv[:, 0], iv[:, 1]
    if droppable(np.ones(len(iv), bool), ga, ca, gb, cb):
        return -INF, INF
    ends = [x for x in np.concatenate([lo, hi]) if np.isfinite(x)] + [-1e308, 1e308]  # beyond every finite end
    with np.errstate(invalid="ignore"):
        good = [x for x in ends if droppable(~((lo <= x) & (x <= hi)), ga, ca, gb, cb)]
    if not good:
        return INF, -INF
    return (-INF if min(good) == -1e308 else min(good)), (INF if max(good) == 1e308 else max(good))


@settings(max_examples=examples(ci=1000))
@given(iv=interval_sets(max_m=40), data=st.data())
def test_qinter_capped_matches_brute_force_and_plain_qinter(iv, data):
    """Wrong intervals capped per group (two groupings, as per pose and per landmark): the hull
    is the brute force's, and never wider than the plain q-intersection with q the most that
    the caps let fail together. Up to 40 inputs: the prefix form counts up to ``SMALL_M`` and
    sweeps beyond."""
    from ivslam_cli.contractors.ctc_qinter import qinter_capped_interval, qinter_capped_prefix

    m = len(iv)
    na, nb = data.draw(st.integers(1, 4)), data.draw(st.integers(1, 4))
    ga = np.array(data.draw(st.lists(st.integers(-1, na - 1), min_size=m, max_size=m)), np.int64)
    gb = np.array(data.draw(st.lists(st.integers(-1, nb - 1), min_size=m, max_size=m)), np.int64)
    ca = np.array(data.draw(st.lists(st.integers(0, 3), min_size=na, max_size=na)), np.int64)
    cb = np.array(data.draw(st.lists(st.integers(0, 3), min_size=nb, max_size=nb)), np.int64)
    lo, hi = qinter_capped_interval(np.ascontiguousarray(iv[:, 0]), np.ascontiguousarray(iv[:, 1]), ga, ca, gb, cb)
    assert (lo, hi) == brute_capped(iv, ga, ca, gb, cb)
    # the counted form on the first m entries of longer buffers (as the pose update calls it)
    pad = np.array([0.0, -INF, math.nan])
    groups = np.full((6, m + 7), 7, np.int64)
    groups[0, :m], groups[1, :m], groups[2, :na], groups[3, :nb] = ga, gb, ca, cb
    assert qinter_capped_prefix(np.concatenate([iv[:, 0], pad]), np.concatenate([iv[:, 1], pad]), m,
                                groups, na, nb) == (lo, hi)
    q = min(sum(min(int(ca[g]), int((ga == g).sum())) for g in range(na)) + int((ga < 0).sum()),
            sum(min(int(cb[g]), int((gb == g).sum())) for g in range(nb)) + int((gb < 0).sum()))
    plain = tuple(qinter(iv, min(q, m))[0]) if m else (-INF, INF)
    if plain[0] <= plain[1] and lo <= hi:
        assert plain[0] <= lo and hi <= plain[1]
    elif plain[0] > plain[1]:
        assert not lo <= hi


def test_qinter_capped_keeps_to_the_caps_per_group():
    """Three poses each seeing landmark A (east: an upper bound of x) and B (loose), at most one
    wrong observation per pose and per landmark: two of A's cannot both be wrong, while the
    plain q-intersection with q = 2 (the most the caps let fail together) drops A's two tightest."""
    from ivslam_cli.contractors.ctc_qinter import qinter_capped_interval

    iv = np.array([[-5.0, 1.0], [-5.0, 1.1], [-5.0, 1.2], [-5.0, 5.0], [-5.0, 5.0], [-5.0, 5.0]])
    pose = np.array([0, 1, 2, 0, 1, 2], np.int64)
    lm = np.array([0, 0, 0, 1, 1, 1], np.int64)
    ones = np.ones(3, np.int64)
    assert qinter_capped_interval(iv[:, 0], iv[:, 1], pose, ones, lm, ones[:2]) == (-5.0, 1.1)
    assert tuple(qinter(iv, 2)[0]) == (-5.0, 1.2)
    assert qinter_capped_interval(iv[:, 0], iv[:, 1], pose, ones * 0, lm, ones[:2]) == (-5.0, 1.0)
    assert qinter_capped_interval(iv[:, 0], iv[:, 1], pose, ones, lm, ones[:2] * 2) == (-5.0, 1.2)


def test_qinter_rejects_the_outlier():
    iv = np.array([[1.0, 3.0], [2.0, 4.0], [2.5, 5.0], [40.0, 41.0]])
    res, rejected = qinter(iv, 1)
    assert res.tolist() == [2.5, 3.0]  # the points in >= 3 of the 4
    assert rejected.tolist() == [False, False, False, True]
    res, _ = qinter(iv, 0)
    assert res[0] == INF and res[1] == -INF  # the plain intersection is empty
    res, rejected = qinter(iv, 0 + 3)
    assert res.tolist() == [1.0, 41.0] and not rejected.any()


def test_qinter_batch_equals_one_group_at_a_time():
    rng = np.random.default_rng(7)
    sizes = rng.integers(0, 12, 300)
    offsets = np.r_[0, np.cumsum(sizes)]
    lo = rng.normal(0, 3, (offsets[-1], 2))
    bx = np.stack([lo, lo + rng.exponential(2, lo.shape)], -1)
    qs = rng.integers(0, 4, len(sizes))
    res, rejected = qinter_batch(bx, offsets, qs)
    assert res.shape == (len(sizes), 2, 2) and rejected.shape == (offsets[-1],)
    for g in range(len(sizes)):
        r1, rej1 = qinter(bx[offsets[g]:offsets[g + 1]], int(qs[g]))
        np.testing.assert_array_equal(res[g], r1)
        np.testing.assert_array_equal(rejected[offsets[g]:offsets[g + 1]], rej1)
    res1, _ = qinter_batch(bx[:, 0], offsets, 1)  # (M, 2) intervals -> (G, 2)
    assert res1.shape == (len(sizes), 2)


def test_qinter_argument_errors():
    with pytest.raises(ValueError, match="shape"):
        qinter(np.zeros((3, 3)), 0)
    with pytest.raises(ValueError, match="q"):
        qinter(np.zeros((3, 2)), -1)
    with pytest.raises(ValueError, match="offsets"):
        qinter_batch(np.zeros((3, 2)), [0, 4], 0)
    with pytest.raises(ValueError, match="offsets"):
        qinter_batch(np.zeros((3, 2)), [0, 2, 1, 3], 0)


def test_difference_api_refuses_copies():
    good = np.array([[0.0, 1.0]])
    with pytest.raises(TypeError, match="b"):
        difference(good, [[0.0, 1.0]], good.copy())
    with pytest.raises(ValueError, match="rows"):
        difference(good, good.copy(), np.zeros((2, 2)))
    ro = np.array([[0.0, 1.0]])
    ro.flags.writeable = False
    with pytest.raises(ValueError, match="writable"):
        difference(good, good.copy(), ro)
