"""Cone beams: the cone-casting kernel against an independent oracle.

The oracle of the nearest wall distance within a cone ``[a - h, a + h]``: ``R`` rays spread
evenly over the cone (its two edges included) and the wall end points inside the cone. Every
point it finds is a wall point of the cone, so its distance ``d_hi`` is an upper bound of the
nearest one, ``d``; and ``d_hi <= d / cos(delta / 2)`` with ``delta = 2 h / (R - 1)``: the
nearest point is a wall end point (found exactly), on an edge ray (found exactly) or the foot
of the perpendicular from the apex on its wall, and then the ray nearest to it in angle meets
that wall's line within ``d / cos(delta / 2)``, or the wall ends before, at an end point inside
the cone and no farther.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ivslam_cli.simulate.conecast import cone_cast
from ivslam_cli.simulate.raycast import cast
from ivslam_cli.simulate.sensors import PROFILES
from ivslam_cli.simulate.worlds import BUILTIN, load_world

REL = 1e-12  # rounding allowance of the kernel and of the oracle (relative)


# ---------------------------------------------------------------- the oracle
def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def oracle(origin: np.ndarray, a: np.ndarray, h: float, segs: np.ndarray, rays: int):
    """``(d_hi, point, delta)`` for cones at ``origin`` ``(M, 2)``, bisector ``a`` ``(M,)``,
    half-width ``h``: the nearest wall point the oracle finds (``inf`` / NaN if none) and the
    angular spacing of its rays."""
    m = origin.shape[0]
    d_hi = np.full(m, np.inf)
    pt = np.full((m, 2), np.nan)
    u = np.linspace(-h, h, rays) if rays > 1 else np.zeros(1)
    phi = a[:, None] + u[None, :]  # (M, R)
    dx, dy = np.cos(phi)[..., None], np.sin(phi)[..., None]  # (M, R, 1)
    ax, ay = segs[:, 0], segs[:, 1]
    ex, ey = segs[:, 2] - ax, segs[:, 3] - ay
    wx, wy = ax[None, None, :] - origin[:, 0, None, None], ay[None, None, :] - origin[:, 1, None, None]
    den = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (wx * ey - wy * ex) / den
        s = (wx * dy - wy * dx) / den
    t = np.where((den != 0) & (t > 0) & (s >= 0) & (s <= 1), t, np.inf).min(axis=2)  # (M, R)
    r = np.argmin(t, axis=1)
    d_hi = t[np.arange(m), r]
    hit = np.isfinite(d_hi)
    pt[hit] = origin[hit] + d_hi[hit, None] * np.column_stack([np.cos(phi[hit, r[hit]]), np.sin(phi[hit, r[hit]])])
    ends = np.concatenate([segs[:, :2], segs[:, 2:]])  # (2K, 2)
    v = ends[None, :, :] - origin[:, None, :]
    de = np.hypot(v[..., 0], v[..., 1])
    inside = np.abs(_wrap(np.arctan2(v[..., 1], v[..., 0]) - a[:, None])) <= h
    de = np.where(inside, de, np.inf)
    j = np.argmin(de, axis=1)
    dj = de[np.arange(m), j]
    better = dj < d_hi
    d_hi = np.where(better, dj, d_hi)
    pt[better] = ends[j[better]]
    return d_hi, pt, (2.0 * h / (rays - 1) if rays > 1 else 0.0)


def bracket(d_hi: np.ndarray, delta: float) -> tuple[np.ndarray, np.ndarray]:
    """``[lo, hi]`` holding the nearest distance, from the oracle's ``d_hi``."""
    return d_hi * math.cos(0.5 * delta) * (1 - REL) - 1e-15, d_hi * (1 + REL) + 1e-15


