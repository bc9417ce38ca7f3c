"""The three pipelines. ``run_pipeline`` turns a log and a resolved config into a Result."""

from __future__ import annotations

import time
from collections.abc import Sequence

from ivslam_cli.config import Config
from ivslam_cli.errors import InconsistentData, IvslamError
from ivslam_cli.logs.model import LogData
from ivslam_cli.results.model import Result
from ivslam_cli.results.provenance import make_provenance


def run_pipeline(log: LogData, cfg: Config, mode: str, argv: Sequence[str] | None = None) -> Result:
    """Run ``mode`` over ``log``. With ``robust.strict`` the result records where it stopped."""
    from ivslam_cli.interval.rounding import ensure_round_to_nearest

    ensure_round_to_nearest()
    t0 = time.perf_counter()
    if mode == "pairs":
        from ivslam_cli.slam.pairs import run_pairs

        out = run_pairs(log, cfg)
        result = Result(
            mode=mode,
            provenance=make_provenance(log.provenance, cfg.as_dict(), argv),
            runtime_s=0.0,
            pairs=out.pairs,
            landmarks=out.landmarks,
            consistency=out.consistency,
            truth=log.truth,
            stats=out.stats,
        )
    else:
        raise IvslamError(f"--mode {mode} is not implemented yet in this version (available: pairs)")
    ev = result.consistency.empty_events
    if cfg["robust.strict"] and len(ev):
        result.consistency.stopped = f"first empty intersection at t={ev.stamp[0]:.3f} s: {ev.text[0]}"
    result.runtime_s = time.perf_counter() - t0
    result.validate()
    return result


__all__ = ["run_pipeline", "InconsistentData"]
