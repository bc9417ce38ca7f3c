"""When an ``ivslam`` process runs the cyclic garbage collector.

A run's start allocates ~180,000 container objects that live as long as the process: the
modules (ivslam's, click, NumPy, h5py, the log reader's, numba's), numba's typing and target
context, the kernels it loads. None of them is garbage, yet each young collection scans those
allocated since the last one, and each older one all of them again. Two settings:

- :func:`collect_less_often` (every command, from the entry point): a young collection every
  :data:`YOUNG_THRESHOLD` allocations instead of CPython's 700.
- :func:`pause` at the start of ``ivslam run`` and :func:`resume` when its pipeline starts on
  the data (:func:`ivslam_cli.slam.run_pipeline`), in a process started by the entry point
  (one that called :func:`collect_less_often`; an in-process call of the command, from tests
  or a library, leaves its host's collector alone): in between (imports, reading the log) a
  young collection only every :data:`START_THRESHOLD` allocations, more than a run allocates
  before its pipeline, so none happens. :func:`resume` then moves every object allocated so far
  to the permanent generation (``gc.freeze``: never scanned again) and restores the threshold,
  so the collections of the pipeline (numba loading its kernels, the data work) scan only what
  the pipeline allocates. A cycle that became garbage before the pipeline is not freed (objects
  of imports and of the log read that refer to each other and are no longer used: few); one
  made later is, as usual. Without :func:`resume` (the parent of a batch, whose workers run
  the pipelines; a batch of logs that all fail to read) the collector still runs, every
  :data:`START_THRESHOLD` allocations.
"""

from __future__ import annotations

import gc

#: net allocations of container objects between two young collections (CPython's default: 700)
YOUNG_THRESHOLD = 10_000

#: the same while ``ivslam run`` starts: ~95,000 are allocated before its pipeline starts
START_THRESHOLD = 250_000

_own_process = False  # the entry point tuned the collector: this process is an ivslam command's
_saved: tuple[int, int, int] | None = None  # the thresholds :func:`pause` replaced


def collect_less_often() -> None:
    """A young collection every :data:`YOUNG_THRESHOLD` allocations (older ones as before).

    At CPython's default the collector runs some 250 times while a run's start allocates, twice
    over all of it, for 60-80 ms of a 0.5 s ``ivslam run`` on a 5-step log (~30 ms at this
    threshold). A reference cycle waits longer to be freed: at most this many allocations.
    """
    global _own_process
    _, older, oldest = gc.get_threshold()
    gc.set_threshold(YOUNG_THRESHOLD, older, oldest)
    _own_process = True


def pause() -> None:
    """No young collection before :data:`START_THRESHOLD` allocations, until :func:`resume`;
    only in a process whose collector :func:`collect_less_often` tuned."""
    global _saved
    if not _own_process:
        return
    if _saved is None:
        _saved = gc.get_threshold()
    gc.set_threshold(START_THRESHOLD, _saved[1], _saved[2])


def resume() -> None:
    """End :func:`pause`: freeze what is allocated so far, restore the thresholds. Does nothing
    unless paused (a pipeline called from a library or a batch worker, or a second log)."""
    global _saved
    if _saved is None:
        return
    gc.freeze()
    gc.set_threshold(*_saved)
    _saved = None
