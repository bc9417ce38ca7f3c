"""Benchmark: LaserScan messages/s into the log model, and peak memory.

Builds, in a temp dir, a 50,000-message ROS 2 MCAP (ros2 profile, CDR, zstd chunks,
written with the ``mcap`` writer) and a ROS 1 bag (rosbags' writer) of 360-beam
``sensor_msgs/LaserScan`` (random ranges, 5% inf), then times ``read_log`` on each and
measures the tracemalloc peak against the size of the resulting arrays. The logs are the reader
tests' synthetic ones (``tests/helpers/ros_logs.py``), larger.
Target: >= 100,000 msgs/s and peak < 2x the arrays.
"""

from __future__ import annotations

import tempfile
import time
import tracemalloc
from pathlib import Path

from tests.helpers.ros_logs import BEAMS, write_bag, write_mcap  # the tests' synthetic logs, larger

N_MSGS = 50_000
TARGET_RATE = 100_000.0
TARGET_MEM = 2.0


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
            path = writer(tmp / fname, N_MSGS)
            r = measure(path)
            ok_rate = "ok" if r["rate"] >= TARGET_RATE else "BELOW TARGET"
            ok_mem = "ok" if r["peak_ratio"] < TARGET_MEM else "ABOVE TARGET"
            print(f"  {name:11s} {r['rate']:>10,.0f} msgs/s (target >= {TARGET_RATE:,.0f}) "
                  f"{ok_rate}; peak {r['peak_mb']:.1f} MB = {r['peak_ratio']:.2f}x arrays "
                  f"of {r['arrays_mb']:.1f} MB (target < {TARGET_MEM:.0f}x) {ok_mem}")


if __name__ == "__main__":
    main()
