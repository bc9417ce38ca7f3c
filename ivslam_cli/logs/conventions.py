"""Real-world conventions every reader applies the same way, and reports.

* no-return beams (``inf``, NaN, 0, below ``range_min``, above ``range_max``, error
  codes) stay in ``ranges`` but are marked invalid in ``Scans.valid``;
* the duplicated last beam of a 360° scanner (first and last beam at the same angle,
  e.g. the Neato's 361 beams from -pi to +pi: ``(n - 1) * increment`` is 2π) is dropped;
* out-of-order stamps are sorted (stable), and counted;
* odometry / observation rows with NaN or inf are dropped, and counted;
* odometry rows that repeat the stamp of the row before them (after sorting) are dropped,
  the first kept, and counted: a motion step needs a positive duration.

Everything removed or marked is recorded as a :class:`Dropped` line.
"""

from __future__ import annotations

import math

import numpy as np

from ivslam_cli import limits
from ivslam_cli.logs.model import Dropped, Odometry, Observations, Scans


class ScanSink:
    """Accumulates decoded scans into flat preallocated arrays.

    ``capacity`` (messages) is a hint; ranges are allocated at ``capacity * beams``
    of the first block and grown geometrically when needed, so the peak memory is the
    final arrays plus one block (plus one growth copy when the hint was too small).
    Scans, beams and beams per scan are checked against ``limits.SCANS``, ``BEAMS`` and
    ``BEAMS_PER_SCAN`` before anything is allocated for them (a declared count is only a
    hint: it is capped by the limits).
    """

    def __init__(self, capacity: int = 1024):
        self.cap = min(max(int(capacity), 1), limits.get("SCANS"))
        self.n = 0
        self.nb = 0
        self.cols = {k: np.empty(self.cap, np.float64) for k in
                     ("stamp", "angle_min", "angle_increment", "range_min", "range_max", "time_increment")}
        self.order = np.empty(self.cap, np.int64)
        self.counts = np.empty(self.cap, np.int64)
        self.ranges: np.ndarray | None = None
        self.valid: np.ndarray | None = None
        self.frame_id = ""
        self.dup_beams = 0
        self.invalid = {"non-finite": 0, "zero": 0, "below range_min": 0,
                        "above range_max": 0}

    def _grow_rows(self, need: int) -> None:
        if need <= self.cap:
            return
        limits.check("SCANS", need, "scans in the log")
        cap = min(max(need, 2 * self.cap), limits.get("SCANS"))
        for k, a in self.cols.items():
            self.cols[k] = np.resize(a, cap)
        self.order = np.resize(self.order, cap)
        self.counts = np.resize(self.counts, cap)
        self.cap = cap

    def _grow_beams(self, need: int, per_scan: int) -> None:
        limits.check("BEAMS", need, "beams in the log")
        cap = limits.get("BEAMS")
        if self.ranges is None:
            size = max(need, min(self.cap * per_scan, cap))
            self.ranges = np.empty(size, np.float32)
            self.valid = np.empty(size, bool)
        elif need > self.ranges.shape[0]:
            size = max(need, min(2 * self.ranges.shape[0], cap))
            new = np.empty(size, np.float32)
            new[: self.nb] = self.ranges[: self.nb]
            self.ranges = new
            newv = np.empty(size, bool)
            newv[: self.nb] = self.valid[: self.nb]
            self.valid = newv

    def add(self, order, stamp, angle_min, angle_increment, range_min, range_max,
            ranges: np.ndarray, frame_id: str = "", angle_max=None,
            error_codes_below: float = 0.0, time_increment=None) -> None:
        """Append ``k`` scans of ``n`` beams each (``ranges`` is ``(k, n)``).

        ``order`` gives each scan's position in the file (to restore file order);
        ``angle_max`` (if given) lets a duplicated last beam be detected; values
        ``<= error_codes_below`` are error codes (invalid), besides the usual rules;
        ``time_increment`` the seconds between two beams, if the log says.
        """
        if time_increment is None:
            time_increment = np.full(ranges.shape[0], np.nan)
        k, n = ranges.shape
        if k == 0:
            return
        limits.check("BEAMS_PER_SCAN", n, "beams in one scan")
        if angle_max is not None and n > 1:
            inc = np.abs(np.asarray(angle_increment, np.float64))
            dup = np.abs((n - 1) * inc - 2 * math.pi) < 0.5 * inc
            if dup.all():
                ranges = ranges[:, : n - 1]
                self.dup_beams += k
                n -= 1
            elif dup.any():  # mixed block: split it
                for mask in (dup, ~dup):
                    self.add(np.asarray(order)[mask], *(np.asarray(a)[mask] for a in (
                        stamp, angle_min, angle_increment, range_min, range_max)),
                        ranges[mask], frame_id, np.asarray(angle_max)[mask], error_codes_below,
                        np.asarray(time_increment)[mask])
                return
        if frame_id and not self.frame_id:
            self.frame_id = frame_id
        self._grow_rows(self.n + k)
        self._grow_beams(self.nb + k * n, n)
        sl = slice(self.n, self.n + k)
        for key, val in (("stamp", stamp), ("angle_min", angle_min),
                         ("angle_increment", angle_increment), ("range_min", range_min),
                         ("range_max", range_max), ("time_increment", time_increment)):
            self.cols[key][sl] = val
        self.order[sl] = order
        self.counts[sl] = n
        out = self.ranges[self.nb: self.nb + k * n].reshape(k, n)
        out[...] = ranges
        v = self.valid[self.nb: self.nb + k * n].reshape(k, n)
        rmin = np.asarray(range_min, np.float64).reshape(-1, 1)
        rmax = np.asarray(range_max, np.float64).reshape(-1, 1)
        finite = np.isfinite(out)
        zero = out <= error_codes_below
        below = finite & ~zero & (out < rmin)
        above = finite & (out > rmax)
        np.logical_and(finite, ~(zero | below | above), out=v)
        self.invalid["non-finite"] += int(k * n - np.count_nonzero(finite))
        self.invalid["zero"] += int(np.count_nonzero(finite & zero))
        self.invalid["below range_min"] += int(np.count_nonzero(below))
        self.invalid["above range_max"] += int(np.count_nonzero(above))
        self.n += k
        self.nb += k * n

    def finish(self, dropped: list[Dropped], zero_reason: str = "zero (no return)",
               mount=(0.0, 0.0, 0.0), frame_id: str | None = None) -> Scans | None:
        """The sorted :class:`Scans` (None if empty); appends what was dropped."""
        if self.n == 0:
            return None
        n = self.n
        cols = {k: a[:n] for k, a in self.cols.items()}
        counts = self.counts[:n]
        offsets = np.zeros(n + 1, np.int64)
        np.cumsum(counts, out=offsets[1:])
        ranges, valid = self.ranges[: self.nb], self.valid[: self.nb]
        # file order first (blocks may come grouped by layout), then time order
        perm = np.argsort(self.order[:n], kind="stable")
        if not np.array_equal(perm, np.arange(n)):
            cols = {k: a[perm] for k, a in cols.items()}
            ranges, valid, offsets = _regather(ranges, valid, offsets, perm)
        late = count_out_of_order(cols["stamp"])
        if late:
            dropped.append(Dropped("scans", late, "out-of-order stamps (sorted, kept)"))
            perm = np.argsort(cols["stamp"], kind="stable")
            cols = {k: a[perm] for k, a in cols.items()}
            ranges, valid, offsets = _regather(ranges, valid, offsets, perm)
        if self.dup_beams:
            dropped.append(Dropped("scans", self.dup_beams,
                                   "duplicated last beam of a 360° scan (beam dropped)"))
        reasons = {"non-finite": "beams inf/NaN (no return, marked invalid)",
                   "zero": zero_reason,
                   "below range_min": "beams below range_min (marked invalid)",
                   "above range_max": "beams above range_max (marked invalid)"}
        for key, count in self.invalid.items():
            if count:
                dropped.append(Dropped("scans", count, reasons[key]))
        ti = cols["time_increment"]
        return Scans(stamp=cols["stamp"], angle_min=cols["angle_min"],
                     angle_increment=cols["angle_increment"], range_min=cols["range_min"],
                     range_max=cols["range_max"], offsets=offsets, ranges=ranges,
                     valid=valid, mount=tuple(float(x) for x in mount),
                     frame_id=self.frame_id if frame_id is None else frame_id,
                     time_increment=ti.copy() if np.isfinite(ti).any() else None)


