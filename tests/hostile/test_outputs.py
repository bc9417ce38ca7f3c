"""Outputs under attack: an output that is an input, a special file, two outputs on one
path, --force on a file ivslam did not write, a missing directory, a full disk, two runs
racing for one path, SIGTERM/SIGINT during a write. Nothing but the expected outputs may
change, no temporary file may be left, every failure is one line."""

from __future__ import annotations

import os
import shutil
import signal
import stat
import subprocess
import time
from pathlib import Path

import pytest

from tests.hostile import builders as B
from tests.hostile.harness import PY, REPO, Snapshot, cli, expect_error, spawn

SAMPLE = REPO / "sample_logs"


@pytest.fixture
def work(tmp_path):
    """A directory with a log, a config, a previous result, a relations file, a stranger's file."""
    shutil.copy(SAMPLE / "pairs.mcap", tmp_path / "log.mcap")
    shutil.copy(SAMPLE / "landmarks.bag", tmp_path / "lm.bag")
    (tmp_path / "c.toml").write_text("[pairs]\nmax_work = 5000000\n")
    B.write_result(tmp_path / "old.h5")
    (tmp_path / "rel.txt").write_text("\n".join(B.relations_lines()) + "\n")
    (tmp_path / "notes.txt").write_text("someone's notes, not an ivslam output\n")
    return tmp_path


def test_output_equal_to_an_input_is_refused_even_with_force(work):
    snap = Snapshot(work)
    for args in (["run", work / "log.mcap", "-o", work / "log.mcap"],
                 ["run", work / "log.mcap", "--config", work / "c.toml", "-o", work / "c.toml"],
                 ["report", work / "old.h5", "--tum", work / "old.h5"],
                 ["report", work / "old.h5", "--relations", work / "rel.txt", "--plot", work / "rel.txt"],
                 ["report", work / "old.h5", "--map-pgm", work / "old"]):  # old.yaml/.pgm new, ok
        r = cli(*args, "--force", timeout=120)
        if args[-1] == work / "old":
            assert r.code in (0, 2), str(r)
            continue
        expect_error(r, args[-1], contains="input")
    snap.assert_unchanged(allow_added={"old.pgm", "old.yaml"})


def test_two_outputs_on_one_path(work):
    snap = Snapshot(work)
    r = cli("run", work / "lm.bag", "--mode", "landmarks", "-o", work / "x.h5", "--tum", work / "x.h5")
    expect_error(r, work / "x.h5", contains="two outputs")
    r = cli("report", work / "old.h5", "--tum", work / "t.png", "--plot", work / "t.png")
    expect_error(r, work / "t.png", contains="two outputs")
    snap.assert_unchanged()


@pytest.mark.parametrize("kind", ["fifo", "chardev", "dir", "symlink-to-input", "stranger", "other-kind"])
def test_force_replaces_only_our_own_outputs(work, kind):
    target = work / "out.h5"
    if kind == "fifo":
        os.mkfifo(target)
    elif kind == "chardev":
        target = Path("/dev/null")
    elif kind == "dir":
        target.mkdir()
    elif kind == "symlink-to-input":
        target.symlink_to(work / "log.mcap")
    elif kind == "stranger":
        target.write_bytes(b"precious, not ours")
    else:  # a log ivslam wrote is not a result
        shutil.copy(SAMPLE / "lidar_rooms.h5", target)
    snap = Snapshot(work)
    null_mode = os.stat("/dev/null").st_mode
    r = cli("run", work / "log.mcap", "-o", target, "--force", "--config", work / "c.toml", timeout=120)
    expect_error(r, target)
    snap.assert_unchanged()
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode) and os.stat("/dev/null").st_mode == null_mode


def test_force_replaces_a_previous_result(work):
    r = cli("run", work / "log.mcap", "-o", work / "old.h5", "--force", "--config", work / "c.toml", timeout=120)
    assert r.code == 0, str(r)
    r = cli("report", work / "old.h5", "--json")
    assert r.code == 0 and '"mode": "pairs"' in r.out


def test_missing_directory_leaves_nothing(work):
    snap = Snapshot(work)
    r = cli("run", work / "lm.bag", "--mode", "landmarks", "-o", work / "r.h5", "--tum", work / "nope" / "r.tum",
            timeout=120)
    expect_error(r, work / "nope" / "r.tum", contains="does not exist")
    r = cli("report", work / "old.h5", "--tum", work / "t.tum", "--plot", work / "nope" / "p.png")
    expect_error(r, work / "nope" / "p.png")
    snap.assert_unchanged()


