"""The cases the hostile-input report named, one test each where the generated corpus does
not already pin them down: bounds a pipeline cannot use (refused, or the work bounded and
stopped at a named limit), option-sized allocations, MCAP CRCs on read and on write, a
LaserScan whose ranges disagree with its angles, a NaN odometry increment, usage errors and
options that do not apply, warnings on stderr, and coarse stamps."""

from __future__ import annotations

import lzma
import struct

import numpy as np
import pytest

from tests.hostile import builders as B
from tests.hostile.harness import REPO, RSS_LIMIT, cli, expect_error, inproc

SAMPLE = REPO / "sample_logs"


# ------------------------------------------------------------------ item 1: hangs
@pytest.mark.parametrize("option,value,key", [
    ("--range-abs", "inf", "range_abs"), ("--range-abs", "1e300", "range_abs"), ("--range-abs", "1e6", "range_abs"),
    ("--eps", "1e-300", "eps"), ("--range-rel", "1e4", "range_rel"), ("--q", "100000000000000000000", "q_pair"),
])
def test_pairs_bounds_it_cannot_use_are_refused_at_once(tmp_path, option, value, key):
    r = cli("run", SAMPLE / "pairs.mcap", "--mode", "pairs", option, value, "-o", tmp_path / "r.h5", timeout=60)
    expect_error(r, "command line", contains=key)
    assert r.seconds < 30 and not (tmp_path / "r.h5").exists(), str(r)


def test_pairs_wide_bounds_stop_at_the_work_limit(tmp_path):
    """--range-abs 10 is a usable bound but a huge subpaving: the run stops at pairs.max_work
    (lowered here so the case is quick; the default, 20 M box tests, is a few minutes)."""
    cfg = tmp_path / "c.toml"
    cfg.write_text("[pairs]\nmax_work = 300000\n")
    log = SAMPLE / "pairs.mcap"
    r = cli("run", log, "--mode", "pairs", "--range-abs", "10", "--config", cfg, "-o", tmp_path / "r.h5", timeout=90)
    expect_error(r, log, contains="pairs.max_work = 300,000")
    assert r.seconds < 60 and not (tmp_path / "r.h5").exists(), str(r)


@pytest.mark.parametrize("mode,log,toml,key", [
    ("landmarks", "landmarks.bag", "[landmarks]\nmax_iterations = 1000000000\n", "max_iterations"),
    ("landmarks", "landmarks.bag", "[landmarks]\npose_slices = 2147483647\n", "pose_slices"),
    ("landmarks", "landmarks.bag", "[landmarks]\npose_pieces = 2147483647\n", "pose_pieces"),
    ("lidar", "lidar_rooms.h5", "[lidar]\nmatch_boxes = 2147483647\n", "match_boxes"),
    ("pairs", "pairs.mcap", "[robust]\nq_pair = 1e20\n", "q_pair"),
])
def test_configuration_values_sizing_an_allocation_are_bounded(tmp_path, mode, log, toml, key):
    """Each of these once allocated what the value asked (8 GB for max_iterations = 1e9)."""
    cfg = tmp_path / "c.toml"
    cfg.write_text(toml)
    r = cli("run", SAMPLE / log, "--mode", mode, "--config", cfg, "-o", tmp_path / "r.h5", timeout=60)
    expect_error(r, cfg, contains=key)
    assert r.peak_rss < RSS_LIMIT, str(r)


def test_a_lidar_eps_far_finer_than_the_map_stops_at_the_cell_limit(tmp_path):
    """lidar.eps = 1 mm (the smallest the key takes) over the rooms log once grew past 8 GB."""
    cfg = tmp_path / "c.toml"
    cfg.write_text("[lidar]\neps = 0.001\n")
    log = SAMPLE / "lidar_rooms.h5"
    r = cli("run", log, "--mode", "lidar", "--config", cfg, "-o", tmp_path / "r.h5", timeout=120)
    expect_error(r, log, contains="MAP_CELLS")
    assert r.peak_rss < RSS_LIMIT, str(r)


# ------------------------------------------------------------------ item 5: corrupt data used silently
def _chunks(path):
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    return summary


@pytest.mark.parametrize("fmt", ["mcap", "ros2-mcap"])
def test_simulated_mcap_is_chunked_with_crcs(tmp_path, fmt):
    from mcap.records import Chunk, DataEnd, Footer
    from mcap.stream_reader import StreamReader

    out = tmp_path / ("s.mcap" if fmt == "mcap" else "s_r2m")
    r = cli("simulate", "--scenario", "landmarks", "--steps", "60", "--format", fmt, "-o", out, timeout=60)
    assert r.code == 0, str(r)
    path = out if out.is_file() else next(out.glob("*.mcap"))
    assert _chunks(path).chunk_indexes, "no chunk index: not chunked"
    chunks, data_end, footer = [], None, None
    with open(path, "rb") as f:
        for rec in StreamReader(f, emit_chunks=True, validate_crcs=True).records:
            if isinstance(rec, Chunk):
                chunks.append(rec)
            elif isinstance(rec, DataEnd):
                data_end = rec
            elif isinstance(rec, Footer):
                footer = rec
    assert chunks and all(c.uncompressed_crc != 0 for c in chunks)
    assert data_end is not None and data_end.data_section_crc != 0
    assert footer is not None and footer.summary_crc != 0


