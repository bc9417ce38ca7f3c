"""Outward rounding for float64 under the default round-to-nearest mode.

``down(c)`` returns a float ``<= pred(c)`` and ``up(c)`` one ``>= succ(c)`` (one ulp, twice at
power-of-two boundaries), using the branch-free PredSucc method of Rump, Zimmermann, Boldo and
Melquiond ("Computing predecessor and successor in rounding to nearest", BIT 2009):
``c -/+ (phi*|c| + eta)`` with ``phi = 2^-53 (1 + 2^-52)`` and ``eta = 2^-1074``. It costs two
flops instead of a libm ``nextafter`` call. Since every IEEE operation (+ - * / sqrt) is
within half an ulp of the exact result, applying ``down``/``up`` to a rounded-to-nearest result
encloses the exact one.

Transcendental functions (sin, cos, tan, atan, atan2 from libm) are not correctly rounded but
are within one ulp on the platforms we support (glibc); ``down2``/``up2`` step two ulps.

NaN never escapes: ``down(nan) = -inf`` and ``up(nan) = +inf`` (a sound, if loose, answer
when an operation was undefined such as ``inf - inf``).

Decimal constants (0.1, pi) are not doubles: ``PI_LO < pi < PI_HI`` etc. enclose them, and
user-given bounds are widened by ``enclose`` before use.
"""

from __future__ import annotations

import ctypes
import math

import numpy as np
from numba import njit

INF = np.inf
_PHI = 2.0**-53 * (1.0 + 2.0**-52)
_ETA = 2.0**-1074

# math.pi is the double nearest to pi, and it is below pi.
PI_LO = math.pi
PI_HI = float(np.nextafter(math.pi, INF))
TWO_PI_LO = 2.0 * PI_LO  # exact scaling by 2
TWO_PI_HI = 2.0 * PI_HI
HALF_PI_LO = 0.5 * PI_LO
HALF_PI_HI = 0.5 * PI_HI
# 1 / (2 pi): the double quotient is within 2 ulps of the real number; step 2 ulps each way.
INV_TWO_PI_LO = float(np.nextafter(np.nextafter(1.0 / (2.0 * math.pi), -INF), -INF))
INV_TWO_PI_HI = float(np.nextafter(np.nextafter(1.0 / (2.0 * math.pi), INF), INF))


@njit(cache=True)
def down(c: float) -> float:
    """A float <= the predecessor of ``c`` (``-inf`` for NaN)."""
    r = c - (_PHI * abs(c) + _ETA)
    if r != r:
        return -INF
    return r


@njit(cache=True)
def up(c: float) -> float:
    """A float >= the successor of ``c`` (``+inf`` for NaN)."""
    r = c + (_PHI * abs(c) + _ETA)
    if r != r:
        return INF
    return r


@njit(cache=True, inline="always")
def down_raw(c: float) -> float:
    """``down(c)`` without its NaN guard: the same float, except NaN where ``down`` gives
    ``-inf`` for ``c = +inf`` or NaN. For a lower bound that only enters ``max`` as the
    argument a NaN of which is ignored (``b if b > a else a``): the same result, two
    operations fewer (SIMD loops)."""
    return c - (_PHI * abs(c) + _ETA)


@njit(cache=True, inline="always")
def up_raw(c: float) -> float:
    """``up(c)`` without its NaN guard (NaN where ``up`` gives ``+inf`` for ``c = -inf`` or
    NaN); see :func:`down_raw`."""
    return c + (_PHI * abs(c) + _ETA)


@njit(cache=True, inline="always")
def down_pos(c: float) -> float:
    """:func:`down_raw` for ``c >= 0`` (``±0``, ``+inf`` and NaN included), without the
    ``abs``: not a lower bound for ``c < 0``, so only where ``c`` is a product, quotient, sum
    or square root of non-negative bounds."""
    return c - (_PHI * c + _ETA)


@njit(cache=True, inline="always")
def up_pos(c: float) -> float:
    """:func:`up_raw` for ``c >= 0`` (``±0``, ``+inf`` and NaN included), without the ``abs``:
    not an upper bound for ``c < 0``; see :func:`down_pos`."""
    return c + (_PHI * c + _ETA)


@njit(cache=True)
def down2(c: float) -> float:
    """Two ulps down: lower bound of a libm transcendental result."""
    return down(down(c))


@njit(cache=True)
def up2(c: float) -> float:
    """Two ulps up: upper bound of a libm transcendental result."""
    return up(up(c))


def enclose(value: float) -> tuple[float, float]:
    """An interval of doubles that holds the real number the user meant by ``value``.

    ``0.1`` in a config is the double nearest to 1/10, not 1/10: widen it by an ulp on
    each side so the decimal the user wrote is inside.
    """
    v = float(value)
    return float(np.nextafter(v, -INF)), float(np.nextafter(v, INF))


# --- the FPU rounding mode ---------------------------------------------------------------
# Everything above assumes round-to-nearest. Other libraries may leave another mode behind
# (importing Codac leaves round-upward), so every Python entry point calls this first.
_FE_TONEAREST = 0  # glibc, x86-64 and aarch64


def _libm() -> ctypes.CDLL | None:
    """The C maths library, or None if there is none to ask (then there is nothing to restore)."""
    try:
        return ctypes.CDLL("libm.so.6")  # glibc, by its soname: no ldconfig run by find_library
    except OSError:  # pragma: no cover - not glibc
        from ctypes.util import find_library

        name = find_library("m")
        try:
            return ctypes.CDLL(name) if name else None
        except OSError:
            return None


_LIBM = _libm()
if _LIBM is not None:
    _LIBM.fegetround.restype = ctypes.c_int


def ensure_round_to_nearest() -> None:
    """Restore round-to-nearest if something in this process changed the rounding mode."""
    if _LIBM is not None and _LIBM.fegetround() != _FE_TONEAREST:
        _LIBM.fesetround(_FE_TONEAREST)
