"""A prior in a stacked calibration: one more set of rows beside the blocks' rows.

The stacked rows are in units of each observation's noise; the prior's rows are
``(x_j - mu_j) / s_j`` on the arm's free parameters (`kinecal.calibration.serial.prior`:
what a prior is and how it is stated). The noise of a set without a stated one is
estimated again with the prior's rows in place (variance components,
`kinecal.calibration.blocks.weights`: the prior's information enters every set's
redundancy): a fit without the prior that bent the arm to zero residual (planes that
become one) says nothing about the noise. The MAP fit, its posterior covariance with
every block's unknowns
marginalised, and the split into directions the data decided and those the prior did
follow the serial path (`kinecal.calibration.serial.prior_fit`); the blind motions of the
mix (a ballbar cannot see where the arm stands) are then decided by the prior too, with
its spread, instead of being left out.

``auto`` scores each strength by K-fold cross-validation over the observations of all
sets: a fold's observations get no weight in the refit (their noise set to infinity, as a
robust fit's outliers), and the held-out score is their residual in units of their noise.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.analysis import stack_scale
from kinecal.calibration.blocks.solve import StackFit, estimate_noise
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.blocks.uncertainty import marginal_normal
from kinecal.calibration.serial.cross_validation import CVScore, fold_of
from kinecal.calibration.serial.prior import Prior, PriorSpec, resolve_prior, tolerance_sigma
from kinecal.calibration.serial.prior_auto import DEFAULT_FOLDS, negligible, scan_strengths
from kinecal.calibration.serial.prior_fit import posterior_uncertainty, prior_split
from kinecal.calibration.uncertainty import Uncertainty
from kinecal.optimize._common import FitResult
from kinecal.optimize.lsq import levenberg_marquardt

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = ["PriorStack", "StackPriorFit", "stack_prior"]

Array = NDArray[np.float64]


class PriorStack(StackedProblem):
    """A `StackedProblem` with the prior's rows after the blocks' rows.

    Parameters
    ----------
    problem : StackedProblem
        The problem (blocks, free parameters, noise, held values).
    prior : Prior
        On ``problem.free``.
    noise : float
        The standard deviation of unit weight the prior rows are scaled with.
    """

    scale_free = False  # the prior's rows weigh against the blocks'

    def __init__(self, problem: StackedProblem, prior: Prior, noise: float) -> None:
        super().__init__(problem.model, problem.blocks, problem.free, problem.sigma,
                         problem.base_params)
        self.exclude(problem.excluded)  # observations a robust start left out stay out
        self.w = noise * np.sqrt(prior.precision)
        self.mean = np.asarray(prior.mean, dtype=float)

    def prior_rows(self, x: Array) -> Array:
        return self.w * (np.asarray(x, dtype=float)[:self.k] - self.mean)

    def residuals(self, x: Array) -> Array:
        return np.concatenate([super().residuals(x), self.prior_rows(x)])

    def jacobian(self, x: Array) -> Array:
        P = np.zeros((self.k, self.n))
        P[:, :self.k] = np.diag(self.w)
        return np.vstack([super().jacobian(x), P])

    def assemble(self, parts, x: Array) -> tuple[Array, Array, Array]:
        r, A, g = super().assemble(parts, x)
        rp = self.prior_rows(x)
        k = self.k
        A[:k, :k] += np.diag(self.w**2)
        g[:k] += self.w * rp
        return np.concatenate([r, rp]), A, g

    def monitor(self, r: Array) -> float:
        return super().monitor(np.asarray(r)[:self.m])


@dataclass
class StackPriorFit:
    """The MAP fit of a stacked problem.

    Attributes
    ----------
    problem : PriorStack
    result : OptimizeResult
        ``x`` (arm and unknowns), ``fun`` of the blocks' rows only.
    noise : float
    uncertainty : Uncertainty
        The arm's posterior (unknowns marginalised).
    nuisance_std : list of ndarray
        Each block's unknowns' standard errors.
    split : dict
        `kinecal.calibration.serial.prior_fit.prior_split`.
    """

    problem: PriorStack
    result: OptimizeResult
    noise: float
    uncertainty: Uncertainty
    nuisance_std: list
    split: dict
    noise_source: str = "stated"


def _solve(ps: PriorStack, x: Array) -> OptimizeResult:
    return levenberg_marquardt.fit(ps.residuals, ps.jacobian, x, monitor=ps.monitor,
                               normal_equations=ps.normal_equations,
                               max_nfev=max(200, 10 * (ps.n + 1)))


def _map(problem: StackedProblem, prior: Prior, noise: float, x: Array) -> OptimizeResult:
    """From `x` and from the prior values (where the prior speaks): the lower wins."""
    ps = PriorStack(problem, prior, noise)
    fit = _solve(ps, x)
    start = x.copy()
    start[:ps.k] = np.where(prior.precision > 0, prior.mean, x[:ps.k])
    if not np.array_equal(start, x):
        other = _solve(ps, start)
        if other.fun < fit.fun:
            other.nfev += fit.nfev
            fit = other
    return fit


def _fold_score(problem: StackedProblem, prior: Prior | None, noise: float, at: Array,
                folds: list[NDArray[np.intp]], k_folds: int) -> CVScore:
    """Refit with each fold's observations weightless; their error in noise units."""
    err = [np.full(b.n_obs, np.inf) for b in problem.blocks]
    saved = problem.sigma
    for f in range(k_folds):
        sig = [np.where(fb == f, np.inf, s) for fb, s in zip(folds, saved, strict=True)]
        problem.set_sigma(sig)
        try:
            if prior is None:
                fit = levenberg_marquardt.fit(problem.residuals, problem.jacobian, at,
                                          monitor=problem.monitor,
                                          normal_equations=problem.normal_equations,
                                          max_nfev=max(200, 10 * (problem.n + 1)))
            else:
                fit = _solve(PriorStack(problem, prior, noise), at)
        finally:
            problem.set_sigma(saved)
        r = problem.block_residuals(np.asarray(fit.x, dtype=float))
        for i, (b, ri, s, fb) in enumerate(zip(problem.blocks, r, saved, folds, strict=True)):
            e = b.observation_errors(ri) / s
            err[i] = np.where(fb == f, e, err[i])
    e_all = np.concatenate(err)
    f_all = np.concatenate(folds)
    means = np.bincount(f_all, weights=e_all, minlength=k_folds) / np.bincount(
        f_all, minlength=k_folds)
    return CVScore(float(e_all.mean()), float(means.std(ddof=1) / np.sqrt(k_folds)), means)


