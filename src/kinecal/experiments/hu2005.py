"""``kinecal reproduce hu2005``: Hu, Xiao and Li (2005), LS + GA hybrid calibration.

The six-joint articulated-arm scanner of Hu, Xiao and Li (2005), Table 1 (bundled model
``hu2005-scanner`` with its true errors ``hu2005-scanner.truth.json``) is calibrated from
simulated probe positions with the three methods of Table 2 and kinecal's default:

``householder``
    The paper's "modified least squares" (sec. 3-4.1, eq. 10-11: Gauss-Newton, each step
    solved by Householder QR) on all 25 parameters. kinecal's implementation detects the
    two singular directions of ``S`` (the paper's complaint that ``G^T G`` becomes singular,
    sec. 4) and freezes them; ``householder-literal`` is the same iteration with the
    paper's literal ``S^-1`` back substitution, which needs the singular pivots.
``ga``
    The real-coded GA of sec. 4.2 (L = 30, Pc = 0.95, Pm = 0.01, roulette on 1 / (s + 1),
    arithmetic crossover, reset mutation, elitism) in the tolerance box around nominal,
    stopped at eps = 0.1 mm (sec. 5): kinecal's method ``ga-hu2005`` (its ``ga`` is Deb's
    SBX GA).
``hybrid-ga``
    Sec. 4.2 items 1-2: least squares first, then the GA with gene ranges centred on the
    LS solution and shrunk to 1/3 of the tolerance (kinecal's ``hybrid-ga-hu2005``). Two
    variants: kinecal's LS stage (Householder, 4 iterations: the paper's LS gains nothing
    after iteration 4) and an LS stage stopped after one iteration, whose 0.5 mm start
    resembles the paper's hybrid start (0.42 mm; its LS stalled at 0.91 mm).
``lm``
    kinecal's default: Levenberg-Marquardt on the identifiable parameters.
``ga`` / ``hybrid-ga`` with ``selection="tournament"``
    Beyond the paper: the same algorithms with binary tournament selection instead of the
    roulette (whose 1 / (s + 1) fitness hardly discriminates small errors).

Calibration points (the paper does not say how many or how they were chosen): 50 poses
with every joint uniform in [-180, 180] deg, noise-free probe positions of the true arm
(the paper's GA reaches 0.094 mm, which rules out measurement noise of that order); 100
further random poses are held out for validation. ``--quick`` uses 20 + 50 poses and small
generation budgets. The full run adds the GA and LM on 10 calibration poses (the count
used by Hu, Xiao and Li (2005)'s reference [2]) to show fitting without finding the geometry.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from importlib.resources import files
from pathlib import Path
from typing import Any

import numpy as np

from kinecal import diagnostics
from kinecal.calibration.serial.api import calibrate
from kinecal.calibration.serial.problem import CalibrationProblem
from kinecal.calibration.serial.result import CalibrationResult
from kinecal.calibration.serial.simulate import read_truth, simulate
from kinecal.experiments._serial_common import (
    checkpoints,
    format_table,
    progress_bar,
    result_row,
    write_convergence_png,
)
from kinecal.io.models import load_model
from kinecal.optimize.lsq import householder_gauss_newton

__all__ = ["PAPER", "paper_name", "render", "run"]

#: Hu, Xiao and Li (2005), Table 2 (mean distance error in mm at the given iteration) and sec. 5
PAPER: dict[str, Any] = {
    "table2": {
        "householder": {1: 25.0143, 2: 2.0588, 3: 1.52944, 4: 0.91343, 5: 0.91343,
                        1000: 0.91341},
        "ga": {1: 10.1303, 100: 9.8435, 1000: 5.4629, 10000: 1.4927, 20000: 0.2383,
               28769: 0.09364},
        "hybrid-ga": {1: 0.4233, 10: 0.3962, 50: 0.2458, 100: 0.1302, 200: 0.1177,
                      262: 0.0939},
    },
    "eps_mm": 0.1,
    "ga_options": {"popsize": 30, "pc": 0.95, "pm": 0.01},
    "ga_generations": 28769,
    "hybrid_generations": 262,
}

#: the rows' method names (the paper's) -> kinecal's methods: the paper's GA is ``ga-hu2005``
PAPER_METHODS = {"ga": "ga-hu2005", "hybrid-ga": "hybrid-ga-hu2005"}

#: experiment sizes: calibration / validation poses, GA budgets, seeds of the GA studies
SIZES = {
    "full": {"n_cal": 50, "n_val": 100, "ga_maxiter": 30000, "seeds": 3, "literal_iter": 20},
    "quick": {"n_cal": 20, "n_val": 50, "ga_maxiter": 300, "seeds": 1, "literal_iter": 8},
}


def paper_name(name: str) -> str:
    """The paper's name of a kinecal parameter: its d_i are our a_i, its h_i our d_i."""
    if name == "tool.z":
        return "h7"
    if name[0] == "a" and name[1:].isdigit():
        return "d" + name[1:]
    if name[0] == "d" and name[1:].isdigit():
        return "h" + name[1:]
    return name


