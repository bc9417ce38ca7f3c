"""Stamps that cannot order a text log: detected, said, and replaced by the file order.

CARMEN-style logs in the wild print stamps with too few digits (``%g``: six significant
digits, so a log of unix times shares three or four distinct stamps) or mix clocks (GMapping's
``.gfs.log`` interleaves records stamped 0 with the others). Sorting by such stamps scrambles
the records. A log's stamps are **unusable** when, in file order,

- more than :data:`TIED` of the records of one stream repeat the stamp of the previous
  record of that stream (a stamp resolution coarser than the record rate), or
- more than :data:`BACK` of all records go back in time (below the largest stamp before them),

and at least :data:`MIN_COUNT` records do (a few records out of order are sorted, counted, as
in every other reader).

The records are then kept in file order, which is the order they were logged in, and given
strictly increasing stamps: the longest run of records whose stamps do not decrease in file
order keeps its stamps (the first of tied ones; the others are the records out of order),
and every other record gets a stamp interpolated linearly by its position in the file
between the kept ones around it. What was found and done is one note of the log (``inspect``
prints it; results keep it in their provenance).
"""

from __future__ import annotations

import bisect

import numpy as np

TIED = 0.05
BACK = 0.01
MIN_COUNT = 10  # and at least this many such records (a few are sorted, as in other logs)


def assess(stamp: np.ndarray, stream: np.ndarray) -> tuple[int, int, str | None]:
    """``(tied, back, worst stream)``: records repeating their stream's previous stamp (in the
    stream with the largest fraction of them), records going back in time."""
    stamp = np.asarray(stamp, np.float64)
    if stamp.size < 2:
        return 0, 0, None
    back = int(np.count_nonzero(stamp[1:] < np.maximum.accumulate(stamp)[:-1]))
    tied, worst, worst_frac = 0, None, -1.0
    for s in np.unique(stream):
        t = stamp[stream == s]
        if t.size < 2:
            continue
        n = int(np.count_nonzero(t[1:] == t[:-1]))
        if n / t.size > worst_frac:
            tied, worst, worst_frac = n, str(s), n / t.size
    return tied, back, worst


def unusable(stamp: np.ndarray, stream: np.ndarray) -> str | None:
    """Why the stamps cannot order the log (None if they can)."""
    stamp = np.asarray(stamp, np.float64)
    n = stamp.size
    if n < 3:
        return None
    tied, back, worst = assess(stamp, stream)
    n_worst = int(np.count_nonzero(stream == worst)) if worst is not None else 0
    if not ((tied > TIED * max(n_worst, 1) and tied >= MIN_COUNT) or (back > BACK * n and back >= MIN_COUNT)):
        return None
    return (f"{tied} of {n_worst} {worst} records repeat the previous stamp, {back} of {n} "
            "records go back in time: stamps printed with too few digits, or mixed clocks")


def _longest_nondecreasing(stamp: np.ndarray) -> np.ndarray:
    """Indices of a longest non-decreasing subsequence (patience sorting, O(n log n))."""
    tails: list[float] = []  # smallest tail value of a run of each length
    tail_idx: list[int] = []
    prev = np.full(stamp.size, -1, np.int64)
    for i, v in enumerate(stamp.tolist()):
        k = bisect.bisect_right(tails, v)
        if k == len(tails):
            tails.append(v)
            tail_idx.append(i)
        else:
            tails[k] = v
            tail_idx[k] = i
        prev[i] = tail_idx[k - 1] if k > 0 else -1
    out = []
    i = tail_idx[-1] if tail_idx else -1
    while i >= 0:
        out.append(i)
        i = prev[i]
    return np.asarray(out[::-1], np.int64)


def file_order_stamps(stamp: np.ndarray, stream: np.ndarray | None = None) -> np.ndarray:
    """Stamps for records in file order, strictly increasing within each stream (records of
    different streams logged together, e.g. a scan and the odometry at it, may keep one stamp):
    see the module docstring."""
    stamp = np.asarray(stamp, np.float64)
    n = stamp.size
    stream = np.zeros(n, np.int64) if stream is None else np.asarray(stream)
    keep = np.zeros(n, bool)
    idx = np.flatnonzero(np.isfinite(stamp))
    if idx.size:
        keep[idx[_longest_nondecreasing(stamp[idx])]] = True
    last: dict = {}
    for i in np.flatnonzero(keep):  # of a stream's tied kept stamps only the first is an anchor
        s = stream[i].item()
        if last.get(s) == stamp[i]:
            keep[i] = False
        else:
            last[s] = stamp[i]
    kept = np.flatnonzero(keep)
    pos = np.arange(n, dtype=np.float64)
    if kept.size == 0:
        return pos  # no stamp at all: the record index, in seconds
    per = 1.0
    if kept.size > 1:
        steps = np.diff(stamp[kept]) / np.diff(kept)
        per = float(np.median(steps[steps > 0])) if np.any(steps > 0) else 1.0
    out = np.interp(pos, kept.astype(np.float64), stamp[kept])
    out[: kept[0]] = stamp[kept[0]] - per * (kept[0] - pos[: kept[0]])
    out[kept[-1] + 1:] = stamp[kept[-1]] + per * (pos[kept[-1] + 1:] - kept[-1])
    for s in np.unique(stream):  # interpolation between close anchors may tie: nudge upward
        rows = np.flatnonzero(stream == s)
        v = out[rows]
        if np.all(np.diff(v) > 0):
            continue
        for k in range(1, v.size):
            if v[k] <= v[k - 1]:
                v[k] = np.nextafter(v[k - 1], np.inf)
        out[rows] = v
    return out
