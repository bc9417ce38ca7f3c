"""Unicycle motion (exact arcs), angle wrapping, and dead reckoning."""

from __future__ import annotations

import math

import numpy as np


def wrap(angle):
    """Angle(s) wrapped to ``(-pi, pi]``."""
    a = np.remainder(np.asarray(angle, dtype=np.float64) + np.pi, 2.0 * np.pi) - np.pi
    return np.where(a == -np.pi, np.pi, a)


def unicycle_step(pose: np.ndarray, v, w, dt) -> np.ndarray:
    """``h(s, u, dt)``: pose(s) ``(..., 3)`` after driving (v, w) constant for ``dt``.

    Exact arc: the chord has length ``v dt sinc(w dt / 2)`` and direction
    ``theta + w dt / 2``; theta is wrapped to ``(-pi, pi]``.
    """
    pose = np.asarray(pose, dtype=np.float64)
    half = 0.5 * np.asarray(w) * dt
    chord = np.asarray(v) * dt * np.sinc(half / np.pi)  # numpy sinc(x) = sin(pi x)/(pi x)
    heading = pose[..., 2] + half
    out = np.empty(np.broadcast(pose[..., 0], chord).shape + (3,))
    out[..., 0] = pose[..., 0] + chord * np.cos(heading)
    out[..., 1] = pose[..., 1] + chord * np.sin(heading)
    out[..., 2] = wrap(pose[..., 2] + 2.0 * half)
    return out


def dead_reckon(pose0: np.ndarray, stamp: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """Integrate ``twist[k]`` over ``[stamp[k], stamp[k+1])`` from ``pose0``; ``(N, 3)``.

    Vectorised: headings are a cumulative sum, positions a cumulative sum of exact chords.
    """
    n = stamp.shape[0]
    dt = np.diff(stamp)
    v, w = twist[:-1, 0], twist[:-1, 1]
    half = 0.5 * w * dt
    theta = pose0[2] + np.concatenate(([0.0], np.cumsum(2.0 * half)))
    chord = v * dt * np.sinc(half / np.pi)
    poses = np.empty((n, 3))
    poses[:, 0] = pose0[0] + np.concatenate(([0.0], np.cumsum(chord * np.cos(theta[:-1] + half))))
    poses[:, 1] = pose0[1] + np.concatenate(([0.0], np.cumsum(chord * np.sin(theta[:-1] + half))))
    poses[:, 2] = wrap(theta)
    return poses


def make_stamps(t0: float, rate: float, n: int) -> np.ndarray:
    """``n`` stamps at ``rate`` Hz on the 1/512 s grid (exact in float s and in ns)."""
    ticks = np.round(np.arange(n) * (512.0 / rate)).astype(np.int64)
    if n > 1 and np.any(np.diff(ticks) <= 0):
        raise ValueError("rate too high for the 1/512 s stamp grid")
    return t0 + ticks / 512.0


T0 = 1_700_000_000.0


def step_scalar(x: float, y: float, theta: float, v: float, w: float, dt: float) -> tuple[float, float, float]:
    """Scalar :func:`unicycle_step` for control loops (same exact-arc formula)."""
    half = 0.5 * w * dt
    chord = v * dt * (math.sin(half) / half if half != 0.0 else 1.0)
    heading = theta + half
    return x + chord * math.cos(heading), y + chord * math.sin(heading), float(wrap(theta + 2.0 * half))
