"""Benchmark: the whole ``ivslam run --mode lidar`` (read the log, run the pipeline, write the
result), warm, one process, one core.

Cases (each in its own process, so its peak memory is its own):

- ``exp1``: a Hokuyo URG-04LX (683 values, 10 Hz: the sensor of the "Guaranteed SLAM –
  practical considerations" slides) with wheel encoders, ``configs/exp1.toml`` (74.6 s of log);
- ``sim600``: a simulated 10-minute URG-04LX log (``ivslam simulate --scenario lidar --world
  rooms --duration 600``; ray-cast beams, so ``lidar.fill_gaps``);
- ``sim600_known``: the same log with ``--poses-known`` (truth ± ``lidar.pose_margin``): every
  scan mapped, the cost of the map update end to end when no box outgrows
  ``lidar.max_pose_width`` (on ``exp1`` and ``sim600`` the dead-reckoned boxes do, and the
  scans after that are neither contracted nor mapped: cheap);
- with ``--all``, the other real logs the pipeline runs on: ACES with ``--poses-known``, the
  Intel keyframes, the ROS 2 TurtleBot bag, its MCAP copy and the ROS 1 Neato bag.

Each figure is the smallest wall time of ``--repeat`` runs after a warm-up run (numba
compiled, caches filled). Printed: beams/s, the real-time factor (log duration / run time), the
sensor's own budget (6,830 beams/s: real time), peak RSS, and what the run achieved (scans
mapped, contracted, too wide to contract, median pose width) so that a fast run that maps
little is read as such.

Reference: real time, the sensor's rate. Target (issue #7): the whole run at >= 100x real time
on exp1 and on the simulated log (both cases of it).

    python -m bench lidar_run         # as part of `make bench`: exp1, sim600, sim600_known
    python -m bench.bench_lidar_run --all
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "datasets"
SEED_BUDGET = 6_830.0  # beams/s: the URG-04LX itself (683 values at 10 Hz)
TARGET = 100.0

CASES = {
    "exp1": (DATA / "breezyslam_mines" / "exp1.dat.xz", "configs/exp1.toml", {}),
    "sim600": (None, None, {"lidar.fill_gaps": True}),
    "sim600_known": (None, None, {"lidar.fill_gaps": True, "lidar.poses_known": True, "lidar.known_poses": "truth"}),
    "aces": (DATA / "carmen_corrected" / "aces-corrected.log.gz", "configs/carmen_corrected.toml",
             {"lidar.poses_known": True}),
    "intel": (DATA / "intel_lab" / "intel_gfs.json.xz", "configs/intel_lab.toml", {}),
    "turtlebot_ros2": (DATA / "ros2_turtlebot4_comprobo22", "configs/ros_laserscan.toml", {}),
    "turtlebot_mcap": (DATA / "mcap_turtlebot4_comprobo22", "configs/ros_laserscan.toml", {}),
    "neato_ros1": (DATA / "ros1_neato_ksoltan", "configs/ros_laserscan.toml", {}),
}
TARGETED = ("exp1", "sim600", "sim600_known")


def _find_log(p: Path) -> Path:
    """A dataset directory's log (the first bag / mcap / ROS 2 bag directory in it)."""
    if p.is_file() or (p / "metadata.yaml").exists():
        return p
    for pat in ("*.mcap", "*.bag", "*/metadata.yaml"):
        hits = sorted(p.glob(pat))
        if hits:
            return hits[0].parent if hits[0].name == "metadata.yaml" else hits[0]
    raise FileNotFoundError(f"no log in {p}")


def _sim_log(tmp: Path) -> Path:
    out = tmp / "sim600.h5"
    subprocess.run([sys.executable, "-m", "ivslam_cli", "simulate", "--scenario", "lidar", "--world", "rooms",
                    "--sensor", "urg-04lx", "--seed", "7", "--duration", "600", "-o", str(out), "--force"],
                   cwd=ROOT, check=True, capture_output=True)
    return out


