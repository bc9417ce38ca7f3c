"""Bad input: truncated / byte-flipped copies, empty files, unknown formats, missing topics.
Only LogError may come out (never another exception), and never a hang (SIGALRM guard)."""

from __future__ import annotations

import gzip
import signal
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from ivslam_cli.errors import LogError
from ivslam_cli.logs import list_formats, read_log
from tests.helpers.ros_logs import laserscan, random_ranges, write_bag, write_mcap


@contextmanager
def time_limit(seconds: int):
    def boom(*_):
        raise TimeoutError("reader hung")

    old = signal.signal(signal.SIGALRM, boom)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _only_logerror(path: Path, **kw) -> None:
    with time_limit(20):
        try:
            read_log(path, **kw)
        except LogError as exc:
            msg = str(exc)
            assert "\n" not in msg and str(path) in msg


@pytest.fixture(scope="module")
def small_logs(tmp_path_factory):
    """Small synthetic bag / MCAP / CARMEN logs written with the real writers."""
    d = tmp_path_factory.mktemp("logs")
    write_bag(d / "s.bag", n=40)
    write_mcap(d / "s.mcap", n=40)
    lines = [f"ODOM {k * 0.1} 0 0 0.1 0 0 {k * 0.1} host {k * 0.1}" for k in range(20)]
    lines += [f"FLASER 4 1 2 3 4 0 0 0 0 0 0 {k * 0.1} host {k * 0.1}" for k in range(20)]
    (d / "s.log").write_text("\n".join(lines) + "\n")
    with gzip.open(d / "s.log.gz", "wt") as f:
        f.write("\n".join(lines) + "\n")
    return d


KINDS = ["s.bag", "s.mcap", "s.log", "s.log.gz"]


@pytest.mark.parametrize("name", KINDS)
def test_small_logs_read(small_logs, name):
    log = read_log(small_logs / name)
    assert len(log.scans) in (20, 40)


@pytest.mark.parametrize("name", KINDS)
def test_truncated_copies(small_logs, tmp_path, name):
    raw = (small_logs / name).read_bytes()
    rng = np.random.default_rng(len(name))
    for i, cut in enumerate(sorted(rng.integers(0, len(raw), 12))):
        p = tmp_path / f"t{i}_{name}"
        p.write_bytes(raw[:cut])
        _only_logerror(p)


@pytest.mark.parametrize("name", KINDS)
def test_byte_flipped_copies(small_logs, tmp_path, name):
    raw = (small_logs / name).read_bytes()
    rng = np.random.default_rng(7 + len(name))
    for i in range(12):
        buf = bytearray(raw)
        for pos in rng.integers(0, len(raw), 1 + i % 4):
            buf[pos] ^= int(rng.integers(1, 256))
        p = tmp_path / f"f{i}_{name}"
        p.write_bytes(bytes(buf))
        _only_logerror(p)


@pytest.mark.datasets
def test_truncated_real_bags(datasets, tmp_path):
    for rel in ("ros1_ccny_urg04lx_scan_only/demo.bag",
                "mcap_turtlebot4_comprobo22/macfirst_floor_take_2.mcap"):
        raw = (datasets / rel).read_bytes()
        for frac in (0.1, 0.5, 0.93):
            p = tmp_path / f"{frac}_{Path(rel).name}"
            p.write_bytes(raw[: int(len(raw) * frac)])
            with pytest.raises(LogError):
                with time_limit(20):
                    read_log(p)


def test_empty_unknown_and_missing(tmp_path):
    for name, content in (("e.bag", b""), ("e.mcap", b""), ("e.log", b""),
                          ("x.xyz", b"hello world\n"), ("b.bag", b"not a bag at all"),
                          ("c.log", b"PARAM a b\nNEFF 1 2\n")):
        p = tmp_path / name
        p.write_bytes(content)
        with pytest.raises(LogError, match=str(p)):
            read_log(p)
    with pytest.raises(LogError, match="no such file"):
        read_log(tmp_path / "nope.bag")
    (tmp_path / "dir").mkdir()
    with pytest.raises(LogError, match="neither a ROS 2 bag"):
        read_log(tmp_path / "dir")
    with pytest.raises(LogError, match="unknown format"):
        read_log(tmp_path / "x.xyz", fmt="nope")
    assert "carmen" in list_formats() and "ivslam-h5" in list_formats()


