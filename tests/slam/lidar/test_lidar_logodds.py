"""The log-odds baseline of the LiDAR pipeline (``slam/lidar_logodds.py``) and its comparison
with the interval map: the kernel on scans whose cells are known by construction, the ray
traversal against the geometry (hypothesis), the disagreement codes, the HDF5 part, the report
(text, JSON, plot) and ``ivslam run --mode lidar`` on a sample and on a real log."""

from __future__ import annotations

import json
import math

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.cli import cli as main
from ivslam_cli.errors import IvslamError
from ivslam_cli.logs.model import Scans
from ivslam_cli.report.core import compute_report
from ivslam_cli.report.jsonout import report_dict
from ivslam_cli.report.plot import plot_report
from ivslam_cli.report.text import render_text
from ivslam_cli.results.example import example_result
from ivslam_cli.results.hdf5 import read_result, write_result
from ivslam_cli.results.model import CELL_EMPTY, CELL_OBSTACLE, CELL_UNKNOWN, LogOddsGrid, MapGrid
from ivslam_cli.slam.lidar.logodds import (
    DIS_EMPTY_OCCUPIED,
    DIS_NONE,
    DIS_OBSTACLE_FREE,
    DIS_UNKNOWN_OCCUPIED,
    L_FREE,
    L_MAX,
    L_MIN,
    L_OCC,
    build_logodds,
    compare,
    laser_centres,
)
from tests.helpers.hyp import examples, lanes
from tests.helpers.paths import CONFIGS, SAMPLE_LOGS as SAMPLES
from tests.helpers.results import assert_same


def make_scans(ranges, valid=None, angle_min=0.0, inc=math.pi / 2, mount=(0.0, 0.0, 0.0), repeat=1) -> Scans:
    r = np.tile(np.asarray(ranges, np.float32), repeat)
    v = np.ones(r.shape, bool) if valid is None else np.tile(np.asarray(valid, bool), repeat)
    n, s = len(ranges), repeat
    return Scans(stamp=np.arange(s, dtype=float), angle_min=np.full(s, angle_min), angle_increment=np.full(s, inc),
                 range_min=np.zeros(s), range_max=np.full(s, 100.0), offsets=np.arange(s + 1) * n, ranges=r,
                 valid=v, mount=mount)


def grid(h, w, origin=(0.0, 0.0), res=1.0, state=None) -> MapGrid:
    st_ = np.zeros((h, w), np.uint8) if state is None else np.asarray(state, np.uint8)
    return MapGrid(origin=np.asarray(origin, float), resolution=res, state=st_)


# ---------------------------------------------------------------- the kernel
def test_hand_made_scan_cells_known_by_construction():
    """Robot box centre (1.5, 2.5, π/2), laser mounted 1 m ahead and turned −π/2: the laser at
    (1.5, 3.5) facing +x. Beams at 0, π/2, π, 3π/2: 4 m along +x, 2 m along +y, 30 m along −x
    (leaves the grid: no return cell), and an invalid one."""
    box = np.array([[[1.0, 2.0], [2.0, 3.0], [math.pi / 2 - 0.1, math.pi / 2 + 0.1]]])
    sc = make_scans([4.0, 2.0, 30.0, 1.0], valid=[True, True, True, False], mount=(1.0, 0.0, -math.pi / 2))
    assert np.allclose(laser_centres(box, sc.mount), [[1.5, 3.5, 0.0]])
    lo = build_logodds(sc, [0], box, grid(6, 12))
    want = np.zeros((6, 12))
    want[3, 1] = 3 * L_FREE  # the laser's cell, crossed by the three valid beams
    want[3, 2:5] = L_FREE  # +x beam
    want[3, 5] = L_OCC
    want[4, 1] = L_FREE  # +y beam
    want[5, 1] = L_OCC
    want[3, 0] = L_FREE  # −x beam: crossed, leaves the grid, no return inside
    assert lo.value.dtype == np.float32
    assert np.array_equal(lo.value, want.astype(np.float32))
    assert (lo.scans, lo.beams) == (1, 3)
    assert (lo.l_occ, lo.l_free, lo.l_min, lo.l_max) == (L_OCC, L_FREE, L_MIN, L_MAX)


def test_clamped_and_scans_in_order():
    box = np.array([[[1.5, 1.5], [3.5, 3.5], [0.0, 0.0]]] * 20)
    sc = make_scans([4.0, 2.0], repeat=20)
    lo = build_logodds(sc, np.arange(20), box, grid(6, 12))
    assert lo.value[3, 5] == L_MAX and lo.value[5, 1] == L_MAX  # return cells, clamped
    assert lo.value[3, 1] == L_MIN and lo.value[3, 3] == L_MIN  # crossed cells, clamped
    assert (lo.scans, lo.beams) == (20, 40)
    # a subset of the scans: only those go in
    lo2 = build_logodds(sc, [3], box[:1], grid(6, 12))
    assert lo2.value[3, 5] == np.float32(L_OCC) and lo2.beams == 2


