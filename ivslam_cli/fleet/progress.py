"""Progress of one long run on stderr: click's progress bar, shown only once the run has taken
more than :data:`DELAY` seconds (short runs print nothing but their summary line)."""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterator

import click

DELAY = 2.0  # seconds before a run shows its bar
STEPS = 1000


class _RunBar:
    """A callback ``progress(fraction, label=None)`` drawing a click progress bar, lazily."""

    def __init__(self, delay: float):
        self.t0 = time.monotonic()
        self.delay = delay
        self.bar = None
        self.pos = 0
        self.label = "run"

    def __call__(self, fraction: float, label: str | None = None) -> None:
        target = round(min(1.0, max(0.0, float(fraction))) * STEPS)
        if label:
            self.label = label
        if self.bar is None:
            if time.monotonic() - self.t0 < self.delay:
                self.pos = max(self.pos, target)
                return
            self.bar = click.progressbar(length=STEPS, label="run", file=sys.stderr, show_eta=False,
                                         show_percent=True, item_show_func=lambda item: item)
            self.bar.__enter__()
            self.bar.update(self.pos, self.label)
        if target > self.pos:
            self.bar.update(target - self.pos, self.label)
            self.pos = target
        elif label:
            self.bar.update(0, self.label)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)


@contextlib.contextmanager
def run_progress(*, enabled: bool, delay: float = DELAY) -> Iterator[_RunBar | None]:
    """A progress callback for :func:`ivslam_cli.fleet.job.run_one` (None when not ``enabled``)."""
    if not enabled:
        yield None
        return
    bar = _RunBar(delay)
    try:
        yield bar
    finally:
        bar.close()
