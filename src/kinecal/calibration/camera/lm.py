"""Dense Levenberg-Marquardt with a robust loss on residual groups (iteratively reweighted).

The residual vector is cut into groups (the two pixel coordinates of a corner); a robust
loss ``rho`` acts on a group's squared norm ``s = |r_g|^2 / f^2`` (scipy's loss names and
formulas: ``linear`` ``s``, ``huber`` ``s`` below 1 and ``2 sqrt(s) - 1`` above,
``soft_l1`` ``2 (sqrt(1 + s) - 1)``, ``cauchy`` ``log(1 + s)``, ``arctan`` ``arctan(s)``).
Each iteration weights the groups by ``rho'(s)`` at the current point (a Gauss-Newton
model of the robust cost that is exact for ``linear``), solves the damped normal equations
with Marquardt's diagonal scaling (invariant to the units of the unknowns: lengths, radians
and pixels per focal length side by side), and accepts the step when the robust cost
decreases. The problems it serves have tens of unknowns and thousands of rows: the normal
matrix is formed and factored whole (Cholesky).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from kinecal.errors import InputError

Array = NDArray[np.float64]

__all__ = ["LOSSES", "LMOutcome", "group_weights", "robust_cost", "robust_lm"]

LOSSES = ("linear", "huber", "soft_l1", "cauchy", "arctan")


def _rho(s: Array, loss: str) -> tuple[Array, Array]:
    """``rho(s)`` and ``rho'(s)`` elementwise."""
    if loss == "linear":
        return s, np.ones_like(s)
    if loss == "huber":
        big = s > 1.0
        root = np.sqrt(np.where(big, s, 1.0))
        return np.where(big, 2.0 * root - 1.0, s), np.where(big, 1.0 / root, 1.0)
    if loss == "soft_l1":
        t = np.sqrt(1.0 + s)
        return 2.0 * (t - 1.0), 1.0 / t
    if loss == "cauchy":
        return np.log1p(s), 1.0 / (1.0 + s)
    if loss == "arctan":
        return np.arctan(s), 1.0 / (1.0 + s * s)
    raise InputError(f"loss: expected one of {', '.join(LOSSES)}, got {loss!r}",
                     option="--loss")


def _group_sq(r: Array, group: int) -> Array:
    return np.sum(r.reshape(-1, group) ** 2, axis=1)


def robust_cost(r: Array, loss: str, f_scale: float, group: int = 2) -> float:
    """``f^2 sum_g rho(|r_g|^2 / f^2)``: the robust cost of residuals `r` ``(m,)``."""
    s = _group_sq(r, group) / f_scale**2
    return float(f_scale**2 * np.sum(_rho(s, loss)[0]))


def group_weights(r: Array, loss: str, f_scale: float, group: int = 2) -> Array:
    """IRLS weight ``rho'(s)`` of every group ``(m / group,)``."""
    return _rho(_group_sq(r, group) / f_scale**2, loss)[1]


@dataclass
class LMOutcome:
    """Result of `robust_lm`.

    Attributes
    ----------
    x : ndarray, shape (p,)
    residual : ndarray, shape (m,)
        Residuals at `x`.
    jacobian : ndarray, shape (m, p)
        Jacobian at `x` (evaluated there after the last accepted step).
    cost : float
        Robust cost at `x`.
    nit, nfev : int
        Iterations (Jacobian evaluations) and residual evaluations.
    history : list of float
        Robust cost after each accepted step (the start first).
    success : bool
        Converged by the tolerances (not by the budget).
    """

    x: Array
    residual: Array
    jacobian: Array
    cost: float
    nit: int
    nfev: int
    history: list[float] = field(default_factory=list)
    success: bool = True


def robust_lm(fun: Callable[[Array, bool], tuple[Array, Array | None]], x0: Array, *,
              loss: str = "linear", f_scale: float = 1.0, group: int = 2,
              max_iter: int = 100, ftol: float = 1e-12, xtol: float = 1e-12) -> LMOutcome:
    """Minimise ``f^2 sum_g rho(|r_g(x)|^2 / f^2)`` by Levenberg-Marquardt.

    Parameters
    ----------
    fun : callable
        ``fun(x, jac)`` -> ``(r (m,), J (m, p) or None)``; the Jacobian only when `jac`.
    x0 : ndarray, shape (p,)
    loss, f_scale, group
        Robust loss (`LOSSES`), its scale (residual units) and the group size (2: the
        two pixel coordinates of a corner).
    max_iter : int
        Jacobian evaluations at most.
    ftol, xtol : float
        Stop when the cost falls by less than ``ftol`` relatively, or the step is below
        ``xtol`` of the unknowns' (scaled) size.

    Returns
    -------
    LMOutcome
    """
    x = np.asarray(x0, float).copy()
    r, J = fun(x, True)
    nfev = 1
    cost = robust_cost(r, loss, f_scale, group)
    history = [cost]
    lam, nu = 1e-3, 2.0
    success = False
    nit = 1
    while nit <= max_iter:
        w = np.repeat(group_weights(r, loss, f_scale, group), group)
        Jw = J * w[:, None]
        H = J.T @ Jw
        g = Jw.T @ r
        d = np.maximum(np.diag(H), 1e-300)
        improved = False
        while True:
            try:
                c = scipy.linalg.cho_factor(H + lam * np.diag(d), check_finite=False)
                step = -scipy.linalg.cho_solve(c, g, check_finite=False)
            except (np.linalg.LinAlgError, ValueError):
                step = -np.linalg.lstsq(H + lam * np.diag(d), g, rcond=None)[0]
            xn = x + step
            rn, _ = fun(xn, False)
            nfev += 1
            cn = robust_cost(rn, loss, f_scale, group)
            small = np.sqrt(np.sum(d * step**2)) <= xtol * (np.sqrt(np.sum(d * x**2)) + xtol)
            if np.isfinite(cn) and cn <= cost:
                rel = (cost - cn) / max(cost, 1e-300)
                x, r, cost = xn, rn, cn
                lam, nu = max(lam / 3.0, 1e-12), 2.0
                improved = True
                success = rel < ftol or small
                break
            lam *= nu
            nu *= 2.0
            if small or lam > 1e16:
                success = True
                break
        history.append(cost)
        if improved:
            r, J = fun(x, True)
            nfev += 1
            nit += 1
        if success or not improved:
            break
    return LMOutcome(x, r, J, cost, nit, nfev, history, success)