def _regather(ranges, valid, offsets, perm):
    counts = np.diff(offsets)[perm]
    starts = offsets[:-1][perm]
    new_off = np.zeros(len(perm) + 1, np.int64)
    np.cumsum(counts, out=new_off[1:])
    idx = np.repeat(starts - new_off[:-1], counts) + np.arange(new_off[-1])
    return ranges[idx], valid[idx], new_off


def count_out_of_order(stamp: np.ndarray) -> int:
    """Number of stamps earlier than some stamp before them in the file."""
    if stamp.size < 2:
        return 0
    return int(np.count_nonzero(stamp[1:] < np.maximum.accumulate(stamp)[:-1]))


def finite_rows(stream: str, stamp: np.ndarray, *cols: np.ndarray | None,
                dropped: list[Dropped]) -> np.ndarray:
    """Mask of rows whose stamp and every column are finite; counts the others."""
    ok = np.isfinite(stamp)
    for c in cols:
        if c is not None:
            ok &= np.isfinite(c.reshape(len(stamp), -1)).all(axis=1)
    bad = int(ok.size - np.count_nonzero(ok))
    if bad:
        dropped.append(Dropped(stream, bad, "rows with NaN/inf (dropped)"))
    return ok


def make_odometry(stamp, pose=None, twist=None, *, dropped: list[Dropped],
                  stream: str = "odometry") -> Odometry | None:
    """A clean, time-sorted :class:`Odometry` (None if no row survives)."""
    stamp = np.asarray(stamp, np.float64)
    if stamp.size == 0:
        return None
    pose = None if pose is None else np.asarray(pose, np.float64).reshape(-1, 3)
    twist = None if twist is None else np.asarray(twist, np.float64).reshape(-1, 2)
    ok = finite_rows(stream, stamp, pose, twist, dropped=dropped)
    stamp = stamp[ok]
    pose = None if pose is None else pose[ok]
    twist = None if twist is None else twist[ok]
    late = count_out_of_order(stamp)
    if late:
        dropped.append(Dropped(stream, late, "out-of-order stamps (sorted, kept)"))
        perm = np.argsort(stamp, kind="stable")
        stamp = stamp[perm]
        pose = None if pose is None else pose[perm]
        twist = None if twist is None else twist[perm]
    if stamp.size == 0:
        return None
    tied = np.concatenate([[False], stamp[1:] == stamp[:-1]])
    if tied.any():
        dropped.append(Dropped(stream, int(tied.sum()), "rows repeating the previous row's stamp "
                               "(dropped, the first kept)"))
        stamp = stamp[~tied]
        pose = None if pose is None else pose[~tied]
        twist = None if twist is None else twist[~tied]
    return Odometry(stamp=stamp, pose=pose, twist=twist)


def make_observations(stamp, landmark_id, rng, bearing, *, dropped: list[Dropped],
                      stream: str = "observations") -> Observations | None:
    """Clean, time-sorted :class:`Observations` (None if empty)."""
    stamp = np.asarray(stamp, np.float64)
    if stamp.size == 0:
        return None
    lid = np.asarray(landmark_id, np.int64)
    rng = np.asarray(rng, np.float64)
    bearing = np.asarray(bearing, np.float64)
    ok = finite_rows(stream, stamp, rng, bearing, dropped=dropped)
    stamp, lid, rng, bearing = stamp[ok], lid[ok], rng[ok], bearing[ok]
    late = count_out_of_order(stamp)
    if late:
        dropped.append(Dropped(stream, late, "out-of-order stamps (sorted, kept)"))
        perm = np.argsort(stamp, kind="stable")
        stamp, lid, rng, bearing = stamp[perm], lid[perm], rng[perm], bearing[perm]
    if stamp.size == 0:
        return None
    return Observations(stamp=stamp, landmark_id=lid, range=rng, bearing=bearing)
