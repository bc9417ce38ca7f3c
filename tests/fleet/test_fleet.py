"""``ivslam run`` over many logs: inputs, executors (sequential, process pool, a real Dask
LocalCluster), a broken log among good ones, --resume, the fleet audit and ``report DIR``."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from click.testing import CliRunner

from ivslam_cli.cli import cli

SEEDS = (1, 2, 3)


def ivslam(*args):
    """``ivslam ARGS`` in-process: (exit code, stdout, stderr)."""
    r = CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)
    return r.exit_code, r.stdout, r.stderr


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> Path:
    """A directory of three small simulated landmark logs (and a file that is not a log)."""
    d = tmp_path_factory.mktemp("fleet_logs")
    for seed in SEEDS:
        code, _, err = ivslam("simulate", "--scenario", "landmarks", "--steps", "200", "--seed", seed,
                              "-o", d / f"lm{seed}.mcap")
        assert code == 0, err
    (d / "README.txt").write_text("not a log\n")
    return d


def _datasets(path: Path) -> dict[str, np.ndarray]:
    out = {}
    with h5py.File(path, "r") as f:
        f.visititems(lambda name, obj: out.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
        attrs = {k: v for k, v in f.attrs.items() if k != "runtime_s"}
    return out, attrs


def _same_results(a: Path, b: Path) -> None:
    da, aa = _datasets(a)
    db, ab = _datasets(b)
    assert sorted(da) == sorted(db)
    for name in da:
        x, y = da[name], db[name]
        if x.dtype.kind == "f":
            assert np.array_equal(x, y, equal_nan=True), name
        else:
            assert np.array_equal(x, y), name
    assert aa == ab


def _audit(out: Path) -> dict:
    return json.loads((out / "fleet.json").read_text())


@pytest.mark.slow  # a LocalCluster and three batches: ~5 s
def test_sequential_pool_and_dask_cluster_give_the_same_results(logs, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    seq, pool, dask_out = tmp_path / "seq", tmp_path / "pool", tmp_path / "dask"
    code, _, err = ivslam("run", logs, "--mode", "landmarks", "-o", seq, "--jobs", "1")
    assert code == 0, err
    code, _, err = ivslam("run", logs, "--mode", "landmarks", "-o", pool, "--jobs", "2")
    assert code == 0, err
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, protocol="tcp",
                                  dashboard_address=None) as cluster:
        code, _, err = ivslam("run", logs, "--mode", "landmarks", "-o", dask_out,
                              "--scheduler", cluster.scheduler_address)
    assert code == 0, err
    names = [f"lm{s}.landmarks.h5" for s in SEEDS]
    for out in (seq, pool, dask_out):
        assert sorted(p.name for p in out.glob("*.h5")) == names
        doc = _audit(out)
        assert [r["status"] for r in doc["logs"]] == ["ok"] * 3
        assert doc["totals"]["ok"] == 3
        assert (out / "fleet.txt").read_text().startswith("# ivslam fleet audit: ")
    assert _audit(seq)["executor"] == "sequential"
    assert _audit(pool)["executor"] == "process pool"
    assert _audit(dask_out)["executor"].startswith("dask tcp://")
    for name in names:
        _same_results(seq / name, pool / name)
        _same_results(seq / name, dask_out / name)
    # the audit's records agree too (timings and workers aside)
    strip = ("runtime_s", "wall_s", "cpu_s", "host", "pid")
    recs = [[{k: v for k, v in r.items() if k not in strip} for r in _audit(o)["logs"]] for o in (seq, pool, dask_out)]
    assert recs[0] == recs[1] == recs[2]


def test_a_broken_log_fails_alone(logs, tmp_path):
    d = tmp_path / "mixed"
    shutil.copytree(logs, d)
    (d / "broken.bag").write_bytes(b"#ROSBAG V2.0\ngarbage")
    out = tmp_path / "out"
    code, _, err = ivslam("run", d, "--mode", "landmarks", "-o", out, "--jobs", "2")
    assert code == 4, err
    assert "Traceback" not in err
    errors = [line for line in err.splitlines() if line.startswith("ivslam: error:")]
    assert len(errors) == 1 and "broken.bag" in errors[0]
    doc = _audit(out)
    by_log = {Path(r["log"]).name: r for r in doc["logs"]}
    assert by_log["broken.bag"]["status"] == "error"
    assert "\n" not in by_log["broken.bag"]["message"] and "broken.bag" in by_log["broken.bag"]["message"]
    assert all(by_log[f"lm{s}.mcap"]["status"] == "ok" for s in SEEDS)
    assert doc["totals"] == {**doc["totals"], "logs": 4, "ok": 3, "error": 1}
    assert sorted(p.name for p in out.glob("*.h5")) == [f"lm{s}.landmarks.h5" for s in SEEDS]
    assert not list(out.glob(".*"))  # no temporary left


@pytest.mark.slow
def test_resume_and_existing_results(logs, tmp_path):
    out = tmp_path / "out"
    code, _, err = ivslam("run", logs / "lm1.mcap", logs / "lm2.mcap", "--mode", "landmarks", "-o", out, "--jobs", 1)
    assert code == 0, err
    before = (out / "lm1.landmarks.h5").stat().st_mtime_ns
    # an existing result is kept: the batch refuses before any work
    code, _, err = ivslam("run", logs, "--mode", "landmarks", "-o", out, "--jobs", 1)
    assert code == 2 and err.count("\n") == 1 and "already exists" in err and "--resume" in err, err
    assert not (out / "lm3.landmarks.h5").exists()
    # --resume: the two done are skipped, the third runs
    code, _, err = ivslam("run", logs, "--mode", "landmarks", "-o", out, "--jobs", 1, "--resume")
    assert code == 0, err
    assert (out / "lm1.landmarks.h5").stat().st_mtime_ns == before
    doc = _audit(out)
    assert [r["resumed"] for r in doc["logs"]] == [True, True, False]
    assert [r["status"] for r in doc["logs"]] == ["ok"] * 3
    assert doc["totals"]["resumed"] == 2
    # --force replaces them (ours only)
    code, _, err = ivslam("run", logs, "--mode", "landmarks", "-o", out, "--jobs", 1, "--force")
    assert code == 0, err
    assert (out / "lm1.landmarks.h5").stat().st_mtime_ns != before
    assert _audit(out)["totals"]["resumed"] == 0


def test_an_empty_directory_is_a_one_line_error(tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("nothing here\n")
    code, _, err = ivslam("run", empty, "-o", tmp_path / "out")
    assert code == 2
    assert err == f"ivslam: error: {empty}: no log in this directory that a reader recognises\n"
    assert not (tmp_path / "out").exists()


def test_several_logs_need_an_output_directory(logs):
    code, _, err = ivslam("run", logs / "lm1.mcap", logs / "lm2.mcap", "--mode", "landmarks")
    assert code == 2 and err.startswith("ivslam: error: several logs need -o DIR"), err


@pytest.mark.slow
def test_manifest_with_per_log_overrides(logs, tmp_path):
    cfg = tmp_path / "wide.toml"
    cfg.write_text("[bounds]\nrange_abs = 0.5\n")
    manifest = tmp_path / "fleet.list"
    manifest.write_text(f"# nightly logs\n{logs / 'lm1.mcap'}\n"
                        f"'{logs / 'lm2.mcap'}' --config wide.toml  # wider range bound\n"
                        f"{logs / 'lm3.mcap'} --mode pairs\n")
    out = tmp_path / "out"
    code, _, err = ivslam("run", manifest, "--mode", "landmarks", "-o", out, "--jobs", 1)
    assert code == 0, err
    assert sorted(p.name for p in out.glob("*.h5")) == ["lm1.landmarks.h5", "lm2.landmarks.h5", "lm3.pairs.h5"]
    modes = [r["mode"] for r in _audit(out)["logs"]]
    assert modes == ["landmarks", "landmarks", "pairs"]
    with h5py.File(out / "lm2.landmarks.h5") as f:
        assert json.loads(f["provenance"].attrs["config_json"])["bounds"]["range_abs"] == 0.5
    bad = tmp_path / "bad.list"
    bad.write_text(f"{logs / 'lm1.mcap'} --q 3\n")
    code, _, err = ivslam("run", bad, "-o", tmp_path / "o2")
    assert code == 2 and err.startswith(f"ivslam: error: {bad}:1: unknown per-log option '--q'"), err


@pytest.mark.slow
def test_mode_auto_over_the_sample_logs(tmp_path):
    from tests.helpers.paths import REPO

    out = tmp_path / "out"
    code, _, err = ivslam("run", REPO / "sample_logs" / "pairs.mcap", REPO / "sample_logs" / "landmarks.bag",
                          "--mode", "auto", "--initial-pose-from-truth", "-o", out, "--jobs", 1)
    assert code == 0, err
    assert sorted(p.name for p in out.glob("*.h5")) == ["landmarks.landmarks.h5", "pairs.pairs.h5"]


@pytest.mark.slow
def test_report_of_a_batch_directory(logs, tmp_path):
    d = tmp_path / "mixed"
    d.mkdir()
    shutil.copy(logs / "lm1.mcap", d)
    (d / "broken.bag").write_bytes(b"#ROSBAG V2.0\ngarbage")
    out = tmp_path / "out"
    code, _, _ = ivslam("run", d, "--mode", "landmarks", "-o", out, "--jobs", 1, "--quiet")
    assert code == 4
    code, text, err = ivslam("report", out)
    assert code == 0, err
    assert "1 ok, 0 proven inconsistent, 1 failed" in text
    assert "containment: landmark 1, pose 1" in text and "broken.bag [landmarks]: ERROR" in text
    code, js, _ = ivslam("report", out, "--json")
    assert code == 0 and json.loads(js)["totals"]["error"] == 1
    code, _, err = ivslam("report", out, "--plot", tmp_path / "fleet.png")
    assert code == 0, err
    assert (tmp_path / "fleet.png").read_bytes().startswith(b"\x89PNG")
    code, _, err = ivslam("report", out, "--tum", tmp_path / "t.tum")
    assert code == 2 and "applies to one result" in err
    code, _, err = ivslam("report", d)
    assert code == 2 and "without fleet.json" in err


@pytest.mark.slow
def test_strict_batch_exits_3_and_records_where_it_stopped(logs, tmp_path):
    from tests.helpers.paths import REPO

    out = tmp_path / "out"
    code, _, err = ivslam("run", logs / "lm1.mcap", REPO / "sample_logs" / "landmarks.bag", "--mode", "landmarks",
                          "--initial-pose-from-truth", "--strict", "-o", out, "--jobs", 1, "--quiet")
    assert code == 3, err
    recs = _audit(out)["logs"]
    assert [r["status"] for r in recs] == ["ok", "inconsistent"]
    assert recs[1]["stopped"] and recs[1]["message"].startswith("stopped (--strict): ")
    assert recs[1]["empty_events"] >= 1 and recs[1]["empty_event_list"][0]["constraint"]


def test_logs_run_in_parallel_track_with_one_thread_each(monkeypatch):
    """A pool or a Dask cluster parallelises over the logs: each job runs lidar.threads = 1; one
    after another, each log keeps the default (the cores)."""
    from ivslam_cli.fleet import execute
    from ivslam_cli.fleet.job import Job, RunOptions

    seen: dict = {}
    monkeypatch.setattr(execute, "run_pool", lambda jobs, done, workers: seen.setdefault("pool", jobs))
    monkeypatch.setattr(execute, "run_dask", lambda jobs, done, client: seen.setdefault("dask", jobs))
    monkeypatch.setattr(execute, "run_sequential", lambda jobs, done: seen.setdefault("sequential", jobs))
    jobs = [Job(log=f"/logs/{i}.h5", out_dir="/out", name=str(i), opts=RunOptions(mode="lidar")) for i in range(2)]
    execute.run_jobs(jobs, lambda i, r: None, workers=2, scheduler=None)
    execute.run_jobs(jobs, lambda i, r: None, workers=2, scheduler="tcp://x:1", client=object())
    execute.run_jobs(jobs, lambda i, r: None, workers=1, scheduler=None)
    for kind in ("pool", "dask"):
        assert [j.opts.overrides()["lidar.threads"] for j in seen[kind]] == [1, 1]
    assert [j.opts.overrides()["lidar.threads"] for j in seen["sequential"]] == [None, None]
