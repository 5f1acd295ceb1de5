"""The Levenberg-Marquardt path of `calibrate`: identifiability, fit and growth in few passes.

Every pass over the poses costs about the same (one chunked forward-kinematics sweep, the
Jacobian rows of the free parameters and their Gram matrix), so the path is arranged to
make as few as possible, none of them over more than a chunk of rows at a time:

1. one pass at the nominal geometry gives the Gram matrix of ``[J | r]`` for every
   candidate parameter: the identifiability analysis (from a square root of the Gram
   matrix, exact enough for decisions at a relative threshold of `GRAM_TOL` and above;
   below, the exact TSQR factor of `kinecal.calibration.serial.problem.analyse_poses`), the
   first normal equations of the fit (their sub-matrix);
2. Levenberg-Marquardt on the identifiable set until the cost settles (relative
   reduction below `GROWTH_FTOL`);
3. one pass there for the parameters that became identifiable at the identified geometry
   (`grow_identifiable`): either the fit continues on the larger set, starting with a
   near Gauss-Newton step, or on the same set where it stopped; in both cases to full
   convergence, so that no pass is repeated and no second solve starts from scratch.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from kinecal._special import fdtri
from kinecal.calibration.identifiability import (
    GROWTH_TOL,
    IdentifiabilityReport,
    analyse_factor,
    conditioning,
    observability_indices,
    separated_columns,
)
from kinecal.calibration.serial.cross_validation import data_poses
from kinecal.calibration.serial.inliers import merge_runs, robust_fit, robust_start
from kinecal.calibration.serial.problem import (
    CalibrationProblem,
    analyse_poses,
    candidate_names,
    characteristic_length,
    column_scale,
)
from kinecal.calibration.serial.rows import PoseRows
from kinecal.data import Measurements
from kinecal.kinematics.serial.model import SerialModel
from kinecal.optimize.factor import gram_root
from kinecal.optimize.lsq import levenberg_marquardt

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = ["GRAM_TOL", "GROWTH_FTOL", "LMSolution", "data_identifiability", "grow_identifiable",
           "solve_lm"]

Array = NDArray[np.float64]

#: smallest rank threshold decided on a square root of the Gram matrix (it loses the
#: directions below sqrt(eps) ~ 1.5e-8 of the largest singular value); below it the
#: analysis folds the exact TSQR factor instead (one more pass)
GRAM_TOL = 1e-6
#: relative cost reduction at which the fit on the first set stops for the growth check
GROWTH_FTOL = 1e-4


@dataclasses.dataclass
class LMSolution:
    """What `solve_lm` found: the final problem (every row), the solver's result (with a
    robust loss and outliers: the fit without them), the free parameters, the
    identifiability report and the outlier rows."""

    problem: CalibrationProblem
    result: OptimizeResult
    names: list[str]
    report: IdentifiabilityReport
    #: rows the robust loss flagged and left out of the last fit (robust losses only)
    outliers: list[int] = dataclasses.field(default_factory=list)
    #: rows left out of the decisions on the free set (`robust_start`)
    start_outliers: list[int] = dataclasses.field(default_factory=list)


def solve_lm(model: SerialModel, data: Measurements, free: str | Sequence[str], *,
             rank_tol: float, rotation_weight: float | None = None,
             check: Callable[[list[str], IdentifiabilityReport], None] | None = None,
             loss: str = "linear", f_scale: float | None = None, choose: bool | None = None,
             ) -> LMSolution:
    """Identifiability analysis and Levenberg-Marquardt fit (module docstring).

    Parameters
    ----------
    model, data, free, rank_tol, rotation_weight, loss, f_scale
        As in `kinecal.calibration.serial.api.calibrate`.
    check : callable, optional
        ``check(names, report)`` after the analysis, before the fit (the data checks of
        `kinecal.calibration.diagnostics`; it may raise `InputError`).
    choose : bool, optional
        Free the identifiable subset of the candidates `free` names (and grow it at the
        identified geometry); default: when ``free="identifiable"``.

    Returns
    -------
    LMSolution
    """
    cand = candidate_names(model, free)
    p0 = model.nominal
    G = r0 = None
    if rank_tol >= GRAM_TOL:
        rw = rotation_weight
        if rw is None and data.rotations is not None:
            rw = characteristic_length(model, data, p0)
        rows = PoseRows(model, data, rw or 0.0, weighted=False)
        G, P, r0 = rows.gram(p0, model.index(cand), residuals=True)
        k = len(cand)
        scale = column_scale(model, data, cand, p0, positions=P)
        B = gram_root(G[:k, :k] * scale[:, None] * scale[None, :]) / scale
        report = analyse_factor(B, cand, rows.rows * rows.n_poses, tol=rank_tol, scale=scale)
    else:
        report = analyse_poses(model, data, cand, tol=rank_tol, rotation_weight=rotation_weight)
    growing = free == "identifiable" if choose is None else bool(choose)
    names = report.identifiable if growing else cand
    poses = data_poses(data)
    if check is not None:
        check(list(names), report)
    problem = CalibrationProblem(model, data, names, rotation_weight)
    start = None
    if G is not None and not problem.weighted:  # the analysis' rows are the fit's rows
        pos = [cand.index(n) for n in names] + [len(cand)]
        Gs = G[np.ix_(pos, pos)]
        start = (r0, Gs[:-1, :-1], Gs[:-1, -1])
    res = levenberg_marquardt.fit(problem.residuals, problem.jacobian, problem.x0,
                              monitor=problem.mean_distance_from_residuals,
                              normal_equations=problem.normal_equations, start=start,
                              ftol=GROWTH_FTOL if growing else None)
    # rank and free set decided on the inliers (`kinecal.calibration.serial.inliers`)
    found = robust_start(problem, res, poses, GROWTH_FTOL if growing else None)
    fit, res = found.problem, found.result
    if growing:
        fit, res, names, report = grow_identifiable(model, fit.data, fit, res, report,
                                                    rank_tol)
    problem = fit if not found.outliers else CalibrationProblem(model, data, names,
                                                                rotation_weight)
    outliers: list[int] = []
    if loss != "linear":  # from the inliers' solution, outliers left out of the last fit
        res, outliers = robust_fit(problem, res.x, poses, loss, f_scale, res)
    elif found.outliers:  # least squares of every pose, from the inliers' solution
        res = merge_runs(res, levenberg_marquardt.fit(
            problem.residuals, problem.jacobian, res.x,
            monitor=problem.mean_distance_from_residuals,
            normal_equations=problem.normal_equations))
    return LMSolution(problem, res, list(names), report, outliers, found.outliers)


def _converge(problem: CalibrationProblem, res: OptimizeResult) -> OptimizeResult:
    """Continue a fit stopped at the loose `GROWTH_FTOL` to full convergence."""
    if res.status != 3:  # stopped for another reason than the relative reduction
        return res
    more = levenberg_marquardt.fit(problem.residuals, problem.jacobian, res.x,
                               monitor=problem.mean_distance_from_residuals,
                               normal_equations=problem.normal_equations,
                               start=(res.residual, res.normal_matrix, res.gradient),
                               damping=res.damping)
    more.nfev += res.nfev - 1  # the start was the last evaluation of `res`
    more.njev += res.njev - 1
    more.nit += res.nit
    more.history = list(res.history) + list(more.history[1:])
    more.elapsed += res.elapsed
    return more


def grow_identifiable(model, data, problem, res, report, tol):
    """Free the parameters that became identifiable at the identified geometry.

    Identifiability is local: directions confounded at the nominal geometry can separate
    at the identified one (e.g. large angle errors make the IRB-120's rank 23 instead of
    20). Candidates are the held parameters whose unit-norm columns keep a component
    above ``max(tol, GROWTH_TOL)`` after projecting out the free set's columns
    (`kinecal.calibration.identifiability.separated_columns`, the stack's test too). The
    larger model is kept only if it lowers the residual sum of squares significantly
    (extra-sum-of-squares F-test at the 1 % level), so noise is never fitted with weakly
    identifiable parameters.

    One chunked pass at the current solution `res` gives the Gram matrix of the
    candidates' identification rows and the residual; everything else is ``(p, p)``
    algebra on it. The F-test is first taken on the linearised fits (the Gauss-Newton
    reductions of the RSS from `res`, which need not be fully converged): when even that
    is not significant, the fit continues on the same set. Otherwise LM continues from
    `res` on the larger set (its first normal equations come from the same pass) and the
    F-test is taken on the actual fit. Either way the returned fit is converged.
    """
    tol = max(GROWTH_TOL, tol)
    names = list(problem.free)
    held = [n for n in report.names if n not in names]
    if not held:
        return problem, _converge(problem, res), names, report
    params = problem.full(res.x)
    cand = names + held
    plain = PoseRows(model, data, problem.rotation_weight, weighted=False)
    G, P = plain.gram(params, model.index(cand))
    kf, kc = len(names), len(cand)
    # the same physical column scale as the analysis, threshold relative to the free set
    scale = column_scale(model, data, cand, params, positions=P)
    B = gram_root(G[:kc, :kc] * scale[:, None] * scale[None, :])  # B^T B = (J D)^T (J D)
    added = [held[k] for k in separated_columns(B, range(kf), range(kf, kc), tol)]
    if not added:
        return problem, _converge(problem, res), names, report
    grown = [n for n in report.names if n in names or n in added]
    k = len(added)
    dof = problem.rows * len(data) - len(grown)
    if problem.weighted:  # the F-test weighs the rows like the fit
        Gw = problem.gram(res.x, grown)
    else:
        pos = [cand.index(n) for n in grown] + [kc]
        Gw = G[np.ix_(pos, pos)]
    A, g = Gw[:-1, :-1], Gw[:-1, -1]
    free_pos = [grown.index(n) for n in names]
    rss = 2.0 * res.fun
    # Gauss-Newton reductions from `res`: the smaller fit converged, and the larger one
    rss0 = rss - g[free_pos] @ np.linalg.lstsq(A[np.ix_(free_pos, free_pos)], g[free_pos],
                                               rcond=None)[0]
    if not _significant(rss0, rss - g @ np.linalg.lstsq(A, g, rcond=None)[0], k, dof):
        return problem, _converge(problem, res), names, report
    bigger = CalibrationProblem(model, data, grown, problem.rotation_weight or None)
    res2 = levenberg_marquardt.fit(bigger.residuals, bigger.jacobian, params[bigger.index],
                               monitor=bigger.mean_distance_from_residuals,
                               normal_equations=bigger.normal_equations,
                               start=(res.residual, A, g), damping=(1e-9, res.damping))
    if not _significant(rss0, 2.0 * res2.fun, k, dof):
        return problem, _converge(problem, res), names, report
    res2.nfev += res.nfev
    res2.nit += res.nit
    res2.history = list(res.history) + list(res2.history)
    P2 = bigger.positions_from_residuals(res2.residual)
    # conditioning of the grown set (scaled like the analysis; no pivoting needed)
    scale2 = column_scale(model, data, grown, positions=P2)
    cond, sv = conditioning(gram_root(res2.normal_matrix) * scale2)
    new_report = dataclasses.replace(
        report, rank=len(grown), identifiable=grown,
        unidentifiable=[n for n in report.names if n not in grown],
        confounded_with={n: c for n, c in report.confounded_with.items() if n not in grown},
        condition_number=cond, observability=observability_indices(sv, bigger.rows * len(data)),
    )
    return bigger, res2, grown, new_report


def _significant(rss0: float, rss1: float, k: int, dof: int) -> bool:
    """Extra-sum-of-squares F-test at the 1 % level: does adding `k` parameters (leaving
    `dof` degrees of freedom) lower the RSS from `rss0` to `rss1` significantly?"""
    if rss1 <= 0.0:
        return True
    return dof > 0 and (rss0 - rss1) / k > float(fdtri(k, dof, 0.99)) * rss1 / dof


def data_identifiability(model: SerialModel, data: Measurements,
                         free: str | Sequence[str] = "all", *, rank_tol: float,
                         rotation_weight: float | None = None) -> IdentifiabilityReport:
    """What `calibrate` frees from `data`, as a report of the candidates `free` (``all``,
    ``identifiable`` or names): the rule of ``free="identifiable"`` (rank at nominal at
    `rank_tol`, outlier poses left out, parameters that became identifiable at the
    identified geometry freed when the fit improves significantly), here applied to any
    candidate set (``kinecal identifiability --data``)."""
    cand = candidate_names(model, "all" if free == "identifiable" else free)
    return solve_lm(model, data, cand, rank_tol=rank_tol, rotation_weight=rotation_weight,
                    choose=True).report
