"""Every LiDAR / landmark dataset in ../shared/datasets, checked against independent readings
(README numbers, or one line parsed by hand here)."""

from __future__ import annotations

import lzma
import math

import numpy as np
import pytest

from ivslam_cli.logs import read_log

pytestmark = pytest.mark.datasets


def _reasons(log):
    return {(d.stream, d.reason): d.count for d in log.provenance.dropped}


def test_ros2_db3_dir_and_mcap_agree(datasets):
    d = datasets / "ros2_turtlebot4_comprobo22" / "macfirst_floor_take_2"
    a = read_log(d)
    b = read_log(d / "macfirst_floor_take_2_0.db3")
    c = read_log(datasets / "mcap_turtlebot4_comprobo22" / "macfirst_floor_take_2.mcap")
    assert (a.provenance.format, c.provenance.format) == ("ros2", "mcap-ros2")
    for log in (a, b, c):  # README §8: 357 scans x 720 beams, 920 odom, yaw +90° mount
        s = log.scans
        assert len(s) == 357 and set(np.diff(s.offsets)) == {720}
        assert len(log.odometry) == 920
        assert s.frame_id == "rplidar_link"
        assert s.mount[2] == pytest.approx(math.pi / 2, abs=1e-6)
        assert s.mount[0] == pytest.approx(0.004, abs=1e-3)
        assert s.range_max[0] == pytest.approx(12.0) and s.range_min[0] == pytest.approx(0.15)
        assert s.stamp[-1] - s.stamp[0] == pytest.approx(46.2, abs=0.5)
        inf = np.count_nonzero(~np.isfinite(s.ranges)) / s.ranges.size
        assert inf == pytest.approx(0.229, abs=0.005)  # README: 22.9 % inf
        assert not s.valid[~np.isfinite(s.ranges)].any()
        assert not s.valid[s.ranges > 12.0].any()
        # the RPLIDAR turns once a scan: time_increment × 719 is about the scan period
        assert np.median(s.time_increment * 719) == pytest.approx(np.median(np.diff(s.stamp)), rel=0.05)
    np.testing.assert_array_equal(a.scans.ranges, c.scans.ranges)
    np.testing.assert_array_equal(a.odometry.pose, c.odometry.pose)


def test_ros1_neato_duplicate_beam_and_rotated_mount(datasets):
    log = read_log(datasets / "ros1_neato_ksoltan" / "left_side.bag")
    s = log.scans
    assert log.provenance.topics["scan"] == "/scan"
    assert len(s) == 174 and set(np.diff(s.offsets)) == {360}  # 361 -> 360
    assert _reasons(log)["scans", "duplicated last beam of a 360° scan (beam dropped)"] == 174
    assert abs(s.mount[2]) == pytest.approx(math.pi, abs=1e-4)
    assert s.mount[0] == pytest.approx(-0.1016, abs=1e-4)
    zero = np.count_nonzero(s.ranges == 0) / s.ranges.size
    assert 0.24 <= zero <= 0.27  # README: 24-27 % exactly 0
    assert not s.valid[s.ranges == 0].any()
    assert len(log.odometry) == 260
    assert np.all(np.diff(s.stamp) >= 0)


def test_ros1_ccny_nonstandard_index_is_read(datasets):
    log = read_log(datasets / "ros1_ccny_urg04lx_scan_only" / "demo.bag")
    s = log.scans
    assert len(s) == 360 and set(np.diff(s.offsets)) == {681}  # 278 + 82 messages
    assert log.odometry is None
    assert s.stamp[-1] - s.stamp[0] == pytest.approx(35.8, abs=0.1)
    assert s.angle_increment[0] == pytest.approx(0.00614, abs=1e-5)
    assert s.range_max[0] == pytest.approx(5.6, abs=1e-6)
    assert np.count_nonzero(s.ranges == 0) / s.ranges.size == pytest.approx(0.052, abs=0.002)
    assert any("sequentially" in n for n in log.provenance.notes)


def _first(path, key):
    with lzma.open(path, "rt") as f:
        for line in f:
            if line.startswith(key + " "):
                return line.split()


def test_carmen_intel_gfs(datasets):
    p = datasets / "intel_lab" / "intel.gfs.log.xz"
    log = read_log(p)
    s = log.scans
    assert len(s) == 910 and set(np.diff(s.offsets)) == {180}
    assert len(log.odometry) == 14541
    # ODOM stamps printed with 6 digits, and 0 after every FLASER: the file order is kept
    assert any(n.startswith("stamps cannot order the records") for n in log.provenance.notes)
    assert np.all(np.diff(log.odometry.stamp) > 0) and np.all(np.diff(s.stamp) > 0)
    tok = _first(p, "FLASER")
    # the earliest FLASER is the first line; values parsed by hand
    np.testing.assert_allclose(s.ranges[:180], np.array(tok[2:182], np.float32))
    assert s.stamp[0] == pytest.approx(float(tok[188]))
    assert s.angle_min[0] == pytest.approx(-math.pi / 2)
    assert s.angle_increment[0] == pytest.approx(math.radians(1))
    at_max = np.isclose(s.ranges, 81.83)
    assert at_max.mean() == pytest.approx(0.025, abs=0.003) and not s.valid[at_max].any()