def _truth(model) -> np.ndarray:
    path = files("kinecal") / "robots" / "hu2005-scanner.truth.json"
    return read_truth(Path(str(path)), model)


def _literal_householder(model, data, maxiter: int) -> dict[str, Any]:
    """The paper's eq. (11) step by Householder QR with literal ``S^-1`` (no singular guard)."""
    problem = CalibrationProblem(model, data, model.calibratable)
    with np.errstate(all="ignore"):
        res = householder_gauss_newton(problem.residuals, problem.jacobian, problem.x0,
                                       maxiter=maxiter, singular_tol=0.0, xtol=0.0,
                                       monitor=problem.mean_distance_from_residuals)
    import scipy.linalg

    R = scipy.linalg.qr(problem.jacobian(problem.x0), mode="r")[0]
    diag = np.abs(np.diag(R))
    return {
        "history": [float(h) for h in res.history],
        "iterations": int(res.nit),
        "evaluations": int(res.nfev),
        "seconds": float(res.elapsed),
        "smallest_pivots": sorted(float(v) for v in diag)[:3],
        "largest_pivot": float(diag.max()),
        "x": res.x,
    }


def _ga_study(model, cal, val, method: str, seeds: list[int], maxiter: int, quiet: bool,
              options: dict | None = None) -> tuple[CalibrationResult, list[dict]]:
    first, runs = None, []
    for s in seeds:
        with progress_bar(f"{method} seed {s}", maxiter, quiet) as cb:
            # the paper's GA searches the tolerance box around nominal (sec. 4.2), not the
            # box derived from the data (calibration.serial.box)
            box = {} if method.startswith("hybrid-") else {"box": "tolerances"}
            res = calibrate(model, cal, PAPER_METHODS[method], free="all", validate=val, rng=s,
                            maxiter=maxiter, target=PAPER["eps_mm"],
                            options={**(options or {}), **box}, progress=cb)
        first = first or res
        runs.append({
            "seed": s,
            "generations": int(res.iterations),
            "reached_eps": _done(res),
            "calibration_mean": float(res.errors_after.mean()),
            "validation_mean": float(res.val_after.mean()),
            "seconds": float(res.seconds),
        })
    assert first is not None
    return first, runs


def _done(res: CalibrationResult) -> bool:
    return bool(res.errors_after.mean() <= PAPER["eps_mm"])


def _summary(runs: list[dict]) -> dict[str, Any]:
    g = np.array([r["generations"] for r in runs], dtype=float)
    return {"runs": runs, "generations_to_eps": [r["generations"] for r in runs],
            "generations_median": float(np.median(g)),
            "reached_eps": int(sum(r["reached_eps"] for r in runs))}


#: diagnostics the paper's setup raises on purpose: it frees all 25 parameters (4 of them
#: confounded on the last link), in --quick and the 10-pose study uses fewer poses than 3
#: equations per parameter, and its GA and hybrid stop above what a least-squares polish
#: reaches (the comparison the experiment is about); kinecal reproduces that setup and says
#: so here instead of warning about it on every run
EXPECTED = ("unidentifiable-free", "few-poses", "optimizer-stalled")


def run(quick: bool = False, seed: int = 0, out_dir: Path | None = None,
        quiet: bool = True) -> dict[str, Any]:
    """Run the experiment of Hu, Xiao and Li (2005) (see `_run`), the paper's setup
    diagnostics expected."""
    with diagnostics.expect(*EXPECTED) as seen:
        result = _run(quick, seed, out_dir, quiet)
    result["expected_warnings"] = sorted({d.code for d in seen})
    return result


#: the iterations at which the paper's Table 2 gives each method's error
IT_LS = list(PAPER["table2"]["householder"])
IT_GA = list(PAPER["table2"]["ga"])
IT_HY = list(PAPER["table2"]["hybrid-ga"])


@dataclass
class _Rows:
    """The experiment's table rows and the convergence curves of the figure."""

    rows: list[dict[str, Any]] = field(default_factory=list)
    curves: dict[str, list[float]] = field(default_factory=dict)
    evals: dict[str, int] = field(default_factory=dict)

    def add(self, row: dict[str, Any], curve: str | None = None,
            history: list[float] | None = None, evaluations: int = 0) -> None:
        self.rows.append(row)
        if curve is not None:
            self.curves[curve], self.evals[curve] = list(history or []), int(evaluations)


