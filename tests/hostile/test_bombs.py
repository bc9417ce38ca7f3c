"""Inputs that ask for far more memory than they take on disk: compression bombs (a .xz of
~0.9 MB or a multi-member .gz inflating to 5 GiB, of zeros or of valid repeated records),
HDF5 datasets declaring 2^29 beams or a 2^20 x 2^20 map, MCAP chunks declaring or inflating
to hundreds of MiB. Each stops with one line naming the limit (exit 2); the child's peak
resident memory is measured (``wait4``) and must stay under 1.5 GB.

The default-limit runs parse up to 256 MiB of text each (14-63 s): marked ``slow``. The
fast variants lower the limit (``IVSLAM_LIMIT_TEXT_BYTES``) to show the same path, on copies
that inflate to 24 MiB only."""

from __future__ import annotations

import gzip
import lzma
import shutil

import h5py
import numpy as np
import pytest

from tests.hostile import builders as B
from tests.hostile.harness import RSS_LIMIT, cli, expect_error

GiB = 1 << 30


def _bomb(path, unit: bytes, total: int = 5 * GiB, comp: str = "xz", block_bytes: int = 32 << 20):
    """``unit`` repeated to ``total`` bytes, as concatenated compressed members (valid .gz/.xz)."""
    block = unit * max(1, block_bytes // len(unit))
    member = gzip.compress(block, 6) if comp == "gz" else lzma.compress(block, preset=6)
    with open(path, "wb") as f:
        for _ in range(total // len(block)):
            f.write(member)
    return path


UNITS = {
    "odom.log": lambda: "\n".join(ln for ln in B.carmen_lines(40) if ln.startswith("ODOM")) + "\n",
    "flaser.log": lambda: "\n".join(B.carmen_lines(40)) + "\n",
    "s.gfs": lambda: "\n".join(B.gfs_lines(30)) + "\n",
    "s.dat": lambda: "\n".join(B.urg_lines(12)) + "\n",
    "victoria.txt": lambda: "\n".join(B.victoria_lines(30)) + "\n",
}


def _make_bombs(d, **size):
    out = {name: _bomb(d / f"{name}.xz", make().encode(), **size) for name, make in UNITS.items()}
    out["zeros.log.gz"] = _bomb(d / "zeros.log.gz", b"\0" * 4096, comp="gz", **size)
    out["mrclam"] = B.mrclam_dir(d / "mrclam")
    (out["mrclam"] / "Robot1_Odometry.dat").unlink()
    _bomb(out["mrclam"] / "Robot1_Odometry.dat.xz", "".join(f"{0.1 * k:.3f} 0.2 0.01\n" for k in range(1000)).encode(),
          **size)
    out["rel.txt.xz"] = _bomb(d / "rel.txt.xz", ("\n".join(B.relations_lines(30)) + "\n").encode(), **size)
    out["result"] = B.write_result(d / "r.h5")
    js = B.keyframe_json(40)
    out["keyframes.json.xz"] = _bomb(d / "keyframes.json.xz", js[:-2].encode() + b", " + b'"9": 1, ' * 8, **size)
    return out


@pytest.fixture(scope="module")
def bombs(tmp_path_factory):
    """The 5 GiB bombs (about 20 s to make: only the slow tests use them)."""
    return _make_bombs(tmp_path_factory.mktemp("bombs"))


@pytest.fixture(scope="module")
def small_bombs(tmp_path_factory):
    """The same inputs inflating to 24 MiB: past the lowered 8 MiB limits, quick to make."""
    return _make_bombs(tmp_path_factory.mktemp("small_bombs"), total=24 << 20, block_bytes=4 << 20)


def _args(bombs, name):
    if name == "rel.txt.xz":
        return ["report", bombs["result"], "--relations", bombs[name]], bombs[name]
    if name == "mrclam":
        return ["inspect", bombs[name]], bombs[name] / "Robot1_Odometry.dat.xz"
    return ["inspect", bombs[name]], bombs[name]


NAMES = [*UNITS, "zeros.log.gz", "mrclam", "rel.txt.xz", "keyframes.json.xz"]


@pytest.mark.slow
def test_bombs_are_small_on_disk(bombs):
    assert all(bombs[n].stat().st_size < 6 << 20 for n in NAMES if n != "mrclam")


@pytest.mark.parametrize("name", NAMES)
def test_bomb_stops_at_a_lowered_limit(small_bombs, name):
    args, about = _args(small_bombs, name)
    r = cli(*args, timeout=60, env={"IVSLAM_LIMIT_TEXT_BYTES": str(8 << 20), "IVSLAM_LIMIT_JSON_BYTES": str(8 << 20)})
    contains = None if name in ("zeros.log.gz", "keyframes.json.xz") else "TEXT_BYTES"
    expect_error(r, about, contains=contains)
    assert r.peak_rss < RSS_LIMIT, str(r)


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_bomb_at_the_default_limit(bombs, name, record_property):
    """The 5 GiB bombs at the default limits: stopped, peak memory measured (< 1.5 GB)."""
    args, about = _args(bombs, name)
    r = cli(*args, timeout=300)
    expect_error(r, about)
    record_property("peak_rss_mib", round(r.peak_rss / 2**20))
    record_property("seconds", round(r.seconds, 1))
    print(f"{name}: {r.peak_rss / 2**20:.0f} MiB peak, {r.seconds:.1f} s: {r.lines[-1][-90:]}")
    assert r.peak_rss < RSS_LIMIT, str(r)


def test_dev_zero_and_a_declared_2e29_beams_log(tmp_path):
    r = cli("inspect", "/dev/zero", timeout=30)
    expect_error(r, "/dev/zero")
    logs = B.write_logs(tmp_path)
    case = tmp_path / "beams.h5"
    shutil.copy(logs["lidar.h5"], case)
    with h5py.File(case, "a") as f:
        for name, dt in (("ranges", np.float32), ("valid", bool)):
            del f[f"scans/{name}"]
            f.create_dataset(f"scans/{name}", shape=(1 << 29,), dtype=dt, chunks=(1 << 16,), compression="gzip")
        off = f["scans/offsets"][()]
        off[-1] = 1 << 29
        del f["scans/offsets"]
        f["scans/offsets"] = off
    assert case.stat().st_size < 1 << 20
    r = cli("inspect", case, timeout=60)
    expect_error(r, case, contains="BEAMS")
    assert r.peak_rss < RSS_LIMIT, str(r)


def test_result_declaring_a_2e20_square_map(tmp_path):
    case = B.write_result(tmp_path / "r.h5")
    with h5py.File(case, "a") as f:
        g = f["map"] if "map" in f else f.create_group("map")
        if "state" in g:
            del g["state"]
        g.create_dataset("state", shape=(1 << 20, 1 << 20), dtype=np.uint8, chunks=(256, 256), compression="gzip")
    r = cli("report", case, "--map-pgm", tmp_path / "m", timeout=60)
    expect_error(r, case, contains="CELLS")
    assert r.peak_rss < RSS_LIMIT and not (tmp_path / "m.pgm").exists(), str(r)


def _mcap_with_chunk(path, data: bytes, compression: str, declared: int):
    """A minimal MCAP: header, one chunk (``data`` compressed as ``compression``, declaring
    ``declared`` bytes uncompressed), data end, footer — no summary (the streaming path)."""
    from mcap.data_stream import RecordBuilder
    from mcap.records import Chunk, DataEnd, Footer, Header

    b = RecordBuilder()
    Header(profile="ros2", library="hostile").write(b)
    Chunk(compression=compression, data=data, message_start_time=0, message_end_time=0,
          uncompressed_crc=0, uncompressed_size=declared).write(b)
    DataEnd(data_section_crc=0).write(b)
    Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(b)
    path.write_bytes(b"\x89MCAP0\r\n" + bytes(b.end()) + b"\x89MCAP0\r\n")
    return path


@pytest.mark.parametrize("case", ["declares-4GiB", "zstd-inflates-beyond", "lz4-inflates-beyond"])
def test_mcap_chunk_bombs(tmp_path, case):
    import lz4.frame
    import zstandard

    zeros = b"\0" * (300 << 20)
    if case == "declares-4GiB":
        p = _mcap_with_chunk(tmp_path / "a.mcap", zstandard.ZstdCompressor().compress(b"\0" * 1024), "zstd", 4 * GiB)
    elif case == "zstd-inflates-beyond":
        c = zstandard.ZstdCompressor(write_content_size=False).compress(zeros)
        p = _mcap_with_chunk(tmp_path / "b.mcap", c, "zstd", 1024)
    else:
        p = _mcap_with_chunk(tmp_path / "c.mcap", lz4.frame.compress(zeros, store_size=False), "lz4", 1024)
    del zeros
    assert p.stat().st_size < 4 << 20
    r = cli("inspect", p, timeout=60)
    expect_error(r, p)
    assert r.peak_rss < 600 << 20, str(r)  # never the 300 MiB, nor the 4 GiB


def test_bounded_decompression_of_bag_chunks():
    """The decompressors ROS 1 chunks go through (ivslam's and rosbags') stop at the limit."""
    import bz2

    import lz4.frame

    from ivslam_cli import limits
    from ivslam_cli.logs.compression import decompress
    from ivslam_cli.logs.ros_bag import _bound_rosbags_decompressors

    zeros = b"\0" * (300 << 20)
    for kind, data in (("lz4", lz4.frame.compress(zeros)), ("bz2", bz2.compress(zeros, 1)),
                       ("zstd", __import__("zstandard").ZstdCompressor().compress(zeros))):
        with pytest.raises(limits.LimitExceeded):
            decompress(kind, data)
    del zeros
    _bound_rosbags_decompressors()
    from rosbags.rosbag1 import reader as r1

    with pytest.raises(limits.LimitExceeded):
        r1.decompressors["lz4"](lz4.frame.compress(b"\0" * (300 << 20)))
