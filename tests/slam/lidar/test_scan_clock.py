"""The sensor's regular clock fitted to jittered scan stamps (:mod:`ivslam_cli.slam.lidar.scan_clock`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ivslam_cli.errors import IvslamError
from ivslam_cli.slam.lidar.scan_clock import fit_clock, scan_clock
from tests.helpers.hyp import examples

EXP1 = Path(__file__).resolve().parents[3].parent / "shared" / "datasets" / "breezyslam_mines" / "exp1.dat.xz"


@given(st.integers(0, 2**31 - 1), st.floats(0.02, 0.2), st.floats(0.0, 0.3), st.floats(0.0, 0.05),
       st.floats(1e5, 2e9), st.integers(100, 800))
@settings(max_examples=examples(ci=100))
def test_the_fit_puts_each_scan_back_on_its_tick(seed, T, jitter, drop, t0, n):
    """Scans taken every ``T`` (a few ticks dropped), stamped up to ``jitter·T`` late or early,
    some read twice (the same ranges, a later stamp): every scan goes back to its own tick, up
    to the fit's error (a small fraction of the jitter), the repeats to their scan's tick."""
    rng = np.random.default_rng(seed)
    ticks = np.cumsum(1 + (rng.random(n) < drop))
    true = t0 + ticks * T
    stamps = true + rng.uniform(-jitter, jitter, n) * T
    rep = np.zeros(n, bool)
    rep[1:] = rng.random(n - 1) < 0.02
    for k in np.flatnonzero(rep):  # read again, later
        true[k] = true[k - 1]
        stamps[k] = stamps[k - 1] + rng.uniform(0.0, 0.3) * T
    c = fit_clock(stamps, rep)
    got = stamps + c.offset
    # the least-squares clock is off the true one by a constant (the mean latency) and a drift
    # over the span of about 2·jitter/√n (the slope's error; 4 of those here), where the stamps
    # spread over 2·jitter
    d = got - true
    assert np.ptp(d) <= 8.0 * jitter * T / np.sqrt(n) + 1e-9 * T + 8 * np.spacing(t0 + n * T), (np.ptp(d), jitter * T)
    assert abs(c.period - T) <= 0.01 * T
    assert c.repeats == int(rep[1:].sum())
    assert np.all(got[rep] == got[np.flatnonzero(rep) - 1])


def test_stamps_that_follow_no_clock_are_refused():
    stamps = np.cumsum(np.r_[0.0, np.tile([0.1, 0.01, 0.19], 20)])
    with pytest.raises(IvslamError, match="regular clock"):
        fit_clock(stamps, np.zeros(stamps.shape, bool))


def test_the_stamps_clock_moves_nothing():
    from ivslam_cli.simulate import SimConfig, simulate

    scans = simulate(SimConfig(scenario="lidar", world="rooms", seed=1, steps=10)).scans
    assert np.all(scan_clock(scans, "stamps").offset == 0.0)


@pytest.mark.skipif(not EXP1.exists(), reason="dataset not present")
def test_exp1s_scans_follow_a_regular_clock_their_stamps_do_not():
    """exp1 (URG-04LX at 600 rpm): a 98.7 ms clock; the stamps are tens of ms off it, and four
    scans repeat the previous one (a stalled read)."""
    from ivslam_cli.logs import read_log

    log = read_log(EXP1)
    c = scan_clock(log.scans, "fitted", str(EXP1))
    assert 0.0985 < c.period < 0.0989
    assert c.repeats == 4
    lo, hi = c.spread
    assert -0.06 < lo < -0.03 and 0.02 < hi < 0.06
    assert "regular clock" in c.text()


@pytest.mark.parametrize("stamps", [[-1e308, 0.1, 0.2, 0.3], [0.0, 0.1, np.inf, 0.3], [0.0, 1e308, 1.5e308, 1.7e308]])
def test_stamps_no_clock_can_be_fitted_to_are_a_clear_error(stamps):
    with pytest.raises(IvslamError, match="scan_clock"):
        fit_clock(np.array(stamps), np.zeros(len(stamps), bool))
