"""`ivslam run --mode lidar` end to end: pose boxes, P_EMPTY / P_OBSTACLE, old/new, result, report.

Simulated logs (``ivslam simulate --scenario lidar --beam-model ray``: a ray-cast LiDAR in a wall
world, twist odometry with stated bounds) are checked against their truth (cone-beam logs, the
simulator's default: ``test_simulate_cone.py``):

- every true pose (at every scan stamp) is in its box;
- every true wall point hit by a valid in-bound beam lies in a cell of ∪ P_OBSTACLE^k ∪
  P_OLD^k (the per-beam outer sets; the map's OBSTACLE state is their seed intersection);
- no P_EMPTY cell meets a true wall.

Real datasets run when ``../shared/datasets`` is there (skipped otherwise; marked ``datasets``).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.cli import cli as main
from ivslam_cli.config import resolve_config
from ivslam_cli.errors import IvslamError
from ivslam_cli.results.model import CELL_EMPTY, CELL_OBSTACLE
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.simulate.lidar import laser_poses
from ivslam_cli.simulate.raycast import cast
from ivslam_cli.slam.lidar import Params as LidarParams
from ivslam_cli.slam.lidar.pipeline import solve
from tests.helpers.hyp import examples
from tests.helpers.lidar_world import segments_meet_cells
from tests.helpers.paths import CONFIGS, SAMPLE_LOGS as SAMPLES

WORLDS = ("rooms", "corridor", "pillars", "open")


# ---------------------------------------------------------------- truth checks
def pose_misses(out, truth) -> int:
    """Scans whose true pose (at the scan's own stamp) is outside its box (heading mod 2π)."""
    k = np.searchsorted(truth.pose_stamp, out.poses.stamp)
    assert np.array_equal(truth.pose_stamp[k], out.poses.stamp)
    p, box = truth.pose[k], out.poses.box
    inside = np.all((box[:, :2, 0] <= p[:, :2]) & (p[:, :2] <= box[:, :2, 1]), axis=1)
    th = box[:, 2, 0] + np.mod(p[:, 2] - box[:, 2, 0], 2 * math.pi)
    return int(np.count_nonzero(~(inside & (th <= box[:, 2, 1]))))


def empty_on_walls(out, world) -> tuple[int, int]:
    """(P_EMPTY cells meeting a wall, P_EMPTY cells)."""
    d = out.tmap.dense(raw=True)
    empty = np.argwhere(d.data & 1) + [d.i0, d.j0]
    bad = int(segments_meet_cells(world, empty, out.tmap.eps).sum()) if empty.size else 0
    return bad, int(empty.shape[0])


def hits_outside_obstacle(log, out) -> tuple[int, int]:
    """(true hit points of valid in-bound beams of mapped scans outside every cell flagged
    P_OBSTACLE^k or P_OLD^k, hit points checked)."""
    sc, tr, tmap = log.scans, log.truth, out.tmap
    nb = int(sc.offsets[1] - sc.offsets[0])
    lp = laser_poses(tr.pose, sc.mount)
    ang = sc.angle_min[0] + sc.angle_increment[0] * np.arange(nb)
    dist = cast(lp, ang, tr.world)
    use = sc.valid.reshape(-1, nb) & ~tr.outliers["scans"].reshape(-1, nb) & np.isfinite(dist)
    mapped = np.zeros(len(sc), bool)
    mapped[out.mapped] = True
    use &= mapped[:, None]
    world = lp[:, 2:3] + ang[None, :]
    px = (lp[:, 0:1] + dist * np.cos(world))[use]
    py = (lp[:, 1:2] + dist * np.sin(world))[use]
    missed = np.ones(px.shape[0], dtype=bool)
    e = tmap.eps
    for ox in (-1e-9, 0.0, 1e-9):  # a point on a cell border belongs to both cells
        for oy in (-1e-9, 0.0, 1e-9):
            f = tmap.get(np.floor(px / e + ox).astype(np.int64), np.floor(py / e + oy).astype(np.int64))
            missed &= (f & 6) == 0
    return int(missed.sum()), int(px.shape[0])


def run_sim(seed, world, sensor="urg-04lx", noise="uniform", steps=60, overrides=None):
    """Ray-cast logs (beams with no width): without ``lidar.fill_gaps`` such scans prove no free
    space, so these runs state the gap assumption to exercise P_EMPTY (it holds in these worlds
    for the URG's 0.35° steps; the SICK pillars case below shows where it does not)."""
    log = simulate(SimConfig(scenario="lidar", world=world, sensor=sensor, seed=seed, steps=steps, noise=noise,
                             beam_model="ray"))
    cfg = resolve_config(None, {"landmarks.initial_pose_from_truth": True, "lidar.fill_gaps": True,
                                **(overrides or {})}, log_bounds=log.bounds)
    return log, solve(log, LidarParams.from_config(cfg))


def assert_truth_kept(log, out):
    assert pose_misses(out, log.truth) == 0
    bad, n_empty = empty_on_walls(out, log.truth.world)
    assert bad == 0, f"{bad} of {n_empty} P_EMPTY cells meet a wall"
    missed, n_hits = hits_outside_obstacle(log, out)
    assert n_hits > 0 and missed == 0, f"{missed} of {n_hits} true hit points outside P_OBSTACLE"
    return n_empty


# ---------------------------------------------------------------- simulated logs
@given(st.integers(0, 2**31 - 1), st.sampled_from(WORLDS), st.sampled_from(["uniform", "edges"]))
@settings(max_examples=examples(ci=50))
def test_simulated_urg_runs_keep_the_truth(seed, world, noise):
    """The seed's sensor (URG-04LX profile, 682 beams 0.35° apart) in every built-in world."""
    log, out = run_sim(seed, world, noise=noise)
    n_empty = assert_truth_kept(log, out)
    assert n_empty > 0 and out.stats["scans_mapped"] > 0
    assert out.stats["old_beams"] + out.stats["new_beams"] == out.stats["valid_beams_mapped"]


@given(st.integers(0, 2**31 - 1), st.sampled_from(WORLDS))
@settings(max_examples=examples(ci=12))
def test_keyframe_scan_matching_keeps_the_truth(seed, world):
    """lidar.keyframes: scans matched to keyframes every 0.3 m / 0.2 rad (several per log)."""
    log, out = run_sim(seed, world, overrides={"lidar.keyframes": True, "lidar.keyframe_distance": 0.3,
                                                "lidar.keyframe_turn": 0.2, "lidar.match_boxes": 300})
    assert_truth_kept(log, out)
    assert out.stats["keyframes"] >= 2 and out.stats["keyframes_matched"] >= 1
    # sound data: no keyframe match may come out empty (that would be an empty event)
    assert not any(str(c).startswith("keyframe") for c in out.consistency.empty_events.constraint)
    pairs, boxes = out.relative
    assert pairs.shape[0] > 0
    tr = log.truth
    p = tr.pose[np.searchsorted(tr.pose_stamp, out.poses.stamp)]
    a, b = p[pairs[:, 0]], p[pairs[:, 1]]
    d = b - a
    c, s_ = np.cos(a[:, 2]), np.sin(a[:, 2])
    rel = np.column_stack([c * d[:, 0] + s_ * d[:, 1], -s_ * d[:, 0] + c * d[:, 1], d[:, 2]])
    th = boxes[:, 4] + np.mod(rel[:, 2] - boxes[:, 4], 2 * math.pi)
    inside = ((boxes[:, 0] <= rel[:, 0]) & (rel[:, 0] <= boxes[:, 1]) & (boxes[:, 2] <= rel[:, 1])
              & (rel[:, 1] <= boxes[:, 3]) & (th <= boxes[:, 5]))
    assert inside.all(), f"{(~inside).sum()} of {inside.size} relative boxes miss the true relative pose"


@pytest.mark.parametrize("seed,world", [(3, "rooms"), (5, "corridor")])
def test_simulated_sick_rooms_and_corridor_keep_the_truth(seed, world):
    log, out = run_sim(seed, world, sensor="sick")
    assert_truth_kept(log, out)


@pytest.mark.xfail(strict=True, reason="the stated lidar.fill_gaps assumption fails here: 1° ray-cast beams "
                   "(sick profile) leave convex wall corners between two beams that poke into the filled free "
                   "triangle (pillar corner at 10 m: gap 17 cm, range margin 13 cm); one P_EMPTY cell meets a wall")
def test_simulated_sick_pillars_corner_between_beams_with_fill_gaps():
    log, out = run_sim(6, "pillars", sensor="sick", steps=80)
    assert pose_misses(out, log.truth) == 0
    assert hits_outside_obstacle(log, out)[0] == 0
    assert empty_on_walls(out, log.truth.world)[0] == 0


def test_without_fill_gaps_ray_beams_prove_no_free_space_and_stay_sound():
    """The default: the same case keeps the truth, because scans whose cones leave gaps prove no
    free space, and the result says so."""
    log, out = run_sim(6, "pillars", sensor="sick", steps=80, overrides={"lidar.fill_gaps": False})
    assert pose_misses(out, log.truth) == 0
    assert hits_outside_obstacle(log, out)[0] == 0
    assert empty_on_walls(out, log.truth.world) == (0, 0)
    assert "no free space proven" in out.consistency.assumption


def test_poses_known_from_the_truth():
    log, out = run_sim(11, "rooms", overrides={"lidar.poses_known": True, "lidar.pose_margin": (0.02, 0.02, 0.005)})
    assert out.stats["motion"] == "known poses" and out.stats["scans_mapped"] == len(log.scans)
    n_empty = assert_truth_kept(log, out)
    # tight boxes prove much more free space than dead reckoning does
    _, dr = run_sim(11, "rooms")
    assert n_empty > empty_on_walls(dr, log.truth.world)[1]
    assert np.nanmax(out.consistency.widths["pose"].width) <= 0.04 + 1e-9


def test_wide_boxes_are_not_mapped_and_said_so():
    log, out = run_sim(2, "corridor", overrides={"lidar.max_pose_width": 0.3})
    w = out.consistency.widths["pose"].width
    assert (w > 0.3).any() and out.stats["scans_mapped"] == int((w <= 0.3).sum()) < len(log.scans)
    assert any("max_pose_width" in d.reason for d in out.dropped)
    assert_truth_kept(log, out)


def test_range_bounds_hold_in_both_conventions():
    """The map kernels take |z − d| ≤ a' + r'·d; [bounds] says |z − d| ≤ a + r·z (measured) and
    simulated logs a + r·d (true): the converted bounds hold for both."""
    cfg = resolve_config(overrides={"bounds.range_abs": 0.05, "bounds.range_rel": 0.1, "bounds.bearing": 0.0})
    b = LidarParams.from_config(cfg).beams
    rng = np.random.default_rng(0)
    d = rng.uniform(0.0, 50.0, 10_000)
    for z in (d + 0.999 * rng.uniform(-1, 1, d.size) * (0.05 + 0.1 * d),  # true-range convention
              (d + 0.05 * rng.uniform(-1, 1, d.size) * 0.999) / (1 + 0.1 * rng.uniform(-1, 1, d.size) * 0.999)):
        assert np.all(np.abs(z - d) <= b.range_abs + b.range_rel * d)
    assert b.range_abs > 0.05 and b.range_rel > 0.1


def test_simulated_log_states_its_beam_angle_bound():
    log = simulate(SimConfig(scenario="lidar", world="rooms", seed=1, steps=5, bounds={"beam_angle": 0.004}))
    cfg = resolve_config(None, {}, log_bounds=log.bounds)
    assert cfg["bounds.bearing"] == 0.004 and cfg.sources["bounds.bearing"] == "log"


# ---------------------------------------------------------------- errors
def test_one_line_errors(tmp_path):
    from ivslam_cli.logs.writers import write_log

    log = simulate(SimConfig(scenario="lidar", world="rooms", seed=1, steps=10))
    cfg = resolve_config(None, {}, log_bounds=log.bounds)
    with pytest.raises(IvslamError, match="no LiDAR scans"):
        solve(replace(log, scans=None), LidarParams.from_config(cfg))
    no_odo = tmp_path / "no_odo.h5"
    write_log(no_odo, replace(log, odometry=None), "h5", force=False)
    r = CliRunner().invoke(main, ["run", str(no_odo), "--mode", "lidar", "-o", str(tmp_path / "r.h5")])
    assert r.exit_code == 2 and "no odometry" in r.output and "--poses-known" in r.output
    assert len(r.output.strip().splitlines()) == 1 and str(no_odo) in r.output
    # ... and with --poses-known the truth is enough
    r = CliRunner().invoke(main, ["run", str(no_odo), "--mode", "lidar", "--poses-known", "-o", str(tmp_path / "r.h5")])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["run", str(SAMPLES / "pairs.mcap"), "--mode", "lidar", "-o", str(tmp_path / "p.h5")])
    assert r.exit_code == 2 and "no LiDAR scans" in r.output and len(r.output.strip().splitlines()) == 1
    r = CliRunner().invoke(main, ["run", str(no_odo), "--mode", "lidar", "--poses-known", "-o",
                                  str(tmp_path / "q.h5"), "--config", str(_toml(tmp_path, 'known_poses = "scan"'))])
    assert r.exit_code == 2 and "records no pose with its scans" in r.output
    # a return far beyond any 2D LiDAR (a unit or encoding error) is refused before the map
    # update would spend hours on it; lidar.max_range makes the log usable
    far = replace(log.scans, ranges=log.scans.ranges.copy(), valid=log.scans.valid.copy(),
                  range_max=np.full(len(log.scans), 1e4))
    k = int(far.offsets[3]) + 5
    far.ranges[k], far.valid[k] = 5000.0, True
    far_log = tmp_path / "far.h5"
    write_log(far_log, replace(log, scans=far), "h5", force=False)
    r = CliRunner().invoke(main, ["run", str(far_log), "--mode", "lidar", "-o", str(tmp_path / "f.h5")])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and str(far_log) in r.output, r.output
    assert "5000 m (scan 3, beam 5)" in r.output and "lidar.max_range" in r.output
    r = CliRunner().invoke(main, ["run", str(far_log), "--mode", "lidar", "-o", str(tmp_path / "f.h5"),
                                  "--config", str(_toml(tmp_path, "max_range = 100.0"))])
    assert r.exit_code == 0, r.output
    # pose boxes the map update cannot take: 1e12 m from the origin (known poses), or 1e12 m wide
    # (an odometry jump, with max_pose_width = 0 mapping every scan): one line naming the scan
    t = log.truth
    shifted = tmp_path / "shifted.h5"
    write_log(shifted, replace(log, truth=replace(t, pose=t.pose + [1e12, 0.0, 0.0])), "h5", force=False)
    r = CliRunner().invoke(main, ["run", str(shifted), "--mode", "lidar", "--poses-known", "-o",
                                  str(tmp_path / "s.h5")])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and str(shifted) in r.output, r.output
    assert "scan 0: its pose box lies 1e+12 m from the origin" in r.output
    jump = tmp_path / "jump.h5"
    o = log.odometry
    jumped = o.pose + (np.arange(len(o.pose)) >= 5)[:, None] * [1e12, 0.0, 0.0]
    write_log(jump, replace(log, odometry=replace(o, pose=jumped)), "h5", force=False)
    for contract in ("true", "false"):  # scan by scan (contraction) and all at once
        cfg_file = tmp_path / f"j{contract}.toml"
        cfg_file.write_text(f'[lidar]\nmotion = "pose"\nmax_pose_width = 0.0\ncontract = {contract}\n')
        r = CliRunner().invoke(main, ["run", str(jump), "--mode", "lidar", "-o", str(tmp_path / "j.h5"),
                                      "--config", str(cfg_file)])
        assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and str(jump) in r.output, r.output
        assert "m wide" in r.output and "lidar.max_pose_width" in r.output