def test_empty_or_unbounded_boxes_are_skipped():
    sc = make_scans([4.0], repeat=2)
    box = np.array([[[np.inf, -np.inf], [0.0, 1.0], [0.0, 0.0]], [[0.0, np.inf], [0.0, 1.0], [0.0, 0.0]]])
    lo = build_logodds(sc, [0, 1], box, grid(6, 12))
    assert not lo.value.any() and (lo.scans, lo.beams) == (0, 0)


def test_bad_arguments():
    sc = make_scans([4.0])
    box = np.zeros((1, 3, 2))
    with pytest.raises(ValueError, match="pose boxes"):
        build_logodds(sc, [0, 0], box, grid(2, 2))
    with pytest.raises(ValueError, match="out of range"):
        build_logodds(sc, [1], box, grid(2, 2))
    with pytest.raises(ValueError, match="l_free < 0 < l_occ"):
        build_logodds(sc, [0], box, grid(2, 2), l_free=0.2)


def _meets(x0, y0, x1, y1, cx, cy, tol=1e-9) -> bool:
    """Does the segment meet the closed unit cell [cx, cx+1] × [cy, cy+1] (within tol)?"""
    t0, t1 = 0.0, 1.0
    x0, y0, cx, cy = float(x0), float(y0), float(cx), float(cy)  # Python floats: q / p for a tiny p is inf, no warning
    dx, dy = float(x1) - x0, float(y1) - y0
    for p, q in ((-dx, x0 - (cx - tol)), (dx, cx + 1 + tol - x0), (-dy, y0 - (cy - tol)), (dy, cy + 1 + tol - y0)):
        if p == 0:
            if q < 0:
                return False
        elif p < 0:
            t0 = max(t0, q / p)
        else:
            t1 = min(t1, q / p)
    return t0 <= t1


coord = st.floats(-3.0, 13.0, allow_nan=False)


@given(coord, st.floats(-3.0, 9.0), coord, st.floats(-3.0, 9.0))
@settings(max_examples=examples(ci=300))
def test_ray_traversal_is_the_cells_the_segment_meets(x0, y0, x1, y1):
    """One beam from (x0, y0) to (x1, y1) on a 12 × 6 grid at the origin (either end may be
    outside): every updated cell meets the segment, every cell a fine sampling of the segment
    inside the grid falls in is updated, the return cell (if in the grid) gets l_occ and the
    others l_free once each."""
    r = math.hypot(x1 - x0, y1 - y0)
    a = math.atan2(y1 - y0, x1 - x0)
    sc = make_scans([r], angle_min=a, inc=0.0)
    box = np.array([[[x0, x0], [y0, y0], [0.0, 0.0]]])
    g = grid(6, 12)
    v = build_logodds(sc, [0], box, g).value
    # where the kernel put the end (its own cos/sin), for the expectations below
    ex, ey = x0 + float(np.float32(r)) * math.cos(a), y0 + float(np.float32(r)) * math.sin(a)
    end = (math.floor(ey), math.floor(ex))
    end_in = 0 <= end[0] < 6 and 0 <= end[1] < 12
    touched = {tuple(rc) for rc in np.argwhere(v != 0)}
    for iy, ix in touched:
        assert _meets(x0, y0, ex, ey, ix, iy), (iy, ix)
        want = L_OCC if end_in and (iy, ix) == end else L_FREE
        assert v[iy, ix] == np.float32(want), (iy, ix, v[iy, ix])
    if end_in:
        assert end in touched
    t = np.linspace(0.0, 1.0, 20001)
    px, py = x0 + t * (ex - x0), y0 + t * (ey - y0)
    cells = np.floor(np.column_stack([py, px])).astype(int)
    inside = (cells[:, 0] >= 0) & (cells[:, 0] < 6) & (cells[:, 1] >= 0) & (cells[:, 1] < 12)
    # a sample within 1e-7 of a cell border may be on either side: not a test of the kernel
    firm = (np.abs(px - np.round(px)) > 1e-7) & (np.abs(py - np.round(py)) > 1e-7)
    sampled = {tuple(c) for c in cells[inside & firm]}
    assert sampled <= touched, sampled - touched


