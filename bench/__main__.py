"""Run every ``bench/bench_*.py`` module's ``main()`` (or only those named on the command line).

    python -m bench                 # all
    python -m bench kernels paving  # bench_kernels.py and bench_paving.py

Each benchmark runs in its own process: timings do not depend on what ran before, and a
reference library's side effects (Codac leaves the FPU rounding upward, and a later h5py import
then crashes) stay inside the benchmark that loads it.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path


def main(argv: list[str]) -> int:
    here = Path(__file__).resolve().parent
    names = sorted(p.stem for p in here.glob("bench_*.py"))
    if argv:
        wanted = {a if a.startswith("bench_") else f"bench_{a}" for a in argv}
        unknown = wanted - set(names)
        if unknown:
            print(f"unknown benchmark(s): {', '.join(sorted(unknown))}; have: {', '.join(names)}")
            return 2
        names = [n for n in names if n in wanted]
    failed = []
    for name in names:
        print(f"\n=== {name} " + "=" * max(0, 60 - len(name)), flush=True)
        t0 = time.perf_counter()
        code = f"import sys, bench.{name} as b; sys.exit(b.main())"
        rc = subprocess.run([sys.executable, "-c", code], cwd=here.parent).returncode
        print(f"--- {name}: {time.perf_counter() - t0:.1f} s", flush=True)
        if rc:
            failed.append(name)
    if failed:
        print(f"\nbenchmarks that missed a target or failed: {', '.join(failed)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
