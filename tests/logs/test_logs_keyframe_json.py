"""Keyframe JSON logs (Intel ``intel_gfs.json`` / ``intel_corrected_log.json``): the reader on
hand-written files (order, angles, no-return value, poses, dropped entries), format detection,
one-line errors for empty / truncated / corrupt / wrong-shape input, and the real Intel files."""

from __future__ import annotations

import gzip
import json
import lzma
import math

import numpy as np
import pytest

from ivslam_cli.errors import LogError
from ivslam_cli.logs import list_formats, read_log
from ivslam_cli.logs.detect import detect_format

N = 180
NO_RETURN = 81.83


def _entries(k=12, seed=0):
    """``k`` keyframes, stamps 9.5, 10.25, ... (string order differs from numeric order)."""
    rng = np.random.default_rng(seed)
    out = {}
    for i in range(k):
        r = np.round(rng.uniform(0.3, 8.0, N), 2)
        r[rng.random(N) < 0.05] = NO_RETURN
        r[0] = float(i)  # tag: beam 0 of keyframe i is i metres (0 for the first: no return)
        out[f"{9.5 + 0.75 * i:g}"] = {"range": r.tolist(), "theta": 0.1 * i, "x": float(i), "y": -0.5 * i}
    return out


def _write(path, doc, how="plain"):
    raw = (json.dumps(doc, indent=4, sort_keys=True) if not isinstance(doc, str) else doc).encode()
    if how == "xz":
        raw = lzma.compress(raw)
    elif how == "gz":
        raw = gzip.compress(raw)
    path.write_bytes(raw)
    return path


def test_format_is_listed():
    assert "keyframe-json" in list_formats()


@pytest.mark.parametrize("name,how", [("k.json", "plain"), ("k.json.xz", "xz"), ("k.json.gz", "gz"),
                                      ("intel_gfs", "plain")])
def test_read_keyframes(tmp_path, name, how):
    p = _write(tmp_path / name, {"map": _entries()}, how)
    assert detect_format(p) == "keyframe-json"
    log = read_log(p)
    s = log.scans
    assert log.provenance.format == "keyframe-json"
    assert len(s) == 12 and set(np.diff(s.offsets)) == {N}
    # numeric order (9.5, 10.25, ...), whatever the key strings' order in the file
    np.testing.assert_array_equal(s.stamp, 9.5 + 0.75 * np.arange(12))
    np.testing.assert_array_equal(s.ranges[s.offsets[1:-1]], np.arange(1, 12, dtype=np.float32))
    assert np.all(s.angle_min == -math.pi / 2) and np.allclose(s.angle_increment, math.radians(1))
    assert s.mount == (0.0, 0.0, 0.0)
    # 81.83 is the no-return value: every such beam invalid, every other positive one valid
    at_max = s.ranges == np.float32(NO_RETURN)
    assert at_max.any() and not s.valid[at_max].any()
    assert np.all(s.range_max < NO_RETURN) and np.all(s.range_max > 81.8)
    assert s.valid[~at_max & (s.ranges > 0)].all()
    assert any("no return" in n for n in log.provenance.notes)
    # poses: odometry (no twist), also per scan in meta; never truth
    o = log.odometry
    assert o.twist is None and len(o) == 12
    np.testing.assert_array_equal(o.stamp, s.stamp)
    np.testing.assert_allclose(o.pose[3], [3.0, -1.5, 0.3])
    assert np.asarray(log.meta["scan_odometry_pose"]).shape == (12, 3)
    assert log.truth is None
    assert log.meta["poses"] == "raw odometry" and "raw odometry" in log.provenance.topics["odom"]


def test_corrected_file_says_so(tmp_path):
    log = read_log(_write(tmp_path / "intel_corrected_log.json", {"map": _entries()}))
    assert log.meta["poses"] == "corrected" and "corrected" in log.provenance.topics["odom"]
    assert log.truth is None


def test_other_beam_counts_and_compact_json(tmp_path):
    doc = {"map": {"1.0": {"x": 0, "y": 0, "theta": 0, "range": [1.0] * 181},
                   "2.0": {"x": 1, "y": 0, "theta": 0, "range": [2.0] * 360}}}
    p = _write(tmp_path / "k.json", json.dumps(doc))  # one line
    log = read_log(p)
    s = log.scans
    assert list(np.diff(s.offsets)) == [181, 360]
    assert s.angle_increment[0] == pytest.approx(math.pi / 180) and s.angle_increment[1] == pytest.approx(math.pi / 360)
    assert np.all(s.range_max == np.inf) and s.valid.all()  # too few beams to call a value "no return"


