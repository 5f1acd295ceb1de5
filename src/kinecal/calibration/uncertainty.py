"""Honest parameter uncertainty: covariance on the identifiable subspace actually fitted.

A least-squares fit determines only the combinations of its free parameters that the
data see: the row space of the Jacobian. `parameter_covariance` (the pseudo-inverse of the
normal matrix) quietly gives every parameter a finite standard error even along null
directions, where the data say nothing (a confounded pair such as ``d2``/``d3`` of parallel
axes, or ``alpha6`` of a tool point on the last axis). `subspace_uncertainty` instead

* splits the (column-scaled) normal matrix ``A`` into the fitted subspace, of the rank the
  identifiability analysis found (eigenpairs ``(w_j, v_j)``), and the rest, the
  unidentified directions (eigenpairs ``(w_i, n_i)``: exactly null for a confounding, or
  below the rank threshold for a near-dependence);
* gives the covariance ``sigma^2 (J^T W J)^+`` restricted to the fitted subspace, with
  ``sigma^2 = RSS / (m - rank)``;
* marks a linear function ``c^T x`` (a parameter: ``c = e_k``; a predicted coordinate: a
  Jacobian row) *not estimable* (standard error ``inf``) when it takes part in the
  unidentified directions. In exact arithmetic that means a component along the null
  space: ``c^T x`` is estimable exactly when ``c`` lies in the row space (Searle, *Linear
  Models*, 1971, sec. 5.4). A near-dependence has no exact null space: its directions
  touch every parameter a little (components of the order of its singular value ratio,
  ~1e-4 at kinecal's rank threshold), and the exact test would take every standard error
  away. The test used is therefore the share of the variance: were the unidentified
  directions estimated at their own (tiny) eigenvalues, they would add
  ``u(c) = sum_i (c^T n_i)^2 / w_i`` to the variance of ``c^T x`` (in units of
  ``sigma^2``), against ``f(c) = sum_j (c^T v_j)^2 / w_j`` from the fitted subspace.
  ``c^T x`` is estimable when ``u(c) <= f(c)``: at most half of its variance would come
  from directions the data do not identify. A parameter of a confounded or near-dependent
  pair has ``u / f`` of 1e5 and beyond (the inverse eigenvalue ratio across the rank
  threshold), one merely touched by the near-null direction a few percent; a component
  below ``ESTIMABLE_TOL`` (round-off of an exact null space) is estimable outright.

`arm_uncertainty` is the covariance step of every calibration of an arm, a single tracker
file's (`kinecal.calibration.serial`) as a stacked problem's
(`kinecal.calibration.blocks`): the unknowns of the measurement sets marginalised
(`marginal_normal`, none for tracker rows), the motions the data are blind to projected
out, then `subspace_uncertainty`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["ESTIMABLE_TOL", "UNFITTED_SHARE", "Uncertainty", "arm_uncertainty",
           "marginal_normal", "subspace_uncertainty"]

Array = NDArray[np.float64]

#: a direction counts as estimable when its component along the null space is below this
#: fraction of its norm (exact confounding leaves round-off, ~1e-12)
ESTIMABLE_TOL = 1e-6
#: ... or when the unidentified directions would add at most this multiple of its
#: fitted-subspace variance (see the module docstring)
UNFITTED_SHARE = 1.0


@dataclass
class Uncertainty:
    """Covariance of the free parameters on their identifiable subspace.

    Attributes
    ----------
    covariance : ndarray, shape (k, k)
        ``sigma^2`` times the pseudo-inverse of ``J^T W J`` on the fitted subspace
        (parameter units squared; finite everywhere, meaningful only for estimable
        combinations).
    sigma : float
        Standard deviation of unit weight (NaN without degrees of freedom).
    estimable : ndarray of bool, shape (k,)
        Parameters the data identify individually.
    null : ndarray, shape (k, k - rank)
        Orthonormal basis of the unidentified directions in scaled coordinates (see
        `scale`).
    scale : ndarray, shape (k,)
        Column factors of the scaled coordinates (1 for lengths, 1 / L for angles).
    fitted : ndarray, shape (k, rank)
        Orthonormal basis of the fitted subspace (scaled coordinates).
    fitted_values, null_values : ndarray, shapes (rank,), (k - rank,)
        Eigenvalues of the scaled normal matrix along `fitted` and `null`.
    """

    covariance: Array
    sigma: float
    estimable: Array
    null: Array
    scale: Array
    fitted: Array = field(default_factory=lambda: np.zeros((0, 0)))
    fitted_values: Array = field(default_factory=lambda: np.zeros(0))
    null_values: Array = field(default_factory=lambda: np.zeros(0))

    @property
    def std(self) -> Array:
        """Standard errors ``(k,)``: ``inf`` for parameters that are not identifiable."""
        s = np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))
        return np.where(self.estimable, s, np.inf)

    def bounded(self, rows: Array) -> Array:
        """Which linear functions (rows of ``(..., k)``, parameter units) are estimable.

        Returns a boolean array of the leading shape of `rows`.
        """
        rows = np.asarray(rows, dtype=float)
        if self.null.shape[1] == 0:
            return np.ones(rows.shape[:-1], dtype=bool)
        scaled = (rows * self.scale).reshape(-1, rows.shape[-1])
        ok = estimable_rows(scaled, self.fitted, self.fitted_values, self.null,
                            self.null_values)
        return ok.reshape(rows.shape[:-1])


def estimable_rows(rows: Array, fitted: Array, fitted_values: Array, null: Array,
                   null_values: Array) -> Array:
    """Which rows ``(n, k)`` (scaled coordinates) the fit determines (module docstring).

    Parameters
    ----------
    rows : ndarray, shape (n, k)
        Linear functions ``c`` of the scaled parameters.
    fitted, fitted_values : ndarray, shapes (k, r), (r,)
        Eigenvectors and (positive) eigenvalues of the fitted subspace.
    null, null_values : ndarray, shapes (k, k - r), (k - r,)
        Eigenvectors and eigenvalues (possibly round-off, even negative) of the
        unidentified directions.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    rows = np.asarray(rows, dtype=float)
    if null.shape[1] == 0:
        return np.ones(len(rows), dtype=bool)
    on_null = rows @ null
    along = np.linalg.norm(on_null, axis=1)
    norm = np.maximum(np.linalg.norm(rows, axis=1), 1e-300)
    f = ((rows @ fitted) ** 2 / fitted_values).sum(axis=1) if fitted.size else 0.0
    # an exactly null direction has a round-off eigenvalue: count it as (almost) zero
    top = max(float(fitted_values.max(initial=0.0)), float(null_values.max(initial=0.0)))
    floor = np.finfo(float).eps * max(top, 1e-300) * max(len(rows[0]) if rows.size else 1, 1)
    u = (on_null ** 2 / np.maximum(null_values, floor)).sum(axis=1)
    return (along <= ESTIMABLE_TOL * norm) | (u <= UNFITTED_SHARE * f)