@pytest.mark.parametrize("name,n_scans,beams,n_odom", [
    ("aces-corrected.log.gz", 440, 180, 7814),
    ("freiburg-079-corrected.log.gz", 4791, 360, 9725),
])
def test_carmen_corrected(datasets, name, n_scans, beams, n_odom):
    log = read_log(datasets / "carmen_corrected" / name)
    assert log.provenance.format == "carmen"
    assert len(log.scans) == n_scans and set(np.diff(log.scans.offsets)) == {beams}
    assert len(log.odometry) == n_odom
    assert np.all(np.diff(log.odometry.stamp) >= 0)


def test_urg_breezyslam_mines(datasets):
    p = datasets / "breezyslam_mines" / "exp1.dat.xz"
    log = read_log(p)
    s = log.scans
    assert log.provenance.format == "urg"
    assert len(s) == 756 and set(np.diff(s.offsets)) == {683}
    assert s.stamp[-1] - s.stamp[0] == pytest.approx(74.6, abs=0.1)
    with lzma.open(p, "rt") as f:
        tok = f.readline().split()
    np.testing.assert_allclose(s.ranges[:683], np.array(tok[24:], float) / 1000, rtol=1e-6)
    mm = np.round(s.ranges * 1000)
    assert not s.valid[mm < 20].any()
    assert s.valid[(mm >= 20) & (mm <= 5600)].all()
    assert log.meta["rover"]["ticks_per_revolution"] == 2000
    assert s.mount == (0.145, 0.0, 0.0)
    path = np.hypot(*np.diff(log.odometry.pose[:, :2], axis=0).T).sum()
    assert path == pytest.approx(46, rel=0.1)  # README: about 46 m


def test_victoria_park(datasets):
    p = datasets / "victoria_park" / "victoria_park.txt.xz"
    log = read_log(p)
    assert len(log.odometry) == 6969
    assert len(log.observations) == 3640
    assert np.unique(log.observations.landmark_id).size == 151
    assert log.observations.range.min() == pytest.approx(4.6, abs=0.05)
    assert log.observations.range.max() == pytest.approx(20.7, abs=0.05)
    path = np.hypot(*np.diff(log.odometry.pose[:, :2], axis=0).T).sum()
    assert path == pytest.approx(4000, rel=0.05)  # README: 4.0 km
    tok = _first(p, "LANDMARK")  # LANDMARK 4 5 11.5387 -3.2007
    k = 0
    assert log.observations.stamp[k] == float(tok[1])
    assert log.observations.range[k] == pytest.approx(math.hypot(float(tok[3]), float(tok[4])))
    assert log.observations.bearing[k] == pytest.approx(math.atan2(float(tok[4]), float(tok[3])))


@pytest.mark.parametrize("robot", [1, 4])
def test_mrclam(datasets, robot):
    root = datasets / "mrclam" / "MRCLAM_Dataset6"
    log = read_log(root, robot=robot)
    obs, other = log.observations, log.other_observations
    assert set(np.unique(obs.landmark_id)) <= set(range(6, 21))
    assert np.all((other.landmark_id <= 5) & (other.landmark_id != 0))
    with lzma.open(root / f"Robot{robot}_Measurement.dat.xz", "rt") as f:
        rows = [ln.split() for ln in f if not ln.startswith("#")]
    assert len(obs) + len(other) == len(rows)
    assert log.truth.landmark_xy.shape == (15, 2)
    assert log.odometry.twist is not None and log.odometry.pose is None
    assert len(log.truth.pose) > 40000
    assert 0 <= log.odometry.twist[:, 0].min() and log.odometry.twist[:, 0].max() <= 0.09 + 1e-9


def test_mrclam_all_robots_in_one_log(datasets):
    """``robot="all"``: each robot's own log (the same as reading it alone), the landmark truth
    shared, the readers' dropped records prefixed by robot; sightings of other robots kept in
    each robot's other_observations."""
    root = datasets / "mrclam" / "MRCLAM_Dataset6"
    log = read_log(root, robot="all")
    assert [r for r, _ in log.robots] == [1, 2, 3, 4, 5]
    assert log.odometry is None and log.observations is None
    assert log.truth.landmark_id.size == 15 and log.truth.pose is None
    one = read_log(root, robot=4)
    four = dict(log.robots)[4]
    assert np.array_equal(four.observations.stamp, one.observations.stamp)
    assert np.array_equal(four.truth.pose, one.truth.pose)
    assert all(d.stream.startswith("robot") for d in log.provenance.dropped)
    seen = [lg.other_observations.landmark_id for _, lg in log.robots]
    assert all(np.isin(np.arange(1, 6), ids).sum() >= 4 for ids in seen)  # each robot saw the others


def test_mrclam_landmark_fraction_over_all_robots(datasets):
    root = datasets / "mrclam" / "MRCLAM_Dataset6"
    total = sum(len(read_log(root, robot=r).observations) for r in range(1, 6))
    assert total == 15383  # README: 15,383 landmark observations