# ---------------------------------------------------------------- the comparison
def test_comparison_codes_and_counts():
    st_ = np.array([[CELL_EMPTY, CELL_EMPTY, CELL_EMPTY, CELL_OBSTACLE],
                    [CELL_OBSTACLE, CELL_OBSTACLE, CELL_UNKNOWN, CELL_UNKNOWN],
                    [CELL_UNKNOWN, CELL_EMPTY, CELL_OBSTACLE, CELL_UNKNOWN]], np.uint8)
    val = np.array([[1.2, -0.4, 0.0, 2.0],
                    [-0.4, 0.85, 0.3, -2.0],
                    [0.0, 0.0001, 0.0, 0.0]], np.float32)
    g = grid(3, 4, state=st_)
    lo = LogOddsGrid(value=val, l_occ=L_OCC, l_free=L_FREE, l_min=L_MIN, l_max=L_MAX)
    d = compare(g, lo)
    want = np.array([[DIS_EMPTY_OCCUPIED, DIS_NONE, DIS_NONE, DIS_NONE],
                     [DIS_OBSTACLE_FREE, DIS_NONE, DIS_UNKNOWN_OCCUPIED, DIS_NONE],
                     [DIS_NONE, DIS_EMPTY_OCCUPIED, DIS_NONE, DIS_NONE]], np.uint8)
    assert np.array_equal(d.code, want) and d.code.dtype == np.uint8
    assert d.counts() == {"empty_occupied": 2, "unknown_occupied": 1, "occupied_outside_obstacle": 3,
                          "obstacle_free": 1}
    assert d.logodds_cells == {"occupied": 5, "free": 3, "unknown": 4}
    assert d.interval_cells == {"empty": 4, "obstacle": 4, "unknown": 4}
    with pytest.raises(ValueError, match="differ"):
        compare(grid(2, 4), lo)


# ---------------------------------------------------------------- result, HDF5, report
def lidar_example():
    """The example result as a lidar result with a log-odds grid on its map grid."""
    r = example_result("lidar")
    r.pairs = None
    rng = np.random.default_rng(7)
    v = rng.choice([-1.0, 0.0, 0.85, 5.0], size=r.grid.state.shape).astype(np.float32)
    r.logodds = LogOddsGrid(value=v, l_occ=L_OCC, l_free=L_FREE, l_min=L_MIN, l_max=L_MAX, scans=4, beams=123)
    r.validate()
    return r


def test_hdf5_round_trip_and_old_files(tmp_path):
    r = lidar_example()
    path = tmp_path / "r.h5"
    write_result(path, r)
    with h5py.File(path, "r") as f:
        g = f["logodds"]
        assert g["value"].dtype == np.float32 and g["value"].chunks is not None
        assert g["value"].compression == "gzip" and bool(g.attrs["guaranteed"]) is False
    assert_same(r, read_result(path))
    # a file written before the log-odds part existed: no /logodds group, still reads
    with h5py.File(path, "a") as f:
        del f["logodds"]
    old = read_result(path)
    assert old.logodds is None and old.grid is not None
    assert "log-odds" not in render_text(compute_report(old))
    assert "logodds" not in report_dict(compute_report(old))["map"]


def test_hdf5_log_odds_of_the_wrong_shape_is_corrupt(tmp_path):
    r = lidar_example()
    path = tmp_path / "r.h5"
    write_result(path, r)
    with h5py.File(path, "a") as f:
        del f["logodds/value"]
        f["logodds"].create_dataset("value", data=np.zeros((2, 2), np.float32))
    with pytest.raises(IvslamError, match="corrupt") as exc:
        read_result(path)
    assert "\n" not in str(exc.value) and "r.h5" in str(exc.value)


def test_validate_rejects_a_mismatched_log_odds_grid():
    r = lidar_example()
    r.logodds.value = r.logodds.value.astype(np.float64)
    with pytest.raises(ValueError, match="float32"):
        r.validate()
    r = lidar_example()
    r.grid = None
    with pytest.raises(ValueError, match="needs the map grid"):
        r.validate()


def test_report_text_and_json_carry_the_comparison():
    r = lidar_example()
    d = compare(r.grid, r.logodds)
    rep = compute_report(r)
    text = render_text(rep)
    lc = d.logodds_cells
    assert "log-odds:   NOT guaranteed" in text
    assert f"occupied {lc['occupied']}, free {lc['free']}, unknown {lc['unknown']} cells" in text
    assert f"(a) {d.empty_occupied} proven-free cells" in text
    assert f"(b) {d.occupied_outside_obstacle} occupied cells" in text
    assert f"(c) {d.obstacle_free} interval-obstacle cells" in text
    j = json.loads(json.dumps(report_dict(rep)))
    lo = j["map"]["logodds"]
    assert lo["guaranteed"] is False and lo["scans"] == 4 and lo["beams"] == 123
    assert lo["cells"] == lc and lo["disagreement"] == d.counts()
    assert lo["model"] == {"l_occ": L_OCC, "l_free": L_FREE, "l_min": L_MIN, "l_max": L_MAX}
    assert sum(lc.values()) == r.grid.state.size