def _toml(tmp_path, line: str) -> Path:
    p = tmp_path / "c.toml"
    p.write_text(f"[lidar]\n{line}\n")
    return p


# ---------------------------------------------------------------- CLI on the samples
def _pgm(path: Path) -> np.ndarray:
    data = path.read_bytes()
    magic, _comment, size, maxval, rest = data.split(b"\n", 4)
    w, h = map(int, size.split())
    assert magic == b"P5" and maxval == b"255"
    return np.frombuffer(rest, np.uint8).reshape(h, w)


@pytest.mark.parametrize("sample", ["lidar_corridor.mcap", "lidar_rooms.h5"])
def test_cli_run_report_exports_on_the_samples(tmp_path, sample):
    out = tmp_path / "r.h5"
    tum = tmp_path / "r.tum"
    cfg = tmp_path / "fill.toml"  # the samples are ray-cast: state the gap assumption (see run_sim)
    cfg.write_text("[lidar]\nfill_gaps = true\n")
    r = CliRunner().invoke(main, ["run", str(SAMPLES / sample), "--mode", "lidar", "--initial-pose-from-truth",
                                  "--config", str(cfg), "-o", str(out), "--tum", str(tum)])
    assert r.exit_code == 0, r.output
    assert "lidar:" in r.output and "old" in r.output and "m² empty" in r.output
    assert len(tum.read_text().splitlines()) > 10
    prefix = tmp_path / "map"
    r = CliRunner().invoke(main, ["report", str(out), "--map-pgm", str(prefix)])
    assert r.exit_code == 0, r.output
    text = r.output
    assert "mode lidar" in text and "pose" in text and "= 1.0000  ok" in text
    assert "explored" in text and "beams:" in text and "old" in text
    from ivslam_cli.results.hdf5 import read_result

    res = read_result(out)
    g = res.grid
    img = _pgm(prefix.with_suffix(".pgm"))
    assert img.shape == g.state.shape
    assert np.array_equal(img[::-1] == 254, g.state == CELL_EMPTY)
    assert np.array_equal(img[::-1] == 0, g.state == CELL_OBSTACLE)
    yml = prefix.with_suffix(".yaml").read_text()
    assert "resolution: 0.05" in yml and "mode: trinary" in yml
    assert res.stats["empty_cells"] == int((g.state == CELL_EMPTY).sum())
    # JSON report carries the map and the beam counts
    r = CliRunner().invoke(main, ["report", str(out), "--json"])
    import json

    js = json.loads(r.output)
    assert js["map"]["area_m2"]["empty"] > 0 and js["map"]["beams"]["old"] == res.stats["old_beams"]


