"""Victoria Park graph text (GTSAM ``victoria_park.txt``; plain or compressed).

* ``ODOMETRY i j dx dy dth I11 I12 I13 I22 I23 I33``: pose j in the frame of pose i.
  Composed into ``Odometry.pose`` (pose 0 at the origin); the raw increments are kept
  in ``meta["increments"]`` (columns i, j, dx, dy, dth).
* ``LANDMARK i l x y c11 c12 c22``: landmark l seen from pose i at robot-frame (x, y)
  [m], converted to range = hypot(x, y), bearing = atan2(y, x).
Pose and landmark ids share one integer namespace, so the pose chain skips ids.
There are no timestamps: the pose id is the stamp (said in ``meta``); an observation's
stamp is the id of the pose it was made from.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ivslam_cli.errors import LogError
from ivslam_cli.logs.conventions import make_observations, make_odometry
from ivslam_cli.logs.model import Dropped, LogData, Provenance
from ivslam_cli.logs.textfile import read_text


def read_victoria(path: Path) -> LogData:
    odo, lm = [], []
    bad = 0
    for line in read_text(path).splitlines():
        tok = line.split()
        if not tok:
            continue
        try:
            if tok[0] == "ODOMETRY" and len(tok) >= 6:
                odo.append([float(x) for x in tok[1:6]])
            elif tok[0] == "LANDMARK" and len(tok) >= 5:
                lm.append([float(x) for x in tok[1:5]])
            else:
                bad += 1
        except ValueError:
            bad += 1
    if not odo:
        raise LogError("no ODOMETRY lines (empty or not a Victoria Park graph file)", path)
    dropped: list[Dropped] = []
    if bad:
        dropped.append(Dropped("records", bad, "unrecognised or malformed lines (dropped)"))
    inc = np.asarray(odo)
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
    pose[:, 2] = np.arctan2(np.sin(pose[:, 2]), np.cos(pose[:, 2]))
    pose_id = np.concatenate([inc[:1, 0], inc[:, 1]])
    odometry = make_odometry(pose_id, pose, None, dropped=dropped)
    obs = None
    if lm:
        a = np.asarray(lm)
        obs = make_observations(a[:, 0], a[:, 1].astype(np.int64), np.hypot(a[:, 2], a[:, 3]),
                                np.arctan2(a[:, 3], a[:, 2]), dropped=dropped)
    prov = Provenance(path=str(path), format="victoria",
                      topics={"odom": "ODOMETRY", "observations": "LANDMARK"}, dropped=dropped,
                      notes=["no timestamps: stamps are pose ids",
                             "odometry poses composed from the ODOMETRY increments"])
    return LogData(provenance=prov, odometry=odometry, observations=obs,
                   meta={"stamps": "pose id", "increments": inc.tolist()})
