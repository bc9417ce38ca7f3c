"""What ``ivslam report`` computes from a :class:`Result` (no I/O, no rendering).

Containment — the check that the guarantee held — per kind of enclosure:

- **landmark**: the box of landmark i holds its true position (for a relative map with
  reference r, it holds m_i − m_r);
- **pair**: the truth of pair (i, j) is dl = m_i − m_j; the subpaving holds it when some box
  of its outer approximation (inner ∪ boundary boxes, closed) does;
- **pose**: every pose box k against the truth at its own stamp ``t_k``. Where the truth has a
  sample at ``t_k`` the box must hold it. Where ``t_k`` falls strictly between two truth
  samples (at most ``MAX_TRUTH_GAP`` s apart) the box must meet the hull of those two samples
  (headings: the second moved by the multiple of 2π nearest the first): the truth is only
  known at its samples, and between two of them it is taken to stay in their hull, so a
  failure there means the box misses every pose the truth takes between its samples. The
  result claims nothing between its own stamps, so truth samples there are not compared. Pose
  boxes outside the truth's span, or inside a longer gap, are not checked (``not_checked``).
  Heading is compared modulo 2π.

A fraction below 1.0 is a **SOUNDNESS FAILURE** — unless outliers were injected (the truth
carries an outlier mask with some True). Injected outliers of a stream some q > 0 of the run
covers (:data:`Q_COVERS`: observations by the landmark, pose and pair q, scans by the beam q)
are relaxed: the guarantee holds only under ``Consistency.assumption``. Injected outliers of a
stream no q covers (odometry beyond its bounds) break the stated bounds themselves: the
guarantee does not hold for that log. Either way the report says so instead.

Widths: landmark and pose boxes by the largest side in x, y (pose heading reported apart);
pair subpavings by the largest side of the hull of their outer approximation. Empty sets
have no width (NaN, counted as ``empty``).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ivslam_cli.interval.pose import box_width
from ivslam_cli.logs.model import GroundTruth
from ivslam_cli.results.model import (
    CELL_EMPTY,
    CELL_OBSTACLE,
    CELL_UNKNOWN,
    FRAME_FIRST_POSE,
    Landmarks,
    PairSubpavings,
    Poses,
    Result,
    WidthHistory,
    box_is_empty,
)

TWO_PI = 2.0 * math.pi
SOUND = "ok"
FAILURE = "SOUNDNESS FAILURE"
RELAXED = "below 1.0 with injected outliers under q-relaxation (holds only under the stated assumption)"
BROKEN = "below 1.0 with injected outliers beyond the stated bounds that no q covers (no guarantee for this log)"
#: the streams of injected outliers (``GroundTruth.outliers``) each kind of q relaxes
Q_COVERS = {"landmark": "observations", "pose": "observations", "pair": "observations", "beams": "scans"}


# ---------------------------------------------------------------- array primitives
def in_box(box: np.ndarray, point: np.ndarray) -> np.ndarray:
    """``box[..., d, 2]`` closed boxes, ``point[..., d]``: True where the point is in the box."""
    return np.all((box[..., 0] <= point) & (point <= box[..., 1]), axis=-1)


def angle_in(lo: np.ndarray, hi: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """True where θ + 2πn ∈ [lo, hi] for some integer n (intervals on the real line)."""
    lo, hi, theta = np.broadcast_arrays(np.asarray(lo, float), np.asarray(hi, float), np.asarray(theta, float))
    finite = np.isfinite(lo) & np.isfinite(hi)
    with np.errstate(invalid="ignore"):
        n = np.ceil((lo - theta) / TWO_PI)  # may be off by one (rounding, underflow): try n ± 1
        ok = hi - lo >= TWO_PI
        for d in (-1.0, 0.0, 1.0):
            shifted = theta + TWO_PI * (n + d)
            ok |= (lo <= shifted) & (shifted <= hi)
    unbounded = (lo <= hi) & ~finite  # an infinite side: contains every angle
    return np.where(finite, ok & (lo <= hi), unbounded)


def box_centre(box: np.ndarray) -> np.ndarray:
    """Centres ``[..., d]``; NaN for empty boxes."""
    with np.errstate(invalid="ignore"):  # inf + (−inf) for empty boxes, masked below
        c = 0.5 * (box[..., 0] + box[..., 1])
    return np.where(box_is_empty(box)[..., None], np.nan, c)


def pair_hulls(pairs: PairSubpavings) -> np.ndarray:
    """Hull ``(P, 2, 2)`` of each pair's outer approximation (empty for pairs with no box)."""
    n = len(pairs)
    hull = np.empty((n, 2, 2))
    hull[..., 0] = np.inf
    hull[..., 1] = -np.inf
    if pairs.boxes.shape[0]:
        owner = np.repeat(np.arange(n), np.diff(pairs.offsets))
        ok = ~box_is_empty(pairs.boxes)
        np.minimum.at(hull[..., 0], owner[ok], pairs.boxes[ok, :, 0])
        np.maximum.at(hull[..., 1], owner[ok], pairs.boxes[ok, :, 1])
    return hull


