"""Hostile HDF5: ivslam's own logs and results with the wrong dtypes, ranks, declared sizes,
offsets, link loops, NaN and inverted boxes. Each is one line and exit 2 (a corrupt file is
never reported as a SOUNDNESS FAILURE), never an internal error."""

from __future__ import annotations

import shutil

import h5py
import numpy as np
import pytest

from tests.hostile import builders as B
from tests.hostile.harness import expect_error, expect_ok_or_error, inproc


@pytest.fixture(scope="module")
def good(tmp_path_factory):
    d = tmp_path_factory.mktemp("h5")
    logs = B.write_logs(d)
    return {"log": logs["lidar.h5"], "lmlog": logs["s.h5"], "result": B.write_result(d / "r.h5")}


def _copy(src, tmp_path, label):
    dst = tmp_path / f"{label}.h5"
    shutil.copy(src, dst)
    return dst


def _replace(f, name, data=None, **kw):
    del f[name]
    if data is None:
        f.create_dataset(name, **kw)
    else:
        f.create_dataset(name, data=data, **kw)


LOG_DATASETS = ["scans/stamp", "scans/angle_min", "scans/angle_increment", "scans/offsets", "scans/ranges",
                "scans/valid", "odometry/stamp", "odometry/pose", "odometry/twist", "truth/pose", "truth/world"]


@pytest.mark.parametrize("name", LOG_DATASETS)
def test_log_dataset_types_ranks_and_links(good, tmp_path, name):
    src = good["log"]
    with h5py.File(src, "r") as f:
        if name not in f:
            pytest.skip(f"{name} not in the simulated log")
        shape = f[name].shape
    variants = {
        "str": dict(data=np.array(["a"] * shape[0], dtype=h5py.string_dtype())),
        "compound": dict(data=np.zeros(shape[0], dtype=[("a", "f8"), ("b", "i4")])),
        "vlen": dict(data=np.empty(shape[0], dtype=h5py.vlen_dtype(np.float64))),
        "rank3": dict(data=np.zeros((2, 2, 2))),
        "scalar": dict(data=np.float64(1.0)),
        "short": dict(data=np.zeros(max(shape[0] - 1, 0)) if len(shape) == 1 else np.zeros((1, shape[1]))),
        "nan": dict(data=np.full(shape, np.nan)),
        "huge": dict(data=np.full(shape, 1e308)),
    }
    for label, kw in variants.items():
        case = _copy(src, tmp_path, f"{name.replace('/', '_')}_{label}")
        with h5py.File(case, "a") as f:
            if label == "vlen":
                del f[name]
                ds = f.create_dataset(name, shape=(shape[0],), dtype=h5py.vlen_dtype(np.float64))
                for i in range(shape[0]):
                    ds[i] = np.arange(i % 3, dtype=np.float64)
            else:
                _replace(f, name, **kw)
        expect_ok_or_error(inproc("inspect", case), case)
    for label in ("loop", "dangling", "group"):
        case = _copy(src, tmp_path, f"{name.replace('/', '_')}_{label}")
        with h5py.File(case, "a") as f:
            del f[name]
            if label == "loop":
                f[name] = h5py.SoftLink("/" + name)  # a link to itself
            elif label == "dangling":
                f[name] = h5py.SoftLink("/nowhere/at/all")
            else:
                f.create_group(name)
        expect_error(inproc("inspect", case), case)


@pytest.mark.parametrize("offsets", ["decreasing", "1e12", "-7", "float", "start1"])
def test_log_scan_offsets(good, tmp_path, offsets):
    case = _copy(good["log"], tmp_path, offsets)
    with h5py.File(case, "a") as f:
        off = f["scans/offsets"][()]
        new = {"decreasing": off[::-1].copy(), "1e12": np.where(np.arange(off.size) == 3, 10 ** 12, off),
               "-7": np.where(np.arange(off.size) == 2, -7, off), "float": off.astype(np.float64) + 0.5,
               "start1": off + 1}[offsets]
        _replace(f, "scans/offsets", new)
    expect_error(inproc("inspect", case), case)


