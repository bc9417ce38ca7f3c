"""Victoria Park graph text (GTSAM ``victoria_park.txt``; plain or compressed).

* ``ODOMETRY i j dx dy dth I11 I12 I13 I22 I23 I33``: pose j in the frame of pose i.
  Composed into ``Odometry.pose`` (pose 0 at the origin); the raw increments are kept
  in ``meta["increments"]`` (columns i, j, dx, dy, dth).
* ``LANDMARK i l x y c11 c12 c22``: landmark l seen from pose i at robot-frame (x, y)
  [m], converted to range = hypot(x, y), bearing = atan2(y, x).
Pose and landmark ids share one integer namespace, so the pose chain skips ids.
There are no timestamps: the pose id is the stamp (said in ``meta``); an observation's
stamp is the id of the pose it was made from. Ids must be integers in [0, 2^31); an
ODOMETRY line with a NaN or infinite increment is an error naming the line (every later pose
would be unknown). Other malformed lines are dropped and counted.
"""

from __future__ import annotations

import math
from array import array
from pathlib import Path

import numpy as np

from ivslam_cli import limits
from ivslam_cli.errors import LogError
from ivslam_cli.logs.conventions import make_observations, make_odometry
from ivslam_cli.logs.model import Dropped, LogData, Provenance
from ivslam_cli.logs.textfile import iter_lines


ID_LIMIT = 2 ** 31  # ids are written as int32 (LandmarkObservations)


def _id(token: str) -> int:
    """An integer id token (``"12"``, or ``"12.0"``), in [0, 2^31)."""
    try:
        v = int(token)
    except ValueError:
        f = float(token)
        if not (math.isfinite(f) and f.is_integer()):
            raise ValueError(f"id {token!r} is not an integer") from None
        v = int(f)
    if not 0 <= v < ID_LIMIT:
        raise ValueError(f"id {token} is outside [0, 2^31)")
    return v


def read_victoria(path: Path) -> LogData:
    odo, lm = array("d"), array("d")  # i, j, dx, dy, dth | i, l, x, y
    bad = 0
    for lineno, line in enumerate(iter_lines(path), 1):
        tok = line.split()
        if not tok:
            continue
        try:
            if tok[0] == "ODOMETRY" and len(tok) >= 6:
                row = [_id(tok[1]), _id(tok[2])] + [float(x) for x in tok[3:6]]
                if not all(math.isfinite(v) for v in row[2:]):
                    raise LogError(f"line {lineno}: ODOMETRY {row[0]} -> {row[1]} has a NaN or infinite "
                                   "increment: the pose chain cannot be composed past it", path)
                limits.check("RECORDS", len(odo) // 5 + 1, "ODOMETRY lines")
                odo.extend(row)
            elif tok[0] == "LANDMARK" and len(tok) >= 5:
                row = [_id(tok[1]), _id(tok[2])] + [float(x) for x in tok[3:5]]
                limits.check("RECORDS", len(lm) // 4 + 1, "LANDMARK lines")
                lm.extend(row)
            else:
                bad += 1
        except ValueError:
            bad += 1
    if not odo:
        raise LogError("no ODOMETRY lines (empty or not a Victoria Park graph file)", path)
    dropped: list[Dropped] = []
    if bad:
        dropped.append(Dropped("records", bad, "unrecognised or malformed lines (dropped)"))
    inc = np.frombuffer(odo, np.float64).reshape(-1, 5)
    inc = inc[np.argsort(inc[:, 0], kind="stable")]
    if not np.all(inc[1:, 0] == inc[:-1, 1]):
        raise LogError("ODOMETRY lines do not form one chain of poses", path)
    n = len(inc) + 1
    pose = np.zeros((n, 3))
    for k in range(1, n):  # compose x_k = x_{k-1} (+) u_k (sequential by nature)
        x, y, th = pose[k - 1]
        dx, dy, dth = inc[k - 1, 2:5]
        c, s = np.cos(th), np.sin(th)
        pose[k] = (x + c * dx - s * dy, y + s * dx + c * dy, th + dth)
    bad_pose = np.flatnonzero(~np.isfinite(pose).all(axis=1))
    if bad_pose.size:
        k = int(bad_pose[0])
        raise LogError(f"the pose chain overflows at ODOMETRY {int(inc[k - 1, 0])} -> {int(inc[k - 1, 1])} "
                       "(the composed pose is not finite: an increment too large?)", path)
    pose[:, 2] = np.arctan2(np.sin(pose[:, 2]), np.cos(pose[:, 2]))
    pose_id = np.concatenate([inc[:1, 0], inc[:, 1]])
    odometry = make_odometry(pose_id, pose, None, dropped=dropped)
    obs = None
    if lm:
        a = np.frombuffer(lm, np.float64).reshape(-1, 4)
        obs = make_observations(a[:, 0], a[:, 1].astype(np.int64), np.hypot(a[:, 2], a[:, 3]),
                                np.arctan2(a[:, 3], a[:, 2]), dropped=dropped)
    prov = Provenance(path=str(path), format="victoria",
                      topics={"odom": "ODOMETRY", "observations": "LANDMARK"}, dropped=dropped,
                      notes=["no timestamps: stamps are pose ids",
                             "odometry poses composed from the ODOMETRY increments"])
    return LogData(provenance=prov, odometry=odometry, observations=obs,
                   meta={"stamps": "pose id", "increments": inc.tolist()})
