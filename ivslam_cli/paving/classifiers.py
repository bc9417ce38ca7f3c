"""Classifiers: what :func:`~ivslam_cli.paving.pave` knows about a set.

A classifier is any callable ``classify(boxes) -> (out, inside)`` over a batch of boxes
``(n, 2, 2)`` (``boxes[k, d] = [lo, hi]`` on axis d) with, for every row ``k``:

- ``out[k]`` a box inside ``boxes[k]`` holding every point of the set that lies in ``boxes[k]``
  (empty, i.e. ``lo > hi`` on some axis, when the box is proven outside): an outer contraction;
- ``inside[k]`` True only if the whole box is proven inside the set.

A classifier may also have a ``complement(boxes) -> cin`` method, the complementary
contraction: ``cin[k]`` a box inside ``boxes[k]`` holding every point of ``boxes[k]`` that is
*not* in the set (empty when the box is proven inside). What lies in ``boxes[k]`` outside
``cin[k]`` is then proven inside the set, as a separator's inner part is in Codac;
:func:`complement` falls back on ``inside`` for classifiers without it.

The families below are numba kernels selected by a code (numba first-class functions do not
mix well with the on-disk cache); :class:`Intersection` combines any classifiers, so a set given
by several constraints is paved in one pass. Any Python callable with the contract above works
too: ``pave`` calls it once per level on the whole batch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ivslam_cli.contractors.ctc_polar import polar_scalar
from ivslam_cli.interval.angles import arg_box, shift
from ivslam_cli.interval.arith import add, inter, sqr, sqrt, sub
from ivslam_cli.interval.rounding import INV_TWO_PI_HI, PI_HI, TWO_PI_HI, down, up

BOX = 0
POLAR = 1


@njit(cache=True)
def _set_empty(out, k):
    out[k, 0, 0] = np.inf
    out[k, 0, 1] = -np.inf
    out[k, 1, 0] = np.inf
    out[k, 1, 1] = -np.inf


@njit(cache=True)
def _box(p, xl, xh, yl, yh):
    """The box ``[p0, p1] x [p2, p3]``: contraction = intersection, inside = inclusion."""
    ox = inter(xl, xh, p[0], p[1])
    oy = inter(yl, yh, p[2], p[3])
    inside = p[0] <= xl and xh <= p[1] and p[2] <= yl and yh <= p[3]
    return ox[0], ox[1], oy[0], oy[1], inside


@njit(cache=True)
def angle_within(al, ah, tl, th):
    """True only if every angle of ``[a]`` is in ``[t] + 2 pi Z`` (sound, outward rounding)."""
    if not (al <= ah) or not (tl <= th):
        return False
    if down(th - tl) >= TWO_PI_HI:  # [t] covers the whole circle
        return True
    # the one copy of [t] that can hold [a]: k near (mid a - mid t) / 2 pi; try neighbours too
    k0 = math.floor((0.5 * (al + ah) - 0.5 * (tl + th)) * INV_TWO_PI_HI + 0.5)
    for dk in range(-1, 2):
        sl, sh = shift(al, ah, -(k0 + dk))
        if tl <= sl and sh <= th:
            return True
    return False


@njit(cache=True)
def _polar(p, xl, xh, yl, yh):
    """``{(x, y): |(x, y) - c| in [rho], arg((x, y) - c) in [theta] mod 2 pi}``, c = (p0, p1),
    [rho] = [p2, p3], [theta] = [p4, p5]. The centre belongs to the set iff ``0 in [rho]``.

    Outer: the polar contractor on ``(x - c, [rho], [theta])``. Inside: the forward norm of the
    box within [rho] and its argument (``arg_box``) within [theta] modulo 2 pi.
    """
    cx, cy = p[0], p[1]
    rl, rh, tl, th = p[2], p[3], p[4], p[5]
    dxl, dxh = sub(xl, xh, cx, cx)
    dyl, dyh = sub(yl, yh, cy, cy)
    # inside test on the whole box
    nl, nh = sqrt(*add(*sqr(dxl, dxh), *sqr(dyl, dyh)))
    inside = rl <= nl and nh <= rh
    if inside:
        al, ah = arg_box(dxl, dxh, dyl, dyh)
        inside = angle_within(al, ah, tl, th)
    if inside:
        return xl, xh, yl, yh, True
    r = polar_scalar(dxl, dxh, dyl, dyh, rl, rh, tl, th)
    if not (r[0] <= r[1]) or not (r[2] <= r[3]):
        return np.inf, -np.inf, np.inf, -np.inf, False
    ox = inter(xl, xh, *add(r[0], r[1], cx, cx))
    oy = inter(yl, yh, *add(r[2], r[3], cy, cy))
    return ox[0], ox[1], oy[0], oy[1], False


@njit(cache=True, inline="always")
def _hull2(al, ah, bl, bh, xl, xh, yl, yh):
    """Hull of the boxes ``[al, ah] x [bl, bh]`` and ``[xl, xh] x [yl, yh]`` (empty is neutral)."""
    if not (xl <= xh) or not (yl <= yh):
        return al, ah, bl, bh
    if not (al <= ah) or not (bl <= bh):
        return xl, xh, yl, yh
    return min(al, xl), max(ah, xh), min(bl, yl), max(bh, yh)


@njit(cache=True)
def _box_complement(p, xl, xh, yl, yh):
    """Hull of the points of ``[x] x [y]`` outside the box ``[p0, p1] x [p2, p3]`` (closed)."""
    al, ah, bl, bh = np.inf, -np.inf, np.inf, -np.inf
    if xl < p[0]:  # the part left of the box
        al, ah, bl, bh = _hull2(al, ah, bl, bh, xl, min(xh, p[0]), yl, yh)
    if xh > p[1]:
        al, ah, bl, bh = _hull2(al, ah, bl, bh, max(xl, p[1]), xh, yl, yh)
    if yl < p[2]:
        al, ah, bl, bh = _hull2(al, ah, bl, bh, xl, xh, yl, min(yh, p[2]))
    if yh > p[3]:
        al, ah, bl, bh = _hull2(al, ah, bl, bh, xl, xh, max(yl, p[3]), yh)
    return al, ah, bl, bh


@njit(cache=True)
def _polar_complement(p, xl, xh, yl, yh):
    """Hull of the points of ``[x] x [y]`` outside the polar set of :func:`_polar`.

    The complement is ``rho < rho_lo`` or ``rho > rho_hi`` or ``arg`` in the complementary arc
    ``(theta_hi, theta_lo + 2 pi)``; each part is enlarged to its closure and contracted with the
    polar contractor (an outer contractor: every point of the part in the box is kept), and the
    results are joined. A point of the box outside the set is in one of the parts, hence in
    the hull.
    """
    cx, cy = p[0], p[1]
    rl, rh, tl, th = p[2], p[3], p[4], p[5]
    dxl, dxh = sub(xl, xh, cx, cx)
    dyl, dyh = sub(yl, yh, cy, cy)
    al, ah, bl, bh = np.inf, -np.inf, np.inf, -np.inf
    for part in range(3):
        if part == 0:  # inside the inner circle
            if not (rl > 0.0):
                continue
            r = polar_scalar(dxl, dxh, dyl, dyh, 0.0, rl, -PI_HI, PI_HI)
        elif part == 1:  # outside the outer circle
            if rh == np.inf:
                continue
            r = polar_scalar(dxl, dxh, dyl, dyh, rh, np.inf, -PI_HI, PI_HI)
        else:  # the complementary arc
            if down(th - tl) >= TWO_PI_HI:
                continue
            r = polar_scalar(dxl, dxh, dyl, dyh, 0.0, np.inf, th, up(tl + TWO_PI_HI))
        if not (r[0] <= r[1]) or not (r[2] <= r[3]):
            continue
        ox = inter(xl, xh, *add(r[0], r[1], cx, cx))
        oy = inter(yl, yh, *add(r[2], r[3], cy, cy))
        al, ah, bl, bh = _hull2(al, ah, bl, bh, ox[0], ox[1], oy[0], oy[1])
    return al, ah, bl, bh


@njit(cache=True)
def complement_kernel(code, params, boxes, out):
    """The complementary contraction of family ``code`` on every row of ``boxes``."""
    for k in range(boxes.shape[0]):
        xl, xh, yl, yh = boxes[k, 0, 0], boxes[k, 0, 1], boxes[k, 1, 0], boxes[k, 1, 1]
        if code == BOX:
            r = _box_complement(params, xl, xh, yl, yh)
        else:
            r = _polar_complement(params, xl, xh, yl, yh)
        if not (r[0] <= r[1]) or not (r[2] <= r[3]):
            _set_empty(out, k)
            continue
        out[k, 0, 0], out[k, 0, 1], out[k, 1, 0], out[k, 1, 1] = r[0], r[1], r[2], r[3]


def complement(classify, boxes: np.ndarray) -> np.ndarray:
    """``classify.complement(boxes)`` if it has one; else each box that is not proven inside
    (``inside`` false) is its own complementary contraction, the others are empty."""
    boxes = np.ascontiguousarray(boxes, dtype=np.float64)
    fn = getattr(classify, "complement", None)
    if fn is not None:
        return fn(boxes)
    _, inside = classify(boxes)
    cin = boxes.copy()
    cin[inside] = np.array([[np.inf, -np.inf], [np.inf, -np.inf]])
    return cin


@njit(cache=True)
def classify_kernel(code, params, boxes, out, inside):
    """Apply family ``code`` with ``params`` to every row of ``boxes`` (writes ``out``, ``inside``)."""
    for k in range(boxes.shape[0]):
        xl, xh, yl, yh = boxes[k, 0, 0], boxes[k, 0, 1], boxes[k, 1, 0], boxes[k, 1, 1]
        if code == BOX:
            r = _box(params, xl, xh, yl, yh)
        else:
            r = _polar(params, xl, xh, yl, yh)
        if not (r[0] <= r[1]) or not (r[2] <= r[3]):
            _set_empty(out, k)
            inside[k] = False
            continue
        out[k, 0, 0], out[k, 0, 1], out[k, 1, 0], out[k, 1, 1] = r[0], r[1], r[2], r[3]
        inside[k] = r[4]


@dataclass(frozen=True)
class KernelClassifier:
    """A classifier family run by :func:`classify_kernel` (code + float parameters)."""

    code: int
    params: np.ndarray = field(repr=False)
    name: str = ""

    def __call__(self, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        boxes = np.ascontiguousarray(boxes, dtype=np.float64)
        out = np.empty_like(boxes)
        inside = np.empty(boxes.shape[0], dtype=np.bool_)
        classify_kernel(self.code, self.params, boxes, out, inside)
        return out, inside

    def complement(self, boxes: np.ndarray) -> np.ndarray:
        """The complementary contraction (see the module docstring)."""
        boxes = np.ascontiguousarray(boxes, dtype=np.float64)
        out = np.empty_like(boxes)
        complement_kernel(self.code, self.params, boxes, out)
        return out

    def __repr__(self) -> str:
        return f"KernelClassifier({self.name})"


def _interval(name: str, v) -> tuple[float, float]:
    lo, hi = (float(v[0]), float(v[1]))
    if math.isnan(lo) or math.isnan(hi) or lo > hi:
        raise ValueError(f"{name}: expected an interval [lo, hi] with lo <= hi, got {v!r}")
    return lo, hi


def box_set(box) -> KernelClassifier:
    """The box ``[[xl, xh], [yl, yh]]`` (bounds are taken as exact doubles)."""
    b = np.asarray(box, dtype=np.float64).reshape(2, 2)
    x = _interval("box x", b[0])
    y = _interval("box y", b[1])
    return KernelClassifier(BOX, np.array([*x, *y]), f"box {b.tolist()}")


def polar_set(center, rho, theta) -> KernelClassifier:
    """``{p : |p - center| in [rho], arg(p - center) in [theta] + 2 pi Z}``.

    The ring sector / a beam's observation set in the Guaranteed SLAM slides (``P_OBSTACLE``
    with ``[rho] = z + [r]``, ``P_EMPTY`` with ``[rho] = [0, z - r_hi]``). ``[theta]`` is any
    real interval (across ±pi is fine; width >= 2 pi is the full annulus). Bounds are exact
    doubles: enclose decimals first (:func:`ivslam_cli.interval.enclose`) when the decimal is
    what you mean.
    """
    cx, cy = (float(center[0]), float(center[1]))
    if not (math.isfinite(cx) and math.isfinite(cy)):
        raise ValueError(f"center must be finite, got {center!r}")
    r = _interval("rho", rho)
    t = _interval("theta", theta)
    return KernelClassifier(POLAR, np.array([cx, cy, *r, *t]),
                            f"polar c=({cx}, {cy}) rho={list(r)} theta={list(t)}")


@dataclass(frozen=True)
class Intersection:
    """The intersection of the sets of several classifiers.

    Outer: the input box contracted by each classifier in turn (each sees the previous
    contraction, so the order only changes tightness). Inside: every classifier proves the
    original box inside (a part sees the original box as long as all parts before it proved
    it inside, since a sound contraction of a box inside a set is the box itself).
    """

    parts: tuple

    def __init__(self, *parts) -> None:
        if not parts:
            raise ValueError("Intersection needs at least one classifier")
        object.__setattr__(self, "parts", tuple(parts))

    def __call__(self, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        boxes = np.ascontiguousarray(boxes, dtype=np.float64)
        out = boxes.copy()
        inside = np.ones(boxes.shape[0], dtype=np.bool_)
        alive = np.ones(boxes.shape[0], dtype=np.bool_)
        for part in self.parts:
            idx = np.flatnonzero(alive)
            seen = out[idx]
            o, ins = part(seen)
            same = np.all(seen == boxes[idx], axis=(1, 2))
            inside[idx] &= ins & same
            out[idx] = o
            alive[idx] = (o[:, 0, 0] <= o[:, 0, 1]) & (o[:, 1, 0] <= o[:, 1, 1])
        out[~alive] = np.array([[np.inf, -np.inf], [np.inf, -np.inf]])
        inside &= alive
        return out, inside

    def complement(self, boxes: np.ndarray) -> np.ndarray:
        """A point outside the intersection is outside some part: the hull of the parts'
        complementary contractions of the same boxes."""
        boxes = np.ascontiguousarray(boxes, dtype=np.float64)
        cin = np.empty_like(boxes)
        cin[:, :, 0] = np.inf
        cin[:, :, 1] = -np.inf
        for part in self.parts:
            c = complement(part, boxes)
            ok = (c[:, 0, 0] <= c[:, 0, 1]) & (c[:, 1, 0] <= c[:, 1, 1])
            cin[ok, :, 0] = np.minimum(cin[ok, :, 0], c[ok, :, 0])
            cin[ok, :, 1] = np.maximum(cin[ok, :, 1], c[ok, :, 1])
        return cin
