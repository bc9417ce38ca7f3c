"""`ivslam simulate`: synthetic logs with ground truth (see :mod:`ivslam_cli.simulate`)."""

from __future__ import annotations

import sys

import click

from ivslam_cli.simulate.config import BEAM_MODELS, DEFAULT_BOUNDS, NOISES, SCENARIOS

_BOUND_OPTIONS = sorted({k for b in DEFAULT_BOUNDS.values() for k in b})
_BOUND_HELP = {
    "beam_angle": "lidar bearing bound [rad], stated in the log (the pipelines read it as 'bearing'): the cone "
                  "half-width of --beam-model cone [default: half the sensor's beam step, the smallest value "
                  "whose adjacent cones touch: urg-04lx 0.0030680, sick 0.0087266; with --sweep, wider so that they "
                  "overlap by the turn between two beams; a value below half a step is refused]; "
                  "with ray, only stated (rays are exact) [default: 0].",
}


def _bound_option(key: str):
    return click.option(f"--{key.replace('_', '-')}", key, type=float, default=None, metavar="B",
                        help=_BOUND_HELP.get(key, f"Noise bound '{key}' (half-width; default per scenario)."))


def _options(f):
    for key in reversed(_BOUND_OPTIONS):
        f = _bound_option(key)(f)
    return f


@click.command(name="simulate")
@click.option("--scenario", type=click.Choice(SCENARIOS), default="pairs", show_default=True,
              help="pairs: holonomic, no rotation; landmarks: unicycle + FOV camera; lidar: unicycle + 2D LiDAR.")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=True, writable=True),
              help="Output log (.mcap, .bag, .h5, or a ROS 2 bag directory).")
@click.option("--format", "fmt", type=click.Choice(["mcap", "ros1", "ros2", "ros2-mcap", "h5"]), default=None,
              help="Log format [default: from the output name; no known suffix: ros2].")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed (same seed, same log).")
@click.option("--steps", type=click.IntRange(min=2), default=None, help="Number of steps.")
@click.option("--duration", type=float, default=None, help="Duration [s] (instead of --steps).")
@click.option("--rate", type=float, default=None, help="Step rate [Hz] (lidar: default the sensor's).")
@click.option("--landmarks", type=int, default=30, show_default=True, help="Number of landmarks.")
@click.option("--world-size", type=float, default=20.0, show_default=True, help="Landmark world side [m].")
@click.option("--world", default="rooms", show_default=True,
              help="lidar world: rooms, corridor, pillars, open, or a TOML world file.")
@click.option("--sensor", type=click.Choice(["urg-04lx", "sick"]), default="urg-04lx", show_default=True,
              help="lidar sensor profile.")
@click.option("--beam-model", type=click.Choice(BEAM_MODELS), default="cone", show_default=True,
              help="lidar beams: cone = the nearest wall within +-beam-angle of the nominal angle (every closer "
                   "point of the cone is free: adjacent cones touch, so scans prove free space); ray = the first "
                   "wall along the nominal angle (zero-width beams: gaps between them prove nothing).")
@click.option("--min-range", type=float, default=None, help="Landmark sensor min range [m].")
@click.option("--max-range", type=float, default=None, help="Landmark sensor max range [m].")
@click.option("--fov", type=float, default=None, help="Landmark sensor half field of view [rad].")
@click.option("--speed", type=float, default=0.5, show_default=True, help="Nominal speed [m/s].")
@click.option("--sweep", type=float, default=0.0, show_default=True,
              help="LiDAR: seconds from a scan's stamp (its first beam) to its last beam; each beam is "
                   "taken from the robot pose at its own time (a URG-04LX: 0.067); the default --beam-angle then "
                   "widens so that adjacent cones overlap by the turn between two beams (free space from "
                   "0.1 m on). 0: every beam at the stamp.")
@click.option("--noise", type=click.Choice(NOISES), default="uniform", show_default=True,
              help="In-bound error distribution (edges = at the bound).")
@click.option("--outlier-rate", type=float, default=0.0, show_default=True,
              help="Fraction of measurements that are gross outliers.")
@click.option("--outlier-magnitude", type=float, default=10.0, show_default=True,
              help="Outlier size as a multiple of the bound.")
@click.option("--wrong-association-rate", type=float, default=0.0, show_default=True,
              help="Fraction of landmark observations with a wrong id.")
@_options
@click.option("--force", is_flag=True, help="Overwrite an existing output.")
def command(scenario, output, fmt, seed, steps, duration, rate, landmarks, world_size, world, sensor,
            beam_model, min_range, max_range, fov, speed, sweep, noise, outlier_rate, outlier_magnitude,
            wrong_association_rate, force, **bounds) -> None:
    """Simulate a log with ground truth (true poses, map, bounds, outliers).

    \b
    Examples:
      ivslam simulate --scenario pairs -o pairs.mcap --seed 1
      ivslam simulate --scenario lidar --world corridor --duration 600 -o urg.bag
      ivslam simulate --scenario lidar --sensor sick --beam-model ray -o rays.mcap
      ivslam simulate --scenario landmarks --noise edges --outlier-rate 0.01 -o lm.h5
    """
    import os
    from pathlib import Path

    from ivslam_cli.atomic import refuse_existing, transaction
    from ivslam_cli.logs.writers import format_from_path, write_log
    from ivslam_cli.simulate import SimConfig, simulate

    out = Path(output)
    world_file = Path(world) if scenario == "lidar" and os.path.lexists(world) else None
    refuse_existing(out, force, kind="log", inputs=[world_file] if world_file else ())
    fmt = fmt or format_from_path(out)
    cfg = SimConfig(scenario=scenario, seed=seed, steps=steps, duration=duration, rate=rate,
                    landmarks=landmarks, world_size=world_size, world=world, sensor=sensor,
                    beam_model=beam_model, min_range=min_range, max_range=max_range, fov=fov,
                    speed=speed, sweep=sweep, noise=noise,
                    bounds={k: v for k, v in bounds.items() if v is not None},
                    outlier_rate=outlier_rate, outlier_magnitude=outlier_magnitude,
                    wrong_association_rate=wrong_association_rate)
    cfg.validate()
    # progress: steps, then one unit for writing
    from ivslam_cli.simulate.sensors import get_profile

    total = cfg.resolved_steps(cfg.resolved_rate(get_profile(sensor).rate)) + 1
    with click.progressbar(length=total, label="simulating", file=sys.stderr,
                           show_eta=False) as bar:
        log = simulate(cfg, progress=bar.update)
        log.provenance.notes.append(f"simulated: scenario {scenario}, seed {seed} (config in meta)")
        with transaction(force=force, inputs=[world_file]):
            write_log(out, log, fmt, force=force)
        bar.update(1)
    click.echo(f"wrote {out} ({fmt}, scenario {scenario}, seed {seed})", err=True)
