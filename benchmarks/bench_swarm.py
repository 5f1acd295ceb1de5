"""Swarm quality at an equal evaluation budget: kinecal's PSO, DE and GA against their peers.

Run ``python benchmarks/bench_swarm.py [--quick] [--out benchmarks/results/swarm.md]``.

Every optimizer gets the same number of objective evaluations (``2000 n`` in ``n`` dimensions)
on the same problem instances: shifted (and for two functions rotated) standard test functions
whose shift vector and rotation matrix are drawn from the run's seed, so that no setting is
tuned to one instance. The table gives the median over seeds of the best cost found (every
function's minimum is 0); the ratios to the best peer count costs below 1e-8 as solved.

- kinecal: ``pso`` (constriction PSO), ``de`` (JADE-style adaptive DE), ``ga`` (SBX GA) with
  their defaults, and the papers' variants ``pso-liu2008``, ``de-storn1997``, ``ga-hu2005``.
- pyswarms ``GlobalBestPSO`` with the options of its documentation's first example
  (``c1 = 0.5, c2 = 0.3, w = 0.9``) and with the usual constriction-equivalent setting
  (``c1 = c2 = 1.49618, w = 0.7298``), as many particles as kinecal's ``pso``, its default
  boundary handling; seeded through numpy's global state (its only source).
- scipy ``differential_evolution`` with its defaults (``best1bin``, ``popsize = 15``,
  ``mutation = (0.5, 1)``, ``recombination = 0.7``, Latin hypercube start, immediate updating)
  except ``tol = atol = 0`` (no early stop, the whole budget is used) and ``polish = False``
  (polishing would spend evaluations outside the budget); and the same with ``popsize = 5``
  (``5 n`` individuals, as kinecal's ``de``: more generations within the budget), vectorized
  (``updating="deferred"``, scipy's documented batch path).
- mealpy ``GA.BaseGA`` with its defaults (100 individuals, ``pc = 0.95``, ``pm = 0.025``,
  tournament with ``k_way = 0.2``, uniform crossover, flip mutation).

Tuning: kinecal's new defaults were chosen on the shifted ellipsoid and Rosenbrock functions
(10-D and 30-D) with instance seeds 100-104 only (``--seed-offset 100``); the table uses seeds
0-4 and adds functions that were not looked at while tuning (rotated ellipsoid, Rastrigin,
Ackley, Griewank, Schwefel 1.2).
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy
from scipy.optimize import differential_evolution
from scipy.stats import special_ortho_group

from kinecal._files import write_text_atomic
from kinecal.optimize import get_method, minimize

try:
    import pyswarms
    from pyswarms.single import GlobalBestPSO
except ImportError:  # optional peer
    pyswarms = None

try:
    import mealpy
    from mealpy import GA as MEALPY_GA
    from mealpy import FloatVar
except ImportError:  # optional peer
    mealpy = None

Vectorized = Callable[[np.ndarray], np.ndarray]
BUDGET_PER_DIM = 2000
#: costs below this count as solved (the CEC convention: errors < 1e-8 are taken as 0), so two
#: solved medians have the ratio 1 however many digits beyond it either reached
SOLVED = 1e-8


# -- problems: (P, n) -> (P,), minimum 0 at the shift --------------------------------------------
@dataclass
class Problem:
    """One instance: the vectorized objective, its box half-width and whether we tuned on it."""

    name: str
    n: int
    fun: Vectorized
    half: float
    tuned: bool


def _ellipsoid_weights(n: int) -> np.ndarray:
    return 10.0 ** (6.0 * np.arange(n) / max(n - 1, 1))  # condition number 1e6


def make_problem(name: str, n: int, seed: int) -> Problem:
    """Draw the instance ``seed`` of function ``name`` in ``n`` dimensions."""
    half = HALF[name]
    rng = np.random.default_rng([seed, n, sorted(HALF).index(name)])
    o = rng.uniform(-0.8 * half, 0.8 * half, n)  # optimum well inside the box
    R = special_ortho_group.rvs(n, random_state=rng) if name.startswith("rotated") else None
    w = _ellipsoid_weights(n)

    def z(X: np.ndarray) -> np.ndarray:
        Z = X - o
        return Z @ R.T if R is not None else Z

    def ellipsoid(X: np.ndarray) -> np.ndarray:
        Z = z(X)
        return (Z * Z) @ w

    def rosenbrock(X: np.ndarray) -> np.ndarray:
        Z = z(X) + 1.0
        return np.sum(100.0 * (Z[:, 1:] - Z[:, :-1] ** 2) ** 2 + (1.0 - Z[:, :-1]) ** 2, axis=1)

    def rastrigin(X: np.ndarray) -> np.ndarray:
        Z = z(X)
        return 10.0 * n + np.sum(Z * Z - 10.0 * np.cos(2.0 * np.pi * Z), axis=1)

    def ackley(X: np.ndarray) -> np.ndarray:
        Z = z(X)
        a = -20.0 * np.exp(-0.2 * np.sqrt(np.einsum("ij,ij->i", Z, Z) / n))
        return a - np.exp(np.mean(np.cos(2.0 * np.pi * Z), axis=1)) + 20.0 + np.e

    def griewank(X: np.ndarray) -> np.ndarray:
        Z = z(X)
        c = np.prod(np.cos(Z / np.sqrt(np.arange(1, n + 1))), axis=1)
        return np.einsum("ij,ij->i", Z, Z) / 4000.0 - c + 1.0

    def schwefel12(X: np.ndarray) -> np.ndarray:
        S = np.cumsum(z(X), axis=1)
        return np.einsum("ij,ij->i", S, S)

    funs = {
        "ellipsoid": ellipsoid,
        "rotated ellipsoid": ellipsoid,
        "rosenbrock": rosenbrock,
        "rastrigin": rastrigin,
        "ackley": ackley,
        "griewank": griewank,
        "schwefel 1.2": schwefel12,
    }
    return Problem(name, n, funs[name], half, name in TUNED)


#: box half-widths (the usual domains)
HALF = {
    "ellipsoid": 5.0,
    "rosenbrock": 5.0,
    "rotated ellipsoid": 5.0,
    "rastrigin": 5.12,
    "ackley": 32.768,
    "griewank": 600.0,
    "schwefel 1.2": 100.0,
}
FUNCTIONS = tuple(HALF)
#: the functions kinecal's defaults were tuned on (instance seeds 100-104 only)
TUNED = ("ellipsoid", "rosenbrock")


def scalar(fun: Vectorized) -> Callable[[np.ndarray], float]:
    """One point ``(n,)`` -> float, for the peers that call the objective point by point."""
    return lambda x: float(fun(np.asarray(x, dtype=float)[None, :])[0])


# -- runners: best cost within the budget ---------------------------------------------------------
def run_kinecal(method: str, p: Problem, budget: int, seed: int) -> float:
    res = minimize(p.fun, [(-p.half, p.half)] * p.n, method, rng=seed, maxiter=10**9,
                   maxfev=budget)
    return float(res.fun)


def pso_particles() -> int:
    """Swarm size of kinecal's ``pso`` default, also given to pyswarms."""
    return int(get_method("pso").defaults["popsize"])


