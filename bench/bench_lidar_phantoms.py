"""Phantom returns (people near the laser) against the LiDAR pipeline's q: truth kept with and
without ``lidar.q_hold``.

Rooms logs of 150 scans (seeds 2–5), whose scans in a window have every 40th valid beam
returning at 0.3 of its range (about 17 beams a scan against ``q_beams = 5``, ``q_retry = 30``).
Some of these scans are q-relaxed (no pose agrees with 5 wrong beams); others still agree, with
5, with a wrong pose — what the hold (the scans of the next ``q_hold`` seconds after a q-relaxed
one matched with ``q_retry`` from the start) is there for. Printed per case and setting: submap
members (every submap, not only the newest) whose relative box misses the true relative pose,
proven-free cells on a true wall, scans q-relaxed and held, the median relative heading, the
time. A measurement, no target::

    python -m bench lidar_phantoms
"""

from __future__ import annotations

import sys
import time

from ivslam_cli.config import resolve_config
from ivslam_cli.slam.lidar import Params as LidarParams
from ivslam_cli.slam.lidar.pipeline import run
from tests.helpers.lidar_submap import phantoms
from tests.helpers.lidar_truth import containment, members_outside

CASES = [(seed, w) for seed in (2, 3, 4, 5) for w in ((30, 55), (40, 60), (60, 90), (80, 120))]
SETTINGS = {"q_hold 0": {"lidar.q_hold": 0.0}, "q_hold 1 s (default)": {}}
Q = {"lidar.q_beams": 5, "lidar.q_retry": 30}


def main() -> int:
    print(f"{'seed':>4} {'window':>8}  {'setting':<22} {'outside':>9} {'free on walls':>13} {'relaxed':>7} "
          f"{'held':>5} {'heading':>8} {'s':>5}")
    lost = {k: 0 for k in SETTINGS}
    for seed, (first, last) in CASES:
        log, bad = phantoms(seed=seed, first=first, last=last, steps=150)
        for name, over in SETTINGS.items():
            params = LidarParams.from_config(resolve_config(None, {**Q, **over}, log_bounds=log.bounds))
            t0 = time.perf_counter()
            res = run(bad, params)
            dt = time.perf_counter() - t0
            out, n = members_outside(bad, res)
            c = containment(res)
            walls = c["map_free"][1] - c["map_free"][0]
            lost[name] += out > 0 or walls > 0
            st = res.stats
            print(f"{seed:>4} {first:>3}–{last:<4}  {name:<22} {out:>4}/{n:<4} {walls:>13} {st['scans_q_relaxed']:>7} "
                  f"{st['scans_q_held']:>5} {st['median_relative_heading']:>8.4f} {dt:>5.1f}", flush=True)
    for name, k in lost.items():
        print(f"{name}: truth lost in {k} of {len(CASES)} cases")
    return 0


if __name__ == "__main__":
    sys.exit(main())
