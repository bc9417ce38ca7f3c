"""Round trips: simulate -> write (every format) -> read back with rosbags / mcap / h5 -> same arrays.

The ROS and MCAP files are decoded (``tests/helpers/ros_messages.py``) with
``rosbags.highlevel.AnyReader`` *without* our typestore and with ``mcap_ros2``'s decoder, i.e.
only from the definitions embedded in the files, independently of the project's readers.
"""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from ivslam_cli.errors import IvslamError, LogError
from ivslam_cli.logs.ivslam_h5 import read_ivslam_h5, write_ivslam_h5
from ivslam_cli.logs.writers import format_from_path, write_log
from ivslam_cli.simulate import SimConfig, simulate
from tests.helpers.ros_messages import decode

EXT = {"mcap": ".mcap", "ros1": ".bag", "ros2": "", "ros2-mcap": "", "h5": ".h5"}


@pytest.fixture(scope="module")
def logs():
    common = dict(seed=21, outlier_rate=0.02)
    return {
        "pairs": simulate(SimConfig(scenario="pairs", steps=40, wrong_association_rate=0.05, **common)),
        "landmarks": simulate(SimConfig(scenario="landmarks", steps=60, **common)),
        "lidar": simulate(SimConfig(scenario="lidar", steps=25, **common)),
        "lidar_sick": simulate(SimConfig(scenario="lidar", sensor="sick", world="open", steps=15, **common)),
    }


def assert_yaw(a, b):
    assert np.max(np.abs((np.asarray(a) - b + np.pi) % (2 * np.pi) - np.pi), initial=0) <= 1e-15


def check_same(log, d):
    rec = d["meta"]
    assert rec.bounds == log.bounds and rec.meta == log.meta
    tr = log.truth
    for name in ("landmark_id", "landmark_xy", "world"):
        a, b = getattr(tr, name), getattr(rec, name)
        assert (a is None and b is None) or np.array_equal(a, b), name
    assert rec.outliers.keys() == tr.outliers.keys()
    for k in tr.outliers:
        assert np.array_equal(rec.outliers[k], tr.outliers[k]), k
    truth = np.array(d["truth"])
    assert np.array_equal(truth[:, 0], tr.pose_stamp) and np.array_equal(truth[:, 1:3], tr.pose[:, :2])
    assert_yaw(truth[:, 3], tr.pose[:, 2])
    if log.scans is not None:
        sc = log.scans
        st = np.array([s[:5] for s in d["scan"]])
        for j, f in enumerate(("stamp", "angle_min", "angle_increment", "range_min", "range_max")):
            assert np.array_equal(st[:, j], getattr(sc, f)), f
        ranges = [s[5] for s in d["scan"]]
        assert np.array_equal(np.cumsum([0] + [r.size for r in ranges]), sc.offsets)
        flat = np.concatenate(ranges)
        assert flat.dtype == np.float32 and np.array_equal(flat, sc.ranges)
        rmin = np.repeat(st[:, 3], np.diff(sc.offsets))
        rmax = np.repeat(st[:, 4], np.diff(sc.offsets))
        assert np.array_equal((flat >= rmin) & (flat <= rmax), sc.valid)
        assert np.array_equal(d["mount"][:2], sc.mount[:2]) and abs(d["mount"][2] - sc.mount[2]) <= 1e-15
    else:
        assert not d["scan"]
    if log.odometry is not None:
        od = np.array(d["odom"])
        o = log.odometry
        assert np.array_equal(od[:, 0], o.stamp) and np.array_equal(od[:, 1:3], o.pose[:, :2])
        assert_yaw(od[:, 3], o.pose[:, 2])
        assert np.array_equal(od[:, 4:6], o.twist)
    else:
        assert not d["odom"]
    if log.observations is not None:
        ob = np.array(d["obs"])
        o = log.observations
        assert np.array_equal(ob[:, 0], o.stamp) and np.array_equal(ob[:, 1].astype(np.int64), o.landmark_id)
        assert np.array_equal(ob[:, 2], o.range) and np.array_equal(ob[:, 3], o.bearing)


@pytest.mark.parametrize("fmt", ["mcap", "ros1", "ros2", "ros2-mcap"])
@pytest.mark.parametrize("name", ["pairs", "landmarks", "lidar", "lidar_sick"])
def test_round_trip_ros_and_mcap(tmp_path, logs, name, fmt):
    path = tmp_path / f"log{EXT[fmt]}"
    write_log(path, logs[name], fmt)
    check_same(logs[name], decode(path, fmt))
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp left


