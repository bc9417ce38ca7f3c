"""Small good inputs of every kind ivslam reads, and the hostile variants made from them.

Each builder writes one small, valid input (a log in every format, a result, a config, a
relations file); the ``*_variants`` generators derive the corpus from them: truncation at
many offsets, bit flips, NaN/inf/huge values in every numeric field of a record, declared
sizes that lie, empty files, binary junk.
"""

from __future__ import annotations

import gzip
import json
import lzma
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np

HOSTILE_NUMBERS = ("nan", "inf", "-inf", "1e308", "-1e308", "1e30", "99999999999999999999999")


# ------------------------------------------------------------------------ text logs
def carmen_lines(n: int = 40) -> list[str]:
    lines = []
    for k in range(n):
        t = 0.1 * k
        lines.append(f"ODOM {0.05 * k:.3f} 0 0 0.5 0 0 {t:.3f} host {t:.3f}")
        if k % 2 == 0:
            r = " ".join(f"{2 + 0.01 * ((i + k) % 7):.2f}" for i in range(180))
            lines.append(f"FLASER 180 {r} {0.05 * k:.3f} 0 0 {0.05 * k:.3f} 0 0 {t + 0.01:.3f} host {t:.3f}")
    return lines


def gfs_lines(n: int = 30) -> list[str]:
    """GMapping output as GridSlamProcessor writes it (ODOM, ODO_UPDATE, FRAME, LASER_READING,
    SM_UPDATE, NEFF, RESAMPLE), two particles."""
    lines = []
    for k in range(n):
        t = 0.2 * k
        x = 0.1 * k
        lines.append(f"ODOM {x:.3f} 0.000 0.000000 {t:.6f}")
        lines.append(f"ODO_UPDATE 2 {x:.3f} 0.000 0.000000 0.000000 {x:.3f} 0.010 0.001000 0.000000 {t:.6f}")
        if k % 3 == 0:
            lines.append(f"FRAME {k} 0.300000 0.000000")
            if k:
                r = " ".join(f"{1.5 + 0.01 * (i % 9):.2f}" for i in range(181))
                lines.append(f"LASER_READING 181 {r} {x:.6f} 0.000000 0.000000 {t:.6f}")
                lines.append(f"SM_UPDATE 2 {x:.3f} 0.000 0.000000 -1.000000 {x:.3f} 0.010 0.001000 -2.000000")
                lines.append("NEFF 1.800000")
                lines.append("RESAMPLE 2 0 0")
    return lines


def urg_lines(n: int = 12) -> list[str]:
    out = []
    for k in range(n):
        head = [str(100000 * k), "0", str(10 * k), str(12 * k)] + ["0"] * 20
        rng = [str(500 + (i * 7 + k) % 3000) for i in range(683)]
        out.append(" ".join(head + rng))
    return out


def victoria_lines(n: int = 30) -> list[str]:
    out = []
    pid = 0
    for k in range(n):
        out.append(f"ODOMETRY {pid} {pid + 1} 0.5 0.0 0.01 1e-4 0 0 4e-6 0 4e-6")
        out.append(f"LANDMARK {pid} 1000 {5.0 - 0.4 * k:.3f} 2.0 0.4 0 0.4")
        out.append(f"LANDMARK {pid} 1001 {6.0 - 0.4 * k:.3f} -2.0 0.4 0 0.4")
        pid += 1
    return out


def keyframe_json(n: int = 12) -> str:
    doc = {"map": {f"{976052890.0 + 3.4 * k:.2f}": {"x": 0.5 * k, "y": 0.0, "theta": 0.01 * k,
                                                   "range": [2.0 + 0.01 * (i % 5) for i in range(180)]}
                   for k in range(n)}}
    return json.dumps(doc)


def relations_lines(n: int = 10) -> list[str]:
    return [f"{0.1 * k:.3f} {0.1 * k + 0.2:.3f} 0.1 0 0 0 0 0.01" for k in range(n)]


def mrclam_dir(root: Path) -> Path:
    root.mkdir(parents=True, exist_ok=True)
    (root / "Barcodes.dat").write_text("# subject barcode\n" + "".join(f"{s} {100 + s}\n" for s in range(1, 21)))
    meas = "".join(f"{0.5 * k:.3f} {106 + k % 4} {2.0 + 0.1 * (k % 3):.3f} {0.1 * (k % 5 - 2):.3f}\n"
                   for k in range(60))
    (root / "Robot1_Measurement.dat").write_text(meas)
    (root / "Robot1_Odometry.dat").write_text("".join(f"{0.1 * k:.3f} 0.2 0.01\n" for k in range(300)))
    (root / "Robot1_Groundtruth.dat").write_text("".join(f"{0.1 * k:.3f} {0.02 * k:.4f} 0 0\n" for k in range(300)))
    (root / "Landmark_Groundtruth.dat").write_text("".join(f"{s} {s * 0.5:.2f} 1.0 0.01 0.01\n"
                                                           for s in range(6, 21)))
    return root


