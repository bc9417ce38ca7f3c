"""Benchmark: ``ivslam run DIR`` over 8 simulated landmark logs, on the local process pool
against the same logs one after another.

Both are whole commands (``ivslam run DIR -o OUT --jobs 1`` and ``--jobs 2``, a fresh
process each, the kernel cache warm), the best of ``--repeat`` runs. Printed: both wall
times and the speed-up; the per-log overhead (everything but the pipelines: process and
worker start, reading, writing, the audit — in core-seconds per log); what the runs achieved
(containment, median pose and landmark widths, empty events); and whether the pool's results
equal the sequential ones (datasets, runtime aside). The cores each command obtained (its CPU
time over its wall time) are printed too: on a machine shared with other work the pool cannot
be faster than the cores it gets.

Target (exit code 1 otherwise): the pool ≥ 1.7× faster than one after another on 2 workers,
every log ok, containment 1.0 and equal results.

    python -m bench fleet              # as part of `make bench`
    python -m bench.bench_fleet --steps 1500 --repeat 2
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET = 1.7
LOGS = 8
WORKERS = 2


def _cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _ivslam(*args: str, cpu: list | None = None) -> float:
    c0, t0 = _cpu(), time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "ivslam_cli", *args], stdout=subprocess.DEVNULL,
                       stderr=subprocess.PIPE, text=True, check=False)
    if r.returncode:
        raise SystemExit(f"ivslam {' '.join(args)} failed ({r.returncode}): {r.stderr.strip()}")
    wall = time.perf_counter() - t0
    if cpu is not None:
        cpu.append((_cpu() - c0) / wall)
    return wall


def _same(a: Path, b: Path) -> bool:
    import h5py
    import numpy as np

    def load(p):
        out = {}
        with h5py.File(p, "r") as f:
            f.visititems(lambda n, o: out.__setitem__(n, o[()]) if isinstance(o, h5py.Dataset) else None)
        return out

    da, db = load(a), load(b)
    return sorted(da) == sorted(db) and all(
        np.array_equal(da[k], db[k], equal_nan=da[k].dtype.kind == "f") for k in da)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=1200, help="steps per simulated log")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each, the best kept")
    args = ap.parse_args(argv)

    from ivslam_cli.logs.writers import write_log
    from ivslam_cli.simulate import SimConfig, simulate

    print(f"machine: {os.cpu_count()} cores, load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        logs = tmp / "logs"
        logs.mkdir()
        for seed in range(1, LOGS + 1):
            write_log(logs / f"lm{seed}.mcap", simulate(SimConfig(scenario="landmarks", seed=seed, steps=args.steps)),
                      "mcap")
        warm = _ivslam("run", str(logs / "lm1.mcap"), "--mode", "landmarks", "-o", str(tmp / "warm.h5"))
        print(f"{LOGS} landmark logs of {args.steps} steps; one `ivslam run` (warms the kernel cache): {warm:.1f} s")
        seq_t, pool_t, seq_c = [], [], []
        for k in range(args.repeat):
            seq_t.append(_ivslam("run", str(logs), "--mode", "landmarks", "-o", str(tmp / f"seq{k}"), "--jobs", "1",
                                 "--quiet", cpu=seq_c))
            pool_t.append(_ivslam("run", str(logs), "--mode", "landmarks", "-o", str(tmp / f"pool{k}"), "--jobs",
                                  str(WORKERS), "--quiet"))
        best_seq, best_pool = min(seq_t), min(pool_t)
        ks, kp = seq_t.index(best_seq), pool_t.index(best_pool)
        seq_doc = json.loads((tmp / f"seq{ks}" / "fleet.json").read_text())
        pool_doc = json.loads((tmp / f"pool{kp}" / "fleet.json").read_text())
        same = all(_same(tmp / f"seq{ks}" / r["result"], tmp / f"pool{kp}" / r["result"])
                   for r in seq_doc["logs"] if r["result"])
    speedup = best_seq / best_pool
    pipe_seq = sum(r["runtime_s"] for r in seq_doc["logs"])
    pipe_pool = sum(r["runtime_s"] for r in pool_doc["logs"])
    print(f"one after another (--jobs 1): {best_seq:.1f} s   (runs: {', '.join(f'{t:.1f}' for t in seq_t)})")
    print(f"process pool (--jobs {WORKERS}):     {best_pool:.1f} s   (runs: {', '.join(f'{t:.1f}' for t in pool_t)})")
    workers = len({(r["host"], r["pid"]) for r in pool_doc["logs"]})
    pool_cpu = sum(r["cpu_s"] for r in pool_doc["logs"]) / best_pool  # the workers' own CPU time
    print(f"cores obtained (CPU time / wall time): one after another {seq_c[ks]:.2f}, pool (its jobs) {pool_cpu:.2f} "
          f"({workers} worker processes); load average now {os.getloadavg()[0]:.2f} (other work on the machine "
          f"takes its share)")
    print(f"speed-up: {speedup:.2f}x (target >= {TARGET}x): {'PASS' if speedup >= TARGET else 'FAIL'}")
    print(f"pipelines: {pipe_seq:.1f} s in total one after another, {pipe_pool:.1f} s on the pool "
          f"({pipe_seq / LOGS:.2f} s a log)")
    print(f"per-log overhead (all but the pipelines, core-seconds a log): one after another "
          f"{(best_seq - pipe_seq) / LOGS:.2f} s, pool {(best_pool * WORKERS - pipe_pool) / LOGS:.2f} s; "
          f"inside the jobs (read + audit + write): "
          f"{sum(r['wall_s'] - r['runtime_s'] for r in seq_doc['logs']) / LOGS:.2f} s")
    recs = pool_doc["logs"]
    ok = all(r["status"] == "ok" for r in recs)
    cont = {k: min(r["containment"].get(k) or 0.0 for r in recs) for k in recs[0]["containment"]}
    import statistics

    widths = {k: statistics.median(r["final_width"][k]["median"] for r in recs) for k in ("pose", "landmark")}
    print(f"achieved: {sum(r['status'] == 'ok' for r in recs)}/{LOGS} ok, {pool_doc['totals']['empty_events']} empty "
          f"events, containment (worst log) {cont}, final median width (median over logs) pose "
          f"{widths['pose']:.3f} m, landmark {widths['landmark']:.3f} m; "
          f"{sum(r['stats'].get('nodes') or 0 for r in recs):.0f} poses")
    print(f"pool results equal to the sequential ones: {'yes' if same else 'NO'}")
    good = speedup >= TARGET and ok and same and all(v == 1.0 for v in cont.values())
    return 0 if good else 1


if __name__ == "__main__":
    sys.exit(main())