def run_pyswarms(options: dict[str, float], p: Problem, budget: int, seed: int) -> float | None:
    if pyswarms is None:
        return None
    P = pso_particles()
    np.random.seed(seed)  # noqa: NPY002 (pyswarms only draws from the global state)
    opt = GlobalBestPSO(n_particles=P, dimensions=p.n, options=dict(options),
                        bounds=(np.full(p.n, -p.half), np.full(p.n, p.half)))
    cost, _ = opt.optimize(p.fun, iters=budget // P, verbose=False)  # one swarm per iteration
    return float(cost)


def run_scipy_de(p: Problem, budget: int, seed: int) -> float:
    pop = 15 * p.n  # scipy's default popsize = 15 (times n)
    res = differential_evolution(scalar(p.fun), [(-p.half, p.half)] * p.n,
                                 maxiter=budget // pop - 1, tol=0.0, atol=0.0, polish=False,
                                 rng=seed)
    return float(res.fun)


def run_scipy_de_small(p: Problem, budget: int, seed: int) -> float:
    pop = 5 * p.n
    res = differential_evolution(lambda XT: p.fun(XT.T), [(-p.half, p.half)] * p.n, popsize=5,
                                 maxiter=budget // pop - 1, tol=0.0, atol=0.0, polish=False,
                                 vectorized=True, updating="deferred", rng=seed)
    return float(res.fun)


def run_mealpy_ga(p: Problem, budget: int, seed: int) -> float | None:
    if mealpy is None:
        return None
    pop = 100  # BaseGA's default pop_size
    problem = {"obj_func": scalar(p.fun), "minmax": "min", "log_to": None,
               "bounds": FloatVar(lb=(-p.half,) * p.n, ub=(p.half,) * p.n)}
    model = MEALPY_GA.BaseGA(epoch=budget // pop - 1, pop_size=pop)  # + the initial population
    best = model.solve(problem, seed=seed)
    return float(best.target.fitness)


PYSWARMS_DOCS = {"c1": 0.5, "c2": 0.3, "w": 0.9}
PYSWARMS_CLERC = {"c1": 1.49618, "c2": 1.49618, "w": 0.7298}

#: row label -> runner(problem, budget, seed); ``None`` results mean "peer not installed"
RUNNERS: dict[str, Callable[[Problem, int, int], float | None]] = {
    "kinecal pso": lambda p, b, s: run_kinecal("pso", p, b, s),
    "kinecal pso-liu2008": lambda p, b, s: run_kinecal("pso-liu2008", p, b, s),
    "pyswarms GlobalBestPSO (docs options)": lambda p, b, s: run_pyswarms(PYSWARMS_DOCS, p, b, s),
    "pyswarms GlobalBestPSO (w 0.7298, c 1.49618)": lambda p, b, s: run_pyswarms(
        PYSWARMS_CLERC, p, b, s),
    "kinecal de": lambda p, b, s: run_kinecal("de", p, b, s),
    "kinecal de-storn1997": lambda p, b, s: run_kinecal("de-storn1997", p, b, s),
    "scipy differential_evolution (defaults)": run_scipy_de,
    "scipy differential_evolution (popsize 5, vectorized)": run_scipy_de_small,
    "kinecal ga": lambda p, b, s: run_kinecal("ga", p, b, s),
    "kinecal ga-hu2005": lambda p, b, s: run_kinecal("ga-hu2005", p, b, s),
    "mealpy BaseGA (defaults)": run_mealpy_ga,
}
#: kinecal's default -> the peers it must come within 2x of (the best of them per function)
TARGETS = {
    "kinecal pso": ("pyswarms GlobalBestPSO (docs options)",
                    "pyswarms GlobalBestPSO (w 0.7298, c 1.49618)"),
    "kinecal de": ("scipy differential_evolution (defaults)",
                   "scipy differential_evolution (popsize 5, vectorized)"),
    "kinecal ga": ("mealpy BaseGA (defaults)",),
}


def run_all(dims: list[int], functions: list[str], rows: list[str], seeds: list[int],
            verbose: bool) -> tuple[dict, dict]:
    """Results ``{(row, n, function): [best per seed]}`` and seconds ``{row: total}``."""
    out: dict[tuple[str, int, str], list[float]] = {}
    seconds: dict[str, float] = dict.fromkeys(rows, 0.0)
    for n in dims:
        budget = BUDGET_PER_DIM * n
        for name in functions:
            for s in seeds:
                p = make_problem(name, n, s)
                for row in rows:
                    t0 = time.perf_counter()
                    v = RUNNERS[row](p, budget, s)
                    seconds[row] += time.perf_counter() - t0
                    if v is not None:
                        out.setdefault((row, n, name), []).append(v)
            if verbose:
                print(f"  done {n}-D {name}", file=sys.stderr, flush=True)
    return out, seconds


def fmt(v: float | None) -> str:
    return "n/a" if v is None else f"{v:.3g}"


def tables(out: dict, dims: list[int], functions: list[str], rows: list[str],
           seeds: list[int]) -> list[str]:
    lines: list[str] = []
    head = " | ".join(f"{f}{'' if f in TUNED else ' (not tuned on)'}" for f in functions)
    med = {k: float(np.median(v)) for k, v in out.items()}
    for n in dims:
        lines += [
            f"### {n}-D, budget {BUDGET_PER_DIM * n} evaluations, median over {len(seeds)} "
            f"seeds (instances {seeds[0]}-{seeds[-1]})",
            "",
            f"| optimizer | {head} |",
            "|---|" + "---:|" * len(functions),
        ]
        for row in rows:
            cells = [fmt(med.get((row, n, f))) for f in functions]
            lines.append(f"| {row} | " + " | ".join(cells) + " |")
        lines += ["", f"Ratio of kinecal's default to the best peer median ({n}-D; <= 2 is the "
                      "issue's target, < 1 is better than the peer; medians below "
                      f"{SOLVED:g} count as {SOLVED:g}, i.e. solved):", "",
                  f"| kinecal | {' | '.join(functions)} |", "|---|" + "---:|" * len(functions)]
        for row, peers in TARGETS.items():
            if row not in rows:
                continue
            cells = []
            for f in functions:
                ref = [med[(q, n, f)] for q in peers if (q, n, f) in med]
                mine = med.get((row, n, f))
                if mine is None or not ref:
                    cells.append("n/a")
                    continue
                r = max(mine, SOLVED) / max(min(ref), SOLVED)
                cells.append(f"{r:.2g}" if r >= 0.01 else f"{r:.1e}")
            lines.append(f"| {row.removeprefix('kinecal ')} | " + " | ".join(cells) + " |")
        lines.append("")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="10-D only, 2 seeds")
    ap.add_argument("--seeds", type=int, default=5, help="seeds (instances) per function")
    ap.add_argument("--seed-offset", type=int, default=0,
                    help="first instance seed (the defaults were tuned on 100-104)")
    ap.add_argument("--dims", default="10,30", help="comma-separated dimensions")
    ap.add_argument("--functions", default=",".join(FUNCTIONS),
                    help=f"comma-separated, from: {', '.join(FUNCTIONS)}")
    ap.add_argument("--rows", default="", help="comma-separated substrings of the row labels")
    ap.add_argument("--out", type=Path, help="also write the markdown tables to this file")
    args = ap.parse_args(argv)
    dims = [10] if args.quick else [int(d) for d in args.dims.split(",")]
    nseeds = 2 if args.quick else args.seeds
    seeds = list(range(args.seed_offset, args.seed_offset + nseeds))
    functions = [f.strip() for f in args.functions.split(",")]
    bad = sorted(set(functions) - set(FUNCTIONS))
    if bad:
        ap.error(f"unknown function(s) {bad}; valid: {', '.join(FUNCTIONS)}")
    wanted = [w.strip() for w in args.rows.split(",") if w.strip()]
    rows = [r for r in RUNNERS if not wanted or any(w in r for w in wanted)]
    t0 = time.perf_counter()
    out, seconds = run_all(dims, functions, rows, seeds, verbose=True)
    text = [
        "# Swarm quality at an equal evaluation budget (`benchmarks/bench_swarm.py`)",
        "",
        f"python {sys.version.split()[0]}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"pyswarms {getattr(pyswarms, '__version__', 'not installed')}, "
        f"mealpy {getattr(mealpy, '__version__', 'not installed')}"
        + (" (quick mode)" if args.quick else ""),
        "",
        *tables(out, dims, functions, rows, seeds),
        "Seconds per optimizer, all runs: " + ", ".join(
            f"{r.removeprefix('kinecal ')} {seconds[r]:.1f}" for r in rows)
        + f" (total {time.perf_counter() - t0:.0f} s).",
    ]
    print("\n".join(text), flush=True)
    if args.out is not None:
        write_text_atomic(args.out, "\n".join(text) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
