"""The metadata record of simulated logs (topic ``/ivslam/meta``, ``std_msgs/String``).

One JSON object, written once at the first stamp, so that any reader can recover what
the messages alone do not carry::

    {"ivslam_meta_version": 1,
     "meta":   {...},                       # LogData.meta (scenario, seed, sensor, ...)
     "bounds": {"range_abs": 0.05, ...},    # LogData.bounds (see ivslam_cli.simulate)
     "truth":  {"landmark_id": [...], "landmark_xy": [[x, y], ...],
                "world": [[x0, y0, x1, y1], ...],
                "outliers": {"observations": [i, ...], "scans": [...], "odometry": [...]}}}

``truth.outliers`` lists, per stream, the indices (in the stream's time order; for
``scans``, flat beam indices) of the measurements that break the bounds. True poses
travel on ``/ground_truth``. Floats are written with ``repr`` and read back exactly.
Pure stdlib + numpy: readers may import this module without loading any kernel.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

META_TOPIC = "/ivslam/meta"
META_VERSION = 1


def encode_meta(log) -> str:
    """The JSON text for a :class:`~ivslam_cli.logs.model.LogData`."""
    truth: dict = {}
    t = log.truth
    if t is not None:
        if t.landmark_id is not None:
            truth["landmark_id"] = np.asarray(t.landmark_id).tolist()
            truth["landmark_xy"] = np.asarray(t.landmark_xy).tolist()
        if t.world is not None:
            truth["world"] = np.asarray(t.world).tolist()
        truth["outliers"] = {k: np.flatnonzero(v).tolist() for k, v in t.outliers.items()}
        truth["outlier_lengths"] = {k: int(np.asarray(v).shape[0]) for k, v in t.outliers.items()}
    return json.dumps({"ivslam_meta_version": META_VERSION, "meta": log.meta,
                       "bounds": log.bounds, "truth": truth}, separators=(",", ":"))


@dataclass
class MetaRecord:
    meta: dict
    bounds: dict[str, float]
    landmark_id: np.ndarray | None = None
    landmark_xy: np.ndarray | None = None
    world: np.ndarray | None = None
    outliers: dict[str, np.ndarray] = field(default_factory=dict)  # boolean masks


def decode_meta(text: str) -> MetaRecord:
    """Parse :func:`encode_meta` output; raises ``ValueError`` on anything else."""
    doc = json.loads(text)
    if not isinstance(doc, dict) or doc.get("ivslam_meta_version") != META_VERSION:
        raise ValueError("not an ivslam metadata record (version 1)")
    truth = doc.get("truth", {})
    rec = MetaRecord(meta=doc.get("meta", {}), bounds={k: float(v) for k, v in doc.get("bounds", {}).items()})
    if "landmark_id" in truth:
        rec.landmark_id = np.asarray(truth["landmark_id"], dtype=np.int64)
        rec.landmark_xy = np.asarray(truth["landmark_xy"], dtype=np.float64).reshape(-1, 2)
    if "world" in truth:
        rec.world = np.asarray(truth["world"], dtype=np.float64).reshape(-1, 4)
    lengths = truth.get("outlier_lengths", {})
    for stream, idx in truth.get("outliers", {}).items():
        mask = np.zeros(int(lengths[stream]), dtype=bool)
        mask[np.asarray(idx, dtype=np.int64)] = True
        rec.outliers[stream] = mask
    return rec
