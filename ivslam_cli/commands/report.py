"""`ivslam report RESULT.h5`: the consistency report of a run (text, JSON, plot, exports)."""

from __future__ import annotations

from pathlib import Path

import click


@click.command(name="report")
@click.argument("result", type=click.Path(path_type=Path, dir_okay=True))
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON instead of text.")
@click.option("--plot", type=click.Path(path_type=Path, dir_okay=False), help="Write a figure (.png or .svg).")
@click.option("--tum", type=click.Path(path_type=Path, dir_okay=False),
              help="Export pose box centres as a TUM trajectory (for evo).")
@click.option("--map-pgm", "map_pgm", type=click.Path(path_type=Path),
              help="Export the map grid as ROS map_server PREFIX.pgm + PREFIX.yaml (LiDAR runs with loop closure: "
                   "the global map, proven in the result's frame).")
@click.option("--graph", "graph", type=click.Path(path_type=Path),
              help="Export the interval pose graph of a LiDAR loop-closure run as PREFIX.graph.json (anchor boxes, "
                   "edge boxes) + PREFIX.g2o (their centres, no guarantee).")
@click.option("--relations", type=click.Path(path_type=Path, dir_okay=False),
              help="Benchmark relations file (t1 t2 dx dy dz droll dpitch dyaw; plain, .gz or .xz): check "
                   "each true relative pose against what the result's two pose boxes allow.")
@click.option("--stamp-tol", type=float, default=None, show_default="0.0001",
              help="--relations: a relation end falls on a pose box when their stamps differ by at most "
                   "this [s] and no other pose stamp is that close.")
@click.option("--max-hops", type=click.IntRange(min=1), default=None, show_default="8",
              help="--relations: relative pose enclosures of the result (keyframes runs) composed at most "
                   "along a chain between the two poses of a relation.")
@click.option("--submap", type=click.IntRange(min=0), default=None, metavar="K",
              help="--plot: draw submap K in its anchor's frame beside the mosaic (LiDAR results).")
