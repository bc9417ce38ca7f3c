"""The command group itself: help, version, cold start, the error policy."""

from __future__ import annotations

import subprocess
import sys
import time

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


def test_unknown_command_fails_cleanly(cli_run):
    res = cli_run("frobnicate")
    assert res.exit_code != 0
    assert "Traceback" not in res.output


def test_readme_generated_sections_are_current():
    """The README's config table and HDF5 schema are generated from the code: never stale."""
    out = subprocess.run([sys.executable, str(REPO / "scripts" / "sync_readme.py"), "--check"],
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
