"""Truth checks of LiDAR results: every enclosure against the simulated truth, in its frame."""

from __future__ import annotations

import math

import numpy as np

from ivslam_cli.report.core import compute_report, relative_pose, truth_at


def true_pose_at(tr, t, t_ref: float = 0.0) -> np.ndarray:
    """The simulated robot's true poses ``(n, 3)`` at times ``t_ref + t``: on the arc through the
    two truth samples around each time (the simulator's unicycle holds its twist over a step:
    :func:`ivslam_cli.simulate.motion.step_scalar`), heading unwrapped; beyond the truth's span,
    on its first or last arc (a swept simulation's last scan is taken on the last step's arc).
    Times relative to ``t_ref`` keep the microseconds between two beams (stamps near 1.7e9 s are
    2.4e-7 s apart)."""
    t = np.atleast_1d(np.asarray(t, float))
    ts = tr.pose_stamp - t_ref
    th = np.unwrap(tr.pose[:, 2])
    k = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
    h = ts[k + 1] - ts[k]
    f = np.where(h > 0.0, (t - ts[k]) / np.where(h > 0.0, h, 1.0), 0.0)
    half = 0.5 * (th[k + 1] - th[k])
    dx, dy = tr.pose[k + 1, 0] - tr.pose[k, 0], tr.pose[k + 1, 1] - tr.pose[k, 1]
    turns = np.abs(half) > 1e-12
    # the chord to the fraction f of the arc: |chord| sin(f half) / sin(half), turned by (f - 1) half
    length = np.hypot(dx, dy) * np.where(turns, np.sin(f * half) / np.where(turns, np.sin(half), 1.0), f)
    a = np.arctan2(dy, dx) + (f - 1.0) * half
    return np.column_stack([tr.pose[k, 0] + length * np.cos(a), tr.pose[k, 1] + length * np.sin(a),
                            th[k] + 2.0 * f * half])


def containment(res) -> dict[str, tuple[int, int]]:
    """``kind -> (contained, checked)`` of the report's truth checks (poses in the result's frame,
    relative boxes, proven-free cells against the walls)."""
    rep = compute_report(res)
    return {k: (c.contained, c.checked) for k, c in rep.containment.items()}


def assert_contained(res, kinds=("pose", "map_free")) -> dict[str, tuple[int, int]]:
    c = containment(res)
    for k in kinds:
        assert k in c, f"no {k} check ({sorted(c)})"
    for k, (ok, n) in c.items():
        assert ok == n, f"{k}: {n - ok} of {n} miss the truth"
    return c


def hits_outside_obstacle(log, out, points) -> tuple[int, int]:
    """(true hit points of valid in-bound beams of mapped scans outside every cell flagged
    P_OBSTACLE^k or P_OLD^k of their submap, in its anchor's true frame; hit points checked).
    ``out``: the pipeline's :class:`LidarOutput` (its ``tracking`` holds the submaps' maps, or
    ``tmap`` the one map of a known-poses run); ``points`` (B, 2): the true hit point of every
    beam (NaN where none)."""
    sc, tr = log.scans, log.truth
    beam_scan = np.repeat(np.arange(len(sc)), np.diff(sc.offsets))
    use = sc.valid & ~tr.outliers["scans"] & np.isfinite(points[:, 0])
    maps = []
    if out.tracking is None:
        mapped = np.zeros(len(sc), bool)
        mapped[out.mapped] = True
        maps.append((out.tmap, mapped, np.zeros(3)))
    else:
        used = out.used
        for s in out.tracking.submaps:
            mapped = np.zeros(len(sc), bool)
            mapped[used[np.asarray(s.mapped, np.int64)]] = True
            a = truth_at(tr, [sc.stamp[s.anchor_scan]])[0]
            maps.append((s.tmap, mapped, a))
    missed = checked = 0
    for tmap, mapped, a in maps:
        sel = use & mapped[beam_scan]
        if not sel.any():
            continue
        p = points[sel]
        c, s_ = math.cos(a[2]), math.sin(a[2])
        d = p - a[:2]
        px, py = c * d[:, 0] + s_ * d[:, 1], -s_ * d[:, 0] + c * d[:, 1]
        miss = np.ones(px.shape[0], dtype=bool)
        e = tmap.eps
        for ox in (-1e-6, 0.0, 1e-6):  # a point on a cell border belongs to both cells
            for oy in (-1e-6, 0.0, 1e-6):
                f = tmap.get(np.floor(px / e + ox).astype(np.int64), np.floor(py / e + oy).astype(np.int64))
                miss &= (f & 6) == 0
        missed += int(miss.sum())
        checked += int(px.shape[0])
    return missed, checked


