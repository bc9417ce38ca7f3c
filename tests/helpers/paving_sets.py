"""Exact membership tests and strategies for the subpaving tests (mpmath at 200 bits: float
coordinates are exact, so the only error is mpmath's)."""

from __future__ import annotations

import math

import mpmath
import numpy as np
from hypothesis import settings
from hypothesis import strategies as st

from ivslam_cli import paving as P
from tests.helpers.hyp import examples

mpmath.mp.prec = 200
SETTINGS = settings(max_examples=examples(ci=40))
DOMAIN = [[-10.0, 10.0], [-10.0, 10.0]]
TWO_PI = 2 * mpmath.pi


# ----------------------------------------------------------------- true sets (mpmath)
def in_polar(x, y, c, rho, theta) -> bool:
    dx = mpmath.mpf(x) - mpmath.mpf(c[0])
    dy = mpmath.mpf(y) - mpmath.mpf(c[1])
    r = mpmath.sqrt(dx * dx + dy * dy)
    if not (mpmath.mpf(rho[0]) <= r <= mpmath.mpf(rho[1])):
        return False
    tl, th = mpmath.mpf(theta[0]), mpmath.mpf(theta[1])
    if th - tl >= TWO_PI:
        return True
    if r == 0:
        return rho[0] <= 0.0
    a = mpmath.atan2(dy, dx)
    k = mpmath.ceil((tl - a) / TWO_PI)  # smallest a + 2 pi k >= tl
    return a + k * TWO_PI <= th


def in_box(x, y, b) -> bool:
    return b[0][0] <= x <= b[0][1] and b[1][0] <= y <= b[1][1]


def polar_points(rng, c, rho, theta, n=150):
    """Float points of the true polar set (sampled in polar form, kept if exactly inside)."""
    r = rng.uniform(rho[0], rho[1], n)
    t = rng.uniform(theta[0], min(theta[1], theta[0] + 2 * math.pi), n)
    pts = np.stack([c[0] + r * np.cos(t), c[1] + r * np.sin(t)], axis=1)
    # the corners of the sector too (most likely to be lost)
    for rr in rho:
        for tt in theta:
            pts = np.vstack([pts, [c[0] + rr * math.cos(tt), c[1] + rr * math.sin(tt)]])
    keep = [in_polar(x, y, c, rho, theta) for x, y in pts]
    return pts[np.array(keep, dtype=bool)]


def cell_samples(rng, p: P.GridPaving, mask, per=3):
    """Corners, centre and random points of the cells selected by ``mask`` (exact floats)."""
    cells = p.cells()[mask]
    if len(cells) == 0:
        return np.empty((0, 2))
    out = []
    for a in (0, 1):
        for b in (0, 1):
            out.append(np.stack([cells[:, 0, a], cells[:, 1, b]], axis=1))
    u = rng.random((len(cells), per, 2))
    lo = cells[:, None, :, 0]
    hi = cells[:, None, :, 1]
    out.append(np.clip(lo + u * (hi - lo), lo, hi).reshape(-1, 2))
    pts = np.concatenate(out)
    if len(pts) > 400:
        pts = pts[rng.choice(len(pts), 400, replace=False)]
    return pts


def check_layout(p: P.GridPaving) -> None:
    """The structure-of-arrays invariants: sorted keys, >= 1 part per cell, parts non-empty and
    inside their cell's box, box = hull of the parts, inside the cell; INNER = one part, the cell."""
    n = len(p)
    assert np.all(p.key[1:] > p.key[:-1])
    assert p.start.shape == (n + 1,) and p.start[0] == 0 and p.start[-1] == p.parts.shape[0]
    assert np.all(p.n_parts >= 1)
    if n == 0:
        return
    own = p.box[p.part_cell]
    assert np.all(p.parts[:, :, 0] <= p.parts[:, :, 1])
    assert np.all(p.parts[:, :, 0] >= own[:, :, 0]) and np.all(p.parts[:, :, 1] <= own[:, :, 1])
    lo = np.minimum.reduceat(p.parts[:, :, 0], p.start[:-1], axis=0)
    hi = np.maximum.reduceat(p.parts[:, :, 1], p.start[:-1], axis=0)
    assert np.array_equal(lo, p.box[:, :, 0]) and np.array_equal(hi, p.box[:, :, 1])
    cells = p.cells()
    assert np.all(p.box[:, :, 0] >= cells[:, :, 0]) and np.all(p.box[:, :, 1] <= cells[:, :, 1])
    inner = p.inner_mask
    assert np.all(p.n_parts[inner] == 1)
    assert np.array_equal(p.parts[p.start[:-1][inner]], cells[inner])
    assert np.array_equal(p.box[inner], cells[inner])


# ----------------------------------------------------------------- strategies
@st.composite
def polar_params(draw):
    c = (draw(st.floats(-3, 3)), draw(st.floats(-3, 3)))
    r1 = draw(st.floats(0.0, 3.0))
    r2 = r1 + draw(st.floats(0.05, 2.0))
    t1 = draw(st.floats(-4.0, 4.0))  # sectors crossing the ±pi cut, and beyond pi
    t2 = t1 + draw(st.sampled_from([draw(st.floats(0.05, 3.0)), draw(st.floats(6.3, 7.0))]))
    eps = draw(st.sampled_from([0.05, 0.1, 0.2, 0.125]))
    origin = (draw(st.floats(-1, 1)), draw(st.floats(-1, 1)))
    return c, (r1, r2), (t1, t2), eps, origin


@st.composite
def box_params(draw):
    x0, y0 = draw(st.floats(-8, 7)), draw(st.floats(-8, 7))
    return [[x0, x0 + draw(st.floats(0.0, 2.0))], [y0, y0 + draw(st.floats(0.0, 2.0))]]
