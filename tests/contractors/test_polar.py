"""Polar contractor: the truth is never lost (hypothesis), contraction happens, the origin is kept."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.contractors import polar
from tests.helpers.exact import around
from tests.helpers.hyp import examples

mpmath.mp.prec = 120
SETTINGS = settings(max_examples=examples(ci=1500))


spread = st.one_of(st.just(0.0), st.floats(0.0, 1e-6), st.floats(0.0, 0.5), st.floats(0.0, 50.0))


@SETTINGS
@given(
    rho=st.one_of(st.just(0.0), st.floats(1e-9, 1e-3), st.floats(0.0, 100.0)),
    theta=st.one_of(
        st.floats(-math.pi, math.pi),
        st.sampled_from([math.pi, -math.pi, 0.0, math.pi / 2, -math.pi / 2]),
    ),
    branch=st.integers(-3, 3),
    m=st.lists(spread, min_size=8, max_size=8),
)
def test_polar_never_loses_the_truth(rho, theta, branch, m):
    R = mpmath.mpf(rho)
    T = mpmath.mpf(theta)
    X, Y = R * mpmath.cos(T), R * mpmath.sin(T)
    t_real = T + 2 * branch * mpmath.pi  # theta's own branch, e.g. near 2 pi or -6 pi
    dx = np.array([around(X, m[0], m[1])])
    dy = np.array([around(Y, m[2], m[3])])
    r = np.array([around(R, m[4], m[5])])
    t = np.array([around(t_real, m[6], m[7])])
    before = [a.copy() for a in (dx, dy, r, t)]
    ok = polar(dx, dy, r, t)
    assert ok[0]
    for arr, truth in ((dx, X), (dy, Y), (r, R), (t, t_real)):
        assert mpmath.mpf(arr[0, 0]) <= truth <= mpmath.mpf(arr[0, 1])
    for arr, old in zip((dx, dy, r, t), before):
        assert arr[0, 0] >= old[0, 0] and arr[0, 1] <= old[0, 1]  # contracts, never widens


def test_polar_contracts_easy_boxes():
    dx = np.array([[1.0, 2.0]])
    dy = np.array([[1.0, 2.0]])
    r = np.array([[0.0, 10.0]])
    t = np.array([[-np.pi, np.pi]])
    assert polar(dx, dy, r, t)[0]
    assert r[0, 0] == pytest.approx(math.sqrt(2), rel=1e-12) and r[0, 1] == pytest.approx(math.sqrt(8), rel=1e-12)
    assert t[0, 0] == pytest.approx(math.atan(0.5), rel=1e-12) and t[0, 1] == pytest.approx(math.atan(2), rel=1e-12)


def test_polar_across_the_cut_keeps_both_sides():
    # points just above and just below the negative x-axis: theta near +pi and near -pi
    dx = np.array([[-2.0, -1.0]])
    dy = np.array([[-0.1, 0.1]])
    r = np.array([[0.0, 10.0]])
    t = np.array([[-4.0, 4.0]])  # wider than 2 pi: holds both representatives
    assert polar(dx, dy, r, t)[0]
    assert t[0, 0] < -math.pi + 0.1 and t[0, 1] > math.pi - 0.1
    t = np.array([[3.0, 3.3]])  # one branch, crossing pi
    dx = np.array([[-2.0, -1.0]])
    dy = np.array([[-0.1, 0.1]])
    assert polar(dx, dy, np.array([[0.0, 10.0]]), t)[0]
    assert t[0, 0] <= math.pi - 0.05 and t[0, 1] >= math.pi + 0.05


def test_polar_keeps_the_origin_for_every_angle():
    dx = np.array([[0.0, 0.0]])
    dy = np.array([[0.0, 0.0]])
    r = np.array([[0.0, 0.0]])
    t = np.array([[1.0, 1.5]])
    assert polar(dx, dy, r, t)[0]
    assert t[0].tolist() == [1.0, 1.5]


def test_polar_detects_inconsistency_and_empties_the_row():
    dx = np.array([[1.0, 2.0], [1.0, 2.0]])
    dy = np.array([[1.0, 2.0], [1.0, 2.0]])
    r = np.array([[5.0, 6.0], [0.0, 10.0]])
    t = np.array([[0.0, 1.0], [0.0, 1.0]])
    ok = polar(dx, dy, r, t)
    assert ok.tolist() == [False, True]
    assert not (dx[0, 0] <= dx[0, 1]) and not (t[0, 0] <= t[0, 1])


def test_polar_rejects_arrays_it_cannot_write():
    a = np.zeros((3, 2))
    with pytest.raises(TypeError):
        polar(a.astype(np.float32), a, a, a)
    ro = np.zeros((3, 2))
    ro.setflags(write=False)
    with pytest.raises(ValueError):
        polar(ro, a.copy(), a.copy(), a.copy())


# ---------------------------------------------------------------- the fast paths of the kernel
# The kernel's fast paths (principal-branch quadrant meets, nonnegative arithmetic, extrema of
# sin/cos by comparisons, libm memo, skipped steps) must give the same bounds as the general
# operations they replace: each is checked against its general counterpart, and the whole
# contractor against a plain loop of general passes.
from ivslam_cli.contractors import ctc_polar as cp  # noqa: E402
from ivslam_cli.interval import arith  # noqa: E402
from ivslam_cli.interval.angles import angle_meet  # noqa: E402

FAST = settings(max_examples=examples(ci=400))
QUADRANTS = [(0.0, cp.HALF_PI_HI), (-cp.HALF_PI_HI, 0.0), (-cp.PI_HI, -cp.HALF_PI_LO),
             (cp.HALF_PI_LO, cp.PI_HI)]


def _theta_box(center: float, w1: float, w2: float, turns: int) -> tuple[float, float]:
    c = center + 2 * math.pi * turns
    return c - w1, c + w2


widths = st.one_of(st.just(0.0), st.floats(0.0, 1e-9), st.floats(0.0, 0.5), st.floats(0.0, 3.2))
centers = st.one_of(st.floats(-math.pi, math.pi),
                    st.sampled_from([math.pi, -math.pi, 0.0, math.pi / 2, -math.pi / 2]))


@FAST
@given(center=centers, w1=widths, w2=widths, turns=st.integers(-1000, 1000),
       s=st.tuples(st.floats(-3.3, 3.3), st.floats(0.0, 3.0)))
def test_meet_near_is_angle_meet(center, w1, w2, turns, s):
    tl, th = _theta_box(center, w1, w2, turns)
    k = float(round(0.5 * (tl + th) * cp.INV_TWO_PI_LO)) if th - tl < cp.TWO_PI_LO else 0.0
    pl, ph = cp._shifted(tl, th, -k, *cp._offsets(-k)[3:5])
    if not (-6.0 < pl and ph < 6.0):
        return  # the fast path's precondition: the kernel takes angle_meet
    o_in, o_out = cp._offsets(-k), cp._offsets(k)
    for ql, qh in QUADRANTS:  # a quadrant meets theta (theta's copies shifted)
        assert cp._meet_near(ql, qh, tl, th, o_in) == angle_meet(ql, qh, tl, th)
    sl, sh = s[0], s[0] + s[1]  # an angle near [-pi, pi] meets theta (its copies shifted)
    assert cp._meet_near(tl, th, sl, sh, o_out) == angle_meet(tl, th, sl, sh)


nonneg = st.tuples(
    st.one_of(st.just(0.0), st.just(-0.0), st.floats(0.0, 1e3), st.floats(0.0, 1e300)),
    st.one_of(st.just(0.0), st.floats(0.0, 1e3), st.just(math.inf)),
).map(lambda p: (p[0], max(p[0], p[1])))


def _same(a: tuple, b: tuple) -> bool:
    """Equal bounds, or both empty."""
    if not (a[0] <= a[1]) and not (b[0] <= b[1]):
        return True
    return a == b


@FAST
@given(a=nonneg, b=nonneg, c=nonneg)
def test_nonnegative_arithmetic_is_the_general_one(a, b, c):
    assert _same(cp._div_nonneg(*a, *b), arith.div(*a, *b))
    assert _same(cp._mul_nonneg(*a, *b), arith.mul(*a, *b))
    fast = cp._bwd_mul_nonneg(*a, *b, *c)
    slow = arith.bwd_mul(*a, *b, *c)
    assert _same(fast[:2], slow[:2]) and _same(fast[2:], slow[2:])


def test_three_half_pi_is_enclosed():
    mpmath.mp.prec = 200
    assert mpmath.mpf(cp.THREE_HALF_PI_LO) < 3 * mpmath.pi / 2 < mpmath.mpf(cp.THREE_HALF_PI_HI)


@FAST
@given(center=centers, w1=widths, w2=widths, turns=st.integers(-50, 50),
       u=st.lists(st.floats(0.0, 1.0), min_size=5, max_size=5))
def test_sin_cos_fast_extrema_enclose_and_match(center, w1, w2, turns, u):
    tl, th = _theta_box(center, w1, w2, turns)
    k = float(round(0.5 * (tl + th) * cp.INV_TWO_PI_LO))
    pl, ph = cp._shifted(tl, th, -k, *cp._offsets(-k)[3:5])
    cl, ch, sl, sh, w = cp._sin_cos(tl, th, cp.NO_TRIG, pl, ph)
    # memoised values give the same answer
    assert cp._sin_cos(tl, th, w, pl, ph)[:4] == (cl, ch, sl, sh)
    # the general functions' bounds, up to the extrema decided differently at an ulp's distance
    for (lo, hi), (glo, ghi) in (((cl, ch), arith.cos(tl, th)), ((sl, sh), arith.sin(tl, th))):
        assert abs(lo - glo) <= 1e-15 and abs(hi - ghi) <= 1e-15
    # every angle of the interval (its bounds, points between, and the extrema inside)
    mpmath.mp.prec = 120
    pts = [mpmath.mpf(tl), mpmath.mpf(th)] + [mpmath.mpf(tl) + f * (mpmath.mpf(th) - mpmath.mpf(tl)) for f in u]
    n0 = mpmath.ceil((mpmath.mpf(tl)) / (mpmath.pi / 2))
    n = n0
    while n * mpmath.pi / 2 <= mpmath.mpf(th):
        pts.append(n * mpmath.pi / 2)
        n += 1
    for t in pts:
        assert cl <= mpmath.cos(t) <= ch
        assert sl <= mpmath.sin(t) <= sh


def _reference(b: list[float]) -> tuple:
    """The contractor as a plain loop of general passes (no branch offsets, memo or skipping)."""
    xl, xh, yl, yh, rl, rh, tl, th = b
    rl = max(rl, 0.0)
    if not (xl <= xh and yl <= yh and rl <= rh and tl <= th):
        return (math.inf, -math.inf) * 4
    for k in range(cp.MAX_PASSES):
        r = cp.polar_pass(xl, xh, yl, yh, rl, rh, tl, th, 0.0, cp.OFFSETS_0, cp.OFFSETS_0,
                          cp.NO_MEMO, cp.NO_TRIG, False, False)
        if not (r[0] <= r[1]):
            return (math.inf, -math.inf) * 4
        old = (xl, xh, yl, yh, rl, rh, tl, th)
        if r[:8] == old:
            break
        progress = max(cp._shrink(old[2 * j], old[2 * j + 1], r[2 * j], r[2 * j + 1]) for j in range(4))
        xl, xh, yl, yh, rl, rh, tl, th = r[:8]
        if k >= 1 and progress < cp.RELATIVE_STOP:
            break
    return xl, xh, yl, yh, rl, rh, tl, th


bound_w = st.one_of(st.just(0.0), st.floats(0.0, 1e-9), st.floats(0.0, 1e-3), st.floats(0.0, 20.0),
                    st.just(math.inf))


@settings(max_examples=examples(ci=600))
@given(
    rho=st.one_of(st.just(0.0), st.floats(0.0, 1e-6), st.floats(0.0, 100.0)),
    theta=centers,
    turns=st.one_of(st.integers(-3, 3), st.integers(-10**6, 10**6)),
    m=st.lists(bound_w, min_size=8, max_size=8),
    shift=st.lists(st.one_of(st.just(0.0), st.floats(-3.0, 3.0)), min_size=4, max_size=4),
)
def test_fast_kernel_equals_plain_passes(rho, theta, turns, m, shift):
    """Same bounds as the plain loop, on boxes around true points (some shifted off them, so
    some are empty), with degenerate, wide and unbounded sides, theta in any branch (up to
    ~6e6 rad) and across ±pi; and the truth of unshifted boxes is kept."""
    x, y = rho * math.cos(theta), rho * math.sin(theta)
    t = theta + 2 * math.pi * turns
    v = [x + shift[0], y + shift[1], rho + abs(shift[2]), t + shift[3]]
    b = []
    for j in range(4):
        b += [v[j] - m[2 * j], v[j] + m[2 * j + 1]]
    b[4] = max(b[4], 0.0)
    fast = cp.polar_scalar(*b)
    ref = _reference(b)
    if not (fast[0] <= fast[1]):
        assert not (ref[0] <= ref[1])
    else:
        assert fast == ref


@FAST
@given(k=st.one_of(st.integers(-10**6, 10**6), st.integers(-10**15, 10**15)).map(float))
def test_branch_offsets_are_shift_offsets(k):
    assert cp._two_pi_times(k) == arith.mul(k, k, cp.TWO_PI_LO, cp.TWO_PI_HI)
    o = cp._offsets(k)
    for j, kk in enumerate((k - 1.0, k, k + 1.0)):
        assert (o[1 + 2 * j], o[2 + 2 * j]) == arith.mul(kk, kk, cp.TWO_PI_LO, cp.TWO_PI_HI)


def test_default_offsets_are_the_kernels_bit_for_bit():
    """``OFFSETS_0``, computed by Python at import, is what the kernel ``_offsets(0.0)`` gives."""
    assert np.array(cp.OFFSETS_0).view(np.int64).tolist() == np.array(cp._offsets(0.0)).view(np.int64).tolist()


@FAST
@given(p=st.one_of(st.just(0.0), st.just(-0.0), st.floats(-1.0, 2.0), st.just(cp.HALF_PI_LO)),
       q=st.one_of(st.just(0.0), st.just(-0.0), st.floats(-1e300, 1e300), st.just(math.inf),
                   st.just(-math.inf)))
def test_tan_atan_bounds_shortcuts_are_exact(p, q):
    """The libm shortcuts (tan 0, atan 0) give the bounds the general expressions give, and
    the bounds enclose the real values."""
    lo = cp.HALF_PI_LO
    want_lo = arith.down2(math.tan(lo)) if p >= lo else max(0.0, arith.down2(math.tan(max(p, 0.0))))
    assert cp._tan_lo(p) == want_lo
    assert cp._atan_lo(q) == arith.atan(q, q)[0] and cp._atan_hi(q) == arith.atan(q, q)[1]
    mpmath.mp.prec = 120
    if 0.0 <= p < lo:
        assert cp._tan_lo(p) <= mpmath.tan(mpmath.mpf(p)) <= cp._tan_hi(p)
    if math.isfinite(q):
        assert cp._atan_lo(q) <= mpmath.atan(mpmath.mpf(q)) <= cp._atan_hi(q)
