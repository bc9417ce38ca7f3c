"""Loop closure over the submaps (`lidar.loop_closure`): loop constraints against older
submaps, the anchor graph contracted to a fixpoint, global boxes that stay bounded.

Every global box after closure must hold the truth in the result's frame (the report's ``pose``
check), every relative box, every submap's P_EMPTY and the global map's too; a log with no loop runs, says so
and keeps its local guarantees. Short simulated rooms logs in the default lane, more seeds
under ``slow``.
"""

from __future__ import annotations

import numpy as np
import pytest

from ivslam_cli.config import resolve_config
from ivslam_cli.interval.pose import compose, position_width
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.slam.lidar import Params as LidarParams
from ivslam_cli.slam.lidar.pipeline import run, solve, summary
from tests.helpers.hyp import seeds
from tests.helpers.lidar_truth import assert_contained
from tests.helpers.paths import CONFIGS


def _run(seed, world="rooms", duration=30.0, steps=None, overrides=None):
    log = simulate(SimConfig(scenario="lidar", world=world, sensor="urg-04lx", seed=seed,
                             duration=None if steps else duration, steps=steps))
    params = LidarParams.from_config(resolve_config(None, dict(overrides or {}), log_bounds=log.bounds))
    return log, params


def _solved(seed, **kw):
    log, params = _run(seed, **kw)
    return log, params, solve(log, params)


def _check_closed(seed, duration):
    log, params = _run(seed, duration=duration)
    res = run(log, params)
    assert_contained(res, ("pose", "pose_relative", "map_free", "global_free"))
    st = res.stats
    assert st["loops_found"] > 0
    # the global map, proven in the result's frame, keeps at least half of what log-odds calls free
    assert st["global_empty_cells"] >= 0.5 * st["global_logodds_free_cells"] > 0
    assert st["graph_empty_meets"] == 0
    w = position_width(res.poses.box)
    assert np.nanmedian(w) < st["median_open_loop_width"]
    assert res.loops is not None and len(res.loops) == st["loops_found"] + st["loops_empty"]
    # a scan with a loop constraint L against old anchor i: its global box is met with G_i ⊕ L
    # directly (through the anchor edge it would compose its relative box twice)
    lp, G = res.loops, res.submaps.anchor_box
    out = np.empty((3, 2))
    for row, sm, box, empty in zip(lp.row, lp.submap, lp.box, lp.empty):
        if empty:
            continue
        compose(np.ascontiguousarray(G[sm]), np.ascontiguousarray(box), 1, out)
        b = res.poses.box[row]
        assert np.all(b[:2, 0] >= out[:2, 0]) and np.all(b[:2, 1] <= out[:2, 1]), (row, sm)
        assert b[2, 1] - b[2, 0] <= out[2, 1] - out[2, 0] + 1e-12, (row, sm)
    return st


@pytest.mark.slow  # ~25 s
@pytest.mark.parametrize("seed", [3])
def test_loops_keep_the_truth_and_bound_the_global_boxes(seed):
    st = _check_closed(seed, 30.0)
    assert st["median_pose_width"] <= 1.0


@pytest.mark.slow  # ~15 s each
@pytest.mark.parametrize("seed", seeds(ci=20))
def test_loops_keep_the_truth_on_more_seeds(seed):
    """20 s logs (200 scans, about 7 submaps). Measured on seeds 0-19: global box median
    0.35–0.48 m on 18 of them, 1.09 m and 1.14 m on seeds 0 and 15, against 0.94–1.41 m from the
    chain alone; global free cells 0.58–0.79× log-odds."""
    _check_closed(seed, 20.0)


def test_a_log_with_no_loop_says_so_and_keeps_local_guarantees():
    log, params, out = _solved(1, world="corridor", steps=40)
    res = run(log, params)
    assert_contained(res, ("pose", "pose_relative", "map_free"))
    assert out.stats["loops_found"] == 0
    assert "no loop found" in summary(res)
    assert res.global_map is not None and res.global_map.frame == "proven"
    # the open-loop boxes are the closed ones when no loop edge exists
    assert out.stats["median_open_loop_width"] >= out.stats["median_pose_width"] - 1e-9


def test_loop_closure_off_writes_no_loops():
    log, params, out = _solved(1, world="corridor", steps=30, overrides={"lidar.loop_closure": False})
    assert out.loops is None and "loops_found" not in out.stats


