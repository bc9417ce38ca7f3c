"""Shared fixtures (the real datasets, a CLI runner), the Hypothesis profile, marker checks.

Shared code lives in ``tests/helpers`` (tests never import each other or this file).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers.hyp import load_profile
from tests.helpers.paths import DATASETS


def pytest_configure(config):
    """Load the Hypothesis profile named by ``$IVSLAM_HYPOTHESIS`` (default ``ci``) unless
    ``--hypothesis-profile`` was given. Runs before any test module is imported, so counts
    computed at import (``examples``, ``seeds``) see the loaded profile."""
    if config.getoption("hypothesis_profile", None) is None:
        load_profile()


def pytest_report_header(config):
    from hypothesis import settings

    return f"hypothesis profile: {settings.get_current_profile_name()} (max_examples {settings.default.max_examples})"


def pytest_collection_modifyitems(config, items):
    """Tests under ``tests/hostile`` get the ``hostile`` marker. A test that uses the ``datasets`` fixture must be marked ``datasets`` (so that
    ``-m "not datasets"`` is exact): refuse to run otherwise."""
    hostile = Path(__file__).parent / "hostile"
    for item in items:  # the hostile-input corpus (processes under limits): make test, not test-fast
        if Path(str(item.fspath)).is_relative_to(hostile):
            item.add_marker(pytest.mark.hostile)
    unmarked = [i.nodeid for i in items if "datasets" in getattr(i, "fixturenames", ())
                and i.get_closest_marker("datasets") is None]
    if unmarked:
        raise pytest.UsageError("tests using the datasets fixture without @pytest.mark.datasets: "
                                + ", ".join(unmarked))


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
