"""Vectorised interval operations over ``(N, 2)`` float64 arrays (column 0 = lo, 1 = hi).

Thin numba loops over the scalar kernels of :mod:`arith` and :mod:`angles`; each returns
a new array. Empty rows are ``[+inf, -inf]``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ivslam_cli.interval import angles as A
from ivslam_cli.interval import arith as K
from ivslam_cli.interval.rounding import ensure_round_to_nearest


@njit(cache=True)
def _unary(code, a):
    n = a.shape[0]
    out = np.empty((n, 2))
    for i in range(n):
        lo, hi = a[i, 0], a[i, 1]
        if code == 0:
            r = K.sqr(lo, hi)
        elif code == 1:
            r = K.sqrt(lo, hi)
        elif code == 2:
            r = K.sin(lo, hi)
        elif code == 3:
            r = K.cos(lo, hi)
        elif code == 4:
            r = K.atan(lo, hi)
        else:
            r = K.neg(lo, hi)
        out[i, 0] = r[0]
        out[i, 1] = r[1]
    return out


@njit(cache=True)
def _binary(code, a, b):
    n = a.shape[0]
    out = np.empty((n, 2))
    for i in range(n):
        al, ah, bl, bh = a[i, 0], a[i, 1], b[i, 0], b[i, 1]
        if code == 0:
            r = K.add(al, ah, bl, bh)
        elif code == 1:
            r = K.sub(al, ah, bl, bh)
        elif code == 2:
            r = K.mul(al, ah, bl, bh)
        elif code == 3:
            r = K.div(al, ah, bl, bh)
        elif code == 4:
            r = K.inter(al, ah, bl, bh)
        elif code == 5:
            r = K.hull(al, ah, bl, bh)
        elif code == 6:
            r = A.atan2(al, ah, bl, bh)
        else:
            r = A.angle_meet(al, ah, bl, bh)
        out[i, 0] = r[0]
        out[i, 1] = r[1]
    return out


@njit(cache=True)
def _backward(code, z, x, y):
    n = z.shape[0]
    xo = np.empty((n, 2))
    yo = np.empty((n, 2))
    for i in range(n):
        zl, zh = z[i, 0], z[i, 1]
        xl, xh, yl, yh = x[i, 0], x[i, 1], y[i, 0], y[i, 1]
        if code == 0:
            r = K.bwd_add(zl, zh, xl, xh, yl, yh)
        elif code == 1:
            r = K.bwd_sub(zl, zh, xl, xh, yl, yh)
        else:
            r = K.bwd_mul(zl, zh, xl, xh, yl, yh)
        xo[i, 0], xo[i, 1], yo[i, 0], yo[i, 1] = r[0], r[1], r[2], r[3]
    return xo, yo


@njit(cache=True)
def _backward_unary(code, z, x):
    n = z.shape[0]
    xo = np.empty((n, 2))
    for i in range(n):
        if code == 0:
            r = K.bwd_sqr(z[i, 0], z[i, 1], x[i, 0], x[i, 1])
        else:
            r = K.bwd_sqrt(z[i, 0], z[i, 1], x[i, 0], x[i, 1])
        xo[i, 0], xo[i, 1] = r[0], r[1]
    return xo


@njit(cache=True)
def _width(a):
    n = a.shape[0]
    out = np.empty(n)
    for i in range(n):
        out[i] = K.width(a[i, 0], a[i, 1])
    return out


def _arr(a) -> np.ndarray:
    ensure_round_to_nearest()
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.ndim == 1 and a.shape[0] == 2:
        a = a.reshape(1, 2)
    if a.ndim != 2 or a.shape[1] != 2:
        raise ValueError(f"expected an (N, 2) array of [lo, hi] rows, got shape {a.shape}")
    return a


def sqr(a):
    return _unary(0, _arr(a))


def sqrt(a):
    return _unary(1, _arr(a))


def sin(a):
    return _unary(2, _arr(a))


def cos(a):
    return _unary(3, _arr(a))


def atan(a):
    return _unary(4, _arr(a))


def neg(a):
    return _unary(5, _arr(a))


def add(a, b):
    return _binary(0, _arr(a), _arr(b))


def sub(a, b):
    return _binary(1, _arr(a), _arr(b))


def mul(a, b):
    return _binary(2, _arr(a), _arr(b))


def div(a, b):
    return _binary(3, _arr(a), _arr(b))


def inter(a, b):
    return _binary(4, _arr(a), _arr(b))


def hull(a, b):
    return _binary(5, _arr(a), _arr(b))


def atan2(y, x):
    """``atan2([y], [x])`` within ``[-pi, pi]`` (hull across the cut)."""
    return _binary(6, _arr(y), _arr(x))


def angle_meet(t, a):
    """``[t] ∩ ([a] + 2 pi Z)`` in ``[t]``'s branch."""
    return _binary(7, _arr(t), _arr(a))


def bwd_add(z, x, y):
    """Contracted ``(x, y)`` under ``z = x + y``."""
    return _backward(0, _arr(z), _arr(x), _arr(y))


def bwd_sub(z, x, y):
    """Contracted ``(x, y)`` under ``z = x - y``."""
    return _backward(1, _arr(z), _arr(x), _arr(y))


def bwd_mul(z, x, y):
    """Contracted ``(x, y)`` under ``z = x * y``."""
    return _backward(2, _arr(z), _arr(x), _arr(y))


def bwd_sqr(z, x):
    """Contracted ``x`` under ``z = x^2``."""
    return _backward_unary(0, _arr(z), _arr(x))


def bwd_sqrt(z, x):
    """Contracted ``x`` under ``z = sqrt(x)``."""
    return _backward_unary(1, _arr(z), _arr(x))


def width(a):
    return _width(_arr(a))


def is_empty(a):
    a = _arr(a)
    return ~(a[:, 0] <= a[:, 1])


def empty(n: int) -> np.ndarray:
    """``n`` empty intervals."""
    out = np.empty((n, 2))
    out[:, 0] = np.inf
    out[:, 1] = -np.inf
    return out


def sym(half) -> np.ndarray:
    """``[-h, h]`` rows for non-negative upper bounds ``h`` (a symmetric error interval)."""
    half = np.asarray(half, dtype=np.float64)
    return np.column_stack([-half, half])


def point(a) -> np.ndarray:
    """Degenerate rows ``[a, a]``."""
    a = np.asarray(a, dtype=np.float64)
    return np.column_stack([a, a])


def bound_up(value: float) -> float:
    """The upper end of the interval enclosing a decimal bound (``0`` stays ``0``)."""
    from ivslam_cli.interval.rounding import enclose

    return enclose(value)[1] if value else 0.0
