"""``ivslam report DIR``: the fleet audit of a batch, as text, JSON, or per-log bars."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ivslam_cli.errors import IvslamError
from ivslam_cli.fleet.audit import read_audit, render_json, render_text

#: the width drawn per log: the first of these kinds its result has
WIDTH_KINDS = ("pose", "landmark", "pair")


def main_width(rec: dict[str, Any]) -> tuple[str | None, float | None]:
    """(kind, final median width) of the kind :data:`WIDTH_KINDS` puts first."""
    for kind in WIDTH_KINDS:
        w = (rec.get("final_width") or {}).get(kind)
        if w is not None:
            return kind, w.get("median")
    return None, None


def plot_fleet(doc: dict[str, Any], path: Path, *, force: bool = False) -> None:
    """Per-log bars: final median width, empty events, runtime (failed logs hatched, at 0)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ivslam_cli.report.plot import FORMATS, _save

    fmt = FORMATS.get(Path(path).suffix.lower())
    if fmt is None:
        raise IvslamError(f"unknown plot format (use {' or '.join(FORMATS)})", path)
    logs = doc["logs"]
    labels = [Path(str(r["log"])).name + (f" r{r['robot']}" if r.get("robot") is not None else "") for r in logs]
    colour = {"ok": "tab:green", "inconsistent": "tab:orange", "error": "tab:red"}
    colours = [colour.get(r["status"], "grey") for r in logs]
    widths = [main_width(r) for r in logs]
    panels = [
        ("final median width [m] (" + ", ".join(sorted({k for k, _ in widths if k})) + ")",
         [w or 0.0 for _, w in widths]),
        ("empty events", [r["empty_events"] or 0 for r in logs]),
        ("runtime [s] (pipeline)", [r["runtime_s"] or 0.0 for r in logs]),
    ]
    n = max(1, len(logs))
    fig, axes = plt.subplots(1, 3, figsize=(13, 1.2 + 0.35 * n), sharey=True, constrained_layout=True)
    y = range(len(logs))
    for ax, (title, values) in zip(axes, panels):
        bars = ax.barh(list(y), values, color=colours)
        for bar, r in zip(bars, logs):
            if r["status"] == "error":
                bar.set_hatch("//")
        ax.set_title(title, fontsize="small")
        ax.grid(axis="x", alpha=0.3)
    axes[0].set_yticks(list(y), labels, fontsize="small")
    axes[0].invert_yaxis()
    t = doc["totals"]
    fig.suptitle(f"ivslam fleet audit: {t['logs']} logs, {t['ok']} ok (green), {t['inconsistent']} proven "
                 f"inconsistent (orange), {t['error']} failed (red)", fontsize="medium")
    try:
        _save(fig, Path(path), fmt, force)
    finally:
        plt.close(fig)


def report_fleet(directory: Path, *, as_json: bool, plot: Path | None, force: bool) -> str:
    """The text (or JSON) to print for the batch directory ``directory``; draws ``plot``."""
    from ivslam_cli.atomic import refuse_existing, transaction

    with transaction(force=force, inputs=[directory / "fleet.json"]):
        if plot is not None:
            refuse_existing(plot, force, kind="plot")
        doc = read_audit(directory)
        if plot is not None:
            plot_fleet(doc, plot, force=force)
    return render_json(doc) if as_json else render_text(doc)
