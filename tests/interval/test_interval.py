"""Soundness of the interval kernel: the truth is never lost, rounding is outward.

Random boxes around random true points (including boxes straddling 0 and ±pi, degenerate
and very wide ones). + - * / are checked against exact rationals (``fractions.Fraction``);
sqrt and the transcendental functions against mpmath at 120 bits. Each operation is also
checked for tightness (a few ulps from the exact hull), so an operation that silently
widened its result would fail too.
"""

from __future__ import annotations

import math
from fractions import Fraction

import mpmath
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from ivslam_cli import interval as iv
from tests.helpers.hyp import examples

mpmath.mp.prec = 120
SETTINGS = settings(max_examples=examples(ci=400))

finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False)
small = st.floats(min_value=-50.0, max_value=50.0, allow_nan=False, allow_infinity=False)
unit = st.floats(min_value=0.0, max_value=1.0)


@st.composite
def box_around(draw, value=finite, spread=st.floats(min_value=0.0, max_value=1e3)):
    """An interval with a point inside it: (lo, hi, x). Degenerate when spread is 0."""
    x = draw(value)
    a = draw(spread) * draw(unit)
    b = draw(spread) * draw(unit)
    lo, hi = x - a, x + b
    assume(math.isfinite(lo) and math.isfinite(hi))
    lo, hi = min(lo, x), max(hi, x)  # float rounding of x-a may exceed x
    return lo, hi, x


def ulps(x: float, n: int = 1, direction: float = math.inf) -> float:
    for _ in range(n):
        x = float(np.nextafter(x, direction))
    return x


def holds(res, exact) -> bool:
    lo, hi = res
    return (lo == -math.inf or Fraction(lo) <= exact) and (hi == math.inf or exact <= Fraction(hi))


# ------------------------------------------------------------------ exact rationals
@SETTINGS
@given(box_around(), box_around())
def test_add_sub_mul_contain_exact_results(a, b):
    al, ah, x = a
    bl, bh, y = b
    X, Y = Fraction(x), Fraction(y)
    assert holds(iv.add([al, ah], [bl, bh])[0], X + Y)
    assert holds(iv.sub([al, ah], [bl, bh])[0], X - Y)
    assert holds(iv.mul([al, ah], [bl, bh])[0], X * Y)


@SETTINGS
@given(box_around(), box_around())
def test_div_contains_exact_quotient(a, b):
    al, ah, x = a
    bl, bh, y = b
    assume(y != 0.0)
    assert holds(iv.div([al, ah], [bl, bh])[0], Fraction(x) / Fraction(y))


@SETTINGS
@given(box_around(), box_around())
def test_arithmetic_is_tight_to_a_few_ulps(a, b):
    """The bounds are the exact extremes rounded outward by at most 2 ulps."""
    al, ah, _ = a
    bl, bh, _ = b
    A = [Fraction(al), Fraction(ah)]
    B = [Fraction(bl), Fraction(bh)]
    for op, f in ((iv.add, lambda p, q: p + q), (iv.sub, lambda p, q: p - q), (iv.mul, lambda p, q: p * q)):
        cands = [f(p, q) for p in A for q in B]
        lo, hi = op([al, ah], [bl, bh])[0]
        exact_lo, exact_hi = min(cands), max(cands)
        assert Fraction(lo) <= exact_lo and Fraction(hi) >= exact_hi
        assert Fraction(ulps(lo, 3)) >= exact_lo or lo == -math.inf
        assert Fraction(ulps(hi, 3, -math.inf)) <= exact_hi or hi == math.inf


def test_rounding_is_outward_on_inexact_sums():
    lo, hi = iv.add([[0.1, 0.1]], [[0.2, 0.2]])[0]
    exact = Fraction(0.1) + Fraction(0.2)
    assert Fraction(lo) < exact < Fraction(hi)
    assert lo < 0.1 + 0.2 < hi  # even the rounded-to-nearest sum is strictly inside


