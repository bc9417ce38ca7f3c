"""Interval scan matching (``slam/lidar_scanmatch.py``): the relative pose of two scans.

Soundness on simulated scans (ray-cast in the built-in worlds, with the stated gap
assumption): the true relative pose stays in the contracted box, with and without outliers
(q). Tightness: with the URG-04LX datasheet bounds the box shrinks well below a typical
odometry box; with cones that leave gaps and no assumption nothing is excluded.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.slam.lidar.map_update import LidarBounds
from ivslam_cli.slam.lidar.scanmatch import covered_free, match_scan
from ivslam_cli.simulate import SimConfig, simulate
from tests.helpers.hyp import examples

WORLDS = ("rooms", "corridor", "pillars", "open")
_LOGS: dict = {}


def _log(world: str, seed: int, tight: bool):
    key = (world, seed, tight)
    if key not in _LOGS:
        b = {"range_abs": 0.01, "range_rel": 0.005} if tight else {}
        _LOGS[key] = simulate(SimConfig(scenario="lidar", world=world, sensor="urg-04lx", seed=seed, steps=40,
                                        bounds=b, beam_model="ray"))  # rays: _bounds' bearing 0
    return _LOGS[key]


def _bounds(log, fill=True) -> LidarBounds:
    a, r = log.bounds["range_abs"], log.bounds["range_rel"]  # true-range convention -> the kernels'
    return LidarBounds(a / (1 - r) * (1 + 1e-12), r / (1 - r) * (1 + 1e-12), 0.0, fill_gaps=fill)


def _relative(log, j: int, k: int) -> np.ndarray:
    p = log.truth.pose
    d = p[k] - p[j]
    c, s = math.cos(p[j, 2]), math.sin(p[j, 2])
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], d[2]])


def _inside(box, t) -> bool:
    th = box[4] + np.mod(t[2] - box[4], 2 * math.pi)
    return bool(box[0] <= t[0] <= box[1] and box[2] <= t[1] <= box[3] and th <= box[5])


@given(st.sampled_from(WORLDS), st.integers(0, 3), st.booleans(), st.integers(0, 30), st.integers(1, 9),
       st.floats(0.02, 0.3), st.floats(0.01, 0.15), st.floats(0, 1), st.floats(0, 1), st.floats(0, 1),
       st.integers(0, 3), st.sampled_from([1, 2, 4]))
@settings(max_examples=examples(ci=120))
def test_the_true_relative_pose_stays_in_the_box(world, seed, tight, j, dk, hxy, hth, fx, fy, ft, q, stride):
    log = _log(world, seed, tight)
    k = j + dk
    t = _relative(log, j, k)
    lo = t - 2 * np.array([hxy, hxy, hth]) * np.array([fx, fy, ft])
    hi = lo + 2 * np.array([hxy, hxy, hth])
    lo, hi = np.minimum(lo, t), np.maximum(hi, t)  # rounding must not leave the truth out of the box
    box = np.array([lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]])
    assert _inside(box, t)
    out, kept, tested = match_scan(log.scans, j, k, box, _bounds(log), q=q, stride=stride, max_boxes=240)
    assert kept > 0, "the true relative pose was excluded"
    assert _inside(out, t)
    assert np.all(out[0::2] >= box[0::2]) and np.all(out[1::2] <= box[1::2])


def test_outlier_beams_within_q_keep_the_truth():
    log = _log("rooms", 1, True)
    j, k = 10, 16
    sc = log.scans
    b0, b1 = int(sc.offsets[k]), int(sc.offsets[k + 1])
    r = sc.ranges.copy()
    idx = np.arange(b0, b1)[sc.valid[b0:b1]][::97][:4]  # 4 beams of k cut short: "a person"
    r[idx] = np.maximum(r[idx] * 0.5, 0.1)
    bad = replace(sc, ranges=r)
    t = _relative(log, j, k)
    box = np.array([t[0] - 0.15, t[0] + 0.15, t[1] - 0.15, t[1] + 0.15, t[2] - 0.08, t[2] + 0.08])
    out, kept, _ = match_scan(bad, j, k, box, _bounds(log), q=4, stride=1, max_boxes=600)
    assert kept > 0 and _inside(out, t)


def test_matching_contracts_with_datasheet_bounds():
    """URG-04LX within 1 cm + 0.5 %: a ±15 cm / ±0.08 rad box (odometry over ~1 m) comes out
    at most half as wide in each of x, y and θ (median over pairs), the truth inside."""
    log = _log("rooms", 2, True)
    ratios = []
    for j in range(0, 30, 5):
        k = j + 8
        t = _relative(log, j, k)
        box = np.array([t[0] - 0.15, t[0] + 0.15, t[1] - 0.15, t[1] + 0.15, t[2] - 0.08, t[2] + 0.08])
        out, kept, _ = match_scan(log.scans, j, k, box, _bounds(log), q=2, stride=2, max_boxes=1200)
        assert kept > 0 and _inside(out, t)
        ratios.append((out[1::2] - out[0::2]) / (box[1::2] - box[0::2]))
    med = np.median(np.array(ratios), axis=0)
    assert np.all(med <= 0.5), med


def test_cones_with_gaps_prove_nothing_without_the_assumption():
    log = _log("rooms", 0, True)
    t = _relative(log, 5, 12)
    box = np.array([t[0] - 0.3, t[0] + 0.3, t[1] - 0.3, t[1] + 0.3, t[2] - 0.3, t[2] + 0.3])
    out, kept, _ = match_scan(log.scans, 5, 12, box, _bounds(log, fill=False), q=0, max_boxes=200)
    assert kept > 0 and np.array_equal(out, box)


def test_covered_free_needs_every_bracketing_beam():
    f = np.array([2.0, 2.0, 2.0, 0.5, 2.0, 2.0, -1.0, 2.0])
    a0, inc = -0.35, 0.1  # beams at -0.35, -0.25, ..., 0.35
    assert covered_free(f, a0, inc, -0.34, -0.16, 1.9)  # beams 0..2
    assert not covered_free(f, a0, inc, -0.34, -0.16, 2.0)  # not strictly nearer
    assert not covered_free(f, a0, inc, -0.1, -0.04, 1.0)  # beam 3 is short
    assert covered_free(f, a0, inc, -0.1, -0.04, 0.4)
    assert not covered_free(f, a0, inc, 0.2, 0.26, 0.4)  # beam 6 invalid
    assert not covered_free(f, a0, inc, -0.4, -0.3, 0.1)  # before the first beam: unknown
    assert not covered_free(f, a0, inc, 0.3, 0.4, 0.1)  # after the last
    # bearings one turn away are the same directions
    assert covered_free(f, a0, inc, -0.34 + 2 * math.pi, -0.16 + 2 * math.pi, 1.9)
    assert not covered_free(f, a0, inc, -1.0, 6.0, 0.1)  # a whole turn


@pytest.mark.parametrize("bad", ["heading", "x"])
def test_a_wrong_box_is_excluded(bad):
    """A box around a wrong relative pose (0.4 rad or 0.5 m off) contradicts the scans: the
    test can fail."""
    log = _log("rooms", 2, True)
    j, k = 5, 13
    t = _relative(log, j, k) + (np.array([0.0, 0.0, 0.4]) if bad == "heading" else np.array([0.5, 0.0, 0.0]))
    box = np.array([t[0] - 0.05, t[0] + 0.05, t[1] - 0.05, t[1] + 0.05, t[2] - 0.02, t[2] + 0.02])
    out, kept, _ = match_scan(log.scans, j, k, box, _bounds(log), q=2, stride=2, max_boxes=600)
    assert kept == 0
