"""GMapping's own log output (``.gfs`` files; plain, gzip or xz), as written by
``gfs_simplegui``/``gfs2log`` users' GMapping (``GridSlamProcessor``'s output stream).

Records read:

* ``ODOM x y theta time``: the raw odometry pose at each laser reading -> odometry (poses,
  no twist);
* ``LASER_READING n r1..rn x y theta time``: a processed laser reading (GMapping writes one
  per map update, from the second on) with the odometry pose at the reading -> a scan, the
  pose kept in ``meta["scan_odometry_pose"]``. The file has no angle fields: the beam
  geometry is GMapping's own (``gfs2log``): n = 180, 181, 360, 361 a 180° field of view from
  −90° (the CARMEN ``FLASER`` rule), n = 540, 541 (SICK S300) from −2.351831 rad in steps of
  0.008727 rad, n = 683 (Hokuyo URG) from −2.094395 rad in steps of 0.006136 rad; a reading
  of another size is dropped and counted;
* ``SIMULATOR_POS x y theta time``: the true pose (simulated runs) -> ground truth.

GMapping's estimates — ``ODO_UPDATE``, ``SM_UPDATE`` (particles), ``RESAMPLE``, ``NEFF``,
``ENTROPY``, ``FRAME`` — and comments are counted (``meta["counts"]``) and not used: they are
no measurement. Stamps, the "no return" value and memory are handled as in
:mod:`.carmen`.
"""

from __future__ import annotations

import math
from array import array
from pathlib import Path

import numpy as np

from ivslam_cli import limits
from ivslam_cli.errors import LogError
from ivslam_cli.logs.carmen import Records, _fov, _ranges, assemble
from ivslam_cli.logs.model import Dropped, GroundTruth, LogData
from ivslam_cli.logs.textfile import iter_lines

FORMAT = "gfs"
ESTIMATES = ("ODO_UPDATE", "SM_UPDATE", "RESAMPLE", "NEFF", "ENTROPY", "FRAME")
COMMENTS = ("COMMENT", "#COMMENT", "#GFS_COMMENT:", "#GFS_COMMENT")
#: keywords only GMapping's output has (how the format is recognised)
KEYS = ("LASER_READING", "ODO_UPDATE", "SM_UPDATE", "RESAMPLE", "SIMULATOR_POS", "ENTROPY", "FRAME")


def beam_geometry(n: int) -> tuple[float, float] | None:
    """(angle_min, increment) GMapping uses for an ``n``-beam reading, None if unknown."""
    if n in (180, 181, 360, 361):
        return _fov(n)
    if n in (540, 541):
        return -2.351831, 0.008727
    if n == 683:
        return -2.094395, 0.006136
    return None


def read_gfs(path: Path) -> LogData:
    rec = Records()
    truth = array("d")  # x, y, theta, time
    counts = {k: 0 for k in ("LASER_READING", "ODOM", "SIMULATOR_POS", *ESTIMATES)}
    bad = unknown_fov = 0
    sizes: set[int] = set()
    for lineno, line in enumerate(iter_lines(path), 1):
        tok = line.split()
        if not tok:
            continue
        key = tok[0]
        if key in ESTIMATES:
            counts[key] += 1
            continue
        if key in COMMENTS or key.startswith("#"):
            continue
        try:
            if key == "LASER_READING":
                n = int(tok[1])
                if n <= 0 or len(tok) != n + 6:
                    bad += 1
                    continue
                geom = beam_geometry(n)
                if geom is None:
                    unknown_fov += 1
                    sizes.add(n)
                    continue
                r = _ranges(tok, 2, n, lineno)
                x, y, th, t = (float(v) for v in tok[2 + n: 6 + n])
                rec.add_scan(t, geom[0], geom[1], math.nan, r, (x, y, th))
                counts[key] += 1
            elif key == "ODOM":
                if len(tok) != 5:
                    bad += 1
                    continue
                x, y, th, t = (float(v) for v in tok[1:5])
                rec.add_odom(t, (x, y, th, math.nan, math.nan))
                counts[key] += 1
            elif key == "SIMULATOR_POS":
                if len(tok) != 5:
                    bad += 1
                    continue
                limits.check("RECORDS", len(truth) // 4 + 1, "SIMULATOR_POS records")
                truth.extend([float(v) for v in tok[1:5]])
                counts[key] += 1
            else:
                bad += 1
        except (ValueError, IndexError):
            bad += 1
    if not rec.ranges and not rec.odom:
        raise LogError("no LASER_READING or ODOM records (empty, or not GMapping .gfs output)", path)
    dropped: list[Dropped] = []
    if bad:
        dropped.append(Dropped("records", bad, "malformed or unknown lines (wrong field count or "
                               "not numbers; dropped)"))
    if unknown_fov:
        dropped.append(Dropped("scans", unknown_fov, "LASER_READING of a size with no known beam "
                               f"geometry ({', '.join(map(str, sorted(sizes)))} beams; dropped)"))
    log = assemble(path, FORMAT, rec, dropped, mount=(0.0, 0.0, 0.0), scan_topic="LASER_READING",
                   odom_topic="ODOM", scan_pose_topic="LASER_READING odometry poses",
                   angles="GMapping's beam geometry for the reading's size (see ivslam_cli.logs.gfs)")
    if truth:
        a = np.frombuffer(truth, np.float64).reshape(-1, 4)
        ok = np.isfinite(a).all(axis=1)
        if not ok.all():
            dropped.append(Dropped("truth", int((~ok).sum()), "rows with NaN/inf (dropped)"))
        a = a[ok][np.argsort(a[ok][:, 3], kind="stable")]
        log.truth = GroundTruth(pose_stamp=a[:, 3], pose=a[:, 0:3])
    log.provenance.notes.append("GMapping's estimates (ODO_UPDATE, SM_UPDATE, RESAMPLE, NEFF, FRAME) "
                                "are not measurements: counted, not used")
    log.meta["counts"] = counts
    return log
