"""The fit of a stacked problem: Levenberg-Marquardt on the arm and every block's unknowns,
the noise of each block estimated where not stated, outlier observations left out of those
estimates and of the next decision (a robust start), parameters freed where they become
identifiable at the solution, then an optional robust refit with outliers flagged and left
out of a last fit."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from kinecal._special import fdtri
from kinecal.calibration.blocks.analysis import analyse_stack
from kinecal.calibration.blocks.base import ResidualBlock
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.blocks.weights import MAX_ROUNDS, SETTLED, variance_factors
from kinecal.calibration.diagnostics.observations import pose_outliers
from kinecal.calibration.identifiability import separated_columns
from kinecal.diagnostics import warn
from kinecal.kinematics.serial.model import SerialModel
from kinecal.optimize.lsq import levenberg_marquardt

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = ["StackFit", "estimate_noise", "fit_stack", "observation_outliers"]

Array = NDArray[np.float64]

#: significance level of freeing parameters that became identifiable at the solution
GROWTH_LEVEL = 0.01
#: largest change of a noise estimate per round, and over all rounds from the first
STEP = 10.0
SPAN = 1e3
#: errors below this fraction of the machine's size are round-off, no outliers
ROUND_OFF = 1e-9
#: fits on the inliers of the robust start at most
INLIER_ROUNDS = 3


@dataclass
class StackFit:
    """What `fit_stack` found.

    Attributes
    ----------
    problem : StackedProblem
        The final problem (free parameters, noise per block).
    result : OptimizeResult
        The last solver run (``x``, ``fun``, ``nit``, ``nfev``, ``history`` ...).
    known : list of bool
        Per block: the noise was stated (else estimated).
    factors : ndarray, shape (n_blocks,)
        ``RSS_b / r_b`` per block in units of the noise used (1 = the noise fits).
    redundancy : ndarray, shape (n_blocks,)
    rounds : int
        Fit / noise-estimate rounds.
    outliers : list of (int, int)
        ``(block, observation)`` of the observations flagged (robust loss: down-weighted).
    """

    problem: StackedProblem
    result: OptimizeResult
    known: list[bool]
    factors: Array
    redundancy: Array
    rounds: int = 1
    outliers: list[tuple[int, int]] = field(default_factory=list)


def _lm(problem: StackedProblem, x: Array, **kw) -> OptimizeResult:
    kw.setdefault("max_nfev", max(200, 10 * (problem.n + 1)))
    return levenberg_marquardt.fit(problem.residuals, problem.jacobian, x, monitor=problem.monitor,
                               normal_equations=problem.normal_equations, **kw)


def _merge(first: OptimizeResult, then: OptimizeResult) -> OptimizeResult:
    """`then` with the counts and history of both runs."""
    then.nit += first.nit
    then.nfev += first.nfev
    then.history = list(first.history) + list(then.history[1:])
    return then


def _estimate(problem: StackedProblem, res: OptimizeResult, known: list[bool]
              ) -> tuple[OptimizeResult, Array, Array, int]:
    """Alternate fit and noise estimates (`kinecal.calibration.blocks.weights`).

    Each round may change a noise by at most `STEP` against the others and all rounds
    together by at most `SPAN` from the first estimate: sets that contradict each other (a
    file of another robot) otherwise drive one noise to zero and the arm to a degenerate
    fit that explains that set alone. A scale common to every set is taken at once when
    every set's noise is estimated (it changes no fit: `StackedProblem.scale_free`). Rounds
    that do not settle end with ``noise-estimate``.
    """
    rounds, first = 1, None
    known = np.asarray(known, dtype=bool)
    floor = _round_off(problem)
    while True:
        r = problem.block_residuals(res.x)
        f, red = variance_factors(problem, res.x, r)
        # a set fitted to round-off (noise-free data) has no noise to estimate
        # (other units: the block's own `round_off`, e.g. a camera's pixels)
        exact = np.array([np.abs(ri).max(initial=0.0) <= (
            floor if b.unit == "length" else getattr(b, "round_off", 0.0))
            for b, ri in zip(problem.blocks, r, strict=True)])
        if all(known | exact):
            return res, f, red, rounds
        step = np.sqrt(np.where(known | exact | ~np.isfinite(f) | (f <= 0), 1.0, f))
        new = [s * st for s, st in zip(problem.sigma, step, strict=True)]
        if first is None:
            first = [s.copy() for s in new]
        else:
            new = [np.clip(s, f0 / SPAN, f0 * SPAN) for s, f0 in zip(new, first, strict=True)]
        change = max(float(np.max(np.abs(n / s - 1.0))) for n, s in
                     zip(new, problem.sigma, strict=True))
        # a scale common to the noise of every set changes no fit (when every set's is
        # estimated and no other rows weigh in): only the ratios are held to `STEP`
        free = ~(known | exact) & np.isfinite(f) & (f > 0)
        common = (float(np.exp(np.mean(np.log(step)))) if free.all() and problem.scale_free
                  else 1.0)
        problem.set_sigma([np.clip(n, s * common / STEP, s * common * STEP) for n, s in
                           zip(new, problem.sigma, strict=True)])
        if change < SETTLED:
            return res, np.where(known, f, 1.0), red, rounds
        if rounds >= MAX_ROUNDS:
            warn("noise-estimate",
                 f"the noise of the measurement sets did not settle in {rounds} rounds (last "
                 f"change {change:.2g}): the sets contradict each other (a file of another "
                 "robot or model, a wrong unit); check the files, or state each set's noise "
                 "(--sigma FILE=SIGMA)")
            return res, f, red, rounds
        res = _merge(res, _lm(problem, res.x))
        rounds += 1


#: the alternation of fit and noise estimates, for a problem with further rows (a prior)
estimate_noise = _estimate


def _significant(rss0: float, rss1: float, k: int, dof: int) -> bool:
    """Extra-sum-of-squares F-test at `GROWTH_LEVEL`."""
    if rss1 <= 0.0:
        return rss0 > 0.0
    return dof > 0 and (rss0 - rss1) / k > float(fdtri(k, dof, 1 - GROWTH_LEVEL)) * rss1 / dof


def _grow(problem: StackedProblem, res: OptimizeResult, candidates: list[str],
          tol: float) -> tuple[StackedProblem, OptimizeResult]:
    """Free the held candidates that became identifiable at the solution, when that pays.

    As the serial path's growth (`kinecal.calibration.serial.solve.grow_identifiable`), by
    the same test (`kinecal.calibration.identifiability.separated_columns`): a held
    parameter is added when its (scaled, blind motions removed) column keeps a pivot above
    ``max(tol, GROWTH_TOL)`` of the free set's largest after projecting out the free set's
    columns, and the larger fit lowers the residual significantly (F-test).
    """
    model, blocks = problem.model, problem.blocks
    params, nuis = problem.params(res.x), problem.nuisance(res.x)
    held = [n for n in candidates if n not in problem.free]
    if not held:
        return problem, res
    cand = StackedProblem(model, blocks, candidates, problem.sigma)
    cand.exclude(problem.excluded)
    B = analyse_stack(cand, cand.pack(params, nuis), tol, report=False).reduced
    free_pos = [candidates.index(n) for n in problem.free]
    held_pos = [candidates.index(n) for n in held]
    added = [held[j] for j in separated_columns(B, free_pos, held_pos, tol)]
    if not added:
        return problem, res
    names = [n for n in candidates if n in problem.free or n in added]
    bigger = StackedProblem(model, blocks, names, problem.sigma)
    bigger.exclude(problem.excluded)
    res2 = _lm(bigger, bigger.pack(params, nuis))
    if not _significant(2 * res.fun, 2 * res2.fun, len(added), bigger.m_used - bigger.n):
        return problem, res
    return bigger, _merge(res, res2)


def _round_off(problem: StackedProblem) -> float:
    """Errors below this size (length unit) are round-off: `ROUND_OFF` of the machine's."""
    b = next((b for b in problem.blocks if len(b.q)), None)
    P = problem.model.positions(b.q[:64], problem.base_params) if b is not None else \
        np.zeros((1, 3))
    return ROUND_OFF * max(float(np.abs(P).max()), 1.0)


