"""When each scan was taken: at its stamp, or on the sensor's own regular clock fitted to the
stamps (``lidar.scan_clock``).

A spinning 2D LiDAR (the URG-04LX turns at 600 rpm) takes a scan every turn on its own clock. A
logger that stamps each scan when it reads it (with the wheel ticks read at the same moment)
adds the read's latency: the stamps jitter around the sensor's ticks while the odometry follows
them. The fitted clock ``g_k = φ + n_k T`` puts each scan back on a tick: the period ``T``
maximises the concentration of the stamps' phases (a Rayleigh periodogram), each scan takes the
nearest tick, a scan whose ranges repeat the previous one's (the same scan read twice) takes the
previous one's, and ``(φ, T)`` are the least-squares fit of the stamps on their ticks. What the
sensor's clock does between ticks is stated, not fitted: ``bounds.scan_time`` bounds how far
each beam may be from its nominal time (``lidar.sweep`` from the stamp or the tick).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ivslam_cli.errors import IvslamError
from ivslam_cli.logs.model import Scans

CLOCKS = ("stamps", "fitted")


@dataclass(frozen=True)
class ScanClock:
    """Each scan's time from its stamp (``offset`` (S,), s: taken at ``stamp + offset``)."""

    offset: np.ndarray
    period: float = 0.0  # the fitted clock's period (0: the stamps)
    repeats: int = 0  # scans that repeat the previous one's ranges
    spread: tuple[float, float] = (0.0, 0.0)  # the stamps off their ticks: least, largest (s)
    concentration: float = 1.0  # |mean exp(2πi t / T)| of the distinct stamps (1: on the ticks, ~0: no clock)

    def text(self) -> str:
        if self.period == 0.0:
            return ""
        lo, hi = self.spread
        return (f"each scan re-timed on the sensor's regular clock fitted to the stamps (period {self.period:.6g} s; "
                f"the stamps off it by {lo:+.3f} to {hi:+.3f} s"
                + (f"; {self.repeats} scan(s) repeat the previous one's ranges: the same scan read again, at its time"
                   if self.repeats else "") + ")")


def repeated_scans(scans: Scans) -> np.ndarray:
    """``(S,)`` bool: scan ``k`` has the same ranges as scan ``k − 1``."""
    n = np.diff(scans.offsets)
    rep = np.zeros(len(scans), bool)
    r = np.asarray(scans.ranges)
    for k in np.flatnonzero((n[1:] == n[:-1]) & (n[1:] > 0)) + 1:
        a, b, c = int(scans.offsets[k - 1]), int(scans.offsets[k]), int(scans.offsets[k + 1])
        rep[k] = np.array_equal(r[a:b], r[b:c], equal_nan=True)
    return rep


def _phase_concentration(s: np.ndarray, periods: np.ndarray) -> np.ndarray:
    """``|mean exp(2πi s / T)|`` for each period (stamps relative to the first)."""
    out = np.empty(periods.shape[0])
    for j in range(0, periods.shape[0], 256):
        ph = np.exp(2j * np.pi * s[None, :] / periods[j:j + 256, None])
        out[j:j + 256] = np.abs(ph.mean(axis=1))
    return out


def _period(tn: np.ndarray, T0: float) -> float:
    """The period near ``T0`` that concentrates the phases of ``tn`` most. The periodogram's
    peak is about ``T²/span`` wide: over the first 64 stamps, steps of a tenth of that within
    ±10 % of ``T0``; then, the stamps doubled each time, within three of the last peak widths."""
    m = min(64, tn.shape[0])
    T, lo, hi = T0, 0.9 * T0, 1.1 * T0
    while True:
        span = max(float(tn[m - 1] - tn[0]), T)
        step = max(0.1 * T * T / span, 1e-12 * T, (hi - lo) / 4096.0)
        periods = np.arange(lo, hi + step, step)
        T = float(periods[np.argmax(_phase_concentration(tn[:m], periods))])
        if m == tn.shape[0]:
            return T
        width = T * T / span
        lo, hi = T - 3.0 * width, T + 3.0 * width
        m = min(2 * m, tn.shape[0])


def fit_clock(stamps: np.ndarray, repeat: np.ndarray, path: str = "") -> ScanClock:
    """The regular clock through ``stamps`` (see the module docstring), ``repeat`` marking scans
    that repeat the previous one. Raises :class:`IvslamError` when the stamps do not follow one
    (two distinct scans on one tick, fewer than 3 distinct scans, or stamps so far apart that
    the fit overflows)."""
    try:
        with np.errstate(over="raise", invalid="raise"):
            return _fit(stamps, repeat, path)
    except (FloatingPointError, ValueError, MemoryError, OverflowError):
        raise IvslamError("lidar.scan_clock = 'fitted': no regular clock can be fitted to the scan stamps "
                          "(they span too much for their intervals)", path) from None


def _fit(stamps: np.ndarray, repeat: np.ndarray, path: str) -> ScanClock:
    s = np.asarray(stamps, float)
    if not np.all(np.isfinite(s)) or (s.size and not np.isfinite(s[-1] - s[0])):
        raise IvslamError("lidar.scan_clock = 'fitted': the scan stamps are not finite numbers", path)
    rep = np.asarray(repeat, bool).copy()
    if rep.size:
        rep[0] = False
    new = ~rep
    if new.sum() < 3:
        raise IvslamError("lidar.scan_clock = 'fitted' needs at least 3 distinct scans", path)
    t = s - s[0]
    tn = t[new]
    dt = np.diff(tn)
    T0 = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 0.0
    if not (T0 > 0.0 and np.isfinite(T0)):
        raise IvslamError("lidar.scan_clock = 'fitted': the scan stamps do not advance", path)
    T = _period(tn, T0)
    phi = float(np.angle(np.mean(np.exp(2j * np.pi * tn / T)))) * T / (2 * np.pi)
    tick = np.empty(s.shape[0], np.int64)
    tick[new] = np.round((tn - phi) / T).astype(np.int64)
    for _ in range(3):
        A = np.column_stack([np.ones(tn.shape[0]), tick[new].astype(float)])
        (phi, T), *_ = np.linalg.lstsq(A, tn, rcond=None)
        tick[new] = np.round((tn - phi) / T).astype(np.int64)
    if np.any(np.diff(tick[new]) <= 0):
        raise IvslamError("lidar.scan_clock = 'fitted': the scan stamps do not follow a regular clock "
                          "(two distinct scans fall on one tick)", path)
    idx = np.maximum.accumulate(np.where(new, np.arange(s.shape[0]), 0))
    tick = tick[idx]
    g = phi + tick * T
    off = g - t
    res = -off[new]
    return ScanClock(offset=off, period=float(T), repeats=int(rep.sum()),
                     spread=(float(res.min()), float(res.max())),
                     concentration=float(_phase_concentration(tn, np.array([T]))[0]))


def scan_clock(scans: Scans, which: str, path: str = "") -> ScanClock:
    """The clock ``which`` (one of :data:`CLOCKS`) of ``scans``."""
    if which == "stamps" or len(scans) == 0:
        return ScanClock(offset=np.zeros(len(scans)))
    if which != "fitted":
        raise ValueError(which)
    return fit_clock(np.asarray(scans.stamp, float), repeated_scans(scans), path)
