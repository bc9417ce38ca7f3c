"""Shared fixtures: where the real datasets live, and a CLI runner."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DATASETS = Path(os.environ.get("IVSLAM_DATASETS", REPO.parent / "shared" / "datasets")).resolve()
SAMPLE_LOGS = REPO / "sample_logs"


@pytest.fixture(scope="session")
def datasets() -> Path:
    """``../shared/datasets``; tests that need it are skipped (loudly) when it is absent."""
    if not DATASETS.is_dir():
        pytest.skip(f"datasets not found at {DATASETS}")
    return DATASETS


@pytest.fixture
def cli_run():
    """Run ``ivslam ARGS`` in-process; returns the click Result (exit_code, output)."""
    from click.testing import CliRunner

    from ivslam_cli.cli import cli

    def _run(*args: str):
        return CliRunner().invoke(cli, [str(a) for a in args], catch_exceptions=False)

    return _run