# ---------------------------------------------------------------- containment
@dataclass
class Containment:
    kind: str
    checked: int
    contained: int
    not_checked: int = 0
    failures: list[str] = field(default_factory=list)  # which entities missed the truth
    centre_error: np.ndarray = field(default_factory=lambda: np.zeros(0))  # per checked entity [m]

    @property
    def fraction(self) -> float:
        return self.contained / self.checked if self.checked else math.nan


def _truth_landmarks(truth: GroundTruth) -> dict[int, np.ndarray]:
    if truth.landmark_id is None or truth.landmark_xy is None:
        return {}
    return {int(i): np.asarray(xy, float) for i, xy in zip(truth.landmark_id, truth.landmark_xy)}


def landmark_containment(lm: Landmarks, truth: GroundTruth) -> Containment | None:
    known = _truth_landmarks(truth)
    if not known:
        return None
    offset = np.zeros(2)
    if lm.reference_id is not None:
        if lm.reference_id not in known:
            return Containment("landmark", 0, 0, not_checked=len(lm))
        offset = known[lm.reference_id]
    have = np.array([int(i) in known for i in lm.id], dtype=bool)
    if not have.any():
        return Containment("landmark", 0, 0, not_checked=len(lm))
    t = np.array([known[int(i)] - offset for i in lm.id[have]])
    box = lm.box[have]
    ok = in_box(box, t)
    err = np.linalg.norm(box_centre(box) - t, axis=-1)
    return Containment(
        "landmark",
        int(have.sum()),
        int(ok.sum()),
        not_checked=int((~have).sum()),
        failures=[f"landmark {int(i)}" for i in lm.id[have][~ok]],
        centre_error=err,
    )


def pair_containment(pairs: PairSubpavings, truth: GroundTruth) -> Containment | None:
    known = _truth_landmarks(truth)
    if not known:
        return None
    have = np.array([int(a) in known and int(b) in known for a, b in zip(pairs.i, pairs.j)], dtype=bool)
    if not have.any():
        return Containment("pair", 0, 0, not_checked=len(pairs))
    dl = np.zeros((len(pairs), 2))
    dl[have] = [known[int(a)] - known[int(b)] for a, b in zip(pairs.i[have], pairs.j[have])]
    counts = np.diff(pairs.offsets)
    owner = np.repeat(np.arange(len(pairs)), counts)
    hit = in_box(pairs.boxes, dl[owner]) if pairs.boxes.shape[0] else np.zeros(0, bool)
    held = np.bincount(owner[hit], minlength=len(pairs)) > 0
    ok = held[have]
    err = np.linalg.norm(box_centre(pair_hulls(pairs))[have] - dl[have], axis=-1)
    return Containment(
        "pair",
        int(have.sum()),
        int(ok.sum()),
        not_checked=int((~have).sum()),
        failures=[f"pair ({int(a)},{int(b)})" for a, b in zip(pairs.i[have][~ok], pairs.j[have][~ok])],
        centre_error=err,
    )


