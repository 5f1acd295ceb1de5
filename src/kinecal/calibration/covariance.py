"""Covariance of identified parameters from the normal equations.

One function, `parameter_covariance`, so that every solver path (LM, Householder,
metaheuristics, robust losses) derives standard errors the same way, from the
``(k, k)`` normal matrix ``J^T W J`` accumulated over chunks of poses (never from the
``(3N, k)`` Jacobian itself).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["parameter_covariance"]

Array = NDArray[np.float64]


def parameter_covariance(normal: Array, rss: float, dof: int) -> tuple[Array, float]:
    """Covariance ``sigma^2 (J^T W J)^+`` and ``sigma`` of a least-squares fit.

    Parameters
    ----------
    normal : ndarray, shape (k, k)
        Normal matrix ``J^T W J`` at the solution (weighted Jacobian of the residuals).
    rss : float
        Weighted residual sum of squares at the solution.
    dof : int
        Degrees of freedom, residuals minus free parameters.

    Returns
    -------
    cov : ndarray, shape (k, k)
        ``sigma^2 pinv(J^T W J)`` with ``sigma^2 = rss / dof`` (parameter units squared),
        the pseudo-inverse taken on the unit-diagonal (equilibrated) matrix.
    sigma : float
        Standard deviation of unit weight (NaN without degrees of freedom).
    """
    sigma2 = float(rss) / dof if dof > 0 else float("nan")
    A = np.asarray(normal, dtype=float)
    # equilibrated: the pseudo-inverse's cut-off must not depend on the parameters' units
    # (a coefficient whose unit moves the tool by 1e-6 mm next to lengths in mm)
    d = np.sqrt(np.clip(np.diag(A), 0.0, None)) if A.size else np.ones(0)
    d = np.where(d > 0, d, 1.0)
    cov = sigma2 * np.linalg.pinv(A / np.outer(d, d)) / np.outer(d, d)
    return cov, float(np.sqrt(sigma2))