def test_graph_contraction_is_sound_on_a_triangle():
    """Three anchors, exact edges around a loop: the contracted boxes keep the true poses and
    the loop narrows the last anchor's box below what the chain gives."""
    from ivslam_cli.slam.lidar.loops import AnchorGraph

    g = AnchorGraph()
    e = 0.05
    def box(x, y, t, w=e):
        return np.array([x - w, x + w, y - w, y + w, t - w, t + w])
    g.add_edge(0, 1, box(1.0, 0.0, np.pi / 2), 0)
    g.add_edge(1, 2, box(1.0, 0.0, np.pi / 2), 0)
    G = np.array([box(0.0, 0.0, 0.0, 1e-9), box(1.0, 0.0, np.pi / 2, 5.0), box(1.0, 1.0, np.pi, 5.0)])
    chain_only = G.copy()
    g.contract(chain_only)
    g.add_edge(0, 2, box(1.0, 1.0, np.pi, 0.02), 1)
    g.contract(G)
    for b, true in zip(G, [(0, 0, 0), (1, 0, np.pi / 2), (1, 1, np.pi)]):
        assert b[0] <= true[0] <= b[1] and b[2] <= true[1] <= b[3] and b[4] <= true[2] <= b[5]
    assert position_width(G[2]) < position_width(chain_only[2])


def test_the_global_map_skips_boxes_too_wide_to_prove_anything():
    """With lidar.max_pose_width = 0 (every scan mapped in its submap) a global box hundreds of
    metres wide (an Intel-like tube without closure) is not rendered: it would prove nothing and
    make the map span kilometres (the map-size limit would stop the run)."""
    from ivslam_cli.slam.lidar.global_map import MAX_WIDTH_ANY, render_global
    from ivslam_cli.slam.lidar.map_update import usable_scans

    log, params = _run(1, world="corridor", steps=6)
    scans, _ = usable_scans(log.scans, params.beams, params.max_range, params.eps, None)
    used = np.arange(len(scans))
    boxes = np.zeros((used.size, 6))
    boxes[:, 1::2] = 0.01
    boxes[-1] = [-900.0, 900.0, -900.0, 900.0, -3.0, 3.0]
    gm = render_global(scans, used, boxes, params.beams, params.eps, 0.0)
    assert gm.scans_mapped == used.size - 1 and gm.empty_cells > 0
    assert gm.grid.shape[0] * params.eps < 2 * 30.0 + MAX_WIDTH_ANY


def test_a_loop_scan_is_met_with_the_old_anchor_and_its_loop_constraint():
    """``G_i ⊕ L`` narrows the scan's global box and keeps its true pose; a constraint that
    misses the box is recorded (a contradiction, never an empty box) and not met."""
    from types import SimpleNamespace

    from ivslam_cli.slam.lidar.loops import LoopConstraint
    from ivslam_cli.slam.lidar.submaps import _meet_loops

    true = np.array([2.0, 1.0, 0.3])  # the scan's true pose in the result's frame
    G = np.array([1.0 - 1e-3, 1.0 + 1e-3, 0.0 - 1e-3, 0.0 + 1e-3, 0.5 - 1e-3, 0.5 + 1e-3])  # old anchor
    c, s = np.cos(-0.5), np.sin(-0.5)
    rel = np.array([c * 1.0 - s * 1.0, s * 1.0 + c * 1.0, 0.3 - 0.5])  # the scan in the anchor's frame
    L = np.column_stack([rel - 0.1, rel + 0.1]).reshape(6)
    wide = np.column_stack([true - 1.0, true + 1.0]).reshape(6)
    subs = [SimpleNamespace(G=G)]
    missed: list = []
    gb = _meet_loops([LoopConstraint(7, 0, 1, wide, L, 100, 10, False)], subs, wide.copy(), missed)
    assert not missed
    assert np.all(gb[0::2] <= true) and np.all(true <= gb[1::2])
    assert np.all(gb[1::2] - gb[0::2] < 0.5) and np.all(gb[1::2] - gb[0::2] > 0.1)
    far = np.column_stack([true + 5.0, true + 6.0]).reshape(6)
    out = _meet_loops([LoopConstraint(7, 0, 1, wide, L, 100, 10, False),
                       LoopConstraint(8, 0, 1, wide, np.full(6, np.nan), 100, 10, True)], subs, far.copy(), missed)
    assert np.array_equal(out, far) and missed == [(7, 0, "loop")]


