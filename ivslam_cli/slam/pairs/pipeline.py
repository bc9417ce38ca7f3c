"""The pairs pipeline (Mustafa, Codres & Stancu): landmark displacement subpavings, intersected over time.

For every pair (i, j) of landmarks observed at the same step, the displacement
``dl = m_i − m_j`` lies in the displacement set ``S_dl(i,j),t`` built from the two range-bearing
observations and the heading interval (Eq. 1–4); the sets of a pair are intersected over time
(Eq. 5) with tolerance q (q-relaxed intersection). Landmarks follow from an anchor (Eq. 6) by
contracting the whole network ``m_i − m_j ∈ S_dl(i,j)`` to a fixpoint, or, without an anchor,
relative to a reference landmark.

Assumption under which the output is guaranteed (stated in every result): each range and
bearing error is within its bound and the true heading is in the heading interval, for all but
at most q observation pairs per landmark pair; observation pairs rejected as empty events are
proven to break that assumption and are left out.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ivslam_cli import interval as iv
from ivslam_cli.errors import IvslamError
from ivslam_cli.logs.model import LogData, Observations
from ivslam_cli.results.model import (
    LABEL_BOUNDARY,
    LABEL_INNER,
    Consistency,
    EmptyEvents,
    Landmarks,
    PairSubpavings,
    Rejections,
    Result,
    WidthHistory,
)
from ivslam_cli.slam.pairs import kernel as K
from ivslam_cli.slam.pairs.params import Params
from ivslam_cli.slam.pipeline import make_result

MAX_NETWORK_SWEEPS = 200
NETWORK_STOP = 1e-4
CHECKPOINTS = 20  # landmark widths are recorded at this many stamps over the log


@dataclass
class PairsOutput:
    """What the pairs pipeline adds to a result."""

    pairs: PairSubpavings
    landmarks: Landmarks
    consistency: Consistency
    stats: dict


def heading_interval(params: Params, log: LogData) -> tuple[float, float]:
    """The heading interval: ``pairs.heading`` if set, else ±``heading`` the log states, else 0."""
    lo, hi = params.heading
    if not params.heading_given and "heading" in log.bounds:
        h = float(log.bounds["heading"])
        lo, hi = -h, h
    return float(lo), float(hi)


def observation_intervals(log: LogData, params: Params) -> tuple[np.ndarray, np.ndarray]:
    """``rho`` and world-frame ``beta`` intervals (N, 2) of every observation, rounded outward.

    ``rho ∈ z ± (range_abs + range_rel z)`` (and ``rho >= 0``), ``beta ∈ z_alpha ± bearing + heading``.
    Every bound is first enclosed (a decimal such as 0.05 is not a double).
    """
    obs = log.observations
    n = len(obs)
    z = np.column_stack([obs.range, obs.range]).astype(np.float64)
    a = np.column_stack([obs.bearing, obs.bearing]).astype(np.float64)

    def const(value: float) -> np.ndarray:
        lo, hi = iv.enclose(value)
        return np.tile([-hi, hi], (n, 1)) if value >= 0 else np.tile([lo, hi], (n, 1))

    rel_lo, rel_hi = iv.enclose(params.range_rel)
    rel = iv.mul(z, np.tile([rel_lo, rel_hi], (n, 1)))
    half = iv.add(rel, np.tile(list(iv.enclose(params.range_abs)), (n, 1)))
    half_sym = np.column_stack([-half[:, 1], half[:, 1]])
    rho = iv.add(z, half_sym)
    rho[:, 0] = np.maximum(rho[:, 0], 0.0)
    beta = iv.add(iv.add(a, const(params.bearing)), heading_intervals(log, params))
    return rho, beta


def heading_intervals(log: LogData, params: Params) -> np.ndarray:
    """The heading interval at every observation, (N, 2), rounded outward.

    ``heading_source = option``: the constant ``pairs.heading`` (or the log's stated bound).
    ``heading_source = odometry``: the hull of the odometry headings at the two odometry stamps
    around the observation (unwrapped), plus ``pairs.heading`` as the bound on the odometry's
    heading error. Assumes the heading between two odometry samples stays between their values;
    an observation outside the odometry's time span gets the whole circle (it proves nothing
    about the heading, the pipeline stays sound).
    """
    obs = log.observations
    n = len(obs)
    h_lo, h_hi = heading_interval(params, log)
    offset = np.tile([iv.enclose(h_lo)[0], iv.enclose(h_hi)[1]], (n, 1))
    if params.heading_source == "option":
        return offset
    odo = log.odometry
    if odo is None or odo.pose is None or len(odo) == 0:
        raise IvslamError("pairs.heading_source = odometry, but the log has no odometry poses", log.provenance.path)
    t = odo.stamp
    th = odo.pose[:, 2]
    s = obs.stamp
    k = np.clip(np.searchsorted(t, s, side="left"), 0, t.shape[0] - 1)
    prev = np.clip(k - 1, 0, t.shape[0] - 1)
    a = th[k]  # exact data
    b = np.where(t[k] == s, th[k], th[prev])
    # the other sample's heading moved next to a: d = wrap(b - a), computed in floats. Its error:
    # the subtraction (an ulp of |a| + |b|) and the float 2 pi below the real one (|turns| * 2.5e-16)
    raw = b - a
    turns = np.round(raw / (2.0 * np.pi))
    d = raw - turns * (2.0 * np.pi)
    margin = 4.0 * np.spacing(np.abs(a) + np.abs(b) + np.pi) + np.abs(turns) * 1e-15
    head = np.column_stack([np.nextafter(a + np.minimum(d, 0.0) - margin, -np.inf),
                            np.nextafter(a + np.maximum(d, 0.0) + margin, np.inf)])
    head = iv.add(head, offset)
    outside = (s < t[0]) | (s > t[-1])
    head[outside] = [-np.pi - 1.0, np.pi + 1.0]
    return head


def _step_offsets(stamp: np.ndarray) -> np.ndarray:
    """Offsets of runs of equal stamps (observations are time-sorted by the readers)."""
    change = np.flatnonzero(np.diff(stamp) != 0.0) + 1
    return np.concatenate([[0], change, [stamp.shape[0]]]).astype(np.int64)


def network_map(ids: np.ndarray, pair_i, pair_j, offsets, boxes, anchor_id, anchor_xy, reference_id):
    """Landmark boxes from the pair subpavings by contracting ``m_i − m_j ∈ S_ij`` to a fixpoint.

    With an anchor (id, position) the boxes are absolute; otherwise relative to ``reference_id``
    (its box is the point 0). Returns ``(box (L, 4), reference or None, sweeps, consistent)``.
    """
    index = {int(v): k for k, v in enumerate(ids)}
    m = np.tile([-np.inf, np.inf, -np.inf, np.inf], (len(ids), 1)).astype(np.float64)
    if anchor_id is not None:
        if int(anchor_id) not in index:
            raise IvslamError(f"anchor landmark {anchor_id} is never observed together with another")
        x_lo, x_hi = iv.enclose(anchor_xy[0])
        y_lo, y_hi = iv.enclose(anchor_xy[1])
        m[index[int(anchor_id)]] = [x_lo, x_hi, y_lo, y_hi]
        reference = None
    else:
        reference = int(ids.min()) if reference_id is None else int(reference_id)
        if reference not in index:
            raise IvslamError(f"reference landmark {reference} is never observed together with another")
        m[index[reference]] = [0.0, 0.0, 0.0, 0.0]
    pi = np.array([index[int(v)] for v in pair_i], dtype=np.int64)
    pj = np.array([index[int(v)] for v in pair_j], dtype=np.int64)
    sweeps = 0
    consistent = True
    for sweeps in range(1, MAX_NETWORK_SWEEPS + 1):
        progress = K.network_pass(m, pi, pj, offsets, boxes)
        if progress < 0.0:
            consistent = False
            break
        if progress < NETWORK_STOP:
            break
    return m, reference, sweeps, consistent


def _landmark_width_history(ids, pair_i, pair_j, snap_boxes, snap_offsets, checkpoints, cp_index, n_pairs,
                            params: Params, final_m, reference) -> WidthHistory:
    """Width of every landmark box at each checkpoint (the network rebuilt from the pair sets then).

    The last checkpoint is the end of the log; its widths are those of the final map. A landmark
    not yet tied to the anchor/reference by any bounded pair set has infinite width.
    """
    ent, stp, stm, wid = [], [], [], []
    for c in range(checkpoints.shape[0]):
        offs = snap_offsets[c * n_pairs : (c + 1) * n_pairs + 1] - snap_offsets[c * n_pairs]
        seg = snap_boxes[snap_offsets[c * n_pairs] : snap_offsets[(c + 1) * n_pairs]]
        try:
            m, _, _, _ = network_map(ids, pair_i, pair_j, np.ascontiguousarray(offs), np.ascontiguousarray(seg),
                                     params.anchor_id, params.anchor_xy,
                                     reference if params.anchor_id is None else None)
        except IvslamError:  # anchor/reference not yet observed at this time
            m = np.tile([-np.inf, np.inf, -np.inf, np.inf], (len(ids), 1))
        w = np.maximum(m[:, 1] - m[:, 0], m[:, 3] - m[:, 2])
        ent.append(np.column_stack([ids, np.full(len(ids), -1)]))
        stp.append(np.full(len(ids), cp_index[c]))
        stm.append(np.full(len(ids), checkpoints[c]))
        wid.append(w)
    return WidthHistory(
        entity=np.concatenate(ent).astype(np.int64).reshape(-1, 2),
        step=np.concatenate(stp).astype(np.int64),
        stamp=np.concatenate(stm).astype(np.float64),
        width=np.concatenate(wid).astype(np.float64),
        definition="largest side of the landmark box (network of the pair sets at that time), metres; "
                   "inf: not yet tied to the anchor/reference",
    )


#: grid cells per side of a pair's domain the subpaving indexes exactly (cell indices are floats)
MAX_CELLS_PER_SIDE = 2.0 ** 40


def _check_grid(rows: np.ndarray, eps: float, log: LogData) -> None:
    """Refuse an ``eps`` too fine for the displacement sets' extent (cell indices would lose
    integers, bisection could not reach a cell): one line naming the key."""
    extent = 0.0
    if rows.shape[0]:
        rho_hi = max(float(np.max(rows[:, 1])), float(np.max(rows[:, 5])))
        extent = 4.0 * rho_hi  # |m_i - m_j| <= rho_i + rho_j, on either side of 0
    if not np.isfinite(extent) or extent / eps > MAX_CELLS_PER_SIDE:
        raise IvslamError(f"pairs.eps = {eps:g} m is too fine for displacement sets {extent:.4g} m across "
                          f"(more than 2^40 cells a side); coarsen pairs.eps or narrow the bounds",
                          log.provenance.path)


def solve(log: LogData, params: Params, progress=None) -> PairsOutput:
    """The pairs pipeline over a log's landmark observations (see the module docstring)."""
    obs = log.observations
    if obs is None or len(obs) == 0:
        raise IvslamError("no landmark observations: --mode pairs needs range-bearing observations", log.provenance.path)
    t0 = time.perf_counter()
    q = params.q
    eps = params.eps
    rho, beta = observation_intervals(log, params)
    steps = _step_offsets(obs.stamp)
    pi, pj, pa, pb, rows = K.pair_rows(steps, obs.landmark_id.astype(np.int64), rho, beta)
    if rows.shape[0] == 0:
        raise IvslamError("no step observes two landmarks: no pair to build", log.provenance.path)
    order = np.lexsort((obs.stamp[pa], pj, pi))
    pi, pj, pa, pb, rows = pi[order], pj[order], pa[order], pb[order], np.ascontiguousarray(rows[order])
    key_change = np.flatnonzero((np.diff(pi) != 0) | (np.diff(pj) != 0)) + 1
    pair_offsets = np.concatenate([[0], key_change, [pi.shape[0]]]).astype(np.int64)
    n_pairs = pair_offsets.shape[0] - 1
    if n_pairs > params.max_pairs:
        raise IvslamError(f"{n_pairs} landmark pairs exceed pairs.max_pairs = {params.max_pairs}")
    row_stamp = np.ascontiguousarray(obs.stamp[pa], dtype=np.float64)
    step_stamps = obs.stamp[steps[:-1]]
    cp_index = np.unique(np.linspace(0, step_stamps.shape[0] - 1, CHECKPOINTS).round().astype(np.int64))
    checkpoints = np.ascontiguousarray(step_stamps[cp_index], dtype=np.float64)
    _check_grid(rows, eps, log)
    (boxes, inner, box_offsets, width, rejected, truncated, snap_boxes, snap_offsets, work,
     over) = K.process_pairs(rows, row_stamp, pair_offsets, q, eps, params.max_boxes, checkpoints, params.max_work)
    if over >= 0:
        raise IvslamError(
            f"the subpavings need more than pairs.max_work = {params.max_work:,} box tests (stopped at landmark "
            f"pair ({int(pi[pair_offsets[over]])}, {int(pj[pair_offsets[over]])}) of {n_pairs}): the bounds are wide "
            f"for eps = {eps:g} m; coarsen pairs.eps, narrow the bounds, or raise pairs.max_work",
            log.provenance.path)
    if progress:
        progress(1.0)
    first_i = pi[pair_offsets[:-1]]
    first_j = pj[pair_offsets[:-1]]
    ids = np.unique(np.concatenate([first_i, first_j]))
    m, reference, sweeps, consistent = network_map(
        ids, first_i, first_j, box_offsets, boxes, params.anchor_id, params.anchor_xy, params.reference_id
    )
    step_of_obs = np.repeat(np.arange(steps.shape[0] - 1), np.diff(steps))
    landmark_widths = _landmark_width_history(
        ids, first_i, first_j, snap_boxes, snap_offsets, checkpoints, cp_index, n_pairs, params, m, reference
    )

    # consistency record
    ev = np.flatnonzero(rejected)
    ev = ev[np.argsort(obs.stamp[pa[ev]], kind="stable")]
    events = EmptyEvents(
        stamp=obs.stamp[pa[ev]].astype(np.float64),
        step=step_of_obs[pa[ev]].astype(np.int64),
        constraint=np.array(["pair_intersection"] * ev.shape[0], dtype=str).reshape(-1),
        entity=np.column_stack([pi[ev], pj[ev]]).astype(np.int64).reshape(-1, 2),
        measurement=pa[ev].astype(np.int64),
        text=np.array(
            [f"observations {a} and {b} (landmarks {i}, {j}) contradict earlier ones beyond q={q}"
             for a, b, i, j in zip(pa[ev], pb[ev], pi[ev], pj[ev])], dtype=str).reshape(-1),
    )
    rejected_obs = np.unique(np.concatenate([pa[ev], pb[ev]]))
    rejections = Rejections(
        stream=np.array(["observations"] * rejected_obs.shape[0], dtype=str).reshape(-1),
        index=rejected_obs.astype(np.int64),
        reason=np.array(["in a pair observation rejected as an empty event"] * rejected_obs.shape[0], dtype=str).reshape(-1),
    )
    widths = WidthHistory(
        entity=np.column_stack([pi, pj]).astype(np.int64).reshape(-1, 2),
        step=step_of_obs[pa].astype(np.int64),
        stamp=obs.stamp[pa].astype(np.float64),
        width=width,
        definition="largest side of the bounding box of the pair's outer subpaving after the update, metres",
    )
    h_lo, h_hi = heading_interval(params, log)
    heading = (f"the true heading in [{h_lo}, {h_hi}] rad" if params.heading_source == "option" else
               f"the true heading within [{h_lo}, {h_hi}] rad of the odometry heading, and between two odometry "
               f"samples between their headings")
    assumption = (
        f"every range error within ±(range_abs + range_rel·range), bearing error within ±bearing, and {heading}, "
        f"for all but at most q={q} observation pairs per landmark pair"
    )
    if ev.shape[0]:
        assumption += f"; {ev.shape[0]} observation pair(s) proven to break it were left out (empty events)"
    if not consistent:
        assumption += "; the landmark network is inconsistent (some landmark box became empty)"
    consistency = Consistency(
        empty_events=events, q={"pair": q}, rejected=rejections,
        widths={"pair": widths, "landmark": landmark_widths}, assumption=assumption,
    )
    label = np.where(inner, LABEL_INNER, LABEL_BOUNDARY).astype(np.uint8)
    pairs = PairSubpavings(
        i=first_i.astype(np.int64), j=first_j.astype(np.int64), offsets=box_offsets.astype(np.int64),
        boxes=boxes.reshape(-1, 2, 2).copy(), label=label,
    )
    landmarks = Landmarks(id=ids.astype(np.int64), box=m.reshape(-1, 2, 2).copy(), reference_id=reference)
    stats = {
        "intersections": int(rows.shape[0]),
        "pairs": int(n_pairs),
        "steps": int(steps.shape[0] - 1),
        "boxes": int(boxes.shape[0]),
        "pairs_truncated": int(truncated.sum()),
        "network_sweeps": int(sweeps),
        "pair_observations_per_s": float(rows.shape[0] / max(time.perf_counter() - t0, 1e-9)),
        "box_tests": int(work),
        "eps": eps,
    }
    return PairsOutput(pairs=pairs, landmarks=landmarks, consistency=consistency, stats=stats)


