"""``ivslam report --relations FILE``: a result's pose enclosures against benchmark relations.

A relations file (Kümmerle et al., "On measuring the accuracy of SLAM algorithms", Autonomous
Robots 27(4), 2009) has one relation a line, ``t1 t2 dx dy dz droll dpitch dyaw``: the true
pose of the robot at ``t2`` expressed in its frame at ``t1``. Plain, gzip or xz; blank lines
and ``#`` comments are skipped. The planar part ``(dx, dy, dyaw)`` is used.

**Matching.** A relation end ``t`` falls on pose enclosure ``k`` of the result when
``|t − stamp_k| ≤ tol`` and ``k`` is the only pose stamp that close (an ambiguous end is not
matched). A relation is checked when both ends fall on pose enclosures, and on two different
ones. The default ``tol`` (:data:`DEFAULT_TOL`, 0.1 ms) asks for the same stamp up to the
microsecond printing of the files: a relation end a millisecond from a keyframe is another
scan of the full log (on the Intel data such ends are 0.75 ms or more away, and some relations
join two scans 5 ms apart that would both fall on one keyframe).

**What the two boxes allow.** With ``[p1] = [x1] × [y1] × [θ1]`` and ``[p2]`` the boxes at the
two ends, every pair of poses in them has its relative pose in

    Δ  = R(−θ1) (p2 − p1)  ∈  [Δx] × [Δy],   Δθ = θ2 − θ1 ∈ [θ2] − [θ1]  (modulo 2π)

computed in interval arithmetic with outward rounding (:mod:`ivslam_cli.interval.arith`):
``[θ1]`` is cut into ``slices`` pieces (each piece's image is enclosed, their hull kept: a
sound and tighter enclosure than one rotation by the whole interval), and each of
``[Δx]``, ``[Δy]`` is met with ``[−ρ, ρ]`` where ``ρ`` bounds ``|p2 − p1|`` (a rotation keeps
the length). The truth is inside when ``dx ∈ [Δx]``, ``dy ∈ [Δy]`` and ``dyaw + 2πn ∈ [Δθ]``
for some integer ``n``. For a sound run every checked relation is inside.

**Relative enclosures.** A result of a keyframes run also holds relative pose enclosures
(``Result.relative``: pose row b in the robot frame of pose row a, see
:class:`~ivslam_cli.results.model.RelativePoses`), which do not carry the drift of the global
boxes. For a relation on rows (a, b) the check then uses the intersection of what the two
global boxes allow with what the relative enclosures give, both sound:

- *relative*: an enclosure of (a, b) itself (several: all of them met);
- *inverted*: an enclosure of (b, a), inverted: ``(−R(−θ) t, −θ)`` for every ``(t, θ)`` in it,
  computed as the relative pose of the origin in its frame (same heading slices);
- *chained*: the shortest path a → k₁ → … → b of at most ``max_hops`` relative enclosures
  (each used as given or inverted), composed: ``p ⊕ r = (t_p + R(θ_p) t_r, θ_p + θ_r)``, with
  outward rounding and ``[θ_p]`` sliced as above; ``|R(θ_p) t_r| = |t_r|`` bounds the rotated part.

The heading intervals are met as angles (modulo 2π, in the narrower branch). Each checked
relation records its source (``global`` when no relative enclosure reaches it) and the number
of relative enclosures composed (``hops``, 0 for global). The report counts the relations per
source and gives, per source, the widths of the enclosures checked beside those of what the two
global boxes alone allow on the same relations (JSON: ``used_relative``, ``by_source``,
``relative_enclosures``, ``max_hops``; ``source`` and ``hops`` per listed relation).

**How tight.** Widths of ``[Δx]``, ``[Δy]`` (m), ``[Δθ]`` (rad), median and max over the
checked relations, and the larger of the x/y widths as a multiple of the relation's length
``|(dx, dy)|``. Two independent boxes lose the correlation between the two poses, so these
widths are those of the boxes (roughly their sum), not of the odometry between the two stamps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ivslam_cli.errors import IvslamError, LogError
from ivslam_cli.interval.rounding import ensure_round_to_nearest
from ivslam_cli.interval.pose import (
    DEFAULT_SLICES,
    compose_enclosure,
    invert_enclosure,
    meet_enclosures,
    relative_enclosure,
)
from ivslam_cli.results.model import Poses, RelativePoses, box_is_empty
from ivslam_cli.report.strict_json import strict

DEFAULT_TOL = 1e-4  # s
DEFAULT_MAX_HOPS = 8  # relative enclosures composed at most along a chain
SOURCES = ("global", "relative", "inverted", "chained")  # codes 0..3 of RelationsCheck.source
FAILURES_LISTED = 20


# ---------------------------------------------------------------- the file
@dataclass
class Relations:
    """Relations of a file: ``t1``, ``t2`` stamps and the true relative pose ``(dx, dy, dyaw)``."""

    path: str
    t1: np.ndarray  # (R,)
    t2: np.ndarray
    rel: np.ndarray  # (R, 3) dx, dy, dyaw

    def __len__(self) -> int:
        return int(self.t1.shape[0])


def read_relations(path) -> Relations:
    """Read a relations file; any problem is a one-line :class:`IvslamError` naming it.

    Streamed (bounded by ``limits.TEXT_BYTES`` and ``RECORDS``) into a compact column."""
    from array import array

    from ivslam_cli import limits
    from ivslam_cli.inputs import check_input
    from ivslam_cli.logs.textfile import iter_lines

    path = check_input(path, "relations file")
    rows = array("d")
    try:
        for lineno, line in enumerate(iter_lines(path), 1):
            s = line.split("#", 1)[0].strip()
            if not s:
                continue
            tok = s.split()
            if len(tok) != 8:
                raise IvslamError(f"line {lineno}: {len(tok)} fields, a relation has 8 "
                                  "(t1 t2 dx dy dz droll dpitch dyaw)", path)
            try:
                vals = [float(t) for t in tok]
            except ValueError:
                raise IvslamError(f"line {lineno}: not a number in {s[:80]!r}", path) from None
            if not all(math.isfinite(v) for v in vals):
                raise IvslamError(f"line {lineno}: NaN or infinite value", path)
            limits.check("RECORDS", len(rows) // 8 + 1, "relations")
            rows.extend(vals)
    except (LogError, limits.LimitExceeded) as exc:  # the same message, said of a relations file
        if exc.path is not None:
            raise
        raise IvslamError(exc.message + " (relations file)", path) from None
    if not rows:
        raise IvslamError("no relations (empty file or only comments)", path)
    a = np.frombuffer(rows, np.float64).reshape(-1, 8)
    return Relations(path=str(path), t1=a[:, 0].copy(), t2=a[:, 1].copy(), rel=np.ascontiguousarray(a[:, [2, 3, 7]]))


def _relative_graph(rp: RelativePoses, slices: int) -> dict[int, dict[int, list[np.ndarray]]]:
    """``g[a][b]``: enclosures of pose row b in the frame of row a (given, and inverted)."""
    inv = invert_enclosure(rp.box, slices)
    g: dict[int, dict[int, list]] = {}
    for r, (a, b) in enumerate(np.asarray(rp.pairs, np.int64).tolist()):
        if a == b:
            continue
        g.setdefault(a, {}).setdefault(b, []).append((rp.box[r], 0))
        g.setdefault(b, {}).setdefault(a, []).append((inv[r], 1))
    return g


def _meet_list(encs: list[np.ndarray]) -> np.ndarray:
    out = np.array(encs[0], np.float64)
    for e in encs[1:]:
        out = meet_enclosures(out, e)[0]
    return out


def chain_enclosures(rp: RelativePoses, a: np.ndarray, b: np.ndarray, max_hops: int = DEFAULT_MAX_HOPS,
                     slices: int = DEFAULT_SLICES) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per pair of pose rows ``(a[i], b[i])``: the enclosure of row b in the frame of row a from
    the relative enclosures ``rp`` (see the module docstring), its source code (index into
    :data:`SOURCES`; 0 = none: the row is unbounded) and the number of enclosures composed.

    One hop: all enclosures of (a, b) and the inverted ones of (b, a), met. More: the first
    shortest path found (breadth first, at most ``max_hops``), the enclosures of each hop met,
    composed along it."""
    ensure_round_to_nearest()
    n = int(np.asarray(a).shape[0])
    enc = np.empty((n, 3, 2))
    enc[..., 0], enc[..., 1] = -np.inf, np.inf
    src = np.zeros(n, np.int8)
    hops = np.zeros(n, np.int64)
    if len(rp) == 0 or n == 0:
        return enc, src, hops
    g = _relative_graph(rp, slices)
    for i, (s, t) in enumerate(zip(np.asarray(a).tolist(), np.asarray(b).tolist())):
        if s not in g or s == t:
            continue
        if t in g[s]:  # one hop: given (a, b) and inverted (b, a) met
            enc[i] = _meet_list([e for e, _ in g[s][t]])
            kinds = {k for _, k in g[s][t]}
            src[i], hops[i] = (1 if 0 in kinds else 2), 1
            continue
        parent = {s: s}
        frontier = [s]
        for _ in range(max_hops):
            nxt = []
            for u in frontier:
                for v in g.get(u, ()):
                    if v not in parent:
                        parent[v] = u
                        nxt.append(v)
            if t in parent or not nxt:
                break
            frontier = nxt
        if t not in parent:
            continue
        path = [t]
        while path[-1] != s:
            path.append(parent[path[-1]])
        path.reverse()
        cur = _meet_list([e for e, _ in g[path[0]][path[1]]])
        for u, v in zip(path[1:-1], path[2:]):
            cur = compose_enclosure(cur, _meet_list([e for e, _ in g[u][v]]), slices)[0]
        enc[i], src[i], hops[i] = cur, 3, len(path) - 1
    return enc, src, hops


