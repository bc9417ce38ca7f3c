"""The generated corpus, per reader: truncated at many offsets, bit-flipped, NaN/inf/huge in
every numeric field of a record, lying declared sizes, empty, junk. Every case ends with
``inspect`` (or ``run``) succeeding or with one ``ivslam: error: <file>: ...`` line and exit
2; never a traceback, an internal error or a hang (each case under a timeout)."""

from __future__ import annotations

import gzip
import lzma

import pytest

from tests.hostile import builders as B
from tests.hostile.harness import expect_error, expect_ok_or_error, inproc

TEXT_KINDS = sorted(B.TEXT_LOGS)
WRAP = ("", ".gz", ".xz")


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    d = tmp_path_factory.mktemp("readers")
    good = {}
    for name, make in B.TEXT_LOGS.items():
        for w in WRAP:
            good[name + w] = B.write_text(d / (name + w), make())
    good.update(B.write_logs(d))
    good["mrclam"] = B.mrclam_dir(d / "mrclam")
    return d, good


@pytest.mark.parametrize("name", [n + w for n in TEXT_KINDS for w in WRAP] +
                         ["s.mcap", "s.bag", "s_ros2", "s_ros2mcap", "s.h5", "lidar.mcap", "lidar.h5", "mrclam"])
def test_good_inputs_read(corpus, name):
    d, good = corpus
    r = inproc("inspect", good[name])
    assert r.code == 0, str(r)


def _file_of(path):
    """The file inside a directory input to corrupt (the bag's storage file)."""
    if path.is_dir():
        return sorted(p for p in path.iterdir() if p.suffix in (".db3", ".mcap"))[0]
    return path


@pytest.mark.parametrize("name", [n + w for n in TEXT_KINDS for w in WRAP] +
                         ["s.mcap", "s.bag", "s_ros2", "s_ros2mcap", "s.h5", "lidar.mcap"])
def test_truncated_and_flipped(corpus, tmp_path, name):
    d, good = corpus
    src = _file_of(good[name])
    raw = src.read_bytes()
    cases = list(B.truncations(raw, 8, len(name))) + list(B.bit_flips(raw, 8, 3 + len(name)))
    for label, data in cases:
        if good[name].is_dir():  # a bag directory: copy it, corrupt its storage file
            import shutil

            case = tmp_path / f"{label}_{name}"
            shutil.copytree(good[name], case)
            (case / src.name).write_bytes(data)
        else:
            case = tmp_path / f"{label}_{name}"
            case.write_bytes(data)
        r = inproc("inspect", case, timeout=60)
        expect_ok_or_error(r, case)


RECORDS = {  # text log -> (keyword, numeric field indices of its first record)
    "s.log": [("ODOM", range(1, 8)), ("FLASER", [1, 2, 100, 181, 182, 183, 184, 185, 186, 187, 188])],
    "s.gfs": [("ODOM", range(1, 5)), ("LASER_READING", [1, 2, 150, 183, 184, 185, 186])],
    "victoria.txt": [("ODOMETRY", range(1, 6)), ("LANDMARK", range(1, 5))],
}


@pytest.mark.parametrize("name,keyword", [(n, k) for n, recs in RECORDS.items() for k, _ in recs])
def test_hostile_numbers_in_every_field(tmp_path, name, keyword):
    fields = dict(RECORDS[name])[keyword]
    lines = B.TEXT_LOGS[name]().splitlines()
    for label, text in B.numeric_field_variants(lines, keyword, fields):
        case = tmp_path / f"{label}_{name}".replace("=", "_")
        case.write_text(text)
        expect_ok_or_error(inproc("inspect", case), case)


def test_hostile_numbers_in_urg_and_json(tmp_path):
    lines = B.urg_lines()
    for f in (0, 2, 3, 24, 400, 706):
        for v in B.HOSTILE_NUMBERS:
            tok = lines[1].split()
            tok[f] = v
            case = tmp_path / f"u{f}_{v}.dat"
            case.write_text("\n".join([lines[0], " ".join(tok)] + lines[2:]) + "\n")
            expect_ok_or_error(inproc("inspect", case, "--format", "urg"), case)
    for key in ("x", "theta", "range"):
        for v in ("NaN", "Infinity", "-Infinity", "1e999", "1" + "0" * 5000, "[]", '"a"', "null"):
            text = B.keyframe_json().replace(f'"{key}": ', f'"{key}": {v}, "_{key}": ', 1)
            case = tmp_path / f"k_{key}_{len(v)}_{v[:3]}.json"
            case.write_text(text)
            expect_ok_or_error(inproc("inspect", case), case)