def test_division_by_interval_holding_zero():
    assert np.array_equal(iv.div([[1.0, 2.0]], [[-1.0, 1.0]])[0], [-np.inf, np.inf])
    lo, hi = iv.div([[1.0, 2.0]], [[0.0, 4.0]])[0]
    assert lo <= 0.25 and hi == np.inf
    lo, hi = iv.div([[1.0, 2.0]], [[-4.0, 0.0]])[0]
    assert lo == -np.inf and hi >= -0.25
    assert iv.is_empty(iv.div([[1.0, 2.0]], [[0.0, 0.0]]))[0]
    # [0, 0] * entire is [0, 0]: 0 * inf never turns into NaN
    lo, hi = iv.mul([[0.0, 0.0]], [[-np.inf, np.inf]])[0]
    assert lo <= 0.0 <= hi and hi - lo < 1e-300


def test_empty_propagates_and_nan_is_empty():
    e = iv.empty(1)
    for op in (iv.add, iv.sub, iv.mul, iv.div, iv.inter):
        assert iv.is_empty(op(e, [[1.0, 2.0]]))[0]
    assert iv.is_empty([[np.nan, 1.0]])[0]
    assert np.array_equal(iv.hull(e, [[1.0, 2.0]])[0], [1.0, 2.0])
    assert iv.width(e)[0] == 0.0


# ------------------------------------------------------------------ high precision
def mp_in(res, value) -> bool:
    lo, hi = res
    return mpmath.mpf(lo) <= value <= mpmath.mpf(hi)


@SETTINGS
@given(box_around(value=st.floats(min_value=0.0, max_value=1e12)))
def test_sqr_sqrt(a):
    lo, hi, x = a
    X = mpmath.mpf(x)
    assert mp_in(iv.sqr([lo, hi])[0], X * X)
    assert mp_in(iv.sqrt([lo, hi])[0], mpmath.sqrt(X))
    assert mp_in(iv.sqr([-hi, -lo])[0], X * X)


@SETTINGS
@given(box_around(value=st.floats(min_value=-1e6, max_value=1e6), spread=st.floats(0.0, 8.0)))
def test_sin_cos_contain_truth(a):
    lo, hi, x = a
    X = mpmath.mpf(x)
    s = iv.sin([lo, hi])[0]
    c = iv.cos([lo, hi])[0]
    assert mp_in(s, mpmath.sin(X)) and mp_in(c, mpmath.cos(X))
    assert -1.0 <= s[0] <= s[1] <= 1.0 and -1.0 <= c[0] <= c[1] <= 1.0


@pytest.mark.parametrize("k", [-3, -1, 0, 1, 2, 1000])
def test_sin_cos_extrema_near_multiples_of_pi(k):
    """Intervals ending an ulp away from an extremum must still reach it when they hold it."""
    for centre, fn, bound in (
        (math.pi / 2 + 2 * k * math.pi, iv.sin, 1.0),
        (-math.pi / 2 + 2 * k * math.pi, iv.sin, -1.0),
        (2 * k * math.pi, iv.cos, 1.0),
        (math.pi + 2 * k * math.pi, iv.cos, -1.0),
    ):
        for lo, hi in ((centre, centre), (ulps(centre, 1, -math.inf), ulps(centre, 1))):
            res = fn([lo, hi])[0]
            assert res[0] <= bound <= res[1] or abs(bound - (res[1] if bound > 0 else res[0])) < 1e-15


@SETTINGS
@given(box_around(value=st.floats(min_value=-1e8, max_value=1e8)))
def test_atan_contains_truth(a):
    lo, hi, x = a
    assert mp_in(iv.atan([lo, hi])[0], mpmath.atan(mpmath.mpf(x)))


def _angle_ok(res, theta) -> bool:
    """Is some theta + 2k pi inside res? (theta an mpf)."""
    lo, hi = mpmath.mpf(res[0]), mpmath.mpf(res[1])
    if not lo <= hi:
        return False
    k = mpmath.ceil((lo - theta) / (2 * mpmath.pi))
    return theta + 2 * k * mpmath.pi <= hi


@SETTINGS
@given(box_around(value=small, spread=st.floats(0.0, 20.0)), box_around(value=small, spread=st.floats(0.0, 20.0)))
def test_atan2_contains_truth_across_the_cut(by, bx):
    yl, yh, y = by
    xl, xh, x = bx
    assume(not (x == 0.0 and y == 0.0))
    theta = mpmath.atan2(mpmath.mpf(y), mpmath.mpf(x))
    if y == 0.0 and x < 0.0:
        theta = mpmath.pi  # the mathematical argument; -0.0 is a float artefact
    res = iv.atan2([yl, yh], [xl, xh])[0]
    assert mp_in(res, theta)


