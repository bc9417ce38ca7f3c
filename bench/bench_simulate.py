"""Benchmark: a 10-minute URG-04LX log (6,000 scans x 682 beams) simulated in < 10 s.

For both beam models (``cone``, the default, and ``ray``): times the simulation alone, the
beam kernel alone (cone casting or ray casting of every beam of every scan against the
world's walls) and simulation + writing MCAP (what ``ivslam simulate -o x.mcap`` does); the
numba kernels are compiled (or loaded from cache) beforehand.

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
    from ivslam_cli.simulate.conecast import cone_cast
    from ivslam_cli.simulate.lidar import laser_poses
    from ivslam_cli.simulate.raycast import cast
    from ivslam_cli.simulate.sensors import get_profile
    from ivslam_cli.simulate.worlds import load_world

    ok = True
    for model in ("cone", "ray"):
        simulate(SimConfig(scenario="lidar", steps=5, beam_model=model))  # warm-up: JIT / cache load
        cfg = SimConfig(scenario="lidar", sensor="urg-04lx", world="rooms", duration=600.0, seed=1,
                        beam_model=model)
        t0 = time.perf_counter()
        log = simulate(cfg)
        t1 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            write_log(Path(tmp) / "urg.mcap", log)
        t2 = time.perf_counter()
        prof, world = get_profile(cfg.sensor), load_world(cfg.world)
        sensor = laser_poses(log.truth.pose, prof.mount)
        k0 = time.perf_counter()
        if model == "cone":
            cone_cast(sensor, prof.beam_angles(), log.bounds["beam_angle"], world.segments)
        else:
            cast(sensor, prof.beam_angles(), world.segments)
        k1 = time.perf_counter()
        beams = log.scans.ranges.shape[0]
        total = t2 - t0
        ok &= total < TARGET_S
        print(f"simulate --beam-model {model}: {len(log.scans)} scans x {beams // len(log.scans)} beams, "
              f"{world.segments.shape[0]} walls: simulation {t1 - t0:.2f} s (beam kernel {k1 - k0:.2f} s), "
              f"+ MCAP write {t2 - t1:.2f} s = {total:.2f} s "
              f"(target < {TARGET_S:.0f} s) {'OK' if total < TARGET_S else 'SLOW'}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
