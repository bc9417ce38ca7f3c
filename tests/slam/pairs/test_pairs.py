"""The pairs pipeline (seed 000) on simulated logs: sound, consistent, converging, robust.

Truth checks are independent of the pipeline's own report code: the true displacement
m_i − m_j must lie in some box of the pair's subpaving, and the true landmark (relative to
the reference, or absolute with an anchor) in its box.
"""

from __future__ import annotations

import numpy as np
import pytest

from ivslam_cli.config import resolve_config
from ivslam_cli.logs.writers import write_log
from ivslam_cli.simulate import simulate
from ivslam_cli.simulate.config import SimConfig
from ivslam_cli.slam import run_pipeline
from tests.helpers.hyp import lanes


def small_log(seed: int, **kw):
    args = dict(scenario="pairs", seed=seed, steps=30, landmarks=6, world_size=8.0, max_range=6.0)
    args.update(kw)
    return simulate(SimConfig(**args))


def run(log, **overrides):
    cfg = resolve_config(overrides={k.replace("__", "."): v for k, v in overrides.items()}, log_bounds=log.bounds)
    return run_pipeline(log, cfg, "pairs")


def truth_of(log):
    return {int(i): xy for i, xy in zip(log.truth.landmark_id, log.truth.landmark_xy)}


def pair_contains(result, truth) -> np.ndarray:
    p = result.pairs
    ok = np.zeros(len(p), dtype=bool)
    for k in range(len(p)):
        b = p.pair_boxes(k)
        dl = truth[int(p.i[k])] - truth[int(p.j[k])]
        ok[k] = np.any((b[:, 0, 0] <= dl[0]) & (dl[0] <= b[:, 0, 1]) & (b[:, 1, 0] <= dl[1]) & (dl[1] <= b[:, 1, 1]))
    return ok


def landmark_contains(result, truth) -> np.ndarray:
    lm = result.landmarks
    ref = np.zeros(2) if lm.reference_id is None else truth[int(lm.reference_id)]
    t = np.array([truth[int(i)] - ref for i in lm.id])
    return np.all((lm.box[:, :, 0] <= t) & (t <= lm.box[:, :, 1]), axis=1)


def widths_never_grow(result) -> bool:
    w = result.consistency.widths["pair"]
    for e in np.unique(w.entity, axis=0):
        sel = np.all(w.entity == e, axis=1)
        seq = w.width[sel]  # rows are in time order within a pair
        if np.any(np.diff(seq) > 0.0):
            return False
    return True


@pytest.mark.parametrize("block", lanes(range(8), fast=[0, 5]))
def test_honest_bounds_contain_the_truth_over_200_logs(block):
    """25 logs per block, 200 in all, three noise distributions (edges = errors at the bound)."""
    noises = ("uniform", "edges", "triangular")
    for seed in range(25 * block, 25 * block + 25):
        log = small_log(seed, noise=noises[seed % 3])
        result = run(log)
        truth = truth_of(log)
        assert len(result.consistency.empty_events) == 0, f"seed {seed}: empty event with honest bounds"
        assert pair_contains(result, truth).all(), f"seed {seed}: a pair set lost the truth"
        assert landmark_contains(result, truth).all(), f"seed {seed}: a landmark box lost the truth"
        assert widths_never_grow(result), f"seed {seed}: an intersection widened a set"


def test_widths_converge_towards_the_bound_driven_limit():
    """After many observations the sets are a small multiple of what one observation allows.

    Limit: a single observation pins a landmark radially to 2 range_abs; the subpaving adds
    at most its resolution eps. A pair seen from many places converges to within 2x that,
    while one observation's set is several times wider.
    """
    log = simulate(SimConfig(scenario="pairs", seed=3, steps=200, landmarks=8, world_size=10.0, max_range=8.0))
    result = run(log)
    eps = 0.05
    limit = 2 * log.bounds["range_abs"] + eps
    w = result.consistency.widths["pair"]
    finals, initials = [], []
    for e in np.unique(w.entity, axis=0):
        seq = w.width[np.all(w.entity == e, axis=1)]
        if seq.shape[0] >= 50:
            finals.append(seq[-1])
            initials.append(seq[0])
    assert len(finals) >= 5
    assert np.median(initials) > 2 * limit  # one observation's set is wide ...
    assert np.median(finals) <= 2 * limit  # ... the intersection converges to the limit
    assert np.max(finals) <= 4 * limit


