"""`ivslam report`: computation on hand-made results with known containment, text, JSON, plots."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.report.core import (
    BROKEN,
    FAILURE,
    RELAXED,
    SOUND,
    angle_in,
    compute_report,
    convergence,
    pair_hulls,
)
from ivslam_cli.report.jsonout import report_dict
from ivslam_cli.report.text import render_text
from ivslam_cli.results.example import TRUE_LANDMARKS, example_result
from ivslam_cli.results.hdf5 import write_result
from ivslam_cli.results.model import WidthHistory
from tests.helpers.hyp import examples


def test_consistent_example_is_fully_contained():
    rep = compute_report(example_result())
    assert {k: c.fraction for k, c in rep.containment.items()} == {"landmark": 1.0, "pair": 1.0, "pose": 1.0}
    assert rep.soundness == {"landmark": SOUND, "pair": SOUND, "pose": SOUND} and rep.sound
    # 3 landmarks, 3 pairs, 6 pose boxes (one a second; the truth every 0.5 s)
    assert [rep.containment[k].checked for k in ("landmark", "pair", "pose")] == [3, 3, 6]
    # landmark boxes are centred 0.05 off in x and y
    np.testing.assert_allclose(rep.containment["landmark"].centre_error, math.hypot(0.05, 0.05))
    np.testing.assert_allclose(rep.containment["pair"].centre_error, math.hypot(0.03, 0.03), atol=1e-12)
    assert rep.final_width["landmark"].median == pytest.approx(0.4)
    assert rep.final_width["pair"].max == pytest.approx(0.2)
    assert rep.empty_events == 1


def test_landmark_box_missing_truth_is_a_soundness_failure():
    r = example_result()
    r.landmarks.box[1, 0] += 1.0  # landmark 2's x interval moves 1 m right: truth outside
    rep = compute_report(r)
    assert rep.containment["landmark"].fraction == pytest.approx(2 / 3)
    assert rep.containment["landmark"].failures == ["landmark 2"]
    assert rep.soundness["landmark"] == FAILURE and not rep.sound
    assert rep.soundness["pair"] == SOUND
    text = render_text(rep)
    assert "2/3 = 0.6667  SOUNDNESS FAILURE" in text
    assert "truth outside: landmark 2" in text


def test_injected_and_relaxed_outliers_are_not_a_failure():
    r = example_result()
    r.landmarks.box[1, 0] += 1.0
    r.truth.outliers["observations"][4] = True
    rep = compute_report(r)
    assert rep.outliers_injected == 1 and rep.relaxed
    assert rep.soundness["landmark"] == RELAXED
    assert rep.outliers_by_stream == {"observations": 1} and rep.outliers_relaxed == {"observations": True}
    assert "outliers injected: 1 (observations 1: q-relaxed)" in render_text(rep)
    # ... but not when nothing was relaxed: the bounds are broken by the log, not by the method
    r.consistency.q = {"pair": 0}
    rep = compute_report(r)
    assert rep.soundness["landmark"] == BROKEN and not rep.relaxed
    assert "SOUNDNESS FAILURE" not in render_text(rep)


def test_odometry_outliers_are_not_relaxed_by_an_observation_q():
    """No q covers odometry: injected odometry outliers break the stated bounds, and a miss is
    reported as such, whatever q the observations had; a clean log's miss stays a failure."""
    r = example_result()
    r.landmarks.box[1, 0] += 1.0
    r.truth.outliers["observations"][:] = False
    r.truth.outliers["odometry"] = np.zeros(6, bool)
    r.truth.outliers["odometry"][2] = True
    rep = compute_report(r)
    assert r.consistency.q == {"pair": 1}
    assert rep.outliers_by_stream == {"odometry": 1} and not rep.relaxed
    assert rep.soundness["landmark"] == BROKEN and rep.soundness["pair"] == SOUND
    text = render_text(rep)
    assert "outliers injected: 1 (odometry 1: beyond the stated bounds, no q covers them)" in text
    assert "SOUNDNESS FAILURE" not in text
    j = report_dict(rep)
    assert j["outliers_by_stream"] == {"odometry": {"injected": 1, "q_relaxed": False}}
    r.truth.outliers["observations"][4] = True  # one of each: not every outlier is relaxed
    rep = compute_report(r)
    assert rep.outliers_relaxed == {"observations": True, "odometry": False} and rep.soundness["landmark"] == BROKEN
    r.truth.outliers["observations"][:] = False
    r.truth.outliers["odometry"][:] = False  # no outlier injected: a real failure
    assert compute_report(r).soundness["landmark"] == FAILURE


