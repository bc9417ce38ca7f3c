"""Benchmark (issue #6): the landmark CSP on the 5 MRCLAM robots and Victoria Park, beside GTSAM.

For each MRCLAM Dataset 6 robot (``configs/mrclam.toml``, read at run time so the bench follows
the config): our time, pose containment (truth at its own stamps, in the tube between nodes),
landmark containment, median pose/landmark box width (largest x-y side), box-centre error,
observations rejected, empty events; the floor (the same run with the true landmark map given,
``landmarks.map_known``: localisation only) beside it — median pose box, heading, containment;
what q-relaxation changed (the same run with plain
intersections, q = 0: empty events, containment, pose width); and GTSAM (``bench.gtsam_baseline``, dev extra) on the same
log with the same bounds: its time, position error (median, RMSE), landmark error, and how often
its 3σ ellipse holds the truth (poses x-y, landmarks). Then Victoria Park
(``configs/victoria_park.toml``): time, nodes, landmarks, widths, rejections, empty events.

Times, all wall clock of one call after the log is read (ours: ``run_landmarks``, i.e. problem
build + sweeps + consistency record; GTSAM: graph build + Levenberg–Marquardt + marginals):

- **cold**: a fresh process with an empty numba cache directory (``NUMBA_CACHE_DIR``): the call
  compiles the kernels. Measured once per dataset (first robot; Victoria Park).
- **warm**: a fresh process whose numba cache that cold run populated: the call loads the
  compiled kernels from the cache (what a second ``ivslam run`` sees). With ``--repeat N`` the
  same process repeats the call and the smallest of the N times is printed.

The process CPU time is printed beside the wall time (the machine may be shared). Targets
(issue #6): warm ≤ 2 s on each MRCLAM robot and on Victoria Park, pose containment ≥ 0.99 and
all 15 landmark boxes holding the truth on each robot, no empty event on Victoria Park.

**Whole processes** (issue #17), as a user runs them: ``ivslam run … --mode landmarks --config
configs/mrclam.toml --initial-pose-from-truth`` on each robot and on ``--robot all`` (the five
robots together), after one run that fills the numba cache, median wall time of
``--processes`` runs, the child's CPU time and peak resident memory, and beside them what
``ivslam report --json`` says of the result (median widths, containment). Targets: ≤ 2 s per
robot, ≤ 10 s for ``--robot all``, ≤ 1 GB, every truth pose and landmark inside.

    python -m bench.bench_landmarks                       # all 5 robots, GTSAM, Victoria Park
    python -m bench.bench_landmarks --robots 1 --no-gtsam --no-victoria
    python -m bench.bench_landmarks --markdown table.md   # also the tables as Markdown
    python -m bench.bench_landmarks --processes 0         # without the whole processes
    python -m bench landmarks                             # as part of `make bench` (found by name)
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parent.parent
DATASETS = Path(os.environ.get("IVSLAM_DATASETS", REPO.parent / "shared" / "datasets")).resolve()
MRCLAM = DATASETS / "mrclam" / "MRCLAM_Dataset6"
VICTORIA = DATASETS / "victoria_park" / "victoria_park.txt.xz"
MRCLAM_CONFIG = REPO / "configs" / "mrclam.toml"
VICTORIA_CONFIG = REPO / "configs" / "victoria_park.toml"

TARGET_WARM_S = 2.0
TARGET_POSE_FRACTION = 0.99
#: issue #17: median pose box (m), landmark box (m), heading (rad) on every MRCLAM robot
TARGET_POSE_W, TARGET_LM_W, TARGET_HEADING_W = 1.5, 1.0, 0.5
TARGET_PEAK_MB = 1024.0  # issue #17: peak memory on MRCLAM ≤ 1 GB
TARGET_ALL_S = 10.0  # issue #17: a warm `ivslam run --robot all` process

#: The bound keys the GTSAM baseline models (σ = bound / 3); every other ``[bounds]`` key of
#: our config is reported as not modelled by it.
GTSAM_KEYS = ("range_abs", "range_rel", "bearing", "odom_v", "odom_v_rel", "odom_w", "odom_w_rel")

_MARK = "BENCH_LANDMARKS_JSON "  # prefix of the worker's result line on stdout


# --- figures (pure) -----------------------------------------------------------------------

def gtsam_bounds(bounds: dict[str, Any]) -> tuple[dict[str, float], list[str]]:
    """The bounds the GTSAM baseline takes (same values as ours), and the non-zero bound keys of
    ours it does not model (e.g. ``odom_lag_xy``/``odom_lag_th``: a bounded offset of the true
    pose from the modelled one has no counterpart in its Gaussian between-factors)."""
    mapped = {k: float(bounds.get(k, 0.0)) for k in GTSAM_KEYS}
    unmodelled = sorted(k for k, v in bounds.items() if k not in GTSAM_KEYS and v)
    return mapped, unmodelled


def _median(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.median(a)) if a.size else math.nan


def _rmse(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a**2))) if a.size else math.nan


def our_figures(log, out) -> dict[str, Any]:
    """Containment, widths, centre errors and consistency counts of a ``LandmarksOutput``
    (containment figures are NaN/0 when the log has no truth)."""
    from ivslam_cli.report.core import landmark_containment, pose_containment

    s = out.stats
    fig: dict[str, Any] = {
        "nodes": int(s["nodes"]), "landmarks": int(s["landmarks"]), "observations": int(s["observations"]),
        "rejected": int(s["observations_rejected"]), "empty_events": int(len(out.consistency.empty_events)),
        "sweeps": int(s["sweeps"]), "converged": bool(s["converged"]),
        "pose_width_median": float(s["median_pose_width"]),
        "landmark_width_median": float(s["median_landmark_width"]),
        "heading_width_median": float(s["median_heading_width"]),
        "pose_checked": 0, "pose_contained": 0, "pose_fraction": math.nan,
        "pose_centre_err_median": math.nan, "pose_centre_err_rmse": math.nan,
        "lm_checked": 0, "lm_contained": 0, "lm_centre_err_median": math.nan,
    }
    truth = log.truth
    if truth is not None:
        pc = pose_containment(out.poses, truth)
        if pc is not None:
            fig.update(pose_checked=pc.checked, pose_contained=pc.contained, pose_fraction=pc.fraction,
                       pose_centre_err_median=_median(pc.centre_error),
                       pose_centre_err_rmse=_rmse(pc.centre_error))
        lc = landmark_containment(out.landmarks, truth)
        if lc is not None:
            fig.update(lm_checked=lc.checked, lm_contained=lc.contained,
                       lm_centre_err_median=_median(lc.centre_error))
    return fig


def gtsam_figures(g: dict[str, Any]) -> dict[str, Any]:
    """The GTSAM baseline's figures the table shows (``gtsam_*`` keys)."""
    n_lm = int(g.get("n_scored_landmarks", 0))
    lm_frac = g.get("lm_xy_in_3sigma", math.nan)
    return {
        "gtsam_s": float(g["t_total_s"]), "gtsam_iterations": int(g["iterations"]),
        "gtsam_pos_err_median": float(g["pos_err_median"]), "gtsam_pos_err_rmse": float(g["pos_err_rmse"]),
        "gtsam_lm_err_median": float(g.get("lm_err_median", math.nan)),
        "gtsam_pose_xy_in_3sigma": float(g["pose_xy_in_3sigma"]), "gtsam_poses_scored": int(g["n_scored_poses"]),
        "gtsam_lm_checked": n_lm,
        "gtsam_lm_in_3sigma": int(round(lm_frac * n_lm)) if n_lm and math.isfinite(lm_frac) else 0,
    }