def assert_logs_equal(a, b):
    for stream in ("scans", "odometry", "observations", "other_observations", "truth"):
        sa, sb = getattr(a, stream), getattr(b, stream)
        assert (sa is None) == (sb is None), stream
        if sa is None:
            continue
        for f, va in vars(sa).items():
            vb = getattr(sb, f)
            if isinstance(va, np.ndarray) or isinstance(vb, np.ndarray):
                assert va.dtype == vb.dtype and np.array_equal(va, vb, equal_nan=va.dtype.kind == "f"), f"{stream}.{f}"
            elif isinstance(va, dict):
                assert va.keys() == vb.keys()
                assert all(np.array_equal(va[k], vb[k]) for k in va)
            else:
                assert va == vb, f"{stream}.{f}"
    assert a.bounds == b.bounds and a.meta == b.meta


@pytest.mark.parametrize("name", ["pairs", "landmarks", "lidar", "lidar_sick"])
def test_round_trip_h5(tmp_path, logs, name):
    path = tmp_path / "log.h5"
    write_log(path, logs[name])
    back = read_ivslam_h5(path)
    assert_logs_equal(logs[name], back)
    assert back.provenance.path == str(path) and back.provenance.format == "ivslam-h5"
    with h5py.File(path) as f:
        assert f.attrs["ivslam_log_version"] == 1
        if "scans" in f:
            assert f["scans/ranges"].compression == "gzip" and f["scans/ranges"].shuffle


@pytest.mark.parametrize("fmt", ["mcap", "ros1", "ros2", "h5"])
def test_the_time_between_beams_survives_the_formats(tmp_path, fmt):
    """A swept log's time between two beams (LaserScan ``time_increment``) is written and read
    back (a float32 in a LaserScan); a log that records none reads back without one."""
    from ivslam_cli.logs import read_log

    log = simulate(SimConfig(scenario="lidar", steps=6, seed=3, sweep=0.0667))
    ti = log.scans.time_increment
    assert ti is not None and np.allclose(ti, 0.0667 / (np.diff(log.scans.offsets) - 1))
    path = tmp_path / f"log{EXT[fmt]}"
    write_log(path, log, fmt)
    np.testing.assert_allclose(read_log(path).scans.time_increment, ti, rtol=1e-6)
    still = simulate(SimConfig(scenario="lidar", steps=6, seed=3))
    write_log(tmp_path / "still.h5", still)
    assert still.scans.time_increment is None and read_log(tmp_path / "still.h5").scans.time_increment is None


def test_h5_errors_are_log_errors(tmp_path, logs):
    with pytest.raises(LogError, match="no such file"):
        read_ivslam_h5(tmp_path / "missing.h5")
    junk = tmp_path / "junk.h5"
    junk.write_bytes(b"not hdf5 at all" * 10)
    with pytest.raises(LogError, match="corrupt") as exc:
        read_ivslam_h5(junk)
    assert "\n" not in str(exc.value)
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = 1
    with pytest.raises(LogError, match="not an ivslam HDF5 log"):
        read_ivslam_h5(other)
    good = tmp_path / "good.h5"
    write_ivslam_h5(good, logs["landmarks"])
    with h5py.File(good, "a") as f:
        f.attrs["ivslam_log_version"] = 99
    with pytest.raises(LogError, match="unsupported ivslam log version 99"):
        read_ivslam_h5(good)
    truncated = tmp_path / "trunc.h5"
    truncated.write_bytes(good.read_bytes()[:3000])
    with pytest.raises(LogError):
        read_ivslam_h5(truncated)


@pytest.mark.parametrize("fmt", ["mcap", "ros1", "ros2", "h5"])
def test_never_clobber_without_force(tmp_path, logs, fmt):
    path = tmp_path / f"out{EXT[fmt]}"
    write_log(path, logs["pairs"], fmt)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    with pytest.raises(IvslamError, match="exists"):
        write_log(path, logs["landmarks"], fmt)
    assert sorted(p.name for p in tmp_path.rglob("*")) == before
    write_log(path, logs["landmarks"], fmt, force=True)  # replaced, atomically
    d = decode(path, fmt) if fmt != "h5" else None
    if d is not None:
        check_same(logs["landmarks"], d)
    else:
        assert_logs_equal(logs["landmarks"], read_ivslam_h5(path))
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_failed_write_leaves_nothing(tmp_path, logs, monkeypatch):
    import ivslam_cli.logs.writers as w

    def boom(*a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(w, "_write_mcap", boom)
    with pytest.raises(RuntimeError):
        write_log(tmp_path / "x.mcap", logs["pairs"])
    assert list(tmp_path.iterdir()) == []


def test_format_from_path():
    assert [format_from_path(p) for p in ("a.mcap", "a.BAG", "a.h5", "a.hdf5", "dir", "a.db3")] == [
        "mcap", "ros1", "h5", "h5", "ros2", "ros2"]