# ---------------------------------------------------------------- matching and the check
def match_stamps(stamps: np.ndarray, t: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Index of the one pose stamp within ``tol`` of each ``t`` (−1 if none) and a mask of the
    ``t`` with more than one pose stamp that close (ambiguous, index −1)."""
    s = np.asarray(stamps, np.float64)
    t = np.asarray(t, np.float64)
    if s.size == 0:
        return np.full(t.shape, -1, np.int64), np.zeros(t.shape, bool)
    lo = np.searchsorted(s, t - tol, side="left")
    hi = np.searchsorted(s, t + tol, side="right")
    n = hi - lo
    idx = np.where(n == 1, lo, -1).astype(np.int64)
    return idx, n > 1


@dataclass
class RelationsCheck:
    path: str
    tol: float
    slices: int
    total: int
    both: int  # both ends fall on pose enclosures (distinct)
    one_end: int  # exactly one end does
    ambiguous: int  # an end has several pose stamps within tol
    same_pose: int  # both ends fall on the same pose enclosure (not checked)
    index: np.ndarray  # (M,) rows of the file (0-based) that were checked
    k1: np.ndarray  # (M,) pose enclosure indices
    k2: np.ndarray
    truth: np.ndarray  # (M, 3)
    enclosure: np.ndarray  # (M, 3, 2)
    inside: np.ndarray  # (M,) bool
    failures: list[str] = field(default_factory=list)
    #: (M,) index into SOURCES: 0 = the two global boxes only, else met with relative enclosures
    source: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int8))
    hops: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # (M,) relative enclosures composed
    global_enclosure: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 2)))  # (M, 3, 2) from the boxes
    max_hops: int = DEFAULT_MAX_HOPS
    relative_available: int = 0  # relative enclosures in the result

    @property
    def checked(self) -> int:
        return int(self.index.shape[0])

    @property
    def contained(self) -> int:
        return int(np.count_nonzero(self.inside))

    @property
    def sound(self) -> bool:
        return self.contained == self.checked

    def widths(self, enclosure: np.ndarray | None = None) -> np.ndarray:
        """(M, 3) widths of [Δx], [Δy], [Δθ] of the enclosures checked (or of ``enclosure``),
        NaN for empty ones."""
        e = self.enclosure if enclosure is None else enclosure
        w = e[..., 1] - e[..., 0]
        return np.where(box_is_empty(e)[:, None], np.nan, w)

    def length(self) -> np.ndarray:
        return np.hypot(self.truth[:, 0], self.truth[:, 1])


def check_relations(poses: Poses, rel: Relations, tol: float = DEFAULT_TOL,
                    slices: int = DEFAULT_SLICES, relative: RelativePoses | None = None,
                    max_hops: int = DEFAULT_MAX_HOPS) -> RelationsCheck:
    """Match the relations to the pose enclosures and check the truth against what they allow
    (the two global boxes, met with the ``relative`` enclosures that reach the relation)."""
    from ivslam_cli.report.core import angle_in

    if not (tol >= 0 and math.isfinite(tol)):
        raise IvslamError(f"--stamp-tol must be a finite number >= 0, got {tol}")
    s = np.asarray(poses.stamp, np.float64)
    order = np.argsort(s, kind="stable")
    i1, amb1 = match_stamps(s[order], rel.t1, tol)
    i2, amb2 = match_stamps(s[order], rel.t2, tol)
    k1 = np.where(i1 >= 0, order[np.maximum(i1, 0)], -1)
    k2 = np.where(i2 >= 0, order[np.maximum(i2, 0)], -1)
    on1, on2 = k1 >= 0, k2 >= 0
    same = on1 & on2 & (k1 == k2)
    both = on1 & on2 & ~same
    idx = np.flatnonzero(both)
    a, b = k1[idx], k2[idx]
    enc_g = relative_enclosure(poses.box[a], poses.box[b], slices)
    enc, src, hops = enc_g, np.zeros(idx.size, np.int8), np.zeros(idx.size, np.int64)
    if relative is not None and len(relative):
        enc_r, src, hops = chain_enclosures(relative, a, b, max_hops, slices)
        enc = enc_g.copy()
        on = np.flatnonzero(src > 0)
        enc[on] = meet_enclosures(enc_g[on], enc_r[on])
    truth = rel.rel[idx]
    with np.errstate(invalid="ignore"):
        ok_xy = np.all((enc[:, :2, 0] <= truth[:, :2]) & (truth[:, :2] <= enc[:, :2, 1]), axis=1)
    ok = ok_xy & angle_in(enc[:, 2, 0], enc[:, 2, 1], truth[:, 2]) if idx.size else np.zeros(0, bool)
    fails = [f"relation {int(i) + 1} (t1={rel.t1[i]:.6f}, t2={rel.t2[i]:.6f}; poses {int(p)}, {int(q)}): "
             f"true ({truth[j, 0]:.4g}, {truth[j, 1]:.4g}, {truth[j, 2]:.4g}) not in "
             f"[{enc[j, 0, 0]:.4g}, {enc[j, 0, 1]:.4g}] x [{enc[j, 1, 0]:.4g}, {enc[j, 1, 1]:.4g}] x "
             f"[{enc[j, 2, 0]:.4g}, {enc[j, 2, 1]:.4g}] ({SOURCES[src[j]]})"
             for j, (i, p, q) in enumerate(zip(idx, a, b)) if not ok[j]]
    return RelationsCheck(
        path=rel.path, tol=float(tol), slices=int(slices), total=len(rel), both=int(both.sum()),
        one_end=int(np.count_nonzero(on1 ^ on2)), ambiguous=int(np.count_nonzero(amb1 | amb2)),
        same_pose=int(same.sum()), index=idx.astype(np.int64), k1=a.astype(np.int64), k2=b.astype(np.int64),
        truth=truth, enclosure=enc, inside=np.asarray(ok, bool), failures=fails, source=src, hops=hops,
        global_enclosure=enc_g, max_hops=int(max_hops), relative_available=0 if relative is None else len(relative))


# ---------------------------------------------------------------- rendering
def _stat(x: np.ndarray) -> dict[str, float | None]:
    x = np.asarray(x, float)
    x = x[~np.isnan(x)]
    if x.size == 0:
        return {"median": None, "max": None}
    return {"median": float(np.median(x)), "max": float(np.max(x))}


def _ratio(rc: RelationsCheck) -> np.ndarray:
    w = rc.widths()
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.max(w[:, :2], axis=1) / rc.length() if w.size else np.zeros(0)


def relations_dict(rc: RelationsCheck) -> dict[str, Any]:
    """The check as strict-JSON-ready data (the ``relations`` key of ``report --json``)."""
    return strict(_relations_dict(rc))


def _width3(w: np.ndarray) -> dict[str, Any]:
    return {"x": _stat(w[:, 0]), "y": _stat(w[:, 1]), "theta": _stat(w[:, 2])}


def _by_source(rc: RelationsCheck) -> dict[str, Any]:
    """Counts per source and, per source, median/max widths of the enclosures checked and of
    what the two global boxes alone allow on the same relations."""
    src, w, wg = rc.source, rc.widths(), rc.widths(rc.global_enclosure)
    out: dict[str, Any] = {}
    for code, name in enumerate(SOURCES):
        on = src == code
        if on.any() or code <= 1:
            out[name] = {"count": int(on.sum()), "width": _width3(w[on]), "global_boxes_width": _width3(wg[on])}
    return out


def _relations_dict(rc: RelationsCheck) -> dict[str, Any]:
    w = rc.widths()
    src, hops = rc.source, rc.hops
    return {
        "file": rc.path,
        "stamp_tol_s": rc.tol,
        "heading_slices": rc.slices,
        "relations": rc.total,
        "matched": rc.checked,
        "one_end_matched": rc.one_end,
        "ambiguous": rc.ambiguous,
        "same_pose": rc.same_pose,
        "inside": rc.contained,
        "soundness": "ok" if rc.sound else "SOUNDNESS FAILURE",
        "sound": rc.sound,
        "width": _width3(w),
        "relative_enclosures": rc.relative_available,
        "max_hops": rc.max_hops,
        "used_relative": int(np.count_nonzero(src > 0)),
        "by_source": _by_source(rc),
        "width_over_length": _stat(_ratio(rc)),
        "length": _stat(rc.length()),
        "failures": rc.failures,
        "list": [
            {"line_index": int(i), "pose1": int(p), "pose2": int(q), "truth": [float(v) for v in t],
             "enclosure": [[float(e[d, 0]), float(e[d, 1])] for d in range(3)], "inside": bool(o),
             "source": SOURCES[int(c)], "hops": int(h)}
            for i, p, q, t, e, o, c, h in zip(rc.index, rc.k1, rc.k2, rc.truth, rc.enclosure, rc.inside, src, hops)
        ],
    }


def _g(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.4g}"


def _w3(w: dict[str, Any]) -> str:
    return (f"x median {_g(w['x']['median'])}, max {_g(w['x']['max'])} m; "
            f"y median {_g(w['y']['median'])}, max {_g(w['y']['max'])} m; "
            f"θ median {_g(w['theta']['median'])}, max {_g(w['theta']['max'])} rad")


def render_relations_text(rc: RelationsCheck) -> str:
    d = _relations_dict(rc)
    w = d["width"]
    out = [
        f"relations:  {rc.path}: {rc.total} relation(s); {rc.checked} with both ends on pose enclosures "
        f"(stamps within {rc.tol:g} s), {rc.one_end} with one end, {rc.ambiguous} ambiguous, "
        f"{rc.same_pose} with both ends on one pose",
    ]
    if rc.checked:
        what = "the two pose boxes allow" if not d["used_relative"] else \
            "the two pose boxes allow, met with the result's relative enclosures where they reach"
        out.append(f"  inside:   {rc.contained}/{rc.checked} true relative poses within what {what} — "
                   f"{d['soundness']}")
        out.append(f"  widths:   {_w3(w)}")
        if rc.relative_available:
            bs = d["by_source"]
            n = {k: v["count"] for k, v in bs.items()}
            out.append(f"  sources:  {n.get('global', 0)} from the two global boxes only, {d['used_relative']} met with "
                       f"relative enclosures ({n.get('relative', 0)} direct, {n.get('inverted', 0)} inverted, "
                       f"{n.get('chained', 0)} chained through keyframes, at most {rc.max_hops} hops; "
                       f"{rc.relative_available} in the result)")
            for name, v in bs.items():
                if v["count"]:
                    out.append(f"    {name + ':':<9} {_w3(v['width'])}"
                               + (f"\n{'':14}(two global boxes alone: {_w3(v['global_boxes_width'])})"
                                  if name != "global" else ""))
        r, ln = d["width_over_length"], d["length"]
        out.append(f"  per length: larger x/y width / relation length: median {_g(r['median'])}, max {_g(r['max'])} "
                   f"(lengths median {_g(ln['median'])}, max {_g(ln['max'])} m)")
        for f in rc.failures[:FAILURES_LISTED]:
            out.append(f"  outside:  {f}")
        if len(rc.failures) > FAILURES_LISTED:
            out.append(f"  outside:  … and {len(rc.failures) - FAILURES_LISTED} more (see --json)")
    else:
        out.append("  no relation has both ends on pose enclosures of this result: nothing checked")
    return "\n".join(out) + "\n"
