"""The HDF5 result: round trip, atomic write, overwrite policy, bad files → one-line errors."""

from __future__ import annotations

import dataclasses
import os
import re
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ivslam_cli.errors import IvslamError
from ivslam_cli.results import hdf5
from ivslam_cli.results.example import example_result
from ivslam_cli.results.hdf5 import SCHEMA_VERSION, read_result, write_result
from ivslam_cli.results.model import (
    LABEL_BOUNDARY,
    LABEL_INNER,
    Consistency,
    PairSubpavings,
    Result,
    ResultProvenance,
    box_is_empty,
)
from tests.helpers.hyp import examples
from tests.helpers.results import assert_same


def test_round_trip_every_field(tmp_path):
    r = example_result()
    # Make it exercise the edges: an empty box, infinite bounds, a NaN width, a relative map.
    r.landmarks.box[2] = [[np.inf, -np.inf], [np.inf, -np.inf]]
    r.poses.box[0, 2] = [-np.inf, np.inf]
    r.consistency.widths["pair"].width[3] = np.nan
    r.landmarks.reference_id = 1
    r.truth.outliers["observations"][[3, 5]] = True
    path = tmp_path / "r.h5"
    write_result(path, r)
    back = read_result(path)
    assert_same(r, back)
    assert box_is_empty(back.landmarks.box).tolist() == [False, False, True]


def test_round_trip_minimal_result(tmp_path):
    """A mode with no poses, landmarks, pairs, grid or truth (everything optional is None)."""
    r = Result(
        mode="lidar",
        provenance=ResultProvenance("0", "ivslam run x", {}, "x", "", "carmen"),
        runtime_s=0.0,
    )
    write_result(tmp_path / "m.h5", r)
    back = read_result(tmp_path / "m.h5")
    assert_same(r, back)
    assert back.poses is None and back.truth is None and back.grid is None


@settings(max_examples=examples(ci=25), suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    counts=st.lists(st.integers(0, 40), min_size=0, max_size=6),
    seed=st.integers(0, 2**32 - 1),
)
def test_round_trip_random_subpavings(tmp_path, counts, seed):
    """Ragged pair subpavings of any sizes (including empty pairs and big compressed ones)."""
    rng = np.random.default_rng(seed)
    n = int(sum(counts))
    lo = rng.normal(size=(n, 2))
    boxes = np.stack([lo, lo + rng.uniform(0, 1, size=(n, 2))], axis=-1)
    r = example_result(with_grid=False)
    r.pairs = PairSubpavings(
        i=np.arange(len(counts), dtype=np.int64),
        j=np.arange(len(counts), dtype=np.int64) + 100,
        offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        boxes=boxes,
        label=rng.choice([LABEL_INNER, LABEL_BOUNDARY], size=n).astype(np.uint8),
    )
    path = tmp_path / f"p{seed}.h5"
    write_result(path, r)
    assert_same(r, read_result(path))
    os.unlink(path)


def test_schema_attributes_and_compression(tmp_path):
    r = example_result()
    r.grid.state = np.zeros((600, 700), dtype=np.uint8)
    r.grid.state[100:200, 50:60] = 2
    path = tmp_path / "r.h5"
    write_result(path, r)
    with h5py.File(path, "r") as f:
        assert int(f.attrs["ivslam_result_version"]) == SCHEMA_VERSION == 2
        assert f.attrs["format"] == "ivslam-result"
        st_ = f["map/state"]
        assert st_.dtype == np.uint8 and st_.chunks is not None and st_.compression == "gzip" and st_.shuffle
        # no variable-length dataset anywhere except the small text vocabularies
        vlen = []
        f.visititems(lambda name, obj: vlen.append(name) if isinstance(obj, h5py.Dataset) and obj.dtype.kind == "O" else None)
        assert vlen and all(name.endswith("_vocab") for name in vlen)
    assert path.stat().st_size < 100_000  # 420 kB of cells compress away


def test_refuses_to_overwrite_without_force(tmp_path):
    path = tmp_path / "r.h5"
    path.write_bytes(b"precious")
    with pytest.raises(IvslamError, match="--force") as info:
        write_result(path, example_result())
    assert "\n" not in str(info.value) and str(path) in str(info.value)
    assert path.read_bytes() == b"precious"
    with pytest.raises(IvslamError, match="not a result written by ivslam"):
        write_result(path, example_result(), force=True)  # --force replaces only a result
    assert path.read_bytes() == b"precious"
    path.unlink()
    write_result(path, example_result())
    write_result(path, example_result(), force=True)
    assert read_result(path).mode == "pairs"


