"""Benchmark: paving the ring sector rho in [4.9, 5.1], theta in [0.3, 0.32] in [-10, 10]^2.

Times ``ivslam_cli.paving.pave`` (grid SIVIA with the polar classifier) and Codac 2's
``pave`` with ``SepInverse`` (and ``SepPolarCart``) on the same sector at the same eps, in the
same run, and compares outer / inner areas with the exact 0.02.
Targets: outer excess <= 3.2 % at eps = 0.01; less time than Codac.

Note on the excess target: a grid paving stores one box per eps-cell, so its outer area is at
least the sum of the exact bounding boxes of (sector ∩ cell); the ``sub`` rows (boundary cells
bisected 4^sub times, hull of the contracted pieces) approach that limit from above.
Codac's pave is not grid-aligned (it bisects the contracted boxes), which is why it can go
below it at the same eps.
"""

from __future__ import annotations

import time

RHO = (4.9, 5.1)
THETA = (0.3, 0.32)
DOMAIN = [[-10.0, 10.0], [-10.0, 10.0]]
EXACT = (RHO[1] ** 2 - RHO[0] ** 2) * (THETA[1] - THETA[0]) / 2  # 0.02
TARGET_EXCESS = 0.032
EPSILONS = (0.01, 0.001)


def _best(fn, repeat: int) -> tuple[float, object]:
    fn()  # warm-up (numba compile / cache load, Codac function setup)
    best = float("inf")
    res = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = fn()
        best = min(best, time.perf_counter() - t0)
    return best, res


def ours(eps: float, sub: int = 0, repeat: int = 20) -> dict:
    from ivslam_cli import paving

    s = paving.polar_set((0.0, 0.0), RHO, THETA)
    t, p = _best(lambda: paving.pave(s, DOMAIN, eps, sub=sub), repeat)
    return {"time": t, "outer": p.outer_area(), "inner": p.inner_area(), "n": len(p)}


def codac(eps: float, kind: str = "SepInverse", repeat: int = 5) -> dict | None:
    try:
        import codac as C
    except ImportError:
        return None
    y = C.IntervalVector([list(RHO), list(THETA)])
    if kind == "SepInverse":
        x = C.VectorVar(2)
        f = C.AnalyticFunction([x], C.vec(C.sqrt(C.sqr(x[0]) + C.sqr(x[1])), C.atan2(x[1], x[0])))
        sep = C.SepInverse(f, y)
    else:
        sep = C.SepPolarCart(C.SepWrapper_IntervalVector(y))
    x0 = C.IntervalVector(DOMAIN)
    t, p = _best(lambda: C.pave(x0, sep, eps), repeat)
    outer = p.boxes(C.PavingInOut.outer)
    inner = p.boxes(C.PavingInOut.inner)
    return {"time": t, "outer": sum(b.volume() for b in outer),
            "inner": sum(b.volume() for b in inner), "n": len(outer)}


def _row(name: str, eps: float, r: dict) -> str:
    ex = (r["outer"] - EXACT) / EXACT
    return (f"  {name:26s} {eps:7.3f} {r['time'] * 1e3:10.2f} {r['n']:8d} {r['outer']:.6f} "
            f"{r['inner']:.6f} {ex * 100:8.2f} %")


def main() -> int:
    """Print the table; return 1 if a target (excess at eps=0.01, time vs Codac) is missed."""
    print(f"bench_paving: ring sector rho {list(RHO)} theta {list(THETA)} in [-10, 10]^2, "
          f"exact area {EXACT:.6f}")
    print(f"  {'method':26s} {'eps':>7s} {'time ms':>10s} {'boxes':>8s} {'outer':>8s} "
          f"{'inner':>8s} {'excess':>10s}")
    summary = []
    missed = False
    for eps in EPSILONS:
        r = ours(eps)
        print(_row("ivslam pave", eps, r))
        if eps == EPSILONS[0]:
            for sub in (1, 2):
                print(_row(f"ivslam pave sub={sub}", eps, ours(eps, sub=sub)))
        c = codac(eps)
        if c is not None:
            print(_row("codac pave(SepInverse)", eps, c))
            cp = codac(eps, "SepPolarCart")
            print(_row("codac pave(SepPolarCart)", eps, cp))
            summary.append((eps, r, c))
        else:
            print("  codac not installed: no comparison")
    for eps, r, c in summary:
        speed = c["time"] / r["time"]
        ex, cex = (r["outer"] - EXACT) / EXACT, (c["outer"] - EXACT) / EXACT
        ok_t = "ok" if speed > 1.0 else "SLOWER THAN CODAC"
        missed |= speed <= 1.0
        line = (f"  eps={eps}: {speed:.1f}x faster than Codac SepInverse ({ok_t}); outer excess "
                f"{ex * 100:.2f} % vs Codac {cex * 100:.2f} %")
        if eps == 0.01:
            line += f" (target <= {TARGET_EXCESS * 100:.1f} %: {'ok' if ex <= TARGET_EXCESS else 'ABOVE TARGET'})"
            missed |= ex > TARGET_EXCESS
        print(line)
    return 1 if missed else 0


if __name__ == "__main__":
    raise SystemExit(main())