# ---------------------------------------------------------------- real data
def _dataset(datasets: Path, rel: str) -> Path:
    p = datasets / rel
    if not p.exists():
        pytest.skip(f"dataset not present: {p}")
    return p


@pytest.mark.datasets
@pytest.mark.parametrize("rel,config,mapped_min", [
    ("carmen_corrected/aces-corrected.log.gz", "carmen_corrected.toml", 440),
    ("breezyslam_mines/exp1.dat.xz", "exp1.toml", 20),
    pytest.param("ros2_turtlebot4_comprobo22/macfirst_floor_take_2", "ros_laserscan.toml", 50,
                 marks=pytest.mark.slow),  # ~5-7 s warm each, the two TurtleBot logs
    pytest.param("mcap_turtlebot4_comprobo22/macfirst_floor_take_2.mcap", "ros_laserscan.toml", 50,
                 marks=pytest.mark.slow),
    ("ros1_neato_ksoltan/left_side.bag", "ros_laserscan.toml", 50),
])
def test_real_datasets_end_to_end(datasets, tmp_path, rel, config, mapped_min):
    path = _dataset(datasets, rel)
    out = tmp_path / "r.h5"
    r = CliRunner().invoke(main, ["run", str(path), "--mode", "lidar", "--config", str(CONFIGS / config),
                                  "-o", str(out)])
    assert r.exit_code == 0, r.output
    from ivslam_cli.results.hdf5 import read_result

    res = read_result(out)
    s = res.stats
    assert s["scans_mapped"] >= mapped_min and s["obstacle_cells"] > 0
    if "no free space proven" in res.consistency.assumption:  # beam cones with gaps (the Neato's 1° steps)
        assert s["empty_cells"] == 0
    else:
        assert s["empty_cells"] > 0
    assert s["old_beams"] + s["new_beams"] == s["valid_beams_mapped"] > 0
    assert len(res.consistency.empty_events) == 0


