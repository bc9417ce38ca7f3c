"""2D worlds of wall segments for the ``lidar`` scenario.

A world is ``segments`` ``(K, 4)`` = x0, y0, x1, y1 [m] plus a start pose. Built-in:
``rooms`` (12 x 8 m, four rooms with doorways and a table), ``corridor`` (24 x 2.4 m
with alcoves), ``pillars`` (14 x 14 m hall with a grid of square pillars), ``open``
(40 x 40 m, a few crates; most beams of a 5.6 m LiDAR get no return).

World file (``--world FILE``, TOML)::

    # every polygon is closed (last point joins the first), polylines are open
    start = [1.0, 1.0, 0.0]            # x, y, theta: must be >= 0.5 m from any wall
    polygons = [
      [[0, 0], [10, 0], [10, 6], [0, 6]],          # outer walls
      [[4, 2], [5, 2], [5, 3], [4, 3]],            # a box
    ]
    polylines = [ [[7, 0], [7, 4]] ]               # an inner wall

The robot must be enclosed by walls (the controller keeps it clear of every segment).
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ivslam_cli.errors import ConfigError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


@dataclass
class World:
    name: str
    segments: np.ndarray  # (K, 4)
    start: tuple[float, float, float]


def _polygon(points) -> list[list[float]]:
    pts = [tuple(map(float, p)) for p in points]
    return [[*pts[i], *pts[(i + 1) % len(pts)]] for i in range(len(pts))]


def _polyline(points) -> list[list[float]]:
    pts = [tuple(map(float, p)) for p in points]
    return [[*pts[i], *pts[i + 1]] for i in range(len(pts) - 1)]


def _box(x0, y0, x1, y1):
    return [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]


def _builtin(name: str) -> tuple[list, list, tuple]:
    if name == "rooms":
        polygons = [_box(0, 0, 12, 8), _box(8.5, 5.5, 10, 6.5)]
        polylines = [
            [[6, 0], [6, 3]], [[6, 4.2], [6, 8]],  # vertical wall, door at y 3-4.2
            [[0, 4], [2.5, 4]], [[3.7, 4], [6, 4]],  # left rooms, door at x 2.5-3.7
            [[6, 4], [7.5, 4]], [[8.7, 4], [12, 4]],  # right rooms, door at x 7.5-8.7
        ]
        return polygons, polylines, (1.5, 1.5, 0.3)
    if name == "corridor":
        polylines = [
            [[0, 0], [6, 0], [6, -1.5], [8, -1.5], [8, 0], [16, 0], [16, -1.5], [18, -1.5],
             [18, 0], [24, 0], [24, 2.4], [12, 2.4], [12, 3.9], [10, 3.9], [10, 2.4],
             [0, 2.4], [0, 0]],
        ]
        return [], polylines, (1.0, 1.2, 0.0)
    if name == "pillars":
        polygons = [_box(0, 0, 14, 14)]
        for i in range(3):
            for j in range(3):
                cx, cy = 3.5 + 3.5 * i, 3.5 + 3.5 * j
                polygons.append(_box(cx - 0.2, cy - 0.2, cx + 0.2, cy + 0.2))
        return polygons, [], (1.5, 1.5, 0.5)
    if name == "open":
        polygons = [_box(0, 0, 40, 40)]
        for cx, cy in ((12, 14), (25, 9), (30, 28), (16, 30), (22, 20)):
            polygons.append(_box(cx - 0.5, cy - 0.4, cx + 0.5, cy + 0.4))
        return polygons, [], (20.0, 15.0, 0.0)
    raise KeyError(name)


BUILTIN = ("rooms", "corridor", "pillars", "open")


def _build(name: str, polygons, polylines, start) -> World:
    segs: list[list[float]] = []
    for poly in polygons:
        if len(poly) < 3:
            raise ConfigError(f"world '{name}': a polygon needs >= 3 points")
        segs += _polygon(poly)
    for line in polylines:
        if len(line) < 2:
            raise ConfigError(f"world '{name}': a polyline needs >= 2 points")
        segs += _polyline(line)
    segments = np.asarray(segs, dtype=np.float64).reshape(-1, 4)
    if segments.shape[0] == 0 or not np.all(np.isfinite(segments)):
        raise ConfigError(f"world '{name}': no walls, or non-finite coordinates")
    start3 = tuple(float(s) for s in start)
    if len(start3) != 3 or not all(math.isfinite(s) for s in start3):
        raise ConfigError(f"world '{name}': start must be [x, y, theta]")
    clearance = float(point_segments_distance(np.asarray(start3[:2]), segments).min())
    if clearance < 0.5:
        raise ConfigError(f"world '{name}': start is {clearance:.3f} m from a wall (need >= 0.5 m)")
    return World(name, segments, start3)  # type: ignore[arg-type]


def load_world(spec: str) -> World:
    """A built-in world by name, or a TOML world file (see the module docstring)."""
    if spec in BUILTIN:
        return _build(spec, *_builtin(spec))
    path = Path(spec)
    if not os.path.lexists(path):
        raise ConfigError(f"unknown world '{spec}' (built-in: {', '.join(BUILTIN)}; or a TOML file)")
    from ivslam_cli import limits
    from ivslam_cli.inputs import check_input

    check_input(path, "TOML world file", error=ConfigError)
    try:
        limits.check("JSON_BYTES", path.stat().st_size, "the world file's size")
    except limits.LimitExceeded as exc:
        raise exc.about(path) from None
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"cannot read world file: {exc}", path) from None
    unknown = set(doc) - {"start", "polygons", "polylines", "name"}
    if unknown:
        raise ConfigError(f"unknown keys in world file: {', '.join(sorted(unknown))}", path)
    if "start" not in doc:
        raise ConfigError("world file needs 'start = [x, y, theta]'", path)
    try:
        return _build(str(doc.get("name", path.stem)), doc.get("polygons", []),
                      doc.get("polylines", []), doc["start"])
    except ConfigError as exc:
        raise ConfigError(str(exc), path) from None
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"bad world geometry ({exc})", path) from None


# ---- geometry (vectorised numpy) ----------------------------------------------------

def point_segments_distance(p: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distances from point(s) ``p`` ``(..., 2)`` to every segment: ``(..., K)``."""
    p = np.asarray(p, dtype=np.float64)[..., None, :]
    a, b = segments[:, :2], segments[:, 2:]
    ab = b - a
    len2 = np.einsum("ij,ij->i", ab, ab)
    t = np.clip(np.einsum("...ij,ij->...i", p - a, ab) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
    closest = a + t[..., None] * ab
    return np.hypot(*np.moveaxis(p - closest, -1, 0))


def segments_cross(p: np.ndarray, q: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Whether each motion ``p[i] -> q[i]`` ``(N, 2)`` crosses any wall: ``(N,)`` bool."""
    p, q = np.atleast_2d(p)[:, None, :], np.atleast_2d(q)[:, None, :]
    a, b = segments[None, :, :2], segments[None, :, 2:]

    def orient(u, v, w):
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0])

    d1, d2 = orient(a, b, p), orient(a, b, q)
    d3, d4 = orient(p, q, a), orient(p, q, b)
    return np.any((d1 * d2 <= 0) & (d3 * d4 <= 0) & ~((d1 == 0) & (d2 == 0)), axis=1)