def observation_outliers(problem: StackedProblem, residuals: Sequence[Array]
                         ) -> list[tuple[int, int]]:
    """Observations far outside their block's spread (`chi_outliers` of the errors in
    units of the noise, per block, the observations of one pose at several markers pooled:
    `ResidualBlock.observation_poses`); none in a block whose errors are all at round-off
    (below `ROUND_OFF` of the workspace's size, or the block's ``round_off`` in its own
    unit). Every observation of a flagged pose is returned."""
    floor = _round_off(problem)
    out = []
    for i, (b, r, s) in enumerate(zip(problem.blocks, residuals, problem.sigma, strict=True)):
        e = b.observation_errors(r)
        # (other units: the block's own round-off, e.g. a camera's pixels)
        if e.size and e.max() <= (floor if b.unit == "length" else getattr(b, "round_off", 0.0)):
            continue
        group, n = b.observation_poses()
        out += [(i, j) for j in pose_outliers(e / s, group, n, b.obs_dof)]
    return out


def _enough(problem: StackedProblem, left_out: Sequence[tuple[int, int]]) -> bool:
    """Whether the observations not in `left_out` still hold twice the unknowns' rows."""
    drop = sum(int(np.count_nonzero(problem.blocks[i].obs_index == j)) for i, j in left_out)
    return problem.m - drop > 2 * problem.n


