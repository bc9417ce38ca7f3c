"""Unicycle and range-bearing contractors: the truth is never lost, contraction happens.

Truths are built first and satisfy the constraint exactly: the free variables are floats, the
dependent ones (``x1, y1, th1``; ``rho, alpha``) are reals computed with mpmath at 120 bits, and
every box is made of floats that surely hold its real value. Boxes are degenerate (floats) or
one-ulp (reals), narrow, wide or infinite; angles sit in random branches, near ±pi, 0, ±pi/2.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.contractors import range_bearing, range_bearing_pass, unicycle
from tests.helpers.hyp import examples

mpmath.mp.prec = 120
SETTINGS = settings(max_examples=examples(ci=800))
INF = math.inf

spread = st.one_of(st.just(0.0), st.floats(0.0, 1e-7), st.floats(0.0, 0.3), st.floats(0.0, 30.0),
                   st.just(INF))
coord = st.one_of(st.floats(-100.0, 100.0), st.just(0.0), st.floats(-1e-3, 1e-3))
angle = st.one_of(
    st.floats(-math.pi, math.pi),
    st.sampled_from([math.pi, -math.pi, 0.0, math.pi / 2, -math.pi / 2, 3.0, -3.0]),
)


def around(value, spreads) -> np.ndarray:
    """A ``(1, 2)`` float box surely holding the real ``value``, ``spreads`` (below, above) wide.

    A float ``value`` is exact (its box may be degenerate); an mpmath one is a real known to
    120 bits, so its box is at least an ulp wide on each side.
    """
    below, above = spreads
    exact = isinstance(value, float)
    v = float(value)
    value = mpmath.mpf(value)
    lo = -INF if below == INF else float(np.nextafter(v - below, -INF))
    hi = INF if above == INF else float(np.nextafter(v + above, INF))
    if exact and below == 0.0:
        lo = v  # degenerate lower bound
    if exact and above == 0.0:
        hi = v
    assert mpmath.mpf(lo) <= value <= mpmath.mpf(hi)
    return np.array([[lo, hi]])


def holds(box: np.ndarray, truth) -> bool:
    return mpmath.mpf(box[0, 0]) <= mpmath.mpf(truth) <= mpmath.mpf(box[0, 1])


def within(after: np.ndarray, before: np.ndarray) -> bool:
    return bool(after[0, 0] >= before[0, 0] and after[0, 1] <= before[0, 1])


pair = st.tuples(spread, spread)


# ---------------------------------------------------------------- unicycle
@SETTINGS
@given(
    x0=coord, y0=coord, th0=angle,
    v=st.one_of(st.floats(-2.0, 2.0), st.just(0.0), st.floats(-1e-6, 1e-6)),
    w=st.floats(-1.5, 1.5), dt=st.one_of(st.floats(1e-3, 1.0), st.just(0.1)),
    q=st.tuples(st.floats(-0.05, 0.05), st.floats(-0.05, 0.05), st.floats(-0.02, 0.02)),
    branches=st.tuples(st.integers(-2, 2), st.integers(-2, 2)),
    s=st.lists(pair, min_size=12, max_size=12),
)
def test_unicycle_never_loses_the_truth(x0, y0, th0, v, w, dt, q, branches, s):
    qx, qy, qth = q
    T0 = th0 if branches[0] == 0 else mpmath.mpf(th0) + 2 * branches[0] * mpmath.pi
    X1 = x0 + mpmath.mpf(v) * dt * mpmath.cos(th0) + qx
    Y1 = y0 + mpmath.mpf(v) * dt * mpmath.sin(th0) + qy
    # th1 = th0 + w dt + qth holds modulo 2 pi: put th1 in another branch than th0
    T1 = mpmath.mpf(th0) + mpmath.mpf(w) * dt + qth + 2 * branches[1] * mpmath.pi
    truth = (x0, y0, T0, X1, Y1, T1, v, w, dt, qx, qy, qth)
    boxes = [around(t, sp) for t, sp in zip(truth, s)]
    before = [b.copy() for b in boxes]
    ok = unicycle(*boxes)
    assert ok[0]
    for b, t, b0 in zip(boxes, truth, before):
        assert holds(b, t)
        assert within(b, b0)


def test_unicycle_contracts_the_next_pose_forward_and_reversing():
    for v, x_true in ((1.0, 1.0), (-1.0, -1.0)):
        b = {k: np.array([[0.0, 0.0]]) for k in ("x0", "y0", "th0")}
        b |= {k: np.array([[-10.0, 10.0]]) for k in ("x1", "y1", "th1")}
        b |= {"v": np.array([[v, v]]), "w": np.array([[0.5, 0.5]]), "dt": np.array([[1.0, 1.0]]),
              "qx": np.array([[-0.01, 0.01]]), "qy": np.array([[-0.01, 0.01]]),
              "qth": np.array([[-0.02, 0.02]])}
        assert unicycle(*b.values())[0]
        np.testing.assert_allclose(b["x1"][0], [x_true - 0.01, x_true + 0.01], atol=1e-12)
        np.testing.assert_allclose(b["y1"][0], [-0.01, 0.01], atol=1e-12)
        # th1 in [-10, 10] holds 0.5 + [-0.02, 0.02] + 2 pi k for k = -1, 0, 1: hull of those
        np.testing.assert_allclose(b["th1"][0], [0.48 - 2 * math.pi, 0.52 + 2 * math.pi], atol=1e-12)


def _step(**kw):
    d = {"x0": [0.0, 0.0], "y0": [0.0, 0.0], "th0": [-math.pi, math.pi],
         "x1": [2.0, 2.0], "y1": [0.0, 0.0], "th1": [-0.1, 0.1],
         "v": [-5.0, 5.0], "w": [-1.0, 1.0], "dt": [1.0, 1.0],
         "qx": [-0.01, 0.01], "qy": [-0.01, 0.01], "qth": [0.0, 0.0]}
    d |= kw
    return {k: np.array([v], dtype=float) for k, v in d.items()}


def test_unicycle_contracts_the_past_and_the_inputs():
    # Known start and end pose (x1 - x0 = (2, 0) +- 0.01), unknown heading and speed.
    # Any turn allowed: forward along th0 ~ 0 or reversing with th0 ~ ±pi, |v| in [1.99, 2.01]
    b = _step(w=[-4.0, 4.0])
    assert unicycle(*b.values())[0]
    assert -2.02 < b["v"][0, 0] < -1.98 and 1.98 < b["v"][0, 1] < 2.02
    # |w dt| <= 1 and th1 ~ 0: th0 is within 1.1 of 0, so only forward motion is possible
    b = _step()
    assert unicycle(*b.values())[0]
    assert 1.98 < b["v"][0, 0] and b["v"][0, 1] < 2.02
    assert -0.01 < b["th0"][0, 0] and b["th0"][0, 1] < 0.01
    # and then w = th1 - th0 is known to +- 0.11
    assert -0.12 < b["w"][0, 0] and b["w"][0, 1] < 0.12
    # a heading box near pi forces reversing
    b = _step(th0=[3.0, 3.3], th1=[3.0, 3.3])
    assert unicycle(*b.values())[0]
    assert -2.02 < b["v"][0, 0] and b["v"][0, 1] < -1.98


def test_unicycle_detects_an_impossible_step():
    b = {k: np.array([[0.0, 0.0]]) for k in ("x0", "y0", "th0", "y1", "th1", "w", "qx", "qy", "qth")}
    b["x1"] = np.array([[5.0, 6.0]])  # moved 5 m in one second at speed <= 1
    b["v"] = np.array([[0.0, 1.0]])
    b["dt"] = np.array([[1.0, 1.0]])
    order = ("x0", "y0", "th0", "x1", "y1", "th1", "v", "w", "dt", "qx", "qy", "qth")
    ok = unicycle(*(b[k] for k in order))
    assert not ok[0]
    for k in order:
        assert b[k][0, 0] == INF and b[k][0, 1] == -INF


# ---------------------------------------------------------------- range-bearing
@SETTINGS
@given(
    sx=coord, sy=coord, sth=angle, mx=coord, my=coord,
    coincide=st.booleans(),
    free_alpha=angle,
    branches=st.tuples(st.integers(-2, 2), st.integers(-2, 2)),
    s=st.lists(pair, min_size=7, max_size=7),
)
def test_range_bearing_never_loses_the_truth(sx, sy, sth, mx, my, coincide, free_alpha, branches, s):
    _rb_keeps_the_truth(range_bearing, sx, sy, sth, mx, my, coincide, free_alpha, branches, s)


@SETTINGS
@given(
    sx=coord, sy=coord, sth=angle, mx=coord, my=coord,
    coincide=st.booleans(),
    free_alpha=angle,
    branches=st.tuples(st.integers(-2, 2), st.integers(-2, 2)),
    s=st.lists(pair, min_size=7, max_size=7),
    passes=st.integers(1, 3),
)
def test_range_bearing_pass_never_loses_the_truth(sx, sy, sth, mx, my, coincide, free_alpha, branches, s, passes):
    _rb_keeps_the_truth(lambda *b: range_bearing_pass(*b, passes=passes), sx, sy, sth, mx, my, coincide,
                        free_alpha, branches, s)


def _rb_keeps_the_truth(contract, sx, sy, sth, mx, my, coincide, free_alpha, branches, s):
    if coincide:  # landmark on the robot: rho = 0, any bearing is a solution
        mx, my = sx, sy
    dx = mpmath.mpf(mx) - mpmath.mpf(sx)
    dy = mpmath.mpf(my) - mpmath.mpf(sy)
    rho = mpmath.sqrt(dx * dx + dy * dy)
    if rho == 0:
        alpha = mpmath.mpf(free_alpha)
    else:
        alpha = mpmath.atan2(dy, dx) - sth
    alpha = alpha + 2 * branches[0] * mpmath.pi
    sth_t = sth if branches[1] == 0 else mpmath.mpf(sth) + 2 * branches[1] * mpmath.pi
    truth = (sx, sy, sth_t, mx, my, rho, alpha)
    boxes = [around(t, sp) for t, sp in zip(truth, s)]
    before = [b.copy() for b in boxes]
    ok = contract(*boxes)
    assert ok[0]
    for b, t, b0 in zip(boxes, truth, before):
        assert holds(b, t)
        assert within(b, b0)


def _rb(**kw):
    d = {"sx": [0.0, 0.0], "sy": [0.0, 0.0], "sth": [0.0, 0.0], "mx": [-INF, INF],
         "my": [-INF, INF], "rho": [0.0, INF], "alpha": [-INF, INF]}
    d |= kw
    return {k: np.array([v], dtype=float) for k, v in d.items()}


@pytest.mark.parametrize("contract", [range_bearing, range_bearing_pass])
def test_range_bearing_locates_the_landmark(contract):
    # robot at the origin facing +y; landmark seen at 5 m, 10 degrees right of the heading
    b = _rb(sth=[math.pi / 2, math.pi / 2], rho=[4.9, 5.1], alpha=[-0.18, -0.17])
    assert contract(*b.values())[0]
    phi = (math.pi / 2 - 0.18, math.pi / 2 - 0.17)
    xs = [r * math.cos(p) for r in (4.9, 5.1) for p in phi]
    ys = [r * math.sin(p) for r in (4.9, 5.1) for p in phi]
    np.testing.assert_allclose(b["mx"][0], [min(xs), max(xs)], atol=1e-9)
    np.testing.assert_allclose(b["my"][0], [min(ys), max(ys)], atol=1e-9)


@pytest.mark.parametrize("contract", [range_bearing, range_bearing_pass])
def test_range_bearing_locates_the_robot_heading(contract):
    # landmark known at (0, 5), robot at the origin, bearing measured 0.3 rad left: heading -0.3
    b = _rb(mx=[0.0, 0.0], my=[5.0, 5.0], sth=[-10.0, 10.0], alpha=[0.29, 0.31])
    assert contract(*b.values())[0]
    np.testing.assert_allclose(b["rho"][0], [5.0, 5.0], atol=1e-12)
    # sth = pi/2 - alpha + 2 pi k inside [-10, 10]: k = -1, 0, 1
    np.testing.assert_allclose(
        b["sth"][0], [math.pi / 2 - 0.31 - 2 * math.pi, math.pi / 2 - 0.29 + 2 * math.pi], atol=1e-12)
    b = _rb(mx=[0.0, 0.0], my=[5.0, 5.0], sth=[-1.0, 2.0], alpha=[0.29, 0.31])
    assert contract(*b.values())[0]
    np.testing.assert_allclose(b["sth"][0], [math.pi / 2 - 0.31, math.pi / 2 - 0.29], atol=1e-12)


@pytest.mark.parametrize("contract", [range_bearing, range_bearing_pass])
def test_range_bearing_across_the_cut(contract):
    # landmark behind the robot, right on the ±pi cut of atan2: both sides must survive
    b = _rb(mx=[-5.0, -5.0], my=[-0.1, 0.1], alpha=[-4.0, 4.0])
    assert contract(*b.values())[0]
    # true bearings: [a, pi] and [-pi, -a] (a = atan2(0.1, -5)), plus their copies 2 pi away
    # inside [-4, 4]: the hull is [a - 2 pi, 2 pi - a], around both -pi and pi
    a = math.atan2(0.1, -5.0)
    np.testing.assert_allclose(b["alpha"][0], [a - 2 * math.pi, 2 * math.pi - a], rtol=1e-12)


@pytest.mark.parametrize("contract", [range_bearing, range_bearing_pass])
def test_range_bearing_detects_an_inconsistent_observation(contract):
    b = _rb(mx=[3.0, 3.0], my=[4.0, 4.0], rho=[6.0, 7.0])  # true range is 5
    ok = contract(*b.values())
    assert not ok[0]
    assert all(a[0, 0] == INF and a[0, 1] == -INF for a in b.values())
    b = _rb(mx=[3.0, 3.0], my=[4.0, 4.0], alpha=[-0.5, 0.5])  # true bearing atan2(4, 3) = 0.927
    assert not contract(*b.values())[0]


def test_rows_are_independent_and_in_place():
    rng = np.random.default_rng(3)
    n = 200
    s = rng.uniform(-5, 5, (n, 2))
    m = rng.uniform(-5, 5, (n, 2))
    d = m - s
    rho = np.hypot(d[:, 0], d[:, 1])
    alpha = np.arctan2(d[:, 1], d[:, 0])
    rho[::7] += 3.0  # every 7th row is inconsistent
    arrs = [np.c_[s[:, 0] - 0.01, s[:, 0] + 0.01], np.c_[s[:, 1] - 0.01, s[:, 1] + 0.01],
            np.full((n, 2), [-math.pi, math.pi]), np.c_[m[:, 0] - 0.01, m[:, 0] + 0.01],
            np.c_[m[:, 1] - 0.01, m[:, 1] + 0.01], np.c_[rho - 0.05, rho + 0.05],
            np.c_[alpha - 0.02, alpha + 0.02]]
    one_by_one = [a.copy() for a in arrs]
    ok = range_bearing(*arrs)
    assert not ok[::7].any() and ok.sum() == n - len(range(0, n, 7))
    for i in range(n):
        rows = [a[i:i + 1].copy() for a in one_by_one]
        assert range_bearing(*rows)[0] == ok[i]
        for r, a in zip(rows, arrs):
            np.testing.assert_array_equal(r[0], a[i])
    far = ok & (rho > 2.0)
    assert far.sum() > 50
    assert (arrs[2][far, 1] - arrs[2][far, 0] < 0.1).all()  # the heading was found


def test_api_rejects_arrays_it_cannot_write():
    good = [np.array([[0.0, 1.0]]) for _ in range(7)]
    with pytest.raises(TypeError, match="mx"):
        range_bearing(*good[:3], np.array([[0.0, 1.0]], dtype=np.float32), *good[4:])
    with pytest.raises(ValueError, match="rows"):
        range_bearing(*good[:6], np.zeros((2, 2)))
    with pytest.raises(ValueError, match="contiguous"):
        range_bearing(np.zeros((2, 4))[:, ::2], *[np.zeros((2, 2)) for _ in range(6)])
    with pytest.raises(TypeError, match="qth"):
        unicycle(*[np.array([[0.0, 1.0]]) for _ in range(11)], [[0.0, 1.0]])