def truth_at(truth: GroundTruth, t: np.ndarray) -> np.ndarray:
    """True poses (n, 3) at stamps ``t``, linearly interpolated (heading unwrapped); NaN outside
    the truth's span."""
    ts, tp = np.asarray(truth.pose_stamp, float), np.asarray(truth.pose, float)
    t = np.atleast_1d(np.asarray(t, float))
    out = np.full((t.size, 3), np.nan)
    if ts.size == 0:
        return out
    inside = (t >= ts[0]) & (t <= ts[-1])
    th = np.unwrap(tp[:, 2])
    for d, col in enumerate((tp[:, 0], tp[:, 1], th)):
        out[inside, d] = np.interp(t[inside], ts, col)
    return out


def relative_pose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a⁻¹ ⊕ b`` row by row: poses ``b`` (n, 3) in the frames of poses ``a`` (n, 3)."""
    d = b[:, :2] - a[:, :2]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], b[:, 2] - a[:, 2]])


def truth_in_frame(poses: Poses, truth: GroundTruth) -> GroundTruth:
    """The truth expressed in the frame of the pose boxes: unchanged in the world frame; for
    the frame of the first pose, every true pose relative to the true pose at ``origin_stamp``
    (and the true landmarks and walls in that frame)."""
    if poses.frame != FRAME_FIRST_POSE or truth.pose is None or truth.pose_stamp is None:
        return truth
    o = truth_at(truth, [poses.origin_stamp])
    if not np.all(np.isfinite(o)):
        return truth
    tp = np.asarray(truth.pose, float)
    out = GroundTruth(pose_stamp=truth.pose_stamp, pose=relative_pose(np.repeat(o, tp.shape[0], 0), tp),
                      outliers=truth.outliers)
    c, s = math.cos(o[0, 2]), math.sin(o[0, 2])

    def to_frame(xy: np.ndarray) -> np.ndarray:
        d = np.asarray(xy, float) - o[0, :2]
        return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])

    if truth.landmark_id is not None and truth.landmark_xy is not None:
        out.landmark_id, out.landmark_xy = truth.landmark_id, to_frame(truth.landmark_xy)
    if truth.world is not None:
        w = np.asarray(truth.world, float)
        out.world = np.column_stack([to_frame(w[:, :2]), to_frame(w[:, 2:])])
    return out


MAX_TRUTH_GAP = 0.5  # s: the longest gap between two truth samples a pose box is compared in


def pose_containment(poses: Poses, truth: GroundTruth, max_gap: float = MAX_TRUTH_GAP) -> Containment | None:
    """Each pose box against the truth at its stamp (see the module docstring); the centre
    error against the truth interpolated linearly at the stamp."""
    if truth.pose_stamp is None or truth.pose is None or len(poses) == 0 or len(truth.pose_stamp) == 0:
        return None
    s, ts, tp = poses.stamp, np.asarray(truth.pose_stamp, float), np.asarray(truth.pose, float)
    j1 = np.clip(np.searchsorted(ts, s, side="left"), 0, len(ts) - 1)
    exact = ts[j1] == s
    j0 = np.where(exact, j1, np.maximum(j1 - 1, 0))
    use = (s >= ts[0]) & (s <= ts[-1]) & (exact | (ts[j1] - ts[j0] <= max_gap))
    rows = np.flatnonzero(use)
    a, b = tp[j0[rows]], tp[j1[rows]].copy()
    b[:, 2] += TWO_PI * np.round((a[:, 2] - b[:, 2]) / TWO_PI)  # the branch nearest a's heading
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    box = poses.box[rows]
    with np.errstate(invalid="ignore"):  # empty (NaN) boxes meet nothing
        meets_xy = np.all((box[:, :2, 0] <= hi[:, :2]) & (lo[:, :2] <= box[:, :2, 1]), axis=-1)
        # [lo, hi] + 2πn meets the heading interval iff hi + 2πn ∈ [box_lo, box_hi + (hi − lo)]
        meets_th = angle_in(box[:, 2, 0], box[:, 2, 1] + (hi[:, 2] - lo[:, 2]), hi[:, 2])
    ok = meets_xy & meets_th
    err = np.linalg.norm(box_centre(box[:, :2]) - truth_at(truth, s[rows])[:, :2], axis=-1)
    return Containment(
        "pose",
        int(rows.size),
        int(ok.sum()),
        not_checked=int(len(s) - rows.size),
        failures=[f"pose {int(k)} at t={t:.6g}" for k, t in zip(rows[~ok], s[rows][~ok])],
        centre_error=err,
    )


def _relative_check(r: Result, truth: GroundTruth, a_rows: np.ndarray, b_rows: np.ndarray, box: np.ndarray):
    """Relative enclosures ``box`` (pose row b in pose row a's robot frame) against the true
    relative poses at the two rows' stamps: ``(have, ok, centre error)``, ``ok`` over the rows
    with both truths (``have``)."""
    st = r.poses.stamp
    ta, tb = truth_at(truth, st[a_rows]), truth_at(truth, st[b_rows])
    have = np.all(np.isfinite(ta), axis=1) & np.all(np.isfinite(tb), axis=1)
    rel = relative_pose(ta[have], tb[have])
    box = box[have]
    ok = in_box(box[:, :2], rel[:, :2]) & angle_in(box[:, 2, 0], box[:, 2, 1], rel[:, 2])
    return have, ok, np.linalg.norm(box_centre(box[:, :2]) - rel[:, :2], axis=-1)


def relative_containment(r: Result, truth: GroundTruth) -> Containment | None:
    """Every scan's box in its submap's frame against the true pose relative to the true pose
    of the submap's anchor (truth at the two scans' stamps)."""
    sm = r.submaps
    if sm is None or truth.pose is None or truth.pose_stamp is None or len(sm) == 0:
        return None
    owner = np.repeat(np.arange(len(sm)), np.diff(sm.member_offsets))
    a_rows, b_rows = sm.anchor[owner], sm.member_row
    keep = a_rows != b_rows
    if not keep.any():
        return None
    have, ok, err = _relative_check(r, truth, a_rows[keep], b_rows[keep], sm.member_box[keep])
    rows = b_rows[keep][have]
    subs = owner[keep][have]
    return Containment("pose_relative", int(have.sum()), int(ok.sum()), not_checked=int((~have).sum()),
                       failures=[f"scan row {int(b)} in submap {int(m)}" for b, m in zip(rows[~ok], subs[~ok])],
                       centre_error=err)


def scan_pair_mask(r: Result) -> np.ndarray | None:
    """Which of ``r.relative``'s enclosures are scan pairs (``lidar.pair_boxes``: consecutive
    scans matched alone), not a submap member's box in its anchor's frame (those are the
    submaps' own); None without any."""
    rp, sm = r.relative, r.submaps
    if rp is None or len(rp) == 0 or sm is None:
        return None
    owner = np.repeat(np.arange(len(sm)), np.diff(sm.member_offsets))
    member: dict = {}
    for a, b, box in zip(np.asarray(sm.anchor)[owner].tolist(), np.asarray(sm.member_row).tolist(), sm.member_box):
        member.setdefault((a, b), []).append(box)
    mask = np.array([not any(np.array_equal(box, m) for m in member.get((int(a), int(b)), ()))
                     for (a, b), box in zip(rp.pairs, rp.box)], bool)
    return mask if mask.any() else None


def scan_pair_containment(r: Result, truth: GroundTruth) -> Containment | None:
    """Every scan pair's relative enclosure (later scan in the earlier one's robot frame) against
    the true relative pose (truth at the two scans' stamps)."""
    mask = scan_pair_mask(r)
    if mask is None or truth.pose is None or truth.pose_stamp is None:
        return None
    pairs = r.relative.pairs[mask]
    have, ok, err = _relative_check(r, truth, pairs[:, 0], pairs[:, 1], r.relative.box[mask])
    bad = pairs[have][~ok]
    return Containment("pose_scan_pair", int(have.sum()), int(ok.sum()), not_checked=int((~have).sum()),
                       failures=[f"scan rows {int(a)} -> {int(b)}" for a, b in bad], centre_error=err)


def segments_meet_cells(segs: np.ndarray, cells: np.ndarray, eps: float, origin, margin: float = 1e-6) -> np.ndarray:
    """Whether each cell ``(column, row)`` of a grid (side ``eps``, corner ``origin``; closed
    squares grown by ``margin``: the safe side for a check of free cells) meets a segment
    ``(x0, y0, x1, y1)`` (Liang–Barsky clipping)."""
    out = np.zeros(cells.shape[0], bool)
    if cells.shape[0] == 0 or segs.shape[0] == 0:
        return out
    for c0 in range(0, cells.shape[0], 20000):  # bounded memory: (chunk, walls) arrays
        ch = cells[c0:c0 + 20000]
        lo = np.asarray(origin, float) + ch[:, None, :] * eps - margin
        hi = np.asarray(origin, float) + (ch[:, None, :] + 1) * eps + margin
        a, d = segs[None, :, :2], segs[None, :, 2:] - segs[None, :, :2]
        t0 = np.zeros(lo.shape[:1] + (segs.shape[0],))
        t1 = np.ones_like(t0)
        ok = np.ones_like(t0, dtype=bool)
        for ax in range(2):
            dd = np.broadcast_to(d[..., ax], t0.shape)
            aa = np.broadcast_to(a[..., ax], t0.shape)
            par = dd == 0
            ok &= ~par | ((aa >= lo[..., ax]) & (aa <= hi[..., ax]))
            with np.errstate(divide="ignore", invalid="ignore"):
                ta = (lo[..., ax] - aa) / dd
                tb = (hi[..., ax] - aa) / dd
            t0 = np.where(par, t0, np.maximum(t0, np.minimum(ta, tb)))
            t1 = np.where(par, t1, np.minimum(t1, np.maximum(ta, tb)))
        out[c0:c0 + 20000] = np.any(ok & (t0 <= t1), axis=1)
    return out


def free_cell_containment(r: Result, truth: GroundTruth) -> Containment | None:
    """P_EMPTY against the true walls (simulated worlds): every proven-free cell of every
    submap, in its anchor's true frame (or of the map, in the result's frame), must miss them."""
    if truth.world is None or r.grid is None:
        return None
    walls = np.asarray(truth.world, float)
    grids = []
    if r.submaps is not None:
        if truth.pose is None or truth.pose_stamp is None:
            return None
        anchors = truth_at(truth, r.poses.stamp[r.submaps.anchor])
        for m in range(len(r.submaps)):
            if not np.all(np.isfinite(anchors[m])):
                continue
            o = anchors[m]
            c, s = math.cos(o[2]), math.sin(o[2])
            d0, d1 = walls[:, :2] - o[:2], walls[:, 2:] - o[:2]
            w = np.column_stack([c * d0[:, 0] + s * d0[:, 1], -s * d0[:, 0] + c * d0[:, 1],
                                 c * d1[:, 0] + s * d1[:, 1], -s * d1[:, 0] + c * d1[:, 1]])
            grids.append((f"submap {m}", r.submaps.grid(m), w))
    elif r.grid.frame != "mosaic":
        grids.append(("map", r.grid, walls))
    return _free_cells_on_walls("map_free", grids)


def global_free_containment(r: Result, truth: GroundTruth) -> Containment | None:
    """The global map's P_EMPTY (``r.global_map``, proven in the result's frame) against the
    true walls in that frame (``truth`` as :func:`truth_in_frame` gives it)."""
    if truth.world is None or r.global_map is None:
        return None
    return _free_cells_on_walls("global_free", [("global map", r.global_map, np.asarray(truth.world, float))])


def _free_cells_on_walls(kind: str, grids) -> Containment:
    checked = bad = 0
    failures: list[str] = []
    for name, g, w in grids:
        rows, cols = np.nonzero(g.state == CELL_EMPTY)
        meet = segments_meet_cells(w, np.column_stack([cols, rows]), g.resolution, g.origin)
        checked += int(rows.size)
        nb = int(meet.sum())
        bad += nb
        if nb:
            failures.append(f"{name}: {nb} proven-free cell(s) on a true wall")
    return Containment(kind, checked, checked - bad, failures=failures)

def robot_pose_containment(r: Result) -> dict[int, Containment]:
    """Per robot of a result of several (``r.robots``): its pose rows against its truth rows."""
    out: dict[int, Containment] = {}
    rb, truth = r.robots, r.truth
    if rb is None or r.poses is None or truth is None or truth.pose is None or truth.pose_stamp is None:
        return out
    for i, rid in enumerate(rb.id):
        a, b = int(rb.pose_offsets[i]), int(rb.pose_offsets[i + 1])
        ta, tb = int(rb.truth_offsets[i]), int(rb.truth_offsets[i + 1])
        if b <= a or tb <= ta:
            continue
        c = pose_containment(Poses(stamp=r.poses.stamp[a:b], box=r.poses.box[a:b]),
                             GroundTruth(pose_stamp=truth.pose_stamp[ta:tb], pose=truth.pose[ta:tb]))
        if c is not None:
            c.failures = [f"robot {int(rid)}: {f}" for f in c.failures]
            out[int(rid)] = c
    return out


def _combined(parts: list[Containment], kind: str) -> Containment:
    return Containment(kind, sum(c.checked for c in parts), sum(c.contained for c in parts),
                       not_checked=sum(c.not_checked for c in parts),
                       failures=[f for c in parts for f in c.failures],
                       centre_error=np.concatenate([c.centre_error for c in parts]) if parts else np.zeros(0))


# ---------------------------------------------------------------- widths
@dataclass
class WidthStat:
    median: float
    max: float
    count: int
    empty: int


def width_stat(w: np.ndarray) -> WidthStat:
    w = np.asarray(w, float)
    fin = w[~np.isnan(w)]
    if fin.size == 0:
        return WidthStat(math.nan, math.nan, int(w.size), int(w.size))
    return WidthStat(float(np.median(fin)), float(np.max(fin)), int(w.size), int(w.size - fin.size))


@dataclass
class Convergence:
    """Per kind: widths at each entity's first and last update, and a binned curve."""

    definition: str
    entities: int
    updates: int
    initial: WidthStat
    final: WidthStat
    increases: int  # consecutive updates of one entity where the width grew
    curve_step: np.ndarray  # bin centres (step)
    curve_median: np.ndarray
    curve_max: np.ndarray


def convergence(h: WidthHistory, bins: int = 50) -> Convergence:
    n = len(h)
    if n == 0:
        nan = WidthStat(math.nan, math.nan, 0, 0)
        z = np.zeros(0)
        return Convergence(h.definition, 0, 0, nan, nan, 0, z, z, z)
    order = np.lexsort((h.step, h.entity[:, 1], h.entity[:, 0]))
    ent, w = h.entity[order], h.width[order]
    new = np.ones(n, dtype=bool)
    new[1:] = np.any(ent[1:] != ent[:-1], axis=1)
    first = np.flatnonzero(new)
    last = np.append(first[1:] - 1, n - 1)
    with np.errstate(invalid="ignore"):
        grew = (~new[1:]) & (w[1:] > w[:-1])
    # binned curve over steps
    step = h.step.astype(float)
    lo, hi = float(step.min()), float(step.max())
    nb = max(1, min(bins, int(hi - lo) + 1))
    edges = np.linspace(lo, hi + 1.0, nb + 1)
    which = np.clip(np.searchsorted(edges, step, side="right") - 1, 0, nb - 1)
    med, mx = np.full(nb, np.nan), np.full(nb, np.nan)
    for b in range(nb):  # ≤ 50 bins: reporting, not a hot path
        vals = h.width[(which == b) & ~np.isnan(h.width)]
        if vals.size:
            med[b], mx[b] = np.median(vals), np.max(vals)
    keep = ~np.isnan(med)
    centres = 0.5 * (edges[:-1] + edges[1:]) - 0.5
    return Convergence(
        h.definition,
        int(first.size),
        n,
        width_stat(w[first]),
        width_stat(w[last]),
        int(grew.sum()),
        centres[keep],
        med[keep],
        mx[keep],
    )


# ---------------------------------------------------------------- the report
@dataclass
class Report:
    result: Result
    containment: dict[str, Containment]
    soundness: dict[str, str]
    final_width: dict[str, WidthStat]
    convergence: dict[str, Convergence]
    outliers_injected: int
    relaxed: bool  # every injected outlier is in a stream some q > 0 covers
    intersections: int  # set updates recorded (width-history records)
    non_empty: int  # ... of which stayed non-empty
    rejected_by_reason: dict[str, int]
    map_cells: dict[str, int]
    map_area_m2: dict[str, float]
    map_beams: dict[str, int] = field(default_factory=dict)  # lidar: scans/beams mapped, old/new
    # lidar: the log-odds baseline (not guaranteed) and where it disagrees with the interval map
    logodds_cells: dict[str, int] = field(default_factory=dict)  # occupied / free / unknown
    disagreement: dict[str, int] = field(default_factory=dict)  # see slam.lidar.logodds.compare
    disagreement_code: np.ndarray | None = None  # (H, W) uint8 per-cell codes (for the plot)
    outliers_by_stream: dict[str, int] = field(default_factory=dict)  # injected, per stream
    outliers_relaxed: dict[str, bool] = field(default_factory=dict)  # ... and whether a q > 0 covers it
    robot_containment: dict[int, Containment] = field(default_factory=dict)  # several robots: poses per robot

    @property
    def empty_events(self) -> int:
        return len(self.result.consistency.empty_events)

    @property
    def sound(self) -> bool:
        return all(v != FAILURE for v in self.soundness.values())


def final_widths(r: Result) -> dict[str, WidthStat]:
    out: dict[str, WidthStat] = {}
    if r.landmarks is not None and len(r.landmarks):
        out["landmark"] = width_stat(box_width(r.landmarks.box))
    if r.pairs is not None and len(r.pairs):
        out["pair"] = width_stat(box_width(pair_hulls(r.pairs)))
    if r.poses is not None and len(r.poses):
        for kind, b in (("pose", r.poses.box), ("pose_relative", r.poses.relative)):
            if b is None:
                continue
            out[kind] = width_stat(box_width(b[:, :2]))
            th = b[:, 2, 1] - b[:, 2, 0]
            out[kind + "_heading"] = width_stat(np.where(box_is_empty(b), np.nan, th))
    mask = scan_pair_mask(r)
    if mask is not None:
        b = r.relative.box[mask]
        out["pose_scan_pair"] = width_stat(box_width(b[:, :2]))
        out["pose_scan_pair_heading"] = width_stat(b[:, 2, 1] - b[:, 2, 0])
    return out


def compute_report(r: Result) -> Report:
    """Everything ``ivslam report`` shows, computed from the result alone."""
    cont: dict[str, Containment] = {}
    truth = r.truth
    per_robot = robot_pose_containment(r)
    if truth is not None:
        framed = truth_in_frame(r.poses, truth) if r.poses is not None else truth
        poses = None
        if r.poses is not None:
            poses = (_combined(list(per_robot.values()), "pose") if r.robots is not None
                     else pose_containment(r.poses, framed))
        for c in (
            landmark_containment(r.landmarks, framed) if r.landmarks is not None else None,
            pair_containment(r.pairs, truth) if r.pairs is not None else None,
            poses,
            relative_containment(r, truth),
            scan_pair_containment(r, truth),
            free_cell_containment(r, framed),
            global_free_containment(r, framed),
        ):
            if c is not None and c.checked:
                cont[c.kind] = c
    by_stream = {str(k): int(np.count_nonzero(m)) for k, m in (truth.outliers.items() if truth else ())}
    by_stream = {k: n for k, n in by_stream.items() if n}
    covered = {Q_COVERS.get(k) for k, q in r.consistency.q.items() if int(q) > 0}
    stream_relaxed = {k: k in covered for k in by_stream}
    injected = sum(by_stream.values())
    relaxed = bool(by_stream) and all(stream_relaxed.values())
    short = FAILURE if not injected else (RELAXED if relaxed else BROKEN)
    soundness = {k: SOUND if c.contained == c.checked else short for k, c in cont.items()}
    widths = r.consistency.widths
    updates = sum(len(h) for h in widths.values())
    non_empty = sum(int(np.count_nonzero(~np.isnan(h.width))) for h in widths.values())
    if "intersections" in r.stats:  # a pipeline may count its own intersections
        updates = int(r.stats["intersections"])
        non_empty = updates - len(r.consistency.empty_events)
    cells: dict[str, int] = {}
    area: dict[str, float] = {}
    if r.grid is not None:
        for name, code in (("unknown", CELL_UNKNOWN), ("empty", CELL_EMPTY), ("obstacle", CELL_OBSTACLE)):
            cells[name] = int(np.count_nonzero(r.grid.state == code))
            area[name] = cells[name] * r.grid.resolution**2
        if "measured_cells" in r.stats:  # cells with any flag (proven free, or in some P_OBSTACLE^k / P_OLD^k)
            cells["explored"] = int(r.stats["measured_cells"])
            area["explored"] = cells["explored"] * r.grid.resolution**2
    beams = {name: int(r.stats[key]) for key, name in (
        ("scans", "scans"), ("scans_mapped", "scans_mapped"), ("beams", "beams"),
        ("valid_beams_mapped", "valid_mapped"), ("old_beams", "old"), ("new_beams", "new")) if key in r.stats}
    lo_cells: dict[str, int] = {}
    dis: dict[str, int] = {}
    dis_code = None
    if r.logodds is not None and r.grid is not None:
        from ivslam_cli.slam.lidar.logodds import compare  # numba only when there is one

        d = compare(r.grid, r.logodds)
        lo_cells, dis, dis_code = d.logodds_cells, d.counts(), d.code
    return Report(
        result=r,
        containment=cont,
        soundness=soundness,
        final_width=final_widths(r),
        convergence={k: convergence(h) for k, h in widths.items()},
        outliers_injected=injected,
        relaxed=relaxed,
        outliers_by_stream=by_stream,
        outliers_relaxed=stream_relaxed,
        intersections=updates,
        non_empty=non_empty,
        rejected_by_reason=dict(Counter(str(x) for x in r.consistency.rejected.reason)),
        map_cells=cells,
        map_area_m2=area,
        map_beams=beams,
        logodds_cells=lo_cells,
        disagreement=dis,
        disagreement_code=dis_code,
        robot_containment=per_robot,
    )


def event_dicts(r: Result) -> list[dict[str, Any]]:
    """Every empty event as a plain dict (text and JSON output)."""
    e = r.consistency.empty_events
    return [
        {
            "stamp": float(e.stamp[k]),
            "step": int(e.step[k]),
            "constraint": str(e.constraint[k]),
            "entity": [int(x) for x in e.entity[k]],
            "measurement": int(e.measurement[k]),
            "text": str(e.text[k]),
        }
        for k in range(len(e))
    ]
