"""The polar kernel's pieces route (boxes near an axis or around the origin, each closed
quadrant piece a lane of its own) against the truth (mpmath) and against the scalar kernel.

Truths are real points (mpmath, 120 bits) near an axis, with float boxes built outward around
them wide enough to straddle it; the boxes go through the public kernel in batches, so the
buffered, flushed route is what is tested. Relation to ``polar_scalar``: the same rows emptied
(but for boxes empty within rounding), no bound outside its result beyond the rounding tolerance of the Codac crosscheck
(``bench_kernels._looser``), as in tests/contractors/test_polar_simd.py.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.bench_kernels import _looser, rounding_tolerance
from ivslam_cli.contractors.ctc_polar import polar_kernel
from ivslam_cli.contractors.ctc_polar_pieces import MAX_PIECES, PB, PROWS, _arc_copy, _take
from ivslam_cli.contractors.ctc_polar_simd import _setup, polar_simd_kernel
from ivslam_cli.contractors.simd_polar_lanes import CHUNK, ROWS
from tests.helpers.exact import around
from tests.helpers.hyp import examples

mpmath.mp.prec = 120
AXES = [0.0, math.pi / 2, math.pi, -math.pi / 2, -math.pi]
near_axis = st.tuples(
    st.one_of(st.floats(1e-3, 1.0), st.floats(0.5, 100.0), st.floats(1e4, 1e6)),  # rho
    st.sampled_from(AXES),
    st.one_of(st.just(0.0), st.floats(-1e-9, 1e-9), st.floats(-1e-3, 1e-3), st.floats(-0.3, 0.3)),
    st.integers(-3, 3),  # branch
    st.lists(st.one_of(st.just(0.0), st.floats(0.0, 1e-9), st.floats(0.0, 1e-3),
                       st.floats(0.0, 0.5), st.floats(0.0, 3.0)), min_size=8, max_size=8),
    st.floats(0.0, 1.0),  # how far the box reaches across the axis, relative to rho
)


def _boxes(points):
    """Boxes around the true points, each widened across the nearest axis of ``(dx, dy)``."""
    truths, rows = [], []
    for rho, axis, off, branch, m, across in points:
        R, T = mpmath.mpf(rho), mpmath.mpf(axis) + mpmath.mpf(off)
        X, Y = R * mpmath.cos(T), R * mpmath.sin(T)
        t_real = T + 2 * branch * mpmath.pi
        m = list(m)
        reach = across * rho
        if axis in (math.pi / 2, -math.pi / 2):  # on the y axis: x straddles 0
            m[0 if X >= 0 else 1] = max(m[0 if X >= 0 else 1], abs(float(X)) + reach)
        else:
            m[2 if Y >= 0 else 3] = max(m[2 if Y >= 0 else 3], abs(float(Y)) + reach)
        truths.append((X, Y, R, t_real))
        rows.append([around(X, m[0], m[1]), around(Y, m[2], m[3]), around(R, m[4], m[5]),
                     around(t_real, m[6], m[7])])
    b = np.array(rows)
    return truths, [np.ascontiguousarray(b[:, j]) for j in range(4)]


@settings(max_examples=examples(ci=300))
@given(st.lists(near_axis, min_size=1, max_size=60))
def test_pieces_never_lose_the_truth(points):
    truths, arrays = _boxes(points)
    before = [a.copy() for a in arrays]
    ok = polar_simd_kernel(*arrays)
    assert ok.all()
    for k, truth in enumerate(truths):
        for j in range(4):
            assert mpmath.mpf(arrays[j][k, 0]) <= truth[j] <= mpmath.mpf(arrays[j][k, 1]), (k, j)
            assert arrays[j][k, 0] >= before[j][k, 0] and arrays[j][k, 1] <= before[j][k, 1]


def _scalar_and_simd(arrays):
    s = [a.copy() for a in arrays]
    v = [a.copy() for a in arrays]
    return s, v, polar_kernel(*s), polar_simd_kernel(*v)


def _empty_alike(arrays, ok_s, ok_v):
    """The rows one kernel empties and the other keeps are empty within rounding: each, widened
    by :func:`rounding_tolerance` of its input, is kept by the kernel that emptied it (a box empty
    by more than rounding stays empty, and fails)."""
    rows = np.flatnonzero(ok_s != ok_v)
    if rows.size == 0:
        return
    box = np.stack(arrays)[:, rows]
    tol_xyr, tol_t = rounding_tolerance(box)
    wide = [np.ascontiguousarray(box[j] + np.outer(tol_xyr if j < 3 else tol_t, [-1.0, 1.0])) for j in range(4)]
    wide[2][:, 0] = np.maximum(wide[2][:, 0], 0.0)
    for r, k in enumerate(rows):
        one = [np.ascontiguousarray(w[r:r + 1]) for w in wide]
        kept = (polar_kernel if ok_v[k] else polar_simd_kernel)(*one)
        assert kept[0], (k, box[:, r].tolist())


@settings(max_examples=examples(ci=300))
@given(st.lists(near_axis, min_size=1, max_size=60), st.floats(0.0, 2.0), st.integers(0, 3))
def test_pieces_never_looser_than_the_scalar_kernel(points, rho_shift, which):
    """Near-axis boxes, some shifted off their truth (rho moved, or theta) so that some have
    no solution: the same rows emptied as ``polar_scalar``, no bound outside its result
    beyond rounding."""
    _, arrays = _boxes(points)
    if which == 1:
        arrays[2][::2] += rho_shift * np.abs(arrays[2][::2, 1:2])
    elif which == 2:
        arrays[3][::3] += rho_shift
    s, v, ok_s, ok_v = _scalar_and_simd(arrays)
    _empty_alike(arrays, ok_s, ok_v)
    both = ok_s & ok_v
    _, beyond = _looser(np.stack(v)[:, both], np.stack(s)[:, both])
    assert beyond == 0


@settings(max_examples=examples(ci=200))
@given(st.lists(st.tuples(st.floats(0.01, 10.0), st.floats(-math.pi, math.pi), st.integers(-2, 2),
                          st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.floats(0.0, 4.6)),
                min_size=1, max_size=40))
def test_four_pieces_around_the_origin(rows):
    """``(dx, dy)`` boxes around the origin with ``rho > 0`` (four pieces): the truth kept, the
    same rows emptied as ``polar_scalar`` and never looser than it beyond rounding."""
    truths, b = [], []
    for rho, theta, branch, a, c, w in rows:
        R, T = mpmath.mpf(rho), mpmath.mpf(theta)
        X, Y = R * mpmath.cos(T), R * mpmath.sin(T)
        t_real = T + 2 * branch * mpmath.pi
        truths.append((X, Y, R, t_real))
        ex, ey = abs(float(X)) + a * rho + 1e-9, abs(float(Y)) + c * rho + 1e-9
        b.append([around(X, ex + float(X), ex - float(X)), around(Y, ey + float(Y), ey - float(Y)),
                  around(R, 0.5 * rho, 0.1 * rho), around(t_real, w * 0.5, w * 0.5)])
    arrays = [np.ascontiguousarray(np.array(b)[:, j]) for j in range(4)]
    s, v, ok_s, ok_v = _scalar_and_simd(arrays)
    assert ok_v.all() and np.array_equal(ok_s, ok_v)
    for k, truth in enumerate(truths):
        for j in range(4):
            assert mpmath.mpf(v[j][k, 0]) <= truth[j] <= mpmath.mpf(v[j][k, 1]), (k, j)
    _, beyond = _looser(np.stack(v)[:, ok_s], np.stack(s)[:, ok_s])
    assert beyond == 0


def test_route_takes_the_near_axis_boxes_and_leaves_the_others():
    """:func:`_take` takes a box off the fast path with finite bounds and a narrow theta unless
    its ``(dx, dy)`` box holds the origin with ``rho`` reaching 0; a box takes at most
    ``MAX_PIECES`` lanes, one per non-empty piece."""
    inf = np.inf
    cases = [
        ([-0.1, 0.2, 3.0, 4.0, 0.0, 5.0, 1.4, 1.7], True, 2),  # x straddles 0
        ([0.0, 1.0, 0.5, 1.0, 0.0, 2.0, 0.0, 2.0], True, 2),  # on the y axis: u = [0, 0] piece
        ([2.0, 3.0, -0.5, 0.5, 0.0, 5.0, 0.1, 0.2], True, 1),  # theta meets only one arc
        ([-1.0, 1.0, -1.0, 1.0, 0.5, 2.0, -4.0, 0.6], True, 4),  # the origin, rho > 0
        ([-1.0, 1.0, -1.0, 1.0, 0.0, 2.0, -4.0, 0.6], False, 0),  # the origin, rho from 0
        ([-inf, inf, 1.0, 2.0, 0.0, 3.0, 0.0, 3.0], False, 0),  # unbounded
        ([-1.0, 2.0, 1.0, 2.0, 0.0, 5.0, -10.0, 10.0], False, 0),  # theta wider than 4.7
    ]
    C = CHUNK
    for row, taken, lanes in cases:
        assert not _setup(row[0], row[1], row[2], row[3], max(row[4], 0.0), *row[5:])[0]
        flat = [np.array(row[2 * j:2 * j + 2]) for j in range(4)]
        L, P = np.empty(ROWS * C), np.empty(PROWS * C)
        tb, rows, cnt = np.empty((C, 2)), np.empty(C, np.int64), np.zeros(2, np.int64)
        assert _take(0, *flat, L, P, tb, rows, cnt) == taken, row
        assert cnt[0] == lanes <= MAX_PIECES and cnt[1] == (1 if taken else 0), row
        assert all(P[PB * C + i] == 0.0 for i in range(lanes))


@settings(max_examples=examples(ci=300))
@given(st.integers(0, 3), st.floats(-1e5, 1e5), st.floats(0.0, 4.69))
def test_arc_copy_is_the_only_copy_meeting_theta(q, mid, w):
    """Of the copies ``k0 - 2 .. k0 + 2`` of the quadrant's arc, none but :func:`_arc_copy`'s
    meets theta (mpmath), and its psi is non-empty when it does."""
    tl, th = mid - 0.5 * w, mid + 0.5 * w
    cl, ch, pl, ph = _arc_copy(q, tl, th)
    c0 = [0, 0, -1, 1][q] * mpmath.pi
    lo = [0, -mpmath.pi / 2, -mpmath.pi, mpmath.pi / 2][q]
    k0 = mpmath.nint((mpmath.mpf(cl) - c0) / (2 * mpmath.pi))
    assert mpmath.mpf(cl) <= 2 * k0 * mpmath.pi + c0 <= mpmath.mpf(ch)
    for dk in range(-2, 3):
        a = lo + 2 * (k0 + dk) * mpmath.pi
        meets = a <= mpmath.mpf(th) and mpmath.mpf(tl) <= a + mpmath.pi / 2
        assert not meets or (dk == 0 and pl <= ph)