def test_report_exports_are_all_or_nothing(work):
    """The last export fails (a result without a map): the earlier ones are not left."""
    shutil.copy(work / "old.h5", work / "nomap.h5")
    import h5py

    with h5py.File(work / "nomap.h5", "a") as f:
        if "map" in f:
            del f["map"]
        if "logodds" in f:
            del f["logodds"]
    snap = Snapshot(work)
    r = cli("report", work / "nomap.h5", "--tum", work / "t.tum", "--map-pgm", work / "m")
    expect_error(r, work / "nomap.h5", contains="no map grid")
    snap.assert_unchanged()


def _can_mount_tmpfs(d: Path) -> bool:
    if os.geteuid() != 0 or not shutil.which("mount"):
        return False
    d.mkdir(exist_ok=True)
    ok = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(d)], capture_output=True).returncode == 0
    return ok


WRITERS = [("run", "landmarks", "r.h5"), ("run", "landmarks", "r.tum"), ("simulate", "mcap", "s.mcap"),
           ("simulate", "ros1", "s.bag"), ("simulate", "ros2", "s_ros2"), ("simulate", "ros2-mcap", "s_r2m"),
           ("simulate", "h5", "s.h5"), ("report", "tum", "t.tum"), ("report", "plot", "p.png"),
           ("report", "map-pgm", "m")]


def _writer_args(work: Path, out_dir: Path, cmd: str, what: str, name: str) -> list:
    out = out_dir / name
    if cmd == "run" and name.endswith(".tum"):
        return ["run", work / "lm.bag", "--mode", "landmarks", "-o", work / "keep.h5", "--tum", out]
    if cmd == "run":
        return ["run", work / "lm.bag", "--mode", what, "-o", out]
    if cmd == "simulate":
        return ["simulate", "--scenario", "landmarks", "--steps", "400", "--format", what, "-o", out]
    flag = {"tum": "--tum", "plot": "--plot", "map-pgm": "--map-pgm"}[what]
    return ["report", work / "old.h5", flag, out]


@pytest.mark.slow
def test_full_disk_tmpfs(work):
    """On a 64 KiB tmpfs (where the machine lets us mount one): one line naming the output,
    exit 1 (an I/O failure), nothing left on the full disk, no segfault."""
    full = work / "full"
    if not _can_mount_tmpfs(full):
        pytest.skip("cannot mount a small tmpfs here (needs root)")
    failed = 0
    try:
        for cmd, what, name in WRITERS:
            before = sorted(os.listdir(full))
            (work / "keep.h5").unlink(missing_ok=True)
            r = cli(*_writer_args(work, full, cmd, what, name), timeout=180)
            if r.code == 0:  # it fitted
                shutil.rmtree(full / name, ignore_errors=True) if (full / name).is_dir() else None
                for p in full.iterdir():
                    p.unlink() if p.is_file() else shutil.rmtree(p)
                continue
            assert r.signal == 0, f"killed by a signal (segfault?): {r}"
            failed += 1
            shown = full / (name + ".pgm" if what == "map-pgm" else name)
            expect_error(r, shown if what != "map-pgm" else None, code=1, contains="No space left")
            assert sorted(os.listdir(full)) == before, f"left on the full disk: {os.listdir(full)}"
            assert not (work / "keep.h5").exists()  # the run's other output was not left either
        assert failed >= 7, f"only {failed} writers met the full disk"
    finally:
        subprocess.run(["umount", str(full)], check=False)


def test_file_size_limit_everywhere(work):
    """RLIMIT_FSIZE (EFBIG, any machine): the same contract as a full disk."""
    out = work / "o"
    out.mkdir()
    warm = work / "warm"  # numba writes its cache on a cold first call: not an output under test
    warm.mkdir()
    for cmd, what, name in WRITERS:
        cli(*_writer_args(work, warm, cmd, what, name), timeout=180)
    (work / "keep.h5").unlink(missing_ok=True)
    failed = 0
    for cmd, what, name in WRITERS:
        (work / "keep.h5").unlink(missing_ok=True)
        r = cli(*_writer_args(work, out, cmd, what, name), timeout=180, fsize=40_000)
        if r.code == 0:
            for p in out.iterdir():
                p.unlink() if p.is_file() else shutil.rmtree(p)
            continue
        failed += 1
        shown = out / (name + ".pgm" if what == "map-pgm" else name)
        expect_error(r, shown if what not in ("map-pgm", "landmarks") else None, code=1, contains="cannot write")
        assert not [p for p in out.iterdir()], f"left: {list(out.iterdir())}"
        assert not (work / "keep.h5").exists()  # the run's other output was not left either
        assert not [p.name for p in work.iterdir() if p.name.startswith(".")]
    assert failed >= 7, f"only {failed} writers met the limit"