def _least_squares_rows(out: _Rows, model, cal, val, size: dict) -> None:
    """1. The paper's least squares on all 25 parameters (sec. 4.1), kinecal's Householder
    and the literal normal-equation version."""
    ls = calibrate(model, cal, "householder", free="all", validate=val, maxiter=1000)
    out.add(result_row("householder", ls, PAPER["table2"]["householder"][1000],
                       table2=checkpoints(ls.history, IT_LS), message=ls.message),
            "householder (25 parameters)", ls.history, ls.evaluations)
    lit = _literal_householder(model, cal, size["literal_iter"])
    lit_val = float(np.linalg.norm(
        model.positions(val.q, CalibrationProblem(model, cal, model.calibratable).full(lit["x"]))
        - val.xyz, axis=1).mean())
    out.add({"method": "householder-literal", "free": len(model.calibratable),
             "iterations": lit["iterations"], "evaluations": lit["evaluations"],
             "seconds": lit["seconds"], "calibration_mean": lit["history"][-1],
             "validation_mean": lit_val, "paper_value": None,
             "table2": checkpoints(lit["history"], [k for k in IT_LS if k <= 10]),
             "smallest_pivots": lit["smallest_pivots"], "largest_pivot": lit["largest_pivot"]})


def _ga_rows(out: _Rows, model, cal, val, seeds: list[int], size: dict, quiet: bool) -> None:
    """2.-3b. The paper's GA in the tolerance box (sec. 4.2, 5), its hybrid (sec. 4.2 items
    1-2) with kinecal's LS stage and a one-iteration one, and beyond the paper both with
    tournament selection (the roulette on 1 / (s + 1) has almost no selection pressure once
    errors are small)."""
    ga, ga_runs = _ga_study(model, cal, val, "ga", seeds, size["ga_maxiter"], quiet)
    out.add(result_row("ga", ga, PAPER["table2"]["ga"][28769],
                       table2=checkpoints(ga.history, IT_GA, _done(ga)),
                       paper_iterations=28769, **_summary(ga_runs)), "ga", ga.history,
            ga.evaluations)
    for ls_iter in (4, 1):
        hy, hy_runs = _ga_study(model, cal, val, "hybrid-ga", seeds, size["ga_maxiter"], quiet,
                                options={"ls_maxiter": ls_iter})
        row = result_row("hybrid-ga", hy, PAPER["table2"]["hybrid-ga"][262],
                         variant=f"least squares stopped after {ls_iter} iteration(s)",
                         ls_iterations=ls_iter,
                         table2=checkpoints(hy.history[1:], IT_HY, _done(hy)),
                         paper_iterations=262, **_summary(hy_runs))
        # the GA's generations (history[0] is the LS end point, also seeded into the GA)
        out.add(row, _label(row) + ", GA generations", hy.history[1:], hy.evaluations)
    for method, opts in (("ga", {}), ("hybrid-ga", {"ls_maxiter": 1})):
        opts = {**opts, "selection": "tournament"}
        tg, tg_runs = _ga_study(model, cal, val, method, seeds, size["ga_maxiter"], quiet,
                                options=opts)
        hist = tg.history[1:] if method == "hybrid-ga" else tg.history
        extra = {"ls_iterations": 1} if method == "hybrid-ga" else {}
        row = result_row(method, tg, None, selection="tournament",
                         table2=checkpoints(hist, IT_HY if extra else IT_GA, _done(tg)),
                         **extra, **_summary(tg_runs))
        out.add(row, _label(row) + (", GA generations" if extra else ""), hist,
                tg.evaluations)