def test_pair_held_only_by_a_boundary_box_counts():
    r = example_result()
    p = r.pairs
    # pair 0: drop every box but the inner one (corner 0.03 off the truth): truth is outside it
    keep = np.ones(len(p.boxes), bool)
    keep[1:4] = False
    p.boxes, p.label = p.boxes[keep], p.label[keep]
    p.offsets = np.array([0, 1, 5, 9])
    rep = compute_report(r)
    assert rep.containment["pair"].contained == 2 and rep.containment["pair"].failures == ["pair (1,2)"]
    # the boundary box alone (the lower-left one) holds dl: contained
    r2 = example_result()
    keep = np.ones(len(r2.pairs.boxes), bool)
    keep[0:3] = False
    r2.pairs.boxes, r2.pairs.label = r2.pairs.boxes[keep], r2.pairs.label[keep]
    r2.pairs.offsets = np.array([0, 1, 5, 9])
    assert compute_report(r2).containment["pair"].fraction == 1.0


def test_pair_with_empty_set_is_not_contained():
    r = example_result()
    p = r.pairs
    p.boxes, p.label = p.boxes[4:], p.label[4:]
    p.offsets = np.array([0, 0, 4, 8])
    rep = compute_report(r)
    assert rep.containment["pair"].failures == ["pair (1,2)"]
    assert np.isnan(pair_hulls(p)[0]).sum() == 0 and np.isinf(pair_hulls(p)[0]).all()
    assert rep.final_width["pair"].empty == 1


def test_relative_map_is_checked_relative_to_its_reference():
    r = example_result()
    ref = np.array(TRUE_LANDMARKS[2])
    r.landmarks.reference_id = 2
    assert compute_report(r).containment["landmark"].fraction == pytest.approx(0.0)
    r.landmarks.box = r.landmarks.box - ref[None, :, None]
    assert compute_report(r).containment["landmark"].fraction == 1.0


def test_pose_box_is_checked_at_its_own_stamp():
    r = example_result()
    r.poses.box[2, 0] = [2.25, 2.3]  # the truth at t = 2 s has x = 2.0
    rep = compute_report(r)
    assert rep.containment["pose"].failures == ["pose 2 at t=2"]
    assert rep.containment["pose"].contained == 5


def test_pose_between_truth_samples_meets_their_hull():
    """A pose stamp between two truth samples: the box must meet the hull of the two samples
    (the truth is only known there), and missing it is a failure."""
    from ivslam_cli.logs.model import GroundTruth
    from ivslam_cli.report.core import pose_containment
    from ivslam_cli.results.model import Poses

    truth = GroundTruth(pose_stamp=np.array([0.0, 0.4]), pose=np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.2]]))
    for x, th, ok in (([0.7, 0.8], [0.15, 0.16], 1), ([0.95, 1.2], [0.19, 0.3], 1),
                      ([1.01, 1.2], [0.1, 0.11], 0), ([0.5, 0.6], [0.21, 0.3], 0)):
        poses = Poses(stamp=np.array([0.2]), box=np.array([[x, [-0.1, 0.1], th]], float))
        c = pose_containment(poses, truth)
        assert (c.checked, c.contained) == (1, ok), (x, th)
    gap = GroundTruth(pose_stamp=np.array([0.0, 2.0]), pose=truth.pose)  # a gap > MAX_TRUTH_GAP
    c = pose_containment(Poses(stamp=np.array([1.0]), box=np.array([[[5.0, 6.0], [5.0, 6.0], [0.0, 0.1]]])), gap)
    assert (c.checked, c.not_checked) == (0, 1)


def test_pose_heading_wraps_around():
    r = example_result()
    r.truth.pose[:, 2] = 0.1 + 2 * np.pi  # the same heading, one turn later
    assert compute_report(r).containment["pose"].fraction == 1.0
    r.truth.pose[2, 2] = 0.1 + np.pi  # the sample at t = 1 s
    assert compute_report(r).containment["pose"].contained == 5


def test_pose_between_truth_samples_across_the_cut_uses_the_near_branch():
    """Two truth samples on either side of ±π: a pose box between them, at the cut, meets
    their hull on the circle (not the hull the long way round)."""
    from ivslam_cli.logs.model import GroundTruth
    from ivslam_cli.report.core import pose_containment
    from ivslam_cli.results.model import Poses

    truth = GroundTruth(pose_stamp=np.array([0.0, 0.2]), pose=np.array([[0.5, 0.5, 3.1], [0.5, 0.5, -3.1]]))
    for th in ([3.13, 3.15], [-3.15, -3.13], [3.0, 3.11], [-3.11, -3.0], [3.1, 3.2]):
        poses = Poses(stamp=np.array([0.1]), box=np.array([[[0.0, 1.0], [0.0, 1.0], th]]))
        assert pose_containment(poses, truth).contained == 1, th
    poses = Poses(stamp=np.array([0.1]), box=np.array([[[0.0, 1.0], [0.0, 1.0], [-0.1, 0.1]]]))  # the far side
    assert pose_containment(poses, truth).contained == 0


