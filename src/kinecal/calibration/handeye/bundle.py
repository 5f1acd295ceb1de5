"""Normal equations of the reprojection refinement and their structured (Schur) solve.

The reprojection problem of `kinecal.calibration.handeye.reprojection` has few shared
unknowns (X and the board pose Y, 6 each; optionally 9 or 12 intrinsics) against many
corners, and, when the robot poses' errors are modelled, 6 unknowns per station that only
that station's corners see. Its normal matrix ``J^T W J`` is an arrow: a small dense shared
block, a block-diagonal station part (6 x 6 per station) and their coupling, the classical
structure of bundle adjustment (Triggs, McLauchlan, Hartley & Fitzgibbon 2000, "Bundle
adjustment - a modern synthesis", sec. 6.1).

- `normal_equations` accumulates ``J^T W J`` and ``J^T W r`` from the per-corner Jacobian
  blocks (`reprojection.predict_blocks`): no dense ``(2M, p)`` Jacobian, one matrix product
  for the shared block and one sum per station for the rest;
- `schur_solve` solves the damped system of a Levenberg-Marquardt step by eliminating the
  station blocks (Schur complement on the shared block): linear in the number of stations
  instead of cubic in ``6 n``;
- `robust_residuals` turns residuals into the pseudo-residuals of Huber's loss (their
  squared norm is the robust cost) and the weights of its gradient, so that the same
  Levenberg-Marquardt minimises the robust cost (iteratively reweighted normal equations).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

__all__ = ["normal_equations", "robust_residuals", "schur_solve"]

#: scipy's floor of the robust scale of a residual beyond Huber's threshold (its
#: ``least_squares`` returns the Jacobian scaled by the square root of this there)
_EPS = float(np.finfo(float).eps)


def robust_residuals(r: Array, loss: str, f_scale: float) -> tuple[Array, Array, Array]:
    """Huber pseudo-residuals, gradient weights and scipy's covariance weights.

    Parameters
    ----------
    r : ndarray
        Residuals (any shape), in units where `f_scale` is the threshold.
    loss : {"linear", "huber"}
    f_scale : float
        Huber threshold.

    Returns
    -------
    pseudo : ndarray
        ``sign(r) f sqrt(rho((r / f)^2))``: half their squared sum is scipy's robust cost
        ``0.5 f^2 sum rho``.
    w : ndarray
        ``rho'((r / f)^2)``: the cost's gradient is ``J^T (w r)`` and ``J^T diag(w) J`` its
        Gauss-Newton Hessian (iteratively reweighted least squares).
    c : ndarray
        ``max(rho' + 2 rho'' z, eps)``: the weights of scipy's scaled Jacobian at a solution
        (1 inside the threshold, ``eps`` beyond it for Huber), for the covariance.
    """
    if loss == "linear":
        one = np.ones_like(r)
        return r, one, one
    z = (r / f_scale) ** 2
    inside = z <= 1.0
    az = np.sqrt(np.where(inside, 1.0, z))
    rho = np.where(inside, z, 2.0 * az - 1.0)
    pseudo = np.sign(r) * f_scale * np.sqrt(rho)
    w = np.where(inside, 1.0, 1.0 / az)
    c = np.where(inside, 1.0, _EPS)
    return pseudo, w, c


def normal_equations(Jg: Array, Je: Array | None, w: Array, r: Array, starts: NDArray[np.intp],
                     prior: tuple[Array, Array, Array] | None = None
                     ) -> tuple[Array, Array]:
    """``J^T W J`` and ``J^T W r`` of the reprojection problem from its blocks.

    Parameters
    ----------
    Jg : ndarray, shape (M, 2, g)
        Jacobian of every corner's two residuals with respect to the shared unknowns.
    Je : ndarray, shape (M, 2, 6) or None
        With respect to its station's robot-pose correction (None: not modelled).
    w : ndarray, shape (M, 2)
        Weights of the residuals.
    r : ndarray, shape (M, 2)
        Residuals.
    starts : ndarray of int, shape (n,)
        First corner of every station (corners are grouped by station, in order; every
        station has at least one corner).
    prior : (ndarray, ndarray, ndarray), optional
        The corrections' prior rows: their Jacobian (inverse standard deviations), weights
        and residuals, each ``(n, 6)`` (row ``k`` of station ``s`` depends on that
        correction alone).

    Returns
    -------
    A : ndarray, shape (p, p)
        ``J^T W J`` with ``p = g + 6 n`` (``g`` without corrections).
    b : ndarray, shape (p,)
        ``J^T W r``.
    """
    g = Jg.shape[2]
    Jw = Jg * w[:, :, None]
    rf = r.reshape(-1)
    Agg = Jw.reshape(-1, g).T @ Jg.reshape(-1, g)
    bg = Jw.reshape(-1, g).T @ rf
    if Je is None:
        return Agg, bg
    n = len(starts)
    Jew = Je * w[:, :, None]
    # per-corner products summed per station (corners are contiguous by station)
    Age = np.add.reduceat(np.einsum("mci,mcj->mij", Jw, Je), starts, axis=0)  # (n, g, 6)
    Aee = np.add.reduceat(np.einsum("mci,mcj->mij", Jew, Je), starts, axis=0)  # (n, 6, 6)
    be = np.add.reduceat(np.einsum("mci,mc->mi", Jew, r), starts, axis=0)  # (n, 6)
    if prior is not None:
        d, wp, rp = prior
        Aee = Aee.copy()
        Aee[:, np.arange(6), np.arange(6)] += d * d * wp
        be = be + d * wp * rp
    p = g + 6 * n
    A = np.zeros((p, p))
    A[:g, :g] = Agg
    A[:g, g:] = np.swapaxes(Age, 0, 1).reshape(g, 6 * n)
    A[g:, :g] = A[:g, g:].T
    idx = _station_index(g, n)
    A[idx[:, :, None], idx[:, None, :]] = Aee
    return A, np.concatenate([bg, be.reshape(-1)])


def _station_index(g: int, n: int) -> NDArray[np.intp]:
    """Rows ``(n, 6)`` of every station's correction in the parameter vector."""
    return g + 6 * np.arange(n)[:, None] + np.arange(6)


def schur_solve(A: Array, damp: Array, b: Array, g: int) -> Array:
    """Solve ``(A + diag(damp)) h = -b`` eliminating the 6 x 6 station blocks.

    Parameters
    ----------
    A : ndarray, shape (p, p)
        Normal matrix of `normal_equations`: shared block ``(g, g)``, then ``n`` station
        blocks of 6 on the diagonal (zero between stations).
    damp : ndarray, shape (p,)
        Diagonal added (Levenberg-Marquardt damping).
    b : ndarray, shape (p,)
        Gradient ``J^T W r``.
    g : int
        Number of shared unknowns.

    Returns
    -------
    ndarray, shape (p,)

    Raises
    ------
    numpy.linalg.LinAlgError
        The damped matrix is not positive definite.
    """
    p = len(b)
    n = (p - g) // 6
    if n == 0:
        return -_spd_solve(A + np.diag(damp), b)
    idx = _station_index(g, n)
    E = A[idx[:, :, None], idx[:, None, :]]  # (n, 6, 6) station blocks, damped
    E[:, np.arange(6), np.arange(6)] += damp[g:].reshape(n, 6)
    np.linalg.cholesky(E)  # raises LinAlgError unless every block is positive definite
    Ei = np.linalg.inv(E)
    Fs = A[:g, g:].reshape(g, n, 6).transpose(1, 0, 2)  # (n, g, 6): coupling per station
    EiFt = Ei @ np.swapaxes(Fs, 1, 2)  # (n, 6, g)
    Eib = np.einsum("sij,sj->si", Ei, b[g:].reshape(n, 6))  # (n, 6)
    S = A[:g, :g] + np.diag(damp[:g]) - np.einsum("sgi,sih->gh", Fs, EiFt)
    rhs = -b[:g] + np.einsum("sgi,si->g", Fs, Eib)
    hg = _spd_solve(S, rhs)
    he = -Eib - np.einsum("sig,g->si", EiFt, hg)
    return np.concatenate([hg, he.reshape(-1)])


def _spd_solve(M: Array, b: Array) -> Array:
    """``M^-1 b`` for a symmetric positive definite ``M`` ``(k, k)`` by its Cholesky factor
    (numpy's: the command line's hand-eye path then never imports scipy.linalg, 0.1 s);
    `numpy.linalg.LinAlgError` when ``M`` is not positive definite."""
    L = np.linalg.cholesky(M)
    return np.linalg.solve(L.T, np.linalg.solve(L, b))