def observations_until(log: LogData, stamp: float) -> LogData:
    """The log with its observations cut after ``stamp`` (indices of the kept ones unchanged)."""
    obs = log.observations
    keep = obs.stamp <= stamp
    cut = Observations(stamp=obs.stamp[keep], landmark_id=obs.landmark_id[keep], range=obs.range[keep],
                       bearing=obs.bearing[keep])
    return replace(log, observations=cut)


def run(log: LogData, params: Params, progress=None) -> Result:
    """The pairs pipeline over ``log`` as a :class:`Result`. With ``params.strict`` the run stops
    at the first empty intersection: the result covers the data up to it."""
    out = solve(log, params, progress)
    events = out.consistency.empty_events
    if params.strict and len(events):
        out = solve(observations_until(log, float(events.stamp[0])), params)
    return make_result("pairs", log, pairs=out.pairs, landmarks=out.landmarks, consistency=out.consistency,
                       stats=out.stats)


def summary(result: Result) -> str:
    """The CLI line: intersections, pairs, landmarks, empty events."""
    s = result.stats
    n_lm = len(result.landmarks) if result.landmarks is not None else 0
    return (f"pairs: {s.get('intersections', 0)} intersections, {s.get('pairs', 0)} pairs, {n_lm} landmarks, "
            f"{len(result.consistency.empty_events)} empty event(s)")
