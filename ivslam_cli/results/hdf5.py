"""Read and write results as HDF5 (schema version 1, described in ``SCHEMA.md``).

Design: one group per part of :class:`~ivslam_cli.results.model.Result`; ragged data are
flat arrays + offsets; text columns are int32 codes + a small vocabulary dataset (never
variable-length data that grows with the log); datasets of 4 KiB or more are chunked and
gzip-compressed with the shuffle filter; the default libver is kept (readable by older
HDF5 libraries). Files are written atomically (temp file + ``os.replace``).

Reading checks the format marker and version first and turns any failure (not HDF5,
truncated, missing part, wrong shape) into a one-line :class:`IvslamError`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ivslam_cli import limits
from ivslam_cli.errors import IvslamError
from ivslam_cli.logs.model import Dropped, GroundTruth
from ivslam_cli.atomic import atomic_path
from ivslam_cli.results.model import (
    Consistency,
    EmptyEvents,
    Landmarks,
    LogOddsGrid,
    MapGrid,
    PairSubpavings,
    Poses,
    PoseSets,
    Rejections,
    RelativePoses,
    Result,
    Loops,
    Submaps,
    ResultProvenance,
    Robots,
    WidthHistory,
    _str_array,
)

SCHEMA_VERSION = 2
FORMAT_NAME = "ivslam-result"
COMPRESS_MIN_BYTES = 4096
_STR = h5py.string_dtype("utf-8")


# ------------------------------------------------------------------ write helpers
def _put(g: h5py.Group, name: str, arr: Any, dtype: Any = None) -> None:
    a = np.ascontiguousarray(arr, dtype=dtype)
    if a.nbytes >= COMPRESS_MIN_BYTES:
        g.create_dataset(name, data=a, chunks=True, compression="gzip", compression_opts=4, shuffle=True)
    else:
        g.create_dataset(name, data=a)


def _put_grid(g: h5py.Group, grid: MapGrid) -> None:
    g.attrs["frame"] = grid.frame
    g.attrs["origin"] = np.asarray(grid.origin, dtype=np.float64)
    g.attrs["resolution"] = np.float64(grid.resolution)
    _put_image(g, "state", np.ascontiguousarray(grid.state, dtype=np.uint8))


def _put_image(g: h5py.Group, name: str, a: np.ndarray) -> None:
    """A 2-D grid, chunked in tiles of at most 256 × 256 and gzip + shuffle (empty: plain)."""
    if a.size:
        chunks = (min(256, a.shape[0]), min(256, a.shape[1]))
        g.create_dataset(name, data=a, chunks=chunks, compression="gzip", compression_opts=4, shuffle=True)
    else:
        g.create_dataset(name, data=a)


def _put_text(g: h5py.Group, name: str, values: np.ndarray) -> None:
    """A text column as ``<name>_code`` (int32) + ``<name>_vocab`` (sorted unique strings)."""
    vocab, codes = np.unique(np.asarray(values, dtype=str), return_inverse=True)
    _put(g, f"{name}_code", codes.reshape(-1), np.int32)
    g.create_dataset(f"{name}_vocab", data=np.asarray(vocab, dtype=object), dtype=_STR)


def _write(f: h5py.File, r: Result) -> None:
    f.attrs["format"] = FORMAT_NAME
    f.attrs["ivslam_result_version"] = np.int64(SCHEMA_VERSION)
    f.attrs["mode"] = r.mode
    f.attrs["runtime_s"] = np.float64(r.runtime_s)

    p = r.provenance
    g = f.create_group("provenance")
    for key in ("ivslam_version", "command", "input_path", "input_sha256", "input_format"):
        g.attrs[key] = getattr(p, key)
    g.attrs["config_json"] = json.dumps(p.config, sort_keys=True)
    g.attrs["topics_json"] = json.dumps(p.topics, sort_keys=True)
    g.attrs["notes_json"] = json.dumps(list(p.notes))
    d = g.create_group("dropped")
    _put_text(d, "stream", _str_array([x.stream for x in p.dropped]))
    _put(d, "count", np.asarray([x.count for x in p.dropped], dtype=np.int64))
    _put_text(d, "reason", _str_array([x.reason for x in p.dropped]))

    if r.poses is not None:
        g = f.create_group("poses")
        g.attrs["frame"] = r.poses.frame
        g.attrs["origin_stamp"] = np.float64(r.poses.origin_stamp)
        _put(g, "stamp", r.poses.stamp, np.float64)
        _put(g, "box", r.poses.box, np.float64)
        if r.poses.submap is not None:
            _put(g, "submap", r.poses.submap, np.int64)
            _put(g, "relative", r.poses.relative, np.float64)
    if r.submaps is not None:
        sm = r.submaps
        g = f.create_group("submaps")
        g.attrs["resolution"] = np.float64(sm.resolution)
        for name, dt in (("anchor", np.int64), ("anchor_box", np.float64), ("origin", np.float64),
                         ("shape", np.int64), ("member_offsets", np.int64), ("member_row", np.int64),
                         ("member_box", np.float64)):
            _put(g, name, getattr(sm, name), dt)
        _put(g, "member_mapped", np.asarray(sm.member_mapped, bool).astype(np.uint8), np.uint8)
        st = np.ascontiguousarray(sm.state, dtype=np.uint8)
        if st.size:
            g.create_dataset("state", data=st, chunks=(min(1 << 16, st.size),), compression="gzip",
                             compression_opts=4, shuffle=True)
        else:
            g.create_dataset("state", data=st)
    if r.loops is not None:
        lp = r.loops
        g = f.create_group("loops")
        g.attrs["sweeps"] = np.int64(lp.sweeps)
        for name, dt in (("row", np.int64), ("submap", np.int64), ("home", np.int64), ("prior", np.float64),
                         ("box", np.float64), ("beams", np.int64), ("edge_a", np.int64), ("edge_b", np.int64),
                         ("edge_box", np.float64), ("edge_kind", np.int64), ("anchor_box_open", np.float64)):
            _put(g, name, getattr(lp, name), dt)
        _put(g, "empty", np.asarray(lp.empty, bool).astype(np.uint8), np.uint8)

    if r.pose_sets is not None:
        g = f.create_group("pose_sets")
        _put(g, "offsets", r.pose_sets.offsets, np.int64)
        _put(g, "boxes", np.asarray(r.pose_sets.boxes).reshape(-1, 3, 2), np.float64)
    if r.robots is not None:
        g = f.create_group("robots")
        _put(g, "id", r.robots.id, np.int64)
        _put(g, "pose_offsets", r.robots.pose_offsets, np.int64)
        _put(g, "truth_offsets", r.robots.truth_offsets, np.int64)
    if r.relative is not None:
        g = f.create_group("relative")
        g.attrs["definition"] = r.relative.definition
        _put(g, "pairs", np.asarray(r.relative.pairs).reshape(-1, 2), np.int64)
        _put(g, "box", np.asarray(r.relative.box).reshape(-1, 3, 2), np.float64)
    if r.landmarks is not None:
        g = f.create_group("landmarks")
        _put(g, "id", r.landmarks.id, np.int64)
        _put(g, "box", r.landmarks.box, np.float64)
        ref = r.landmarks.reference_id
        g.attrs["reference_id"] = np.int64(-1 if ref is None else ref)
        g.attrs["has_reference"] = np.bool_(ref is not None)
    if r.pairs is not None:
        g = f.create_group("pairs")
        _put(g, "i", r.pairs.i, np.int64)
        _put(g, "j", r.pairs.j, np.int64)
        _put(g, "offsets", r.pairs.offsets, np.int64)
        _put(g, "boxes", r.pairs.boxes, np.float64)
        _put(g, "label", r.pairs.label, np.uint8)
    for name, grid in (("map", r.grid), ("global_map", r.global_map)):
        if grid is not None:
            _put_grid(f.create_group(name), grid)
    if r.logodds is not None:
        lo = r.logodds
        g = f.create_group("logodds")
        for key in ("l_occ", "l_free", "l_min", "l_max"):
            g.attrs[key] = np.float64(getattr(lo, key))
        g.attrs["scans"] = np.int64(lo.scans)
        g.attrs["beams"] = np.int64(lo.beams)
        g.attrs["guaranteed"] = np.bool_(False)
        _put_image(g, "value", np.ascontiguousarray(lo.value, dtype=np.float32))

    c = r.consistency
    g = f.create_group("consistency")
    g.attrs["assumption"] = c.assumption
    g.attrs["stopped"] = c.stopped
    q = g.create_group("q")
    for fam, val in c.q.items():
        q.attrs[fam] = np.int64(val)
    e = g.create_group("empty_events")
    _put(e, "stamp", c.empty_events.stamp, np.float64)
    _put(e, "step", c.empty_events.step, np.int64)
    _put_text(e, "constraint", c.empty_events.constraint)
    _put(e, "entity", np.asarray(c.empty_events.entity).reshape(-1, 2), np.int64)
    _put(e, "measurement", c.empty_events.measurement, np.int64)
    _put_text(e, "text", c.empty_events.text)
    rj = g.create_group("rejected")
    _put_text(rj, "stream", c.rejected.stream)
    _put(rj, "index", c.rejected.index, np.int64)
    _put_text(rj, "reason", c.rejected.reason)
    w = g.create_group("widths")
    for kind, h in c.widths.items():
        k = w.create_group(kind)
        k.attrs["definition"] = h.definition
        _put(k, "entity", np.asarray(h.entity).reshape(-1, 2), np.int64)
        _put(k, "step", h.step, np.int64)
        _put(k, "stamp", h.stamp, np.float64)
        _put(k, "width", h.width, np.float64)

    if r.truth is not None:
        t = r.truth
        g = f.create_group("truth")
        for name, dt in (
            ("pose_stamp", np.float64),
            ("pose", np.float64),
            ("landmark_id", np.int64),
            ("landmark_xy", np.float64),
            ("world", np.float64),
        ):
            val = getattr(t, name)
            if val is not None:
                _put(g, name, val, dt)
        o = g.create_group("outliers")
        for stream, mask in t.outliers.items():
            _put(o, stream, np.asarray(mask, dtype=bool).astype(np.uint8))

    s = f.create_group("stats")
    for key, val in r.stats.items():
        s.attrs[key] = val


def write_result(path: str | Path, result: Result, *, force: bool = False) -> None:
    """Write ``result`` to ``path`` atomically; an existing file is refused unless ``force``
    (and then only a previous result is replaced).

    Raises ValueError if the Result is malformed (a pipeline bug) before touching the disk.
    The file is built in memory and written with plain file I/O, so a full disk is one
    :class:`~ivslam_cli.errors.OutputError` (libhdf5 never meets the failing write).
    """
    result.validate()
    image = hdf5_image(lambda f: _write(f, result))
    with atomic_path(path, force=force, kind="result") as tmp:
        with open(tmp, "wb") as fh:
            fh.write(image)


def hdf5_image(fill) -> memoryview:
    """The bytes of an HDF5 file built in memory by ``fill(h5py.File)``."""
    import io

    buf = io.BytesIO()
    with h5py.File(buf, "w") as f:
        fill(f)
    return buf.getbuffer()


# ------------------------------------------------------------------- read helpers
class _Corrupt(Exception):
    pass


def _dataset(g: h5py.Group, name: str, kinds: str = "biuf") -> h5py.Dataset:
    """``g[name]``, checked before anything is read: a dataset (not a group, broken or looping
    link) of a plain type of ``kinds`` whose declared size is within the limits (a map grid's
    cells ``limits.CELLS``, any other dataset ``limits.ROWS``)."""
    where = f"{g.name.rstrip('/')}/{name}"
    try:
        if name not in g:
            raise _Corrupt(f"missing dataset {where}")
        ds = g[name]
    except (KeyError, RuntimeError, RecursionError, ValueError, OSError) as exc:
        raise _Corrupt(f"{where} cannot be opened ({_first_line(exc)})") from None
    if not isinstance(ds, h5py.Dataset):
        raise _Corrupt(f"{where} is not a dataset")
    if ds.dtype.kind not in kinds or ds.dtype.fields is not None or ds.dtype.subdtype is not None:
        raise _Corrupt(f"{where} has type {ds.dtype}, not a plain {'number' if kinds == 'biuf' else 'text'} type")
    limit = "CELLS" if name in ("state", "value") else "ROWS"
    limits.check(limit, float(np.prod(ds.shape, dtype=np.float64)), f"{where} declares values")
    return ds


def _get(g: h5py.Group, name: str, dtype: Any) -> np.ndarray:
    return np.asarray(_dataset(g, name)[()], dtype=dtype)


def _get_grid(g: h5py.Group) -> MapGrid:
    return MapGrid(origin=np.asarray(_attr(g, "origin"), dtype=np.float64), resolution=float(_attr(g, "resolution")),
                   state=_get(g, "state", np.uint8), frame=str(_attr(g, "frame")) if "frame" in g.attrs else "proven")


def _get_text(g: h5py.Group, name: str) -> np.ndarray:
    codes = _get(g, f"{name}_code", np.int64)
    if f"{name}_vocab" not in g:
        raise _Corrupt(f"missing dataset {g.name}/{name}_vocab")
    vocab = np.asarray(_dataset(g, f"{name}_vocab", "SOU").asstr()[()], dtype=object)
    if codes.size == 0:
        return _str_array()
    if codes.min() < 0 or codes.max() >= vocab.shape[0]:
        raise _Corrupt(f"{g.name}/{name}_code out of range of its vocabulary")
    return np.asarray(vocab[codes], dtype=str)


def _attr(g: h5py.Group | h5py.File, name: str) -> Any:
    if name not in g.attrs:
        raise _Corrupt(f"missing attribute {name!r} on {g.name}")
    v = g.attrs[name]
    if isinstance(v, (bytes, str)):
        limits.check("JSON_BYTES", len(v), f"attribute {name!r} is bytes long")
    if isinstance(v, bytes):
        return v.decode("utf-8")
    if isinstance(v, np.ndarray):
        return v
    return v.item() if isinstance(v, np.generic) else v


def _group(f: h5py.File, name: str) -> h5py.Group:
    if name not in f:
        raise _Corrupt(f"missing group /{name}")
    return f[name]


def _read(f: h5py.File) -> Result:
    g = _group(f, "provenance")
    d = _group(g, "dropped")
    streams, counts, reasons = _get_text(d, "stream"), _get(d, "count", np.int64), _get_text(d, "reason")
    if not (streams.shape == counts.shape == reasons.shape):
        raise _Corrupt("provenance/dropped columns differ in length")
    prov = ResultProvenance(
        ivslam_version=str(_attr(g, "ivslam_version")),
        command=str(_attr(g, "command")),
        config=json.loads(_attr(g, "config_json")),
        input_path=str(_attr(g, "input_path")),
        input_sha256=str(_attr(g, "input_sha256")),
        input_format=str(_attr(g, "input_format")),
        topics=json.loads(_attr(g, "topics_json")),
        dropped=[Dropped(str(s), int(n), str(why)) for s, n, why in zip(streams, counts, reasons)],
        notes=list(json.loads(_attr(g, "notes_json"))),
    )
    r = Result(mode=str(_attr(f, "mode")), provenance=prov, runtime_s=float(_attr(f, "runtime_s")))
    if "poses" in f:
        g = f["poses"]
        r.poses = Poses(stamp=_get(g, "stamp", np.float64), box=_get(g, "box", np.float64))
        if "frame" in g.attrs:  # version 2
            r.poses.frame = str(_attr(g, "frame"))
            r.poses.origin_stamp = float(_attr(g, "origin_stamp"))
        if "submap" in g:
            r.poses.submap = _get(g, "submap", np.int64)
            r.poses.relative = _get(g, "relative", np.float64)
    if "submaps" in f:  # optional (lidar, version 2)
        g = f["submaps"]
        r.submaps = Submaps(
            anchor=_get(g, "anchor", np.int64), anchor_box=_get(g, "anchor_box", np.float64),
            resolution=float(_attr(g, "resolution")), origin=_get(g, "origin", np.float64).reshape(-1, 2),
            shape=_get(g, "shape", np.int64).reshape(-1, 2), state=_get(g, "state", np.uint8).reshape(-1),
            member_offsets=_get(g, "member_offsets", np.int64), member_row=_get(g, "member_row", np.int64),
            member_box=_get(g, "member_box", np.float64).reshape(-1, 3, 2),
            member_mapped=_get(g, "member_mapped", np.uint8).astype(bool))
    if "loops" in f:  # optional (lidar with loop closure)
        g = f["loops"]
        r.loops = Loops(
            row=_get(g, "row", np.int64), submap=_get(g, "submap", np.int64), home=_get(g, "home", np.int64),
            prior=_get(g, "prior", np.float64).reshape(-1, 3, 2), box=_get(g, "box", np.float64).reshape(-1, 3, 2),
            beams=_get(g, "beams", np.int64), empty=_get(g, "empty", np.uint8).astype(bool),
            edge_a=_get(g, "edge_a", np.int64), edge_b=_get(g, "edge_b", np.int64),
            edge_box=_get(g, "edge_box", np.float64).reshape(-1, 3, 2), edge_kind=_get(g, "edge_kind", np.int64),
            anchor_box_open=_get(g, "anchor_box_open", np.float64).reshape(-1, 3, 2), sweeps=int(_attr(g, "sweeps")))

    if "pose_sets" in f:  # optional (landmarks)
        g = f["pose_sets"]
        r.pose_sets = PoseSets(offsets=_get(g, "offsets", np.int64), boxes=_get(g, "boxes", np.float64).reshape(-1, 3, 2))
    if "robots" in f:  # optional (several robots)
        g = f["robots"]
        r.robots = Robots(id=_get(g, "id", np.int64), pose_offsets=_get(g, "pose_offsets", np.int64),
                          truth_offsets=_get(g, "truth_offsets", np.int64))
    if "relative" in f:  # optional (lidar with keyframes)
        g = f["relative"]
        r.relative = RelativePoses(pairs=_get(g, "pairs", np.int64), box=_get(g, "box", np.float64),
                                   definition=str(_attr(g, "definition")))
    if "landmarks" in f:
        g = f["landmarks"]
        ref = int(_attr(g, "reference_id")) if bool(_attr(g, "has_reference")) else None
        r.landmarks = Landmarks(id=_get(g, "id", np.int64), box=_get(g, "box", np.float64), reference_id=ref)
    if "pairs" in f:
        g = f["pairs"]
        r.pairs = PairSubpavings(
            i=_get(g, "i", np.int64),
            j=_get(g, "j", np.int64),
            offsets=_get(g, "offsets", np.int64),
            boxes=_get(g, "boxes", np.float64),
            label=_get(g, "label", np.uint8),
        )
    if "map" in f:
        r.grid = _get_grid(f["map"])
    if "global_map" in f:  # optional
        r.global_map = _get_grid(f["global_map"])
    if "logodds" in f:  # optional
        g = f["logodds"]
        r.logodds = LogOddsGrid(
            value=_get(g, "value", np.float32),
            **{key: float(_attr(g, key)) for key in ("l_occ", "l_free", "l_min", "l_max")},
            scans=int(_attr(g, "scans")),
            beams=int(_attr(g, "beams")),
        )

    g = _group(f, "consistency")
    e = _group(g, "empty_events")
    rj = _group(g, "rejected")
    widths = {}
    for kind, k in _group(g, "widths").items():
        widths[kind] = WidthHistory(
            entity=_get(k, "entity", np.int64).reshape(-1, 2),
            step=_get(k, "step", np.int64),
            stamp=_get(k, "stamp", np.float64),
            width=_get(k, "width", np.float64),
            definition=str(_attr(k, "definition")),
        )
    r.consistency = Consistency(
        empty_events=EmptyEvents(
            stamp=_get(e, "stamp", np.float64),
            step=_get(e, "step", np.int64),
            constraint=_get_text(e, "constraint"),
            entity=_get(e, "entity", np.int64).reshape(-1, 2),
            measurement=_get(e, "measurement", np.int64),
            text=_get_text(e, "text"),
        ),
        q={str(k): int(v) for k, v in _group(g, "q").attrs.items()},
        rejected=Rejections(
            stream=_get_text(rj, "stream"), index=_get(rj, "index", np.int64), reason=_get_text(rj, "reason")
        ),
        widths=widths,
        assumption=str(_attr(g, "assumption")),
        stopped=str(_attr(g, "stopped")),
    )

    if "truth" in f:
        g = f["truth"]
        t = GroundTruth()
        for name, dt in (
            ("pose_stamp", np.float64),
            ("pose", np.float64),
            ("landmark_id", np.int64),
            ("landmark_xy", np.float64),
            ("world", np.float64),
        ):
            if name in g:
                setattr(t, name, _get(g, name, dt))
        if "outliers" in g:
            t.outliers = {str(k): np.asarray(v[()]).astype(bool) for k, v in g["outliers"].items()}
        r.truth = t
    if "stats" in f:
        r.stats = {}
        for key in f["stats"].attrs:
            r.stats[str(key)] = _attr(f["stats"], key)
    r.validate()
    return r


def read_result(path: str | Path) -> Result:
    """Read a result file; any problem becomes a one-line :class:`IvslamError` naming ``path``."""
    from ivslam_cli.inputs import check_input

    path = check_input(path, "result file")
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise IvslamError(f"not an ivslam result (not a readable HDF5 file: {_first_line(exc)})", path) from exc
    with f:
        fmt = f.attrs.get("format")
        version = f.attrs.get("ivslam_result_version")
        if version is None or (fmt.decode() if isinstance(fmt, bytes) else fmt) != FORMAT_NAME:
            raise IvslamError("not an ivslam result (HDF5 file without the ivslam_result_version marker)", path)
        try:
            version = int(version)
        except (TypeError, ValueError) as exc:
            raise IvslamError("corrupt result: bad ivslam_result_version attribute", path) from exc
        if version > SCHEMA_VERSION:
            raise IvslamError(
                f"result schema version {version} is newer than this ivslam reads ({SCHEMA_VERSION}); upgrade ivslam",
                path,
            )
        if version < 1:
            raise IvslamError(f"corrupt result: unknown schema version {version}", path)
        try:
            r = _read(f)
            _check_values(r)
            return r
        except _Corrupt as exc:
            raise IvslamError(f"corrupt result: {exc}", path) from exc
        except limits.LimitExceeded as exc:
            raise exc.about(path) from None
        except MemoryError:
            raise IvslamError("corrupt result: a dataset too large to read", path) from None
        except (OSError, KeyError, ValueError, TypeError, json.JSONDecodeError, RuntimeError, RecursionError,
                AttributeError, OverflowError, IndexError) as exc:
            raise IvslamError(f"corrupt or truncated result ({type(exc).__name__}: {_first_line(exc)})", path) from exc


def _check_values(r: Result) -> None:
    """What the shapes do not say: no NaN in any enclosure; every interval ``lo <= hi`` or the
    empty interval ``[+inf, -inf]`` (an inverted interval is a corrupt file, not a proof);
    pose stamps finite and sorted; map geometry finite. A corrupt file must not be reported as
    a soundness failure."""
    boxes = {"poses/box": r.poses.box if r.poses is not None else None,
             "poses/relative": r.poses.relative if r.poses is not None else None,
             "landmarks/box": r.landmarks.box if r.landmarks is not None else None,
             "pairs/boxes": r.pairs.boxes if r.pairs is not None else None,
             "relative/box": r.relative.box if r.relative is not None else None,
             "submaps/anchor_box": r.submaps.anchor_box if r.submaps is not None else None,
             "submaps/member_box": r.submaps.member_box if r.submaps is not None else None}
    for name, box in boxes.items():
        if box is None or box.size == 0:
            continue
        if np.isnan(box).any():
            raise _Corrupt(f"{name} has NaN bounds")
        lo, hi = box[..., 0], box[..., 1]
        inverted = (lo > hi) & ~((lo == np.inf) & (hi == -np.inf))
        if inverted.any():
            row = int(np.flatnonzero(inverted.reshape(inverted.shape[0], -1).any(axis=1))[0])
            raise _Corrupt(f"{name} row {row} has an interval with lo > hi (not the empty interval "
                           "[+inf, -inf])")
    if r.poses is not None and len(r.poses):
        st = r.poses.stamp
        d = np.diff(st)
        if r.robots is not None and len(r.robots):  # sorted within each robot's rows
            off = np.asarray(r.robots.pose_offsets, dtype=np.int64)
            if off[0] != 0 or off[-1] != st.size or np.any(np.diff(off) < 0):
                raise _Corrupt("robots/pose_offsets do not partition the poses")
            cut = off[1:-1]
            d[cut[(cut > 0) & (cut < st.size)] - 1] = 0.0
        if not np.isfinite(st).all() or np.any(d < 0):
            raise _Corrupt("poses/stamp is not finite and sorted")
    for name, grid in (("map", r.grid), ("global_map", r.global_map)):
        if grid is not None and not (np.isfinite(grid.origin).all() and np.isfinite(grid.resolution)):
            raise _Corrupt(f"{name} origin or resolution is not finite")


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
