"""What a scan's free cones prove: the cone model of the map kernels (docs/lidar.md) read by the
matcher (:mod:`.matcher`) in continuous polar form, without cells.

Beam ``i`` of a scan points at ``a0 + i·inc``; the nearest surface in its cone (half-width
``ra``, the stated bearing bound) is at a true distance within its range bounds, so every point
of the cone nearer than the lower bound (its free range) is free. Cones that touch (``ra ≥
inc / 2``) leave no bearing between beams; with narrower cones the gap between two beams is free
only under ``fill_gaps``. :func:`covered_free` certifies a window of bearings free to a
distance, :func:`_seg_free` a rectangle, and :func:`_may_cover` is a cheap necessary condition
of the latter. Float bearings are widened by explicit bounds on their error.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval.rounding import down, up
from ivslam_cli.slam.lidar.geometry import ATAN_ERR, atan2_fast, dn, range_bounds, upf

TWO_PI = 2.0 * math.pi
#: margin on bearings shifted by whole turns (2π·n in floating point, |n| small)
SHIFT_MARGIN = 1e-12
#: a cone's ends ``a0 + i·inc ± ra`` as computed are within this of the true ones (|angles| < 64)
CONE_MARGIN = 1e-13
#: bearings from :func:`box_bearings_fast` are within ATAN_ERR (+ an ulp) of the true ones
_BEAR_MARGIN = ATAN_ERR + 1e-12


@njit(cache=True)
def free_ranges(ranges, valid, r_abs, r_rel, out):
    """``out[i]`` = the true distance's lower bound of beam ``i`` (every point of its cone nearer
    than this is free), −1 for an invalid beam."""
    for i in range(ranges.shape[0]):
        if valid[i]:
            out[i] = range_bounds(float(ranges[i]), r_abs, r_rel)[0]
        else:
            out[i] = -1.0


@njit(cache=True)
def covered_free(f, a0, inc, ra, bl, bh, rho_h, one_pose):
    """True if every point at bearing in ``[bl, bh]`` (sensor frame) and distance ≤ ``rho_h``
    is proven free by a scan with free ranges ``f`` (beams at ``a0 + i·inc``, each cone of
    half-width ``ra``). Cones that touch (``ra ≥ inc / 2``), every beam taken from one pose
    (``one_pose``): the cones of the beams free beyond ``rho_h`` cover the window (each bearing
    lies in one of them: consecutive cones touch, others must meet, each shrunk by
    :data:`CONE_MARGIN`), as a point in a cone nearer than its free range is free whatever the
    other cones holding it saw. Cones that touch, beams taken from poses apart (a sweep): every
    beam whose cone meets the window is free beyond ``rho_h`` (so that, seen from each beam's
    own pose, one of them holds the point: :func:`sweep_free_from`). Gaps assumed free (``ra <
    inc / 2``, ``fill_gaps``): every beam from the one at or before ``bl`` to the one at or
    after ``bh``."""
    nb = f.shape[0]
    if not (bh - bl < TWO_PI):
        return False
    ac = a0 + 0.5 * (nb - 1) * inc
    n = math.floor((0.5 * (bl + bh) - ac) / TWO_PI + 0.5)
    if n != 0:
        bl = down(bl - n * TWO_PI) - SHIFT_MARGIN
        bh = up(bh - n * TWO_PI) + SHIFT_MARGIN
    if ra >= 0.5 * inc:  # the beams i with a0 + i·inc ± ra meeting [bl, bh]; more, never fewer
        i0 = math.ceil(down(down(down(bl - a0) - ra) / inc))
        i1 = math.floor(up(up(up(bh - a0) + ra) / inc))
        if one_pose:
            return _cones_cover(f, a0, inc, ra, bl, bh, rho_h, max(i0, 0), min(i1, nb - 1))
    else:
        i0 = math.floor(down(down(bl - a0) / inc))
        i1 = math.ceil(up(up(bh - a0) / inc))
    if i0 < 0 or i1 > nb - 1:
        return False
    for i in range(i0, i1 + 1):
        if not (rho_h < f[i]):
            return False
    return True


@njit(cache=True, inline="always")
def _cones_cover(f, a0, inc, ra, bl, bh, rho_h, i0, i1):
    """True if the cones of the beams ``i0..i1`` free beyond ``rho_h`` cover ``[bl, bh]``
    (consecutive cones touch, ``2 ra ≥ inc``; past a gap, a cone must start by the covered end;
    each shrunk by :data:`CONE_MARGIN`)."""
    reach = bl  # [bl, reach] is covered
    last = -2
    for i in range(i0, i1 + 1):
        if not (rho_h < f[i]):
            continue
        c = a0 + i * inc
        if i != last + 1 and up(c - ra) + CONE_MARGIN > reach:
            return False  # a bearing no cone free beyond rho_h holds: later cones start later
        reach = max(reach, down(c + ra) - CONE_MARGIN)
        last = i
        if reach >= bh:
            return True
    return False


@njit(cache=True, inline="always")
def _seg_free(vx, vy, ux, uy, ah, ac, stl, sth, f, a0, inc, ra, smin):
    """True if every point ``v + s u + t u⊥`` (``|s| <= ah``, ``|t| <= ac``; ``v`` relative to a
    sensor whose heading is in ``[stl, sth]``) lies in the certain free space of that sensor's
    scan (free ranges ``f``, beams at ``a0 + i·inc``, cones of half-width ``ra``), none nearer
    than ``smin`` to the sensor (:func:`sweep_free_from`: with cones that touch, 0 only when
    every beam is taken from one pose, so :func:`covered_free` may take each bearing from any
    cone that holds it)."""
    dist = math.hypot(vx, vy)
    if not dist > 0.0:
        return False
    ex, ey = vx / dist, vy / dist
    cb = abs(ux * ex + uy * ey)
    sb = abs(ux * ey - uy * ex)
    along = upf(upf(ah * cb + ac * sb) * (1.0 + 1e-12)) + 1e-12  # extents along and across v
    lat = upf(upf(ah * sb + ac * cb) * (1.0 + 1e-12)) + 1e-12
    near = dn(dist * (1.0 - 1e-12)) - along
    if not (near > 2.0 * lat and near >= smin):
        return False
    half = upf(upf(lat / near) * (1.0 + 1e-12)) + 1e-12  # >= atan(lat / near)
    bc = atan2_fast(vy, vx)
    far = upf(dist * (1.0 + 1e-12)) + along
    rho_h = upf(upf(math.hypot(far, lat)) * (1.0 + 1e-12))
    return covered_free(f, a0, inc, ra, bc - half - _BEAR_MARGIN - sth, bc + half + _BEAR_MARGIN - stl, rho_h,
                        not (smin > 0.0))


#: angle error of :func:`_may_cover`'s bearings: atan2_fast's plus what coordinates below
#: :data:`_QUICK_COORD` can add at distances above :data:`_QUICK_RHO2`'s root
_QUICK_M = ATAN_ERR + 1e-7
_QUICK_COORD = 1e4
_QUICK_RHO2 = 1e-6


@njit(cache=True, inline="always")
def _cover_setup(nb, a0, inc, ra):
    """:func:`_may_cover`'s per-scan constants: ``(1 / inc, centre angle, index margin, usable,
    cone half-width / inc)``, the last at least 1/2 when the cones touch (as
    :func:`covered_free` decides) and 0 otherwise."""
    ok = inc >= 1e-5 and (nb - 1) * inc < TWO_PI - 1e-3
    ii = 1.0 / inc if inc > 0.0 else 0.0
    rr = max(ra * ii * (1.0 + 1e-12), 0.5) if ra >= 0.5 * inc else 0.0
    return ii, a0 + 0.5 * (nb - 1) * inc, _QUICK_M * ii + 1e-9, ok, rr


@njit(cache=True, inline="always")
def _may_cover(px, py, cx, cy, c, f, a0, ii, ac, mi, ok, rr, one_pose):
    """False only if the point ``(px, py)`` cannot be in what :func:`covered_free` certifies
    free for a scan (free ranges ``f``, beams at ``a0 + i·inc``; ``ii, ac, mi, ok, rr`` from
    :func:`_cover_setup`) from a sensor at ``(cx, cy)`` with heading ``c``: a certified point
    at sensor bearing ``β`` is nearer than ``f[j]`` for a beam ``j`` whose cone holds ``β``
    (cones that touch, ``rr ≥ 1/2``), or ``j = ⌊(β − a0) / inc⌋`` (gaps assumed free) — and,
    with cones that touch and beams taken from poses apart (not ``one_pose``), than every beam
    whose cone surely holds ``β`` (such beams are in every window holding ``β``, and such a
    window is certified only if all its beams are free beyond the point). A cheap necessary
    condition, so :func:`_seg_free` runs only where it may succeed."""
    if not ok or not (abs(px) + abs(py) + abs(cx) + abs(cy) < _QUICK_COORD):
        return True
    dx = px - cx
    dy = py - cy
    rho2 = dx * dx + dy * dy
    if not rho2 > _QUICK_RHO2:
        return True
    b = atan2_fast(dy, dx) - c
    if not abs(b - ac) < 64.0:  # a heading far from the principal turns (or NaN): no shortcut
        return True
    while b - ac >= math.pi:
        b -= TWO_PI
    while b - ac < -math.pi:
        b += TWO_PI
    jc = (b - a0) * ii
    if rr >= 0.5:
        if not one_pose:
            # the beams whose cones surely hold β are in every window holding it: all free beyond
            s0 = math.ceil(jc - rr + mi)
            s1 = math.floor(jc + rr - mi)
            if s0 <= s1:
                if s0 < 0 or s1 > f.shape[0] - 1:
                    return False
                fs = f[s0]
                for j in range(s0 + 1, s1 + 1):
                    fs = min(fs, f[j])
                if not (fs > 0.0 and rho2 < fs * fs * (1.0 + 1e-9)):
                    return False
        j0 = max(math.ceil(jc - rr - mi), 0)
        j1 = min(math.floor(jc + rr + mi), f.shape[0] - 1)
    else:
        j0 = max(math.floor(jc - mi), 0)
        j1 = min(math.floor(jc + mi), f.shape[0] - 1)
    fm = -1.0
    for j in range(j0, j1 + 1):
        fm = max(fm, f[j])
    return fm > 0.0 and rho2 < fm * fm * (1.0 + 1e-9)


def sweep_free_from(drift: np.ndarray, inc: np.ndarray, ra: float, fill: bool) -> np.ndarray:
    """Per scan, the distance from its sensor below which its free cones prove nothing, its
    beams taken one after another while the sensor moves at most ``δ`` and turns at most ``η``
    between two consecutive beams (``drift`` (S, 2); beam step ``inc`` (S,), cones of
    half-width ``ra``): inf when the cones cannot overlap by the turn; 0 only when every beam
    is taken from one pose, or when cones that do not touch are not assumed to leave free gaps
    (they certify nothing then); a moving scan under ``fill`` gets the least positive float.

    Why. A point ``x`` proven free lies, seen from every sensor pose of the (swept) box, at a
    bearing in the window of beams ``i0..i1`` and nearer than their free ranges. Seen from beam
    ``i``'s own pose, its bearing minus the beam's, ``g(i)``, is above ``−ra`` at ``i0`` and
    below ``ra`` at ``i1`` (``2 ra ≥ inc``), and falls from one beam to the next by ``inc``
    give or take ``η`` plus the angle the sensor's shift subtends at ``x``: at most ``(π/3)
    δ/s`` at a distance ``s ≥ δ`` from both positions. A fall of at most ``2 ra`` cannot step
    over ``[−ra, ra]``: some beam's own cone holds ``x`` where ``2 ra − inc − η ≥ (π/3) δ/s``,
    i.e. from ``s = (π/3) δ / (2 ra − inc − η)``. Nearer, or when ``2 ra − inc ≤ η``, slivers
    between cones are seen by no beam. Under ``fill`` the gap between two adjacent beams is
    assumed free whatever their poses (0); cones that do not touch prove nothing anyway (0)."""
    d = np.asarray(drift, float).reshape(-1, 2)
    inc = np.broadcast_to(np.asarray(inc, float), (d.shape[0],))
    out = np.zeros(d.shape[0])
    if fill:  # from the sensor on; a moving scan's least distance is not 0 (0: one pose)
        out[(d[:, 0] > 0.0) | (d[:, 1] > 0.0)] = np.nextafter(0.0, 1.0)
        return out
    moving = ((d[:, 0] > 0.0) | (d[:, 1] > 0.0)) & (ra >= 0.5 * inc)
    margin = (2.0 * ra - inc - d[:, 1]) - 1e-12 * (2.0 * ra + inc + d[:, 1])  # rounded down
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(margin > 0.0, (math.pi / 3.0 + 1e-12) * d[:, 0] / margin * (1.0 + 1e-12), np.inf)
    out[moving] = np.nextafter(np.maximum(s[moving], d[moving, 0]), np.inf)
    return out


def free_of(ranges, valid, r_abs: float, r_rel: float) -> np.ndarray:
    """Free ranges of a scan's beams (every point of a beam's cone nearer than this is free;
    −1 for an invalid beam)."""
    f = np.full(ranges.shape[0], -1.0)
    free_ranges(ranges, valid, r_abs, r_rel, f)
    return f