@click.option("--force", is_flag=True, help="Overwrite existing output files.")
def command(result: Path, as_json: bool, plot: Path | None, tum: Path | None, map_pgm: Path | None,
            graph: Path | None, relations: Path | None, stamp_tol: float | None, max_hops: int | None, submap: int | None,
            force: bool) -> None:
    """Report on a result: bounds used, empty intersections, convergence, containment.

    \b
    RESULT may be the output directory of a batch (`ivslam run LOG... -o DIR`): its fleet
    audit (per log: mode, status, empty events, containment, widths, runtime; totals), as
    text or --json, and --plot draws per-log bars.

    \b
    Containment against ground truth below 1.0 is flagged SOUNDNESS FAILURE, unless
    outliers were injected: then it says whether the run relaxed them (a q > 0 covering
    their stream) or they break the stated bounds (odometry outliers: no q covers them).

    \b
    Examples:
      ivslam report result.h5
      ivslam report result.h5 --json > report.json
      ivslam report result.h5 --plot map.png --tum traj.txt --map-pgm map
      ivslam report lidar.h5 --plot submap3.png --submap 3
      ivslam report lidar.h5 --graph graph   # graph.graph.json + graph.g2o
      ivslam report intel.h5 --relations ../shared/datasets/intel_lab/intel.relations.xz
      ivslam report out/fleet --plot fleet.png
    """
    import math

    from ivslam_cli.atomic import refuse_existing, transaction
    from ivslam_cli.errors import IvslamError
    from ivslam_cli.report.core import compute_report
    from ivslam_cli.results.hdf5 import read_result

    if result.is_dir() and not (result / "metadata.yaml").exists():
        for name, value in (("--tum", tum), ("--map-pgm", map_pgm), ("--relations", relations),
                            ("--submap", submap)):
            if value is not None:
                raise IvslamError(f"{name} applies to one result, not to a batch directory", result)
        from ivslam_cli.fleet.report import report_fleet

        click.echo(report_fleet(result, as_json=as_json, plot=plot, force=force), nl=False)
        return
    if stamp_tol is not None and relations is None:
        raise IvslamError("--stamp-tol applies to --relations only")
    if stamp_tol is not None and not (math.isfinite(stamp_tol) and stamp_tol >= 0):
        raise IvslamError(f"--stamp-tol must be a finite number >= 0, not {stamp_tol}")
    if max_hops is not None and relations is None:
        raise IvslamError("--max-hops applies to --relations only")
    if submap is not None and plot is None:
        raise IvslamError("--submap applies to --plot only")
    with transaction(force=force, inputs=[result, relations]):
        # every output checked before any work: existing, special, an input, or given twice
        if map_pgm is not None:
            refuse_existing(map_pgm.with_name(map_pgm.name + ".pgm"), force, kind="pgm")
            refuse_existing(map_pgm.with_name(map_pgm.name + ".yaml"), force, kind="map-yaml")
        if plot is not None:
            refuse_existing(plot, force, kind="plot")
        if graph is not None:
            refuse_existing(graph.with_name(graph.name + ".graph.json"), force, kind="graph")
            refuse_existing(graph.with_name(graph.name + ".g2o"), force, kind="g2o")
        res = read_result(result)
        if graph is not None and (res.loops is None or res.submaps is None):
            raise IvslamError("has no anchor graph (LiDAR runs with submaps and lidar.loop_closure have): nothing "
                              "to export to --graph", result)
        if tum is not None:
            from ivslam_cli.results.export import tum_paths

            for path in tum_paths(tum, None if res.robots is None else res.robots.id):
                refuse_existing(path, force, kind="tum")
        rep = compute_report(res)
        rel_check = None
        if relations is not None:
            from ivslam_cli.report.relations import (DEFAULT_MAX_HOPS, DEFAULT_TOL, check_relations,
                                                     read_relations)

            if res.poses is None:
                raise IvslamError(f"has no pose enclosures ({res.mode} mode): nothing to check --relations "
                                  "against", result)
            rel_check = check_relations(res.poses, read_relations(relations),
                                        DEFAULT_TOL if stamp_tol is None else stamp_tol, relative=res.relative,
                                        max_hops=DEFAULT_MAX_HOPS if max_hops is None else max_hops)
        if tum is not None and res.poses is None:
            raise IvslamError(f"has no pose enclosures ({res.mode} mode): nothing to export to --tum", result)
        if map_pgm is not None and res.grid is None:
            raise IvslamError(f"has no map grid ({res.mode} mode): nothing to export to --map-pgm", result)
        skipped = 0
        if tum is not None:
            from ivslam_cli.results.export import write_tum

            skipped = write_tum(tum, res.poses, force=force, robots=res.robots)
        if map_pgm is not None:
            from ivslam_cli.results.export import write_map_server

            write_map_server(map_pgm, res.main_map, force=force)
        if graph is not None:
            from ivslam_cli.results.export import write_graph

            write_graph(graph, res.submaps.anchor_box, res.loops, force=force)
        if plot is not None:
            from ivslam_cli.report.plot import plot_report, plot_submap

            if submap is None:
                plot_report(rep, plot, force=force)
            else:
                plot_submap(rep, submap, plot, force=force)
    if skipped:
        click.echo(f"ivslam: note: {tum}: skipped {skipped} empty pose box(es)", err=True)
    if as_json:
        from ivslam_cli.report.jsonout import render_json

        text = render_json(rep)
        if rel_check is not None:
            import json

            from ivslam_cli.report.relations import relations_dict

            doc = json.loads(text)
            doc["relations"] = relations_dict(rel_check)
            text = json.dumps(doc, indent=2, allow_nan=False)
        click.echo(text)
    else:
        from ivslam_cli.report.text import render_text

        click.echo(render_text(rep, str(result)), nl=False)
        if rel_check is not None:
            from ivslam_cli.report.relations import render_relations_text

            click.echo(render_relations_text(rel_check), nl=False)
