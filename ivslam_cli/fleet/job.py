"""One log's run: what ``ivslam run LOG`` does, and what every worker of a batch does.

:class:`RunOptions` holds the options of ``ivslam run`` (everything but the log and the
output); :func:`run_one` reads the log, resolves the configuration, runs the pipeline and
writes the result (and the TUM trajectory) in one atomic transaction. The single-log
command and the batch worker (:func:`run_job`) both call it, so a log gives the same result
whichever way it is run.
"""

from __future__ import annotations

import dataclasses
import os
import socket
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ivslam_cli.errors import IvslamError

#: ``--mode auto``: the pipeline chosen from what the log holds (see :func:`auto_mode`)
AUTO = "auto"

#: the modes each mode-specific option applies to (given for another mode: an error, not ignored)
OPTION_MODES: dict[str, tuple[str, ...]] = {
    "--q": ("pairs",), "--heading": ("pairs",), "--heading-source": ("pairs",), "--anchor": ("pairs",),
    "--reference": ("pairs",), "--eps": ("pairs", "lidar"),
    "--q-landmark": ("landmarks",), "--q-pose": ("landmarks",), "--max-iterations": ("landmarks",),
    "--tolerance": ("landmarks",),
    "--initial-pose": ("landmarks", "lidar"), "--initial-pose-from-truth": ("landmarks", "lidar"),
    "--tum": ("landmarks", "lidar"),
    "--poses-known": ("lidar",), "--max-range": ("lidar",),
}

#: option name → RunOptions field
_FIELDS = {"--q": "q_pair", "--heading": "heading", "--heading-source": "heading_source", "--anchor": "anchor",
           "--reference": "reference", "--eps": "eps", "--q-landmark": "q_landmark", "--q-pose": "q_pose",
           "--max-iterations": "max_iterations", "--tolerance": "tolerance", "--initial-pose": "initial_pose",
           "--initial-pose-from-truth": "initial_pose_from_truth", "--tum": "tum",
           "--poses-known": "poses_known", "--max-range": "max_range"}


@dataclass(frozen=True)
class RunOptions:
    """The options of ``ivslam run`` (picklable: a batch sends them to its workers)."""

    mode: str = "pairs"
    config_file: str | None = None
    force: bool = False
    fmt: str | None = None
    robot: int | str | None = None
    scan_topic: str | None = None
    odom_topic: str | None = None
    landmark_topic: str | None = None
    truth_topic: str | None = None
    range_abs: float | None = None
    range_rel: float | None = None
    bearing: float | None = None
    q_pair: int | None = None
    strict: bool | None = None
    eps: float | None = None
    heading: tuple[float, float] | None = None
    heading_source: str | None = None
    anchor: tuple[int, float, float] | None = None
    reference: int | None = None
    initial_pose: tuple[float, float, float] | None = None
    initial_pose_from_truth: bool | None = None
    q_landmark: int | None = None
    q_pose: int | None = None
    max_iterations: int | None = None
    tolerance: float | None = None
    poses_known: bool | None = None
    max_range: float | None = None
    tum: str | None = None
    #: lidar.threads (not an option of ``ivslam run``: a batch's workers run one thread each)
    threads: int | None = None
    #: options given for another mode are dropped instead of refused (a batch under --mode auto:
    #: each option applies to the logs whose mode it fits)
    lenient: bool = False

    def replace(self, **changes: Any) -> RunOptions:
        return dataclasses.replace(self, **changes)

    def for_mode(self, mode: str) -> RunOptions:
        """These options for a run in ``mode``: the mode-specific ones that do not apply refused
        (one-line error) or, when ``lenient``, dropped."""
        dropped = {}
        for name, fld in _FIELDS.items():
            if getattr(self, fld) is not None and mode not in OPTION_MODES[name]:
                if not self.lenient:
                    raise IvslamError(f"{name} applies to --mode {' or '.join(OPTION_MODES[name])} only "
                                      f"(not {mode})")
                dropped[fld] = None
        if self.robot == "all" and mode != "landmarks":
            raise IvslamError(f"--robot all needs --mode landmarks (not {mode})")
        return dataclasses.replace(self, mode=mode, **dropped)

    def overrides(self) -> dict[str, Any]:
        """The configuration keys the options set (None: not given), for ``self.mode``."""
        mode, anchor = self.mode, self.anchor
        return {
            "bounds.range_abs": self.range_abs, "bounds.range_rel": self.range_rel, "bounds.bearing": self.bearing,
            "robust.q_pair": self.q_pair, "robust.strict": self.strict,
            "pairs.eps": self.eps if mode == "pairs" else None, "lidar.eps": self.eps if mode == "lidar" else None,
            "lidar.poses_known": self.poses_known, "lidar.max_range": self.max_range,
            "pairs.heading": self.heading, "pairs.heading_source": self.heading_source,
            "pairs.reference_id": self.reference,
            "pairs.anchor_id": anchor[0] if anchor else None,
            "pairs.anchor_xy": (anchor[1], anchor[2]) if anchor else None,
            "landmarks.initial_pose": self.initial_pose,
            "landmarks.initial_pose_from_truth": self.initial_pose_from_truth,
            "robust.q_landmark": self.q_landmark, "robust.q_pose": self.q_pose,
            "landmarks.max_iterations": self.max_iterations, "landmarks.tolerance": self.tolerance,
            "lidar.threads": self.threads,
        }


def default_output(log: str | Path, mode: str) -> Path:
    """``LOG-name.MODE.h5`` beside the log (the name before its first dot)."""
    p = Path(str(log).rstrip("/"))
    return p.with_name(f"{p.name.split('.')[0]}.{mode}.h5")