def random_world(rng, k: int) -> np.ndarray:
    """``k`` walls in a 10 m square: random segments, polyline chains sharing their end
    points, some axis-aligned."""
    segs = []
    while len(segs) < k:
        kind = rng.integers(3)
        if kind == 0:
            segs.append(rng.uniform(0, 10, 4))
        elif kind == 1:
            p = rng.uniform(0, 10, 2)
            for _ in range(rng.integers(2, 5)):
                q = p + rng.normal(0, 1.5, 2)
                segs.append(np.r_[p, q])
                p = q
        else:
            x, y, w = *rng.uniform(0, 10, 2), rng.uniform(0.1, 3)
            segs.append(np.array([x, y, x + w, y]) if rng.random() < 0.5 else np.array([x, y, x, y + w]))
    return np.asarray(segs[:k], dtype=np.float64)


# ---------------------------------------------------------------- the kernel against the oracle
@given(st.integers(0, 2**32 - 1), st.sampled_from([0.0, 1e-7, 0.0030679615757712823, 0.0087266, 0.05, 0.4, 1.2]))
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_cone_kernel_equals_the_clipped_nearest_distance(seed, h):
    rng = np.random.default_rng(seed)
    segs = random_world(rng, int(rng.integers(1, 25)))
    n = 60
    origin = rng.uniform(-1, 11, (n, 2))
    a = rng.uniform(-4, 4, n)
    d = cone_cast(np.column_stack([origin, a]), [0.0], h, segs)[:, 0]
    d_hi, _, delta = oracle(origin, a, h, segs, 2000)
    assert np.array_equal(np.isinf(d), np.isinf(d_hi)), "a cone with walls the other misses"
    f = np.isfinite(d)
    lo, hi = bracket(d_hi[f], delta)
    assert np.all(d[f] <= hi), np.max(d[f] / d_hi[f] - 1)  # d_exact <= d_hi
    assert np.all(d[f] >= lo), np.max(lo / d[f] - 1)  # d_hi <= d_exact / cos(delta / 2)


@pytest.mark.parametrize("world", BUILTIN)
def test_cone_kernel_in_the_worlds_and_its_ray_limit(world):
    """Built-in worlds (walls meeting at corners), random sensor poses and URG/SICK cones; a
    cone is never farther than its own bisector ray, and at h = 0 it is that ray."""
    w = load_world(world)
    rng = np.random.default_rng(7)
    lo_xy, hi_xy = w.segments.reshape(-1, 2).min(axis=0), w.segments.reshape(-1, 2).max(axis=0)
    pose = np.column_stack([rng.uniform(lo_xy[0], hi_xy[0], 40), rng.uniform(lo_xy[1], hi_xy[1], 40),
                            rng.uniform(-math.pi, math.pi, 40)])
    for prof in PROFILES.values():
        ang = prof.beam_angles()
        h = prof.half_step()
        d = cone_cast(pose, ang, h, w.segments)
        ray = cast(pose, ang, w.segments)
        assert np.all(d <= ray * (1 + REL))
        d0 = cone_cast(pose, ang, 0.0, w.segments)
        f = np.isfinite(ray)
        assert np.array_equal(np.isfinite(d0), f) and np.allclose(d0[f], ray[f], rtol=1e-9, atol=0)
        for i in range(0, pose.shape[0], 8):  # the oracle on every beam of a few scans
            d_hi, _, delta = oracle(np.repeat(pose[i:i + 1, :2], ang.size, 0), pose[i, 2] + ang, h,
                                    w.segments, 400)
            assert np.array_equal(np.isinf(d[i]), np.isinf(d_hi))
            f = np.isfinite(d_hi)
            lo, hi = bracket(d_hi[f], delta)
            assert np.all((lo <= d[i, f]) & (d[i, f] <= hi))


def test_cone_kernel_refuses_a_half_width_of_a_quarter_turn():
    with pytest.raises(ValueError, match="half-width"):
        cone_cast(np.zeros((1, 3)), [0.0], 0.5 * math.pi, np.array([[1.0, -1.0, 1.0, 1.0]]))
