"""The command group itself: help, version, cold start, the error policy."""

from __future__ import annotations

import subprocess
import sys

from ivslam_cli import __version__
from tests.helpers.paths import REPO


def test_version(cli_run):
    res = cli_run("--version")
    assert res.exit_code == 0
    assert __version__ in res.output


def test_help_lists_every_command(cli_run):
    res = cli_run("--help")
    assert res.exit_code == 0
    for name in ("run", "report", "simulate", "inspect"):
        assert name in res.output


def test_every_command_has_help_with_example(cli_run):
    for name in ("run", "report", "simulate", "inspect"):
        res = cli_run(name, "--help")
        assert res.exit_code == 0, res.output
        assert "ivslam " + name in res.output, f"{name} --help shows no example"


def test_help_is_cold_fast_and_loads_no_kernel():
    code = (
        "import sys, time; t=time.perf_counter();"
        "from ivslam_cli.cli import cli;"
        "import click.testing as ct; r=ct.CliRunner().invoke(cli,['--help']);"
        "assert r.exit_code==0;"
        "print(time.perf_counter()-t, 'numba' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    seconds, numba_loaded = out.stdout.split()
    assert numba_loaded == "False"
    assert float(seconds) < 0.5


#: what ``ivslam run`` on a pairs log never needs: other commands, pipelines and readers, the
#: batch executors, the optional plotting and cluster libraries
NOT_FOR_A_PAIRS_RUN = ("matplotlib", "dask", "distributed", "ivslam_cli.report", "ivslam_cli.simulate",
                       "ivslam_cli.slam.landmarks", "ivslam_cli.slam.lidar", "ivslam_cli.fleet.batch",
                       "ivslam_cli.fleet.execute", "ivslam_cli.logs.ros_bag", "rosbags.rosbag1", "rosbags.rosbag2")
#: and on a log in ivslam's own HDF5 format, the MCAP and ROS message libraries
NOT_FOR_AN_H5_LOG = ("mcap", "rosbags", "ivslam_cli.logs.mcap_file")


_RUN = """
import os, sys
import ivslam_cli.cli as cli


def report(code):  # instead of ending the process, say what it holds
    from numba.core.dispatcher import Dispatcher

    assert code == 0, code
    ours = [m for n, m in list(sys.modules.items()) if n.startswith("ivslam_cli")]
    kernels = {d.py_func.__module__ for m in ours for d in vars(m).values() if isinstance(d, Dispatcher) and d.overloads}
    print(*sorted(sys.modules))
    print(*sorted(kernels))
    print(len(os.listdir("/proc/self/task")) if os.path.isdir("/proc/self/task") else 1)
    sys.stdout.flush()
    os._exit(0)


cli.end = report
cli.main(["run", *sys.argv[1:], "--quiet"])
"""


def _imported_by_run(log, out) -> tuple[set[str], set[str], int]:
    """What ``ivslam run LOG -o OUT`` holds at its end (a fresh process, through the console-script
    entry point): the modules imported, those whose kernels were loaded, the number of threads."""
    res = subprocess.run([sys.executable, "-c", _RUN, str(log), "-o", str(out)], capture_output=True, text=True,
                         check=True, cwd=REPO)
    modules, kernels, threads = res.stdout.splitlines()
    return set(modules.split()), set(kernels.split()), int(threads)


def _under(modules: set[str], roots: tuple[str, ...]) -> list[str]:
    return sorted(m for m in modules if any(m == r or m.startswith(r + ".") for r in roots))


def test_a_pairs_run_imports_and_loads_only_what_it_uses(cli_run, tmp_path, monkeypatch):
    """``ivslam run`` pays only for its mode and its log's format: no other pipeline, reader or
    command is imported, the kernels a warm run loads are those of the pairs pipeline (and the
    interval arithmetic it calls from Python), and no BLAS thread is started."""
    for name in ("pairs.mcap", "pairs.h5"):
        assert cli_run("simulate", "--scenario", "pairs", "--steps", "5", "-o", tmp_path / name).exit_code == 0
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    # warm: on a cold cache the kernels the pairs kernel calls are compiled with it (and counted)
    _imported_by_run(tmp_path / "pairs.mcap", tmp_path / "r0.h5")
    modules, kernels, threads = _imported_by_run(tmp_path / "pairs.mcap", tmp_path / "r1.h5")
    assert "mcap" in modules and "ivslam_cli.slam.pairs" in modules  # the check sees what a run imports
    assert not _under(modules, NOT_FOR_A_PAIRS_RUN)
    assert kernels and all(k.startswith(("ivslam_cli.slam.pairs.", "ivslam_cli.interval.")) for k in kernels), kernels
    assert threads == 1
    modules, _, _ = _imported_by_run(tmp_path / "pairs.h5", tmp_path / "r2.h5")
    assert not _under(modules, NOT_FOR_A_PAIRS_RUN + NOT_FOR_AN_H5_LOG)


_RUN_COLLECTIONS = """
import gc, os, sys
import ivslam_cli.cli as cli
from ivslam_cli import collector

paused = []  # per collection: did it run while the start of the run paused the collector?


def seen(phase, info):
    if phase == "start":
        paused.append(gc.get_threshold()[0] == collector.START_THRESHOLD)


gc.callbacks.append(seen)


def report(code):
    assert code == 0, code
    print(sum(paused), gc.get_freeze_count(), gc.get_threshold()[0])
    sys.stdout.flush()
    os._exit(0)


cli.end = report
cli.main(["run", *sys.argv[1:], "--quiet"])
"""


def test_a_run_collects_no_garbage_before_its_pipeline(cli_run, tmp_path):
    """The start of ``ivslam run`` (imports, the log read) allocates fewer objects than the paused
    collector waits for: no collection; the pipeline starts with them frozen and the threshold back."""
    from ivslam_cli import collector

    assert cli_run("simulate", "--scenario", "pairs", "--steps", "5", "-o", tmp_path / "p.mcap").exit_code == 0
    for k in range(2):  # the second warm: a cold cache compiles the kernels (in the pipeline)
        res = subprocess.run([sys.executable, "-c", _RUN_COLLECTIONS, str(tmp_path / "p.mcap"), "-o",
                              str(tmp_path / f"r{k}.h5")], capture_output=True, text=True, check=True, cwd=REPO)
    while_paused, frozen, threshold = map(int, res.stdout.split())
    assert while_paused == 0
    assert frozen > 50_000  # the modules, the reader's objects, numba's
    assert threshold == collector.YOUNG_THRESHOLD


def test_unknown_command_fails_cleanly(cli_run):
    res = cli_run("frobnicate")
    assert res.exit_code != 0
    assert "Traceback" not in res.output


def test_readme_generated_docs_are_current():
    """docs/config.md and docs/schema.md are generated from the code: never stale."""
    out = subprocess.run([sys.executable, str(REPO / "scripts" / "sync_docs.py"), "--check"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_readme_and_docs_relative_links_exist():
    """Every relative link in README.md and docs/*.md points to a file (or directory) that exists."""
    import re
    from pathlib import Path

    repo = Path(__file__).resolve().parents[2]
    pages = [repo / "README.md", *sorted((repo / "docs").glob("*.md"))]
    assert len(pages) > 1, "docs/ has no pages"
    link = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
    broken = []
    for page in pages:
        text = page.read_text(encoding="utf-8")
        text = re.sub(r"^(```|~~~).*?^\1", "", text, flags=re.S | re.M)  # fenced code blocks
        text = re.sub(r"`[^`\n]*`", "", text)  # inline code
        for target in link.findall(text):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith("#"):
                continue  # URLs, mailto:, anchors within the page
            path = target.split("#", 1)[0].split("?", 1)[0]
            if not (page.parent / path).exists():
                broken.append(f"{page.relative_to(repo)}: {target}")
    assert not broken, "broken relative links:\n" + "\n".join(broken)