TEXT_LOGS = {
    "s.log": lambda: "\n".join(carmen_lines()) + "\n",
    "s.gfs": lambda: "\n".join(gfs_lines()) + "\n",
    "s.dat": lambda: "\n".join(urg_lines()) + "\n",
    "victoria.txt": lambda: "\n".join(victoria_lines()) + "\n",
    "keyframes.json": keyframe_json,
}


def write_text(path: Path, text: str) -> Path:
    if path.suffix == ".gz":
        with gzip.open(path, "wt") as f:
            f.write(text)
    elif path.suffix == ".xz":
        with lzma.open(path, "wt") as f:
            f.write(text)
    else:
        path.write_text(text)
    return path


# ------------------------------------------------------------------------ binary logs
def simulated(scenario: str, steps: int = 20):
    from ivslam_cli.simulate import SimConfig, simulate

    return simulate(SimConfig(scenario=scenario, seed=1, steps=steps, landmarks=8, world_size=8.0))


def write_logs(d: Path) -> dict[str, Path]:
    """Small logs in every binary format the simulator writes."""
    from ivslam_cli.logs.writers import write_log

    log = simulated("landmarks")
    lidar = simulated("lidar", steps=8)
    out = {}
    for name, fmt, lg in (("s.mcap", "mcap", log), ("s.bag", "ros1", log), ("s_ros2", "ros2", log),
                          ("s_ros2mcap", "ros2-mcap", log), ("s.h5", "h5", log),
                          ("lidar.mcap", "mcap", lidar), ("lidar.h5", "h5", lidar)):
        out[name] = write_log(d / name, lg, fmt)
    return out


def write_result(path: Path) -> Path:
    from ivslam_cli.results.example import example_result
    from ivslam_cli.results.hdf5 import write_result as wr

    wr(path, example_result())
    return path


# ------------------------------------------------------------------------ variants
def truncations(raw: bytes, count: int, seed: int) -> Iterator[tuple[str, bytes]]:
    rng = np.random.default_rng(seed)
    cuts = sorted(set([0, 1, len(raw) // 2, len(raw) - 1] + rng.integers(0, len(raw), count).tolist()))
    for c in cuts[:count]:
        yield f"cut{c}", raw[:c]


def bit_flips(raw: bytes, count: int, seed: int) -> Iterator[tuple[str, bytes]]:
    rng = np.random.default_rng(seed)
    for i in range(count):
        buf = bytearray(raw)
        for pos in rng.integers(0, len(raw), 1 + i % 3):
            buf[int(pos)] ^= 1 << int(rng.integers(0, 8))
        yield f"flip{i}", bytes(buf)


def numeric_field_variants(lines: list[str], keyword: str, fields: range | list[int]) -> Iterator[tuple[str, str]]:
    """The log with, in its first ``keyword`` record, each numeric field in ``fields`` replaced
    by each hostile number (NaN, ±inf, ±1e308, 1e30, an integer overflowing int64)."""
    at = next(i for i, ln in enumerate(lines) if ln.split()[0] == keyword)
    tok = lines[at].split()
    for f in fields:
        for v in HOSTILE_NUMBERS:
            t = list(tok)
            t[f] = v
            new = list(lines)
            new[at] = " ".join(t)
            yield f"{keyword}{f}={v}", "\n".join(new) + "\n"


def coarse_stamp_carmen(n: int = 120) -> str:
    """A CARMEN log whose stamps were printed with %g (6 significant digits) on unix time:
    the whole log shares a handful of distinct stamps; file order is the true order."""
    lines = []
    t0 = 976052890.0
    for k in range(n):
        t = t0 + 0.2 * k
        x = 0.05 * k
        lines.append(f"ODOM {x:.3f} 0 0 0.25 0 0 {t:g} host {t:g}")
        if k % 4 == 0:
            r = " ".join("2.00" for _ in range(180))
            lines.append(f"FLASER 180 {r} {x:.3f} 0 0 {x:.3f} 0 0 {t:g} host {t:g}")
    return "\n".join(lines) + "\n"


def finite(x) -> bool:
    return isinstance(x, float) and math.isfinite(x)
