"""Polar contractor: the truth is never lost (hypothesis), contraction happens, the origin is kept."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ivslam_cli.contractors import polar

mpmath.mp.prec = 120
SETTINGS = settings(max_examples=1500, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def around(value: mpmath.mpf, below: float, above: float) -> list[float]:
    """A float interval that surely holds the real ``value`` (outward by an ulp past the margins)."""
    v = float(value)
    lo = float(np.nextafter(v - below, -np.inf))
    hi = float(np.nextafter(v + above, np.inf))
    assert mpmath.mpf(lo) <= value <= mpmath.mpf(hi)
    return [lo, hi]


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