@pytest.mark.parametrize("suffix", lanes([".png", ".svg"], fast=[".png"]))
def test_plot_draws_both_maps_and_the_disagreement(tmp_path, suffix):
    r = lidar_example()
    rep = compute_report(r)
    assert rep.disagreement["empty_occupied"] > 0 and rep.disagreement["obstacle_free"] > 0
    path = tmp_path / f"fig{suffix}"
    plot_report(rep, path)
    data = path.read_bytes()
    assert len(data) > 5000
    if suffix == ".svg":  # matplotlib keeps each text as a comment beside its paths
        text = data.decode()
        assert "log-odds at the pose-box centres (NOT guaranteed)" in text
        assert "(a) proven free, log-odds occupied" in text and "(c) interval obstacle, log-odds free" in text
        assert "widths over time" in text
    else:
        assert data.startswith(b"\x89PNG\r\n\x1a\n")


# ---------------------------------------------------------------- end to end
def test_cli_run_and_report_on_the_lidar_sample(tmp_path):
    out = tmp_path / "r.h5"
    r = CliRunner().invoke(main, ["run", str(SAMPLES / "lidar_rooms.h5"), "--mode", "lidar",
                                  "--initial-pose-from-truth", "-o", str(out)])
    assert r.exit_code == 0, r.output
    res = read_result(out)
    lo, s = res.logodds, res.stats
    assert lo is not None and lo.value.shape == res.grid.state.shape
    # per submap, from the same scans as its interval map: a scan in two submaps counts twice
    mapped = int(res.submaps.member_mapped.sum())
    assert lo.scans == mapped >= s["scans_mapped"] and lo.beams >= s["valid_beams_mapped"] > 0
    assert (lo.value > 0).any() and (lo.value < 0).any()
    r = CliRunner().invoke(main, ["report", str(out), "--plot", str(tmp_path / "fig.png")])
    assert r.exit_code == 0, r.output
    assert "log-odds:   NOT guaranteed" in r.output and "disagree:   (a)" in r.output
    r = CliRunner().invoke(main, ["report", str(out), "--json"])
    j = json.loads(r.output)["map"]["logodds"]
    d = compare(res.grid, lo)
    assert j["disagreement"] == d.counts() and j["cells"] == d.logodds_cells


@pytest.mark.datasets
def test_real_log_aces_with_known_poses(datasets, tmp_path):
    """ACES (SICK, 180 beams, GMapping-corrected poses ± 5 cm): the log-odds map at the box
    centres mostly agrees with the interval map; its occupied cells in proven-free space (a)
    are a small fraction of that space."""
    path = datasets / "carmen_corrected" / "aces-corrected.log.gz"
    if not path.exists():
        pytest.skip(f"dataset not present: {path}")
    out = tmp_path / "r.h5"
    r = CliRunner().invoke(main, ["run", str(path), "--mode", "lidar", "--poses-known", "--config",
                                  str(CONFIGS / "carmen_corrected.toml"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    res = read_result(out)
    lo, s = res.logodds, res.stats
    assert lo.scans == s["scans_mapped"] and lo.beams == s["valid_beams_mapped"]
    d = compare(res.grid, lo)
    free_cells = d.interval_cells["empty"]
    occ = d.logodds_cells["occupied"]
    print(f"\nACES: interval empty {free_cells} cells ({free_cells * res.grid.resolution ** 2:.1f} m²), "
          f"obstacle {d.interval_cells['obstacle']}; log-odds occupied {occ}, free {d.logodds_cells['free']}; "
          f"disagreement {d.counts()}")
    assert free_cells > 0 and occ > 0
    # (a): the probabilistic map contradicts the proof in well under 1 % of the proven-free cells
    assert d.empty_occupied < 0.01 * free_cells
    # most cells log-odds calls occupied are in the interval map's (outer) obstacle set
    assert d.occupied_outside_obstacle < 0.5 * occ
    # log-odds free space covers the proven-free cells it was built from: the rays at the box
    # centres cross nearly all of them
    assert np.count_nonzero((lo.value < 0) & (res.grid.state == CELL_EMPTY)) > 0.9 * free_cells
    r = CliRunner().invoke(main, ["report", str(out), "--json"])
    assert json.loads(r.output)["map"]["logodds"]["disagreement"] == d.counts()
