"""``ivslam run`` over many logs: plan the jobs, check every output first, run them, write the audit.

Exit codes (also in the README): 0 every log ran (some may be proven inconsistent: their
empty events are in the audit, as a single run's are in its result); 3 with ``--strict``,
some log was stopped at an empty intersection and none failed; 4 some log failed (its
one-line error is in the audit and on stderr; the others completed); 2 the batch could not
start (bad options, a directory with no log, an existing output without ``--force`` or
``--resume``); 1 the audit could not be written (disk full, I/O error).
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from pathlib import Path

import click

from ivslam_cli.errors import IvslamError
from ivslam_cli.fleet import audit
from ivslam_cli.fleet.inputs import Entry, expand, result_name
from ivslam_cli.fleet.job import AUTO, Job, RunOptions

EXIT_SOME_FAILED = 4


def _plan(entries: list[Entry], opts: RunOptions, out_dir: Path, *, argv, debug: bool) -> list[Job]:
    jobs: list[Job] = []
    names: dict[str, str] = {}
    for e in entries:
        mode = e.mode or opts.mode
        robot = e.robot if e.robot is not None else opts.robot
        jopts = opts.replace(mode=mode, robot=robot, config_file=e.config_file or opts.config_file,
                             lenient=opts.lenient or mode == AUTO or mode != opts.mode)
        name = result_name(e, robot)
        key = f"{name}.{mode}"
        if key in names and names[key] != str(e.path):
            raise IvslamError(f"its result {name}.{mode if mode != AUTO else 'MODE'}.h5 would also be that of "
                              f"{names[key]}: run them into different directories", e.label)
        names[key] = str(e.path)
        jobs.append(Job(log=os.path.abspath(e.path), out_dir=str(out_dir.resolve()), name=name, opts=jopts,
                        argv=tuple(argv) if argv is not None else None, label=e.label, debug=debug))
    return jobs


def _candidates(job: Job) -> list[Path]:
    from ivslam_cli.slam import MODES

    return [job.output(m) for m in (MODES if job.opts.mode == AUTO else (job.opts.mode,))]


def _progress(total: int, enabled: bool):
    if not enabled or total == 0:
        return contextlib.nullcontext(None)
    return click.progressbar(length=total, label="logs", file=sys.stderr, show_pos=True, show_eta=True,
                             item_show_func=lambda item: item)


def run_batch(args: tuple[str, ...], opts: RunOptions, output: str | None, *, jobs: int | None,
              scheduler: str | None, resume: bool, quiet: bool, argv=None, debug: bool = False) -> int:
    """Run every log of ``args`` into the directory ``output``; returns the exit code."""
    from ivslam_cli.atomic import EXISTS, check_output, written_by_ivslam
    from ivslam_cli.fleet.execute import default_jobs, run_jobs
    from ivslam_cli.inputs import same_or_inside

    t0 = time.perf_counter()
    if output is None:
        raise IvslamError("several logs need -o DIR, the directory for their results")
    if opts.tum is not None:
        raise IvslamError("--tum writes one trajectory: it applies to a single log, not a batch")
    if resume and opts.force:
        raise IvslamError("--resume keeps the results already there, --force replaces them: give one")
    if opts.mode != AUTO:
        opts.for_mode(opts.mode)  # options that do not apply to the mode: refused once, before any work
    out_dir = Path(output)
    if out_dir.exists() and not out_dir.is_dir():
        raise IvslamError("exists and is not a directory: -o names the output directory of a batch", out_dir)
    entries = expand(args)
    for e in entries:
        if same_or_inside(out_dir, e.path) and Path(e.path).is_dir():
            raise IvslamError(f"is inside or around the input {e.label}: refusing to write results there", out_dir)
    if not out_dir.exists():
        parent = out_dir.parent if str(out_dir.parent) else Path(".")
        if not parent.is_dir():
            raise IvslamError(f"directory {str(parent)!r} does not exist", out_dir)
    plan = _plan(entries, opts, out_dir, argv=argv, debug=debug)

    # every output checked before any work: existing results, the audit itself
    records: dict[int, dict] = {}
    pending: list[int] = []
    existing: list[Path] = []
    for i, job in enumerate(plan):
        there = [p for p in _candidates(job) if os.path.lexists(p)]
        if resume and there and written_by_ivslam(there[0]) == "result":
            records[i] = audit.resumed_record(job, there[0])
            continue
        if there and not opts.force and not resume:
            existing.extend(there)
        pending.append(i)
    if existing:
        more = f" (and {len(existing) - 1} other result(s))" if len(existing) > 1 else ""
        raise IvslamError(f"{EXISTS[:-1]}, or --resume to skip the logs already done){more}", existing[0])
    replace_audit = opts.force or resume
    if out_dir.is_dir():
        for name in (audit.JSON_NAME, audit.TEXT_NAME):
            check_output(out_dir / name, force=replace_audit, kind="fleet")
    client = None
    if scheduler is not None and pending:  # an unreachable scheduler: an error before anything is written
        from ivslam_cli.fleet.execute import connect

        client = connect(scheduler)
    if not out_dir.is_dir():
        out_dir.mkdir()

    workers = jobs if jobs is not None else default_jobs()
    show = not quiet and sys.stderr.isatty()
    failed = [0]
    todo = [plan[i] for i in pending]
    executor = "none (every result already there)"
    with _progress(len(plan), show) as bar:
        if bar is not None and records:
            bar.update(len(records), f"{len(records)} resumed")

        def done(k: int, rec: dict) -> None:
            records[pending[k]] = rec
            if rec["status"] == "error":
                failed[0] += 1
                if bar is None:
                    click.echo(f"ivslam: error: {rec['message']}", err=True)
            if bar is not None:
                bar.update(1, f"{failed[0]} failed" if failed[0] else "")

        if todo:
            executor = run_jobs(todo, done, workers=workers, scheduler=scheduler, client=client)
        elif client is not None:
            client.close()
    ordered = [records[i] for i in range(len(plan))]
    wall = time.perf_counter() - t0
    n_at_once = 1 if executor == "sequential" else (workers if scheduler is None else 0)
    doc = audit.fleet_doc(ordered, output_dir=out_dir.resolve(), command=" ".join(argv or ()),
                          executor=executor, jobs=n_at_once, wall_s=wall)
    jpath, _ = audit.write_audit(doc, out_dir, replace=replace_audit)
    t = doc["totals"]
    if show:  # the errors, after the bar
        for rec in ordered:
            if rec["status"] == "error" and not rec["resumed"]:
                click.echo(f"ivslam: error: {rec['message']}", err=True)
    if debug:
        for rec in ordered:
            if rec.get("traceback"):
                click.echo(rec["traceback"], err=True)
    if not quiet:
        resumed = f", {t['resumed']} resumed" if t["resumed"] else ""
        click.echo(f"fleet: {t['logs']} log(s): {t['ok']} ok, {t['inconsistent']} proven inconsistent, "
                   f"{t['error']} failed{resumed}; {t['empty_events']} empty event(s); {wall:.2f} s "
                   f"({executor}) -> {jpath}", err=True)
    if t["error"]:
        return EXIT_SOME_FAILED
    if any(r["stopped"] for r in ordered):
        return 3
    return 0