def true_relative(log, res) -> tuple[np.ndarray, np.ndarray]:
    """True poses of every submap member relative to its anchor's, and the members' boxes."""
    sm = res.submaps
    owner = np.repeat(np.arange(len(sm)), np.diff(sm.member_offsets))
    st = res.poses.stamp
    rel = relative_pose(truth_at(log.truth, st[sm.anchor[owner]]), truth_at(log.truth, st[sm.member_row]))
    return rel, sm.member_box


def members_outside(log, res) -> tuple[int, int]:
    """Submap members (every submap's, not only the newest's) whose box misses the true
    relative pose, and the members."""
    rel, box = true_relative(log, res)
    box = np.asarray(box).reshape(-1, 6)
    inside = np.all((box[:, 0:4:2] <= rel[:, :2]) & (rel[:, :2] <= box[:, 1:4:2]), axis=1)
    lo, hi = box[:, 4], box[:, 5]
    th = rel[:, 2] + 2 * np.pi * np.round(((lo + hi) / 2 - rel[:, 2]) / (2 * np.pi))
    inside &= (lo <= th) & (th <= hi)
    return int((~inside).sum()), int(inside.size)


def nearest_in_cones(log) -> np.ndarray:
    """The true hit point (B, 2) of every beam of a cone-beam log: the nearest wall point within
    the beam's cone (its stated half-width ``beam_angle``), NaN where the cone sees no wall."""
    sc, tr = log.scans, log.truth
    h = float(log.bounds.get("beam_angle", 0.0))
    mx, my, myaw = sc.mount
    segs = np.asarray(tr.world, float)
    out = np.full((sc.ranges.shape[0], 2), np.nan)
    k_of = np.searchsorted(tr.pose_stamp, sc.stamp)
    for k in range(len(sc)):
        x, y, th = tr.pose[k_of[k]]
        o = np.array([x + math.cos(th) * mx - math.sin(th) * my, y + math.sin(th) * mx + math.cos(th) * my])
        b0, b1 = int(sc.offsets[k]), int(sc.offsets[k + 1])
        ang = th + myaw + sc.angle_min[k] + np.arange(b1 - b0) * sc.angle_increment[k]
        a = segs[None, :, :2] - o  # (1, K, 2)
        dseg = segs[None, :, 2:] - segs[None, :, :2]
        t0 = np.zeros((b1 - b0, segs.shape[0]))
        t1 = np.ones_like(t0)
        ok = np.ones_like(t0, dtype=bool)
        # the wedge: n·p >= 0 for its two edge normals and the bisector (h < pi/2)
        for phi, sgn in ((ang - h, 1.0), (ang + h, -1.0), (ang, 0.0)):
            if sgn == 0.0:
                n = np.stack([np.cos(phi), np.sin(phi)], -1)  # ahead of the sensor
            else:
                n = sgn * np.stack([-np.sin(phi), np.cos(phi)], -1)
            na = (n[:, None, :] * a).sum(-1)
            nd = (n[:, None, :] * dseg).sum(-1)
            with np.errstate(divide="ignore", invalid="ignore"):
                tc = -na / nd
            t0 = np.where(nd > 0, np.maximum(t0, tc), t0)
            t1 = np.where(nd < 0, np.minimum(t1, tc), t1)
            ok &= ~((nd == 0) & (na < 0))
        ok &= t0 <= t1
        # the closest point of the clipped piece to the sensor
        dd = (dseg * dseg).sum(-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            tp = np.clip(-(a * dseg).sum(-1) / dd, t0, t1)
        p = a + tp[..., None] * dseg
        dist = np.where(ok, np.hypot(p[..., 0], p[..., 1]), np.inf)
        j = dist.argmin(1)
        best = dist[np.arange(b1 - b0), j]
        pts = p[np.arange(b1 - b0), j] + o
        pts[~np.isfinite(best)] = np.nan
        out[b0:b1] = pts
    return out
