"""CARMEN text logs (``.log``, ``.clf``, GMapping ``.gfs.log``; plain, gzip or xz).

Records read (every other keyword, e.g. ``NEFF``, ``PARAM`` except the laser offset,
``SYNC``, ``RLASER``, is ignored):

* ``FLASER n r1..rn x y th odom_x odom_y odom_th ipc_t host logger_t``: no angle
  fields; assumed 180° field of view from -90°, increment pi/n (n = 180, 360) or
  pi/(n-1) (n = 181, 361). The odometry pose at the scan is kept in ``meta``.
* ``ROBOTLASER1 type start fov res max_range acc remission_mode n r1..rn m e1..em
  laser_x laser_y laser_th robot_x robot_y robot_th tv rv fsd ssd turn ipc_t host t``.
* ``ODOM x y th tv rv accel ipc_t host logger_t`` -> odometry pose and (v, omega).

Stamps are the ``ipc_t`` field. Without a stated maximum range, a value that is the
maximum of the whole log, above twice the median range, and occurs in >= 0.5% of
at least 1000 beams is the "no return" value
(81.83 m in the Intel log): ``range_max`` is set just below it, so those beams are
invalid and counted. Without ``ODOM`` lines, the FLASER odometry poses are the odometry.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ivslam_cli.errors import LogError
from ivslam_cli.logs.conventions import ScanSink, make_odometry
from ivslam_cli.logs.model import LogData, Provenance
from ivslam_cli.logs.textfile import read_text


def _fov(n: int) -> tuple[float, float]:
    inc = math.pi / (n - 1) if n % 2 == 1 else math.pi / n
    return -math.pi / 2, inc


def read_carmen(path: Path) -> LogData:
    text = read_text(path)
    dropped, notes = [], []
    scan_rows: list[tuple] = []  # stamp, amin, inc, rmax(or nan), ranges
    scan_odo: list[tuple] = []
    odom: list[tuple] = []
    mount_x = 0.0
    bad = 0
    for lineno, line in enumerate(text.splitlines(), 1):
        tok = line.split()
        if not tok:
            continue
        key = tok[0]
        try:
            if key == "FLASER":
                n = int(tok[1])
                if n <= 0 or len(tok) != n + 11:
                    bad += 1
                    continue
                r = np.array(tok[2:2 + n], np.float32)
                amin, inc = _fov(n)
                rest = [float(x) for x in tok[2 + n: 8 + n]]
                scan_rows.append((float(tok[8 + n]), amin, inc, math.nan, r))
                scan_odo.append((float(tok[8 + n]), *rest[3:6]))
            elif key == "ROBOTLASER1":
                n = int(tok[8])
                m = int(tok[9 + n])
                if n <= 0 or m < 0 or len(tok) != 10 + n + m + 14:
                    bad += 1
                    continue
                r = np.array(tok[9:9 + n], np.float32)
                start, fov, res, rmax = (float(x) for x in tok[2:6])
                after = 10 + n + m
                stamp = float(tok[after + 11])
                scan_rows.append((stamp, start, res if res else fov / max(n - 1, 1), rmax, r))
                scan_odo.append((stamp, *(float(x) for x in tok[after + 3: after + 6])))
            elif key == "ODOM":
                if len(tok) != 10:
                    bad += 1
                    continue
                odom.append(tuple(float(x) for x in tok[1:6]) + (float(tok[7]),))
            elif key == "PARAM" and len(tok) > 2 and tok[1] == "robot_frontlaser_offset":
                mount_x = float(tok[2])
        except ValueError:
            bad += 1
    if not scan_rows and not odom:
        raise LogError("no FLASER, ROBOTLASER1 or ODOM records (empty or not a CARMEN log)",
                       path)
    if bad:
        from ivslam_cli.logs.model import Dropped

        dropped.append(Dropped("records", bad, "malformed FLASER/ROBOTLASER1/ODOM lines "
                               "(wrong field count or not numbers)"))
    scans = None
    meta: dict[str, object] = {}
    if scan_rows:
        allr = np.concatenate([row[4] for row in scan_rows])
        fin = allr[np.isfinite(allr)]
        vmax = float(fin.max()) if fin.size else math.inf
        saturated = (fin.size >= 1000 and vmax > 2 * float(np.median(fin))
                     and np.count_nonzero(fin == vmax) >= 0.005 * allr.size)
        default_max = float(np.nextafter(np.float32(vmax), np.float32(0))) if saturated \
            else math.inf
        if saturated:
            notes.append(f"value {vmax:g} m is the log's max-range 'no return' value")
        sink = ScanSink(len(scan_rows))
        for k, (stamp, amin, inc, rmax, r) in enumerate(scan_rows):
            rm = default_max if math.isnan(rmax) else rmax
            sink.add([k], [stamp], [amin], [inc], [0.0], [rm], r.reshape(1, -1))
        scans = sink.finish(dropped, zero_reason="beams equal to 0 (no return, marked invalid)",
                            mount=(mount_x, 0.0, 0.0), frame_id="laser")
        meta["scan_odometry_pose"] = [list(row[1:]) for row in scan_odo]
        meta["angles"] = "FLASER: 180 deg field of view from -90 deg assumed"
    if odom:
        a = np.asarray(odom, np.float64)
        odometry = make_odometry(a[:, 5], a[:, 0:3], a[:, 3:5], dropped=dropped)
        src = "ODOM"
    else:
        a = np.asarray(scan_odo, np.float64)
        odometry = make_odometry(a[:, 0], a[:, 1:4], None, dropped=dropped)
        src = "FLASER odometry poses"
    prov = Provenance(path=str(path), format="carmen",
                      topics={"scan": "FLASER/ROBOTLASER1", "odom": src} if scans else
                      {"odom": src}, dropped=dropped, notes=notes)
    meta["counts"] = {"FLASER/ROBOTLASER1": len(scan_rows), "ODOM": len(odom)}
    return LogData(provenance=prov, scans=scans, odometry=odometry, meta=meta)