def test_failed_write_leaves_nothing(tmp_path, monkeypatch):
    path = tmp_path / "r.h5"
    calls = {"n": 0}
    real = hdf5._put

    def failing_put(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 5:  # in the middle of the file
            raise RuntimeError("disk full (simulated)")
        return real(*args, **kwargs)

    monkeypatch.setattr(hdf5, "_put", failing_put)
    with pytest.raises(RuntimeError, match="simulated"):
        write_result(path, example_result())
    assert list(tmp_path.iterdir()) == []


def test_failed_overwrite_keeps_old_file(tmp_path, monkeypatch):
    path = tmp_path / "r.h5"
    old = example_result()
    old.runtime_s = 123.0
    write_result(path, old)
    monkeypatch.setattr(hdf5, "_write", lambda f, r: (_ for _ in ()).throw(RuntimeError("boom")))
    with pytest.raises(RuntimeError):
        write_result(path, example_result(), force=True)
    assert [p.name for p in tmp_path.iterdir()] == ["r.h5"]
    assert read_result(path).runtime_s == 123.0


def test_malformed_result_is_a_bug_not_a_file(tmp_path):
    r = example_result()
    r.pairs.offsets[-1] += 1
    with pytest.raises(ValueError, match="offsets"):
        write_result(tmp_path / "r.h5", r)
    assert not (tmp_path / "r.h5").exists()


# ---------------------------------------------------------------- bad files
def _one_line_error(path: Path, match: str) -> None:
    with pytest.raises(IvslamError, match=match) as info:
        read_result(path)
    msg = str(info.value)
    assert "\n" not in msg and str(path) in msg


def test_read_errors(tmp_path):
    _one_line_error(tmp_path / "missing.h5", "no such file")
    _one_line_error(tmp_path, "directory")
    text = tmp_path / "t.h5"
    text.write_text("hello\n")
    _one_line_error(text, "not an ivslam result")
    other = tmp_path / "o.h5"
    with h5py.File(other, "w") as f:
        f["x"] = [1, 2, 3]
    _one_line_error(other, "not an ivslam result")


def test_newer_version_refused(tmp_path):
    path = tmp_path / "r.h5"
    write_result(path, example_result())
    with h5py.File(path, "r+") as f:
        f.attrs["ivslam_result_version"] = SCHEMA_VERSION + 1
    _one_line_error(path, "newer")


def test_missing_part_is_corrupt(tmp_path):
    path = tmp_path / "r.h5"
    write_result(path, example_result())
    with h5py.File(path, "r+") as f:
        del f["pairs/offsets"]
    _one_line_error(path, "corrupt result: missing dataset /pairs/offsets")


def test_inconsistent_shapes_are_corrupt(tmp_path):
    path = tmp_path / "r.h5"
    write_result(path, example_result())
    with h5py.File(path, "r+") as f:
        del f["landmarks/id"]
        f["landmarks/id"] = np.arange(7)
    _one_line_error(path, "corrupt")


@pytest.mark.parametrize("keep", [0.1, 0.5, 0.9])
def test_truncated_file(tmp_path, keep):
    path = tmp_path / "r.h5"
    r = example_result()
    r.grid.state = np.random.default_rng(0).integers(0, 3, size=(300, 300), dtype=np.uint8)
    write_result(path, r)
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])
    _one_line_error(path, "not an ivslam result|corrupt|truncated")


