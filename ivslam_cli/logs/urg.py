"""CoreSLAM / BreezySLAM URG-04LX ``.dat`` logs (plain or compressed).

One scan per line: token 0 time [us], token 1 unknown, tokens 2-3 cumulative left and
right wheel ticks, tokens 4-23 auxiliary, tokens 24.. the 683 ranges [mm] of a Hokuyo
URG-04LX (240° field of view, 360/1024 deg steps, centred on the laser x axis).
Ranges 0 (no return) and 1-19 (error codes) are invalid; valid 20..5600 mm.
Odometry integrates the ticks with the rover geometry in :data:`ROVER` (midpoint rule);
the geometry used is written into ``LogData.meta``.
"""

from __future__ import annotations

import math
from array import array
from pathlib import Path

import numpy as np

from ivslam_cli import limits
from ivslam_cli.errors import LogError
from ivslam_cli.logs.conventions import ScanSink, make_odometry
from ivslam_cli.logs.model import Dropped, LogData, Provenance
from ivslam_cli.logs.textfile import iter_lines

ROVER = {"wheel_radius_m": 0.077, "half_axle_m": 0.165, "ticks_per_revolution": 2000,
         "laser_offset_x_m": 0.145}
FIRST_RANGE = 24
BEAMS = 683
INC = 2 * math.pi / 1024


def read_urg(path: Path) -> LogData:
    head = array("d")  # the FIRST_RANGE leading tokens of every scan line
    ranges = array("f")  # the BEAMS ranges [m]
    dropped: list[Dropped] = []
    short = 0
    for line in iter_lines(path):
        tok = line.split()
        if not tok:
            continue
        if len(tok) != FIRST_RANGE + BEAMS:
            short += 1
            continue
        try:
            row = np.array(tok, dtype=np.float64)
        except ValueError:
            raise LogError("non-numeric token in a URG .dat log", path) from None
        limits.check("SCANS", len(head) // FIRST_RANGE + 1, "scans in the log")
        limits.check("BEAMS", len(ranges) + BEAMS, "beams in the log")
        head.frombytes(row[:FIRST_RANGE].tobytes())
        ranges.frombytes((row[FIRST_RANGE:] * 1e-3).astype(np.float32).tobytes())
    if short:
        dropped.append(Dropped("records", short, f"lines without {FIRST_RANGE + BEAMS} tokens (dropped)"))
    if not head:
        raise LogError("no URG scan lines (empty or not a URG .dat log)", path)
    a = np.frombuffer(head, np.float64).reshape(-1, FIRST_RANGE)
    ticks = a[:, 2:4]
    ok = np.isfinite(ticks) & (ticks == np.round(ticks)) & (np.abs(ticks) < 2.0 ** 53)
    if not ok.all():
        k = int(np.flatnonzero(~ok.all(axis=1))[0])
        raise LogError(f"scan line {k + 1}: wheel ticks {ticks[k].tolist()} are not integers below 2^53 "
                       "(the odometry cannot be integrated past them)", path)
    stamp = a[:, 0] * 1e-6
    r = np.frombuffer(ranges, np.float32).reshape(-1, BEAMS)
    k = len(stamp)
    sink = ScanSink(k)
    sink.add(np.arange(k), stamp, np.full(k, -(BEAMS - 1) / 2 * INC), np.full(k, INC),
             np.full(k, 0.020), np.full(k, 5.6), r, "laser", error_codes_below=0.0195)
    scans = sink.finish(dropped, zero_reason="beams 0 (no return) or 1-19 mm (URG error "
                        "codes), marked invalid", mount=(ROVER["laser_offset_x_m"], 0, 0))
    # wheel ticks -> pose (x, y, theta), midpoint integration
    per_tick = 2 * math.pi * ROVER["wheel_radius_m"] / ROVER["ticks_per_revolution"]
    d_left = np.diff(a[:, 2]) * per_tick
    d_right = np.diff(a[:, 3]) * per_tick
    ds = 0.5 * (d_left + d_right)
    dth = (d_right - d_left) / (2 * ROVER["half_axle_m"])
    th = np.concatenate([[0.0], np.cumsum(dth)])
    mid = th[:-1] + 0.5 * dth
    x = np.concatenate([[0.0], np.cumsum(ds * np.cos(mid))])
    y = np.concatenate([[0.0], np.cumsum(ds * np.sin(mid))])
    dt = np.diff(stamp)
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.concatenate([[0.0], ds / dt])
        w = np.concatenate([[0.0], dth / dt])
    odometry = make_odometry(stamp, np.column_stack([x, y, th]), np.column_stack([v, w]),
                             dropped=dropped)
    prov = Provenance(path=str(path), format="urg",
                      topics={"scan": "URG-04LX ranges", "odom": "wheel ticks"},
                      dropped=dropped,
                      notes=["odometry integrated from wheel ticks with the rover geometry "
                             "in meta['rover']"])
    return LogData(provenance=prov, scans=scans, odometry=odometry,
                   meta={"rover": dict(ROVER), "ticks": a[:, 2:4].astype(np.int64).tolist()})
