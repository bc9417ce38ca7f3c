"""The garbage collector's policy: paused while ``ivslam run`` starts, frozen and restored when
its pipeline does, and left alone in a process that is not an ivslam command's."""

from __future__ import annotations

import gc

import pytest

from ivslam_cli import collector


@pytest.fixture
def thresholds():
    """Restore this process's collector (thresholds, frozen objects, the module's state)."""
    before = gc.get_threshold()
    yield before
    gc.set_threshold(*before)
    gc.unfreeze()
    collector._saved = None


def test_pause_and_resume_in_an_ivslam_process(thresholds, monkeypatch):
    monkeypatch.setattr(collector, "_own_process", True)
    collector.pause()
    assert gc.get_threshold() == (collector.START_THRESHOLD, *thresholds[1:])
    collector.pause()  # twice: still restores the thresholds from before the first
    frozen = gc.get_freeze_count()
    collector.resume()
    assert gc.get_threshold() == thresholds
    assert gc.get_freeze_count() > frozen
    collector.resume()  # not paused: nothing more
    assert gc.get_threshold() == thresholds


def test_elsewhere_the_collector_is_left_alone(thresholds, monkeypatch):
    """Tests and libraries that call the command in their own process keep their collector."""
    monkeypatch.setattr(collector, "_own_process", False)
    frozen = gc.get_freeze_count()
    collector.pause()
    assert gc.get_threshold() == thresholds
    collector.resume()
    assert gc.get_threshold() == thresholds
    assert gc.get_freeze_count() == frozen


def test_an_in_process_run_leaves_the_collector_alone(thresholds, cli_run, tmp_path):
    assert cli_run("simulate", "--scenario", "pairs", "--steps", "5", "-o", tmp_path / "p.mcap").exit_code == 0
    frozen = gc.get_freeze_count()
    assert cli_run("run", tmp_path / "p.mcap", "-o", tmp_path / "r.h5", "-q").exit_code == 0
    assert gc.get_threshold() == thresholds
    assert gc.get_freeze_count() == frozen