def test_malformed_entries_are_dropped_and_counted(tmp_path):
    e = _entries(6)
    e["abc"] = {"x": 0, "y": 0, "theta": 0, "range": [1.0] * N}  # key not a number
    e["20.0"] = {"x": "0", "y": 0, "theta": 0, "range": [1.0] * N}  # x a string
    e["21.0"] = {"y": 0, "theta": 0, "range": [1.0] * N}  # x missing
    e["22.0"] = {"x": 0, "y": 0, "theta": 0, "range": []}  # no ranges
    e["23.0"] = {"x": 0, "y": 0, "theta": 0, "range": [1.0, "a"]}  # a range not a number
    e["24.0"] = [1, 2, 3]  # not an object
    e["9.50"] = {"x": 9, "y": 9, "theta": 0, "range": [5.0] * N}  # same stamp as "9.5"
    log = read_log(_write(tmp_path / "k.json", json.dumps({"map": e})))
    d = {dr.reason.split(" (")[0]: dr.count for dr in log.provenance.dropped if dr.stream == "records"}
    assert d == {"malformed keyframes": 6, "keyframes with an already seen stamp": 1}
    assert len(log.scans) == 6 and log.odometry.pose[0].tolist() == [0.0, 0.0, 0.0]  # "9.5" kept, not "9.50"


def test_non_finite_ranges_are_invalid_beams(tmp_path):
    text = '{"map": {"1.0": {"x": 0, "y": 0, "theta": 0, "range": [1.0, NaN, Infinity, 0]}}}'
    log = read_log(_write(tmp_path / "k.json", text))
    assert log.scans.valid.tolist() == [True, False, False, False]


@pytest.mark.parametrize("text,needle", [
    ("", "empty file"),
    ("   \n", "empty file"),
    ('{"map": {"1.0": {"x": 0, "y": 0, "theta": 0, "range": [1.0, 2.0', "not valid JSON"),
    ('{"map": {}}', "no usable keyframe"),
    ('{"map": {"x": {"x": 0}}}', "no usable keyframe"),
    ('{"map": []}', "not a keyframe JSON log"),
    ('{"mapp": {}}', "not a keyframe JSON log"),
    ("[1, 2]", "not a keyframe JSON log"),
])
def test_bad_files_one_line_errors(tmp_path, text, needle):
    p = _write(tmp_path / "bad.json", text)
    with pytest.raises(LogError) as exc:
        read_log(p, fmt="keyframe-json")
    msg = str(exc.value)
    assert needle in msg and str(p) in msg and "\n" not in msg


def test_truncated_and_byte_flipped_copies(tmp_path):
    raw = lzma.compress(json.dumps({"map": _entries(8)}, indent=1).encode())
    plain = json.dumps({"map": _entries(8)}, indent=1).encode()
    rng = np.random.default_rng(3)
    for i, (data, suffix) in enumerate([(raw, ".json.xz"), (plain, ".json")] * 6):
        cut = int(rng.integers(1, len(data) - 1))
        p = tmp_path / f"t{i}{suffix}"
        p.write_bytes(data[:cut])
        with pytest.raises(LogError) as exc:
            read_log(p, fmt="keyframe-json")
        assert str(p) in str(exc.value) and "\n" not in str(exc.value)
    for i in range(12):
        data = bytearray(plain)
        for j in rng.integers(0, len(data), 4):
            data[j] = int(rng.integers(0, 256))
        p = tmp_path / f"f{i}.json"
        p.write_bytes(bytes(data))
        try:  # a flip inside a number may leave a valid file: only LogError may come out
            read_log(p, fmt="keyframe-json")
        except LogError as exc:
            assert str(p) in str(exc) and "\n" not in str(exc)


# ----------------------------------------------------------------- the real Intel files
@pytest.mark.datasets
@pytest.mark.parametrize("name,poses", [("intel_gfs.json.xz", "raw odometry"),
                                        ("intel_corrected_log.json.xz", "corrected")])
def test_intel_keyframe_files(datasets, name, poses):
    p = datasets / "intel_lab" / name
    doc = json.loads(lzma.open(p).read())["map"]
    keys = sorted(doc, key=float)
    log = read_log(p)
    s = log.scans
    assert log.provenance.format == "keyframe-json" and log.meta["poses"] == poses
    assert len(s) == 910 and set(np.diff(s.offsets)) == {180}
    np.testing.assert_array_equal(s.stamp, [float(k) for k in keys])
    assert s.stamp[0] == pytest.approx(976052890.24, abs=0.01) and s.stamp[-1] == pytest.approx(976055541.10, abs=0.01)
    np.testing.assert_array_equal(s.ranges[-180:], np.array(doc[keys[-1]]["range"], np.float32))
    np.testing.assert_array_equal(log.odometry.pose[5], [doc[keys[5]][k] for k in ("x", "y", "theta")])
    at_max = np.isclose(s.ranges, NO_RETURN)
    assert at_max.mean() == pytest.approx(0.025, abs=0.003) and not s.valid[at_max].any()  # README: 2.5 %
    assert s.valid[~at_max].all()  # every other range (0.23 .. ~80 m) is a return
