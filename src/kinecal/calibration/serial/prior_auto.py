"""``--prior auto``: the strength of the prior chosen by K-fold cross-validation.

The candidates are no prior and the model's tolerances on the arm's lengths and angles
times ``t`` for ``t`` in `GRID` (`kinecal.calibration.serial.prior`), scanned from the
weakest prior to the strongest until past the minimum; each is scored by its mean
held-out distance error over the folds (deterministic, `cross_validation.fold_of`):

* on a small set (up to `REFIT_ROWS` rows) every one of `REFIT_FOLDS` folds is refitted
  (exact cross-validation, started from the candidate's fit on all poses): there the fit
  without a prior is too non-linear for one Gauss-Newton step to stand for it;
* on a larger set as ``--error-model auto`` scores its candidates
  (`kinecal.calibration.serial.cross_validation`: per-fold Gram matrices of one pass over
  the poses, every training fit the Gauss-Newton step from the candidate's MAP fit on all
  poses, the prior entering it as a quadratic penalty). A first screen linearises every
  candidate at the fit without a prior (one pass for all); when no prior wins there, the
  data decide and the scan is skipped.

The candidate with the lowest mean held-out error is chosen. When its MAP fit moves no
free parameter by more than a tenth of its standard error from the fit without a prior
(`negligible`: a large set, where the data decide everything), no prior is kept, and the
result is the plain fit's, bit for bit.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.serial.cross_validation import (
    CVScore,
    FoldedRows,
    data_poses,
    fold_of,
    n_poses,
)
from kinecal.calibration.serial.prior import Prior, PriorSpec, resolve_prior, tolerance_sigma
from kinecal.calibration.serial.prior_fit import (
    PriorFit,
    PriorProblem,
    fit_with_prior,
    map_from_both,
    noise_level,
    solve_map,
)
from kinecal.calibration.serial.problem import CalibrationProblem
from kinecal.errors import InputError
from kinecal.optimize.lsq import levenberg_marquardt

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = ["DEFAULT_FOLDS", "GRID", "REFIT_FOLDS", "REFIT_ROWS", "apply_prior",
           "choose_strength", "cv_choice", "negligible", "scan_strengths"]

Array = NDArray[np.float64]

#: candidate strengths: multiples of the model's tolerances (1/64 .. 16)
GRID = tuple(float(2.0**e) for e in range(-6, 5))
#: folds (fewer when there are fewer poses)
DEFAULT_FOLDS = 10
#: folds of the exact refits on a small set: training sets closer to the whole set (a
#: 10-fold training set of 30 poses is a tenth smaller, which on the edge of what the
#: poses identify favours too strong a prior: over 40 simulated 25-40-pose sets, 20 folds
#: came within 0.006 mm of the best fixed prior where 10 folds stayed 0.0125 mm above)
REFIT_FOLDS = 20
#: up to this many measurement rows every fold is refitted (exact cross-validation; a
#: small set's fit without a prior is too non-linear for one Gauss-Newton step, which
#: misjudged it by 6 % on 38 poses of a KR6); beyond, the linearised folds (one pass for
#: all folds: the data dominate and the fits are close to linear), as a refit of every
#: fold and candidate would cost ten full fits each
REFIT_ROWS = 400
#: a prior that moves no free parameter by more than this fraction of its standard error
#: decides nothing: ``auto`` then keeps the fit without it (bit for bit)
NEGLIGIBLE = 0.1


def cv_choice(scores: list[CVScore]) -> int:
    """Index of the candidate with the lowest mean held-out error (``scores[0]``: no
    prior; a tie keeps the weaker prior)."""
    means = [float(s.mean) for s in scores]
    return int(np.argmin(means))


def negligible(x_prior: Array, x_plain: Array, std: Array) -> bool:
    """True when a MAP fit moves no free parameter by more than `NEGLIGIBLE` of its
    standard error from the fit without the prior: the prior decides nothing."""
    moved = np.abs(np.asarray(x_prior) - np.asarray(x_plain))
    return bool(np.all(moved <= NEGLIGIBLE * np.asarray(std)))


def _penalty(prior: Prior, noise: float, x_lin: Array) -> tuple[Array, Array]:
    """The prior as a penalty of the training fits linearised at `x_lin`."""
    return noise**2 * prior.precision, x_lin - prior.mean


def _stop(means: list[float], ses: list[float]) -> bool:
    """Past the minimum: the last two candidates both score above the best by more than
    two of its standard errors (the scores only grow from there on as the prior
    tightens)."""
    if len(means) < 3:
        return False
    best = int(np.argmin(means))
    limit = means[best] + 2.0 * ses[best]
    return best < len(means) - 2 and means[-1] > limit and means[-2] > limit


def _refit_score(problem: CalibrationProblem, folds: NDArray[np.intp], k_folds: int,
                 x: Array, prior: Prior | None, noise: float) -> CVScore:
    """Cross-validation score of one candidate by refitting every fold (from `x`, the
    candidate's fit on all poses): exact, for the small sets where the fit without a prior
    is too non-linear for one Gauss-Newton step to stand for it."""
    model, data = problem.model, problem.data
    dist = np.full(len(data), np.inf)
    rw = problem.rotation_weight or None
    for f in range(k_folds):
        held = np.flatnonzero(folds == f)
        try:
            sub = CalibrationProblem(model, data.subset(np.flatnonzero(folds != f)),
                                     problem.free, rw)
        except InputError:  # a fold leaves fewer equations than parameters: no score
            continue
        if prior is None:
            fit = levenberg_marquardt.fit(sub.residuals, sub.jacobian, x,
                                      monitor=sub.mean_distance_from_residuals,
                                      normal_equations=sub.normal_equations)
        else:
            fit = solve_map(PriorProblem(sub, prior, noise), x)
        p = problem.full(np.asarray(fit.x, dtype=float))
        mk = None if data.marker is None else data.marker[held]
        e = model.positions(data.q[held], p, mk) - data.xyz[held]
        dist[held] = np.linalg.norm(e, axis=1)
    means = np.bincount(folds, weights=dist, minlength=k_folds) / np.bincount(
        folds, minlength=k_folds)
    return CVScore(float(dist.mean()), float(means.std(ddof=1) / np.sqrt(k_folds)), means)


def choose_strength(problem: CalibrationProblem, res: OptimizeResult, spec: PriorSpec,
                    noise: float, folds: int | None = None) -> Prior:
    """The ``auto`` prior of `problem`'s free parameters.

    Each candidate is scored linearised at its own MAP fit on all poses (the training
    fits leave out one fold: they lie close to it), the candidates from the weakest prior
    to the strongest, each fit started from the last one's and from the prior values
    (`map_from_both`); the scan stops once past the minimum (`_stop`).

    Parameters
    ----------
    problem : CalibrationProblem
    res : OptimizeResult
        The fit without a prior.
    spec : PriorSpec
        ``auto`` (its prior values: nominal or ``--prior-from``).
    noise : float
        Noise per coordinate of a row of weight 1 (`prior_fit.noise_level`).
    folds : int, optional
        Cross-validation folds (default `REFIT_FOLDS` on a small set, `DEFAULT_FOLDS` on
        a larger one; at most the number of poses).

    Returns
    -------
    Prior
        With ``strength`` None when no prior is chosen; ``choice`` holds the table.
    """
    model, names = problem.model, list(problem.free)
    n = n_poses(problem.data)  # rows at several markers of one pose fold together
    refit = len(problem.data) <= REFIT_ROWS
    k_folds = min((REFIT_FOLDS if refit else DEFAULT_FOLDS) if folds is None else int(folds), n)
    if k_folds < 2:
        raise InputError(f"--prior auto: {n} poses leave no folds to cross-validate on",
                         option="--prior")
    if not np.isfinite(tolerance_sigma(model, names)).any():  # only the set-up is free
        out = resolve_prior(model, spec, names, None)
        out.choice = {"folds": k_folds, "candidates": [], "chosen": None}
        return out
    cols = [list(range(len(names)))]
    folds_of = fold_of(len(problem.data), k_folds, data_poses(problem.data))

    def fit(prior: Prior, x: Array) -> Array:
        return np.asarray(map_from_both(PriorProblem(problem, prior, noise), prior, x).x,
                          dtype=float)

    def score(prior: Prior | None, at: Array) -> CVScore:
        if refit:
            return _refit_score(problem, folds_of, k_folds, at, prior, noise)
        fr = FoldedRows(model, problem.data, problem.full(at), problem.index, k_folds,
                        problem.rotation_weight)
        pen = None if prior is None else [_penalty(prior, noise, at)]
        return fr.scores(cols, penalties=pen)[0]

    x = np.asarray(res.x, dtype=float)
    if not refit:  # a large set: first every candidate linearised at the plain fit
        fr = FoldedRows(model, problem.data, problem.full(x), problem.index, k_folds,
                        problem.rotation_weight)
        priors = [None] + [resolve_prior(model, spec, names, t) for t in GRID]
        pens = [None if p is None else _penalty(p, noise, x) for p in priors]
        screen = fr.scores(cols * len(priors), penalties=pens)
        if cv_choice(screen) == 0:  # no prior helps: done in one pass
            out = resolve_prior(model, spec, names, None)
            out.choice = {"candidates": [{"strength": None if p is None else p.strength,
                                          "mean": sc.mean, "se": sc.se}
                                         for p, sc in zip(priors, screen, strict=True)],
                          "chosen": None, "folds": k_folds, "screened": True}
            return out
    out = scan_strengths(lambda t: resolve_prior(model, spec, names, t), fit, score, x)
    out.choice["folds"] = k_folds
    return out


def scan_strengths(prior_of, fit, score, x: Array) -> Prior:
    """The scan of `GRID` from the weakest prior to the strongest (module docstring).

    Parameters
    ----------
    prior_of : callable
        ``prior_of(t)`` -> `Prior` (``t`` None: no prior).
    fit : callable
        ``fit(prior, x)`` -> the MAP fit's unknowns, started from `x` (the last one's).
    score : callable
        ``score(prior or None, at)`` -> `CVScore` of the candidate whose fit on all data
        is `at`.
    x : ndarray
        The fit without a prior.

    Returns
    -------
    Prior
        ``prior_of(chosen)`` with ``choice``: ``candidates`` (strength, mean, se) and
        ``chosen``.
    """
    strengths: list[float | None] = [None]
    scores = [score(None, x)]
    for t in sorted(GRID, reverse=True):  # weakest first
        prior = prior_of(t)
        x = fit(prior, x)
        strengths.append(t)
        scores.append(score(prior, x))
        if _stop([s.mean for s in scores], [s.se for s in scores]):
            break
    strength = strengths[cv_choice(scores)]
    out = prior_of(strength)
    out.choice = {"candidates": [{"strength": t, "mean": s.mean, "se": s.se}
                                 for t, s in zip(strengths, scores, strict=True)],
                  "chosen": strength}
    return out


def apply_prior(problem: CalibrationProblem, res: OptimizeResult, spec: PriorSpec, *,
                sigma: float | None, rank: int, rank_tol: float,
                folds: int | None = None) -> tuple[Prior, PriorFit | None]:
    """The prior step of a serial calibration: the noise (`noise_level`), the prior of the
    free parameters (``auto``: `choose_strength`), and the MAP fit (`fit_with_prior`;
    None when the prior has nothing to say: ``auto`` chose none, or it names no free
    parameter).

    Parameters
    ----------
    problem : CalibrationProblem
    res : OptimizeResult
        The fit without the prior.
    spec : PriorSpec
    sigma : float or None
        The stated noise (``--sigma``).
    rank : int
        Rank of the fit without the prior (for the noise estimate).
    rank_tol : float
        The calibration's rank threshold.
    folds : int, optional
        ``auto``: cross-validation folds.
    """
    noise, source = noise_level(problem, res, rank, sigma)
    if spec.kind == "auto":
        prior = choose_strength(problem, res, spec, noise, folds)
    else:
        prior = resolve_prior(problem.model, spec, list(problem.free))
    if not prior.active:
        return prior, None
    fit = fit_with_prior(problem, res, prior, noise, source, rank_tol)
    if spec.kind == "auto" and negligible(fit.result.x, res.x, fit.uncertainty.std):
        prior.choice["negligible"] = prior.strength
        prior.choice["chosen"] = prior.strength = None
        prior.sigma = np.full(len(prior.names), np.inf)
        return prior, None
    return prior, fit