def test_threads_give_the_same_result():
    """lidar.threads: the submaps a scan is tracked in are matched and mapped in parallel; every
    array of the result is what one thread gives (a loop log: scans in two submaps, loops)."""
    log, params = _run(3, duration=12.0, overrides={"lidar.threads": 1})
    one = run(log, params)
    log, params = _run(3, duration=12.0, overrides={"lidar.threads": 3})
    three = run(log, params)
    assert one.stats["loops_found"] > 0 and len(one.submaps.member_row) > len(one.submaps)
    pairs = [(one.poses.box, three.poses.box), (one.poses.relative, three.poses.relative),
             (one.submaps.state, three.submaps.state), (one.submaps.member_box, three.submaps.member_box),
             (one.loops.box, three.loops.box), (one.grid.state, three.grid.state),
             (one.logodds.value, three.logodds.value), (one.global_map.state, three.global_map.state)]
    for a, b in pairs:
        assert a.shape == b.shape and np.array_equal(a, b, equal_nan=True)


def _pose(p, q):
    """``p ⊕ q`` for poses (x, y, θ)."""
    c, s = np.cos(p[2]), np.sin(p[2])
    return np.array([p[0] + c * q[0] - s * q[1], p[1] + s * q[0] + c * q[1], p[2] + q[2]])


def _inv(p):
    c, s = np.cos(p[2]), np.sin(p[2])
    return np.array([-c * p[0] - s * p[1], s * p[0] - c * p[1], -p[2]])


def _around(rng, p, w):
    """A box around ``p``, each side ``w / 10`` to ``w`` from it (far above rounding)."""
    return np.column_stack([p - rng.uniform(w / 10, w, 3), p + rng.uniform(w / 10, w, 3)])


def _in(b, p):
    t = (p[2] - b[2, 0]) % (2 * np.pi) + b[2, 0]
    return b[0, 0] <= p[0] <= b[0, 1] and b[1, 0] <= p[1] <= b[1, 1] and t <= b[2, 1]


def test_loop_priors_hold_the_true_pose_in_every_old_anchor_frame():
    """Random anchor chains, boxes around the true poses: each prior holds the scan's true pose in
    that old anchor's frame, and none is a miss (the truth is in both boxes it meets)."""
    from ivslam_cli.slam.lidar.loops import SLICES, loop_priors

    rng = np.random.default_rng(7)
    for _ in range(300):
        n = int(rng.integers(2, 9))
        steps = [np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(-np.pi, np.pi)]) for _ in range(n)]
        A = [np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-np.pi, np.pi)])]
        for k in range(n - 1):
            A.append(_pose(A[-1], steps[k]))
        rel = steps[-1]  # the scan in its home anchor h = n - 1
        scan = _pose(A[-1], rel)
        w = rng.choice([1e-6, 0.05, 0.5, 3.0])
        G = np.array([_around(rng, a, w) for a in A])
        E = np.array([_around(rng, steps[k], w) for k in range(n - 1)])
        out = np.empty((n - 1, 3, 2))
        ok = np.zeros(n - 1, bool)
        loop_priors(G, _around(rng, scan, w), E, n - 1, _around(rng, rel, w), SLICES, float(rng.choice([0.5, 7.0])),
                    out, ok)
        assert ok.all()
        for i in range(n - 1):
            assert _in(out[i], _pose(_inv(A[i]), scan)), (i, out[i])