def test_atan2_box_straddling_the_cut_keeps_both_sides():
    lo, hi = iv.atan2([[-0.1, 0.1]], [[-2.0, -1.0]])[0]
    assert lo <= -3.1 and hi >= 3.1
    # a box just above the cut: angles just below pi, nothing near -pi
    lo, hi = iv.atan2([[0.0, 0.1]], [[-2.0, -1.0]])[0]
    assert lo > 3.0 and hi >= math.pi


@SETTINGS
@given(
    st.floats(-math.pi, math.pi),
    st.integers(-5, 5),
    st.floats(0.0, 3.0),
    st.floats(0.0, 3.0),
    st.floats(0.0, 7.0),
    unit,
)
def test_angle_meet_keeps_every_equivalent_angle(phi, k, a_lo, a_hi, t_spread, t_pos):
    """If theta = phi + 2k pi is in [t] and phi in [a], theta survives [t] ∩ ([a] + 2pi Z)."""
    theta = mpmath.mpf(phi) + 2 * k * mpmath.pi
    tc = float(theta)
    t_lo = float(np.nextafter(tc - t_spread * t_pos, -np.inf))
    t_hi = float(np.nextafter(tc + t_spread * (1 - t_pos), np.inf))
    res = iv.angle_meet([t_lo, t_hi], [phi - a_lo, phi + a_hi])[0]
    assert mp_in(res, theta)
    assert res[0] >= t_lo and res[1] <= t_hi


@SETTINGS
@given(
    st.floats(-math.pi, math.pi),
    st.integers(-5, 5),
    st.integers(-5, 5),
    st.floats(0.0, 3.0),
    st.floats(0.0, 3.0),
    st.floats(0.0, 30.0),
    unit,
)
def test_angle_meet_narrow_keeps_the_angle_modulo_two_pi(phi, k, j, a_lo, a_hi, t_spread, t_pos):
    """theta = phi + 2k pi in [t], phi + 2j pi in [a]: some phi + 2m pi is in the result, and the
    result is no wider than either branch-keeping meet."""
    from ivslam_cli.interval.angles import angle_meet, angle_meet_narrow

    theta = mpmath.mpf(phi) + 2 * k * mpmath.pi
    tc = float(theta)
    t_lo = float(np.nextafter(tc - t_spread * t_pos, -np.inf))
    t_hi = float(np.nextafter(tc + t_spread * (1 - t_pos), np.inf))
    ac = float(mpmath.mpf(phi) + 2 * j * mpmath.pi)
    a = (float(np.nextafter(ac - a_lo, -np.inf)), float(np.nextafter(ac + a_hi, np.inf)))
    lo, hi = angle_meet_narrow(t_lo, t_hi, *a)
    assert lo <= hi
    m = mpmath.floor((mpmath.mpf(lo) - phi) / (2 * mpmath.pi))
    assert any(lo <= phi + 2 * (m + d) * mpmath.pi <= hi for d in (0, 1, 2))
    p1 = angle_meet(t_lo, t_hi, *a)
    p2 = angle_meet(a[0], a[1], t_lo, t_hi)
    assert hi - lo <= min(p1[1] - p1[0], p2[1] - p2[0])


def test_angle_meet_narrow_leaves_the_wide_branch():
    """A heading known over several turns met with a narrow image: the narrow arc, not the hull
    of its copies."""
    from ivslam_cli.interval.angles import angle_meet, angle_meet_narrow

    assert angle_meet(-5.0, 16.0, 3.4, 4.9)[1] - angle_meet(-5.0, 16.0, 3.4, 4.9)[0] > 12
    lo, hi = angle_meet_narrow(-5.0, 16.0, 3.4, 4.9)
    assert hi - lo <= 1.5 + 1e-12


def test_angle_meet_contracts_and_detects_empty():
    lo, hi = iv.angle_meet([[10.0, 11.0]], [[-3.0, -2.0]])[0]
    assert 10.0 <= lo and abs(hi - (-2.0 + 4 * math.pi)) < 1e-12
    assert iv.is_empty(iv.angle_meet([[0.0, 0.5]], [[1.0, 2.0]]))[0]


