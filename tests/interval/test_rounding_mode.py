"""The kernels assume round-to-nearest; another library may leave another mode behind.

Importing Codac leaves the FPU rounding upward. Every Python entry point restores
round-to-nearest first, so the guarantee does not depend on what else the process loaded.
"""

from __future__ import annotations

import ctypes
import ctypes.util
from fractions import Fraction

import numpy as np

from ivslam_cli import contractors, interval as iv

_LIBM = ctypes.CDLL(ctypes.util.find_library("m") or "libm.so.6")
FE_UPWARD = 0x800  # glibc x86-64
FE_DOWNWARD = 0x400


def test_entry_points_restore_round_to_nearest():
    try:
        for mode in (FE_UPWARD, FE_DOWNWARD):
            _LIBM.fesetround(mode)
            lo, hi = iv.add([[0.1, 0.1]], [[0.2, 0.2]])[0]
            assert _LIBM.fegetround() == 0
            exact = Fraction(0.1) + Fraction(0.2)
            assert Fraction(lo) < exact < Fraction(hi)
            _LIBM.fesetround(mode)
            dx, dy = np.array([[1.0, 2.0]]), np.array([[1.0, 2.0]])
            contractors.polar(dx, dy, np.array([[0.0, 10.0]]), np.array([[-4.0, 4.0]]))
            assert _LIBM.fegetround() == 0
    finally:
        _LIBM.fesetround(0)
