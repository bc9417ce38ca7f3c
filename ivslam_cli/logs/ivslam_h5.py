"""ivslam's own HDF5 log (what ``ivslam simulate -o LOG.h5`` writes).

Layout (version 1, root attribute ``ivslam_log_version = 1``)::

    /                       attrs: ivslam_log_version, meta_json, bounds_json, provenance_json
    /scans                  stamp angle_min angle_increment range_min range_max (S,) f8
                            offsets (S+1,) i8, ranges (B,) f4, valid (B,) bool
                            attrs: mount (3,) f8, frame_id
    /odometry               stamp (N,) f8, pose (N, 3) f8 [optional], twist (N, 2) f8 [optional]
    /observations           stamp range bearing (M,) f8, landmark_id (M,) i8
    /other_observations     same as /observations
    /truth                  pose_stamp (G,), pose (G, 3), landmark_id (L,), landmark_xy (L, 2),
                            world (K, 4)  [each optional]
    /truth/outliers/<name>  (n,) bool, one per stream

Absent streams are absent groups. Ragged scans are flat ``ranges`` + ``offsets`` (scan
``k`` is ``ranges[offsets[k]:offsets[k+1]]``). Non-empty datasets are chunked,
gzip + shuffle. ``meta_json``/``bounds_json`` are JSON (floats round-trip exactly).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ivslam_cli.errors import LogError
from ivslam_cli.logs.model import (
    Dropped, GroundTruth, LogData, Observations, Odometry, Provenance, Scans)

LOG_VERSION = 1
_SCAN_FIELDS = ("stamp", "angle_min", "angle_increment", "range_min", "range_max", "offsets", "ranges", "valid")
_OBS_FIELDS = ("stamp", "landmark_id", "range", "bearing")
_TRUTH_FIELDS = ("pose_stamp", "pose", "landmark_id", "landmark_xy", "world")


def _put(group, name: str, data) -> None:
    data = np.asarray(data)
    if data.size:
        group.create_dataset(name, data=data, chunks=True, compression="gzip", shuffle=True)
    else:
        group.create_dataset(name, data=data)


def write_h5_file(path: str | Path, log: LogData) -> None:
    """Write ``log`` to ``path`` directly (no atomicity: see :func:`write_ivslam_h5`)."""
    import h5py

    with h5py.File(path, "w") as f:
        f.attrs["ivslam_log_version"] = LOG_VERSION
        f.attrs["meta_json"] = json.dumps(log.meta)
        f.attrs["bounds_json"] = json.dumps(log.bounds)
        p = log.provenance
        f.attrs["provenance_json"] = json.dumps({
            "path": p.path, "format": p.format, "topics": p.topics, "notes": p.notes,
            "dropped": [[d.stream, d.count, d.reason] for d in p.dropped]})
        if log.scans is not None:
            g = f.create_group("scans")
            for name in _SCAN_FIELDS:
                _put(g, name, getattr(log.scans, name))
            g.attrs["mount"] = np.asarray(log.scans.mount, dtype=np.float64)
            g.attrs["frame_id"] = log.scans.frame_id
        if log.odometry is not None:
            g = f.create_group("odometry")
            for name in ("stamp", "pose", "twist"):
                if getattr(log.odometry, name) is not None:
                    _put(g, name, getattr(log.odometry, name))
        for key in ("observations", "other_observations"):
            obs = getattr(log, key)
            if obs is not None:
                g = f.create_group(key)
                for name in _OBS_FIELDS:
                    _put(g, name, getattr(obs, name))
        if log.truth is not None:
            g = f.create_group("truth")
            for name in _TRUTH_FIELDS:
                if getattr(log.truth, name) is not None:
                    _put(g, name, getattr(log.truth, name))
            o = g.create_group("outliers")
            for stream, mask in log.truth.outliers.items():
                _put(o, stream, np.asarray(mask, dtype=bool))


def write_ivslam_h5(path: str | Path, log: LogData, force: bool = False) -> Path:
    """Write ``log`` atomically (temp file beside ``path`` + rename); refuses to replace an
    existing file unless ``force``."""
    from ivslam_cli.atomic import atomic_output

    with atomic_output(path, force=force) as tmp:
        write_h5_file(tmp, log)
    return Path(path)


def read_ivslam_h5(path: str | Path) -> LogData:
    """Read an ivslam HDF5 log; any problem is a one-line :class:`LogError`."""
    import h5py

    path = Path(path)
    if not path.is_file():
        raise LogError("no such file", path)
    try:
        with h5py.File(path, "r") as f:
            version = f.attrs.get("ivslam_log_version")
            if version is None:
                raise LogError("not an ivslam HDF5 log (no ivslam_log_version attribute)", path)
            if int(version) != LOG_VERSION:
                raise LogError(f"unsupported ivslam log version {int(version)} (this reader: {LOG_VERSION})", path)
            return _read(f, path)
    except LogError:
        raise
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise LogError(f"corrupt ivslam HDF5 log ({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})",
                       path) from None


def _read(f, path: Path) -> LogData:
    def arr(g, name):
        return g[name][()] if name in g else None

    prov = json.loads(f.attrs["provenance_json"])
    log = LogData(
        provenance=Provenance(path=str(path), format="ivslam-h5", topics=dict(prov.get("topics", {})),
                              dropped=[Dropped(*d) for d in prov.get("dropped", [])],
                              notes=list(prov.get("notes", [])) + [f"written from {prov.get('format')}"]),
        bounds={k: float(v) for k, v in json.loads(f.attrs["bounds_json"]).items()},
        meta=json.loads(f.attrs["meta_json"]))
    if "scans" in f:
        g = f["scans"]
        log.scans = Scans(**{name: g[name][()] for name in _SCAN_FIELDS},
                          mount=tuple(float(m) for m in g.attrs["mount"]), frame_id=str(g.attrs["frame_id"]))
        if log.scans.offsets.shape != (len(log.scans) + 1,) or log.scans.offsets[-1] != log.scans.ranges.shape[0]:
            raise LogError("corrupt ivslam HDF5 log (scan offsets do not match ranges)", path)
    if "odometry" in f:
        g = f["odometry"]
        log.odometry = Odometry(stamp=g["stamp"][()], pose=arr(g, "pose"), twist=arr(g, "twist"))
    for key in ("observations", "other_observations"):
        if key in f:
            g = f[key]
            setattr(log, key, Observations(**{name: g[name][()] for name in _OBS_FIELDS}))
    if "truth" in f:
        g = f["truth"]
        log.truth = GroundTruth(**{name: arr(g, name) for name in _TRUTH_FIELDS})
        if "outliers" in g:
            log.truth.outliers = {k: v[()] for k, v in g["outliers"].items()}
    return log
