"""Least-squares solvers for calibration: paper 000's Householder Gauss-Newton and LM.

Both take a residual function ``r(x) -> (m,)`` and its Jacobian ``J(x) -> (m, n)`` and
return the same `scipy.optimize.OptimizeResult` as the metaheuristics, with ``history``
holding a monitored cost after each iteration (``monitor(r)``, default the RMS residual).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from kinecal._blas import small_products
from kinecal.errors import InputError
from kinecal.optimize._common import FitResult, fit_result, make_result
from kinecal.optimize.lm import (
    LinearSolver,
    LMSolution,
    NormalEquations,
    cached_normal_equations,
    cholesky_step,
    iterate,
    plain_normal_equations,
    rms,
)

if TYPE_CHECKING:
    from scipy.optimize import OptimizeResult

__all__ = ["LOSSES", "householder_gauss_newton", "levenberg_marquardt"]

Array = NDArray[np.float64]
Residual = Callable[[Array], Array]
Jacobian = Callable[[Array], Array]

#: robust losses of `levenberg_marquardt` (scipy names)
LOSSES = ("linear", "huber", "soft_l1", "cauchy", "arctan")


@small_products
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
    monitor = monitor or rms
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
            from scipy.optimize import OptimizeResult

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


def _scipy_result(fit: Callable[..., FitResult]) -> Callable[..., OptimizeResult]:
    """The public form of the solver `fit`: its result as scipy's `OptimizeResult`. `fit`
    itself stays reachable as ``.fit`` for kinecal's own paths, which then never import
    scipy.optimize (`kinecal.optimize._common.FitResult`)."""

    @functools.wraps(fit)
    def solver(*args, **kwargs) -> OptimizeResult:
        from scipy.optimize import OptimizeResult

        return OptimizeResult(fit(*args, **kwargs))

    solver.fit = fit  # type: ignore[attr-defined]
    return solver


@_scipy_result
def levenberg_marquardt(
    residual: Residual,
    jacobian: Jacobian,
    x0: Array,
    *,
    loss: str = "linear",
    f_scale: float = 1.0,
    max_nfev: int | None = None,
    ftol: float | None = None,
    xtol: float | None = None,
    gtol: float | None = None,
    solver: str = "kinecal",
    monitor: Callable[[Array], float] | None = None,
    normal_equations: NormalEquations | None = None,
    start: tuple[Array, Array, Array] | None = None,
    damping: float | tuple[float, float] = 1e-3,
    linear_solver: LinearSolver | None = None,
) -> OptimizeResult:
    """Levenberg-Marquardt with the analytic Jacobian.

    ``solver="kinecal"`` (default for ``loss="linear"``): Marquardt-scaled damping
    ``(J^T J + mu diag(J^T J)) h = -J^T r`` solved by Cholesky, with Nielsen's damping update
    (Madsen, Nielsen, Tingleff 2004, "Methods for non-linear least squares problems",
    alg. 3.16). Calibration Jacobians are tall and narrow (thousands of rows, tens of
    columns): forming ``J^T J`` once per iteration costs a fraction of MINPACK's QR, which
    matters once the residual and Jacobian themselves are cheap.
    ``solver="minpack"`` or a robust loss (``huber``, ``soft_l1``, ``cauchy``, ``arctan``,
    with scale `f_scale` in residual units): scipy `least_squares` (MINPACK LM for linear,
    trust-region reflective for robust losses) with the same analytic Jacobian.

    Parameters
    ----------
    residual, jacobian : callable
        ``r(x) -> (m,)`` and ``J(x) -> (m, n)``.
    x0 : ndarray, shape (n,)
        Start point.
    normal_equations : callable, optional
        ``normal_equations(x) -> (r, J^T J, J^T r)``: the kinecal solver then never asks
        for ``J`` itself, so a caller can accumulate the ``(n, n)`` normal equations over
        chunks of rows (memory linear in ``m`` with a small constant). Used only by the
        kinecal solver; `residual` and `jacobian` still serve MINPACK and robust losses.
    start : tuple of ndarray, optional
        ``(r, J^T J, J^T r)`` already known at `x0` (kinecal solver): saves one evaluation.
    damping : float or (float, float)
        Initial damping ``mu`` of the kinecal solver, relative to ``diag(J^T J)``. The
        default suits a start far from the solution. A pair ``(first, fallback)`` tries
        the first step with ``first`` and, if that step fails, continues from
        ``fallback``: a start where the linearisation is probably good (continuing a fit
        on more parameters) tries a near Gauss-Newton step (``first`` = 1e-9) at the risk
        of one evaluation. With weakly identifiable directions (condition ``c``) each
        accepted step divides ``mu`` by at most 3: a large ``mu`` costs about
        ``log3(c^2 mu)`` iterations before those directions move.
    linear_solver : callable, optional
        ``linear_solver(A, damp, g) -> h`` solving ``(A + diag(damp)) h = -g`` for the
        kinecal solver's steps (raising `numpy.linalg.LinAlgError` when the matrix is not
        positive definite), for normal matrices with structure (e.g. a Schur complement);
        default: dense Cholesky.

    Returns
    -------
    OptimizeResult
        (``levenberg_marquardt.fit``: the same fields in a `FitResult`)
        ``x, fun (0.5 sum rho(r^2)), nit, nfev, njev, history, residual, jac, success,
        status, message``; the kinecal solver also returns ``normal_matrix`` (``J^T J``)
        and ``gradient`` (``J^T r``) at ``x`` and its last ``damping``, and ``jac`` only
        without `normal_equations`;
        ``history`` is the monitored cost (default RMS residual) after each accepted step,
        ``history[0]`` at `x0`.

    Notes
    -----
    Stopping (kinecal solver; defaults 1e-12): relative cost reduction of an accepted step
    ``<= ftol``, or predicted and actual relative reductions of a trial step both
    ``<= ftol`` (the cost's round-off floor), or a predicted relative reduction ``<= ftol``
    right after a step that the quadratic model predicted well (gain ratio > 0.75), step
    ``<= xtol (||x|| + xtol)``, gradient ``max |J^T r| <= gtol ||r||``, a zero residual,
    or no decrease possible at round-off level. MINPACK defaults: 1e-15.
    """
    if loss not in LOSSES:
        raise InputError(f"loss: expected one of {', '.join(LOSSES)}, got {loss!r}",
                         option="--loss")
    if solver not in ("kinecal", "minpack"):
        raise InputError(f"solver: expected kinecal or minpack, got {solver!r}")
    monitor = monitor or rms
    if loss == "linear" and solver == "kinecal":
        if normal_equations is not None:
            evaluate, linearize = cached_normal_equations(normal_equations)
        else:
            evaluate, linearize = plain_normal_equations(residual, jacobian)
        return _as_result(iterate(
            evaluate, linearize, np.asarray(x0, dtype=float), start=start, damping=damping,
            max_nfev=max_nfev or 200 * (np.size(x0) + 1),
            ftol=1e-12 if ftol is None else ftol, xtol=1e-12 if xtol is None else xtol,
            gtol=1e-12 if gtol is None else gtol, monitor=monitor,
            linear_solver=linear_solver or cholesky_step))
    ftol, xtol, gtol = (1e-15 if v is None else v for v in (ftol, xtol, gtol))
    history: list[float] = []

    def fun(x: Array) -> Array:
        r = residual(x)
        value = monitor(r)
        history.append(value if not history else min(value, history[-1]))
        return r

    from scipy.optimize import least_squares

    t0 = time.perf_counter()
    method = "lm" if loss == "linear" else "trf"
    out = least_squares(fun, np.asarray(x0, dtype=float), jac=lambda x: jacobian(x),
                        method=method, loss=loss, f_scale=f_scale, max_nfev=max_nfev,
                        ftol=ftol, xtol=xtol, gtol=gtol, x_scale="jac")
    elapsed = time.perf_counter() - t0
    njev = int(out.njev) if out.njev is not None else 0
    return fit_result(
        out.x, float(out.cost), nit=njev, nfev=int(out.nfev), success=bool(out.success),
        status=int(out.status), message=str(out.message), history=history, elapsed=elapsed,
        njev=njev, residual=out.fun, jac=out.jac,
    )


def _as_result(sol: LMSolution) -> FitResult:
    """The `FitResult` of a kinecal LM solution (``jac`` only when it was formed)."""
    extra = {} if sol.jac is None else {"jac": sol.jac}
    return fit_result(
        sol.x, sol.fun, nit=sol.nit, nfev=sol.nfev, success=sol.success, status=sol.status,
        message=sol.message, history=sol.history, elapsed=sol.elapsed, njev=sol.njev,
        residual=sol.residual, normal_matrix=sol.normal_matrix, gradient=sol.gradient,
        damping=sol.damping, **extra,
    )