# ------------------------------------------------------------------ backward operations
@SETTINGS
@given(box_around(), box_around())
def test_backward_add_sub_mul_keep_solutions(a, b):
    al, ah, x = a
    bl, bh, y = b
    for fwd, bwd, exact in (
        (iv.add, iv.bwd_add, Fraction(x) + Fraction(y)),
        (iv.sub, iv.bwd_sub, Fraction(x) - Fraction(y)),
        (iv.mul, iv.bwd_mul, Fraction(x) * Fraction(y)),
    ):
        z = [float(np.nextafter(float(exact), -np.inf)), float(np.nextafter(float(exact), np.inf))]
        assert Fraction(z[0]) <= exact <= Fraction(z[1])
        xo, yo = bwd([z], [[al, ah]], [[bl, bh]])
        assert xo[0, 0] <= x <= xo[0, 1] and yo[0, 0] <= y <= yo[0, 1]
        assert al <= xo[0, 0] and xo[0, 1] <= ah  # never widened


@SETTINGS
@given(box_around(value=st.floats(-1e6, 1e6)))
def test_backward_sqr_keeps_both_signs(a):
    lo, hi, x = a
    z = iv.sqr([[x, x]])
    out = iv.bwd_sqr(z, [[lo, hi]])[0]
    assert out[0] <= x <= out[1] and lo <= out[0] and out[1] <= hi
    out = iv.bwd_sqrt(iv.sqrt([[abs(x), abs(x)]]), [[min(lo, 0.0), max(hi, abs(x))]])[0]
    assert out[0] <= abs(x) <= out[1]


def test_backward_mul_with_zero_divisor_keeps_everything():
    xo, yo = iv.bwd_mul([[0.0, 0.0]], [[-5.0, 5.0]], [[-1.0, 1.0]])
    assert np.array_equal(xo[0], [-5.0, 5.0]) and np.array_equal(yo[0], [-1.0, 1.0])


def test_enclose_decimal_constants():
    lo, hi = iv.enclose(0.1)
    assert Fraction(lo) < Fraction(1, 10) < Fraction(hi)


@pytest.mark.parametrize("x", [1e15, 3e17, 5.8e19, 1e22, 1e300, -7e20])
def test_sin_cos_of_huge_arguments(x):
    """Far beyond 2^63 / (2 pi): k can no longer be an int64; results must stay sound."""
    for lo, hi in ((x, x), (x, float(np.nextafter(x, np.inf)))):
        s = iv.sin([lo, hi])[0]
        c = iv.cos([lo, hi])[0]
        assert mp_in(s, mpmath.sin(mpmath.mpf(lo))) and mp_in(c, mpmath.cos(mpmath.mpf(lo)))
        assert mp_in(s, mpmath.sin(mpmath.mpf(hi))) and mp_in(c, mpmath.cos(mpmath.mpf(hi)))


@SETTINGS
@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                 st.sampled_from([0.0, -0.0, 5e-324, -5e-324, math.inf, -math.inf, math.nan])))
def test_unguarded_roundings_are_down_and_up_where_they_are_used(c):
    """``down_raw`` / ``up_raw`` are ``down`` / ``up`` except NaN where those give ``-inf`` /
    ``+inf`` (nothing, for a ``max`` / ``min`` that ignores NaN); ``down_pos`` / ``up_pos`` are
    ``down_raw`` / ``up_raw`` for ``c >= 0``, ``±0``, ``+inf`` and NaN."""
    from ivslam_cli.interval.rounding import down, down_pos, down_raw, up, up_pos, up_raw

    def same(a, b):
        return (a == b and math.copysign(1.0, a) == math.copysign(1.0, b)) or (a != a and b != b)

    for raw, guarded, nothing in ((down_raw, down, -math.inf), (up_raw, up, math.inf)):
        r, g = raw(c), guarded(c)
        assert same(r, g) or (r != r and g == nothing)
    if c >= 0.0 or c != c:
        assert same(down_pos(c), down_raw(c)) and same(up_pos(c), up_raw(c))
