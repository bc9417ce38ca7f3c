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
    """``dx = rho cos(theta)``, ``dy = rho sin(theta)``, ``rho >= 0`` (theta mod 2 pi).

    Runs the SIMD kernel (:mod:`~ivslam_cli.contractors.ctc_polar_simd`); the scalar
    reference is :func:`ivslam_cli.contractors.ctc_polar.polar_kernel`.
    """
    from ivslam_cli.contractors.ctc_polar_simd import polar_simd_kernel

    n = boxes("dx", dx)
    for name, a in (("dy", dy), ("rho", rho), ("theta", theta)):
        boxes(name, a, n)
    return polar_simd_kernel(dx, dy, rho, theta)


def difference(a: np.ndarray, b: np.ndarray, c: np.ndarray, periodic: bool = False) -> np.ndarray:
    """``a = b - c`` (Mustafa, Codres & Stancu, Eq. (3)-(4)); modulo 2 pi when ``periodic``.

    One forward-backward pass, which for this linear constraint is the fixpoint: the result
    is the smallest box holding the solutions, up to an ulp of outward rounding per bound.
    With ``periodic`` each variable keeps its own branch of the circle.
    """
    from ivslam_cli.contractors.ctc_difference import difference_kernel

    n = boxes("a", a)
    boxes("b", b, n)
    boxes("c", c, n)
    return difference_kernel(a, b, c, bool(periodic))


def unicycle(x0: np.ndarray, y0: np.ndarray, th0: np.ndarray,
             x1: np.ndarray, y1: np.ndarray, th1: np.ndarray,
             v: np.ndarray, w: np.ndarray, dt: np.ndarray,
             qx: np.ndarray, qy: np.ndarray, qth: np.ndarray) -> np.ndarray:
    """One unicycle motion step (the kinematic model of the Guaranteed SLAM slides), all twelve
    variables contracted::

        x1  = x0  + v dt cos(th0) + qx
        y1  = y0  + v dt sin(th0) + qy
        th1 = th0 + w dt + qth            (mod 2 pi)

    ``(x0, y0, th0)`` is the pose at step k-1, ``(x1, y1, th1)`` at step k, ``v, w`` the
    inputs, ``dt`` the (possibly interval) time step, ``qx, qy, qth`` the bounded noise.
    ``v dt`` may have any sign (reversing: the displacement points along ``th0 + pi``);
    headings are angles (any branch; each keeps its own).

    Runs the SIMD kernel (:mod:`~ivslam_cli.contractors.ctc_unicycle_simd`); the scalar
    reference is :func:`ivslam_cli.contractors.ctc_unicycle.unicycle_kernel`.
    """
    from ivslam_cli.contractors.ctc_unicycle_simd import unicycle_simd_kernel

    arrays = (("x0", x0), ("y0", y0), ("th0", th0), ("x1", x1), ("y1", y1), ("th1", th1),
              ("v", v), ("w", w), ("dt", dt), ("qx", qx), ("qy", qy), ("qth", qth))
    n = boxes("x0", x0)
    for name, arr in arrays[1:]:
        boxes(name, arr, n)
    return unicycle_simd_kernel(x0, y0, th0, x1, y1, th1, v, w, dt, qx, qy, qth)