def test_truth_outside_the_time_span_is_not_checked():
    r = example_result()
    r.truth.pose_stamp = r.truth.pose_stamp + 1.0  # the first pose box before the truth's span
    c = compute_report(r).containment["pose"]
    assert c.not_checked == 1 and c.checked == 5


@settings(max_examples=examples(ci=200))
@given(
    lo=st.floats(-20, 20),
    w=st.floats(0, 8),
    theta=st.floats(-20, 20),
)
def test_angle_in_matches_a_brute_force_search(lo, w, theta):
    hi = lo + w
    brute = any(lo <= theta + 2 * math.pi * n <= hi for n in range(-10, 11))
    assert bool(angle_in(lo, hi, theta)) == brute


def test_convergence_summary_and_increases():
    h = WidthHistory(
        entity=np.array([[1, 2]] * 4 + [[1, 3]] * 3),
        step=np.array([0, 1, 2, 3, 0, 2, 4]),
        stamp=np.zeros(7),
        width=np.array([4.0, 2.0, 3.0, 1.0, 8.0, 2.0, 0.5]),
    )
    cv = convergence(h)
    assert cv.entities == 2 and cv.updates == 7
    assert cv.initial.median == 6.0 and cv.initial.max == 8.0
    assert cv.final.median == 0.75 and cv.final.max == 1.0
    assert cv.increases == 1  # 2.0 -> 3.0 for pair (1,2)
    assert cv.curve_step.tolist() == [0, 1, 2, 3, 4]
    assert cv.curve_median.tolist() == [6.0, 2.0, 2.5, 1.0, 0.5]


def test_no_truth_means_no_containment():
    r = example_result()
    r.truth = None
    rep = compute_report(r)
    assert rep.containment == {} and rep.sound
    assert "no ground truth" in render_text(rep)
    assert report_dict(rep)["containment"] == {}


# ----------------------------------------------------------------- the command
@pytest.fixture
def result_file(tmp_path):
    def make(r=None, name="r.h5"):
        path = tmp_path / name
        write_result(path, r if r is not None else example_result())
        return path

    return make


def test_cli_text(cli_run, result_file):
    res = cli_run("report", result_file())
    assert res.exit_code == 0, res.output
    out = res.output
    assert "mode pairs" in out and "range_abs=0.1" in out and "bearing=0.0175" in out
    assert "1 empty event" in out and "EMPTY step 3 t=1.5 pair_intersection pair (1,3) measurement 7" in out
    assert "landmark  3/3 = 1.0000  ok" in out
    assert "initial median 0.8, max 0.8 → final median 0.2, max 0.2" in out
    assert "SOUNDNESS FAILURE" not in out


def test_cli_json_keys_and_values(cli_run, result_file):
    r = example_result()
    r.landmarks.box[0, 1] = [10.0, 11.0]  # landmark 1's y interval no longer holds y = 1
    res = cli_run("report", result_file(r), "--json")
    assert res.exit_code == 0, res.output
    j = json.loads(res.output)
    for key in ("mode", "empty_events", "containment", "final_width", "runtime_s"):
        assert key in j
    assert j["mode"] == "pairs" and j["runtime_s"] == 0.25 and j["empty_events"] == 1
    assert j["containment"]["landmark"] == pytest.approx(2 / 3)
    assert j["containment"]["pair"] == 1.0 and j["containment"]["pose"] == 1.0
    assert j["soundness"]["landmark"] == FAILURE and j["sound"] is False
    assert j["containment_detail"]["landmark"]["failures"] == ["landmark 1"]
    assert j["final_width"]["pair"]["median"] == pytest.approx(0.2)
    assert j["final_width"]["landmark"]["max"] == pytest.approx(1.0)
    assert j["empty_event_list"][0]["entity"] == [1, 3]
    assert j["q"] == {"pair": 1} and j["config"]["bounds"]["range_abs"] == 0.1
    assert j["map"]["cells"] == {"unknown": 9, "empty": 6, "obstacle": 5}


