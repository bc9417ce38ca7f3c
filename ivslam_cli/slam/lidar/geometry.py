"""Geometry of a scan seen from a pose box (numba kernels, outward rounding).

Sensor model (the cone model of the "Guaranteed SLAM – practical considerations" slides): beam ``i`` of a scan points at ``a_i = angle_min + i Δ``
(real arithmetic on the stored doubles) in the sensor frame, with a bearing error within
``[-r_α, r_α]``. A valid return ``z`` satisfies ``|z - d| <= abs + rel d`` for the true distance
``d`` (the convention of ``ivslam simulate``), hence ``d ∈ [(z - abs) / (1 + rel),
(z + abs) / (1 - rel)]``.

- P_OBSTACLE^{i,k}: the endpoint lies at range ``d`` and bearing ``a_i + [r_α]``.
- P_EMPTY^{i,k}: nothing lies in the cone ``a_i + [-h, h]`` closer than ``(z - abs) / (1 + rel)``,
  with ``h = max(r_α, Δ/2)``. When ``r_α >= Δ/2`` this is the slides' cone model. When
  ``r_α < Δ/2`` (ray-like beams) the cones of two adjacent beams do not touch and an obstacle
  can hide in the gap (a thin pole, or a convex corner poking between two beams whose faces
  both cross the beams further out): such a scan proves no free space, unless the kernels are
  told ``fill`` (``lidar.fill_gaps``, a stated assumption): the triangle (sensor, the two
  beams' points at the nearer free range) is then taken as free, free ranges multiplied by
  ``cos(Δ/2)`` so a cell inside the sector is inside the triangles.

Invalid beams (no return, max range, error codes) prove nothing here: no obstacle and, for now
and conservatively, no free space.

A cell (or block) ``C`` and a sensor pose box ``[x] x [y] x [θ]`` give ``D = C - [x] x [y]``
(every sensor-to-point vector), the range interval of ``D`` and its bearing interval minus
``[θ]``; the beams whose widened cone ``a_i + [-h, h]`` may meet those bearings form a window
``[i_lo, i_hi]`` of beam indices (a superset, rounded outward).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval.arith import add, cos, mul, sin, sub
from ivslam_cli.interval.rounding import INF, PI_HI, PI_LO, TWO_PI_HI, TWO_PI_LO, down, down2, up, up2


@njit(cache=True)
def sensor_offset(tl, th, mx, my, myaw):
    """The mount's offset and heading for the robot headings ``[tl, th]``: every ``(cos θ mx -
    sin θ my, sin θ mx + cos θ my)`` and ``θ + myaw`` is inside the returned ``(oxl, oxh, oyl,
    oyh, stl, sth)``."""
    cl, ch = cos(tl, th)
    sl, sh = sin(tl, th)
    ax, bx = mul(cl, ch, mx, mx)
    cx, dx = mul(sl, sh, my, my)
    ox, oxh = sub(ax, bx, cx, dx)
    ay, by = mul(sl, sh, mx, mx)
    cy, dy = mul(cl, ch, my, my)
    oy, oyh = add(ay, by, cy, dy)
    stl, sth = add(tl, th, myaw, myaw)
    return ox, oxh, oy, oyh, stl, sth


@njit(cache=True)
def sensor_box(xl, xh, yl, yh, tl, th, mx, my, myaw):
    """Sensor pose box from a robot pose box and the mount ``(mx, my, myaw)``.

    Every sensor pose ``(x + cos θ mx - sin θ my, y + sin θ mx + cos θ my, θ + myaw)`` of a
    robot pose in the box is inside the returned ``(xl, xh, yl, yh, tl, th)``.
    """
    ox, oxh, oy, oyh, stl, sth = sensor_offset(tl, th, mx, my, myaw)
    sxl, sxh = add(xl, xh, ox, oxh)
    syl, syh = add(yl, yh, oy, oyh)
    return sxl, sxh, syl, syh, stl, sth


@njit(cache=True, inline="always")
def beam_offset(stl, sth, rl, rh, ang, r_alpha):
    """Endpoint offset from the sensor of a beam at angle ``ang`` with ranges ``[rl, rh]``, for
    every sensor heading in ``[stl, sth]`` and bearing error within ``r_alpha``: ``(dxl, dxh,
    dyl, dyh)`` (the angle sum widened by 1e-15 relative beyond its outward rounding)."""
    al, ah = add(stl, sth, ang, ang)
    al = down(down(al - r_alpha) - 1e-15 * abs(al))
    ah = up(up(ah + r_alpha) + 1e-15 * abs(ah))
    cl, ch = cos(al, ah)
    sl, sh = sin(al, ah)
    dxl, dxh = mul(rl, rh, cl, ch)
    dyl, dyh = mul(rl, rh, sl, sh)
    return dxl, dxh, dyl, dyh


@njit(cache=True)
def sensor_boxes_of(b, rows, mx, my, myaw):
    """:func:`sensor_box` of the robot boxes ``b[rows]`` (S, 6), into rows ``rows`` of an (S, 6)
    array (other rows zero)."""
    out = np.zeros_like(b)
    for r in rows:
        o = sensor_box(b[r, 0], b[r, 1], b[r, 2], b[r, 3], b[r, 4], b[r, 5], mx, my, myaw)
        for j in range(6):
            out[r, j] = o[j]
    return out


# down / up of ivslam_cli.interval.rounding without their NaN test: the same values for every
# finite argument whose step does not overflow (|c| < 1e300). For the fast paths, on
# coordinates and ranges of a map (callers check the magnitudes or fall back).
_PHI = 2.0**-53 * (1.0 + 2.0**-52)
_ETA = 2.0**-1074
FIN_MAX = 1e150  # |values| below this: the squares below stay finite


@njit(cache=True, inline="always")
def dn(c):
    """:func:`~ivslam_cli.interval.rounding.down` for finite ``c`` (``|c| < 1e300``)."""
    return c - (_PHI * abs(c) + _ETA)


@njit(cache=True, inline="always")
def upf(c):
    """:func:`~ivslam_cli.interval.rounding.up` for finite ``c`` (``|c| < 1e300``)."""
    return c + (_PHI * abs(c) + _ETA)


@njit(cache=True, inline="always")
def _box_ranges(dxl, dxh, dyl, dyh, fin):
    """``[min, max]`` of ``|v|`` over the box ``[dx] x [dy]``, rounded outward (``fin``: by
    :func:`dn` / :func:`upf`, the same values for a finite box below ``FIN_MAX``)."""
    if dxl > 0.0:
        mx = dxl
    elif dxh < 0.0:
        mx = -dxh
    else:
        mx = 0.0
    if dyl > 0.0:
        my = dyl
    elif dyh < 0.0:
        my = -dyh
    else:
        my = 0.0
    Mx = max(-dxl, dxh)
    My = max(-dyl, dyh)
    lo = 0.0
    if fin:
        if mx > 0.0 or my > 0.0:
            lo = max(0.0, dn(math.sqrt(dn(dn(mx * mx) + dn(my * my)))))
        return lo, upf(math.sqrt(upf(upf(Mx * Mx) + upf(My * My))))
    if mx > 0.0 or my > 0.0:
        lo = max(0.0, down(math.sqrt(down(down(mx * mx) + down(my * my)))))
    return lo, up(math.sqrt(up(up(Mx * Mx) + up(My * My))))


@njit(cache=True, inline="always")
def box_ranges(dxl, dxh, dyl, dyh):
    """``[min, max]`` of ``|v|`` over the box ``[dx] x [dy]``, rounded outward."""
    return _box_ranges(dxl, dxh, dyl, dyh, False)


@njit(cache=True, inline="always")
def box_ranges_fin(dxl, dxh, dyl, dyh):
    """:func:`box_ranges` (the same values) for a finite box with ``|bounds| < FIN_MAX``."""
    return _box_ranges(dxl, dxh, dyl, dyh, True)


@njit(cache=True)
def _atan2_lo(y, x):
    return down2(math.atan2(y, x))


@njit(cache=True)
def _atan2_hi(y, x):
    return up2(math.atan2(y, x))


@njit(cache=True)
def box_bearings(xl, xh, yl, yh):
    """Bearings of the points of the box as a real interval ``(lo, hi, full)``.

    Two atan2 calls (the extreme corners are known from the box's position). ``full`` is
    True when the box holds the origin (every bearing). Boxes left of the origin crossing the
    negative x-axis get an interval around pi (``hi > pi``): no bearing is lost at the cut.
    """
    if xl > 0.0:  # right half plane: theta in (-pi/2, pi/2), increasing in y
        lo = _atan2_lo(yl, xl if yl < 0.0 else xh)
        hi = _atan2_hi(yh, xl if yh > 0.0 else xh)
        return lo, hi, False
    if xh < 0.0:  # left: mirror through the origin, then add pi
        lo = _atan2_lo(-yh, -xh if -yh < 0.0 else -xl)
        hi = _atan2_hi(-yl, -xh if -yl > 0.0 else -xl)
        return down(lo + PI_LO), up(hi + PI_HI), False
    if yl > 0.0:  # upper: theta in (0, pi), decreasing in x
        lo = _atan2_lo(yl if xh > 0.0 else yh, xh)
        hi = _atan2_hi(yh if xl > 0.0 else yl, xl)
        return lo, hi, False
    if yh < 0.0:  # lower: theta in (-pi, 0), increasing in x
        lo = _atan2_lo(yl if xl > 0.0 else yh, xl)
        hi = _atan2_hi(yh if xh > 0.0 else yl, xh)
        return lo, hi, False
    return -PI_HI, PI_HI, True


# ---------------------------------------------------------------- fast bearings (with an error bound)
# atan(t) on [0, 1] by the odd polynomial t P(t^2), P of degree 5 (a minimax fit, max error
# 1.7e-6 on [0, 1]), evaluated by Estrin's scheme (short dependency chains). ATAN_ERR bounds
# |atan2_fast(y, x) - atan2(y, x)| for every finite (y, x) != (0, 0), roundings included;
# tests/test_lidar_map.py checks it by dense sampling plus a bound of the error's derivative.
# Callers that need the exact libm-based bearings use these only where an ATAN_ERR margin
# decides, and widen/shrink by it elsewhere.
_AT0 = 0.9999772193087108
_AT1 = -0.33262282995263187
_AT2 = 0.19354038085333508
_AT3 = -0.11642648340601075
_AT4 = 0.05264734644076964
_AT5 = -0.011719132190780815
ATAN_COEFFS = (_AT0, _AT1, _AT2, _AT3, _AT4, _AT5)
ATAN_ERR = 1e-5


@njit(cache=True, inline="always")
def atan_poly(t):
    """``atan(t)`` for ``t`` in ``[0, 1]`` within 1.7e-6 (plus roundings)."""
    t2 = t * t
    t4 = t2 * t2
    return ((_AT0 + _AT1 * t2) + t4 * (_AT2 + _AT3 * t2) + (t4 * t4) * (_AT4 + _AT5 * t2)) * t


@njit(cache=True, inline="always")
def atan2_fast(y, x):
    """``atan2(y, x)`` in ``[-pi, pi]`` within :data:`ATAN_ERR` for finite ``(y, x)`` (``(0, 0)``
    gives 0; NaN is not handled: callers check their inputs). Written with selects, no
    branches: vectorisable in loops (:mod:`.lidar_kernel`'s level passes)."""
    ax = abs(x)
    ay = abs(y)
    sw = ay > ax
    num = ax if sw else ay
    den = ay if sw else ax
    a = atan_poly(num / (den if den > 0.0 else 1.0))
    a = 0.5 * math.pi - a if sw else a
    a = math.pi - a if x < 0.0 else a
    a = -a if y < 0.0 else a
    return a if den > 0.0 else 0.0


@njit(cache=True, inline="always")
def box_bearings_fast(xl, xh, yl, yh):
    """:func:`box_bearings` with :func:`atan2_fast` at the same corners and in the same
    branches: ``(lo, hi, full)`` with ``lo, hi`` within ``ATAN_ERR`` (+ an ulp) of the real
    bearings of those corners (no outward rounding: callers add their margins). The corners
    are chosen by selects (vectorisable)."""
    right = xl > 0.0
    left = xh < 0.0
    # lower half plane, overridden by upper, left, right (box_bearings' order, reversed)
    ya, xa, yb, xb = (yl if xl > 0.0 else yh), xl, (yh if xh > 0.0 else yl), xh
    if yl > 0.0:
        ya, xa, yb, xb = (yl if xh > 0.0 else yh), xh, (yh if xl > 0.0 else yl), xl
    if left:
        ya, xa, yb, xb = -yh, (-xh if -yh < 0.0 else -xl), -yl, (-xh if -yl > 0.0 else -xl)
    if right:
        ya, xa, yb, xb = yl, (xl if yl < 0.0 else xh), yh, (xl if yh > 0.0 else xh)
    lo = atan2_fast(ya, xa)
    hi = atan2_fast(yb, xb)
    if left and not right:
        lo += math.pi
        hi += math.pi
    full = not (right or left or yl > 0.0 or yh < 0.0)
    return (-PI_HI if full else lo), (PI_HI if full else hi), full


@njit(cache=True)
def beam_window(pl, ph, a0, inc, h, nb):
    """Beams whose cone ``a_i + [-h, h]`` may meet bearings ``[pl, ph] + 2πZ`` (sensor frame).

    Returns ``(o_lo, o_hi, e_lo, e_hi, cover)``: ``[o_lo, o_hi]`` (clipped to the scan, empty
    when ``o_lo > o_hi``) holds every such beam; ``[e_lo, e_hi]`` is the window of one branch
    ``[pl, ph] - 2πm`` and ``cover`` says its cones cover all of ``[pl, ph]`` (every bearing
    lies between two adjacent beams of the window, or within ``h`` of one of them).
    """
    if not (ph - pl < 6.0):
        return 0, nb - 1, 0, -1, False
    a_end = a0 + (nb - 1) * inc
    c = 0.5 * (pl + ph) - 0.5 * (a0 + a_end)
    m = float(round(c / (2.0 * math.pi)))
    if m != 0.0:
        sl, sh = mul(m, m, TWO_PI_LO, TWO_PI_HI)
        pl, ph = down(pl - sh), up(ph - sl)
    return window_in_branch(pl, ph, a0, inc, h, nb, down(a0 - h), up(up(a_end + h)))


@njit(cache=True, inline="always")
def window_in_branch(pl, ph, a0, inc, h, nb, lo_edge, hi_edge):
    """:func:`beam_window` of bearings ``[pl, ph]`` already in the branch of the scan (``lo_edge
    = down(a0 - h)``, ``hi_edge = up(up(a_end + h))``, the scan's cones)."""
    ul = down(down(down(pl - h) - a0) / inc)
    uh = up(up(up(ph + h) - a0) / inc)
    if not (-1e9 < ul and uh < 1e9):
        return 0, nb - 1, 0, -1, False
    e_lo = int(math.ceil(ul))  # the beams whose cones a_i + [-h, h] meet [pl, ph] (h >= inc / 2: they cover it)
    e_hi = int(math.floor(uh))
    cover = e_lo >= 0 and e_hi <= nb - 1
    o_lo = max(e_lo, 0)
    o_hi = min(e_hi, nb - 1)
    # another branch meeting the scan's cones (wide bearing sets only): all beams, outer
    if down(pl + TWO_PI_LO) <= hi_edge or up(ph - TWO_PI_LO) >= lo_edge:
        o_lo, o_hi = 0, nb - 1
    return o_lo, o_hi, e_lo, e_hi, cover


@njit(cache=True)
def range_bounds(z, r_abs, r_rel):
    """``[(z - abs) / (1 + rel), (z + abs) / (1 - rel)]`` rounded outward (true distance)."""
    lo = down(down(z - r_abs) / up(1.0 + r_rel))
    hi = up(up(z + r_abs) / down(1.0 - r_rel))
    return max(lo, 0.0), hi


#: absolute and relative (to the beam's range) error bound of a rotated endpoint region
MARGIN_ABS = 1e-9
MARGIN_REL = 1e-12


@njit(cache=True, inline="always")
def beam_region(ccx, ccy, cc, sc, ca, sa, rl, rh, d):
    """A beam at angle ``α`` (``ca``, ``sa``: its cosine and sine) with true distance in
    ``[rl, rh]``, from a sensor at ``(ccx, ccy)`` whose heading is within ``d`` (the bearing
    error included) of ``c`` (``cc``, ``sc``): its end point lies in the rectangle of centre
    ``(cx, cy)``, axis ``u`` (the beam's mid direction), half-length ``ah`` along ``u`` and
    half-width ``ac`` across; ``hx``, ``hy``: the rectangle's half extents in x, y. Floating
    point, widened by the error bound (:data:`MARGIN_ABS`, :data:`MARGIN_REL`)."""
    ux = cc * ca - sc * sa
    uy = sc * ca + cc * sa
    al = rl * (1.0 - upf(0.5 * upf(d * d)))  # r cos t >= r (1 - t²/2)
    am = 0.5 * (al + rh)
    marg = MARGIN_ABS + MARGIN_REL * rh
    ah = 0.5 * (rh - al) + marg
    ac = rh * d + marg  # |r sin t| <= r |t|
    hx = ah * abs(ux) + ac * abs(uy)
    hy = ah * abs(uy) + ac * abs(ux)
    return ccx + am * ux, ccy + am * uy, ux, uy, ah, ac, hx, hy


__all__ = ["ATAN_ERR", "FIN_MAX", "INF", "MARGIN_ABS", "MARGIN_REL", "atan2_fast", "beam_offset", "beam_region",
           "beam_window", "box_bearings", "box_bearings_fast", "box_ranges", "box_ranges_fin", "dn", "range_bounds", "sensor_box",
           "sensor_boxes_of", "sensor_offset", "upf", "window_in_branch"]
