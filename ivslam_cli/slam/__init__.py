"""The pipelines and their registry: ``--mode`` → pipeline (:mod:`.pairs`, :mod:`.landmarks`,
:mod:`.lidar`); each has the surface described in :mod:`.pipeline`.

``run_pipeline(log, cfg, mode)`` builds the pipeline's parameters from the resolved
configuration, runs it and completes the result's provenance (configuration, command line).
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Sequence
from types import ModuleType
from typing import TYPE_CHECKING

from ivslam_cli import collector
from ivslam_cli.errors import IvslamError

if TYPE_CHECKING:  # the registry stays light: ``ivslam run --help`` imports it
    from ivslam_cli.config import Config
    from ivslam_cli.logs.model import LogData
    from ivslam_cli.results.model import Result

#: mode → module of the pipeline (imported on first use: a mode loads only its own kernels)
PIPELINES: dict[str, str] = {
    "pairs": "ivslam_cli.slam.pairs",
    "landmarks": "ivslam_cli.slam.landmarks",
    "lidar": "ivslam_cli.slam.lidar",
}
MODES: tuple[str, ...] = tuple(PIPELINES)


def get_pipeline(mode: str) -> ModuleType:
    """The pipeline module of ``mode`` (``Params``, ``run``, ``summary``)."""
    if mode not in PIPELINES:
        raise IvslamError(f"unknown --mode {mode} (available: {', '.join(MODES)})")
    return importlib.import_module(PIPELINES[mode])


def run_pipeline(log: LogData, cfg: Config, mode: str, argv: Sequence[str] | None = None,
                 progress=None) -> Result:
    """Run ``mode`` over ``log`` with the resolved configuration ``cfg``.

    With ``robust.strict`` the run stops at the first empty intersection: the result covers the
    data up to that measurement and ``consistency.stopped`` says where (the CLI then exits 3).
    """
    from ivslam_cli.interval.rounding import ensure_round_to_nearest
    from ivslam_cli.results.provenance import command_line

    ensure_round_to_nearest()
    pipe = get_pipeline(mode)
    if log.robots and not getattr(pipe, "MULTI_ROBOT", False):
        raise IvslamError(f"a log of several robots (--robot all) needs --mode landmarks (not {mode})",
                          log.provenance.path)
    params = pipe.Params.from_config(cfg)
    collector.resume()  # the start of a run is over: what it allocated is never scanned again
    t0 = time.perf_counter()
    try:
        result = pipe.run(log, params, progress)
    except IvslamError as exc:  # a limit or a contradiction met in the data: name the log
        raise exc.about(log.provenance.path) from exc
    result.provenance.config = cfg.as_dict()
    result.provenance.command = command_line(argv)
    ev = result.consistency.empty_events
    if params.strict and len(ev) and not result.consistency.stopped:
        result.consistency.stopped = f"first empty intersection at t={ev.stamp[0]:.3f} s: {ev.text[0]}"
    result.runtime_s = time.perf_counter() - t0
    result.validate()
    return result


def summary(result: Result) -> str:
    """The one-line summary of ``result`` by its pipeline."""
    return get_pipeline(result.mode).summary(result)


__all__ = ["MODES", "PIPELINES", "get_pipeline", "run_pipeline", "summary"]
