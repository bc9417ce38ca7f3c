"""Benchmark: a 10-minute URG-04LX log (6,000 scans x 682 beams) simulated in < 10 s.

Times the simulation alone and simulation + writing MCAP (what ``ivslam simulate -o
x.mcap`` does); the numba kernels are compiled (or loaded from cache) beforehand.

Reference: none. Target (exit code 1 otherwise): simulation + write < 10 s.

    python -m bench simulate          # as part of `make bench`
    python -m bench.bench_simulate
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

TARGET_S = 10.0


def main() -> int:
    from ivslam_cli.logs.writers import write_log
    from ivslam_cli.simulate import SimConfig, simulate

    simulate(SimConfig(scenario="lidar", steps=5))  # warm-up: JIT / cache load
    cfg = SimConfig(scenario="lidar", sensor="urg-04lx", world="rooms", duration=600.0, seed=1)
    t0 = time.perf_counter()
    log = simulate(cfg)
    t1 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        write_log(Path(tmp) / "urg.mcap", log)
    t2 = time.perf_counter()
    beams = log.scans.ranges.shape[0]
    total = t2 - t0
    print(f"simulate: {len(log.scans)} scans x {beams // len(log.scans)} beams: "
          f"simulation {t1 - t0:.2f} s, + MCAP write {t2 - t1:.2f} s = {total:.2f} s "
          f"(target < {TARGET_S:.0f} s) {'OK' if total < TARGET_S else 'SLOW'}")
    return 0 if total < TARGET_S else 1


if __name__ == "__main__":
    raise SystemExit(main())
