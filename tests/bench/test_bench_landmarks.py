"""The landmark benchmark's figures, tables and verdicts on a small simulated log (no real data,
no timing targets: those live in ``python -m bench.bench_landmarks``)."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

from bench.bench_landmarks import (
    VICTORIA_COLUMNS,
    format_table,
    gtsam_bounds,
    mrclam_columns,
    our_figures,
    run_case,
    verdicts,
)
from ivslam_cli.config import resolve_config
from ivslam_cli.report.core import landmark_containment, pose_containment
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.slam.landmarks import Params as LandmarksParams
from ivslam_cli.slam.landmarks.pipeline import solve

HAVE_GTSAM = importlib.util.find_spec("gtsam") is not None
OVERRIDES = {"landmarks.initial_pose_from_truth": True}


@pytest.fixture(scope="module")
def sim():
    return simulate(SimConfig(scenario="landmarks", seed=3, steps=80, landmarks=8, world_size=10.0))


@pytest.fixture(scope="module")
def row(sim):
    r = run_case(sim, None, gtsam=HAVE_GTSAM, overrides=OVERRIDES)
    return {"robot": 7, **r}


def test_our_figures_match_the_report(sim):
    out = solve(sim, LandmarksParams.from_config(resolve_config(None, OVERRIDES, log_bounds=sim.bounds)))
    fig = our_figures(sim, out)
    pc, lc = pose_containment(out.poses, sim.truth), landmark_containment(out.landmarks, sim.truth)
    assert (fig["pose_checked"], fig["pose_contained"]) == (pc.checked, pc.contained) and pc.checked > 0
    assert (fig["lm_checked"], fig["lm_contained"]) == (lc.checked, lc.contained) and lc.checked > 0
    assert fig["pose_fraction"] == pc.fraction == 1.0  # honest bounds: the truth is kept
    assert fig["pose_centre_err_median"] == pytest.approx(np.median(pc.centre_error))
    assert fig["pose_centre_err_rmse"] == pytest.approx(np.sqrt(np.mean(pc.centre_error**2)))
    assert fig["lm_centre_err_median"] == pytest.approx(np.median(lc.centre_error))
    assert fig["nodes"] == len(out.poses.stamp) and fig["landmarks"] == len(out.landmarks.id)
    assert fig["empty_events"] == len(out.consistency.empty_events) == 0
    assert fig["rejected"] == out.stats["observations_rejected"]
    assert fig["pose_width_median"] == out.stats["median_pose_width"] > 0


def test_figures_without_truth_are_nan(sim):
    from dataclasses import replace

    log = replace(sim, truth=None)
    out = solve(log, LandmarksParams.from_config(resolve_config(None, {"landmarks.initial_pose": [0.0, 0.0, 0.0]}, log_bounds=log.bounds)))
    fig = our_figures(log, out)
    assert fig["pose_checked"] == 0 and math.isnan(fig["pose_fraction"]) and fig["lm_checked"] == 0
    text = format_table([{"name": "no truth", **fig, "ours_s": 0.5}], VICTORIA_COLUMNS)
    assert "no truth" in text and str(fig["nodes"]) in text


def test_gtsam_bounds_map_the_same_values_and_name_the_rest():
    bounds = {"range_abs": 0.2, "range_rel": 0.15, "bearing": 0.1, "odom_v": 0.02, "odom_v_rel": 0.1,
              "odom_w": 0.05, "odom_w_rel": 0.0, "odom_lag_xy": 0.15, "odom_lag_th": 0.2, "odom_trans_abs": 0.0}
    mapped, unmodelled = gtsam_bounds(bounds)
    assert mapped == {k: bounds[k] for k in mapped} and set(mapped) >= {"range_abs", "bearing", "odom_w_rel"}
    assert unmodelled == ["odom_lag_th", "odom_lag_xy"]  # zero-valued keys are not listed


def test_table_has_a_cell_per_column_and_markdown_form(row):
    cols = mrclam_columns(HAVE_GTSAM)
    text = format_table([row, row], cols)
    lines = text.splitlines()
    assert len(lines) == 3 and len({len(line) for line in lines}) == 1  # fixed width
    md = format_table([row], cols, markdown=True).splitlines()
    assert len(md) == 3 and all(line.count("|") == len(cols) + 1 for line in md)
    assert md[0].startswith("| robot |") and md[2].startswith("| 7 |")
    assert f"{row['lm_contained']}/{row['lm_checked']}" in md[2]
    assert f"{row['ours_s']:.2f}" in md[2]
    if HAVE_GTSAM:
        assert "GTSAM s" in md[0] and f"{row['gtsam_pos_err_median']:.3f}" in md[2]


@pytest.mark.skipif(not HAVE_GTSAM, reason="gtsam (dev extra) not installed")
def test_gtsam_columns_on_the_simulated_log(row):
    assert row["gtsam_s"] > 0 and 0 <= row["gtsam_pose_xy_in_3sigma"] <= 1
    assert 0 <= row["gtsam_lm_in_3sigma"] <= row["gtsam_lm_checked"] == row["lm_checked"]
    assert math.isfinite(row["gtsam_pos_err_rmse"]) and 0 <= row["gtsam_pos_err_median"] < 1.0


TIGHT = {"pose_width_median": 1.2, "landmark_width_median": 0.8, "heading_width_median": 0.4}


def test_verdicts_pass_and_fail_on_the_targets(row):
    good = dict(row, ours_s=1.0, pose_fraction=0.995, pose_contained=995, pose_checked=1000,
                lm_contained=15, lm_checked=15, loc_pose_fraction=1.0, **TIGHT)
    assert all(ok for ok, _ in verdicts([good], {"ours_s": 1.5, "empty_events": 0}))
    for bad in (dict(good, ours_s=2.5), dict(good, pose_fraction=0.98), dict(good, lm_contained=14),
                dict(good, pose_fraction=math.nan), dict(good, lm_checked=0, lm_contained=0),
                dict(good, pose_width_median=1.6), dict(good, landmark_width_median=1.1),
                dict(good, heading_width_median=math.nan), dict(good, loc_pose_fraction=0.999)):
        checks = verdicts([bad], None)
        assert len(checks) == 7 and sum(not ok for ok, _ in checks) == 1


def test_the_floor_is_the_same_run_with_the_true_map(sim, row):
    """run_case's ``loc_*`` figures: the map given (landmarks.map_known), truth kept, no wider
    than the SLAM run; the table shows them beside the SLAM widths."""
    assert row["loc_pose_fraction"] == 1.0 and row["loc_pose_checked"] == row["pose_checked"] > 0
    assert 0 < row["loc_pose_width_median"] <= row["pose_width_median"]
    assert row["loc_heading_width_median"] <= row["heading_width_median"]
    heads = [h for h, _ in mrclam_columns(False)]
    assert heads.index("map given: pose w m") == heads.index("head w rad") + 1
    assert f"{row['loc_pose_width_median']:.2f}" in format_table([row], mrclam_columns(False))
    v = verdicts([], {"ours_s": 3.0, "empty_events": 2})
    assert [ok for ok, _ in v] == [False, False] and "2 empty events" in v[1][1]


def test_main_writes_markdown_and_json_and_fails_on_a_missed_target(row, tmp_path, monkeypatch, capsys):
    import json

    import bench.bench_landmarks as B

    good = dict(row, ours_s=1.0, pose_fraction=1.0, pose_contained=10, pose_checked=10, lm_contained=15,
                lm_checked=15, cold_s=30.0, loc_pose_fraction=1.0, **TIGHT)

    def fake(args, robots, use_gtsam, mrclam):  # the cases' processes, replaced by known rows
        second = {k: v for k, v in good.items() if k != "cold_s"}  # cold: measured once, first robot
        mrclam.extend([good, dict(second, robot=8, ours_s=2.5)])
        return dict(good, name="Victoria Park", pose_fraction=math.nan)

    proc = {"wall_s": 1.5, "walls": [1.5, 1.6, 1.4], "cpu_s": 1.4, "peak_mb": 300.0, "pose_width_median": 1.0,
            "landmark_width_median": 0.9, "heading_width_median": 0.4, "empty_events": 0, "pose_checked": 10,
            "pose_contained": 10, "lm_checked": 15, "lm_contained": 15}
    asked = []

    def fake_processes(robots, n):  # the whole `ivslam run` processes, replaced by known rows
        asked.append((robots, n))
        return [dict(proc, robot=7), dict(proc, robot=8), dict(proc, robot="all", wall_s=12.0)]

    monkeypatch.setattr(B, "_run_all", fake)
    monkeypatch.setattr(B, "run_processes", fake_processes)
    monkeypatch.setattr(B, "_have_gtsam", lambda: HAVE_GTSAM)
    monkeypatch.setattr(B, "MRCLAM", tmp_path)
    monkeypatch.setattr(B, "VICTORIA", tmp_path)
    md, js = tmp_path / "t.md", tmp_path / "f.json"
    assert B.main(["--robots", "7,8", "--markdown", str(md), "--json", str(js)]) == 1
    out = capsys.readouterr().out
    assert "FAIL MRCLAM robot 8: warm 2.50 s" in out and "PASS MRCLAM robot 7: warm 1.00 s" in out
    assert asked == [([7, 8, "all"], 3)]
    assert "PASS MRCLAM robot 7: warm `ivslam run` process 1.50 s" in out
    assert "FAIL MRCLAM --robot all: warm `ivslam run` process 12.00 s <= 10 s" in out
    text = md.read_text()
    assert "| 7 | 30.0 | 1.00 |" in text and "| 8 | – | 2.50 |" in text and "| Victoria Park |" in text
    assert "| all | 12.00 |" in text
    doc = json.loads(js.read_text())  # standard JSON: NaN written as null
    assert doc["victoria"]["pose_fraction"] is None and doc["mrclam"][1]["ours_s"] == 2.5
    assert doc["processes"][2]["robot"] == "all"
    assert B.main(["--robots", "7,8", "--processes", "0"]) == 1 and len(asked) == 1  # none asked for


def test_a_failing_case_process_is_reported(tmp_path):
    import bench.bench_landmarks as B

    with pytest.raises(B.WorkerError, match="no-such-case"):
        B._spawn("no-such-case", tmp_path / "cache", gtsam=False)


def test_whole_process_figures_come_from_the_report_and_are_judged(sim, tmp_path):
    """The whole-process rows read widths and containment from `ivslam report --json`; a row
    is judged against 2 s per robot, 10 s for --robot all, 1 GB and full containment."""
    import json

    from click.testing import CliRunner

    from bench.bench_landmarks import PROCESS_COLUMNS, process_verdicts, report_figures
    from ivslam_cli.cli import cli
    from ivslam_cli.logs.writers import write_log

    log = tmp_path / "sim.h5"
    write_log(log, sim)
    res = tmp_path / "res.h5"
    runner = CliRunner()
    assert runner.invoke(cli, ["run", str(log), "--mode", "landmarks", "--initial-pose-from-truth",
                                "-o", str(res)]).exit_code == 0
    rep = runner.invoke(cli, ["report", str(res), "--json"])
    fig = report_figures(json.loads(rep.output))
    assert fig["pose_checked"] > 0 and fig["pose_contained"] == fig["pose_checked"]
    assert fig["lm_checked"] > 0 and fig["lm_contained"] == fig["lm_checked"]
    assert fig["pose_width_median"] > 0 and fig["heading_width_median"] > 0 and fig["empty_events"] == 0
    row = {"robot": 3, "wall_s": 1.9, "walls": [1.9, 2.1, 1.8], "cpu_s": 1.8, "peak_mb": 300.0, **fig}
    assert all(ok for ok, _ in process_verdicts([row]))
    assert not process_verdicts([{**row, "wall_s": 2.1}])[0][0]
    assert process_verdicts([{**row, "robot": "all", "wall_s": 9.5}])[0][0]
    assert not process_verdicts([{**row, "robot": "all", "wall_s": 10.5}])[0][0]
    assert not process_verdicts([{**row, "peak_mb": 2000.0}])[1][0]
    assert not process_verdicts([{**row, "pose_contained": fig["pose_checked"] - 1}])[2][0]
    assert "1.90" in format_table([row], PROCESS_COLUMNS)
