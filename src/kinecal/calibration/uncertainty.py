"""Honest parameter uncertainty: covariance on the identifiable subspace actually fitted.

A least-squares fit determines only the combinations of its free parameters that the
data see: the row space of the Jacobian. `parameter_covariance` (the pseudo-inverse of the
normal matrix) quietly gives every parameter a finite standard error even along null
directions, where the data say nothing (a confounded pair such as ``d2``/``d3`` of parallel
axes, or ``alpha6`` of a tool point on the last axis). `subspace_uncertainty` instead

* splits the (column-scaled) normal matrix into the fitted subspace, of the rank the
  identifiability analysis found, and its null space;
* gives the covariance ``sigma^2 (J^T W J)^+`` restricted to the fitted subspace, with
  ``sigma^2 = RSS / (m - rank)``;
* marks a parameter *not identifiable* (standard error ``inf``) when its unit vector has a
  component along the null space: a linear function ``c^T x`` is estimable exactly when
  ``c`` lies in the row space (Searle, *Linear Models*, 1971, sec. 5.4); the same test
  applied to Jacobian rows tells whether a predicted position is bounded.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["ESTIMABLE_TOL", "Uncertainty", "subspace_uncertainty"]

Array = NDArray[np.float64]

#: a direction counts as estimable when its component along the null space is below this
#: fraction of its norm (exact confounding leaves round-off, ~1e-12)
ESTIMABLE_TOL = 1e-6


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
        Orthonormal basis of the null space in scaled coordinates (see `scale`).
    scale : ndarray, shape (k,)
        Column factors of the scaled coordinates (1 for lengths, 1 / L for angles).
    """

    covariance: Array
    sigma: float
    estimable: Array
    null: Array
    scale: Array

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
        scaled = rows * self.scale
        along = np.linalg.norm(scaled @ self.null, axis=-1)
        return along <= ESTIMABLE_TOL * np.maximum(np.linalg.norm(scaled, axis=-1), 1e-300)


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
    dof = n_rows - int(pos.sum())
    sigma2 = float(rss) / dof if dof > 0 else float("nan")
    cov = sigma2 * (D[:, None] * ((V1 / w1) @ V1.T) * D[None, :])
    along = np.linalg.norm(null, axis=1) if null.size else np.zeros(k)
    estimable = along <= ESTIMABLE_TOL
    return Uncertainty(cov, float(np.sqrt(sigma2)), estimable, null, D)