def test_a_chunk_failing_its_crc_is_refused(tmp_path):
    """The chunk's CRC (over its decompressed records) is wrong, everything else intact (the
    data-section CRC cleared so that only the chunk's can catch it): one line, exit 2."""
    logs = B.write_logs(tmp_path)
    src = logs["s.mcap"]
    raw = bytearray(src.read_bytes())
    summary = _chunks(src)
    ci = summary.chunk_indexes[0]
    at = ci.chunk_start_offset + 1 + 8 + 8 + 8 + 8  # opcode, length, start/end time, size: the CRC
    (crc,) = struct.unpack_from("<I", raw, at)
    assert crc != 0
    struct.pack_into("<I", raw, at, crc ^ 0x5A5A)
    # the DataEnd record (opcode 0x0F) just before the summary: its data-section CRC to 0
    footer_at = len(raw) - 8 - (1 + 8 + 8 + 8 + 4)
    summary_start = struct.unpack_from("<Q", raw, footer_at + 9)[0]
    data_end = summary_start - 13 if summary_start else len(raw) - 8 - 29 - 13
    assert raw[data_end] == 0x0F
    struct.pack_into("<I", raw, data_end + 9, 0)
    case = tmp_path / "crc.mcap"
    case.write_bytes(bytes(raw))
    for cmd in (["inspect", case], ["run", case, "--mode", "landmarks", "-o", tmp_path / "r.h5"]):
        line = expect_error(inproc(*cmd), case)
        assert "CRC" in line, line
    assert not (tmp_path / "r.h5").exists()


def test_laserscan_whose_ranges_disagree_with_its_angles_is_dropped_and_said(tmp_path):
    from ivslam_cli.logs import read_log
    from ivslam_cli.logs import writers as W

    log = B.simulated("lidar", steps=8)
    msgs = W.messages(log, 2, "{}")
    ts = W.typestore(2)
    scans = [i for i, (_, topic, _) in enumerate(msgs) if topic == "/scan"]
    ns, topic, data = msgs[scans[3]]
    msg = ts.deserialize_cdr(data, W.T_SCAN)
    msg.angle_max = float(msg.angle_max + 7 * msg.angle_increment)  # 7 beams more than the array holds
    msgs[scans[3]] = (ns, topic, bytes(ts.serialize_cdr(msg, W.T_SCAN)))
    case = tmp_path / "mismatch.mcap"
    W._write_mcap(case, msgs, "{}")
    got = read_log(case)
    assert len(got.scans) == len(log.scans) - 1
    r = inproc("inspect", case)
    assert r.code == 0 and "angle_increment" in r.out, str(r)
    assert "duplicated 360" not in r.out


def test_a_nan_odometry_increment_is_an_error_not_a_shorter_log(tmp_path):
    lines = B.victoria_lines(30)
    at = [i for i, ln in enumerate(lines) if ln.startswith("ODOMETRY")][5]
    tok = lines[at].split()
    tok[3] = "nan"
    lines[at] = " ".join(tok)
    case = tmp_path / "victoria.txt"
    case.write_text("\n".join(lines) + "\n")
    expect_error(inproc("inspect", case), case, contains=f"line {at + 1}")
    expect_error(inproc("run", case, "--mode", "pairs", "-o", tmp_path / "r.h5"), case)


# ------------------------------------------------------------------ item 6: huge values
def test_huge_landmark_ids(tmp_path):
    lines = [ln.replace("LANDMARK 3 1000", "LANDMARK 3 99999999999999999999") for ln in B.victoria_lines(30)]
    case = tmp_path / "ids.txt"
    case.write_text("\n".join(lines) + "\n")
    r = inproc("inspect", case)  # an id past int64: the line is dropped, and said (no overflow)
    assert r.code == 0 and "malformed lines (dropped)" in r.out, str(r)


def test_a_1e9_m_scan_pose_stops_at_the_map_limit(tmp_path):
    """A laser pose 1e9 m from the others (once an internal error: a dense grid 'too big')."""
    far = B.carmen_lines(40)
    at = next(i for i, ln in enumerate(far) if ln.startswith("FLASER"))
    tok = far[at].split()
    tok[182:185] = ["1e9", "1e9", "0"]  # the laser pose, 1e9 m away
    tok[185:188] = ["1e9", "1e9", "0"]
    far[at] = " ".join(tok)
    case = tmp_path / "far.log"
    case.write_text("\n".join(far) + "\n")
    r = cli("run", case, "--mode", "lidar", "--poses-known", "-o", tmp_path / "r.h5", timeout=60)
    expect_error(r, case, contains="MAP_CELLS")
    assert r.peak_rss < RSS_LIMIT, str(r)


