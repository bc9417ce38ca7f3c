"""The fleet audit: one record per log of a batch, their totals, ``fleet.json`` and ``fleet.txt``.

A record (a plain dict, what a worker sends back) has: ``log`` (as given), ``path``
(absolute), ``result`` (the result's file name in the output directory, or null), ``mode``,
``status`` — ``ok``; ``inconsistent``: the data are *proven* to contradict the bounds (some
empty event, or the run stopped under ``--strict``); ``error``: the log failed, ``message``
says why in one line —, ``resumed`` (the result was already there: ``--resume``),
``empty_events`` (how many) and ``empty_event_list`` (the first :data:`MAX_EVENTS`: stamp,
step, constraint, entity, measurement, text — the sensor-fault audit), ``stopped``,
``containment`` (kind → fraction, when the log has truth), ``sound``, ``final_width`` (kind →
median, max [m]), ``scans`` (``scans``, ``scans_used``, ``scans_mapped`` in lidar mode, else
null), ``stats`` (the pipeline's counters), ``summary`` (the line ``ivslam run`` prints),
``runtime_s`` (the pipeline), ``wall_s`` (the whole job: read, run, write), ``cpu_s`` (the
CPU time of the job's thread), ``host``, ``pid`` (the worker).

``fleet.json``: ``{"format": "ivslam-fleet", "version": 1, "output_dir", "command",
"executor", "jobs", "wall_s", "totals": {logs, ok, inconsistent, error, resumed,
empty_events, runtime_s, wall_s}, "logs": [records]}``. ``fleet.txt`` is the same as text.
Both are written atomically; ``--force`` or ``--resume`` replace only earlier ones of ivslam.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ivslam_cli.errors import IvslamError
from ivslam_cli.report.strict_json import strict

FORMAT = "ivslam-fleet"
VERSION = 1
JSON_NAME = "fleet.json"
TEXT_NAME = "fleet.txt"
TEXT_HEADER = "# ivslam fleet audit"
MAX_EVENTS = 100  # empty events listed per log (all are counted)
STATUSES = ("ok", "inconsistent", "error")
_STATS = ("nodes", "landmarks", "observations", "observations_rejected", "sweeps", "converged", "pairs",
          "intersections", "scans", "scans_used", "scans_mapped", "submaps")


def _num(x: Any) -> float | None:
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _base(job, wall_s: float) -> dict[str, Any]:
    return {"log": job.label or job.log, "path": job.log, "result": None, "mode": job.opts.mode,
            "robot": job.opts.robot, "status": "error", "message": None, "exit_code": None, "resumed": False,
            "empty_events": 0, "empty_event_list": [], "stopped": None, "containment": {}, "sound": None,
            "final_width": {}, "scans": None, "stats": {}, "summary": None, "runtime_s": None,
            "wall_s": float(wall_s), "cpu_s": None}


def error_record(job, message: str, exit_code: int, wall_s: float) -> dict[str, Any]:
    """The record of a log that failed: its one-line error."""
    rec = _base(job, wall_s)
    label = job.label or job.log
    if label != job.log:  # the log as the user named it, not its absolute path
        message = message.replace(job.log, label)
    if label not in message:
        message = f"{label}: {message}"
    rec.update(message=message, exit_code=int(exit_code))
    return rec


def result_record(job, result, path: Path, wall_s: float, *, resumed: bool = False) -> dict[str, Any]:
    """The record of a log whose result is ``result`` (written to ``path``)."""
    from ivslam_cli.report.core import compute_report, event_dicts
    from ivslam_cli.slam import summary

    rep = compute_report(result)
    events = event_dicts(result)
    stopped = result.consistency.stopped or None
    rec = _base(job, wall_s)
    st = result.stats
    rec.update(
        result=Path(path).name, mode=result.mode, status="inconsistent" if events or stopped else "ok",
        message=f"stopped (--strict): {stopped}" if stopped else None,
        exit_code=3 if stopped else 0, resumed=resumed,
        empty_events=len(events), empty_event_list=events[:MAX_EVENTS], stopped=stopped,
        containment={k: _num(v.fraction) for k, v in rep.containment.items()}, sound=bool(rep.sound),
        final_width={k: {"median": _num(v.median), "max": _num(v.max)} for k, v in rep.final_width.items()},
        scans=({k: int(st[k]) for k in ("scans", "scans_used", "scans_mapped") if k in st}
               if "scans_mapped" in st else None),
        stats={k: (v if isinstance(v, bool) else _num(v)) for k, v in st.items() if k in _STATS},
        summary=summary(result), runtime_s=_num(result.runtime_s),
    )
    return rec


def resumed_record(job, path: Path) -> dict[str, Any]:
    """The record of a log skipped by ``--resume``, from the result already there."""
    from ivslam_cli.results.hdf5 import read_result

    try:
        result = read_result(path)
    except IvslamError as exc:
        rec = error_record(job, str(exc), exc.exit_code, 0.0)
        rec["resumed"] = True
        return rec
    return result_record(job, result, path, 0.0, resumed=True)


def totals(records: list[dict[str, Any]]) -> dict[str, Any]:
    count = {s: sum(r["status"] == s for r in records) for s in STATUSES}
    return {"logs": len(records), **count, "resumed": sum(bool(r["resumed"]) for r in records),
            "empty_events": sum(int(r["empty_events"]) for r in records),
            "runtime_s": sum(r["runtime_s"] or 0.0 for r in records if not r["resumed"]),
            "wall_s": sum(r["wall_s"] or 0.0 for r in records if not r["resumed"])}


def fleet_doc(records: list[dict[str, Any]], *, output_dir: Path, command: str, executor: str, jobs: int,
              wall_s: float) -> dict[str, Any]:
    return {"format": FORMAT, "version": VERSION, "output_dir": str(output_dir), "command": command,
            "executor": executor, "jobs": jobs, "wall_s": float(wall_s), "totals": totals(records),
            "logs": records}


def render_json(doc: dict[str, Any]) -> str:
    return json.dumps(strict(doc), indent=2, allow_nan=False) + "\n"


def _fmt(x: float | None, spec: str = ".3g") -> str:
    return "-" if x is None else format(x, spec)


def render_text(doc: dict[str, Any]) -> str:
    """The audit as text: the totals, then one block per log."""
    t = doc["totals"]
    resumed = f", {t['resumed']} resumed" if t["resumed"] else ""
    at_once = f", {doc['jobs']} at once" if doc.get("jobs") else ""
    totals_line = (f"{t['logs']} log(s): {t['ok']} ok, {t['inconsistent']} proven inconsistent, {t['error']} "
                   f"failed{resumed}; {t['empty_events']} empty event(s); pipelines {t['runtime_s']:.2f} s, jobs "
                   f"{t['wall_s']:.2f} s, batch {doc['wall_s']:.2f} s ({doc['executor']}{at_once})")
    lines = [f"{TEXT_HEADER}: {doc['output_dir']}", totals_line, ""]
    for r in doc["logs"]:
        robot = f" robot {r['robot']}" if r.get("robot") is not None else ""
        head = f"{r['log']}{robot} [{r['mode']}]: {r['status'].upper() if r['status'] != 'ok' else 'ok'}"
        if r["resumed"]:
            head += " (resumed: result already there)"
        lines.append(head)
        if r["status"] == "error":
            lines.append(f"  error: {r['message']}")
            lines.append("")
            continue
        lines.append(f"  -> {r['result']}; {r['summary']}")
        if r["message"]:
            lines.append(f"  {r['message']}")
        if r["containment"]:
            parts = ", ".join(f"{k} {_fmt(v, '.4g')}" for k, v in r["containment"].items())
            lines.append(f"  containment: {parts}{'' if r['sound'] else '  SOUNDNESS FAILURE'}")
        if r["final_width"]:
            parts = ", ".join(f"{k} median {_fmt(v['median'])} max {_fmt(v['max'])}"
                              for k, v in r["final_width"].items())
            lines.append(f"  final widths [m]: {parts}")
        if r["scans"]:
            s = r["scans"]
            lines.append(f"  scans: {s.get('scans_mapped')} mapped, {s.get('scans_used')} used of {s.get('scans')}")
        lines.append(f"  runtime: pipeline {_fmt(r['runtime_s'], '.2f')} s, job {_fmt(r['wall_s'], '.2f')} s")
        if r["empty_events"]:
            lines.append(f"  empty events: {r['empty_events']}")
            for e in r["empty_event_list"]:
                lines.append(f"    t={e['stamp']:.3f} s step {e['step']} {e['constraint']} "
                             f"measurement {e['measurement']}: {e['text']}")
            if r["empty_events"] > len(r["empty_event_list"]):
                lines.append(f"    ... {r['empty_events'] - len(r['empty_event_list'])} more")
        lines.append("")
    return "\n".join(lines).rstrip("\n") + "\n"


def write_audit(doc: dict[str, Any], out_dir: Path, *, replace: bool) -> tuple[Path, Path]:
    """``fleet.json`` and ``fleet.txt`` in ``out_dir``, atomically and together."""
    from ivslam_cli.atomic import transaction, write_text_atomic

    jpath, tpath = out_dir / JSON_NAME, out_dir / TEXT_NAME
    with transaction(force=replace):
        write_text_atomic(jpath, render_json(doc), force=replace, kind="fleet")
        write_text_atomic(tpath, render_text(doc), force=replace, kind="fleet")
    return jpath, tpath


def read_audit(path: Path) -> dict[str, Any]:
    """The fleet audit of a directory (``DIR/fleet.json``), checked; one-line errors."""
    path = Path(path)
    jpath = path / JSON_NAME if path.is_dir() else path
    if not jpath.is_file():
        raise IvslamError(f"is a directory without {JSON_NAME}: not a batch output directory "
                          "(`ivslam run LOG... -o DIR` writes one)", path)
    try:
        doc = json.loads(jpath.read_text(encoding="utf-8"))
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise IvslamError(f"cannot read the fleet audit ({type(exc).__name__}: {exc})", jpath) from None
    if not isinstance(doc, dict) or doc.get("format") != FORMAT or not isinstance(doc.get("logs"), list):
        raise IvslamError("is not an ivslam fleet audit", jpath)
    if doc.get("version") != VERSION:
        raise IvslamError(f"fleet audit version {doc.get('version')!r} is not supported (this ivslam reads "
                          f"{VERSION})", jpath)
    return doc
