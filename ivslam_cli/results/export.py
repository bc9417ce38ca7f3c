"""Exports for other tools: TUM trajectories (evo) and ROS ``map_server`` maps.

Both are derived views, not enclosures: a TUM line is the *centre* of a pose box; a PGM
map shows the cell states. Files are written atomically and never overwrite without force.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ivslam_cli.atomic import check_output, transaction, write_bytes_atomic, write_text_atomic
from ivslam_cli.results.model import CELL_EMPTY, CELL_OBSTACLE, MapGrid, Poses, Robots, box_is_empty

# map_server trinary PGM values (negate = 0): p = (255 − value) / 255 is the occupancy.
PGM_FREE = 254
PGM_OCCUPIED = 0
PGM_UNKNOWN = 205
OCCUPIED_THRESH = 0.65
FREE_THRESH = 0.196


def tum_text(poses: Poses) -> tuple[str, int]:
    """TUM lines ``stamp x y z qx qy qz qw`` of box centres (z = 0, yaw-only quaternion).

    Empty pose boxes have no centre and are skipped; returns (text, number skipped).
    """
    keep = ~box_is_empty(poses.box)
    b = poses.box[keep]
    c = 0.5 * (b[..., 0] + b[..., 1])
    half = 0.5 * c[:, 2]
    rows = np.column_stack(
        [poses.stamp[keep], c[:, 0], c[:, 1], np.zeros(len(c)), np.zeros(len(c)), np.zeros(len(c)),
         np.sin(half), np.cos(half)]
    )
    buf = io.StringIO()
    buf.write("# timestamp x y z qx qy qz qw (centres of ivslam pose boxes)\n")
    np.savetxt(buf, rows, fmt="%.17g")
    return buf.getvalue(), int((~keep).sum())


def tum_paths(path: str | Path, robot_ids=None) -> list[Path]:
    """The TUM files ``write_tum`` writes: ``path``, or for a result of several robots (their
    numbers ``robot_ids``) one per robot, ``path`` with ``.robotN`` before its suffix
    (``all.tum`` → ``all.robot1.tum``)."""
    path = Path(path)
    if robot_ids is None:
        return [path]
    return [path.with_name(f"{path.stem}.robot{int(i)}{path.suffix}") for i in robot_ids]


def write_tum(path: str | Path, poses: Poses, *, force: bool = False, robots: Robots | None = None) -> int:
    """Write a TUM trajectory (one per robot of a result of several, see :func:`tum_paths`);
    returns how many empty pose boxes were skipped."""
    skipped = 0
    for r, out in enumerate(tum_paths(path, None if robots is None else robots.id)):
        part = poses
        if robots is not None:
            a, b = int(robots.pose_offsets[r]), int(robots.pose_offsets[r + 1])
            part = Poses(stamp=poses.stamp[a:b], box=poses.box[a:b])
        text, n = tum_text(part)
        write_text_atomic(out, text, force=force, kind="tum")
        skipped += n
    return skipped


def pgm_bytes(grid: MapGrid) -> bytes:
    """Binary (P5) trinary PGM; image row 0 is the top (largest y), as map_server expects."""
    img = np.full(grid.state.shape, PGM_UNKNOWN, dtype=np.uint8)
    img[grid.state == CELL_EMPTY] = PGM_FREE
    img[grid.state == CELL_OBSTACLE] = PGM_OCCUPIED
    img = np.ascontiguousarray(img[::-1])
    h, w = img.shape
    return f"P5\n# ivslam map\n{w} {h}\n255\n".encode("ascii") + img.tobytes()


def map_yaml(grid: MapGrid, image_name: str) -> str:
    ox, oy = (float(v) for v in grid.origin)
    return (
        f"image: {image_name}\n"
        "mode: trinary\n"
        f"resolution: {float(grid.resolution)!r}\n"
        f"origin: [{ox!r}, {oy!r}, 0.0]\n"
        "negate: 0\n"
        f"occupied_thresh: {OCCUPIED_THRESH}\n"
        f"free_thresh: {FREE_THRESH}\n"
    )


def write_map_server(prefix: str | Path, grid: MapGrid, *, force: bool = False) -> tuple[Path, Path]:
    """Write ``PREFIX.pgm`` and ``PREFIX.yaml`` (the YAML names the PGM relative to itself)."""
    prefix = Path(prefix)
    pgm, yml = prefix.with_name(prefix.name + ".pgm"), prefix.with_name(prefix.name + ".yaml")
    check_output(pgm, force=force, kind="pgm")  # either file refused: neither is written
    check_output(yml, force=force, kind="map-yaml")
    with transaction(force=force):  # both files or neither
        write_bytes_atomic(pgm, pgm_bytes(grid), force=force, kind="pgm")
        write_text_atomic(yml, map_yaml(grid, pgm.name), force=force, kind="map-yaml")
    return pgm, yml


def graph_texts(anchor_box: np.ndarray, loops) -> tuple[str, str]:
    """The interval pose graph as JSON (``{"format": "ivslam-interval-pose-graph", "version": 1,
    "nodes": [{"id", "box": [[x_lo, x_hi], [y_lo, y_hi], [θ_lo, θ_hi]]}], "edges": [{"from", "to",
    "kind", "box"}]}``: node boxes in the result's frame, edge boxes the pose of ``to`` in the robot
    frame of ``from``) and as g2o text of the box centres (``VERTEX_SE2 id x y θ``, ``EDGE_SE2 a b
    dx dy dθ`` + the upper triangle of an information matrix ``1/w²`` per axis from the box
    half-widths ``w``; centres only: no guarantee)."""
    import json

    def c(b):
        return [0.5 * (float(b[d, 0]) + float(b[d, 1])) for d in range(3)]

    nodes = [{"id": i, "box": np.asarray(b, float).tolist()} for i, b in enumerate(anchor_box)]
    edges = [{"from": int(a), "to": int(b), "kind": "loop" if int(k) == 1 else "chain",
              "box": np.asarray(e, float).tolist()}
             for a, b, e, k in zip(loops.edge_a, loops.edge_b, loops.edge_box, loops.edge_kind)]
    doc = json.dumps({"format": "ivslam-interval-pose-graph", "version": 1, "frame": "result (see /poses frame)",
                      "nodes": nodes, "edges": edges}, indent=1, allow_nan=False)
    lines = ["# ivslam pose graph centres (g2o)"] + [f"VERTEX_SE2 {i} {x:.9g} {y:.9g} {t:.9g}" for i, (x, y, t) in ((n["id"], c(np.asarray(n["box"])))
                                                                         for n in nodes)]
    lines.append("FIX 0")
    for a, b, e in zip(loops.edge_a, loops.edge_b, loops.edge_box):
        x, y, t = c(e)
        w = [max(0.5 * float(e[d, 1] - e[d, 0]), 1e-6) for d in range(3)]
        inf = [1.0 / (w[0] ** 2), 0.0, 0.0, 1.0 / (w[1] ** 2), 0.0, 1.0 / (w[2] ** 2)]
        lines.append(f"EDGE_SE2 {int(a)} {int(b)} {x:.9g} {y:.9g} {t:.9g} " + " ".join(f"{v:.6g}" for v in inf))
    return doc + "\n", "\n".join(lines) + "\n"


def write_graph(prefix: str | Path, anchor_box: np.ndarray, loops, *, force: bool = False) -> tuple[Path, Path]:
    """Write ``PREFIX.graph.json`` (the interval pose graph) and ``PREFIX.g2o`` (its centres)."""
    prefix = Path(prefix)
    js, g2o = graph_texts(anchor_box, loops)
    pj = prefix.with_name(prefix.name + ".graph.json")
    pg = prefix.with_name(prefix.name + ".g2o")
    write_text_atomic(pj, js, force=force, kind="graph")
    write_text_atomic(pg, g2o, force=force, kind="g2o")
    return pj, pg