def test_keyframes_without_map_contraction_and_zero_areas():
    """lidar.keyframes works with lidar.contract off (the assumption says which ran); an empty
    obstacle set has area 0, not a rounded-up subnormal."""
    log, out = run_sim(4, "corridor", overrides={"lidar.keyframes": True, "lidar.contract": False,
                                                   "lidar.keyframe_distance": 0.3, "lidar.match_boxes": 200})
    assert_truth_kept(log, out)
    assert out.stats["keyframes_matched"] >= 1 and out.stats["scans_contracted"] == 0
    text = out.consistency.assumption
    assert "keyframe scans" in text and "against the map" not in text
    from ivslam_cli.paving.tiles import TileMap

    assert TileMap(0.05).area("obstacle", upward=True) == 0.0


def test_a_scan_contradicting_its_keyframe_is_an_empty_event():
    """Scans whose ranges are all halved (the bounds broken) cannot match their keyframe: the
    run says so as empty events instead of dropping the empty intersection."""
    log = simulate(SimConfig(scenario="lidar", world="rooms", sensor="urg-04lx", seed=2, steps=60,
                             bounds={"range_abs": 0.01, "range_rel": 0.005}))
    sc = log.scans
    r = sc.ranges.copy()
    for k in range(30, 60):
        r[sc.offsets[k]:sc.offsets[k + 1]] *= 0.5
    bad = replace(log, scans=replace(sc, ranges=r))
    cfg = resolve_config(None, {"landmarks.initial_pose_from_truth": True, "lidar.fill_gaps": True,
                                "lidar.keyframes": True, "lidar.contract": False, "lidar.q_beams": 0,
                                "lidar.keyframe_distance": 0.2, "lidar.match_boxes": 300}, log_bounds=log.bounds)
    out = solve(bad, LidarParams.from_config(cfg))
    kinds = [str(c) for c in out.consistency.empty_events.constraint]
    assert any(c.startswith("keyframe") for c in kinds), kinds
    assert out.stats["keyframes_unmatched"] + kinds.count("keyframe_meet") >= 1
