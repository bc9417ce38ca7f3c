"""UTIAS MRCLAM dataset directories (``Barcodes.dat``, ``RobotN_*.dat``; plain or ``.xz``).

One robot is read (``robot=N``, default 1), or all five (:func:`read_mrclam_all`: each robot's
log in ``LogData.robots``, sharing the landmarks). Measurements carry a *barcode*, mapped to a
subject through ``Barcodes.dat``: subjects 6-20 are landmarks (``observations``, id =
subject); measurements of robots (subjects 1-5, id = subject) and of barcodes not in
``Barcodes.dat`` (id = -barcode) go to ``other_observations``, never mixed in.
Odometry is the commanded twist (v, omega); ground truth: the robot's Vicon poses and
the surveyed landmark positions.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ivslam_cli.errors import LogError
from ivslam_cli.logs.conventions import make_observations, make_odometry
from ivslam_cli.logs.model import Dropped, GroundTruth, LogData, Provenance
from ivslam_cli.logs.textgrid import int_column, table

LANDMARK_SUBJECTS = range(6, 21)


def _file(root: Path, name: str, required: bool = True) -> Path | None:
    for p in (root / name, root / f"{name}.xz", root / f"{name}.gz"):
        if p.is_file():
            return p
    if required:
        raise LogError(f"MRCLAM file {name} missing", root)
    return None


def read_mrclam(root: Path, robot: int = 1) -> LogData:
    if not 1 <= robot <= 5:
        raise LogError(f"MRCLAM robot must be 1..5, not {robot}", root)
    dropped: list[Dropped] = []
    bc_path = _file(root, "Barcodes.dat")
    bc = table(bc_path, 2)
    bc = np.column_stack([int_column(bc[:, 0], "subject", bc_path), int_column(bc[:, 1], "barcode", bc_path)])
    subject_of = {int(b): int(s) for s, b in bc}
    meas_path = _file(root, f"Robot{robot}_Measurement.dat")
    meas = table(meas_path, 4)
    odo = table(_file(root, f"Robot{robot}_Odometry.dat"), 3)
    barcode = int_column(meas[:, 1], "barcode", meas_path)
    subject = np.array([subject_of.get(int(b), -int(b)) for b in barcode], np.int64).reshape(-1)
    is_lm = np.isin(subject, list(LANDMARK_SUBJECTS))
    n_robot = int(np.count_nonzero((subject >= 1) & (subject <= 5)))
    n_unknown = int(np.count_nonzero(subject < 0))
    if n_robot:
        dropped.append(Dropped("observations", n_robot, "measurements of other robots "
                               "(moved to other_observations)"))
    if n_unknown:
        dropped.append(Dropped("observations", n_unknown, "unknown barcodes "
                               "(moved to other_observations, id = -barcode)"))
    obs = make_observations(meas[is_lm, 0], subject[is_lm], meas[is_lm, 2], meas[is_lm, 3],
                            dropped=dropped)
    other = make_observations(meas[~is_lm, 0], subject[~is_lm], meas[~is_lm, 2],
                              meas[~is_lm, 3], dropped=dropped, stream="other_observations")
    odometry = make_odometry(odo[:, 0], None, odo[:, 1:3], dropped=dropped)
    truth = GroundTruth()
    gt_path = _file(root, f"Robot{robot}_Groundtruth.dat", required=False)
    if gt_path is not None:
        gt = table(gt_path, 4)
        gt = gt[np.argsort(gt[:, 0], kind="stable")]
        truth.pose_stamp, truth.pose = gt[:, 0], gt[:, 1:4]
    lm_path = _file(root, "Landmark_Groundtruth.dat", required=False)
    if lm_path is not None:
        lm = table(lm_path, 5)
        truth.landmark_id, truth.landmark_xy = int_column(lm[:, 0], "landmark id", lm_path), lm[:, 1:3]
    if obs is None and odometry is None:
        raise LogError(f"robot {robot}: no measurements and no odometry", root)
    prov = Provenance(path=str(root), format="mrclam",
                      topics={"observations": f"Robot{robot}_Measurement.dat",
                              "odom": f"Robot{robot}_Odometry.dat",
                              "truth": f"Robot{robot}_Groundtruth.dat"},
                      dropped=dropped,
                      notes=["odometry is the commanded twist (v, omega)"])
    return LogData(provenance=prov, odometry=odometry, observations=obs,
                   other_observations=other, truth=truth,
                   meta={"robot": robot, "barcodes": {int(b): s for b, s in subject_of.items()}})


ROBOTS = range(1, 6)


def read_mrclam_all(root: Path) -> LogData:
    """Every robot of the dataset: ``robots`` = ``[(1, log of robot 1), ..., (5, ...)]`` (the
    robots whose files are present); the top level holds the provenance (each robot's dropped
    records, prefixed ``robotN/``) and the landmark truth shared by all."""
    robots = []
    for r in ROBOTS:
        if _file(root, f"Robot{r}_Measurement.dat", required=False) is None:
            continue
        robots.append((r, read_mrclam(root, robot=r)))
    if not robots:
        raise LogError("no RobotN_Measurement.dat file", root)
    dropped = [Dropped(f"robot{r}/{d.stream}", d.count, d.reason) for r, log in robots for d in log.provenance.dropped]
    first = robots[0][1]
    truth = GroundTruth(landmark_id=first.truth.landmark_id, landmark_xy=first.truth.landmark_xy)
    topics = {f"robot{r}/{k}": v for r, log in robots for k, v in log.provenance.topics.items()}
    prov = Provenance(path=str(root), format="mrclam", topics=topics, dropped=dropped,
                      notes=["odometry is the commanded twist (v, omega)",
                             f"robots {', '.join(str(r) for r, _ in robots)} together (their measurements of each "
                             "other are observations between them)"])
    return LogData(provenance=prov, truth=truth, meta={"robot": "all", "barcodes": first.meta["barcodes"]},
                   robots=robots)
