"""Benchmark (issue #16): are a log's scans taken at their stamps? A LiDAR pipeline pairs each
scan with the odometry at its stamp; if the stamps jitter while the sensor keeps its own clock,
that pairing is off by the jitter, a lag no bound states.

Two checks on the moving steps between consecutive scans (stamps shared by scans and odometry):

- the odometry's translation between two stamps against the stamp interval: proportional when
  the odometry is read at the stamps (correlation, slope);
- the change of the range straight ahead (valid beams within ``--cone`` rad, along the
  heading) on straight forward steps, divided by the odometry's translation, binned by the
  stamp interval over its mean: about 1 in every bin when the scans are taken at their stamps,
  about ``mean / interval`` when they keep a regular clock of the mean period.

    python -m bench scan_timing
    python -m bench.bench_scan_timing --log ../shared/datasets/breezyslam_mines/exp1.dat.xz
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
EXP1 = ROOT.parent / "shared" / "datasets" / "breezyslam_mines" / "exp1.dat.xz"
BINS = ((0.0, 0.85), (0.85, 1.15), (1.15, math.inf))


def ahead(log, k: int, cone: float) -> float:
    """Median distance along the heading of scan ``k``'s valid beams within ``cone`` of it
    (NaN with fewer than 5)."""
    sc = log.scans
    a, b = int(sc.offsets[k]), int(sc.offsets[k + 1])
    ang = float(sc.angle_min[k]) + float(sc.angle_increment[k]) * np.arange(b - a) + float(sc.mount[2])
    ang = np.angle(np.exp(1j * ang))  # in the robot's frame
    v = np.asarray(sc.valid[a:b], bool) & (np.abs(ang) < cone)
    r = np.asarray(sc.ranges[a:b], float)[v] * np.cos(ang[v])
    return float(np.median(r)) if r.size >= 5 else math.nan


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--log", type=Path, default=EXP1)
    ap.add_argument("--cone", type=float, default=0.15, help="beams within this of the heading [rad]")
    args = ap.parse_args(argv)
    if not args.log.exists():
        print(f"dataset not present: {args.log}")
        return 0
    from ivslam_cli.logs import read_log

    log = read_log(args.log)
    st = np.asarray(log.scans.stamp, float)
    ot, op = np.asarray(log.odometry.stamp, float), np.asarray(log.odometry.pose, float)
    i = np.clip(np.searchsorted(ot, st), 0, len(ot) - 1)
    shared = float(np.mean(np.abs(ot[i] - st) < 1e-9))
    dt = np.diff(st)
    # the odometry at the scan stamps (interpolated where they are not shared)
    P = np.column_stack([np.interp(st, ot, op[:, 0]), np.interp(st, ot, op[:, 1]),
                         np.interp(st, ot, np.unwrap(op[:, 2]))])
    dxy = np.hypot(np.diff(P[:, 0]), np.diff(P[:, 1]))
    dth = np.abs(np.angle(np.exp(1j * np.diff(P[:, 2]))))
    print(f"{args.log.name}: {st.size} scans, stamps shared with the odometry: {shared:.0%}; stamp interval "
          f"1st/50th/99th percentile {np.percentile(dt, 1):.4f} / {np.median(dt):.4f} / {np.percentile(dt, 99):.4f} s, "
          f"mean {dt.mean():.4f} s")
    mov = dxy > 0.02
    ref = 0.5 * (dxy[:-2] + dxy[2:])
    m3 = ref > 0.05
    r3, q3 = dxy[1:-1][m3] / ref[m3], dt[1:-1][m3] / (0.5 * (dt[:-2] + dt[2:]))[m3]
    if q3.size > 2:
        print(f"odometry translation against the stamp interval ({m3.sum()} moving steps, each over its "
              f"neighbours'): correlation {np.corrcoef(r3, q3)[0, 1]:.3f}, slope {np.polyfit(q3, r3, 1)[0]:.3f} "
              "(1: read at the stamps)")
    fr = np.array([ahead(log, k, args.cone) for k in range(st.size)])
    dr = -np.diff(fr)
    m = mov & (dth < 0.01) & np.isfinite(dr) & (np.abs(dr - dxy) < 0.15)
    q = dt / dt.mean()
    print(f"straight forward steps ({m.sum()}): range change straight ahead / odometry translation, by stamp "
          "interval over its mean")
    print(f"{'interval / mean':>16} {'steps':>6} {'median ratio':>13} {'regular clock':>14}")
    for lo, hi in BINS:
        s = m & (q >= lo) & (q < hi)
        if s.any():
            print(f"{f'[{lo:g}, {hi:g})':>16} {int(s.sum()):>6} {np.median(dr[s] / dxy[s]):>13.3f} "
                  f"{np.median(1.0 / q[s]):>14.3f}")
    outer = [int((m & (q >= lo) & (q < hi)).sum()) for lo, hi in (BINS[0], BINS[2])]
    if sum(outer) < 5:
        print(f"the stamp intervals vary too little to tell ({outer[0]} short and {outer[1]} long straight steps, "
              "5 needed)")
        return 0
    if m.sum() > 10:
        slope = np.polyfit(q[m], dr[m] / dxy[m], 1)[0]
        verdict = ("the scans keep their own clock: each is paired with odometry off its acquisition by up to the "
                   "stamps' jitter" if slope < -0.5 else "the scans follow their stamps")
        print(f"slope of the ratio over the interval: {slope:.2f} (0: taken at the stamps; about -1: a regular "
              f"clock) — {verdict}")
    # the same against the odometry interpolated at the fitted clock's ticks (a check, not a bound)
    from ivslam_cli.slam.lidar.scan_clock import scan_clock

    try:
        clock = scan_clock(log.scans, "fitted", str(args.log))
    except Exception as exc:  # noqa: BLE001 - a log without a clock is an answer here
        print(f"no regular clock fits the stamps: {exc}")
        return 0
    g = st + clock.offset
    th = np.unwrap(op[:, 2])
    Pg = np.column_stack([np.interp(g, ot, op[:, 0]), np.interp(g, ot, op[:, 1]), np.interp(g, ot, th)])
    gxy = np.hypot(np.diff(Pg[:, 0]), np.diff(Pg[:, 1]))
    mg = m & (gxy > 0.02)
    print(f"{clock.text()}; the same ratio against the odometry interpolated at the ticks:")
    for lo, hi in BINS:
        s = mg & (q >= lo) & (q < hi)
        if s.any():
            print(f"{f'[{lo:g}, {hi:g})':>16} {int(s.sum()):>6} {np.median(dr[s] / gxy[s]):>13.3f}")
    if mg.sum() > 10:
        print(f"slope over the stamp interval: {np.polyfit(q[mg], dr[mg] / gxy[mg], 1)[0]:.2f} (0: the ticks are "
              "when the scans were taken)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