def one_case(name: str, log_path: str, config: str | None, overrides: dict, repeat: int) -> dict:
    """Run one case in this process (warm-up + ``repeat`` timed runs); a dict of figures."""
    import resource

    import numpy as np

    from ivslam_cli.config import resolve_config
    from ivslam_cli.logs import read_log
    from ivslam_cli.results.hdf5 import write_result
    from ivslam_cli.slam import run_pipeline

    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    best = {"read": np.inf, "run": np.inf, "write": np.inf, "total": np.inf}
    with tempfile.TemporaryDirectory() as tmp:
        for it in range(repeat + 1):
            t0 = time.perf_counter()
            log = read_log(log_path)
            t1 = time.perf_counter()
            cfg = resolve_config(config, overrides, log_bounds=log.bounds)
            result = run_pipeline(log, cfg, "lidar")
            t2 = time.perf_counter()
            write_result(Path(tmp) / "r.h5", result, force=True)
            t3 = time.perf_counter()
            if it == 0:
                continue  # warm-up
            for k, v in (("read", t1 - t0), ("run", t2 - t1), ("write", t3 - t2), ("total", t3 - t0)):
                best[k] = min(best[k], v)
    s = result.stats
    return {
        "case": name, "beams": int(s["beams"]), "duration": float(s["log_duration_s"]),
        "scans": int(s["scans_used"]), "mapped": int(s["scans_mapped"]),
        "contracted": int(s.get("scans_contracted", 0)), "too_wide": int(s.get("scans_too_wide_to_contract", 0)),
        "median_width": float(s["median_pose_width"]), "area_empty": float(s["area_empty_m2"]),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "rss_growth_mb": (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0) / 1024.0,
        **{f"{k}_s": float(v) for k, v in best.items()},
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench lidar_run", description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3, help="timed runs per case (after one warm-up); default 3")
    ap.add_argument("--all", action="store_true", help="also the other real logs (ACES, Intel, ROS bags)")
    ap.add_argument("--case", action="append", choices=sorted(CASES), help="only these cases")
    ap.add_argument("--one", nargs=5, help=argparse.SUPPRESS)  # internal: run one case, print JSON
    a = ap.parse_args(sys.argv[1:] if argv is None else argv)
    if a.one:
        name, log, config, ov, repeat = a.one
        print(json.dumps(one_case(name, log, None if config == "-" else config, json.loads(ov), int(repeat))))
        return 0

    names = a.case or (list(CASES) if a.all else list(TARGETED))
    print(__doc__.split("\n\n")[0])
    print(f"load average {os.getloadavg()[0]:.2f} (2 cores shared: figures are the min of {a.repeat} runs)")
    print(f"{'case':16s} {'beams':>9s} {'log s':>7s} {'read s':>7s} {'run s':>7s} {'write s':>7s} {'total s':>8s} "
          f"{'beams/s':>10s} {'x real':>8s} {'seed s':>8s} {'peak MB':>8s}  achieved")
    failed = []
    with tempfile.TemporaryDirectory() as tmp:
        sim = None
        for name in names:
            path, config, ov = CASES[name]
            try:
                if path is None:
                    sim = sim or _sim_log(Path(tmp))
                log = sim if path is None else _find_log(path)
            except (FileNotFoundError, subprocess.CalledProcessError) as e:
                print(f"{name:16s} skipped: {e}")
                continue
            p = subprocess.run([sys.executable, "-m", "bench.bench_lidar_run", "--one", name, str(log),
                                config or "-", json.dumps(ov), str(a.repeat)], cwd=ROOT, capture_output=True,
                               text=True)
            if p.returncode:
                print(f"{name:16s} FAILED: {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else p.returncode}")
                failed.append(name)
                continue
            r = json.loads(p.stdout.strip().splitlines()[-1])
            rate = r["beams"] / r["total_s"]
            rt = r["duration"] / r["total_s"] if r["duration"] > 0 else float("nan")
            print(f"{name:16s} {r['beams']:9d} {r['duration']:7.1f} {r['read_s']:7.3f} {r['run_s']:7.3f} "
                  f"{r['write_s']:7.3f} {r['total_s']:8.3f} {rate:10.3g} {rt:8.1f} {r['beams'] / SEED_BUDGET:8.1f} "
                  f"{r['peak_rss_mb']:8.0f}  {r['mapped']}/{r['scans']} scans mapped, {r['contracted']} contracted, "
                  f"{r['too_wide']} too wide to contract, median pose width {r['median_width']:.3g} m, "
                  f"{r['area_empty']:.4g} m² proven free")
            if name in TARGETED:
                ok = rt >= TARGET
                print(f"{'':16s} target >= {TARGET:g}x real time ({TARGET * SEED_BUDGET / 1e3:.0f} k beams/s): "
                      f"{'PASS' if ok else 'FAIL'} ({rt / TARGET:.0%} of it)")
                if not ok:
                    failed.append(name)
    print("seed s = the log's beams at the seed's budget (the sensor's own rate, 6,830 beams/s)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
