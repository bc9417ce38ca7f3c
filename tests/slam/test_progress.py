"""Progress inside a run: the LiDAR and landmark pipelines tell their listener how far they got
(scans, sweeps), and listening changes no result."""

from __future__ import annotations

import dataclasses
import io
import sys

import pytest

from ivslam_cli.config import resolve_config
from ivslam_cli.fleet.progress import _RunBar
from ivslam_cli.simulate import SimConfig, simulate
from ivslam_cli.slam import run_pipeline
from ivslam_cli.slam.progress import listening, tell
from tests.helpers.results import assert_same


class Heard:
    def __init__(self):
        self.calls: list[tuple[float, str | None]] = []

    def __call__(self, fraction, label=None):
        self.calls.append((float(fraction), label))


def test_tell_without_a_listener_does_nothing_and_listeners_nest():
    tell(1, 2)
    outer, inner = Heard(), Heard()
    with listening(outer, "sweep"):
        tell(1, 4)
        with listening(inner, "scan", share=(0.5, 1.0)):
            tell(1, 2)
        tell(2, 4)
    tell(3, 4)
    assert outer.calls == [(0.25, "sweep 1/4"), (0.5, "sweep 2/4")]
    assert inner.calls == [(0.75, "scan 1/2")]
    with listening(None, "sweep"):
        tell(1, 1)


RUNTIME = {"provenance", "runtime_s", "stats"}  # timings, the command line


def _same(a, b):
    for f in dataclasses.fields(a):
        if f.name not in RUNTIME:
            assert_same(getattr(a, f.name), getattr(b, f.name), f"result.{f.name}")


CASES = {
    "lidar": (dict(scenario="lidar", world="rooms", sensor="urg-04lx", seed=2, steps=30), {}, "scan"),
    "landmarks": (dict(scenario="landmarks", seed=3, steps=80, landmarks=12, world_size=10.0),
                  {"landmarks.initial_pose_from_truth": True}, "sweep"),
}


@pytest.mark.parametrize("mode", sorted(CASES))
def test_every_pipeline_reports_its_units_and_results_do_not_change(mode):
    sim, over, unit = CASES[mode]
    log = simulate(SimConfig(**sim))
    cfg = resolve_config(None, over, log_bounds=log.bounds)
    heard = Heard()
    with_bar = run_pipeline(log, cfg, mode, progress=heard)
    without = run_pipeline(log, cfg, mode)
    _same(with_bar, without)
    units = [c for c in heard.calls if c[1] and c[1].startswith(unit + " ")]
    assert units, heard.calls[:5]
    fractions = [f for f, _ in units]
    assert all(0.0 <= f <= 1.0 for f in fractions)
    assert fractions == sorted(fractions)
    if mode == "lidar":  # one call per scan used
        assert len(units) == len(with_bar.poses.stamp)


class Terminal(io.StringIO):
    def isatty(self):
        return True


def test_the_run_bar_draws_the_label_it_hears(monkeypatch):
    term = Terminal()
    monkeypatch.setattr(sys, "stderr", term)
    bar = _RunBar(delay=0.0)
    bar(0.2, "lidar: scan 3/15")
    bar(0.6, "lidar: scan 9/15")
    bar.close()
    assert "scan 9/15" in term.getvalue()
    assert "60%" in term.getvalue()
