"""Interval pose algebra on SE(2): outer enclosures of pose composition, inversion, relative
poses, and the intersection of two enclosures of one pose.

Box layout, everywhere: ``(..., 3, 2)`` float64, rows ``x``, ``y``, ``θ`` and columns lo, hi
(a flat ``(..., 6)`` row ``x_lo, x_hi, y_lo, y_hi, θ_lo, θ_hi`` is the same memory: reshape,
do not copy). ``θ`` intervals live on the real line; the true heading modulo 2π is inside.
The empty box is ``[+inf, −inf]`` on every row.

With a pose ``p = (t, θ)``:

- ``p ⊕ r = (t_p + R(θ_p) t_r, θ_p + θ_r)``: the pose ``r``, given in the frame of ``p``, in the
  frame ``p`` is given in (:func:`compose`);
- ``p⁻¹ = (−R(−θ) t, −θ)`` (:func:`invert`);
- ``p₁⁻¹ ⊕ p₂ = (R(−θ₁)(t₂ − t₁), θ₂ − θ₁)``: ``p₂`` in the frame of ``p₁`` (:func:`relative`).

Guarantee: every pose the input boxes allow maps into the output box (outward rounding in every
operation, :mod:`ivslam_cli.interval.arith`). The rotation angle is cut into ``slices`` pieces
(the hull of the pieces' images is kept: sound, and tighter than one rotation by the whole
interval), and each rotated component is met with ``[−ρ, ρ]``, ``ρ`` bounding the length of the
rotated vector (a rotation keeps it). Headings are met as angles (modulo 2π, in the narrower
branch).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ivslam_cli.interval import arith as K
from ivslam_cli.interval.angles import angle_meet_narrow
from ivslam_cli.interval.rounding import ensure_round_to_nearest, up

DEFAULT_SLICES = 16


@njit(cache=True)
def _set_empty(out):
    for d in range(3):
        out[d, 0], out[d, 1] = K.EMPTY_LO, K.EMPTY_HI


@njit(cache=True)
def _rotate(al, ah, xl, xh, yl, yh, slices, inverse):
    """Hull of ``R(a) (x, y)`` (``inverse``: ``R(−a) (x, y)``) over ``a ∈ [al, ah]``, cut into
    ``slices`` pieces, each component met with ``[−ρ, ρ]``, ``ρ ≥ |(x, y)|``:
    ``(ul, uh, vl, vh)``, outward."""
    mx = max(abs(xl), abs(xh))
    my = max(abs(yl), abs(yh))
    rho = up(math.sqrt(up(up(mx * mx) + up(my * my))))
    m = slices
    if not (ah - al < 1e3) or m < 1:  # unbounded or huge angle: one piece (sin, cos give [-1, 1])
        m = 1
    ul, uh, vl, vh = math.inf, -math.inf, math.inf, -math.inf
    prev = al
    for j in range(m):
        nxt = ah if j == m - 1 else al + (ah - al) * ((j + 1) / m)
        if nxt < prev:  # rounding: keep the pieces ordered; their union still covers [al, ah]
            nxt = prev
        cl, ch = K.cos(prev, nxt)
        sl, sh = K.sin(prev, nxt)
        p1l, p1h = K.mul(cl, ch, xl, xh)
        p2l, p2h = K.mul(sl, sh, yl, yh)
        p3l, p3h = K.mul(sl, sh, xl, xh)
        p4l, p4h = K.mul(cl, ch, yl, yh)
        if inverse:  # R(−a) (x, y) = (c·x + s·y, c·y − s·x)
            ql, qh = K.add(p1l, p1h, p2l, p2h)
            wl, wh = K.sub(p4l, p4h, p3l, p3h)
        else:  # R(a) (x, y) = (c·x − s·y, s·x + c·y)
            ql, qh = K.sub(p1l, p1h, p2l, p2h)
            wl, wh = K.add(p3l, p3h, p4l, p4h)
        ul, uh = min(ul, ql), max(uh, qh)
        vl, vh = min(vl, wl), max(vh, wh)
        prev = nxt
    return max(ul, -rho), min(uh, rho), max(vl, -rho), min(vh, rho)


@njit(cache=True)
def relative(b1, b2, slices, out):
    """``out`` ⊇ ``p₁⁻¹ ⊕ p₂ = (R(−θ₁)(t₂ − t₁), θ₂ − θ₁)`` for every ``p₁ ∈ b1``, ``p₂ ∈ b2``:
    the pose of box ``b2``'s robot in the frame of box ``b1``'s. Empty input: empty output."""
    dxl, dxh = K.sub(b2[0, 0], b2[0, 1], b1[0, 0], b1[0, 1])
    dyl, dyh = K.sub(b2[1, 0], b2[1, 1], b1[1, 0], b1[1, 1])
    tl, th = K.sub(b2[2, 0], b2[2, 1], b1[2, 0], b1[2, 1])
    if not (dxl <= dxh) or not (dyl <= dyh) or not (tl <= th):
        _set_empty(out)
        return
    ul, uh, vl, vh = _rotate(b1[2, 0], b1[2, 1], dxl, dxh, dyl, dyh, slices, True)
    out[0, 0], out[0, 1] = ul, uh
    out[1, 0], out[1, 1] = vl, vh
    out[2, 0], out[2, 1] = tl, th


@njit(cache=True)
def invert(b, slices, out):
    """``out`` ⊇ ``p⁻¹ = (−R(−θ) t, −θ)`` for every ``p ∈ b``: the origin in the frame of ``b``."""
    relative(b, np.zeros((3, 2)), slices, out)


@njit(cache=True)
def compose(p, r, slices, out):
    """``out`` ⊇ ``p ⊕ r = (t_p + R(θ_p) t_r, θ_p + θ_r)`` for every pose of box ``p`` and every
    relative pose (in ``p``'s frame) of box ``r``. Empty input: empty output."""
    tl, th = K.add(p[2, 0], p[2, 1], r[2, 0], r[2, 1])
    ok = tl <= th
    for d in range(3):
        ok = ok and p[d, 0] <= p[d, 1] and r[d, 0] <= r[d, 1]
    if not ok:
        _set_empty(out)
        return
    ul, uh, vl, vh = _rotate(p[2, 0], p[2, 1], r[0, 0], r[0, 1], r[1, 0], r[1, 1], slices, False)
    out[0, 0], out[0, 1] = K.add(p[0, 0], p[0, 1], ul, uh)
    out[1, 0], out[1, 1] = K.add(p[1, 0], p[1, 1], vl, vh)
    out[2, 0], out[2, 1] = tl, th


@njit(cache=True)
def meet(a, b, out):
    """``out`` = ``a ∩ b`` for two enclosures of one pose (headings met modulo 2π in the
    narrower branch). Returns False, ``out`` empty, when they do not meet. ``out`` may be ``a``."""
    xl, xh = max(a[0, 0], b[0, 0]), min(a[0, 1], b[0, 1])
    yl, yh = max(a[1, 0], b[1, 0]), min(a[1, 1], b[1, 1])
    tl, th = angle_meet_narrow(a[2, 0], a[2, 1], b[2, 0], b[2, 1])
    if not (xl <= xh and yl <= yh and tl <= th):
        _set_empty(out)
        return False
    out[0, 0], out[0, 1], out[1, 0], out[1, 1], out[2, 0], out[2, 1] = xl, xh, yl, yh, tl, th
    return True


@njit(cache=True)
def meet_or_keep(a, b, out):
    """``out[j]`` = ``a[j] ∩ b[j]`` row by row (``(N, 3, 2)``), where a row whose intersection is
    empty keeps ``a[j]`` (both hold the same pose: an empty meet is a contradiction the caller
    reports). Returns the number of such rows."""
    bad = 0
    tmp = np.empty((3, 2))
    for j in range(a.shape[0]):
        if meet(a[j], b[j], tmp):
            out[j] = tmp
        else:
            bad += 1
            out[j] = a[j]
    return bad


@njit(cache=True)
def _relative_all(b1, b2, slices, out):
    for i in range(b1.shape[0]):
        relative(b1[i], b2[i], slices, out[i])


@njit(cache=True)
def _invert_all(b, slices, out):
    for i in range(b.shape[0]):
        invert(b[i], slices, out[i])


@njit(cache=True)
def _compose_all(p, r, slices, out):
    for i in range(p.shape[0]):
        compose(p[i], r[i], slices, out[i])


@njit(cache=True)
def _meet_all(a, b, out):
    for i in range(a.shape[0]):
        meet(a[i], b[i], out[i])


def _boxes(*arrays) -> list[np.ndarray]:
    out = [np.ascontiguousarray(a, np.float64).reshape(-1, 3, 2) for a in arrays]
    if any(o.shape != out[0].shape for o in out):
        raise ValueError("pose boxes of different shapes")
    return out


def relative_enclosure(box1, box2, slices: int = DEFAULT_SLICES) -> np.ndarray:
    """``(N, 3, 2)`` enclosures of the pose of ``box2``'s robot in ``box1``'s frame, row by row."""
    ensure_round_to_nearest()
    b1, b2 = _boxes(box1, box2)
    out = np.empty_like(b1)
    _relative_all(b1, b2, int(slices), out)
    return out


def invert_enclosure(box, slices: int = DEFAULT_SLICES) -> np.ndarray:
    """``(N, 3, 2)`` enclosures of the inverses ``(−R(−θ) t, −θ)`` of the poses in ``box``."""
    ensure_round_to_nearest()
    (b,) = _boxes(box)
    out = np.empty_like(b)
    _invert_all(b, int(slices), out)
    return out


def compose_enclosure(p, r, slices: int = DEFAULT_SLICES) -> np.ndarray:
    """``(N, 3, 2)`` enclosures of ``p ⊕ r``, row by row."""
    ensure_round_to_nearest()
    a, b = _boxes(p, r)
    out = np.empty_like(a)
    _compose_all(a, b, int(slices), out)
    return out


def meet_enclosures(a, b) -> np.ndarray:
    """``(N, 3, 2)``: ``a ∩ b`` row by row (headings modulo 2π); empty rows where they do not meet."""
    x, y = _boxes(a, b)
    out = np.empty_like(x)
    _meet_all(x, y, out)
    return out


def box_width(box) -> np.ndarray:
    """The largest side of each box over its last-but-one axis (``(..., D, 2)`` → ``(...)``); NaN
    for an empty box. For pose boxes pass ``box[..., :2, :]`` to get the position width."""
    b = np.asarray(box, dtype=np.float64)
    with np.errstate(invalid="ignore"):  # inf − inf of empty boxes, masked below
        w = np.max(b[..., 1] - b[..., 0], axis=-1)
    return np.where(np.all(b[..., 0] <= b[..., 1], axis=-1), w, np.nan)


def position_width(box) -> np.ndarray:
    """The larger of the x and y sides of each pose box (``(..., 3, 2)``, or flat ``(..., 6)``);
    NaN where the box is empty (any of its three intervals)."""
    b = np.asarray(box, dtype=np.float64)
    b = b.reshape(b.shape[:-1] + (3, 2)) if b.shape[-1] == 6 else b
    w = np.maximum(b[..., 0, 1] - b[..., 0, 0], b[..., 1, 1] - b[..., 1, 0])
    return np.where(np.all(b[..., 0] <= b[..., 1], axis=-1), w, np.nan)
