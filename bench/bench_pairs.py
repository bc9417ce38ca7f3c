"""Benchmark: the pairs pipeline on a 20-landmark, 10,000-step simulated log.

Prints pair observations processed per second and the time of the whole ``ivslam run``
(read + pipeline + HDF5 write), cold (a fresh numba cache: the first run compiles) and warm
(a second process loading the cache), plus the containment of the truth.

Reference: none; the figures are compared from run to run. Target (exit code 1 otherwise):
containment 1.0 for every kind and no empty event.

    python -m bench pairs             # as part of `make bench`
    python -m bench.bench_pairs
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def _ivslam(*args: str, env: dict) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "ivslam_cli", *args], check=True, env=env,
                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return time.perf_counter() - t0


def main() -> int:
    from ivslam_cli.logs.writers import write_log
    from ivslam_cli.simulate import SimConfig, simulate

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        log = simulate(SimConfig(scenario="pairs", seed=1, steps=10_000, landmarks=20, world_size=12.0,
                                 max_range=6.0))
        path = write_log(tmp / "pairs10k.mcap", log, "mcap")
        env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp / "numba-cache"))
        cold = _ivslam("run", str(path), "--mode", "pairs", "-o", str(tmp / "cold.h5"), env=env)
        warm = _ivslam("run", str(path), "--mode", "pairs", "-o", str(tmp / "warm.h5"), env=env)
        rep = subprocess.run([sys.executable, "-m", "ivslam_cli", "report", str(tmp / "warm.h5"), "--json"],
                             check=True, env=env, capture_output=True, text=True)
        doc = json.loads(rep.stdout)
        from ivslam_cli.results.hdf5 import read_result

        stats = read_result(tmp / "warm.h5").stats
    n_obs = len(log.observations)
    rate = stats.get("pair_observations_per_s", float("nan"))
    print(f"log: 10,000 steps, 20 landmarks, {n_obs} observations, {stats.get('intersections')} pair "
          f"observations, {stats.get('pairs')} pairs")
    print(f"pipeline: {rate:,.0f} pair observations/s (warm)")
    print(f"whole `ivslam run`: cold {cold:.1f} s (compiles the kernels), warm {warm:.1f} s")
    print(f"containment: {doc['containment']}   empty events: {doc['empty_events']}")
    ok = all(v == 1.0 for v in doc["containment"].values() if v is not None) and doc["empty_events"] == 0
    print("soundness: OK" if ok else "soundness: FAILED")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
