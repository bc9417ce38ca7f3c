"""Bad input: truncated / byte-flipped copies, empty files, unknown formats, missing topics.
Only LogError may come out (never another exception), and never a hang (SIGALRM guard)."""

from __future__ import annotations

import gzip
import shutil
import signal
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from ivslam_cli.errors import LogError
from ivslam_cli.logs import list_formats, read_log


@contextmanager
def time_limit(seconds: int):
    def boom(*_):
        raise TimeoutError("reader hung")

    old = signal.signal(signal.SIGALRM, boom)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def _only_logerror(path: Path, **kw) -> None:
    with time_limit(20):
        try:
            read_log(path, **kw)
        except LogError as exc:
            msg = str(exc)
            assert "\n" not in msg and str(path) in msg


@pytest.fixture(scope="module")
def small_logs(tmp_path_factory):
    """Small synthetic bag / MCAP / CARMEN logs written with the real writers."""
    from bench.bench_readers import write_bag, write_mcap

    d = tmp_path_factory.mktemp("logs")
    write_bag(d / "s.bag", n=40)
    write_mcap(d / "s.mcap", n=40)
    lines = [f"ODOM {k * 0.1} 0 0 0.1 0 0 {k * 0.1} host {k * 0.1}" for k in range(20)]
    lines += [f"FLASER 4 1 2 3 4 0 0 0 0 0 0 {k * 0.1} host {k * 0.1}" for k in range(20)]
    (d / "s.log").write_text("\n".join(lines) + "\n")
    with gzip.open(d / "s.log.gz", "wt") as f:
        f.write("\n".join(lines) + "\n")
    return d


KINDS = ["s.bag", "s.mcap", "s.log", "s.log.gz"]


@pytest.mark.parametrize("name", KINDS)
def test_small_logs_read(small_logs, name):
    log = read_log(small_logs / name)
    assert len(log.scans) in (20, 40)


@pytest.mark.parametrize("name", KINDS)
def test_truncated_copies(small_logs, tmp_path, name):
    raw = (small_logs / name).read_bytes()
    rng = np.random.default_rng(len(name))
    for i, cut in enumerate(sorted(rng.integers(0, len(raw), 12))):
        p = tmp_path / f"t{i}_{name}"
        p.write_bytes(raw[:cut])
        _only_logerror(p)


@pytest.mark.parametrize("name", KINDS)
def test_byte_flipped_copies(small_logs, tmp_path, name):
    raw = (small_logs / name).read_bytes()
    rng = np.random.default_rng(7 + len(name))
    for i in range(12):
        buf = bytearray(raw)
        for pos in rng.integers(0, len(raw), 1 + i % 4):
            buf[pos] ^= int(rng.integers(1, 256))
        p = tmp_path / f"f{i}_{name}"
        p.write_bytes(bytes(buf))
        _only_logerror(p)


@pytest.mark.datasets
def test_truncated_real_bags(datasets, tmp_path):
    for rel in ("ros1_ccny_urg04lx_scan_only/demo.bag",
                "mcap_turtlebot4_comprobo22/macfirst_floor_take_2.mcap"):
        raw = (datasets / rel).read_bytes()
        for frac in (0.1, 0.5, 0.93):
            p = tmp_path / f"{frac}_{Path(rel).name}"
            p.write_bytes(raw[: int(len(raw) * frac)])
            with pytest.raises(LogError):
                with time_limit(20):
                    read_log(p)


def test_empty_unknown_and_missing(tmp_path):
    for name, content in (("e.bag", b""), ("e.mcap", b""), ("e.log", b""),
                          ("x.xyz", b"hello world\n"), ("b.bag", b"not a bag at all"),
                          ("c.log", b"PARAM a b\nNEFF 1 2\n")):
        p = tmp_path / name
        p.write_bytes(content)
        with pytest.raises(LogError, match=str(p)):
            read_log(p)
    with pytest.raises(LogError, match="no such file"):
        read_log(tmp_path / "nope.bag")
    (tmp_path / "dir").mkdir()
    with pytest.raises(LogError, match="neither a ROS 2 bag"):
        read_log(tmp_path / "dir")
    with pytest.raises(LogError, match="unknown format"):
        read_log(tmp_path / "x.xyz", fmt="nope")
    assert "carmen" in list_formats() and "ivslam-h5" in list_formats()


def test_missing_and_mistyped_topics(small_logs):
    with pytest.raises(LogError, match="'/nope' not in log"):
        read_log(small_logs / "s.bag", scan_topic="/nope")
    with pytest.raises(LogError, match="has type sensor_msgs/msg/LaserScan"):
        read_log(small_logs / "s.mcap", odom_topic="/scan")


def test_forced_wrong_format_is_a_logerror(small_logs):
    for fmt in ("carmen", "victoria", "urg", "mcap", "ros1"):
        _only_logerror(small_logs / "s.log" if fmt in ("mcap", "ros1") else
                       small_logs / "s.bag", fmt=fmt)


def test_out_of_order_and_nan_odometry_are_counted(tmp_path):
    lines = ["ODOM 0 0 0 0 0 0 0.0 h 0", "ODOM 1 0 0 0 0 0 0.2 h 0",
             "ODOM 2 0 0 0 0 0 0.1 h 0", "ODOM nan 0 0 0 0 0 0.3 h 0",
             "FLASER 3 1 0 inf 0 0 0 0 0 0 0.5 h 0"]
    p = tmp_path / "o.log"
    p.write_text("\n".join(lines) + "\n")
    log = read_log(p)
    got = {(d.stream, d.reason): d.count for d in log.provenance.dropped}
    assert got["odometry", "rows with NaN/inf (dropped)"] == 1
    assert got["odometry", "out-of-order stamps (sorted, kept)"] == 1
    np.testing.assert_array_equal(log.odometry.stamp, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(log.odometry.pose[:, 0], [0, 2, 1])
    np.testing.assert_array_equal(log.scans.valid, [True, False, False])
