"""``ivslam report --plot FILE.png|.svg``: the map with the truth, and widths over time.

matplotlib is imported lazily (only here, only when plotting) with the Agg backend, so the
CLI never needs a display. Left panel, in world coordinates: the map grid (if any), the
pose tube (x, y of the pose boxes), pair subpavings drawn where they place landmark i given
landmark j (dl(i,j) + position of j: its truth when known, else its box centre; inner boxes
darker), landmark boxes, and the truth (landmarks as crosses, trajectory as a line). Right
panel: width-over-time curves per kind (median and max per step bin). A lidar result with the
log-odds baseline gets it beside the map, on the same axes, with the cells where the two
disagree in colour (``slam.lidar.logodds.compare``), and the widths below.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ivslam_cli.errors import IvslamError
from ivslam_cli.report.core import Report, box_centre, truth_in_frame
from ivslam_cli.atomic import atomic_path
from ivslam_cli.results.model import CELL_EMPTY, CELL_OBSTACLE, LABEL_INNER, box_is_empty

FORMATS = {".png": "png", ".svg": "svg"}
MAX_BOXES = 20_000  # per layer; beyond, an even subsample is drawn (said in the legend)


def _rects(ax, boxes: np.ndarray, **style) -> int:
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Rectangle

    finite = np.isfinite(boxes).all(axis=tuple(range(1, boxes.ndim))) if boxes.ndim > 1 else np.isfinite(boxes)
    boxes = boxes[~box_is_empty(boxes) & finite]
    if boxes.shape[0] > MAX_BOXES:
        boxes = boxes[np.linspace(0, boxes.shape[0] - 1, MAX_BOXES).astype(int)]
    patches = [Rectangle((b[0, 0], b[1, 0]), b[0, 1] - b[0, 0], b[1, 1] - b[1, 0]) for b in boxes]
    if patches:
        ax.add_collection(PatchCollection(patches, **style))
    return len(patches)


def _draw_map(ax, rep: Report) -> None:
    r = rep.result
    t = truth_in_frame(r.poses, r.truth) if r.truth is not None and r.poses is not None else r.truth
    g = r.main_map
    if g is not None and g.state.size:
        img = np.full(g.state.shape + (4,), 0.0)
        img[g.state == CELL_EMPTY] = (1.0, 1.0, 1.0, 1.0)
        img[g.state == CELL_OBSTACLE] = (0.0, 0.0, 0.0, 1.0)
        img[(g.state != CELL_EMPTY) & (g.state != CELL_OBSTACLE)] = (0.75, 0.75, 0.75, 1.0)
        ax.imshow(img, origin="lower", interpolation="nearest", extent=_grid_extent(g))
    if r.loops is not None and r.submaps is not None and len(r.submaps):
        _draw_anchor_graph(ax, r.submaps.anchor_box, r.loops)
    if r.poses is not None and len(r.poses):
        _rects(ax, r.poses.box[:, :2], facecolor="tab:blue", alpha=0.15, edgecolor="tab:blue", linewidth=0.3)
        c = box_centre(r.poses.box[:, :2])
        ax.plot(c[:, 0], c[:, 1], color="tab:blue", lw=0.8, label="pose box centres")
    known: dict[int, np.ndarray] = {}
    if t is not None and t.landmark_id is not None and t.landmark_xy is not None:
        known = {int(i): np.asarray(xy, float) for i, xy in zip(t.landmark_id, t.landmark_xy)}
    offset = np.zeros(2)
    if r.landmarks is not None and r.landmarks.reference_id is not None:
        offset = known.get(r.landmarks.reference_id, np.zeros(2))  # draw a relative map at its reference
    centres = {}
    if r.landmarks is not None:
        centres = {int(i): box_centre(b) + offset for i, b in zip(r.landmarks.id, r.landmarks.box)}
    if r.pairs is not None and len(r.pairs):
        shifted, inner = [], []
        for p in range(len(r.pairs)):
            j = int(r.pairs.j[p])
            at = known.get(j, centres.get(j))
            if at is None or np.any(np.isnan(at)):
                continue
            b = r.pairs.pair_boxes(p) + at[:, None]
            shifted.append(b)
            inner.append(r.pairs.label[r.pairs.offsets[p] : r.pairs.offsets[p + 1]] == LABEL_INNER)
        if shifted:
            b, m = np.concatenate(shifted), np.concatenate(inner)
            _rects(ax, b[~m], facecolor="gold", alpha=0.5, edgecolor="none")
            _rects(ax, b[m], facecolor="darkorange", alpha=0.8, edgecolor="none")
            ax.plot([], [], "s", color="gold", label="pair subpavings (boundary / inner), placed at m_j")
    if r.landmarks is not None and len(r.landmarks):
        box = r.landmarks.box + offset[:, None]
        _rects(ax, box, facecolor="none", edgecolor="tab:green", linewidth=1.0)
        ax.plot([], [], "s", mfc="none", color="tab:green", label="landmark boxes")
    if t is not None:
        if t.pose is not None and len(t.pose):
            ax.plot(t.pose[:, 0], t.pose[:, 1], color="tab:red", lw=0.8, ls="--", label="true trajectory")
        if known:
            xy = np.array(list(known.values()))
            ax.plot(xy[:, 0], xy[:, 1], "x", color="tab:red", label="true landmarks")
        if t.world is not None and len(t.world):
            for x0, y0, x1, y1 in t.world:
                ax.plot([x0, x1], [y0, y1], color="tab:red", lw=0.6)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    what = ""
    if g is not None and g is r.global_map:
        what = " (global map: proven in this frame)"
    elif g is not None and g.frame == "mosaic":
        what = " (mosaic of the submaps: display only)"
    ax.set_title(f"{r.mode}: enclosures and truth{what}")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="x-small", loc="best")


def _draw_anchor_graph(ax, anchor_box: np.ndarray, loops) -> None:
    """The anchor graph: anchors at their box centres, chain edges grey, loop edges orange."""
    from matplotlib.collections import LineCollection

    c = box_centre(anchor_box[:, :2])
    for kind, colour, label in ((0, "0.45", "anchor graph: chain edges"), (1, "tab:orange", "loop edges")):
        sel = loops.edge_kind == kind
        segs = np.stack([c[loops.edge_a[sel]], c[loops.edge_b[sel]]], axis=1)
        segs = segs[np.isfinite(segs).all(axis=(1, 2))]
        if segs.shape[0]:
            ax.add_collection(LineCollection(segs, colors=colour, linewidths=0.9 if kind else 0.6, zorder=3,
                                             label=f"{label} ({segs.shape[0]})"))
    ok = np.isfinite(c).all(axis=1)
    ax.plot(c[ok, 0], c[ok, 1], ".", color="0.2", ms=3, zorder=4, label="anchors (box centres)")


# disagreement code -> colour, legend (see slam.lidar.logodds.compare). (a) and the occupied
# unknown cells are few and small: drawn as markers (on both panels) so that they show at any
# scale; (c) is a tint of the log-odds image (the outer obstacle set's margin).
DIS_MARKED = (
    (1, "red", "(a) proven free, log-odds occupied"),
    (2, "darkorange", "log-odds occupied in interval unknown ((b) = (a) + these)"),
)
DIS_TINT = (3, (0.55, 0.75, 1.0, 1.0), "(c) interval obstacle, log-odds free")


def _grid_extent(g) -> tuple[float, float, float, float]:
    h, w = g.shape
    return (g.origin[0], g.origin[0] + w * g.resolution, g.origin[1], g.origin[1] + h * g.resolution)


def _mark_disagreement(ax, rep: Report, legend: bool) -> list:
    """Markers at the centres of the (a) and occupied-unknown cells; their legend handles."""
    from matplotlib.lines import Line2D

    g, code = rep.result.grid, rep.disagreement_code
    handles = []
    for c, colour, text in DIS_MARKED:
        rc = np.argwhere(code == c)
        if rc.size:
            x = g.origin[0] + (rc[:, 1] + 0.5) * g.resolution
            y = g.origin[1] + (rc[:, 0] + 0.5) * g.resolution
            ax.plot(x, y, "o", ms=3, mfc="none", mec=colour, mew=0.8, zorder=5,
                    label=None if legend else f"{text} (log-odds baseline)")
        handles.append(Line2D([], [], ls="none", marker="o", mfc="none", mec=colour,
                              label=f"{text}: {int(rc.shape[0])} cells" if legend else text))
    return handles


def _draw_logodds(ax, rep: Report) -> None:
    """The log-odds map (grey: 1 − p; never-updated cells in the interval map's unknown grey)
    with the cells where it disagrees with the interval map in colour."""
    from matplotlib.patches import Patch

    r = rep.result
    g, v = r.grid, r.logodds.value.astype(np.float64)
    grey = 1.0 / (1.0 + np.exp(np.clip(v, -50.0, 50.0)))  # 1 − p
    grey[v == 0] = 0.75
    img = np.repeat(grey[..., None], 4, axis=-1)
    img[..., 3] = 1.0
    handles = []
    if rep.disagreement_code is not None:
        c, colour, text = DIS_TINT
        m = rep.disagreement_code == c
        img[m] = colour
        handles = _mark_disagreement(ax, rep, legend=True)
        handles.append(Patch(color=colour, label=f"{text}: {int(m.sum())} cells"))
    ax.imshow(img, origin="lower", interpolation="nearest", extent=_grid_extent(g))
    ax.set_aspect("equal", adjustable="box")  # its limits are the map panel's
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("log-odds at the pose-box centres (NOT guaranteed)\nwhere it disagrees with the interval map")
    if handles:
        ax.legend(handles=handles, fontsize="x-small", loc="best")


def _draw_widths(ax, rep: Report) -> None:
    drawn = False
    for kind, cv in rep.convergence.items():
        if cv.curve_step.size:
            line = ax.plot(cv.curve_step, cv.curve_median, label=f"{kind} median")[0]
            ax.plot(cv.curve_step, cv.curve_max, ls=":", color=line.get_color(), label=f"{kind} max")
            drawn = True
    if drawn:
        if all(np.all(cv.curve_max[~np.isnan(cv.curve_max)] > 0) for cv in rep.convergence.values()):
            ax.set_yscale("log")
        ax.legend(fontsize="x-small")
    else:
        ax.text(0.5, 0.5, "no width history", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("step")
    ax.set_ylabel("width [m]")
    ax.set_title("widths over time")


def plot_report(rep: Report, path: str | Path, *, force: bool = False) -> None:
    """Write the figure to ``path`` (format from the suffix: .png or .svg), atomically."""
    path = Path(path)
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise IvslamError(f"unsupported plot format {path.suffix or '(none)'!r}: use .png or .svg", path)
    try:
        import matplotlib
    except ImportError:  # pragma: no cover - optional extra
        raise IvslamError("plotting needs matplotlib (pip install 'ivslam[plot]')", path) from None
    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    r = rep.result
    if r.logodds is not None and r.grid is not None and r.grid.state.size:
        # the interval map and the log-odds map side by side (same axes), widths below
        fig = Figure(figsize=(13, 11), layout="constrained")
        axes = fig.subplot_mosaic([["map", "logodds"], ["widths", "widths"]], height_ratios=(1.6, 1))
        if rep.disagreement_code is not None:
            _mark_disagreement(axes["map"], rep, legend=False)
        _draw_map(axes["map"], rep)
        _draw_logodds(axes["logodds"], rep)
        axes["logodds"].set_xlim(axes["map"].get_xlim())  # the same window of the world
        axes["logodds"].set_ylim(axes["map"].get_ylim())
        _draw_widths(axes["widths"], rep)
    else:
        fig = Figure(figsize=(12, 5.5), layout="constrained")
        ax_map, ax_w = fig.subplots(1, 2, width_ratios=(1.3, 1))
        _draw_map(ax_map, rep)
        _draw_widths(ax_w, rep)
    _save(fig, path, fmt, force)


def plot_submap(rep: Report, m: int, path: str | Path, *, force: bool = False) -> None:
    """Submap ``m`` in its anchor's frame (its proven map, its scans' relative boxes and, with a
    truth, their true poses relative to the anchor's) beside the mosaic of all submaps."""
    path = Path(path)
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise IvslamError(f"unsupported plot format {path.suffix or '(none)'!r}: use .png or .svg", path)
    r = rep.result
    sm = r.submaps
    if sm is None:
        raise IvslamError("has no submaps (only LiDAR runs with dead reckoning have): --submap does not apply",
                          r.provenance.input_path)
    if not 0 <= m < len(sm):
        raise IvslamError(f"--submap {m}: the result has submaps 0..{len(sm) - 1}", path)
    try:
        import matplotlib
    except ImportError:  # pragma: no cover - optional extra
        raise IvslamError("plotting needs matplotlib (pip install 'ivslam[plot]')", path) from None
    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    from ivslam_cli.report.core import relative_pose, truth_at

    fig = Figure(figsize=(13, 6), layout="constrained")
    ax, ax_m = fig.subplots(1, 2)
    g = sm.grid(m)
    img = np.full(g.state.shape + (4,), 0.0)
    img[g.state == CELL_EMPTY] = (1.0, 1.0, 1.0, 1.0)
    img[g.state == CELL_OBSTACLE] = (0.0, 0.0, 0.0, 1.0)
    img[(g.state != CELL_EMPTY) & (g.state != CELL_OBSTACLE)] = (0.75, 0.75, 0.75, 1.0)
    if g.state.size:
        ax.imshow(img, origin="lower", interpolation="nearest", extent=_grid_extent(g))
    rows, boxes, _ = sm.members(m)
    _rects(ax, boxes[:, :2], facecolor="tab:blue", alpha=0.2, edgecolor="tab:blue", linewidth=0.3)
    c = box_centre(boxes[:, :2])
    ax.plot(c[:, 0], c[:, 1], color="tab:blue", lw=0.8, label="relative box centres")
    t = r.truth
    if t is not None and t.pose is not None and t.pose_stamp is not None:
        ta = truth_at(t, r.poses.stamp[np.repeat(sm.anchor[m], rows.size)])
        tb = truth_at(t, r.poses.stamp[rows])
        ok = np.all(np.isfinite(ta), axis=1) & np.all(np.isfinite(tb), axis=1)
        if ok.any():
            rel = relative_pose(ta[ok], tb[ok])
            ax.plot(rel[:, 0], rel[:, 1], color="tab:red", lw=0.8, ls="--", label="truth (relative to the anchor)")
    ax.set_aspect("equal")
    ax.set_title(f"submap {m} in its anchor's frame (proven: P_EMPTY white, P_OBSTACLE black)")
    ax.legend(fontsize="x-small")
    mo = r.grid
    if mo is not None and mo.state.size:
        img = np.full(mo.state.shape + (4,), 0.0)
        img[mo.state == CELL_EMPTY] = (1.0, 1.0, 1.0, 1.0)
        img[mo.state == CELL_OBSTACLE] = (0.0, 0.0, 0.0, 1.0)
        img[(mo.state != CELL_EMPTY) & (mo.state != CELL_OBSTACLE)] = (0.75, 0.75, 0.75, 1.0)
        ax_m.imshow(img, origin="lower", interpolation="nearest", extent=_grid_extent(mo))
    ac = box_centre(sm.anchor_box[:, :2])
    ax_m.plot(ac[:, 0], ac[:, 1], "o-", color="tab:orange", ms=2, lw=0.6, label="anchor box centres (the chain)")
    ax_m.plot([ac[m, 0]], [ac[m, 1]], "o", color="tab:red", ms=6, label=f"anchor of submap {m}")
    ax_m.set_aspect("equal")
    ax_m.set_title("mosaic of the submaps at their anchors' box centres (display only)")
    ax_m.legend(fontsize="x-small")
    _save(fig, path, fmt, force)


def _save(fig, path: Path, fmt: str, force: bool) -> None:
    from ivslam_cli import __version__

    # the ivslam marker lets a later --force replace this plot (and nothing that is not ours)
    marker = {"png": {"Software": f"ivslam {__version__} (matplotlib)"},
              "svg": {"Creator": f"ivslam {__version__} (matplotlib)"}}[fmt]
    with atomic_path(path, force=force, kind="plot") as tmp:
        fig.savefig(tmp, format=fmt, dpi=120, metadata=marker)
