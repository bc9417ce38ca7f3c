"""Random wall worlds and a cone LiDAR whose truth is known, for the map update, the pose
contraction and the pipeline tests (moved from test_lidar_map.py unchanged).

Scans come from a cone LiDAR in random wall worlds: beam ``i`` returns the distance to the
nearest wall point within its cone ``a_i + [-r_α, r_α]`` (the seed's sensor model), plus a
bounded error ``|e| <= 0.999 (abs + rel d)``, as float32. The hit point is that nearest point.
Pose boxes hold the true robot pose at a random place.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ivslam_cli.logs.model import Scans

BEAMS, INC = 683, 2 * math.pi / 1024  # URG-04LX-like: 683 beams over 240 degrees
A0 = -0.5 * (BEAMS - 1) * INC
RANGE_MIN, RANGE_MAX = 0.02, 5.6


# ---------------------------------------------------------------- worlds and a cone LiDAR
def random_world(rng: np.random.Generator) -> tuple[np.ndarray, tuple[float, float, float, float]]:
    """A rectangular room with random inner walls and boxes: segments (K, 4) and the room."""
    w, h = rng.uniform(3.0, 9.0), rng.uniform(3.0, 7.0)
    x0, y0 = rng.uniform(-20, 20), rng.uniform(-20, 20)
    segs = [[x0, y0, x0 + w, y0], [x0 + w, y0, x0 + w, y0 + h], [x0 + w, y0 + h, x0, y0 + h],
            [x0, y0 + h, x0, y0]]
    for _ in range(rng.integers(0, 5)):
        ax, ay = x0 + rng.uniform(0, w), y0 + rng.uniform(0, h)
        ang, ln = rng.uniform(0, math.pi), rng.uniform(0.3, 2.5)
        segs.append([ax, ay, ax + ln * math.cos(ang), ay + ln * math.sin(ang)])
    for _ in range(rng.integers(0, 3)):
        cx, cy, s = x0 + rng.uniform(0, w), y0 + rng.uniform(0, h), rng.uniform(0.1, 0.5)
        segs += [[cx - s, cy - s, cx + s, cy - s], [cx + s, cy - s, cx + s, cy + s],
                 [cx + s, cy + s, cx - s, cy + s], [cx - s, cy + s, cx - s, cy - s]]
    return np.asarray(segs, dtype=np.float64), (x0, y0, w, h)


def seg_dist(p: np.ndarray, segs: np.ndarray) -> np.ndarray:
    a, b = segs[:, :2], segs[:, 2:]
    ab = b - a
    t = np.clip(((p - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-300), 0.0, 1.0)
    return np.hypot(*(p - (a + t[:, None] * ab)).T)


def random_pose(rng, segs, room) -> np.ndarray:
    x0, y0, w, h = room
    for _ in range(1000):
        p = np.array([x0 + rng.uniform(0.4, w - 0.4), y0 + rng.uniform(0.4, h - 0.4)])
        if seg_dist(p, segs).min() > 0.4:
            return np.array([p[0], p[1], rng.uniform(-math.pi, math.pi)])
    pytest.skip("no free pose in this world")  # pragma: no cover


def cone_scan(origin: np.ndarray, yaw: float, segs: np.ndarray, half: float):
    """Nearest wall point within each beam's cone: distances (B,) (inf: none) and points (B, 2)."""
    beta = yaw + A0 + INC * np.arange(BEAMS)
    rel = segs.reshape(-1, 2, 2) - origin  # (K, 2, 2)
    a, b = rel[:, 0], rel[:, 1]
    best = np.full(BEAMS, np.inf)
    pts = np.zeros((BEAMS, 2))

    def consider(p, ok):  # p (B, K, 2), ok (B, K)
        d = np.where(ok, np.hypot(p[..., 0], p[..., 1]), np.inf)
        k = d.argmin(1)
        dk = d[np.arange(BEAMS), k]
        better = dk < best
        best[better] = dk[better]
        pts[better] = p[np.arange(BEAMS), k][better]

    def in_cone(p):
        ang = np.arctan2(p[..., 1], p[..., 0]) - beta[:, None]
        ang = (ang + math.pi) % (2 * math.pi) - math.pi
        return np.abs(ang) <= half

    for end in (a, b):  # end points inside the cone
        p = np.broadcast_to(end, (BEAMS,) + end.shape)
        consider(p, in_cone(p))
    ab = b - a
    t = np.clip(-(a * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-300), 0.0, 1.0)
    foot = np.broadcast_to(a + t[:, None] * ab, (BEAMS,) + a.shape)  # nearest point of each segment
    consider(foot, in_cone(foot))
    for edge in (-half, half):  # crossings of the cone's two boundary rays
        u = np.stack([np.cos(beta + edge), np.sin(beta + edge)], 1)[:, None, :]
        den = u[..., 0] * ab[None, :, 1] - u[..., 1] * ab[None, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (a[None, :, 0] * u[..., 1] - a[None, :, 1] * u[..., 0]) / den
            r = (a[None, :, 0] * ab[None, :, 1] - a[None, :, 1] * ab[None, :, 0]) / den
        ok = (den != 0) & (s >= 0) & (s <= 1) & (r > 0)
        consider(u * np.where(ok, r, 0.0)[..., None], ok)
    pts = pts + origin
    return best, pts


def make_scans(rng, segs, poses, mount, half, r_abs, r_rel, noise="uniform"):
    """Scans of the cone LiDAR from robot poses (T, 3); returns (Scans, hit points (T, B, 2), hit (T, B))."""
    T = poses.shape[0]
    ranges, valid, hits, hitmask = [], [], [], []
    for k in range(T):
        x, y, th = poses[k]
        o = np.array([x + math.cos(th) * mount[0] - math.sin(th) * mount[1],
                      y + math.sin(th) * mount[0] + math.cos(th) * mount[1]])
        d, p = cone_scan(o, th + mount[2], segs, half)
        b = r_abs + r_rel * np.where(np.isfinite(d), d, 0.0)
        u = rng.uniform(-1, 1, BEAMS) if noise == "uniform" else np.where(rng.random(BEAMS) < 0.5, -1.0, 1.0)
        z = np.where(np.isfinite(d), d + 0.999 * u * b, 0.0).astype(np.float32)
        ok = np.isfinite(d) & (z >= np.float32(RANGE_MIN)) & (z <= np.float32(RANGE_MAX))
        assert np.all(np.abs(z[ok].astype(np.float64) - d[ok]) <= b[ok])
        ranges.append(np.where(ok, z, np.float32(0.0)))
        valid.append(ok)
        hits.append(p)
        hitmask.append(ok)
    ones = np.ones(T)
    scans = Scans(stamp=np.arange(T) * 0.1, angle_min=ones * A0, angle_increment=ones * INC,
                  range_min=ones * RANGE_MIN, range_max=ones * RANGE_MAX,
                  offsets=np.arange(T + 1, dtype=np.int64) * BEAMS,
                  ranges=np.concatenate(ranges).astype(np.float32), valid=np.concatenate(valid),
                  mount=tuple(mount))
    return scans, np.stack(hits), np.stack(hitmask)


def random_box(rng, pose, wxy, wth, full=False) -> np.ndarray:
    """A box of half-widths up to (exactly, with ``full``) (wxy, wxy, wth) holding ``pose``."""
    hw = (1.0 if full else rng.uniform(0.3, 1.0, 3)) * np.array([wxy, wxy, wth])
    f = rng.uniform(0, 1, 3)
    lo = pose - 2 * hw * f
    return np.array([lo[0], lo[0] + 2 * hw[0], lo[1], lo[1] + 2 * hw[1], lo[2], lo[2] + 2 * hw[2]])


# ---------------------------------------------------------------- truth checks
def segments_meet_cells(segs: np.ndarray, cells: np.ndarray, eps: float, margin: float = 1e-9) -> np.ndarray:
    """Whether each cell (closed square at the grid origin 0, grown by ``margin``: the safe side)
    meets any segment: the report's check (:func:`ivslam_cli.report.core.segments_meet_cells`)."""
    from ivslam_cli.report.core import segments_meet_cells as meet

    return meet(np.asarray(segs, float), np.asarray(cells), eps, (0.0, 0.0), margin)