def test_missing_and_mistyped_topics(small_logs):
    with pytest.raises(LogError, match="'/nope' not in log"):
        read_log(small_logs / "s.bag", scan_topic="/nope")
    with pytest.raises(LogError, match="has type sensor_msgs/msg/LaserScan"):
        read_log(small_logs / "s.mcap", odom_topic="/scan")


def test_forced_wrong_format_is_a_logerror(small_logs):
    for fmt in ("carmen", "victoria", "urg", "mcap", "ros1"):
        _only_logerror(small_logs / "s.log" if fmt in ("mcap", "ros1") else
                       small_logs / "s.bag", fmt=fmt)


def test_out_of_order_and_nan_odometry_are_counted(tmp_path):
    lines = ["ODOM 0 0 0 0 0 0 0.0 h 0", "ODOM 1 0 0 0 0 0 0.2 h 0",
             "ODOM 2 0 0 0 0 0 0.1 h 0", "ODOM nan 0 0 0 0 0 0.3 h 0",
             "FLASER 3 1 0 inf 0 0 0 0 0 0 0.5 h 0"]
    p = tmp_path / "o.log"
    p.write_text("\n".join(lines) + "\n")
    log = read_log(p)
    got = {(d.stream, d.reason): d.count for d in log.provenance.dropped}
    assert got["odometry", "rows with NaN/inf (dropped)"] == 1
    assert got["odometry", "out-of-order stamps (sorted, kept)"] == 1
    np.testing.assert_array_equal(log.odometry.stamp, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(log.odometry.pose[:, 0], [0, 2, 1])
    np.testing.assert_array_equal(log.scans.valid, [True, False, False])


def test_ros1_profile_mcap_with_odometry(tmp_path):
    """ros1-profile MCAP (which rosbags' AnyReader refuses) reads scans and odometry."""
    from mcap.writer import Writer

    from ivslam_cli.logs.typestore import typestore

    store = typestore(1)
    T = store.types
    p = tmp_path / "r1.mcap"
    with open(p, "wb") as f:
        w = Writer(f)
        w.start(profile="ros1", library="test")
        ids = {}
        for topic, ty in (("/scan", "sensor_msgs/msg/LaserScan"), ("/odom", "nav_msgs/msg/Odometry")):
            sid = w.register_schema(name=ty.replace("/msg/", "/"), encoding="ros1msg",
                                    data=store.generate_msgdef(ty)[0].encode())
            ids[topic] = w.register_channel(topic=topic, message_encoding="ros1", schema_id=sid)
        ranges = random_ranges(5)
        for k in range(5):
            t = k * 100_000_000
            w.add_message(channel_id=ids["/scan"], log_time=t, publish_time=t,
                          data=store.serialize_ros1(laserscan(store, 1, k, ranges[k]),
                                                    "sensor_msgs/msg/LaserScan"))
            odo = T["nav_msgs/msg/Odometry"](
                header=T["std_msgs/msg/Header"](seq=k, stamp=T["builtin_interfaces/msg/Time"](
                    sec=k, nanosec=0), frame_id="odom"), child_frame_id="base_link",
                pose=T["geometry_msgs/msg/PoseWithCovariance"](
                    pose=T["geometry_msgs/msg/Pose"](
                        position=T["geometry_msgs/msg/Point"](x=float(k), y=0.0, z=0.0),
                        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)),
                    covariance=np.zeros(36)),
                twist=T["geometry_msgs/msg/TwistWithCovariance"](
                    twist=T["geometry_msgs/msg/Twist"](
                        linear=T["geometry_msgs/msg/Vector3"](x=0.5, y=0.0, z=0.0),
                        angular=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.1)),
                    covariance=np.zeros(36)))
            w.add_message(channel_id=ids["/odom"], log_time=t, publish_time=t,
                          data=store.serialize_ros1(odo, "nav_msgs/msg/Odometry"))
        w.finish()
    log = read_log(p)
    assert log.provenance.format == "mcap-ros1"
    np.testing.assert_array_equal(log.scans.ranges.reshape(5, -1), ranges)
    np.testing.assert_array_equal(log.odometry.pose[:, 0], np.arange(5.0))
    np.testing.assert_allclose(log.odometry.twist, [[0.5, 0.1]] * 5)