@pytest.mark.parametrize("suffix, magic", [(".png", b"\x89PNG\r\n\x1a\n"), (".svg", b"<?xml")])
def test_cli_plot(cli_run, result_file, tmp_path, suffix, magic):
    out = tmp_path / f"fig{suffix}"
    res = cli_run("report", result_file(), "--plot", out)
    assert res.exit_code == 0, res.output
    data = out.read_bytes()
    assert data.startswith(magic) and len(data) > 5000
    if suffix == ".svg":
        assert b"<svg" in data
    # refuses to clobber it, keeps it
    res = cli_run("report", result_file(name="r2.h5"), "--plot", out)
    assert res.exit_code != 0 and "--force" in res.output
    assert out.read_bytes() == data


def test_cli_plot_bad_suffix(cli_run, result_file, tmp_path):
    res = cli_run("report", result_file(), "--plot", tmp_path / "fig.bmp")
    assert res.exit_code != 0 and "use .png or .svg" in res.output and "Traceback" not in res.output


def test_cli_plot_without_truth_or_grid(cli_run, tmp_path):
    r = example_result(with_grid=False)
    r.truth = None
    write_result(tmp_path / "r.h5", r)
    res = cli_run("report", tmp_path / "r.h5", "--plot", tmp_path / "f.png")
    assert res.exit_code == 0 and (tmp_path / "f.png").stat().st_size > 0


def test_cli_help_has_example(cli_run):
    res = cli_run("report", "--help")
    assert res.exit_code == 0 and "  ivslam report result.h5" in res.output


def test_plot_with_no_inner_boxes(tmp_path):
    """A pair subpaving with only boundary boxes (no inner layer) still plots."""
    from ivslam_cli.report.core import compute_report
    from ivslam_cli.report.plot import plot_report
    from ivslam_cli.results.example import example_result
    from ivslam_cli.results.model import LABEL_BOUNDARY

    r = example_result()
    if r.pairs is not None:
        r.pairs.label[:] = LABEL_BOUNDARY
    plot_report(compute_report(r), tmp_path / "p.png")
    assert (tmp_path / "p.png").stat().st_size > 0


def test_angle_in_requires_both_bounds():
    """Regression: a heading a subnormal below [0, 0] is not inside it (the quotient underflows)."""
    from ivslam_cli.report.core import angle_in

    assert not bool(angle_in(0.0, 0.0, -5e-324))
    assert bool(angle_in(0.0, 0.0, 0.0))
    assert bool(angle_in(6.0, 7.0, 6.5 - 2 * math.pi))


def test_plot_draws_the_truth_in_the_result_frame_and_the_anchor_graph():
    """A first-pose-frame result: the walls are drawn where the report compares them (the
    truth relative to its pose at the origin stamp), and the anchor graph's chain and loop
    edges between the anchors' box centres."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    from ivslam_cli.report.core import truth_in_frame
    from ivslam_cli.report.plot import _draw_map
    from ivslam_cli.results.model import FRAME_FIRST_POSE, Loops, Submaps

    r = example_result("lidar")
    r.truth.world = np.array([[0.0, 5.0, 4.0, 5.0]])
    r.poses.frame, r.poses.origin_stamp = FRAME_FIRST_POSE, float(r.truth.pose_stamp[2])
    a = np.zeros((3, 3, 2))
    a[:, 0] = [[0, 0.1], [1, 1.1], [2, 2.1]]
    r.submaps = Submaps(anchor=np.array([0, 2, 4]), anchor_box=a, resolution=0.25, origin=np.zeros((3, 2)),
                        shape=np.zeros((3, 2), np.int64), state=np.zeros(0, np.uint8),
                        member_offsets=np.zeros(4, np.int64), member_row=np.zeros(0, np.int64),
                        member_box=np.zeros((0, 3, 2)), member_mapped=np.zeros(0, bool))
    z = np.zeros(0, np.int64)
    r.loops = Loops(row=z, submap=z, home=z, prior=np.zeros((0, 3, 2)), box=np.zeros((0, 3, 2)), beams=z,
                    empty=np.zeros(0, bool), edge_a=np.array([0, 1, 0]), edge_b=np.array([1, 2, 2]),
                    edge_box=np.zeros((3, 3, 2)), edge_kind=np.array([0, 0, 1]), anchor_box_open=a.copy())
    ax = Figure().subplots()
    _draw_map(ax, compute_report(r))
    framed = truth_in_frame(r.poses, r.truth).world[0]
    drawn = [ln.get_xydata() for ln in ax.get_lines() if ln.get_color() == "tab:red" and len(ln.get_xydata()) == 2]
    assert any(np.allclose(d.reshape(-1), framed[[0, 1, 2, 3]]) for d in drawn)
    edges = {c.get_label(): len(c.get_segments()) for c in ax.collections if isinstance(c, LineCollection)}
    assert edges == {"anchor graph: chain edges (2)": 2, "loop edges (1)": 1}