def test_two_runs_racing_for_one_new_path(work):
    """8 rounds of two processes writing the same new -o without --force: one wins."""
    code = ("import sys, time; from ivslam_cli.atomic import write_text_atomic;\n"
            "t = float(sys.argv[2])\n"
            "while time.time() < t: pass\n"
            "try:\n    write_text_atomic(sys.argv[1], sys.argv[3])\n"
            "except Exception as e:\n    print(e); sys.exit(2)\n")
    for k in range(8):
        target = work / f"race{k}.txt"
        start = time.time() + 0.5
        procs = [subprocess.Popen([PY, "-c", code, str(target), str(start), who], cwd=REPO,
                                  stdout=subprocess.PIPE, text=True) for who in ("a", "b")]
        codes = [p.wait(timeout=30) for p in procs]
        assert sorted(codes) == [0, 2], codes
        winner = "ab"[codes.index(0)]
        assert target.read_text() == winner
    assert not [p.name for p in work.iterdir() if p.name.startswith(".")]


# the result's temporary file is complete and about to be staged when the signal comes
SLOW_COMMIT = ("import sys, time, ivslam_cli.atomic as a\n"
               "real = a._finish\n"
               "def slow(item):\n    print('staging', item.path, flush=True)\n    time.sleep(60)\n    real(item)\n"
               "a._finish = slow\n"
               "from ivslam_cli.cli import main\nmain(sys.argv[1:])\n")


@pytest.mark.parametrize("sig,code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_signal_during_a_write(work, sig, code):
    snap = Snapshot(work)

    def hit(p):
        deadline = time.time() + 120
        while time.time() < deadline and p.poll() is None:  # wait for the temp file of the result
            if any(n.name.startswith(".r.h5.") for n in work.iterdir()):
                break
            time.sleep(0.05)
        time.sleep(0.3)
        os.kill(p.pid, sig)

    r = spawn([PY, "-c", SLOW_COMMIT, "run", str(work / "lm.bag"), "--mode", "landmarks", "-o", str(work / "r.h5"),
               "--tum", str(work / "r.tum")], timeout=150, on_start=hit)
    assert not r.timed_out, str(r)
    assert r.code == code, str(r)
    assert r.lines[-1] in ("ivslam: interrupted", "ivslam: terminated (SIGTERM)"), str(r)
    assert "Traceback" not in r.err and "Aborted" not in r.err
    snap.assert_unchanged()


def test_inputs_that_are_special_files(work):
    """A FIFO as LOG, RESULT, --config, --relations, --world; /dev/zero and a directory as a log:
    refused at once (nothing ever writes to the FIFO: an open() would block forever)."""
    fifo = work / "p.fifo"
    os.mkfifo(fifo)
    cases = [(["inspect", fifo], fifo), (["run", fifo], fifo), (["report", fifo], fifo),
             (["run", work / "log.mcap", "--config", fifo], fifo),
             (["report", work / "old.h5", "--relations", fifo], fifo),
             (["simulate", "--scenario", "lidar", "--world", fifo, "-o", work / "w.mcap"], fifo),
             (["inspect", "/dev/zero"], "/dev/zero"), (["run", "/dev/urandom"], "/dev/urandom"),
             (["report", "/dev/zero"], "/dev/zero")]
    d = work / "bagdir"
    d.mkdir()
    (d / "metadata.yaml").write_text("x")
    os.mkfifo(d / "data.db3")
    cases.append((["inspect", d], d))
    for args, about in cases:
        r = cli(*args, timeout=30)
        expect_error(r, about)
        assert r.seconds < 20


def test_output_inside_an_input_directory(work, tmp_path):
    bag = work / "bag2"
    shutil.copytree(REPO / "sample_logs", work / "samples")
    r = cli("simulate", "--scenario", "pairs", "--steps", "5", "--format", "ros2", "-o", bag)
    assert r.code == 0, str(r)
    snap = Snapshot(work)
    r = cli("run", bag, "--mode", "pairs", "-o", bag / "inside.h5")
    expect_error(r, bag / "inside.h5", contains="input")
    snap.assert_unchanged()
