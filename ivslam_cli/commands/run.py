"""``ivslam run LOG...``: read a log, run a pipeline, write the HDF5 result; over many logs, a
batch into one directory with its fleet audit (:mod:`ivslam_cli.fleet`)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from ivslam_cli.slam import MODES


class _Robot(click.ParamType):
    """A robot number, or ``all``."""

    name = "N|all"

    def convert(self, value, param, ctx):
        if isinstance(value, int) or value == "all":
            return value
        try:
            return int(value)
        except ValueError:
            self.fail(f"{value!r} is neither a robot number nor 'all'", param, ctx)


ROBOT = _Robot()


@click.command(name="run")
@click.argument("logs", metavar="LOG...", nargs=-1, required=True, type=click.Path(exists=False))
@click.option("--mode", type=click.Choice((*MODES, "auto")), default="pairs", show_default=True,
              help="pairs: landmark displacement subpavings (Mustafa et al.); landmarks: pose/landmark CSP; "
                   "lidar: feature-less P_EMPTY/P_OBSTACLE map (Guaranteed SLAM slides); auto: from what each "
                   "log holds (its simulated scenario; scans: lidar; observations and odometry: landmarks; "
                   "observations alone: pairs).")
@click.option("-o", "--output", type=click.Path(), default=None,
              help="Result file [default: LOG name + .MODE.h5 beside the log]; with several logs, the output "
                   "directory (one result per log, LOG name + .MODE.h5, and the audit fleet.json, fleet.txt).")
@click.option("--config", "config_file", type=click.Path(), default=None, help="TOML configuration file.")
@click.option("--force", is_flag=True, help="Overwrite an existing result.")
@click.option("--format", "fmt", default=None, help="Force the log reader (see `ivslam inspect --help`).")
@click.option("--robot", type=ROBOT, default=None,
              help="MRCLAM robot number, or all: every robot together (landmarks mode; shared landmarks, "
                   "their measurements of each other; --tum writes one file per robot, FILE.robotN).")
@click.option("--scan-topic", default=None)
@click.option("--odom-topic", default=None)
@click.option("--landmark-topic", default=None)
@click.option("--truth-topic", default=None)
@click.option("--range-abs", type=float, default=None, help="bounds.range_abs [m].")
@click.option("--range-rel", type=float, default=None, help="bounds.range_rel.")
@click.option("--bearing", type=float, default=None, help="bounds.bearing [rad].")
@click.option("--q", "q_pair", type=int, default=None, help="robust.q_pair: inconsistent observations tolerated per pair.")
@click.option("--strict", is_flag=True, default=None, help="Fail (exit 3) on the first empty intersection.")
@click.option("--eps", type=float, default=None,
              help="pairs.eps (subpaving resolution) or, in lidar mode, lidar.eps (map cell side) [m].")
@click.option("--heading", type=(float, float), default=None, metavar="LO HI",
              help="pairs.heading: known heading interval [rad].")
@click.option("--heading-source", type=click.Choice(["option", "odometry"]), default=None,
              help="pairs.heading_source: the --heading interval, or the log's odometry heading per step "
                   "(--heading is then its error bound).")
@click.option("--anchor", type=(int, float, float), default=None, metavar="ID X Y",
              help="Anchoring landmark and its known position (absolute map).")
@click.option("--reference", type=int, default=None, help="pairs.reference_id for a relative map.")
@click.option("--initial-pose", type=(float, float, float), default=None, metavar="X Y THETA",
              help="landmarks.initial_pose: the first pose (box: ± landmarks.initial_margin).")
@click.option("--initial-pose-from-truth", is_flag=True, default=None,
              help="landmarks.initial_pose_from_truth: anchor the map frame at the true first pose.")
@click.option("--q-landmark", type=int, default=None, help="robust.q_landmark: outliers tolerated per landmark.")
@click.option("--q-pose", type=int, default=None, help="robust.q_pose: outliers tolerated at each pose.")
@click.option("--max-iterations", type=int, default=None, help="landmarks.max_iterations: sweep cap.")
@click.option("--tolerance", type=float, default=None, help="landmarks.tolerance: stop when widths shrink less.")
@click.option("--poses-known", is_flag=True, default=None,
              help="lidar.poses_known: guaranteed mapping from given poses (truth, scan poses or odometry: "
                   "lidar.known_poses) ± lidar.pose_margin; no odometry model.")
@click.option("--max-range", type=float, default=None,
              help="lidar.max_range: returns beyond this prove nothing [m].")
@click.option("--tum", type=click.Path(dir_okay=False), default=None,
              help="Also write the pose box centres as a TUM trajectory (landmarks and lidar modes).")
@click.option("-j", "--jobs", type=click.IntRange(min=1), default=None,
              help="Several logs: how many run at once on a local process pool [default: the machine's cores; "
                   "1: one after another in this process].")
@click.option("--scheduler", metavar="tcp://HOST:PORT", default=None,
              help="Several logs: run them on this existing Dask cluster (pip install 'ivslam[fleet]'; the "
                   "workers need ivslam and write the results to -o DIR, a path they must share).")
@click.option("--resume", is_flag=True,
              help="Several logs: skip the logs whose result is already in -o DIR (an interrupted batch "
                   "continues where it stopped).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line (errors still print).")
@click.pass_context
def command(ctx, logs, mode, output, config_file, force, fmt, robot, scan_topic, odom_topic, landmark_topic,
            truth_topic, range_abs, range_rel, bearing, q_pair, strict, eps, heading, heading_source, anchor, reference,
            initial_pose, initial_pose_from_truth, q_landmark, q_pose, max_iterations, tolerance, poses_known,
            max_range, tum, jobs, scheduler, resume, quiet):
    """Run a guaranteed SLAM pipeline over LOG and write the result (HDF5).

    \b
    Several LOGs, a directory (every log in it a reader recognises) or a manifest (one log a
    line, optionally followed by --robot N, --config FILE, --mode MODE) run as a batch: one
    result per log in the directory -o DIR, and the fleet audit DIR/fleet.json + fleet.txt
    (`ivslam report DIR`). A broken log fails alone; exit 4 if any failed.

    \b
    Examples:
      ivslam run sample_logs/pairs.mcap --mode pairs -o pairs.h5
      ivslam run log.bag --mode pairs --q 1 --anchor 6 1.5 2.0 --force
      ivslam run sample_logs/landmarks.bag --mode landmarks --initial-pose-from-truth
      ivslam run ../shared/datasets/mrclam/MRCLAM_Dataset6 --robot 1 --mode landmarks
          --config configs/mrclam.toml --tum robot1.tum -o robot1.h5
      ivslam run sample_logs/lidar_rooms.h5 --mode lidar --initial-pose-from-truth
      ivslam run ../shared/datasets/carmen_corrected/aces-corrected.log.gz --mode lidar --poses-known
      ivslam run sample_logs --mode auto --initial-pose-from-truth -o out/fleet --jobs 2
      ivslam run logs.txt --mode landmarks -o out/fleet --scheduler tcp://10.0.0.5:8786 --resume
    """
    from ivslam_cli import collector

    collector.pause()  # no collection while the run starts, until its pipeline does (run_pipeline)
    from ivslam_cli.errors import InconsistentData
    from ivslam_cli.fleet.inputs import single_log
    from ivslam_cli.fleet.job import RunOptions, default_output, run_one
    from ivslam_cli.slam import summary

    opts = RunOptions(
        mode=mode, config_file=config_file, force=force, fmt=fmt, robot=robot, scan_topic=scan_topic,
        odom_topic=odom_topic, landmark_topic=landmark_topic, truth_topic=truth_topic, range_abs=range_abs,
        range_rel=range_rel, bearing=bearing, q_pair=q_pair, strict=strict, eps=eps, heading=heading,
        heading_source=heading_source, anchor=anchor, reference=reference, initial_pose=initial_pose,
        initial_pose_from_truth=initial_pose_from_truth, q_landmark=q_landmark, q_pose=q_pose,
        max_iterations=max_iterations, tolerance=tolerance, poses_known=poses_known, max_range=max_range, tum=tum)
    argv = sys.argv[1:] if ctx.parent else None
    batch = jobs is not None or scheduler is not None or resume or not single_log(logs)
    if batch:
        from ivslam_cli.fleet.batch import run_batch

        root = ctx.find_root().obj
        return run_batch(logs, opts, output, jobs=jobs, scheduler=scheduler, resume=resume, quiet=quiet,
                         argv=argv, debug=bool(root and root.get("debug")))
    log = logs[0]
    from ivslam_cli.fleet.progress import run_progress

    with run_progress(enabled=not quiet and sys.stderr.isatty()) as progress:
        result, out = run_one(log, opts, Path(output) if output else (lambda m: default_output(log, m)),
                              argv=argv, progress=progress)
    if not quiet:
        click.echo(f"{summary(result)}, {result.runtime_s:.2f} s -> {out}", err=True)
    if result.consistency.stopped:
        raise InconsistentData(f"stopped (--strict): {result.consistency.stopped}; result written to {out}")
