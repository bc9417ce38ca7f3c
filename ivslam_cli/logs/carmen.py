"""CARMEN text logs (``.log``, ``.clf``, GMapping ``.gfs.log``; plain, gzip or xz).

Records read (every other keyword, e.g. ``NEFF``, ``PARAM`` except the laser offset,
``SYNC``, ``RLASER``, is ignored):

* ``FLASER n r1..rn x y th odom_x odom_y odom_th ipc_t host logger_t``: no angle
  fields; assumed 180° field of view from -90°, increment pi/n (n = 180, 360) or
  pi/(n-1) (n = 181, 361). The odometry pose at the scan is kept in ``meta``.
* ``ROBOTLASER1 type start fov res max_range acc remission_mode n r1..rn m e1..em
  laser_x laser_y laser_th robot_x robot_y robot_th tv rv fsd ssd turn ipc_t host t``.
* ``ODOM x y th tv rv accel ipc_t host logger_t`` -> odometry pose and (v, omega).

Stamps are the ``ipc_t`` field. When they cannot order the log (too few digits, mixed
clocks: :mod:`.stamps`), the records keep their file order with repaired stamps, and a note
says so. Without a stated maximum range, a value that is the
maximum of the whole log, above twice the median range, and occurs in >= 0.5% of
at least 1000 beams is the "no return" value
(81.83 m in the Intel log): ``range_max`` is set just below it, so those beams are
invalid and counted. Without ``ODOM`` lines, the FLASER odometry poses are the odometry.

The file is streamed (:func:`~.textfile.iter_lines`) into compact columns: memory stays
near the size of the numbers, whatever the file's size up to ``limits.TEXT_BYTES``.
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ivslam_cli import limits
from ivslam_cli.errors import LogError
from ivslam_cli.logs.conventions import ScanSink, make_odometry
from ivslam_cli.logs.model import Dropped, LogData, Provenance
from ivslam_cli.logs.stamps import file_order_stamps, unusable
from ivslam_cli.logs.textfile import iter_lines


def _fov(n: int) -> tuple[float, float]:
    inc = math.pi / (n - 1) if n % 2 == 1 else math.pi / n
    return -math.pi / 2, inc


@dataclass
class Records:
    """What a text laser log gives, in file order, in compact columns."""

    scan_meta: array = field(default_factory=lambda: array("d"))  # amin, inc, rmax (nan: unknown)
    scan_pose: array = field(default_factory=lambda: array("d"))  # odometry pose at each scan
    ranges: list = field(default_factory=list)  # float32 array per scan
    odom: array = field(default_factory=lambda: array("d"))  # x, y, th, v, w (nan: absent)
    stamp: array = field(default_factory=lambda: array("d"))  # every record, file order
    kind: array = field(default_factory=lambda: array("b"))  # 0 scan, 1 odometry
    beams: int = 0

    def add_scan(self, stamp: float, amin: float, inc: float, rmax: float, ranges: np.ndarray,
                 pose) -> None:
        limits.check("SCANS", len(self.ranges) + 1, "scans in the log")
        self.beams += ranges.size
        limits.check("BEAMS", self.beams, "beams in the log")
        self.scan_meta.extend((amin, inc, rmax))
        self.scan_pose.extend(pose)
        self.ranges.append(ranges)
        self.stamp.append(stamp)
        self.kind.append(0)

    def add_odom(self, stamp: float, row) -> None:
        limits.check("RECORDS", len(self.odom) // 5 + 1, "odometry records")
        self.odom.extend(row)
        self.stamp.append(stamp)
        self.kind.append(1)


def _ranges(tok: list[str], a: int, n: int, lineno: int) -> np.ndarray:
    if n > limits.get("BEAMS_PER_SCAN"):
        limits.check("BEAMS_PER_SCAN", n, f"line {lineno} declares beams")
    return np.array(tok[a:a + n], np.float32)


def read_carmen(path: Path) -> LogData:
    rec = Records()
    mount_x = 0.0
    bad = 0
    for lineno, line in enumerate(iter_lines(path), 1):
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
                r = _ranges(tok, 2, n, lineno)
                amin, inc = _fov(n)
                rest = [float(x) for x in tok[2 + n: 8 + n]]
                rec.add_scan(float(tok[8 + n]), amin, inc, math.nan, r, rest[3:6])
            elif key == "ROBOTLASER1":
                n = int(tok[8])
                if n <= 0 or len(tok) < 10 + n:
                    bad += 1
                    continue
                m = int(tok[9 + n])
                if m < 0 or len(tok) != 10 + n + m + 14:
                    bad += 1
                    continue
                r = _ranges(tok, 9, n, lineno)
                start, fov, res, rmax = (float(x) for x in tok[2:6])
                after = 10 + n + m
                inc = res if res else fov / max(n - 1, 1)
                rec.add_scan(float(tok[after + 11]), start, inc, rmax, r,
                             [float(x) for x in tok[after + 3: after + 6]])
            elif key == "ODOM":
                if len(tok) != 10:
                    bad += 1
                    continue
                rec.add_odom(float(tok[7]), [float(x) for x in tok[1:6]])
            elif key == "PARAM" and len(tok) > 2 and tok[1] == "robot_frontlaser_offset":
                mount_x = float(tok[2])
        except (ValueError, IndexError):
            bad += 1
    if not rec.ranges and not rec.odom:
        raise LogError("no FLASER, ROBOTLASER1 or ODOM records (empty or not a CARMEN log)",
                       path)
    dropped: list[Dropped] = []
    if bad:
        dropped.append(Dropped("records", bad, "malformed FLASER/ROBOTLASER1/ODOM lines "
                               "(wrong field count or not numbers)"))
    if not math.isfinite(mount_x):
        raise LogError("PARAM robot_frontlaser_offset is not a finite number", path)
    return assemble(path, "carmen", rec, dropped, mount=(mount_x, 0.0, 0.0),
                    scan_topic="FLASER/ROBOTLASER1", odom_topic="ODOM",
                    scan_pose_topic="FLASER odometry poses",
                    angles="FLASER: 180 deg field of view from -90 deg assumed")


def _no_return(allr: np.ndarray) -> float:
    fin = allr[np.isfinite(allr)]
    vmax = float(fin.max()) if fin.size else math.inf
    saturated = (fin.size >= 1000 and vmax > 2 * float(np.median(fin))
                 and np.count_nonzero(fin == vmax) >= 0.005 * allr.size)
    return vmax if saturated else math.nan


def assemble(path: Path, fmt: str, rec: Records, dropped: list[Dropped], *, mount, scan_topic: str,
             odom_topic: str, scan_pose_topic: str, angles: str) -> LogData:
    """The :class:`LogData` of a text laser log read into ``rec`` (CARMEN, GMapping .gfs)."""
    notes: list[str] = []
    meta: dict[str, object] = {}
    stamp = np.frombuffer(rec.stamp, np.float64).copy()
    kind = np.frombuffer(rec.kind, np.int8)
    why = unusable(stamp, np.where(kind == 0, "scan", "odometry"))
    if why is not None:
        stamp = file_order_stamps(stamp, kind)
        notes.append(f"stamps cannot order the records ({why}); records kept in file order, "
                     "with strictly increasing stamps (those out of order or tied interpolated by "
                     "their position in the file)")
        meta["stamps"] = "file order (the log's stamps cannot order it)"
    scan_stamp, odom_stamp = stamp[kind == 0], stamp[kind == 1]
    scans = None
    n_scans = len(rec.ranges)
    if n_scans:
        sm = np.frombuffer(rec.scan_meta, np.float64).reshape(-1, 3)
        allr = np.concatenate(rec.ranges)
        vmax = _no_return(allr)
        default_max = math.inf
        if not math.isnan(vmax):
            default_max = float(np.nextafter(np.float32(vmax), np.float32(0)))
            notes.append(f"value {vmax:g} m is the log's max-range 'no return' value")
        del allr
        sink = ScanSink(n_scans)
        for k in range(n_scans):
            rm = default_max if math.isnan(sm[k, 2]) else sm[k, 2]
            sink.add([k], [scan_stamp[k]], [sm[k, 0]], [sm[k, 1]], [0.0], [rm],
                     rec.ranges[k].reshape(1, -1))
        scans = sink.finish(dropped, zero_reason="beams equal to 0 (no return, marked invalid)",
                            mount=mount, frame_id="laser")
        meta["scan_odometry_pose"] = np.frombuffer(rec.scan_pose, np.float64).reshape(-1, 3).tolist()
        meta["angles"] = angles
    if rec.odom:
        a = np.frombuffer(rec.odom, np.float64).reshape(-1, 5)
        twist = a[:, 3:5] if np.isfinite(a[:, 3:5]).any() else None
        odometry = make_odometry(odom_stamp, a[:, 0:3], twist, dropped=dropped)
        src = odom_topic
    elif n_scans:
        odometry = make_odometry(scan_stamp, np.frombuffer(rec.scan_pose, np.float64).reshape(-1, 3),
                                 None, dropped=dropped)
        src = scan_pose_topic
    else:
        odometry = None
        src = odom_topic
    prov = Provenance(path=str(path), format=fmt,
                      topics={"scan": scan_topic, "odom": src} if scans else {"odom": src},
                      dropped=dropped, notes=notes)
    meta["counts"] = {scan_topic: n_scans, odom_topic: len(rec.odom) // 5}
    return LogData(provenance=prov, scans=scans, odometry=odometry, meta=meta)
