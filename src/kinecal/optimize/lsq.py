"""Least-squares solvers for calibration: paper 000's Householder Gauss-Newton and LM.

Both take a residual function ``r(x) -> (m,)`` and its Jacobian ``J(x) -> (m, n)`` and
return the same `scipy.optimize.OptimizeResult` as the metaheuristics, with ``history``
holding a monitored cost after each iteration (``monitor(r)``, default the RMS residual).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import scipy.linalg
from numpy.typing import NDArray
from scipy.optimize import OptimizeResult, least_squares

from kinecal.errors import InputError
from kinecal.optimize._common import make_result

__all__ = ["LOSSES", "householder_gauss_newton", "levenberg_marquardt"]

Array = NDArray[np.float64]
Residual = Callable[[Array], Array]
Jacobian = Callable[[Array], Array]

#: robust losses of `levenberg_marquardt` (scipy names)
LOSSES = ("linear", "huber", "soft_l1", "cauchy", "arctan")


def _rms(r: Array) -> float:
    return float(np.sqrt(np.mean(np.square(r))))


def householder_gauss_newton(
    residual: Residual,
    jacobian: Jacobian,
    x0: Array,
    *,
    maxiter: int = 1000,
    xtol: float = 1e-12,
    singular_tol: float = 1e-10,
    monitor: Callable[[Array], float] | None = None,
    callback: Callable[[OptimizeResult], bool | None] | None = None,
) -> OptimizeResult:
    """Gauss-Newton with the normal equations solved by Householder QR (papers/000 sec. 3-4.1).

    Each iteration linearises ``dP = J d`` (papers/000 eq. 7), and computes the update of
    eq. (10)-(11), ``d = (J^T J)^-1 J^T dP``, the way sec. 4.1 ("modified least squares")
    does: Householder QR of ``J`` (no pivoting), ``R d = Q^T dP``, without forming ``J^T J``.
    The paper notes that ``J^T J`` tends to become singular; here a diagonal element of
    ``R`` below ``singular_tol * max |R_kk|`` is that singularity: the step is then taken
    with those components set to zero (the update the paper could still compute), the
    result's ``singular`` lists their column indices and the message says so.

    Parameters
    ----------
    residual, jacobian : callable
        ``r(x) -> (m,)`` and ``J(x) -> (m, n)`` (``dr/dx``).
    x0 : ndarray, shape (n,)
        Start point.
    maxiter : int
        Iteration budget (papers/000 Table 2 runs the LS to 1000 iterations).
    xtol : float
        Stop when ``||d|| <= xtol * (||x|| + xtol)``.
    singular_tol : float
        Relative threshold on ``|R_kk|`` for a singular column.
    monitor : callable, optional
        ``monitor(r) -> float`` recorded in ``history`` (default RMS of r).
    callback : callable, optional
        Called with an intermediate result after each iteration; True stops.

    Returns
    -------
    OptimizeResult
        ``x, fun (0.5 ||r||^2), nit, nfev, njev, history, singular, success, status, message``.
    """
    monitor = monitor or _rms
    t0 = time.perf_counter()
    x = np.array(x0, dtype=float)
    r = residual(x)
    history = [monitor(r)]
    nfev, njev = 1, 0
    singular_seen: set[int] = set()
    status, message = 0, "maximum number of iterations reached"
    for it in range(1, maxiter + 1):
        J = jacobian(x)
        njev += 1
        Q, R = scipy.linalg.qr(J, mode="economic")  # LAPACK geqrf: Householder reflections
        diag = np.abs(np.diag(R))
        singular = diag <= singular_tol * diag.max()
        rhs = -(Q.T @ r)
        if singular.any():
            singular_seen.update(np.flatnonzero(singular).tolist())
            keep = ~singular
            d = np.zeros_like(x)
            d[keep] = scipy.linalg.solve_triangular(R[np.ix_(keep, keep)], rhs[keep])
        else:
            d = scipy.linalg.solve_triangular(R, rhs)
        x = x + d
        r = residual(x)
        nfev += 1
        history.append(monitor(r))
        if callback is not None:
            stop = callback(OptimizeResult(x=x.copy(), fun=0.5 * float(r @ r), nit=it, nfev=nfev))
            if stop:
                status, message = 3, "stopped by the callback"
                break
        if np.linalg.norm(d) <= xtol * (np.linalg.norm(x) + xtol):
            status, message = 4, "step below xtol"
            break
    nit = it
    if singular_seen:
        message += (
            f"; J^T J singular in {len(singular_seen)} direction(s) (columns "
            f"{sorted(singular_seen)}): those parameters are not identifiable and were not updated"
        )
    return make_result(
        x,
        0.5 * float(r @ r),
        nit=nit,
        nfev=nfev,
        success=status in (0, 4) and not singular_seen,
        status=status,
        message=message,
        history=history,
        elapsed=time.perf_counter() - t0,
        njev=njev,
        singular=sorted(singular_seen),
    )


def levenberg_marquardt(
    residual: Residual,
    jacobian: Jacobian,
    x0: Array,
    *,
    loss: str = "linear",
    f_scale: float = 1.0,
    max_nfev: int | None = None,
    ftol: float = 1e-15,
    xtol: float = 1e-15,
    gtol: float = 1e-15,
    x_scale: Array | str = "jac",
    monitor: Callable[[Array], float] | None = None,
) -> OptimizeResult:
    """Levenberg-Marquardt (scipy `least_squares`) with the analytic Jacobian.

    ``loss="linear"`` uses MINPACK's LM (``method="lm"``); a robust loss (``huber``,
    ``soft_l1``, ``cauchy``, ``arctan``, with scale `f_scale` in residual units) uses the
    trust-region reflective solver, which supports it.

    Returns
    -------
    OptimizeResult
        ``x, fun (0.5 sum rho(r^2)), nit, nfev, njev, history, residual, jac, success,
        status, message``; ``history`` is the best monitored cost after each residual
        evaluation (non-increasing).
    """
    if loss not in LOSSES:
        raise InputError(
            f"loss: expected one of {', '.join(LOSSES)}, got {loss!r}", option="--loss"
        )
    monitor = monitor or _rms
    history: list[float] = []

    def fun(x: Array) -> Array:
        r = residual(x)
        value = monitor(r)
        history.append(value if not history else min(value, history[-1]))
        return r

    t0 = time.perf_counter()
    method = "lm" if loss == "linear" else "trf"
    out = least_squares(
        fun,
        np.asarray(x0, dtype=float),
        jac=lambda x: jacobian(x),
        method=method,
        loss=loss,
        f_scale=f_scale,
        max_nfev=max_nfev,
        ftol=ftol,
        xtol=xtol,
        gtol=gtol,
        x_scale=x_scale,
    )
    elapsed = time.perf_counter() - t0
    njev = int(out.njev) if out.njev is not None else 0
    return make_result(
        out.x,
        float(out.cost),
        nit=njev,
        nfev=int(out.nfev),
        success=bool(out.success),
        status=int(out.status),
        message=str(out.message),
        history=history,
        elapsed=elapsed,
        njev=njev,
        residual=out.fun,
        jac=out.jac,
    )
