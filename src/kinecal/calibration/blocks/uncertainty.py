"""Uncertainty of a stacked fit: the arm's covariance with every block's unknowns
marginalised, on the identifiable subspace (`kinecal.calibration.uncertainty.
arm_uncertainty`, the serial calibration's too), and the standard errors of the unknowns
themselves."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kinecal.calibration.blocks.analysis import StackAnalysis, stack_scale
from kinecal.calibration.blocks.motions import blind_basis
from kinecal.calibration.blocks.stack import StackedProblem
from kinecal.calibration.uncertainty import Uncertainty, arm_uncertainty, marginal_normal

__all__ = ["marginal_normal", "stack_uncertainty"]

Array = NDArray[np.float64]


def stack_uncertainty(problem: StackedProblem, x: Array, analysis: StackAnalysis,
                      outliers: Sequence[tuple[int, int]] = ()
                      ) -> tuple[Uncertainty, list[Array]]:
    """Covariance of the free arm parameters and standard errors of each block's unknowns.

    Parameters
    ----------
    problem : StackedProblem
        The fitted problem.
    x : ndarray, shape (n,)
        The solution.
    analysis : StackAnalysis
        Identifiability at the solution (its unidentifiable parameters set the rank).
    outliers : sequence of (block, observation)
        Observations left out (down-weighted by a robust loss).

    Returns
    -------
    Uncertainty
        Of the free arm parameters (`kinecal.calibration.uncertainty.subspace_uncertainty`,
        ``sigma^2 = RSS / (m - n)`` over every row).
    list of ndarray
        Standard error of each block's unknowns ``(n_b,)``.
    """
    sigma = [s.copy() for s in problem.sigma]
    for i, j in outliers:
        sigma[i][j] = np.inf
    saved = problem.sigma
    problem.set_sigma(sigma)
    try:
        r, A, _ = problem.normal_equations(x)
    finally:
        problem.set_sigma(saved)
    k = problem.k
    params = problem.params(x)
    D, L, q, P = stack_scale(problem, params)
    Dn = np.concatenate([b.nuisance_scale(L) for b in problem.blocks] or [np.zeros(0)])
    Df = np.r_[D, Dn]
    Q, _ = blind_basis(problem, params, q, P, D)
    rank = k - int(np.isin(problem.free, analysis.report.unidentifiable).sum())
    used = int(sum(int(np.isfinite(s[b.obs_index]).sum()) for s, b in
                   zip(sigma, problem.blocks, strict=True)))
    unc = arm_uncertainty(A, float(r @ r), used - (problem.n - k), k, rank, Df, Q)
    As = A * Df[:, None] * Df[None, :]
    cov = np.linalg.pinv(As, rcond=1e-12, hermitian=True) * Df[:, None] * Df[None, :]
    s2 = unc.sigma ** 2 if np.isfinite(unc.sigma) else np.nan
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None) * s2)
    return unc, [std[s] for s in problem.slices]