def timed(fn, repeat: int = 1) -> tuple[Any, float, float]:
    """``fn()`` run ``repeat`` times; (last result, smallest wall time, its CPU time) in seconds."""
    best, best_cpu, res = math.inf, math.nan, None
    for _ in range(max(1, repeat)):
        c0, t0 = time.process_time(), time.perf_counter()
        res = fn()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        if wall < best:
            best, best_cpu = wall, cpu
    return res, best, best_cpu


def run_case(log, config: str | Path | None, *, gtsam: bool, repeat: int = 1,
             overrides: dict[str, Any] | None = None, floor: bool = True) -> dict[str, Any]:
    """Our pipeline (and optionally GTSAM, same bounds) on a log: one row of figures; with
    ``floor`` and a log with the landmarks' truth, also the localisation-only run (``loc_*``)."""
    from ivslam_cli.config import resolve_config
    from ivslam_cli.slam.landmarks import Params as LandmarksParams
    from ivslam_cli.slam.landmarks.pipeline import solve

    cfg = resolve_config(config, overrides or {}, log_bounds=log.bounds)
    out, wall, cpu = timed(lambda: solve(log, LandmarksParams.from_config(cfg)), repeat)
    row: dict[str, Any] = {"ours_s": wall, "ours_cpu_s": cpu, **our_figures(log, out)}
    # what q-relaxation changed: the same run with plain intersections (q = 0)
    if int(cfg["robust.q_landmark"]) or int(cfg["robust.q_pose"]) or float(cfg["robust.q_landmark_frac"]):
        plain_cfg = resolve_config(config, {**(overrides or {}), "robust.q_landmark": 0, "robust.q_pose": 0,
                                            "robust.q_landmark_frac": 0.0}, log_bounds=log.bounds)
        plain = our_figures(log, solve(log, LandmarksParams.from_config(plain_cfg)))
        row.update({f"plain_{k}": plain[k] for k in ("empty_events", "pose_fraction", "lm_contained",
                                                     "pose_width_median", "landmark_width_median")})
    # the floor: the same run with the true map given (localisation only, landmarks.map_known)
    if floor and log.truth is not None and log.truth.landmark_xy is not None and len(log.truth.landmark_xy):
        loc_cfg = resolve_config(config, {**(overrides or {}), "landmarks.map_known": True}, log_bounds=log.bounds)
        loc, loc_s, _ = timed(lambda: solve(log, LandmarksParams.from_config(loc_cfg)))
        f = our_figures(log, loc)
        row.update({f"loc_{k}": f[k] for k in ("pose_width_median", "heading_width_median", "pose_fraction",
                                               "pose_contained", "pose_checked", "rejected", "empty_events")})
        row["loc_s"] = loc_s
    if gtsam:
        from bench.gtsam_baseline import run_gtsam

        bounds, unmodelled = gtsam_bounds(cfg.section("bounds"))
        # span="odometry": poses on to the last odometry stamp, the span of our poses
        g = run_gtsam(log, bounds=bounds, robust=True, span="odometry")
        row.update(gtsam_figures(g), gtsam_unmodelled=unmodelled)
    return row


