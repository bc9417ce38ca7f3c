"""Interval arithmetic with outward rounding: the ground floor of every guarantee in ivslam.

Scalar numba kernels live in :mod:`~ivslam_cli.interval.arith` (+ - * / sqr sqrt sin cos atan,
and the backward operations forward-backward contractors need) and
:mod:`~ivslam_cli.interval.angles` (argument of a box, atan2, intervals on the circle).
This module re-exports their vectorised forms over ``(N, 2)`` arrays::

    >>> import numpy as np
    >>> from ivslam_cli import interval as iv
    >>> iv.add([[0.1, 0.2]], [[1.0, 1.0]])   # every x + y, x in [0.1, 0.2], y = 1, is inside
    array([[1.1, 1.2]])                      # (printed to a few digits; bounds are outward)

An interval is ``[lo, hi]``; the empty set is ``[+inf, -inf]`` (``is_empty`` also treats NaN
as empty). See :mod:`~ivslam_cli.interval.rounding` for how rounding is made outward.
"""

from ivslam_cli.interval.rounding import enclose
from ivslam_cli.interval.vector import (
    add,
    angle_meet,
    atan,
    atan2,
    bwd_add,
    bwd_mul,
    bwd_sqr,
    bwd_sqrt,
    bwd_sub,
    cos,
    div,
    empty,
    hull,
    inter,
    is_empty,
    mul,
    neg,
    sin,
    sqr,
    sqrt,
    sub,
    width,
)

__all__ = [
    "add", "angle_meet", "atan", "atan2", "bwd_add", "bwd_mul", "bwd_sqr", "bwd_sqrt",
    "bwd_sub", "cos", "div", "empty", "enclose", "hull", "inter", "is_empty", "mul", "neg",
    "sin", "sqr", "sqrt", "sub", "width",
]
