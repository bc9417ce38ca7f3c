"""``ivslam report``'s default output: the report as plain text for a terminal."""

from __future__ import annotations

import math

import numpy as np

from ivslam_cli.results.model import CELL_EMPTY, GRID_MOSAIC

from ivslam_cli.report.core import FAILURE, MAX_TRUTH_GAP, SOUND, Report, WidthStat, event_dicts

MAX_LISTED = 20  # failures listed per kind (all empty events are always listed)


def _g(x: float) -> str:
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.4g}"


def _ws(w: WidthStat) -> str:
    s = f"median {_g(w.median)}, max {_g(w.max)}"
    return s + (f" ({w.empty} empty)" if w.empty else "")


def _value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return "unset" if v is None else str(v)


def _entity(constraint: str, entity: list[int]) -> str:
    a, b = entity
    if b >= 0:
        return f"pair ({a},{b})"
    return f"{'pose' if 'motion' in constraint or 'pose' in constraint else 'entity'} {a}"


REJECTED_SHOWN = 20  # rejected measurements listed in the text report


def render_text(rep: Report, source: str = "") -> str:
    r = rep.result
    p = r.provenance
    c = r.consistency
    out: list[str] = []
    add = out.append
    add(f"ivslam report{': ' + source if source else ''}")
    add(f"run:        mode {r.mode}, ivslam {p.ivslam_version}, {r.runtime_s:.3g} s")
    if p.command:
        add(f"command:    {p.command}")
    add(f"input:      {p.input_path} ({p.input_format}, sha256 {p.input_sha256[:16]}…)")
    if p.topics:
        add("topics:     " + ", ".join(f"{k}={v}" for k, v in sorted(p.topics.items())))
    for d in p.dropped:
        add(f"dropped:    {d.stream}: {d.count} ({d.reason})")
    for section, values in p.config.items():
        if isinstance(values, dict) and values:
            add(f"[{section}]".ljust(12) + " ".join(f"{k}={_value(v)}" for k, v in values.items()))
    add("q used:     " + (", ".join(f"{k}={v}" for k, v in c.q.items()) or "none (plain intersection)"))
    if c.assumption:
        add(f"guarantee:  {c.assumption}")

    add("")
    add(f"consistency: {rep.intersections} set updates, {rep.non_empty} stayed non-empty; "
        f"{rep.empty_events} empty event{'s' if rep.empty_events != 1 else ''}")
    for e in event_dicts(r):
        meas = f" measurement {e['measurement']}" if e["measurement"] >= 0 else ""
        add(f"  EMPTY step {e['step']} t={e['stamp']:.6g} {e['constraint']} {_entity(e['constraint'], e['entity'])}"
            f"{meas}: {e['text']}")
    if len(c.rejected):
        add(f"  rejected {len(c.rejected)} measurement(s): "
            + "; ".join(f"{why} ×{n}" for why, n in sorted(rep.rejected_by_reason.items())))
        shown = min(len(c.rejected), REJECTED_SHOWN)
        for i in range(shown):
            add(f"    {c.rejected.stream[i]}[{int(c.rejected.index[i])}]: {c.rejected.reason[i]}")
        if len(c.rejected) > shown:
            add(f"    … {len(c.rejected) - shown} more (all in --json and in the result's consistency/rejected)")
    if c.stopped:
        add(f"  STOPPED EARLY: {c.stopped}")

    if rep.convergence:
        add("")
        add("convergence (widths, initial → final per entity):")
        for kind, cv in rep.convergence.items():
            add(f"  {kind:<9} {cv.entities} entities, {cv.updates} updates: initial {_ws(cv.initial)} → "
                f"final {_ws(cv.final)}; widened {cv.increases} time(s)")
            if cv.curve_median.size:
                at = np.unique(np.round(np.linspace(0, cv.curve_median.size - 1, 5)).astype(int))
                pts = ", ".join(f"step {cv.curve_step[i]:.0f}: {_g(cv.curve_median[i])}" for i in at)
                add(f"            median curve: {pts}")
            if cv.definition:
                add(f"            width = {cv.definition}")
    if rep.final_width:
        add("final widths:")
        pad = max(13, *(len(k) + 1 for k in rep.final_width))
        for kind, w in rep.final_width.items():
            add(f"  {kind:<{pad}}{w.count} enclosures: {_ws(w)}")
    if r.relative is not None:
        wr = (r.relative.box[..., 1] - r.relative.box[..., 0]).reshape(-1, 3)
        med = np.median(wr, axis=0) if wr.size else np.full(3, np.nan)
        add(f"  relative     {len(r.relative)} enclosures (a pose in the frame of a keyframe's): median x "
            f"{_g(float(med[0]))}, y {_g(float(med[1]))} m, θ {_g(float(med[2]))} rad")

    add("")
    if not rep.containment:
        add("containment: no ground truth to check against")
    else:
        add("containment against ground truth:")
        for kind, cn in rep.containment.items():
            status = rep.soundness[kind]
            err = cn.centre_error[~np.isnan(cn.centre_error)] if cn.centre_error.size else cn.centre_error
            e = f"; centre error median {_g(float(np.median(err)))}, max {_g(float(np.max(err)))} m" if err.size else ""
            skip = f" ({cn.not_checked} not checked)" if cn.not_checked else ""
            add(f"  {kind:<9} {cn.contained}/{cn.checked} = {cn.fraction:.4f}  "
                f"{'ok' if status == SOUND else status}{skip}{e}")
            for f in cn.failures[:MAX_LISTED]:
                add(f"            truth outside: {f}")
            if len(cn.failures) > MAX_LISTED:
                add(f"            … and {len(cn.failures) - MAX_LISTED} more")
        for rid, cn in rep.robot_containment.items():
            add(f"    robot {rid}: poses {cn.contained}/{cn.checked} = {cn.fraction:.4f}")
        if "pose" in rep.containment:
            add("  (poses: each box against the truth at its stamp, or the hull of the two truth samples")
            add(f"   around it; not checked: outside the truth's span or in a gap > {MAX_TRUTH_GAP:g} s)")
        if rep.outliers_injected:
            parts = [f"{k} {n}: " + ("q-relaxed" if rep.outliers_relaxed[k] else "beyond the stated bounds, no q covers them")
                     for k, n in rep.outliers_by_stream.items()]
            add(f"  outliers injected: {rep.outliers_injected} ({'; '.join(parts)})")
        if any(v == FAILURE for v in rep.soundness.values()):
            add("SOUNDNESS FAILURE: an enclosure lost the truth although the stated bounds should hold")

    if r.submaps is not None:
        sm, st = r.submaps, r.stats
        free = [int(np.count_nonzero(sm.grid(m).state == CELL_EMPTY)) for m in range(len(sm))]
        members = np.diff(sm.member_offsets)
        add("")
        add(f"submaps:    {len(sm)} local frames (each the robot pose at its anchor scan; P_EMPTY proven in that "
            f"frame given its scans' relative boxes), {int(np.median(members)) if len(sm) else 0} scans each (median)")
        lo_free = int(st.get("logodds_free_cells", 0))
        ratio = f" = {sum(free) / lo_free:.3g}× the log-odds free cells on the same scans ({lo_free})" if lo_free else ""
        add(f"            proven free: {sum(free)} cells = {sum(free) * sm.resolution ** 2:.4g} m² in all (median "
            f"{_g(float(np.median(free))) if free else 0} per submap){ratio}")
        if st.get("pose_set_cells", 0):
            add(f"            of them first proven by the scans' pose sets beyond their hulls (lidar.map_sets): "
                f"{int(st['pose_set_cells'])}")
        if "mapped_fraction" in st:
            add(f"            scans mapped: {st.get('scans_mapped', 0)}/{st.get('scans_used', 0)} "
                f"({100.0 * float(st['mapped_fraction']):.4g} %)")
    if r.loops is not None:
        lp, st = r.loops, r.stats
        ok = ~lp.empty
        add("")
        if not ok.any():
            add(f"loops:      no loop found ({len(lp)} searches with no pose agreeing: {int(lp.empty.sum())}); "
                "the global boxes are the chain of anchors met with dead reckoning, local guarantees unchanged")
        else:
            from ivslam_cli.interval.pose import position_width

            wb = position_width(lp.box[ok])
            add(f"loops:      {int(ok.sum())} loop constraints (scans matched against older submaps: "
                f"{len(set(lp.submap[ok].tolist()))} submaps), {int(lp.empty.sum())} empty (contradictions, not used); "
                f"loop box median {_g(float(np.median(wb)))} m / "
                f"{_g(float(np.median(lp.box[ok, 2, 1] - lp.box[ok, 2, 0])))} rad")
        if "median_open_loop_width" in st:
            add(f"            global box median {_g(float(st['median_pose_width']))} m after closure, "
                f"{_g(float(st['median_open_loop_width']))} m from the chain of anchors alone; anchor graph: "
                f"{len(lp.edge_a)} edges, {int(lp.sweeps)} sweeps")
    if r.global_map is not None:
        g, st = r.global_map, r.stats
        free = int(np.count_nonzero(g.state == CELL_EMPTY))
        lo_free = int(st.get("global_logodds_free_cells", 0))
        local = int(st.get("empty_cells", 0))
        ratio = f" = {free / lo_free:.3g}× the log-odds free cells on the same scans ({lo_free})" if lo_free else ""
        add(f"global map: every scan with a global box ≤ lidar.max_pose_width mapped in the result's frame "
            f"({st.get('global_scans_mapped', '?')} scans; P_EMPTY proven in that frame), {g.shape[1]}×{g.shape[0]} "
            f"cells of {g.resolution:g} m")
        add(f"            proven free: {free} cells = {free * g.resolution ** 2:.4g} m²{ratio}; "
            f"the submaps, each in its frame: {local} cells")
    if r.grid is not None:
        g = r.grid
        add("")
        what = ("mosaic:     the submaps placed at their anchors' box centres, FOR DISPLAY ONLY (the guarantees "
                "are per submap and per pose box); " if g.frame == GRID_MOSAIC else "map grid:   ")
        add(f"{what}{g.shape[1]}×{g.shape[0]} cells of {g.resolution:g} m at origin "
            f"({g.origin[0]:g}, {g.origin[1]:g})")
        add("            " + ", ".join(f"{k} {rep.map_cells[k]} cells = {rep.map_area_m2[k]:.4g} m²" for k in rep.map_cells))
        if "explored" in rep.map_cells:
            add("            (explored: cells proven free or in some beam's P_OBSTACLE^k / P_OLD^k; the map's obstacle "
                "state is (∪ P_OBSTACLE^k) ∩ (∪ P_OLD^k))")
        b = rep.map_beams
        if b:
            add(f"beams:      {b.get('scans_mapped', 0)} of {b.get('scans', 0)} scans mapped, {b.get('beams', 0)} beams, "
                f"{b.get('valid_mapped', 0)} valid in mapped scans: {b.get('old', 0)} old, {b.get('new', 0)} new "
                "(old: its P_OBSTACLE^{i,k} meets no unmeasured cell of the map before its scan)")
    if r.logodds is not None and rep.logodds_cells:
        lo, lc, d = r.logodds, rep.logodds_cells, rep.disagreement
        add(f"log-odds:   NOT guaranteed (probabilistic baseline): {lo.scans} scans at their pose-box centres, "
            f"{lo.beams} beams, l_occ {lo.l_occ:g}, l_free {lo.l_free:g}, clamp [{lo.l_min:g}, {lo.l_max:g}]; "
            f"occupied {lc['occupied']}, free {lc['free']}, unknown {lc['unknown']} cells")
        n_empty = rep.map_cells.get("empty", 0)
        share = f" = {100.0 * d['empty_occupied'] / n_empty:.3g} % of the proven-free cells" if n_empty else ""
        add(f"disagree:   (a) {d['empty_occupied']} proven-free cells log-odds calls occupied{share}; "
            f"(b) {d['occupied_outside_obstacle']} occupied cells outside the interval obstacle set "
            f"((a) + {d['unknown_occupied']} unknown); (c) {d['obstacle_free']} interval-obstacle cells "
            "log-odds calls free (the obstacle set is outer: a margin, not a contradiction)")
    return "\n".join(out) + "\n"
