"""The three pipelines. ``run_pipeline`` turns a log and a resolved config into a Result."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ivslam_cli.config import Config
from ivslam_cli.errors import InconsistentData, IvslamError
from ivslam_cli.logs.model import LogData, Observations
from ivslam_cli.results.model import RelativePoses, Result
from ivslam_cli.results.provenance import make_provenance


def observations_until(log: LogData, stamp: float) -> LogData:
    """The log with its observations cut after ``stamp`` (indices of the kept ones unchanged)."""
    obs = log.observations
    keep = obs.stamp <= stamp
    cut = Observations(stamp=obs.stamp[keep], landmark_id=obs.landmark_id[keep], range=obs.range[keep],
                       bearing=obs.bearing[keep])
    return replace(log, observations=cut)


def _result(mode: str, log: LogData, cfg: Config, argv, out, **parts) -> Result:
    """A Result from a pipeline output with ``consistency``, ``stats`` and ``dropped``."""
    prov = make_provenance(log.provenance, cfg.as_dict(), argv)
    prov.dropped = list(prov.dropped) + list(out.dropped)
    return Result(mode=mode, provenance=prov, runtime_s=0.0, consistency=out.consistency, truth=log.truth,
                  stats=out.stats, **parts)


def relative_poses(rel) -> RelativePoses | None:
    """``LidarOutput.relative`` = ``(pairs (R, 2), flat boxes (R, 6))`` as :class:`RelativePoses`
    (None stays None)."""
    if rel is None:
        return None
    pairs, boxes = rel
    return RelativePoses(pairs=np.ascontiguousarray(pairs, np.int64).reshape(-1, 2),
                         box=np.ascontiguousarray(boxes, np.float64).reshape(-1, 3, 2))


def run_pipeline(log: LogData, cfg: Config, mode: str, argv: Sequence[str] | None = None) -> Result:
    """Run ``mode`` over ``log``.

    With ``robust.strict`` the run stops at the first empty intersection: the result covers the
    data up to that measurement and ``consistency.stopped`` says where (the CLI then exits 3).
    """
    from ivslam_cli.interval.rounding import ensure_round_to_nearest

    ensure_round_to_nearest()
    t0 = time.perf_counter()
    if mode == "pairs":
        from ivslam_cli.slam.pairs import run_pairs

        out = run_pairs(log, cfg)
        events = out.consistency.empty_events
        if cfg["robust.strict"] and len(events):
            # stop at the first empty intersection: the result holds the data up to it
            out = run_pairs(observations_until(log, float(events.stamp[0])), cfg)
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
    elif mode == "landmarks":
        from ivslam_cli.slam.landmarks import run_landmarks

        out = run_landmarks(log, cfg)
        result = _result(mode, log, cfg, argv, out, poses=out.poses, landmarks=out.landmarks)
    elif mode == "lidar":
        from ivslam_cli.slam.lidar import run_lidar

        from ivslam_cli.slam.lidar_logodds import logodds_of

        out = run_lidar(log, cfg)
        # the probabilistic baseline (not guaranteed) from the same scans at the box centres
        result = _result(mode, log, cfg, argv, out, poses=out.poses, grid=out.grid, logodds=logodds_of(out),
                         relative=relative_poses(out.relative))
    else:
        raise IvslamError(f"unknown --mode {mode} (available: pairs, landmarks, lidar)")
    ev = result.consistency.empty_events
    if cfg["robust.strict"] and len(ev) and not result.consistency.stopped:
        result.consistency.stopped = f"first empty intersection at t={ev.stamp[0]:.3f} s: {ev.text[0]}"
    result.runtime_s = time.perf_counter() - t0
    result.validate()
    return result


__all__ = ["run_pipeline", "InconsistentData"]