def _run(quick: bool = False, seed: int = 0, out_dir: Path | None = None,
         quiet: bool = True) -> dict[str, Any]:
    """Run the Hu, Xiao and Li (2005) experiment; see the module docstring.

    Returns
    -------
    dict
        ``{"paper": "hu2005", "identifiable", "unidentifiable", "setup", "rows", "paper"}``;
        every row has ``method, iterations, evaluations, seconds, calibration_mean,
        validation_mean, paper_value`` (mm) and ``table2`` (our value at the paper's
        iterations). GA rows add per-seed ``runs`` and ``generations_to_eps``.
    """
    size = SIZES["quick" if quick else "full"]
    model = load_model("hu2005-scanner")
    truth = _truth(model)
    rng = np.random.default_rng(seed)
    cal = simulate(model, size["n_cal"], errors=truth - model.nominal, rng=rng).data
    val = simulate(model, size["n_val"], errors=truth - model.nominal, rng=rng).data
    seeds = [seed + k for k in range(size["seeds"])]
    out = _Rows()
    _least_squares_rows(out, model, cal, val, size)
    _ga_rows(out, model, cal, val, seeds, size, quiet)
    if not quick:
        # 3c. the GA on 10 calibration poses (the count of the paper's ref. [2]): it fits
        # them to eps but the geometry it finds is not the true one
        cal10 = simulate(model, 10, errors=truth - model.nominal, rng=rng).data
        g10, g10_runs = _ga_study(model, cal10, val, "ga", seeds[:1], size["ga_maxiter"], quiet)
        lm10 = calibrate(model, cal10, "lm", validate=val)
        out.add(result_row("ga", g10, None, variant="10 calibration poses", poses=10,
                           **_summary(g10_runs)))
        out.add(result_row("lm", lm10, None, variant="10 calibration poses", poses=10))
    # 4. kinecal's default
    lm = calibrate(model, cal, "lm", validate=val)
    out.add(result_row("lm", lm, None, table2=checkpoints(lm.history, IT_LS)),
            "lm (identifiable), per evaluation", lm.history, lm.evaluations)
    rows, curves, evals = out.rows, out.curves, out.evals
    rep = lm.identifiability
    result: dict[str, Any] = {
        "paper": "hu2005",
        "source": "Hu, Xiao and Li (2005)",
        "units": "mm",
        "identifiable": list(lm.free),
        "unidentifiable": list(rep.unidentifiable),
        "unidentifiable_paper_names": [paper_name(n) for n in rep.unidentifiable],
        "rank": int(rep.rank),
        "parameters": len(model.calibratable),
        "setup": {
            "model": "hu2005-scanner",
            "truth": "hu2005-scanner.truth.json (Hu, Xiao and Li 2005, Table 1)",
            "calibration_poses": size["n_cal"],
            "validation_poses": size["n_val"],
            "poses": "every joint uniform in [-180, 180] deg, noise-free",
            "ga_options": PAPER["ga_options"],
            "eps_mm": PAPER["eps_mm"],
            "ga_maxiter": size["ga_maxiter"],
            "seeds": seeds,
            "tolerances": dict(model.tolerances),
            "quick": quick,
        },
        "paper_values": {k: {str(i): v for i, v in t.items()}
                         for k, t in PAPER["table2"].items()},
        "rows": rows,
    }
    if out_dir is not None:
        png = write_convergence_png(
            Path(out_dir) / "hu2005-convergence.png", curves,
            "Hu, Xiao and Li (2005) scanner: mean distance error", evaluations=evals,
            hline=PAPER["eps_mm"])
        result["figure"] = str(png)
    return result


def _label(row: dict[str, Any]) -> str:
    """Row label: method, LS iterations of a hybrid, selection, pose count."""
    label = row["method"]
    if "ls_iterations" in row:
        label += f" (LS {row['ls_iterations']} it.)"
    if row.get("selection", "roulette") != "roulette":
        label += f" ({row['selection']})"
    if "poses" in row:
        label += f" ({row['poses']} poses)"
    return label


def render(result: dict[str, Any]) -> str:
    """Table 2 beside ours, then the summary table with validation errors."""
    setup = result["setup"]
    out = [
        "Hu, Xiao and Li (2005): scanner of Table 1, "
        f"{setup['calibration_poses']} calibration + {setup['validation_poses']} validation "
        f"poses ({setup['poses']}); errors in mm",
        f"identifiable: {result['rank']} of {result['parameters']} parameters; not separable: "
        + ", ".join(f"{n} (paper {p})" for n, p in zip(result["unidentifiable"],
                                                      result["unidentifiable_paper_names"],
                                                      strict=True)),
        "",
        "Table 2 (paper iteration k = start + k - 1 steps; our value of the first seed)",
    ]
    t2 = []
    for r in result["rows"]:
        if r["method"] in ("householder", "ga", "hybrid-ga") and "poses" not in r:
            for k, v in result["paper_values"][r["method"]].items():
                t2.append([_label(r), int(k), v, r["table2"].get(k)])
    out.append(format_table(["method", "iteration", "paper", "kinecal"], t2))
    out.append("")
    rows = []
    for r in result["rows"]:
        label = _label(r)
        gens = r.get("generations_to_eps")
        rows.append([label, r["free"], r["iterations"], r["evaluations"], r["seconds"],
                     r["calibration_mean"], r["validation_mean"], r["paper_value"],
                     ", ".join(str(g) for g in gens) if gens else "-"])
    out.append(format_table(
        ["method", "free", "iterations", "evaluations", "seconds", "calibration mean",
         "validation mean", "paper", "generations per seed"], rows))
    out.append(f"paper: GA reaches eps = {PAPER['eps_mm']} mm after {PAPER['ga_generations']} "
               f"generations, the hybrid after {PAPER['hybrid_generations']}")
    if "figure" in result:
        out.append(f"figure: {result['figure']}")
    return "\n".join(out)