def range_bearing(sx: np.ndarray, sy: np.ndarray, sth: np.ndarray, mx: np.ndarray,
                  my: np.ndarray, rho: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """A range-bearing observation of landmark ``m`` from pose ``s`` (the sensor model of the
    Guaranteed SLAM slides)::

        rho   = |m - s|
        alpha = atan2(my - sy, mx - sx) - sth      (mod 2 pi)

    The measurement noise is folded into ``rho`` and ``alpha`` (``[z] + [r]``); ``rho >= 0``.
    Pose, landmark, ``rho`` and ``alpha`` are all contracted (angles keep their branch).

    Runs the SIMD kernel (:mod:`~ivslam_cli.contractors.ctc_range_bearing_simd`); the scalar
    reference is :func:`ivslam_cli.contractors.ctc_range_bearing.range_bearing_kernel`.
    """
    from ivslam_cli.contractors.ctc_range_bearing_simd import range_bearing_simd_kernel

    n = boxes("sx", sx)
    for name, arr in (("sy", sy), ("sth", sth), ("mx", mx), ("my", my), ("rho", rho),
                      ("alpha", alpha)):
        boxes(name, arr, n)
    return range_bearing_simd_kernel(sx, sy, sth, mx, my, rho, alpha)


def range_bearing_pass(sx: np.ndarray, sy: np.ndarray, sth: np.ndarray, mx: np.ndarray,
                       my: np.ndarray, rho: np.ndarray, alpha: np.ndarray, passes: int = 2) -> np.ndarray:
    """The constraint of :func:`range_bearing`, contracted by at most ``passes`` forward-backward
    passes of its closed form ``m − s = ρ (cos(s_θ + α), sin(s_θ + α))`` (a fraction of the cost
    of the fixpoint; close to it on narrow headings). Same arguments, in place, same guarantee.
    """
    from ivslam_cli.contractors.ctc_range_bearing import range_bearing_pass_kernel

    n = boxes("sx", sx)
    for name, arr in (("sy", sy), ("sth", sth), ("mx", mx), ("my", my), ("rho", rho),
                      ("alpha", alpha)):
        boxes(name, arr, n)
    return range_bearing_pass_kernel(sx, sy, sth, mx, my, rho, alpha, int(passes))


def _as_boxes(name: str, a) -> tuple[np.ndarray, bool]:
    arr = np.ascontiguousarray(a, dtype=np.float64)
    if arr.ndim == 2 and arr.shape[1] == 2:
        return arr.reshape(arr.shape[0], 1, 2), True
    if arr.ndim == 3 and arr.shape[2] == 2:
        return arr, False
    raise ValueError(f"{name}: expected (m, 2) intervals or (m, d, 2) boxes, got shape {arr.shape}")


def qinter(intervals, q: int) -> tuple[np.ndarray, np.ndarray]:
    """q-relaxed intersection of ``m`` intervals ``(m, 2)`` or boxes ``(m, d, 2)``.

    Returns ``(result, rejected)``: ``result`` (``(2,)`` for intervals, ``(d, 2)`` for boxes)
    contains every point lying in at least ``m - q`` inputs; ``rejected`` (``(m,)`` bool) marks
    the inputs disjoint from ``result`` (all of them if it is empty).

    For intervals ``result`` is exactly the hull of that set (O(m log m), no rounding). For
    boxes it is the per-dimension hull, an **outer approximation** (the exact q-relaxed
    intersection of boxes is NP-hard). ``q >= m`` gives the whole space. The input is not
    modified.
    """
    arr, is_1d = _as_boxes("intervals", intervals)
    q = int(q)
    if q < 0:
        raise ValueError(f"q: must be >= 0, got {q}")
    out, rejected = qinter_batch(arr, np.array([0, arr.shape[0]]), np.array([q]))
    return (out[0, 0] if is_1d else out[0]), rejected


def qinter_batch(intervals, offsets, q) -> tuple[np.ndarray, np.ndarray]:
    """Many q-relaxed intersections at once: group ``g`` is ``intervals[offsets[g]:offsets[g+1]]``.

    ``intervals`` is ``(M, 2)`` or ``(M, d, 2)``, ``offsets`` non-decreasing ``(G + 1,)`` from 0
    to M, ``q`` an int or ``(G,)`` ints. Returns ``(results, rejected)``: ``(G, 2)`` or
    ``(G, d, 2)`` results (as :func:`qinter`) and the ``(M,)`` rejected mask.
    """
    from ivslam_cli.contractors.ctc_qinter import qinter_batch_kernel

    arr, is_1d = _as_boxes("intervals", intervals)
    off = np.ascontiguousarray(offsets, dtype=np.int64)
    if (off.ndim != 1 or off.shape[0] < 1 or off[0] != 0 or off[-1] != arr.shape[0]
            or np.any(np.diff(off) < 0)):
        raise ValueError("offsets: expected a non-decreasing 1-D array from 0 to the number of inputs")
    g = off.shape[0] - 1
    qs = np.ascontiguousarray(np.broadcast_to(np.asarray(q, dtype=np.int64), (g,)))
    if np.any(qs < 0):
        raise ValueError("q: must be >= 0")
    out, rejected = qinter_batch_kernel(arr, off, qs)
    return (out[:, 0] if is_1d else out), rejected


__all__ = ["difference", "polar", "qinter", "qinter_batch", "range_bearing", "range_bearing_pass", "unicycle"]