def test_finer_grid_gives_tighter_sets():
    log = small_log(11, steps=60)
    coarse = run(log, pairs__eps=0.1)
    fine = run(log, pairs__eps=0.02)
    assert pair_contains(fine, truth_of(log)).all()
    wc = coarse.consistency.widths["pair"].width
    wf = fine.consistency.widths["pair"].width
    assert np.median(wf) < np.median(wc)


@pytest.mark.parametrize("seed", range(6))
def test_outliers_detected_or_absorbed_and_q_restores_containment(seed):
    log = small_log(100 + seed, steps=40, outlier_rate=0.05, outlier_magnitude=20.0)
    bad_obs = log.truth.outliers["observations"]
    assert bad_obs.any()
    truth = truth_of(log)
    # q = 0: every pair touched by an outlier either reports an empty event or still holds the truth
    strict = run(log)
    contained = pair_contains(strict, truth)
    events = {tuple(e) for e in strict.consistency.empty_events.entity}
    obs = log.observations
    per_pair_bad: dict[tuple[int, int], int] = {}
    stamps = np.unique(obs.stamp)
    for t in stamps:
        idx = np.flatnonzero(obs.stamp == t)
        for u in idx:
            for v in idx:
                i, j = int(obs.landmark_id[u]), int(obs.landmark_id[v])
                if i < j and (bad_obs[u] or bad_obs[v]):
                    per_pair_bad[(i, j)] = per_pair_bad.get((i, j), 0) + 1
    p = strict.pairs
    for k in range(len(p)):
        key = (int(p.i[k]), int(p.j[k]))
        if key in per_pair_bad:
            assert contained[k] or key in events, f"pair {key}: outlier neither detected nor absorbed"
    # q >= the most outliers any pair received: the truth is held everywhere
    q = max(per_pair_bad.values())
    relaxed = run(log, robust__q_pair=q)
    assert pair_contains(relaxed, truth).all()
    assert landmark_contains(relaxed, truth).all()
    assert relaxed.consistency.q == {"pair": q}
    assert f"q={q}" in relaxed.consistency.assumption


def test_a_too_tight_bound_is_proven_inconsistent():
    log = small_log(5, steps=40, noise="edges")
    result = run(log, bounds__range_abs=log.bounds["range_abs"] / 10, bounds__bearing=log.bounds["bearing"] / 10)
    ev = result.consistency.empty_events
    assert len(ev) > 0
    assert np.all(np.diff(ev.stamp) >= 0)
    assert set(ev.constraint) == {"pair_intersection"}
    assert len(result.consistency.rejected) > 0
    assert "left out" in result.consistency.assumption


def test_anchor_gives_an_absolute_map_holding_the_truth():
    log = small_log(8, steps=50)
    truth = truth_of(log)
    result = run(log)
    anchor = int(result.landmarks.id[0])
    xy = truth[anchor]
    absolute = run(log, pairs__anchor_id=anchor, pairs__anchor_xy=(float(xy[0]), float(xy[1])))
    assert absolute.landmarks.reference_id is None
    assert landmark_contains(absolute, truth).all()
    assert np.isfinite(absolute.landmarks.box).all()


def test_heading_interval_is_used_and_stays_sound():
    log = small_log(9, steps=40, bounds={"heading": 0.01})
    result = run(log)
    assert "[-0.01, 0.01]" in result.consistency.assumption
    assert pair_contains(result, truth_of(log)).all()


def test_cli_run_report_and_refusals(tmp_path, cli_run):
    log = small_log(21)
    path = write_log(tmp_path / "p.mcap", log, "mcap")
    out = tmp_path / "r.h5"
    res = cli_run("run", path, "--mode", "pairs", "-o", out)
    assert res.exit_code == 0, res.output
    assert out.exists()
    res = cli_run("run", path, "-o", out)
    assert res.exit_code != 0 and "--force" in res.output and "Traceback" not in res.output
    res = cli_run("report", out, "--json")
    assert res.exit_code == 0
    assert '"containment"' in res.output
    res = cli_run("run", path, "--mode", "pairs", "-o", tmp_path / "s.h5", "--strict", "--range-abs", "0.001")
    assert res.exit_code == 3 and "stopped (--strict)" in res.output
    assert (tmp_path / "s.h5").exists()  # written for diagnosis
    from ivslam_cli.results.hdf5 import read_result

    stopped = read_result(tmp_path / "s.h5")
    first = stopped.consistency.empty_events.stamp.min()
    assert stopped.consistency.stopped
    assert stopped.consistency.widths["pair"].stamp.max() <= first  # nothing after the first event
    assert np.all(stopped.consistency.empty_events.stamp == first)
    res = cli_run("run", tmp_path / "missing.mcap", "-o", tmp_path / "x.h5")
    assert res.exit_code != 0 and "Traceback" not in res.output