def subspace_uncertainty(normal: Array, rss: float, n_rows: int, rank: int,
                         scale: Array | None = None) -> Uncertainty:
    """Covariance and estimability of a least-squares fit on its identifiable subspace.

    Parameters
    ----------
    normal : ndarray, shape (k, k)
        ``J^T W J`` at the solution (parameter units).
    rss : float
        Weighted residual sum of squares at the solution.
    n_rows : int
        Number of independent residual rows (``m``).
    rank : int
        Dimension of the fitted subspace (the identifiability analysis' rank of the free
        set; ``k`` when every free parameter is identifiable).
    scale : ndarray, shape (k,), optional
        Column factors making lengths and angles comparable (default 1).

    Returns
    -------
    Uncertainty
    """
    A = np.asarray(normal, dtype=float)
    k = A.shape[0]
    D = np.ones(k) if scale is None else np.asarray(scale, dtype=float)
    rank = int(min(max(rank, 0), k))
    w, V = np.linalg.eigh(A * D[:, None] * D[None, :]) if k else (np.zeros(0), np.zeros((0, 0)))
    order = np.argsort(w)[::-1]
    w, V = w[order], V[:, order]
    pos = w[:rank] > 0
    V1, w1 = V[:, :rank][:, pos], w[:rank][pos]
    null = np.concatenate([V[:, rank:], V[:, :rank][:, ~pos]], axis=1)
    w_null = np.concatenate([w[rank:], w[:rank][~pos]])
    dof = n_rows - int(pos.sum())
    sigma2 = float(rss) / dof if dof > 0 else float("nan")
    cov = sigma2 * (D[:, None] * ((V1 / w1) @ V1.T) * D[None, :])
    estimable = estimable_rows(np.eye(k), V1, w1, null, w_null)
    return Uncertainty(cov, float(np.sqrt(sigma2)), estimable, null, D, V1, w1, w_null)


def marginal_normal(A: Array, k: int, scale: Array) -> Array:
    """The arm's information ``(k, k)`` with the unknowns after column `k` marginalised:
    the Schur complement ``A_aa - A_an A_nn^-1 A_na`` (computed on the columns scaled by
    `scale` ``(n,)``, returned in parameter units); `A` itself when it has no further
    columns."""
    if A.shape[0] == k:
        return np.array(A, dtype=float)
    from scipy.linalg import cho_factor, cho_solve  # on first use (0.1-0.3 s to import)

    As = A * scale[:, None] * scale[None, :]
    Aaa, Aan, Ann = As[:k, :k], As[:k, k:], As[k:, k:]
    try:
        S = Aaa - Aan @ cho_solve(cho_factor(Ann), Aan.T)
    except np.linalg.LinAlgError:
        S = Aaa - Aan @ np.linalg.pinv(Ann) @ Aan.T
    d = scale[:k]
    return 0.5 * (S + S.T) / d[:, None] / d[None, :]


def arm_uncertainty(A: Array, rss: float, n_rows: int, k: int, rank: int, scale: Array,
                    blind: Array | None = None) -> Uncertainty:
    """Covariance of an arm's `k` free parameters from the normal matrix of a fit.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        ``J^T W J`` at the solution: the arm's `k` columns first, then the unknowns of the
        measurement sets (marginalised, `marginal_normal`).
    rss : float
        Weighted residual sum of squares there.
    n_rows : int
        Independent residual rows left after the unknowns (``m - (n - k)``).
    rank : int
        Dimension of the fitted subspace of the arm's parameters.
    scale : ndarray, shape (n,)
        Column factors (lengths 1, angles ``1 / L``; the unknowns' own).
    blind : ndarray, shape (k, b), optional
        Orthonormal arm directions (columns scaled by ``scale[:k]``) producing motions
        the data are blind to: exact null directions, projected out (at a noisy solution
        they show at the noise's level and would blur the fitted subspace).

    Returns
    -------
    Uncertainty
        `subspace_uncertainty` of the arm's parameters.
    """
    D = np.asarray(scale, dtype=float)[:k]
    S = marginal_normal(np.asarray(A, dtype=float), k, np.asarray(scale, dtype=float))
    if blind is not None and blind.size:
        Pr = np.eye(k) - blind @ blind.T
        S = (Pr @ (S * D[:, None] * D[None, :]) @ Pr) / D[:, None] / D[None, :]
    return subspace_uncertainty(S, rss, n_rows, rank, D)
