"""``bench/bench_scan_timing.py`` on exp1: its scans keep their own clock (the ratio follows
mean / interval at the stamps), and on the fitted clock's ticks they do not any more."""

from __future__ import annotations

import re

import pytest

from bench.bench_scan_timing import EXP1, main


@pytest.mark.skipif(not EXP1.exists(), reason="dataset not present")
def test_exp1s_scans_follow_their_clock_not_their_stamps(capsys):
    assert main([]) == 0
    out = capsys.readouterr().out
    stamps = float(re.search(r"slope of the ratio over the interval: (-?[\d.]+)", out).group(1))
    ticks = float(re.search(r"slope over the stamp interval: (-?[\d.]+)", out).group(1))
    assert stamps < -0.7 and abs(ticks) < 0.3, out
    assert "keep their own clock" in out and "4 scan(s) repeat" in out
