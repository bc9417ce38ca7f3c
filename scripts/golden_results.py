"""Run a fixed set of `ivslam run` commands and compare their results with a reference set.

    python scripts/golden_results.py run  OUTDIR [--ivslam PATH]   # write OUTDIR/<case>.h5
    python scripts/golden_results.py diff REF_DIR NEW_DIR          # compare case by case

Two results are equal when every dataset (values, dtype, shape) and every attribute are equal,
except the attributes that record the run rather than its result (runtime, command line,
version, timings in /stats). A refactoring must leave every case equal.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
D = ROOT.parent / "shared" / "datasets"

CASES: dict[str, list[str]] = {
    "pairs_sample": ["sample_logs/pairs.mcap", "--mode", "pairs"],
    "pairs_sample_q1_anchor": ["sample_logs/pairs.mcap", "--mode", "pairs", "--q", "1", "--anchor", "3", "1.0", "2.0"],
    "landmarks_sample": ["sample_logs/landmarks.bag", "--mode", "landmarks", "--initial-pose-from-truth",
                         "--q-landmark", "2", "--q-pose", "1"],
    "landmarks_sample_strict": ["sample_logs/landmarks.bag", "--mode", "landmarks", "--initial-pose-from-truth",
                                "--strict"],
    "lidar_rooms": ["sample_logs/lidar_rooms.h5", "--mode", "lidar", "--initial-pose-from-truth"],
    "lidar_rooms_known": ["sample_logs/lidar_rooms.h5", "--mode", "lidar", "--poses-known"],
    "lidar_corridor": ["sample_logs/lidar_corridor.mcap", "--mode", "lidar", "--initial-pose-from-truth"],
    "mrclam_r1": [str(D / "mrclam/MRCLAM_Dataset6"), "--robot", "1", "--mode", "landmarks",
                  "--config", "configs/mrclam.toml"],
    "mrclam_r3": [str(D / "mrclam/MRCLAM_Dataset6"), "--robot", "3", "--mode", "landmarks",
                  "--config", "configs/mrclam.toml"],
    "victoria": [str(D / "victoria_park/victoria_park.txt.xz"), "--mode", "landmarks",
                 "--config", "configs/victoria_park.toml"],
    "aces": [str(D / "carmen_corrected/aces-corrected.log.gz"), "--mode", "lidar",
             "--config", "configs/carmen_corrected.toml"],
    "exp1": [str(D / "breezyslam_mines/exp1.dat.xz"), "--mode", "lidar", "--config", "configs/exp1.toml"],
    "intel": [str(D / "intel_lab/intel_gfs.json.xz"), "--mode", "lidar", "--config", "configs/intel_lab.toml"],
    "pairs_strict": ["sample_logs/pairs.mcap", "--mode", "pairs", "--range-abs", "0.001", "--strict"],
    "rooms_kf": ["sample_logs/lidar_rooms.h5", "--mode", "lidar", "--initial-pose-from-truth",
                 "--config", "{out}/kf.toml"],
    "intel_kf": [str(D / "intel_lab/intel_gfs.json.xz"), "--mode", "lidar", "--config", "{out}/intel_kf.toml"],
}
# configs the cases above name ({out}: the output directory)
CONFIGS = {
    "kf.toml": "[lidar]\nkeyframes = true\n",
    "intel_kf.toml": "\n".join(line for line in (ROOT / "configs/intel_lab.toml").read_text().splitlines()
                               if not line.startswith("#")) + "\nkeyframes = true\nkeyframe_distance = 0.0\n"
                     "keyframe_turn = 0.0\n",
}

# attributes that describe the run, not its result
SKIP_ATTRS = {"/runtime_s", "/provenance/command", "/provenance/ivslam_version"}
SKIP_STATS = ("_s", "beams_per_s")


def run(outdir: Path, ivslam: str, only=None) -> int:
    outdir.mkdir(parents=True, exist_ok=True)
    for name, text in CONFIGS.items():
        (outdir / name).write_text(text)
    bad = 0
    for name, args in CASES.items():
        if only and name not in only:
            continue
        out = outdir / f"{name}.h5"
        cmd = [ivslam, "run", *(a.format(out=outdir.resolve()) for a in args), "-o", str(out), "--force"]
        p = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        print(f"{name}: exit {p.returncode} {p.stderr.strip().splitlines()[-1] if p.stderr.strip() else ''}")
        if p.returncode not in (0, 3):
            bad += 1
    return bad


def _items(f: h5py.File) -> dict:
    out = {}

    def visit(name, obj):
        key = "/" + name
        if isinstance(obj, h5py.Dataset):
            out[key] = ("dataset", obj.dtype.str, obj.shape, obj[()])
        for a, v in obj.attrs.items():
            out[f"{key}@{a}"] = ("attr", v)

    for a, v in f.attrs.items():
        out[f"/@{a}"] = ("attr", v)
    f.visititems(visit)
    return out


def _skip(key: str) -> bool:
    path, _, attr = key.partition("@")
    if f"{path.rstrip('/') or ''}/{attr}".replace("//", "/") in SKIP_ATTRS:
        return True
    return path == "/stats" and attr.endswith(SKIP_STATS)


def _equal(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape or a.dtype != b.dtype:
            return False
        if a.dtype.kind == "f":
            return bool(np.array_equal(a, b, equal_nan=True))
        return bool(np.array_equal(a, b))
    return a == b or (isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b))


def diff(ref: Path, new: Path) -> int:
    bad = 0
    for name in CASES:
        a, b = ref / f"{name}.h5", new / f"{name}.h5"
        if not a.exists() or not b.exists():
            print(f"{name}: missing ({'ref' if not a.exists() else 'new'})")
            bad += 1
            continue
        with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
            ia, ib = _items(fa), _items(fb)
        keys = sorted(k for k in set(ia) | set(ib) if not _skip(k))
        diffs = [k for k in keys if k not in ia or k not in ib or not all(
            _equal(x, y) for x, y in zip(ia[k], ib[k]))]
        print(f"{name}: {'equal' if not diffs else 'DIFFERENT: ' + ', '.join(diffs[:8])}")
        bad += bool(diffs)
    return bad


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "run":
        ivs = sys.argv[sys.argv.index("--ivslam") + 1] if "--ivslam" in sys.argv else str(ROOT / ".venv/bin/ivslam")
        only = sys.argv[sys.argv.index("--only") + 1].split(",") if "--only" in sys.argv else None
        sys.exit(run(Path(sys.argv[2]), ivs, only))
    if len(sys.argv) == 4 and sys.argv[1] == "diff":
        sys.exit(diff(Path(sys.argv[2]), Path(sys.argv[3])))
    sys.exit(__doc__)