def _inliers(problem: StackedProblem, res: OptimizeResult, known: list[bool]):
    """The robust start: observations flagged at the first fit left out, the fit and the
    noise estimates repeated on the others, every observation judged again there, until
    the flagged set repeats (at most `INLIER_ROUNDS` fits;
    `kinecal.calibration.serial.inliers` for a tracker file alone). Returns ``(res, f,
    red, rounds)`` of the last fit, with `problem` excluding the flagged observations."""
    flagged = observation_outliers(problem, problem.block_residuals(res.x))
    out = None
    for _ in range(INLIER_ROUNDS):
        if not flagged or not _enough(problem, flagged):
            break
        problem.exclude(flagged)
        res = _merge(res, _lm(problem, res.x))
        out = _estimate(problem, res, known)
        res = out[0]
        again = observation_outliers(problem, problem.block_residuals(res.x))
        if again == flagged:
            break
        flagged = again
    if out is None or not flagged:
        problem.exclude([])
        return None
    return out


def fit_stack(model: SerialModel, blocks: Sequence[ResidualBlock], names: list[str],
              candidates: list[str], params: Array, nuisance: Sequence[Array],
              sigma: Sequence[Array], known: list[bool], *, tol: float,
              grow: bool, loss: str = "linear", f_scale: float | None = None) -> StackFit:
    """Fit the arm's `names` and every block's unknowns (module docstring).

    Parameters
    ----------
    model, blocks
        The nominal model and the started blocks.
    names, candidates : list of str
        Free parameters; the candidates that may be freed at the solution (`grow`).
    params : ndarray, shape (n_params,)
        Start (and held) parameter values.
    nuisance : sequence of ndarray
        Each block's start unknowns.
    sigma, known
        Start noise per observation of each block; whether it was stated.
    tol : float
        Rank threshold of the growth analysis.
    loss, f_scale
        Robust loss of the final refit (scipy names) and its scale in units of the noise
        (default 3 x the median weighted residual of the plain fit).
    """
    problem = StackedProblem(model, blocks, names, sigma, params)
    res = _lm(problem, problem.pack(params, nuisance))
    res, f, red, rounds = _estimate(problem, res, known)
    start = _inliers(problem, res, known)  # free set and noise decided on the inliers
    if start is not None:
        res, f, red, more = start
        rounds += more
    if grow:
        grown, res2 = _grow(problem, res, candidates, tol)
        if grown is not problem:
            problem, (res, f, red, more) = grown, _estimate(grown, res2, known)
            rounds += more
    if problem.excluded:  # every observation again, from the inliers' solution
        problem.exclude([])
        if loss == "linear":
            res = _merge(res, _lm(problem, res.x))
            res, f, red, more = _estimate(problem, res, known)
            rounds += more
    outliers = observation_outliers(problem, problem.block_residuals(res.x))
    if loss != "linear":
        r = problem.residuals(res.x)
        scale = f_scale if f_scale is not None else 3.0 * max(float(np.median(np.abs(r))),
                                                             1e-12)
        robust = levenberg_marquardt.fit(problem.residuals, problem.jacobian, res.x, loss=loss,
                                     f_scale=scale, monitor=problem.monitor)
        res = _merge(res, robust)
        outliers = observation_outliers(problem, problem.block_residuals(res.x))
        if outliers and _enough(problem, outliers):  # down-weighted they still pull
            problem.exclude(outliers)
            res = _merge(res, levenberg_marquardt.fit(
                problem.residuals, problem.jacobian, res.x, loss=loss, f_scale=scale,
                monitor=problem.monitor))
    return StackFit(problem, res, list(known), f, red, rounds, outliers)