def _choose(problem: StackedProblem, x: Array, spec: PriorSpec, noise: float) -> Prior:
    model, names = problem.model, list(problem.free)
    n_obs = sum(b.n_obs for b in problem.blocks)
    k_folds = min(DEFAULT_FOLDS, n_obs)
    if k_folds < 2 or not np.isfinite(tolerance_sigma(model, names)).any():
        out = resolve_prior(model, spec, names, None)
        out.choice = {"folds": k_folds, "candidates": [], "chosen": None}
        return out
    f_all = fold_of(n_obs, k_folds)
    ends = np.cumsum([0, *[b.n_obs for b in problem.blocks]])
    folds = [f_all[a:b] for a, b in pairwise(ends)]
    out = scan_strengths(
        lambda t: resolve_prior(model, spec, names, t),
        lambda prior, at: np.asarray(_map(problem, prior, noise, at).x, dtype=float),
        lambda prior, at: _fold_score(problem, prior, noise, at, folds, k_folds), x)
    out.choice["folds"] = k_folds
    out.choice["score"] = "held-out observation error in units of its noise"
    return out


def _posterior(ps: PriorStack, x: Array, noise: float, prior: Prior, rank_tol: float
               ) -> tuple[Uncertainty, list, dict]:
    k = ps.k
    _, A, _ = ps.normal_equations(x)
    params = ps.params(x)
    D, L, _, _ = stack_scale(ps, params)
    Dn = np.concatenate([b.nuisance_scale(L) for b in ps.blocks] or [np.zeros(0)])
    Df = np.r_[D, Dn]
    S = marginal_normal(A, k, Df)
    unc = posterior_uncertainty(S, noise, D, rank_tol)
    A_data = A.copy()
    A_data[:k, :k] -= np.diag(ps.w**2)
    split = prior_split(marginal_normal(A_data, k, Df) / noise**2, prior, unc, D, rank_tol)
    As = A * Df[:, None] * Df[None, :]
    cov = np.linalg.pinv(As, rcond=1e-12, hermitian=True) * Df[:, None] * Df[None, :]
    std = noise * np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return unc, [std[s] for s in ps.slices], split


def stack_prior(fit: StackFit, spec: PriorSpec, rank_tol: float
                ) -> tuple[Prior, StackPriorFit | None]:
    """The prior step of a stacked calibration (module docstring): the prior of the arm's
    free parameters (``auto``: chosen by cross-validation), and the MAP fit, the noise of
    the sets without a stated one estimated again with the prior's rows in place (None
    when the prior decides nothing).

    Parameters
    ----------
    fit : StackFit
        The fit without the prior (`kinecal.calibration.blocks.solve.fit_stack`); its
        problem takes the noise estimated with the prior.
    spec : PriorSpec
    rank_tol : float
    """
    problem = fit.problem
    x = np.asarray(fit.result.x, dtype=float)
    noise = 1.0  # the rows are in units of each observation's noise
    if spec.kind == "auto":
        prior = _choose(problem, x, spec, noise)
    else:
        prior = resolve_prior(problem.model, spec, list(problem.free))
    if not prior.active:
        return prior, None
    ps = PriorStack(problem, prior, noise)
    res = _map(problem, prior, noise, x)
    res, fit.factors, fit.redundancy, rounds = estimate_noise(ps, res, fit.known)
    xm = np.asarray(res.x, dtype=float)
    unc, nuis_std, split = _posterior(ps, xm, noise, prior, rank_tol)
    if spec.kind == "auto" and negligible(xm[:ps.k], x[:ps.k], unc.std):
        prior.choice["negligible"] = prior.strength
        prior.choice["chosen"] = prior.strength = None
        prior.sigma = np.full(len(prior.names), np.inf)
        return prior, None
    problem.set_sigma(ps.sigma)
    fit.rounds += rounds
    r = np.asarray(res.residual)[:ps.m]
    out = FitResult(res)
    out.x, out.residual, out.fun = xm, r, 0.5 * float(r @ r)
    out.nfev += int(fit.result.nfev)
    out.nit += int(fit.result.nit)
    out.history = list(fit.result.history) + list(res.history)
    return prior, StackPriorFit(ps, out, noise, unc, nuis_std, split,
                                "stated" if all(fit.known) else "estimated per set")