def test_log_attributes(good, tmp_path):
    for label, attr, value in (("version", "ivslam_log_version", "one"), ("version2", "ivslam_log_version", 99),
                               ("meta", "meta_json", "{not json"), ("bounds", "bounds_json", '{"range_abs": "x"}'),
                               ("prov", "provenance_json", "[1, 2]"), ("deep", "meta_json", "[" * 100000)):
        case = _copy(good["lmlog"], tmp_path, label)
        with h5py.File(case, "a") as f:
            f.attrs[attr] = value
        expect_error(inproc("inspect", case), case)


RESULT_DATASETS = ["poses/box", "poses/stamp", "landmarks/box", "landmarks/id", "pairs/boxes", "pairs/offsets",
                   "map/state", "consistency/empty_events/stamp", "consistency/empty_events/text_vocab",
                   "provenance/dropped/count"]


@pytest.mark.parametrize("name", RESULT_DATASETS)
def test_result_datasets(good, tmp_path, name):
    src = good["result"]
    with h5py.File(src, "r") as f:
        if name not in f:
            pytest.skip(f"{name} not in the example result")
        shape = f[name].shape
    variants = {"compound": np.zeros(max(shape[0], 1), dtype=[("a", "f8")]), "rank3": np.zeros((2, 2, 2, 2)),
                "short": np.zeros((0,) + tuple(shape[1:])), "str": np.array(["x"], dtype=h5py.string_dtype())}
    for label, data in variants.items():
        case = _copy(src, tmp_path, f"{name.replace('/', '_')}_{label}")
        with h5py.File(case, "a") as f:
            _replace(f, name, data)
        expect_ok_or_error(inproc("report", case), case)
    for label in ("loop", "group"):
        case = _copy(src, tmp_path, f"{name.replace('/', '_')}_{label}")
        with h5py.File(case, "a") as f:
            del f[name]
            if label == "loop":
                f[name] = h5py.SoftLink("/" + name)
            else:
                f.create_group(name)
        expect_error(inproc("report", case), case)


@pytest.mark.parametrize("what", ["nan", "inverted", "nan_landmark", "inverted_pair", "stamps"])
def test_result_nan_or_inverted_boxes_are_corrupt_not_unsound(good, tmp_path, what):
    case = _copy(good["result"], tmp_path, what)
    with h5py.File(case, "a") as f:
        name = {"nan": "poses/box", "inverted": "poses/box", "nan_landmark": "landmarks/box",
                "inverted_pair": "pairs/boxes", "stamps": "poses/stamp"}[what]
        a = f[name][()]
        if what.startswith("nan"):
            a.reshape(-1)[0] = np.nan
        elif what == "stamps":
            a[:] = a[::-1].copy() if a.size > 1 else np.nan
        else:
            a[0, 0] = [3.0, 1.0]
        _replace(f, name, a)
    line = expect_error(inproc("report", case), case)
    assert "corrupt" in line and "SOUNDNESS" not in line


def test_result_declaring_a_huge_map(good, tmp_path):
    """A 2^20 x 2^20 map declared in a tiny file (chunked, never written): refused by the
    CELLS limit before anything is read."""
    case = _copy(good["result"], tmp_path, "hugemap")
    with h5py.File(case, "a") as f:
        if "map" in f:
            del f["map/state"]
            g = f["map"]
        else:
            g = f.create_group("map")
            g.attrs["origin"] = np.zeros(2)
            g.attrs["resolution"] = 0.05
        g.create_dataset("state", shape=(1 << 20, 1 << 20), dtype=np.uint8, chunks=(256, 256),
                         compression="gzip")
    assert case.stat().st_size < 1 << 20
    expect_error(inproc("report", case), case, contains="CELLS")


def test_log_declaring_2e29_beams(good, tmp_path):
    case = _copy(good["log"], tmp_path, "beams")
    with h5py.File(case, "a") as f:
        for name in ("ranges", "valid"):
            del f[f"scans/{name}"]
            f.create_dataset(f"scans/{name}", shape=(1 << 29,), dtype=np.float32 if name == "ranges" else bool,
                             chunks=(1 << 16,), compression="gzip")
        off = f["scans/offsets"][()]
        off[-1] = 1 << 29
        _replace(f, "scans/offsets", off)
    expect_error(inproc("inspect", case), case, contains="BEAMS")
