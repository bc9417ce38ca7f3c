"""Small synthetic LaserScan logs written with the real writers: a ROS 2 MCAP (``mcap`` writer,
ros2 profile, CDR) and a ROS 1 bag (``rosbags``' writer) of 360-beam ``sensor_msgs/LaserScan``
(random ranges, 5% inf), one scan every 0.1 s on ``/scan``.

Shared by the reader tests (tests/logs/test_logs_corrupt.py) and the reader benchmark
(bench/bench_readers.py, which writes 50,000 scans): moved here from the benchmark unchanged.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

BEAMS = 360


def laserscan(store, ros: int, k: int, ranges: np.ndarray):
    """Scan ``k`` (stamp ``k * 0.1`` s) as a ROS ``ros`` message of ``store``'s types."""
    T = store.types
    stamp = T["builtin_interfaces/msg/Time"](sec=k // 10, nanosec=(k % 10) * 100_000_000)
    hdr = (T["std_msgs/msg/Header"](seq=k, stamp=stamp, frame_id="laser") if ros == 1
           else T["std_msgs/msg/Header"](stamp=stamp, frame_id="laser"))
    return T["sensor_msgs/msg/LaserScan"](
        header=hdr, angle_min=-np.pi, angle_max=np.pi - 2 * np.pi / BEAMS,
        angle_increment=2 * np.pi / BEAMS, time_increment=0.0, scan_time=0.1,
        range_min=0.1, range_max=30.0, ranges=ranges, intensities=np.zeros(0, np.float32))


def random_ranges(n: int, seed: int = 0) -> np.ndarray:
    """``(n, BEAMS)`` float32 ranges in [0.2, 25] m, 5% of them inf."""
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.2, 25.0, size=(n, BEAMS)).astype(np.float32)
    r[rng.random((n, BEAMS)) < 0.05] = np.inf
    return r


def write_mcap(path: Path, n: int) -> Path:
    from mcap.writer import Writer

    from ivslam_cli.logs.typestore import typestore

    store = typestore(2)
    msgdef, _ = store.generate_msgdef("sensor_msgs/msg/LaserScan", ros_version=2)
    ranges = random_ranges(n)
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="ivslam-bench")
        sid = w.register_schema(name="sensor_msgs/msg/LaserScan", encoding="ros2msg",
                                data=msgdef.encode())
        cid = w.register_channel(topic="/scan", message_encoding="cdr", schema_id=sid)
        for k in range(n):
            data = store.serialize_cdr(laserscan(store, 2, k, ranges[k]), "sensor_msgs/msg/LaserScan")
            t = k * 100_000_000
            w.add_message(channel_id=cid, log_time=t, publish_time=t, data=data)
        w.finish()
    return path


def write_bag(path: Path, n: int) -> Path:
    from rosbags.rosbag1 import Writer

    from ivslam_cli.logs.typestore import typestore

    store = typestore(1)
    ranges = random_ranges(n, seed=1)
    with Writer(path) as w:
        conn = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        for k in range(n):
            w.write(conn, k * 100_000_000,
                    store.serialize_ros1(laserscan(store, 1, k, ranges[k]), "sensor_msgs/msg/LaserScan"))
    return path