def test_mode_without_observations_is_a_clear_error(tmp_path, cli_run):
    log = simulate(SimConfig(scenario="lidar", seed=1, steps=5))
    path = write_log(tmp_path / "l.h5", log, "h5")
    res = cli_run("run", path, "--mode", "pairs", "-o", tmp_path / "x.h5")
    assert res.exit_code != 0
    assert "observations" in res.output and "Traceback" not in res.output


def test_landmark_widths_are_recorded_over_time_and_end_at_the_final_map():
    log = small_log(31, steps=60)
    result = run(log)
    w = result.consistency.widths["landmark"]
    assert len(w) > 0
    last = w.stamp == w.stamp.max()
    final = np.max(result.landmarks.box[:, :, 1] - result.landmarks.box[:, :, 0], axis=1)
    by_id = dict(zip(w.entity[last, 0].tolist(), w.width[last].tolist()))
    for lid, fw in zip(result.landmarks.id.tolist(), final.tolist()):
        assert by_id[lid] == pytest.approx(fw, rel=1e-9, abs=1e-12)
    for lid in np.unique(w.entity[:, 0]):
        seq = w.width[w.entity[:, 0] == lid]
        finite = seq[np.isfinite(seq)]
        assert np.all(np.diff(finite) <= 0.01 * finite[:-1] + 1e-12), f"landmark {lid} box grew over time"
        assert np.isfinite(seq[-1])


def test_heading_per_step_from_odometry():
    """A rotating robot: the heading comes from the log's odometry poses, per step."""
    from ivslam_cli.logs.model import Odometry

    log = simulate(SimConfig(scenario="landmarks", seed=4, steps=80, landmarks=12, world_size=10.0,
                             fov=3.1, max_range=8.0))
    t = log.truth
    # odometry heading = true heading + a known error within ±0.01 rad, sampled at the truth's stamps
    err = 0.009 * np.sin(np.arange(t.pose.shape[0]))
    log.odometry = Odometry(stamp=t.pose_stamp.copy(), pose=np.column_stack([t.pose[:, :2], t.pose[:, 2] + err]))
    result = run(log, pairs__heading_source="odometry", pairs__heading=(-0.01, 0.01))
    truth = truth_of(log)
    assert "odometry heading" in result.consistency.assumption
    assert len(result.consistency.empty_events) == 0
    assert pair_contains(result, truth).all()
    assert landmark_contains(result, truth).all()
    # assuming heading 0 instead is proven wrong: the robot turns
    wrong = run(log, pairs__heading=(0.0, 0.0))
    assert len(wrong.consistency.empty_events) > 0 or not pair_contains(wrong, truth).all()


def test_heading_source_errors(tmp_path, cli_run):
    log = small_log(2)
    with pytest.raises(Exception, match="no odometry poses"):
        run(log, pairs__heading_source="odometry")
    with pytest.raises(Exception, match="heading_source"):
        run(log, pairs__heading_source="compass")


def test_heading_from_odometry_many_turns_away():
    """Odometry headings far from [-pi, pi] (thousands of turns, stored unwrapped or wrapped)."""
    from ivslam_cli.logs.model import Odometry

    log = simulate(SimConfig(scenario="landmarks", seed=6, steps=60, landmarks=10, world_size=10.0,
                             fov=3.1, max_range=8.0))
    t = log.truth
    turns = 2 * np.pi * np.where(np.arange(t.pose.shape[0]) % 2 == 0, 3000.0, -1000.0)  # alternate branches
    log.odometry = Odometry(stamp=t.pose_stamp.copy(), pose=np.column_stack([t.pose[:, :2], t.pose[:, 2] + turns]))
    result = run(log, pairs__heading_source="odometry", pairs__heading=(-1e-6, 1e-6))
    truth = truth_of(log)
    assert len(result.consistency.empty_events) == 0
    assert pair_contains(result, truth).all()
    assert landmark_contains(result, truth).all()