def test_mrclam_hostile_values(tmp_path):
    cases = {"Barcodes.dat": ["1 1e30", "nan 5", "1 -99999999999999999999", "3"],
             "Robot1_Measurement.dat": ["0 1e30 1 0", "0 nan 1 0", "0 106 nan 0", "x y z w"],
             "Robot1_Odometry.dat": ["0 nan 0", "inf 0 0", "0 1e308 1e308"]}
    for fname, rows in cases.items():
        for i, row in enumerate(rows):
            d = B.mrclam_dir(tmp_path / f"{fname}_{i}")
            p = d / fname
            p.write_text(p.read_text() + row + "\n")
            expect_ok_or_error(inproc("inspect", d), None)


def test_declared_sizes_that_lie(tmp_path):
    """A beam count that is not what the line holds, 25 M beams, negative, zero."""
    base = B.carmen_lines()
    for n in ("25000000", "-5", "0", "181", "179", "1e3", "99999999999999999999"):
        at = next(i for i, ln in enumerate(base) if ln.startswith("FLASER"))
        tok = base[at].split()
        tok[1] = n
        case = tmp_path / f"n{n[:6]}.log"
        case.write_text("\n".join(base[:at] + [" ".join(tok)] + base[at + 1:]) + "\n")
        expect_ok_or_error(inproc("inspect", case), case)
    gfs = B.gfs_lines()
    at = next(i for i, ln in enumerate(gfs) if ln.startswith("LASER_READING"))
    for n in ("25000000", "-1", "200"):
        tok = gfs[at].split()
        tok[1] = n
        case = tmp_path / f"g{n}.gfs"
        case.write_text("\n".join(gfs[:at] + [" ".join(tok)] + gfs[at + 1:]) + "\n")
        expect_ok_or_error(inproc("inspect", case), case)
    # a ROBOTLASER1 with a remission count past the end of the line
    case = tmp_path / "rl.log"
    case.write_text("ROBOTLASER1 0 -1.57 3.14 0.0175 50 0.01 0 3 1 2 3 99999 0 0 0 0 0 0 0 0 0 0 0 0.1 h 0.1\n")
    expect_ok_or_error(inproc("inspect", case), case)


@pytest.mark.parametrize("content,suffix", [
    (b"", ".log"), (b"", ".mcap"), (b"", ".bag"), (b"", ".h5"), (b"", ".json"), (b"\x00" * 64, ".log"),
    (bytes(range(256)) * 8, ".dat"), (b"#ROSBAG V2.0\n" + b"\xff" * 100, ".bag"),
    (b"\x89MCAP0\r\n" + b"\x00" * 40, ".mcap"), (b"\x89HDF\r\n\x1a\n" + b"\x00" * 100, ".h5"),
    (b"SQLite format 3\x00" + b"\x00" * 100, ".db3"), (b"\x1f\x8b\x08\x00garbage", ".log.gz"),
    (b"\xfd7zXZ\x00garbage", ".log.xz"), (b'{"map": {"1": ', ".json"), (b"{" * 100000, ".json"),
    (b"PARAM a b\nNEFF 1 2\n", ".log"), (b"#GFS_COMMENT only\n", ".gfs"),
])
def test_empty_junk_and_wrong_magic(tmp_path, content, suffix):
    case = tmp_path / f"junk{suffix}"
    case.write_bytes(content)
    expect_error(inproc("inspect", case), case)


def test_forced_wrong_format(corpus):
    d, good = corpus
    for name, fmt in (("s.log", "mcap"), ("s.log", "ros1"), ("s.mcap", "carmen"), ("s.h5", "gfs"),
                      ("s.bag", "victoria"), ("s.gfs", "urg"), ("keyframes.json", "ivslam-h5"),
                      ("s.dat", "keyframe-json"), ("victoria.txt", "mrclam"), ("s.mcap", "nope")):
        expect_ok_or_error(inproc("inspect", good[name], "--format", fmt), good[name])


def test_gz_and_xz_of_corrupt_streams(tmp_path):
    text = "\n".join(B.carmen_lines()).encode()
    for comp, mod in ((".gz", gzip), (".xz", lzma)):
        raw = mod.compress(text)
        for label, data in B.truncations(raw, 6, 9):
            case = tmp_path / f"{label}.log{comp}"
            case.write_bytes(data)
            expect_ok_or_error(inproc("inspect", case), case)