def auto_mode(data) -> str:
    """The pipeline for a log under ``--mode auto``: the scenario a simulated log states; else
    ``lidar`` for scans without landmark observations, ``landmarks`` for observations with
    odometry (or several robots), ``pairs`` for observations alone."""
    from ivslam_cli.errors import LogError
    from ivslam_cli.slam import MODES

    scenario = data.meta.get("scenario") if isinstance(data.meta, dict) else None
    if scenario in MODES:
        return str(scenario)
    if data.robots:
        return "landmarks"
    has_obs = data.observations is not None and len(data.observations) > 0
    if data.scans is not None and len(data.scans) > 0 and not has_obs:
        return "lidar"
    if has_obs:
        return "landmarks" if data.odometry is not None and len(data.odometry) > 0 else "pairs"
    raise LogError("--mode auto: the log has neither LiDAR scans nor landmark observations",
                   data.provenance.path)


def run_one(log: str | Path, opts: RunOptions, out: Path | Callable[[str], Path], *,
            argv: Sequence[str] | None = None, progress=None):
    """Read ``log``, run ``opts.mode`` (or the mode :func:`auto_mode` picks), write the result
    to ``out`` (a path, or a function of the mode), atomically with the TUM trajectory.

    Returns ``(result, path written)``. Every output is checked before the pipeline runs.
    ``progress(fraction, label)``, if given, hears of the stages (read, run — with the
    pipeline's own fractions —, written).
    """
    from ivslam_cli.atomic import refuse_existing, transaction
    from ivslam_cli.config import resolve_config
    from ivslam_cli.logs import check_reader_options, read_log
    from ivslam_cli.results.hdf5 import write_result
    from ivslam_cli.slam import run_pipeline

    log = str(log)
    if opts.mode != AUTO:
        opts = opts.for_mode(opts.mode)
    force = opts.force
    with transaction(force=force, inputs=[log, opts.config_file]):
        path = None
        if opts.mode != AUTO:
            path = Path(out(opts.mode)) if callable(out) else Path(out)
            refuse_existing(path, force, kind="result")  # fail before the run, not after it
        data = read_log(log, opts.fmt, scan_topic=opts.scan_topic, odom_topic=opts.odom_topic,
                        landmark_topic=opts.landmark_topic, truth_topic=opts.truth_topic, robot=opts.robot)
        if opts.mode == AUTO:
            try:
                opts = opts.for_mode(auto_mode(data))
            except IvslamError as exc:
                raise exc.about(log) from None
            path = Path(out(opts.mode)) if callable(out) else Path(out)
            refuse_existing(path, force, kind="result")
        if opts.tum is not None:
            from ivslam_cli.results.export import tum_paths

            for p in tum_paths(opts.tum, None if data.robots is None else [r for r, _ in data.robots]):
                refuse_existing(p, force, kind="tum")
        check_reader_options(data, robot=opts.robot, scan_topic=opts.scan_topic, odom_topic=opts.odom_topic,
                             landmark_topic=opts.landmark_topic, truth_topic=opts.truth_topic)
        cfg = resolve_config(opts.config_file, opts.overrides(), log_bounds=data.bounds)
        inner = None
        if progress is not None:
            progress(0.1, f"{opts.mode}: running")

            def inner(fraction: float, label: str | None = None):
                progress(0.1 + 0.8 * fraction, f"{opts.mode}: {label or 'running'}")
        result = run_pipeline(data, cfg, opts.mode, argv=argv, progress=inner)
        if progress is not None:
            progress(0.9, "writing the result")
        write_result(path, result, force=force)
        if opts.tum is not None:
            from ivslam_cli.results.export import write_tum

            write_tum(opts.tum, result.poses, force=force, robots=result.robots)
    if progress is not None:
        progress(1.0, "done")
    return result, path


# --------------------------------------------------------------------------- batch worker
@dataclass(frozen=True)
class Job:
    """One log of a batch: where it is, where its result goes, with which options."""

    log: str  # absolute path (workers of a cluster may run elsewhere in the tree)
    out_dir: str  # absolute
    name: str  # the result's name without ".MODE.h5": the log's name, and its robot
    opts: RunOptions
    argv: tuple[str, ...] | None = None
    label: str = ""  # the log as the user named it
    debug: bool = False

    def output(self, mode: str) -> Path:
        return Path(self.out_dir) / f"{self.name}.{mode}.h5"


def run_job(job: Job) -> dict[str, Any]:
    """Run one log of a batch; never raises (but for signals): its audit record (see
    :mod:`.audit`), with ``status`` ``ok``, ``inconsistent`` or ``error`` and the one-line
    message of the error, as ``ivslam run`` would print it."""
    import warnings

    from ivslam_cli.fleet.audit import error_record, result_record

    if not job.debug:  # numpy's RuntimeWarnings (NaN in, overflow) are not messages for the user
        warnings.simplefilter("ignore", RuntimeWarning)
    t0, c0 = time.perf_counter(), time.thread_time()
    where = {"host": socket.gethostname(), "pid": os.getpid()}
    try:
        result, path = run_one(job.log, job.opts, job.output, argv=job.argv)
    except Exception as exc:  # noqa: BLE001 - a broken log fails alone, as one line
        from ivslam_cli.cli import error_line

        message, code = error_line(exc)
        rec = error_record(job, message, code, time.perf_counter() - t0)
        if job.debug:
            import traceback

            rec["traceback"] = traceback.format_exc()
        rec.update(where, cpu_s=time.thread_time() - c0)
        return rec
    rec = result_record(job, result, path, time.perf_counter() - t0)
    rec.update(where, cpu_s=time.thread_time() - c0)
    return rec