def test_cli_reports_bad_files_on_one_line(cli_run, tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 100)
    for p in (bad, tmp_path / "missing.h5"):
        res = cli_run("report", p)
        assert res.exit_code != 0
        lines = [ln for ln in res.output.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("ivslam: error:"), res.output
        assert "Traceback" not in res.output and str(p) in lines[0]


def test_consistency_defaults_are_valid(tmp_path):
    r = Result(mode="pairs", provenance=ResultProvenance("0", "", {}, "", "", ""), runtime_s=1.0,
               consistency=Consistency(q={"pair": 0}))
    write_result(tmp_path / "r.h5", r)
    assert read_result(tmp_path / "r.h5").consistency.q == {"pair": 0}


def test_schema_md_documents_every_name_written(tmp_path):
    """Every dataset and attribute the writer produces is named in SCHEMA.md."""
    doc = (Path(hdf5.__file__).parent / "SCHEMA.md").read_text()
    path = tmp_path / "r.h5"
    write_result(path, example_result())
    names: set[str] = set()

    def visit(name, obj):
        parts = name.split("/")
        if parts[0] in ("stats",) or parts[:2] in (["consistency", "q"], ["truth", "outliers"]):
            return  # free-form keys (counters, q families, stream names)
        if isinstance(obj, h5py.Dataset):
            leaf = parts[-1]
            names.add(leaf.removesuffix("_code").removesuffix("_vocab"))
        for a in obj.attrs:
            names.add(a)

    with h5py.File(path, "r") as f:
        names.update(f.attrs)
        f.visititems(visit)
    missing = sorted(n for n in names if not re.search(r"[`/]" + re.escape(n) + r"[`_/,]", doc))
    assert not missing, f"not documented in SCHEMA.md: {missing}"
    assert len(names) > 30


def _with_sets_and_robots():
    """The example result as a landmarks result of two robots with pose sets: rows 0-2 robot 1,
    3-5 robot 2; two boxes per pose (heading halves), one pose with none."""
    from ivslam_cli.results.model import PoseSets, Robots

    r = example_result("landmarks")
    n = len(r.poses)
    lo, hi = r.poses.box.copy(), r.poses.box.copy()
    mid = 0.5 * (r.poses.box[:, 2, 0] + r.poses.box[:, 2, 1])
    lo[:, 2, 1] = mid
    hi[:, 2, 0] = mid
    boxes = np.stack([lo, hi], axis=1).reshape(-1, 3, 2)
    counts = np.full(n, 2)
    counts[4] = 0
    keep = np.repeat(counts > 0, 2)
    r.pose_sets = PoseSets(offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64), boxes=boxes[keep])
    g = len(r.truth.pose)
    r.robots = Robots(id=np.array([1, 2]), pose_offsets=np.array([0, 3, n]), truth_offsets=np.array([0, g // 2, g]))
    return r


def test_round_trip_pose_sets_and_robots(tmp_path):
    r = _with_sets_and_robots()
    write_result(tmp_path / "r.h5", r)
    back = read_result(tmp_path / "r.h5")
    assert_same(r, back)
    assert back.pose_sets.node_boxes(4).shape == (0, 3, 2) and back.pose_sets.node_boxes(0).shape == (2, 3, 2)
    with h5py.File(tmp_path / "r.h5", "r") as f:  # optional groups: absent when not produced
        assert "pose_sets" in f and "robots" in f
    write_result(tmp_path / "plain.h5", example_result("landmarks"))
    with h5py.File(tmp_path / "plain.h5", "r") as f:
        assert "pose_sets" not in f and "robots" not in f


def test_pose_sets_and_robots_are_checked():
    from ivslam_cli.results.model import PoseSets, Robots

    r = _with_sets_and_robots()
    bad = dataclasses.replace(r, pose_sets=PoseSets(offsets=r.pose_sets.offsets[:-1], boxes=r.pose_sets.boxes))
    with pytest.raises(ValueError, match="pose_sets"):
        bad.validate()
    bad = dataclasses.replace(r, robots=Robots(id=r.robots.id, pose_offsets=np.array([0, 4, 3]),
                                                truth_offsets=r.robots.truth_offsets))
    with pytest.raises(ValueError, match="robots"):
        bad.validate()
    bad = dataclasses.replace(r, robots=Robots(id=r.robots.id, pose_offsets=r.robots.pose_offsets,
                                                truth_offsets=np.array([0, 1, 2])))
    with pytest.raises(ValueError, match="truth_offsets"):
        bad.validate()


def test_schema_md_documents_the_pose_sets_and_robots(tmp_path):
    doc = (Path(hdf5.__file__).parent / "SCHEMA.md").read_text()
    write_result(tmp_path / "r.h5", _with_sets_and_robots())
    with h5py.File(tmp_path / "r.h5", "r") as f:
        names = {f"{g}/{d}" for g in ("pose_sets", "robots") for d in f[g]}
    for name in names:
        group, leaf = name.split("/")
        assert f"`/{group}`" in doc and f"`{leaf}`" in doc, name


def test_round_trip_global_map(tmp_path):
    """The LiDAR global map (``/global_map``, optional): same layout as ``/map``, always proven."""
    from ivslam_cli.results.model import MapGrid

    r = example_result("lidar")
    r.global_map = MapGrid(origin=np.array([-2.0, 1.5]), resolution=0.05,
                           state=np.arange(12, dtype=np.uint8).reshape(3, 4) % 3)
    write_result(tmp_path / "g.h5", r)
    back = read_result(tmp_path / "g.h5")
    assert_same(r, back)
    with h5py.File(tmp_path / "g.h5", "r") as f:
        assert f["global_map"].attrs["frame"] == "proven"
    r.global_map.frame = "mosaic"
    with pytest.raises(ValueError, match="global_map.frame"):
        r.validate()