# --- tables (pure) ------------------------------------------------------------------------

def _f(v: Any, fmt: str) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return fmt.format(v)


def _frac(a: Any, b: Any) -> str:
    return f"{a}/{b}" if b else "–"


def mrclam_columns(gtsam: bool) -> list[tuple[str, Any]]:
    """(header, cell function of a row) of the MRCLAM table."""
    cols: list[tuple[str, Any]] = [
        ("robot", lambda r: str(r["robot"])),
        ("ours cold s", lambda r: _f(r.get("cold_s"), "{:.1f}")),
        ("ours warm s", lambda r: _f(r["ours_s"], "{:.2f}")),
        ("peak MB", lambda r: _f(r.get("peak_mb"), "{:.0f}")),
        ("pose in box", lambda r: _f(r["pose_fraction"], "{:.4f}")),
        ("lm in box", lambda r: _frac(r["lm_contained"], r["lm_checked"])),
        ("pose w m", lambda r: _f(r["pose_width_median"], "{:.2f}")),
        ("lm w m", lambda r: _f(r["landmark_width_median"], "{:.2f}")),
        ("head w rad", lambda r: _f(r.get("heading_width_median"), "{:.2f}")),
        ("map given: pose w m", lambda r: _f(r.get("loc_pose_width_median"), "{:.2f}")),
        ("map given: head w rad", lambda r: _f(r.get("loc_heading_width_median"), "{:.2f}")),
        ("map given: pose in box", lambda r: _f(r.get("loc_pose_fraction"), "{:.4f}")),
        ("centre err m", lambda r: _f(r["pose_centre_err_median"], "{:.3f}")),
        ("lm centre err m", lambda r: _f(r["lm_centre_err_median"], "{:.3f}")),
        ("rejected", lambda r: str(r["rejected"])),
        ("empty ev", lambda r: str(r["empty_events"])),
        ("q=0: empty ev", lambda r: str(r["plain_empty_events"]) if "plain_empty_events" in r else "–"),
        ("q=0: pose in box", lambda r: _f(r.get("plain_pose_fraction"), "{:.4f}")),
        ("q=0: lm in box", lambda r: _frac(r.get("plain_lm_contained"), r["lm_checked"]) if "plain_lm_contained" in r else "–"),
        ("q=0: pose w m", lambda r: _f(r.get("plain_pose_width_median"), "{:.2f}")),
    ]
    if gtsam:
        cols += [
            ("GTSAM s", lambda r: _f(r.get("gtsam_s"), "{:.2f}")),
            ("GTSAM err med m", lambda r: _f(r.get("gtsam_pos_err_median"), "{:.3f}")),
            ("GTSAM err rmse m", lambda r: _f(r.get("gtsam_pos_err_rmse"), "{:.3f}")),
            ("GTSAM lm err m", lambda r: _f(r.get("gtsam_lm_err_median"), "{:.3f}")),
            ("GTSAM pose in 3σ", lambda r: _f(r.get("gtsam_pose_xy_in_3sigma"), "{:.3f}")),
            ("GTSAM lm in 3σ", lambda r: _frac(r.get("gtsam_lm_in_3sigma"), r.get("gtsam_lm_checked"))),
        ]
    return cols


