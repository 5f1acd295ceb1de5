"""Benchmark of kinecal.optimize: per-iteration overhead and solution quality.

Run ``python benchmarks/bench_optimizers.py [--quick] [--out FILE.md]``.

1. Overhead: time per iteration spent beside the objective (total run time minus the time inside
   the objective) at population 30, 50 and 100 in 10-D, for every kinecal method and, in the same
   process, pyswarms ``GlobalBestPSO`` and scipy ``differential_evolution(vectorized=True)``
   (each peer is skipped when not installed). Ratios are against pyswarms (and scipy DE).
2. Quality: best cost reached by every method with its default budget on shifted 10-D and 25-D
   sphere, Rastrigin, Rosenbrock and Ackley functions, median over seeds, beside pyswarms and
   scipy DE given the budget of kinecal's pso-liu2008 and de-storn1997 (whose settings they
   copy). Equal-budget medians against the peers' own defaults: ``bench_swarm.py``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import scipy
from scipy.optimize import differential_evolution

from kinecal.optimize import METHODS, minimize

try:
    import pyswarms
    from pyswarms.single import GlobalBestPSO
except ImportError:  # optional peer
    pyswarms = None

try:
    from kinecal._files import write_text_atomic
except ImportError:  # pragma: no cover
    write_text_atomic = None


# -- test functions (vectorized over rows; global minimum 0 at the shift) --------------------
def _shift(n: int) -> np.ndarray:
    return np.linspace(-1.7, 2.3, n)


def sphere(X: np.ndarray) -> np.ndarray:
    Z = X - _shift(X.shape[1])
    return np.einsum("ij,ij->i", Z, Z)


def rastrigin(X: np.ndarray) -> np.ndarray:
    Z = X - _shift(X.shape[1])
    return 10.0 * X.shape[1] + np.sum(Z * Z - 10.0 * np.cos(2.0 * np.pi * Z), axis=1)


def rosenbrock(X: np.ndarray) -> np.ndarray:
    Z = X - _shift(X.shape[1]) + 1.0  # minimum at Z = 1
    return np.sum(100.0 * (Z[:, 1:] - Z[:, :-1] ** 2) ** 2 + (1.0 - Z[:, :-1]) ** 2, axis=1)


def ackley(X: np.ndarray) -> np.ndarray:
    Z = X - _shift(X.shape[1])
    n = X.shape[1]
    a = -20.0 * np.exp(-0.2 * np.sqrt(np.einsum("ij,ij->i", Z, Z) / n))
    return a - np.exp(np.mean(np.cos(2.0 * np.pi * Z), axis=1)) + 20.0 + np.e


FUNCTIONS: dict[str, tuple[Callable[[np.ndarray], np.ndarray], float]] = {
    "sphere": (sphere, 5.12),
    "rastrigin": (rastrigin, 5.12),
    "rosenbrock": (rosenbrock, 5.0),
    "ackley": (ackley, 32.0),
}


class Timed:
    """Objective wrapper that accumulates the time spent inside the objective."""

    def __init__(self, fun: Callable[[np.ndarray], np.ndarray], transpose: bool = False):
        self.fun, self.transpose, self.t, self.calls = fun, transpose, 0.0, 0

    def __call__(self, X: np.ndarray) -> np.ndarray:
        t0 = time.perf_counter()
        f = self.fun(X.T if self.transpose else X)
        self.t += time.perf_counter() - t0
        self.calls += 1
        return f


# -- overhead --------------------------------------------------------------------------------
#: evaluated points per iteration seen in the overhead runs, by (method, population)
POINTS_PER_ITER: dict[tuple[str, int], float] = {}


def overhead_kinecal(method: str, pop: int, n: int, iters: int, seed: int) -> float:
    """Per-iteration time beside the objective of one run (s)."""
    obj = Timed(sphere)
    t0 = time.perf_counter()
    res = minimize(
        obj, [(-5.12, 5.12)] * n, method, rng=seed, maxiter=iters, options={"popsize": pop}
    )
    elapsed = time.perf_counter() - t0 - obj.t
    POINTS_PER_ITER[(method, pop)] = res.nfev / max(res.nit, 1)
    return elapsed / max(res.nit, 1)


def overhead_pyswarms(pop: int, n: int, iters: int, seed: int) -> float | None:
    if pyswarms is None:
        return None
    np.random.seed(seed)  # noqa: NPY002 (pyswarms only draws from the global state)
    opt = GlobalBestPSO(
        n_particles=pop,
        dimensions=n,
        options={"c1": 1.8, "c2": 1.8, "w": 0.5},
        bounds=(np.full(n, -5.12), np.full(n, 5.12)),
    )
    obj = Timed(sphere)
    t0 = time.perf_counter()
    opt.optimize(obj, iters=iters, verbose=False)
    return (time.perf_counter() - t0 - obj.t) / iters


def overhead_scipy_de(pop: int, n: int, iters: int, seed: int) -> float | None:
    if pop % n:
        return None
    obj = Timed(sphere, transpose=True)
    t0 = time.perf_counter()
    res = differential_evolution(
        obj,
        [(-5.12, 5.12)] * n,
        popsize=pop // n,
        maxiter=iters,
        tol=0.0,
        atol=0.0,
        polish=False,
        init="random",
        vectorized=True,
        updating="deferred",
        rng=seed,
    )
    return (time.perf_counter() - t0 - obj.t) / max(res.nit, 1)


def overhead_table(quick: bool) -> list[str]:
    n, iters, reps = 10, (100 if quick else 300), (3 if quick else 7)
    pops = (30, 50, 100)
    runners: dict[str, Callable[[int, int], float | None]] = {
        m: (lambda p, r, m=m: overhead_kinecal(m, p, n, iters, r)) for m in METHODS
    }
    runners["pyswarms"] = lambda p, r: overhead_pyswarms(p, n, iters, r)
    runners["scipy-de"] = lambda p, r: overhead_scipy_de(p, n, iters, r)
    samples: dict[tuple[str, int], list[float | None]] = {}
    for r in range(reps):  # interleaved, so that machine load hits every method alike
        for p in pops:
            for name, run in runners.items():
                samples.setdefault((name, p), []).append(run(p, r))

    def best(name: str, p: int) -> float | None:
        vals = [v for v in samples[(name, p)] if v is not None]
        return min(vals) if vals else None

    rows = {m: [best(m, p) for p in pops] for m in METHODS}
    ps = [best("pyswarms", p) for p in pops]
    de = [best("scipy-de", p) for p in pops]
    lines = [
        f"Per-iteration overhead beside the objective, 10-D, {iters} iterations, best of "
        f"{reps} interleaved runs (ms); ratio = kinecal / peer (smaller is faster).",
        "",
        "| method | "
        + " | ".join(f"pop {p} (ms)" for p in pops)
        + " | "
        + " | ".join(f"/ pyswarms @{p}" for p in pops)
        + " | points/iter @50 | us/point @50 |",
        "|---|" + "---:|" * (2 * len(pops) + 2),
    ]

    def fmt(v: float | None) -> str:
        return "n/a" if v is None else f"{1e3 * v:.3f}"

    def ratio(a: float, b: float | None) -> str:
        return "n/a" if b is None else f"{a / b:.2f}x"

    def per_point(v: float | None, points: float) -> str:
        return "n/a" if v is None else f"{1e6 * v / points:.2f}"

    for m, vals in rows.items():
        pts = POINTS_PER_ITER[(m, 50)]
        lines.append(
            f"| {m} | "
            + " | ".join(fmt(v) for v in vals)
            + " | "
            + " | ".join(ratio(v, b) for v, b in zip(vals, ps, strict=True))
            + f" | {pts:.0f} | {per_point(vals[1], pts)} |"
        )
    for label, vals in (("pyswarms GlobalBestPSO", ps), ("scipy DE (vectorized)", de)):
        lines.append(
            f"| {label} | {' | '.join(fmt(v) for v in vals)} |"
            + " |" * 3
            + f" 50 | {per_point(vals[1], 50)} |"
        )
    lines += [
        "",
        "kinecal de / scipy DE: "
        + ", ".join(
            f"pop {p}: {ratio(v, b)}" for p, v, b in zip(pops, rows["de"], de, strict=True)
        ),
        "",
        "kinecal de-storn1997 / scipy DE: "
        + ", ".join(
            f"pop {p}: {ratio(v, b)}"
            for p, v, b in zip(pops, rows["de-storn1997"], de, strict=True)
        ),
        "",
        "AFSA and SA-IAFSA evaluate up to four batches per iteration (swarm centres, swarm and "
        "follow moves, prey tries, prey and random moves); IGWO two candidates and DLH-GWO-DE four "
        "per wolf in one batch.",
    ]
    return lines


# -- quality ---------------------------------------------------------------------------------
def run_pyswarms(fun, n: int, half: float, pop: int, iters: int, seed: int) -> float | None:
    if pyswarms is None:
        return None
    np.random.seed(seed)  # noqa: NPY002 (pyswarms only draws from the global state)
    opt = GlobalBestPSO(
        n_particles=pop,
        dimensions=n,
        options={"c1": 1.8, "c2": 1.8, "w": 0.3},
        bounds=(np.full(n, -half), np.full(n, half)),
    )
    cost, _ = opt.optimize(fun, iters=iters, verbose=False)
    return float(cost)


def run_scipy_de(fun, n: int, half: float, maxfev: int, seed: int) -> float:
    pop = 10  # x n individuals, as kinecal's de default
    res = differential_evolution(
        lambda XT: fun(XT.T),
        [(-half, half)] * n,
        popsize=pop,
        maxiter=max(maxfev // (pop * n) - 1, 1),
        tol=0.0,
        atol=0.0,
        polish=False,
        init="random",
        strategy="rand1bin",
        mutation=0.5,
        recombination=0.9,
        vectorized=True,
        updating="deferred",
        rng=seed,
    )
    return float(res.fun)


def quality_table(n: int, seeds: int) -> list[str]:
    names = [*METHODS, "pyswarms", "scipy-de"]
    lines = [
        f"{n}-D shifted functions, default budgets, median best cost over {seeds} seeds "
        "(minimum 0); [nfev] = evaluations used per run.",
        "",
        "| method | " + " | ".join(FUNCTIONS) + " | nfev |",
        "|---|" + "---:|" * (len(FUNCTIONS) + 1),
    ]
    results: dict[str, list[str]] = {m: [] for m in names}
    nfev: dict[str, int] = {}
    for fun, half in FUNCTIONS.values():
        bounds = [(-half, half)] * n
        for m in METHODS:
            vals = []
            for s in range(seeds):
                r = minimize(fun, bounds, m, rng=s)
                vals.append(r.fun)
                nfev[m] = r.nfev
            results[m].append(f"{np.median(vals):.3g}")
        ps = [run_pyswarms(fun, n, half, 80, 500, s) for s in range(seeds)]
        results["pyswarms"].append("n/a" if ps[0] is None else f"{np.median(ps):.3g}")
        nfev["pyswarms"] = 80 * 500
        budget = 10 * n * 1001
        results["scipy-de"].append(
            f"{np.median([run_scipy_de(fun, n, half, budget, s) for s in range(seeds)]):.3g}"
        )
        nfev["scipy-de"] = budget
    for m in names:
        lines.append(f"| {m} | " + " | ".join(results[m]) + f" | {nfev[m]} |")
    lines += [
        "",
        "pyswarms: GlobalBestPSO, 80 particles, 500 iterations, c1 = c2 = 1.8, fixed w = 0.3 "
        "(the mean of the paper-004 schedule). scipy-de: rand1bin, F = 0.5, CR = 0.9, 10 n "
        "individuals, the budget of kinecal's de-storn1997, no polishing.",
    ]
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer iterations, runs and seeds")
    ap.add_argument("--out", type=Path, help="also write the markdown tables to this file")
    ap.add_argument("--overhead-only", action="store_true", help="skip the quality tables")
    args = ap.parse_args(argv)
    head = [
        "# kinecal.optimize benchmark",
        "",
        f"python {sys.version.split()[0]}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"pyswarms {getattr(pyswarms, '__version__', 'not installed')}"
        + (" (quick mode)" if args.quick else ""),
        "",
        "## Overhead",
        "",
    ]
    text = head + overhead_table(args.quick)
    print("\n".join(text), flush=True)
    seeds = 2 if args.quick else 5
    for n in () if args.overhead_only else (10, 25):
        part = ["", f"## Quality, {n}-D", "", *quality_table(n, seeds)]
        print("\n".join(part), flush=True)
        text += part
    if args.out is not None:
        body = "\n".join(text) + "\n"
        if write_text_atomic is not None:
            write_text_atomic(args.out, body)
        else:  # pragma: no cover
            args.out.write_text(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
