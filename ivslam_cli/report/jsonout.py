"""``ivslam report --json``: the report as a JSON document (keys are a stable interface).

Top-level keys: ``mode``, ``runtime_s``, ``empty_events`` (int: how many), ``empty_event_list``
(each: stamp, step, constraint, entity, measurement, text), ``intersections`` (total,
non_empty), ``containment`` (kind → fraction, only kinds checkable against the truth),
``containment_detail`` (kind → checked, contained, not_checked, failures),
``robot_containment`` (a result of several robots: robot → checked, contained, fraction of its
poses; empty otherwise), ``soundness``
(kind → "ok" / "SOUNDNESS FAILURE" / relaxed or broken-bounds note), ``sound`` (bool), ``centre_error``
(kind → median, max [m]), ``final_width`` (kind → median, max, count, empty),
``convergence`` (kind → initial/final median and max, increases, curve), ``rejected``,
``q``, ``assumption``, ``stopped``, ``outliers_injected``, ``outliers_by_stream`` (stream →
``injected``, ``q_relaxed``: whether a q > 0 of the run covers that stream), ``input``, ``config``, ``map`` (lidar;
with ``map.logodds`` when the result has the log-odds baseline: ``guaranteed`` (false), ``scans``,
``beams``, ``model``, ``cells`` occupied/free/unknown and ``disagreement``: ``empty_occupied`` (a),
``unknown_occupied``, ``occupied_outside_obstacle`` (b = a + unknown_occupied), ``obstacle_free`` (c)),
``relative`` (when the result holds relative pose enclosures: ``count``, ``definition``, ``width``
x/y/theta median and max).
NaN becomes null, ±inf the strings "inf"/"-inf".
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np

from ivslam_cli.results.model import CELL_EMPTY, CELL_OBSTACLE

from ivslam_cli.report.core import Report, WidthStat, event_dicts
from ivslam_cli.report.strict_json import strict
from ivslam_cli.results.hdf5 import SCHEMA_VERSION


def _num(x: float) -> float | None:
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else float(x)


def _ws(w: WidthStat) -> dict[str, Any]:
    return {"median": _num(w.median), "max": _num(w.max), "count": w.count, "empty": w.empty}


def _arr(a: np.ndarray) -> list[float | None]:
    return [_num(float(x)) for x in a]


def report_dict(rep: Report) -> dict[str, Any]:
    r = rep.result
    p = r.provenance
    c = r.consistency
    out: dict[str, Any] = {
        "ivslam_result_version": SCHEMA_VERSION,
        "mode": r.mode,
        "runtime_s": float(r.runtime_s),
        "input": {"path": p.input_path, "format": p.input_format, "sha256": p.input_sha256, "topics": p.topics},
        "command": p.command,
        "ivslam_version": p.ivslam_version,
        "config": p.config,
        "q": dict(c.q),
        "assumption": c.assumption,
        "stopped": c.stopped,
        "empty_events": rep.empty_events,
        "empty_event_list": event_dicts(r),
        "intersections": {"total": rep.intersections, "non_empty": rep.non_empty},
        "rejected": {"count": len(c.rejected), "by_reason": rep.rejected_by_reason},
        "rejected_list": [{"stream": str(st), "index": int(i), "reason": str(why)}
                          for st, i, why in zip(c.rejected.stream, c.rejected.index, c.rejected.reason)],
        "outliers_injected": rep.outliers_injected,
        "outliers_by_stream": {k: {"injected": n, "q_relaxed": rep.outliers_relaxed[k]}
                               for k, n in rep.outliers_by_stream.items()},
        "containment": {k: _num(v.fraction) for k, v in rep.containment.items()},
        "containment_detail": {
            k: {"checked": v.checked, "contained": v.contained, "not_checked": v.not_checked, "failures": v.failures}
            for k, v in rep.containment.items()
        },
        "robot_containment": {str(k): {"checked": v.checked, "contained": v.contained, "fraction": _num(v.fraction)}
                              for k, v in rep.robot_containment.items()},
        "soundness": dict(rep.soundness),
        "sound": rep.sound,
        "centre_error": {
            k: {
                "median": _num(float(np.nanmedian(v.centre_error))) if np.any(~np.isnan(v.centre_error)) else None,
                "max": _num(float(np.nanmax(v.centre_error))) if np.any(~np.isnan(v.centre_error)) else None,
            }
            for k, v in rep.containment.items()
        },
        "final_width": {k: _ws(v) for k, v in rep.final_width.items()},
        "convergence": {
            k: {
                "definition": v.definition,
                "entities": v.entities,
                "updates": v.updates,
                "initial": _ws(v.initial),
                "final": _ws(v.final),
                "increases": v.increases,
                "curve": {"step": _arr(v.curve_step), "median": _arr(v.curve_median), "max": _arr(v.curve_max)},
            }
            for k, v in rep.convergence.items()
        },
        "dropped": [{"stream": d.stream, "count": d.count, "reason": d.reason} for d in p.dropped],
    }
    if r.relative is not None:
        wr = (r.relative.box[..., 1] - r.relative.box[..., 0]).reshape(-1, 3)
        out["relative"] = {"count": len(r.relative), "definition": r.relative.definition, "width": {
            k: {"median": float(np.median(wr[:, d])) if wr.size else None,
                "max": float(np.max(wr[:, d])) if wr.size else None}
            for d, k in enumerate(("x", "y", "theta"))}}
    if r.poses is not None:
        out["frame"] = {"poses": r.poses.frame, "origin_stamp": float(r.poses.origin_stamp)}
    if r.submaps is not None:
        sm, st = r.submaps, r.stats
        free = [int(np.count_nonzero(sm.grid(m).state == CELL_EMPTY)) for m in range(len(sm))]
        out["submaps"] = {
            "count": len(sm),
            "anchor_rows": [int(a) for a in sm.anchor],
            "members": [int(n) for n in np.diff(sm.member_offsets)],
            "proven_free_cells": free,
            "proven_free_cells_total": int(sum(free)),
            "proven_free_m2_total": float(sum(free) * sm.resolution ** 2),
            "logodds_free_cells_total": int(st.get("logodds_free_cells", 0)),
            "pose_set_cells": int(st.get("pose_set_cells", 0)),
            "mapped_fraction": float(st.get("mapped_fraction", float("nan"))),
        }
    if r.loops is not None:
        lp = r.loops
        ok = ~lp.empty
        out["loops"] = {
            "found": int(ok.sum()), "empty": int(lp.empty.sum()),
            "constraints": [{"row": int(lp.row[i]), "submap": int(lp.submap[i]), "home": int(lp.home[i]),
                             "box": None if lp.empty[i] else lp.box[i].tolist(), "prior": lp.prior[i].tolist(),
                             "beams": int(lp.beams[i]), "empty": bool(lp.empty[i])} for i in range(len(lp))],
            "median_global_width_after": float(r.stats.get("median_pose_width", float("nan"))),
            "median_global_width_open_loop": float(r.stats.get("median_open_loop_width", float("nan"))),
            "anchor_boxes": r.submaps.anchor_box.tolist() if r.submaps is not None else [],
            "anchor_boxes_open_loop": lp.anchor_box_open.tolist(),
            "edges": int(len(lp.edge_a)), "sweeps": int(lp.sweeps),
        }
    if r.global_map is not None:
        g, st = r.global_map, r.stats
        free = int(np.count_nonzero(g.state == CELL_EMPTY))
        out["global_map"] = {
            "frame": g.frame, "origin": [float(x) for x in g.origin], "resolution": float(g.resolution),
            "shape": list(g.shape), "scans_mapped": int(st.get("global_scans_mapped", 0)),
            "proven_free_cells": free, "proven_free_m2": float(free * g.resolution ** 2),
            "logodds_free_cells": int(st.get("global_logodds_free_cells", 0)),
            "obstacle_cells": int(np.count_nonzero(g.state == CELL_OBSTACLE)),
        }
    if r.grid is not None:
        out["map"] = {
            "frame": r.grid.frame,
            "origin": [float(x) for x in r.grid.origin],
            "resolution": float(r.grid.resolution),
            "shape": list(r.grid.shape),
            "cells": rep.map_cells,
            "area_m2": rep.map_area_m2,
            "beams": rep.map_beams,
        }
        if r.logodds is not None and rep.logodds_cells:
            lo = r.logodds
            out["map"]["logodds"] = {
                "guaranteed": False,
                "scans": lo.scans,
                "beams": lo.beams,
                "model": {"l_occ": lo.l_occ, "l_free": lo.l_free, "l_min": lo.l_min, "l_max": lo.l_max},
                "cells": rep.logodds_cells,
                "disagreement": rep.disagreement,
            }
    return out


def render_json(rep: Report) -> str:
    return json.dumps(strict(report_dict(rep)), indent=2, allow_nan=False)