VICTORIA_COLUMNS: list[tuple[str, Any]] = [
    ("log", lambda r: str(r["name"])),
    ("ours cold s", lambda r: _f(r.get("cold_s"), "{:.1f}")),
    ("ours warm s", lambda r: _f(r["ours_s"], "{:.2f}")),
    ("nodes", lambda r: str(r["nodes"])),
    ("landmarks", lambda r: str(r["landmarks"])),
    ("observations", lambda r: str(r["observations"])),
    ("pose w m", lambda r: _f(r["pose_width_median"], "{:.2f}")),
    ("lm w m", lambda r: _f(r["landmark_width_median"], "{:.2f}")),
    ("rejected", lambda r: str(r["rejected"])),
    ("empty ev", lambda r: str(r["empty_events"])),
    ("sweeps", lambda r: f"{r['sweeps']}{'' if r['converged'] else ' (cap)'}"),
]


PROCESS_COLUMNS: list[tuple[str, Any]] = [
    ("robot", lambda r: str(r["robot"])),
    ("process s (median)", lambda r: _f(r["wall_s"], "{:.2f}")),
    ("runs s", lambda r: " ".join(f"{t:.2f}" for t in r["walls"])),
    ("CPU s", lambda r: _f(r["cpu_s"], "{:.2f}")),
    ("peak MB", lambda r: _f(r["peak_mb"], "{:.0f}")),
    ("pose in box", lambda r: _frac(r["pose_contained"], r["pose_checked"])),
    ("lm in box", lambda r: _frac(r["lm_contained"], r["lm_checked"])),
    ("pose w m", lambda r: _f(r["pose_width_median"], "{:.2f}")),
    ("lm w m", lambda r: _f(r["landmark_width_median"], "{:.2f}")),
    ("head w rad", lambda r: _f(r["heading_width_median"], "{:.2f}")),
    ("empty ev", lambda r: str(r["empty_events"])),
]