# ------------------------------------------------------------------ item 8: messages
@pytest.mark.parametrize("args,contains", [
    (["run", "--mode", "nope", "x"], "--mode"), (["run"], "Missing argument 'LOG...'"),
    (["inspect", "--bogus"], "--bogus"), (["frob"], "frob"), (["run", "x", "--heading", "1"], "--heading"),
])
def test_usage_errors_are_one_line(args, contains):
    r = inproc(*args)
    line = expect_error(r, None, contains=contains)
    assert "Usage:" not in r.err and "Try '" not in r.err, str(r)
    assert len(line) < 300, line


@pytest.mark.parametrize("log,args,name", [
    ("pairs.mcap", ["--mode", "pairs", "--poses-known"], "--poses-known"),
    ("pairs.mcap", ["--mode", "pairs", "--initial-pose", "0", "0", "0"], "--initial-pose"),
    ("landmarks.bag", ["--mode", "landmarks", "--anchor", "1", "0", "0"], "--anchor"),
    ("landmarks.bag", ["--mode", "landmarks", "--eps", "0.1"], "--eps"),
    ("landmarks.bag", ["--mode", "landmarks", "--robot", "2"], "--robot"),
    ("lidar_rooms.h5", ["--mode", "lidar", "--q-pose", "1"], "--q-pose"),
])
def test_options_that_do_not_apply_are_errors(tmp_path, log, args, name):
    expect_error(inproc("run", SAMPLE / log, *args, "-o", tmp_path / "r.h5"), None, contains=f"{name} applies to")
    assert not (tmp_path / "r.h5").exists()


def test_no_runtime_warnings_on_stderr(tmp_path):
    """NaN and huge values through a reader and a pipeline: numpy's warnings stay quiet."""
    lines = B.carmen_lines(40)
    at = [i for i, ln in enumerate(lines) if ln.startswith("FLASER")][2]
    tok = lines[at].split()
    tok[5:9] = ["nan", "inf", "1e308", "-1e308"]
    lines[at] = " ".join(tok)
    case = tmp_path / "nan.log"
    case.write_text("\n".join(lines) + "\n")
    for args in (["inspect", case], ["run", case, "--mode", "lidar", "--poses-known", "-o", tmp_path / "r.h5"]):
        r = cli(*args, timeout=90)
        assert not r.timed_out and "Warning" not in r.err and "Traceback" not in r.err, str(r)


# ------------------------------------------------------------------ item 10: coarse stamps
def test_coarse_stamp_carmen_log_is_read_in_file_order(tmp_path):
    from ivslam_cli.logs import read_log

    case = tmp_path / "coarse.log"
    case.write_text(B.coarse_stamp_carmen())
    log = read_log(case)
    assert np.all(np.diff(log.odometry.stamp) > 0) and np.all(np.diff(log.scans.stamp) > 0)
    assert np.all(np.diff(log.odometry.pose[:, 0]) > 0), "the records are not in file order"
    r = inproc("inspect", case)
    assert r.code == 0 and "stamps cannot order the records" in r.out, str(r)
    r = cli("run", case, "--mode", "lidar", "--poses-known", "-o", tmp_path / "r.h5", timeout=90)
    assert r.code == 0, str(r)
    import h5py

    with h5py.File(tmp_path / "r.h5") as f:
        text = " ".join(str(v) for v in f["provenance"].attrs.values())
        text += " ".join(str(f[k][()]) for k in f["provenance"] if isinstance(f["provenance"][k], h5py.Dataset))
    assert "stamps cannot order the records" in text


@pytest.mark.slow  # about a minute of lidar mode on one core
@pytest.mark.datasets
def test_intel_gfs_log_runs_with_its_config(datasets, tmp_path):
    """The shipped GMapping .gfs.log (its first 120 laser keyframes, to stay quick) with its own
    configs/intel_lab.toml: once 'odometry stamps are not strictly increasing'."""
    lines = lzma.open(datasets / "intel_lab" / "intel.gfs.log.xz", "rt").read().splitlines()
    keep, scans = [], 0
    for ln in lines:
        keep.append(ln)
        scans += ln.startswith(("FLASER", "ROBOTLASER1"))
        if scans >= 120:
            break
    case = tmp_path / "intel120.gfs.log"
    case.write_text("\n".join(keep) + "\n")
    r = cli("run", case, "--mode", "lidar", "--config", REPO / "configs" / "intel_lab.toml", "-o", tmp_path / "r.h5",
            timeout=300)
    assert r.code == 0 and "lidar: 120/120 scans" in r.err, str(r)
