"""Benchmark: LaserScan messages/s into the log model, and peak memory.

Builds, in a temp dir, a 50,000-message ROS 2 MCAP (ros2 profile, CDR, zstd chunks,
written with the ``mcap`` writer) and a ROS 1 bag (rosbags' writer) of 360-beam
``sensor_msgs/LaserScan`` (random ranges, 5% inf), then times ``read_log`` on each and
measures the tracemalloc peak against the size of the resulting arrays.

Reference: the size of the arrays read. Targets: >= 100,000 msgs/s and peak < 2x the arrays
(printed as ok / BELOW TARGET / ABOVE TARGET).

    python -m bench readers           # as part of `make bench`
    python -m bench.bench_readers
"""

from __future__ import annotations

import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

N_MSGS = 50_000
BEAMS = 360
TARGET_RATE = 100_000.0
TARGET_MEM = 2.0


def _scan(store, ros: int, k: int, ranges: np.ndarray):
    T = store.types
    stamp = T["builtin_interfaces/msg/Time"](sec=k // 10, nanosec=(k % 10) * 100_000_000)
    hdr = (T["std_msgs/msg/Header"](seq=k, stamp=stamp, frame_id="laser") if ros == 1
           else T["std_msgs/msg/Header"](stamp=stamp, frame_id="laser"))
    return T["sensor_msgs/msg/LaserScan"](
        header=hdr, angle_min=-np.pi, angle_max=np.pi - 2 * np.pi / BEAMS,
        angle_increment=2 * np.pi / BEAMS, time_increment=0.0, scan_time=0.1,
        range_min=0.1, range_max=30.0, ranges=ranges, intensities=np.zeros(0, np.float32))


def _ranges(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    r = rng.uniform(0.2, 25.0, size=(n, BEAMS)).astype(np.float32)
    r[rng.random((n, BEAMS)) < 0.05] = np.inf
    return r


def write_mcap(path: Path, n: int = N_MSGS) -> Path:
    from mcap.writer import Writer

    from ivslam_cli.logs.typestore import typestore

    store = typestore(2)
    msgdef, _ = store.generate_msgdef("sensor_msgs/msg/LaserScan", ros_version=2)
    ranges = _ranges(n)
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="ivslam-bench")
        sid = w.register_schema(name="sensor_msgs/msg/LaserScan", encoding="ros2msg",
                                data=msgdef.encode())
        cid = w.register_channel(topic="/scan", message_encoding="cdr", schema_id=sid)
        for k in range(n):
            data = store.serialize_cdr(_scan(store, 2, k, ranges[k]), "sensor_msgs/msg/LaserScan")
            t = k * 100_000_000
            w.add_message(channel_id=cid, log_time=t, publish_time=t, data=data)
        w.finish()
    return path


def write_bag(path: Path, n: int = N_MSGS) -> Path:
    from rosbags.rosbag1 import Writer

    from ivslam_cli.logs.typestore import typestore

    store = typestore(1)
    ranges = _ranges(n, seed=1)
    with Writer(path) as w:
        conn = w.add_connection("/scan", "sensor_msgs/msg/LaserScan", typestore=store)
        for k in range(n):
            w.write(conn, k * 100_000_000,
                    store.serialize_ros1(_scan(store, 1, k, ranges[k]), "sensor_msgs/msg/LaserScan"))
    return path


def measure(path: Path) -> dict[str, float]:
    from ivslam_cli.logs import read_log

    read_log(path)  # warm imports / page cache
    t0 = time.perf_counter()
    data = read_log(path)
    seconds = time.perf_counter() - t0
    del data
    tracemalloc.start()
    data = read_log(path)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    s = data.scans
    arrays = sum(a.nbytes for a in (s.stamp, s.angle_min, s.angle_increment, s.range_min,
                                     s.range_max, s.offsets, s.ranges, s.valid))
    assert len(s) == N_MSGS and s.offsets[-1] == N_MSGS * BEAMS
    return {"rate": len(s) / seconds, "seconds": seconds, "peak_ratio": peak / arrays,
            "arrays_mb": arrays / 1e6, "peak_mb": peak / 1e6}


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        print(f"bench_readers: {N_MSGS} LaserScans x {BEAMS} beams")
        for name, writer, fname in (("ROS 2 MCAP", write_mcap, "scans.mcap"),
                                    ("ROS 1 bag", write_bag, "scans.bag")):
            path = writer(tmp / fname)
            r = measure(path)
            ok_rate = "ok" if r["rate"] >= TARGET_RATE else "BELOW TARGET"
            ok_mem = "ok" if r["peak_ratio"] < TARGET_MEM else "ABOVE TARGET"
            print(f"  {name:11s} {r['rate']:>10,.0f} msgs/s (target >= {TARGET_RATE:,.0f}) "
                  f"{ok_rate}; peak {r['peak_mb']:.1f} MB = {r['peak_ratio']:.2f}x arrays "
                  f"of {r['arrays_mb']:.1f} MB (target < {TARGET_MEM:.0f}x) {ok_mem}")


if __name__ == "__main__":
    main()