def format_table(rows: list[dict[str, Any]], columns: list[tuple[str, Any]], markdown: bool = False) -> str:
    """Rows as a fixed-width text table, or a Markdown (GitHub) table."""
    heads = [h for h, _ in columns]
    cells = [[fn(r) for _, fn in columns] for r in rows]
    if markdown:
        lines = ["| " + " | ".join(heads) + " |", "|" + "|".join("---:" for _ in heads) + "|"]
        lines += ["| " + " | ".join(c) + " |" for c in cells]
        return "\n".join(lines)
    widths = [max(len(h), *(len(c[i]) for c in cells)) for i, h in enumerate(heads)]
    lines = ["  ".join(h.rjust(w) for h, w in zip(heads, widths))]
    lines += ["  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in cells]
    return "\n".join(lines)


def process_verdicts(rows: list[dict[str, Any]]) -> list[tuple[bool, str]]:
    """(passed, line) per whole-process target of issue #17."""
    out: list[tuple[bool, str]] = []
    for r in rows:
        name = "MRCLAM --robot all" if r["robot"] == "all" else f"MRCLAM robot {r['robot']}"
        limit = TARGET_ALL_S if r["robot"] == "all" else TARGET_WARM_S
        out.append((r["wall_s"] <= limit, f"{name}: warm `ivslam run` process {r['wall_s']:.2f} s <= {limit:g} s "
                                          f"(median of {len(r['walls'])})"))
        out.append((r["peak_mb"] <= TARGET_PEAK_MB, f"{name}: process peak memory {r['peak_mb']:.0f} MB "
                                                    f"<= {TARGET_PEAK_MB:g} MB"))
        out.append((r["pose_checked"] > 0 and r["pose_contained"] == r["pose_checked"]
                    and r["lm_checked"] > 0 and r["lm_contained"] == r["lm_checked"],
                    f"{name}: ivslam report: poses {r['pose_contained']}/{r['pose_checked']}, "
                    f"landmarks {r['lm_contained']}/{r['lm_checked']} inside"))
    return out


def verdicts(mrclam: list[dict[str, Any]], victoria: dict[str, Any] | None) -> list[tuple[bool, str]]:
    """(passed, line) per target of issue #6."""
    out: list[tuple[bool, str]] = []
    for r in mrclam:
        name = f"MRCLAM robot {r['robot']}"
        out.append((r["ours_s"] <= TARGET_WARM_S, f"{name}: warm {r['ours_s']:.2f} s <= {TARGET_WARM_S:g} s"))
        if "peak_mb" in r:
            out.append((r["peak_mb"] <= TARGET_PEAK_MB, f"{name}: peak memory of the case's process "
                                                        f"{r['peak_mb']:.0f} MB <= {TARGET_PEAK_MB:g} MB"))
        pf = r["pose_fraction"]
        out.append((math.isfinite(pf) and pf >= TARGET_POSE_FRACTION,
                    f"{name}: pose containment {_f(pf, '{:.4f}')} >= {TARGET_POSE_FRACTION:g} "
                    f"({r['pose_contained']}/{r['pose_checked']} truth poses)"))
        out.append((r["lm_checked"] > 0 and r["lm_contained"] == r["lm_checked"],
                    f"{name}: landmarks contained {r['lm_contained']}/{r['lm_checked']} (all)"))
        for key, target, what in (("pose_width_median", TARGET_POSE_W, "median pose box"),
                                  ("landmark_width_median", TARGET_LM_W, "median landmark box"),
                                  ("heading_width_median", TARGET_HEADING_W, "median heading")):
            v = r.get(key, math.nan)
            out.append((math.isfinite(v) and v <= target, f"{name}: {what} {_f(v, '{:.2f}')} <= {target:g}"))
        if "loc_pose_fraction" in r:
            lf = r["loc_pose_fraction"]
            out.append((math.isfinite(lf) and lf >= 1.0,
                        f"{name}: map given, pose containment {_f(lf, '{:.4f}')} = 1 "
                        f"({r['loc_pose_contained']}/{r['loc_pose_checked']} truth poses)"))
    if victoria is not None:
        out.append((victoria["ours_s"] <= TARGET_WARM_S,
                    f"Victoria Park: warm {victoria['ours_s']:.2f} s <= {TARGET_WARM_S:g} s"))
        out.append((victoria["empty_events"] == 0,
                    f"Victoria Park: consistent end to end ({victoria['empty_events']} empty events)"))
    return out


# --- processes ----------------------------------------------------------------------------

def _worker(spec: str, gtsam: bool, repeat: int) -> dict[str, Any]:
    """One case in this process: ``mrclam:R`` or ``victoria``."""
    from ivslam_cli.logs import read_log

    t0 = time.perf_counter()
    if spec.startswith("mrclam:"):
        robot = int(spec.split(":", 1)[1])
        log = read_log(MRCLAM, None, robot=robot)
        config, head = MRCLAM_CONFIG, {"robot": robot}
    elif spec == "victoria":
        log = read_log(VICTORIA)
        config, head, gtsam = VICTORIA_CONFIG, {"name": "Victoria Park"}, False
    else:
        raise ValueError(f"unknown case {spec!r}")
    read_s = time.perf_counter() - t0
    row = {**head, "read_s": read_s, **run_case(log, config, gtsam=gtsam, repeat=repeat)}
    row["peak_mb"] = peak_rss_mb()
    return row


def peak_rss_mb() -> float:
    """This process's peak resident memory so far, MiB (Linux reports ``ru_maxrss`` in KiB):
    the whole case — log, our runs, GTSAM's — an upper bound of our pipeline's own."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _spawn(spec: str, cache: Path | None, *, gtsam: bool, repeat: int = 1) -> dict[str, Any]:
    """Run ``_worker(spec)`` in a fresh process with ``NUMBA_CACHE_DIR=cache`` (None: the
    environment's own numba cache)."""
    env = dict(os.environ) if cache is None else dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    cmd = [sys.executable, "-m", "bench.bench_landmarks", "--worker", spec, "--repeat", str(repeat)]
    if not gtsam:
        cmd.append("--no-gtsam")
    p = subprocess.run(cmd, cwd=REPO, env=env, capture_output=True, text=True)
    for line in p.stdout.splitlines():
        if line.startswith(_MARK):
            return json.loads(line[len(_MARK):])
    raise WorkerError(f"the {spec} run failed (exit {p.returncode}):\n{p.stderr[-2000:]}")


def report_figures(report: dict[str, Any]) -> dict[str, Any]:
    """The widths and containment of an ``ivslam report --json`` document."""
    fw = report.get("final_width") or {}
    cd = report.get("containment_detail") or {}

    def med(kind: str) -> float:
        v = (fw.get(kind) or {}).get("median")
        return math.nan if v is None else float(v)

    pose, lm = cd.get("pose") or {}, cd.get("landmark") or {}
    return {"pose_width_median": med("pose"), "landmark_width_median": med("landmark"),
            "heading_width_median": med("pose_heading"), "empty_events": int(report.get("empty_events") or 0),
            "pose_checked": int(pose.get("checked", 0)), "pose_contained": int(pose.get("contained", 0)),
            "lm_checked": int(lm.get("checked", 0)), "lm_contained": int(lm.get("contained", 0))}


def _ivslam() -> list[str]:
    """The console script beside this interpreter (as a user calls it), else ``-m ivslam_cli``."""
    script = Path(sys.executable).parent / "ivslam"
    return [str(script)] if script.exists() else [sys.executable, "-m", "ivslam_cli"]


def _child(cmd: list[str]) -> tuple[float, float, float]:
    """Run ``cmd``; (wall s, its CPU s, its peak resident MiB). Raises WorkerError if it fails."""
    with tempfile.TemporaryFile() as errf:  # a file, not a pipe: a chatty child cannot block on it
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.DEVNULL, stderr=errf)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
        if p.returncode != 0:
            errf.seek(0)
            err = errf.read().decode(errors="replace")
            raise WorkerError(f"{' '.join(cmd)} failed (exit {p.returncode}): {err[-2000:]}")
    return wall, ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0


def run_processes(robots: list[int | str], n: int) -> list[dict[str, Any]]:
    """Whole warm ``ivslam run`` processes per robot (``"all"``: ``--robot all``): see the module
    docstring."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-landmarks-cli-") as tmp:
        for robot in robots:
            out = Path(tmp) / f"robot_{robot}.h5"
            cmd = [*_ivslam(), "run", str(MRCLAM), "--robot", str(robot), "--mode", "landmarks", "--config",
                   str(MRCLAM_CONFIG), "--initial-pose-from-truth", "-o", str(out), "--force"]
            _child(cmd)  # fills the numba cache if it is empty or stale
            runs = [_child(cmd) for _ in range(n)]
            walls = [w for w, _, _ in runs]
            mid = sorted(range(n), key=lambda i: walls[i])[n // 2]
            rep = subprocess.run([*_ivslam(), "report", str(out), "--json"], cwd=REPO, capture_output=True, text=True)
            if rep.returncode != 0:
                raise WorkerError(f"ivslam report {out} failed: {rep.stderr[-2000:]}")
            row = {"robot": robot, "wall_s": walls[mid], "walls": walls, "cpu_s": runs[mid][1],
                   "peak_mb": max(r[2] for r in runs), **report_figures(json.loads(rep.stdout))}
            rows.append(row)
            print(f"  {'--robot all' if robot == 'all' else f'robot {robot}'}: process {row['wall_s']:.2f} s "
                  f"(runs {' '.join(f'{w:.2f}' for w in walls)}; CPU {row['cpu_s']:.2f} s), "
                  f"peak {row['peak_mb']:.0f} MB", flush=True)
    return rows


class WorkerError(RuntimeError):
    """A case's process ended without its figures."""


def _finite_or_none(v: Any) -> Any:
    """NaN/inf as JSON null (the --json file is standard JSON)."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: _finite_or_none(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_finite_or_none(x) for x in v]
    return v


def _have_gtsam() -> bool:
    import importlib.util

    return importlib.util.find_spec("gtsam") is not None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.bench_landmarks", description=__doc__.split("\n")[0])
    ap.add_argument("--robots", default="1,2,3,4,5", help="MRCLAM robots, comma-separated (default 1,2,3,4,5)")
    ap.add_argument("--no-gtsam", action="store_true", help="skip the GTSAM baseline")
    ap.add_argument("--no-victoria", action="store_true", help="skip Victoria Park")
    ap.add_argument("--no-cold", action="store_true",
                    help="skip the cold (empty numba cache) runs; warm runs then use the usual numba cache")
    ap.add_argument("--repeat", type=int, default=1, help="warm: calls per process, the smallest time kept")
    ap.add_argument("--processes", type=int, default=3,
                    help="whole warm `ivslam run` processes per robot and for --robot all, median kept (0: none)")
    ap.add_argument("--markdown", metavar="PATH", help="also write the tables as Markdown to PATH")
    ap.add_argument("--json", metavar="PATH", help="also write every figure as JSON to PATH")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)

    if args.worker:
        row = _worker(args.worker, gtsam=not args.no_gtsam, repeat=args.repeat)
        print(_MARK + json.dumps(row), flush=True)
        return 0

    robots = [int(r) for r in args.robots.split(",") if r.strip()] if args.robots else []
    use_gtsam = not args.no_gtsam and bool(robots)
    if use_gtsam and not _have_gtsam():
        print("gtsam is not installed (dev extra): the GTSAM columns are left out")
        use_gtsam = False
    missing = [p for p, need in ((MRCLAM, robots), (VICTORIA, not args.no_victoria)) if need and not p.exists()]
    if missing:
        print(f"dataset(s) not found: {', '.join(map(str, missing))}")
        return 1
    load = os.getloadavg()
    print(f"machine: {os.cpu_count()} CPUs, load average {load[0]:.2f} (1 min) at start")
    print("times: wall clock of one call after the log is read (ours: run_landmarks; GTSAM: build + LM + "
          "marginals); cold = fresh process, empty numba cache (compiles); warm = fresh process, "
          + ("the usual numba cache (compiles if it is empty or stale)" if args.no_cold else
             "the cache the cold run populated")
          + (f", best of {args.repeat} calls" if args.repeat > 1 else ""))

    mrclam: list[dict[str, Any]] = []
    victoria: dict[str, Any] | None = None
    processes: list[dict[str, Any]] = []
    try:
        victoria = _run_all(args, robots, use_gtsam, mrclam)
        if robots and args.processes > 0:
            print(f"\nWhole warm `ivslam run` processes (MRCLAM, {MRCLAM_CONFIG.relative_to(REPO)}, "
                  f"--initial-pose-from-truth; median of {args.processes})", flush=True)
            processes = run_processes([*robots, "all"] if len(robots) > 1 else robots, args.processes)
    except WorkerError as exc:
        print(f"FAIL {exc}")
        return 1
    return _summarise(args, mrclam, victoria, use_gtsam, processes)


def _run_all(args: argparse.Namespace, robots: list[int], use_gtsam: bool,
             mrclam: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The cases, each in its own process; MRCLAM rows appended to ``mrclam``; Victoria Park's returned."""
    victoria = None
    with tempfile.TemporaryDirectory(prefix="bench-landmarks-") as tmp:
        # warm runs load what the cold run compiled; without cold runs, the usual cache
        # (populated by any earlier run; if it is empty, the first "warm" call compiles)
        cache = None if args.no_cold else Path(tmp) / "numba-cache"
        cold_mrclam = None
        if robots:
            print(f"\nMRCLAM Dataset 6, config {MRCLAM_CONFIG.relative_to(REPO)} (read now)", flush=True)
            if not args.no_cold:
                cold_mrclam = _spawn(f"mrclam:{robots[0]}", cache, gtsam=False)
                print(f"  cold (robot {robots[0]}): {cold_mrclam['ours_s']:.1f} s "
                      f"(CPU {cold_mrclam['ours_cpu_s']:.1f} s)", flush=True)
            for robot in robots:
                row = _spawn(f"mrclam:{robot}", cache, gtsam=use_gtsam, repeat=args.repeat)
                if cold_mrclam is not None and robot == robots[0]:
                    row["cold_s"], row["cold_cpu_s"] = cold_mrclam["ours_s"], cold_mrclam["ours_cpu_s"]
                mrclam.append(row)
                g = f", GTSAM {row['gtsam_s']:.2f} s" if use_gtsam else ""
                print(f"  robot {robot}: read {row['read_s']:.1f} s, ours warm {row['ours_s']:.2f} s "
                      f"(CPU {row['ours_cpu_s']:.2f} s){g}", flush=True)
            if use_gtsam and mrclam and mrclam[0].get("gtsam_unmodelled"):
                print(f"  GTSAM: same bounds (σ = bound/3); not modelled by it: "
                      f"{', '.join(mrclam[0]['gtsam_unmodelled'])}")
        if not args.no_victoria:
            print(f"\nVictoria Park, config {VICTORIA_CONFIG.relative_to(REPO)}", flush=True)
            vcache = Path(tmp) / "numba-cache-victoria"
            cold_v = None if args.no_cold else _spawn("victoria", vcache, gtsam=False)
            victoria = _spawn("victoria", vcache if cold_v is not None else cache, gtsam=False, repeat=args.repeat)
            if cold_v is not None:
                victoria["cold_s"], victoria["cold_cpu_s"] = cold_v["ours_s"], cold_v["ours_cpu_s"]
            print(f"  read {victoria['read_s']:.1f} s, ours warm {victoria['ours_s']:.2f} s "
                  f"(CPU {victoria['ours_cpu_s']:.2f} s)", flush=True)
    return victoria


def _summarise(args: argparse.Namespace, mrclam: list[dict[str, Any]], victoria: dict[str, Any] | None,
               use_gtsam: bool, processes: list[dict[str, Any]]) -> int:
    """Tables, PASS/FAIL lines and the optional files; the exit code."""
    md: list[str] = []
    if mrclam:
        cols = mrclam_columns(use_gtsam)
        print("\n" + format_table(mrclam, cols))
        md += ["MRCLAM Dataset 6 (`configs/mrclam.toml`), per robot:", "", format_table(mrclam, cols, True), ""]
    if processes:
        print("\n" + format_table(processes, PROCESS_COLUMNS))
        md += ["Whole warm `ivslam run` processes (MRCLAM, `configs/mrclam.toml`, `--initial-pose-from-truth`):",
               "", format_table(processes, PROCESS_COLUMNS, True), ""]
    if victoria is not None:
        print("\n" + format_table([victoria], VICTORIA_COLUMNS))
        md += ["Victoria Park (`configs/victoria_park.toml`, no ground truth):", "",
               format_table([victoria], VICTORIA_COLUMNS, True), ""]
    print("\ncolumns: pose/lm in box = truth inside our pose tube / landmark box; w = median largest x-y side "
          "of the boxes; head w = median heading width; map given = the same run with the true landmark map "
          "(landmarks.map_known: localisation only: the floor as our solver reaches it, from above; "
          "bench_landmark_floor measures it from below); peak MB = the case process's peak resident memory; centre err = median distance of box centres to the truth; GTSAM in 3σ = truth inside "
          "the 3σ (χ²₂ = 9) ellipse of its marginal; GTSAM err = its estimate's position error")
    checks = verdicts(mrclam, victoria) + process_verdicts(processes)
    print()
    for ok, line in checks:
        print(f"{'PASS' if ok else 'FAIL'} {line}")
    if args.markdown:
        Path(args.markdown).write_text("\n".join(md))
        print(f"\nMarkdown tables written to {args.markdown}")
    if args.json:
        Path(args.json).write_text(json.dumps(_finite_or_none({"mrclam": mrclam, "victoria": victoria,
                                                               "processes": processes}), indent=1, allow_nan=False))
    return 0 if all(ok for ok, _ in checks) else 1


if __name__ == "__main__":
    sys.exit(main())