def test_the_mosaic_places_every_cell_at_its_anchor_box_centre():
    """The mosaic against its definition, computed cell by cell here: nearest cell of each known
    cell of each submap moved by its anchor's box centre; majority state, summed log-odds."""
    from ivslam_cli.results.model import CELL_EMPTY, CELL_OBSTACLE, CELL_UNKNOWN, LogOddsGrid, Submaps
    from ivslam_cli.slam.lidar.mosaic import mosaic

    rng = np.random.default_rng(3)
    eps, shapes = 0.05, [(7, 5), (0, 0), (4, 9), (6, 6)]
    states = [rng.choice([CELL_UNKNOWN, CELL_EMPTY, CELL_OBSTACLE], size=s).astype(np.uint8) for s in shapes]
    origin = rng.uniform(-1, 1, (len(shapes), 2))
    ab = np.array([_around(rng, np.array([rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-3, 3)]), 0.2)
                   for _ in shapes])
    sm = Submaps(anchor=np.arange(len(shapes)), anchor_box=ab, resolution=eps, origin=origin,
                 shape=np.array(shapes, np.int64), state=np.concatenate([s.reshape(-1) for s in states]),
                 member_offsets=np.zeros(len(shapes) + 1, np.int64), member_row=np.zeros(0, np.int64),
                 member_box=np.zeros((0, 3, 2)), member_mapped=np.zeros(0, bool))
    vals = [rng.choice([0.0, -0.4, 0.85], size=s).astype(np.float32) for s in shapes]
    lo = [LogOddsGrid(value=v, l_occ=0.85, l_free=-0.4, l_min=-5.0, l_max=5.0, scans=1, beams=1) for v in vals]
    grid, lgrid = mosaic(sm, lo)
    free, obst, val = {}, {}, {}
    for m, (st, v) in enumerate(zip(states, vals)):
        c = 0.5 * (ab[m, :, 0] + ab[m, :, 1])
        for r in range(st.shape[0]):
            for col in range(st.shape[1]):
                if st[r, col] == CELL_UNKNOWN and v[r, col] == 0:
                    continue
                x, y = origin[m, 0] + (col + 0.5) * eps, origin[m, 1] + (r + 0.5) * eps
                key = (int(np.floor((c[0] + np.cos(c[2]) * x - np.sin(c[2]) * y) / eps)),
                       int(np.floor((c[1] + np.sin(c[2]) * x + np.cos(c[2]) * y) / eps)))
                free[key] = free.get(key, 0) + (st[r, col] == CELL_EMPTY)
                obst[key] = obst.get(key, 0) + (st[r, col] == CELL_OBSTACLE)
                val[key] = val.get(key, 0.0) + float(v[r, col])
    i0, j0 = min(k[0] for k in free), min(k[1] for k in free)
    assert np.allclose(grid.origin, [i0 * eps, j0 * eps])
    assert grid.state.shape == (max(k[1] for k in free) - j0 + 1, max(k[0] for k in free) - i0 + 1)
    for (i, j), nf in free.items():
        want = CELL_OBSTACLE if obst[(i, j)] > 0 and obst[(i, j)] >= nf else (CELL_EMPTY if nf > 0 else CELL_UNKNOWN)
        assert grid.state[j - j0, i - i0] == want
        assert lgrid.value[j - j0, i - i0] == np.float32(np.clip(val[(i, j)], -5, 5))
    assert np.count_nonzero(grid.state != CELL_UNKNOWN) == sum(
        1 for k in free if free[k] > 0 or obst[k] > 0)


@pytest.mark.slow  # ~45 s each
@pytest.mark.parametrize("seed", seeds(ci=20))
def test_the_simulated_config_keeps_the_truth_in_narrow_relative_boxes(seed):
    """``configs/simulated_lidar.toml`` (no simulated beam breaks its bounds: ``q_beams = 0``,
    every beam, the heading searched to 0.625 mm, a submap every metre, loops searched every
    other scan) on 20 s rooms logs: every truth inside, no empty event; the relative boxes of
    the scans (the anchors' apart) median at most 0.15 m and 0.03 rad (issue #16's targets);
    the global map at least half the log-odds free cells; the global box median at most 0.5 m
    (issue #18's target). Measured on seeds 0-19: relative 0.063-0.072 m and 0.0218-0.0295
    rad; global box median 0.23-0.49 m (seed 15 the widest); global free cells 0.64-0.85x
    log-odds."""
    log, _ = _run(seed, duration=20.0)
    params = LidarParams.from_config(resolve_config(CONFIGS / "simulated_lidar.toml", {}, log_bounds=log.bounds))
    res = run(log, params)
    assert_contained(res, ("pose", "pose_relative", "map_free", "global_free"))
    assert len(res.consistency.empty_events) == 0
    R = res.poses.relative
    mine = ~np.isin(np.arange(R.shape[0]), res.submaps.anchor)
    assert np.median(position_width(R[mine])) <= 0.15
    assert np.median(R[mine, 2, 1] - R[mine, 2, 0]) <= 0.03
    st = res.stats
    assert st["global_empty_cells"] >= 0.5 * st["global_logodds_free_cells"] > 0
    assert np.nanmedian(position_width(res.poses.box)) <= 0.5
