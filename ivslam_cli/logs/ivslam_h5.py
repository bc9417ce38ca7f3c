"""ivslam's own HDF5 log (what ``ivslam simulate -o LOG.h5`` writes).

Layout (version 1, root attribute ``ivslam_log_version = 1``)::

    /                       attrs: ivslam_log_version, meta_json, bounds_json, provenance_json
    /scans                  stamp angle_min angle_increment range_min range_max (S,) f8
                            time_increment (S,) f8, if the log records it
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

from ivslam_cli import limits
from ivslam_cli.errors import LogError
from ivslam_cli.logs.model import (
    Dropped, GroundTruth, LogData, Provenance, Scans)

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
    """Write ``log`` to ``path`` directly (no atomicity: see :func:`write_ivslam_h5`).

    The file is built in memory and written with plain file I/O, so a full disk is an
    ``OSError`` naming no HDF5 internals."""
    from ivslam_cli.results.hdf5 import hdf5_image

    image = hdf5_image(lambda f: _fill(f, log))
    with open(path, "wb") as fh:
        fh.write(image)


def _fill(f, log: LogData) -> None:
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
        if log.scans.time_increment is not None:
            _put(g, "time_increment", log.scans.time_increment)
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

    with atomic_output(path, force=force, kind="log") as tmp:
        write_h5_file(tmp, log)
    return Path(path)


def read_ivslam_h5(path: str | Path) -> LogData:
    """Read an ivslam HDF5 log; any problem is a one-line :class:`LogError`.

    Nothing is read before it is checked: every dataset must be numeric (no strings,
    compound or variable-length types) with the rank the layout gives, and its declared size
    within ``limits.BEAMS`` (ranges), ``SCANS`` (per-scan columns) or ``RECORDS`` (other
    streams); scan offsets must start at 0, never decrease and end at the number of ranges;
    scan stamps and angles must be finite and the stamps sorted. Odometry and observations go
    through the readers' conventions (non-finite rows dropped, stamps sorted, counted).
    """
    import h5py

    path = Path(path)
    if not path.is_file():
        raise LogError("no such file", path)
    try:
        with h5py.File(path, "r") as f:
            version = f.attrs.get("ivslam_log_version")
            if version is None:
                raise LogError("not an ivslam HDF5 log (no ivslam_log_version attribute)", path)
            try:
                version = int(np.asarray(version).reshape(-1)[0])
            except (TypeError, ValueError, IndexError, OverflowError):
                raise LogError("corrupt ivslam HDF5 log (bad ivslam_log_version attribute)", path) from None
            if version != LOG_VERSION:
                raise LogError(f"unsupported ivslam log version {version} (this reader: {LOG_VERSION})", path)
            return _read(f, path)
    except (LogError, limits.LimitExceeded) as exc:
        raise exc.about(path) from None
    except (OSError, KeyError, ValueError, TypeError, RuntimeError, AttributeError, RecursionError,
            OverflowError, IndexError) as exc:
        text = str(exc).splitlines()[0] if str(exc) else ""
        raise LogError(f"corrupt ivslam HDF5 log ({type(exc).__name__}: {text[:160]})", path) from None


class _Corrupt(LogError):
    pass


def _node(g, name: str):
    """``g[name]`` if present (a broken or looping link is corruption), else None."""
    import h5py

    try:
        if name not in g:
            return None
        obj = g[name]
    except (KeyError, RuntimeError, RecursionError, OSError, ValueError) as exc:
        raise _Corrupt(f"corrupt ivslam HDF5 log ({g.name.rstrip('/')}/{name} cannot be opened: "
                       f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__})") from None
    if not isinstance(obj, (h5py.Dataset, h5py.Group)):
        raise _Corrupt(f"corrupt ivslam HDF5 log ({g.name.rstrip('/')}/{name} is not a dataset or group)")
    return obj


def _ds(g, name: str, kinds: str, ndim: int, limit: str, *, required: bool = True, cols: int | None = None):
    """A checked dataset read into memory (see :func:`read_ivslam_h5`)."""
    import h5py

    where = f"{g.name.rstrip('/')}/{name}"
    obj = _node(g, name)
    if obj is None:
        if required:
            raise _Corrupt(f"corrupt ivslam HDF5 log (missing dataset {where})")
        return None
    if not isinstance(obj, h5py.Dataset):
        raise _Corrupt(f"corrupt ivslam HDF5 log ({where} is a group, not a dataset)")
    if obj.dtype.kind not in kinds or obj.dtype.fields is not None or obj.dtype.subdtype is not None:
        raise _Corrupt(f"corrupt ivslam HDF5 log ({where} has type {obj.dtype}, not a plain "
                       f"{'number' if kinds != 'b' else 'boolean'} type)")
    if obj.ndim != ndim or (cols is not None and obj.shape[1] != cols):
        raise _Corrupt(f"corrupt ivslam HDF5 log ({where} has shape {obj.shape})")
    limits.check(limit, int(np.prod(obj.shape, dtype=np.float64)), f"{where} declares values")
    return obj[()]


def _json_attr(f, name: str):
    raw = f.attrs.get(name)
    if raw is None:
        raise _Corrupt(f"corrupt ivslam HDF5 log (missing attribute {name})")
    if isinstance(raw, bytes):
        raw = raw.decode("utf-8")
    if not isinstance(raw, str):
        raise _Corrupt(f"corrupt ivslam HDF5 log (attribute {name} is not text)")
    limits.check("JSON_BYTES", len(raw), f"attribute {name} is bytes long")
    try:
        return json.loads(raw)
    except (ValueError, RecursionError):
        raise _Corrupt(f"corrupt ivslam HDF5 log (attribute {name} is not JSON)") from None


def _read(f, path: Path) -> LogData:
    from ivslam_cli.logs.conventions import count_out_of_order, make_observations, make_odometry

    prov = _json_attr(f, "provenance_json")
    bounds = _json_attr(f, "bounds_json")
    meta = _json_attr(f, "meta_json")
    if not (isinstance(prov, dict) and isinstance(bounds, dict) and isinstance(meta, dict)):
        raise _Corrupt("corrupt ivslam HDF5 log (provenance, bounds or meta is not a JSON object)")
    try:
        dropped = [Dropped(str(d[0]), int(d[1]), str(d[2])) for d in prov.get("dropped", [])]
        bounds = {str(k): float(v) for k, v in bounds.items()}
    except (TypeError, ValueError, IndexError, KeyError):
        raise _Corrupt("corrupt ivslam HDF5 log (malformed provenance or bounds)") from None
    log = LogData(
        provenance=Provenance(path=str(path), format="ivslam-h5",
                              topics={str(k): str(v) for k, v in dict(prov.get("topics", {})).items()},
                              dropped=dropped,
                              notes=[str(n) for n in prov.get("notes", [])] + [f"written from {prov.get('format')}"]),
        bounds=bounds, meta=meta)
    F, I, B = "fiu", "iu", "bu"  # noqa: E741
    g = _node(f, "scans")
    if g is not None:
        cols = {name: _ds(g, name, F, 1, "SCANS") for name in
                ("stamp", "angle_min", "angle_increment", "range_min", "range_max")}
        n = cols["stamp"].shape[0]
        if any(c.shape[0] != n for c in cols.values()):
            raise _Corrupt("corrupt ivslam HDF5 log (scan columns differ in length)")
        offsets = _ds(g, "offsets", I, 1, "SCANS").astype(np.int64)
        ranges = _ds(g, "ranges", F, 1, "BEAMS").astype(np.float32)
        valid = _ds(g, "valid", B, 1, "BEAMS").astype(bool)
        if (offsets.shape != (n + 1,) or (n and (offsets[0] != 0 or np.any(np.diff(offsets) < 0)))
                or offsets[-1] != ranges.shape[0] or valid.shape != ranges.shape):
            raise _Corrupt("corrupt ivslam HDF5 log (scan offsets do not match ranges)")
        if n:
            limits.check("BEAMS_PER_SCAN", int(np.diff(offsets).max()), "beams in one scan")
        angles = np.concatenate([cols["stamp"], cols["angle_min"], cols["angle_increment"]]).astype(np.float64)
        if not np.isfinite(angles).all() or np.any(cols["angle_increment"] == 0):
            raise _Corrupt("corrupt ivslam HDF5 log (non-finite scan stamps or angles, or a zero increment)")
        if count_out_of_order(cols["stamp"].astype(np.float64)):
            raise _Corrupt("corrupt ivslam HDF5 log (scan stamps not sorted)")
        mount = np.asarray(g.attrs.get("mount", (0.0, 0.0, 0.0)), dtype=np.float64).reshape(-1)
        if mount.shape != (3,) or not np.isfinite(mount).all():
            raise _Corrupt("corrupt ivslam HDF5 log (bad laser mount attribute)")
        ti = _ds(g, "time_increment", F, 1, "SCANS", required=False)
        if ti is not None and ti.shape[0] != n:
            raise _Corrupt("corrupt ivslam HDF5 log (scan columns differ in length)")
        log.scans = Scans(**{k: v.astype(np.float64) for k, v in cols.items()}, offsets=offsets,
                          ranges=ranges, valid=valid, mount=tuple(float(m) for m in mount),
                          frame_id=str(g.attrs.get("frame_id", "")),
                          time_increment=None if ti is None else ti.astype(np.float64))
    dropped = log.provenance.dropped
    g = _node(f, "odometry")
    if g is not None:
        stamp = _ds(g, "stamp", F, 1, "RECORDS")
        pose = _ds(g, "pose", F, 2, "RECORDS", required=False, cols=3)
        twist = _ds(g, "twist", F, 2, "RECORDS", required=False, cols=2)
        if any(a is not None and a.shape[0] != stamp.shape[0] for a in (pose, twist)):
            raise _Corrupt("corrupt ivslam HDF5 log (odometry columns differ in length)")
        log.odometry = make_odometry(stamp, pose, twist, dropped=dropped)
    for key in ("observations", "other_observations"):
        g = _node(f, key)
        if g is not None:
            stamp, rng, bearing = (_ds(g, name, F, 1, "RECORDS") for name in ("stamp", "range", "bearing"))
            lid = _ds(g, "landmark_id", I, 1, "RECORDS")
            if not stamp.shape == rng.shape == bearing.shape == lid.shape:
                raise _Corrupt(f"corrupt ivslam HDF5 log ({key} columns differ in length)")
            setattr(log, key, make_observations(stamp, lid.astype(np.int64), rng, bearing, dropped=dropped,
                                                stream=key))
    g = _node(f, "truth")
    if g is not None:
        t = GroundTruth(pose_stamp=_ds(g, "pose_stamp", F, 1, "RECORDS", required=False),
                        pose=_ds(g, "pose", F, 2, "RECORDS", required=False, cols=3),
                        landmark_id=_ds(g, "landmark_id", I, 1, "RECORDS", required=False),
                        landmark_xy=_ds(g, "landmark_xy", F, 2, "RECORDS", required=False, cols=2),
                        world=_ds(g, "world", F, 2, "RECORDS", required=False, cols=4))
        if (t.pose is None) != (t.pose_stamp is None) or (t.pose is not None and t.pose.shape[0] != t.pose_stamp.shape[0]):
            raise _Corrupt("corrupt ivslam HDF5 log (truth pose columns differ)")
        if (t.landmark_id is None) != (t.landmark_xy is None) or (
                t.landmark_id is not None and t.landmark_id.shape[0] != t.landmark_xy.shape[0]):
            raise _Corrupt("corrupt ivslam HDF5 log (truth landmark columns differ)")
        if t.landmark_id is not None:
            t.landmark_id = t.landmark_id.astype(np.int64)
        o = _node(g, "outliers")
        if o is not None:
            t.outliers = {str(k): _ds(o, k, B, 1, "BEAMS").astype(bool) for k in list(o.keys())}
        log.truth = t
    return log
