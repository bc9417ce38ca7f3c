"""Forward-backward contractors over N boxes at once, in place.

Each contractor takes ``(N, 2)`` float64 arrays (one per variable, rows ``[lo, hi]``),
contracts them in place and returns a boolean mask of the rows that stayed non-empty.
An emptied row has every variable set to the empty interval ``[+inf, -inf]``.

Guarantee (all of them): a point of the input box that satisfies the constraint is in the
output box. Nothing else is promised about tightness, but see each module.

    >>> import numpy as np
    >>> from ivslam_cli import contractors as ctc
    >>> dx = np.array([[1.0, 2.0]]); dy = np.array([[1.0, 2.0]])
    >>> rho = np.array([[0.0, 10.0]]); theta = np.array([[-np.pi, np.pi]])
    >>> ctc.polar(dx, dy, rho, theta)        # contracts rho to [1.414.., 2.828..], theta to [0.46.., 1.1..]
    array([ True])
"""

from __future__ import annotations

import numpy as np

from ivslam_cli.contractors._arrays import boxes


def polar(dx: np.ndarray, dy: np.ndarray, rho: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """``dx = rho cos(theta)``, ``dy = rho sin(theta)``, ``rho >= 0`` (theta mod 2 pi)."""
    from ivslam_cli.contractors.ctc_polar import polar_kernel

    n = boxes("dx", dx)
    for name, a in (("dy", dy), ("rho", rho), ("theta", theta)):
        boxes(name, a, n)
    return polar_kernel(dx, dy, rho, theta)


__all__ = ["polar"]
