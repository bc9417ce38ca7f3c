"""``ivslam run LOG``: read a log, run a pipeline, write the HDF5 result."""

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


def _default_output(log: str, mode: str) -> Path:
    p = Path(log.rstrip("/"))
    return p.with_name(f"{p.name.split('.')[0]}.{mode}.h5")


@click.command(name="run")
@click.argument("log", type=click.Path(exists=False))
@click.option("--mode", type=click.Choice(MODES), default="pairs", show_default=True,
              help="pairs: landmark displacement subpavings (Mustafa et al.); landmarks: pose/landmark CSP; "
                   "lidar: feature-less P_EMPTY/P_OBSTACLE map (Guaranteed SLAM slides).")
@click.option("-o", "--output", type=click.Path(), default=None,
              help="Result file [default: LOG name + .MODE.h5 beside the log].")
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
@click.option("--q-pose", type=int, default=None, help="robust.q_pose: outliers tolerated per pose window.")
@click.option("--max-iterations", type=int, default=None, help="landmarks.max_iterations: sweep cap.")
@click.option("--tolerance", type=float, default=None, help="landmarks.tolerance: stop when widths shrink less.")
@click.option("--poses-known", is_flag=True, default=None,
              help="lidar.poses_known: guaranteed mapping from given poses (truth, scan poses or odometry: "
                   "lidar.known_poses) ± lidar.pose_margin; no odometry model.")
@click.option("--max-range", type=float, default=None,
              help="lidar.max_range: returns beyond this prove nothing [m].")
@click.option("--tum", type=click.Path(dir_okay=False), default=None,
              help="Also write the pose box centres as a TUM trajectory (landmarks and lidar modes).")
@click.pass_context
def command(ctx, log, mode, output, config_file, force, fmt, robot, scan_topic, odom_topic, landmark_topic,
            truth_topic, range_abs, range_rel, bearing, q_pair, strict, eps, heading, heading_source, anchor, reference,
            initial_pose, initial_pose_from_truth, q_landmark, q_pose, max_iterations, tolerance, poses_known,
            max_range, tum):
    """Run a guaranteed SLAM pipeline over LOG and write the result (HDF5).

    \b
    Examples:
      ivslam run sample_logs/pairs.mcap --mode pairs -o pairs.h5
      ivslam run log.bag --mode pairs --q 1 --anchor 6 1.5 2.0 --force
      ivslam run sample_logs/landmarks.bag --mode landmarks --initial-pose-from-truth
      ivslam run ../shared/datasets/mrclam/MRCLAM_Dataset6 --robot 1 --mode landmarks
          --config configs/mrclam.toml --tum robot1.tum -o robot1.h5
      ivslam run sample_logs/lidar_rooms.h5 --mode lidar --initial-pose-from-truth
      ivslam run ../shared/datasets/carmen_corrected/aces-corrected.log.gz --mode lidar --poses-known
    """
    from ivslam_cli.atomic import refuse_existing, transaction
    from ivslam_cli.config import resolve_config
    from ivslam_cli.errors import InconsistentData, IvslamError
    from ivslam_cli.logs import check_reader_options, read_log
    from ivslam_cli.results.hdf5 import write_result
    from ivslam_cli.slam import run_pipeline, summary

    given = {"--q": q_pair, "--heading": heading, "--heading-source": heading_source, "--anchor": anchor,
             "--reference": reference, "--q-landmark": q_landmark, "--q-pose": q_pose,
             "--max-iterations": max_iterations, "--tolerance": tolerance, "--initial-pose": initial_pose,
             "--initial-pose-from-truth": initial_pose_from_truth, "--tum": tum, "--poses-known": poses_known,
             "--max-range": max_range, "--eps": eps}
    for name, value in given.items():
        if value is not None and mode not in OPTION_MODES[name]:
            raise IvslamError(f"{name} applies to --mode {' or '.join(OPTION_MODES[name])} only (not {mode})")
    if robot == "all" and mode != "landmarks":
        raise IvslamError(f"--robot all needs --mode landmarks (not {mode})")
    out = Path(output) if output else _default_output(log, mode)
    with transaction(force=force, inputs=[log, config_file]):
        refuse_existing(out, force, kind="result")  # fail before the run, not after it
        data = read_log(log, fmt, scan_topic=scan_topic, odom_topic=odom_topic, landmark_topic=landmark_topic,
                        truth_topic=truth_topic, robot=robot)
        if tum is not None:
            from ivslam_cli.results.export import tum_paths

            for path in tum_paths(tum, None if data.robots is None else [r for r, _ in data.robots]):
                refuse_existing(path, force, kind="tum")
        check_reader_options(data, robot=robot, scan_topic=scan_topic, odom_topic=odom_topic,
                             landmark_topic=landmark_topic, truth_topic=truth_topic)
        overrides = {
            "bounds.range_abs": range_abs, "bounds.range_rel": range_rel, "bounds.bearing": bearing,
            "robust.q_pair": q_pair, "robust.strict": strict,
            "pairs.eps": eps if mode == "pairs" else None, "lidar.eps": eps if mode == "lidar" else None,
            "lidar.poses_known": poses_known, "lidar.max_range": max_range,
            "pairs.heading": heading, "pairs.heading_source": heading_source, "pairs.reference_id": reference,
            "pairs.anchor_id": anchor[0] if anchor else None,
            "pairs.anchor_xy": (anchor[1], anchor[2]) if anchor else None,
            "landmarks.initial_pose": initial_pose, "landmarks.initial_pose_from_truth": initial_pose_from_truth,
            "robust.q_landmark": q_landmark, "robust.q_pose": q_pose, "landmarks.max_iterations": max_iterations,
            "landmarks.tolerance": tolerance,
        }
        cfg = resolve_config(config_file, overrides, log_bounds=data.bounds)
        result = run_pipeline(data, cfg, mode, argv=sys.argv[1:] if ctx.parent else None)
        write_result(out, result, force=force)
        if tum is not None:
            from ivslam_cli.results.export import write_tum

            write_tum(tum, result.poses, force=force, robots=result.robots)
    click.echo(f"{summary(result)}, {result.runtime_s:.2f} s -> {out}", err=True)
    if result.consistency.stopped:
        raise InconsistentData(f"stopped (--strict): {result.consistency.stopped}; result written to {out}")


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
